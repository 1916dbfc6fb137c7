"""Run random fuzz scripts against freshly built FMUs for a while; print what failed.

usage: python3 -m tests.fuzz.run [--seconds S] [--seed N] [--valgrind-every K] [--keep DIR]

Builds the FMUs, compiles tests/fuzz/fuzz_host.c, then until S seconds have passed runs, each
in its own process: a random valid sequence with its replay oracles, or one to four random
invalid cases of tests/fuzz/cases.py in a random model's sequence; every K-th script under
valgrind (memory errors only).  A failing script is written to DIR (default
build/fuzz-failures) with the host's output, to replay with ``DIR/work/fuzz_host < script``
(DIR/work holds the FMUs and the host of the last run).  Exit
code 0 when nothing failed, 1 otherwise.
"""
import argparse
import random
import shutil
import sys
import time
from pathlib import Path

from . import compile_host, reads, run_script, unzip, valid_sequence
from . import cases as fuzz_cases

VALGRIND = ["-q", "--undef-value-errors=no", "--error-exitcode=99"]


def prepare(work):
    """Build the FMUs into ``work``; (host, {name: Model})."""
    from driftfmu.fmu_src.builder import NAMES, build_fmus
    fmus = build_fmus(work / "fmus", names=NAMES, log=lambda line: None)
    models = {name: unzip(fmu, work / "unzipped" / name) for name, fmu in zip(NAMES, fmus)}
    return compile_host(work), models


def check_valid(host, model, seed, valgrind=None):
    """Problems of one random valid sequence and its replays."""
    lines, pairs = valid_sequence(model, seed)
    result = run_script(host, lines, valgrind=valgrind)
    problems = result.problems()
    bad = {n: s for n, s in result.statuses().items() if s > 1}
    if bad:
        problems.append("valid calls refused: %s" % sorted(bad.items())[:5])
    for a, b in pairs:
        if reads(result, a) != reads(result, b):
            problems.append("replay differs (lines %d-%d vs %d-%d)" % (a[0], a[-1], b[0], b[-1]))
    return problems, lines, result


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m tests.fuzz.run", description=__doc__)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--valgrind-every", type=int, default=25)
    parser.add_argument("--keep", default="build/fuzz-failures")
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2 ** 32)
    rng = random.Random(seed)
    valgrind_ok = shutil.which("valgrind") is not None and args.valgrind_every > 0
    keep = Path(args.keep)
    print("fuzz: seed %d, %g s" % (seed, args.seconds), flush=True)
    work = keep / "work"  # the FMUs and the host stay, so that a failing script replays
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    host, models = prepare(work.resolve())
    if host is None:
        print("fuzz: no C compiler", file=sys.stderr)
        return 1
    names = sorted(models)
    end = time.monotonic() + args.seconds
    runs = failures = 0
    while time.monotonic() < end:
        runs += 1
        valgrind = VALGRIND if valgrind_ok and runs % args.valgrind_every == 0 else None
        model = models[rng.choice(names)]
        script_seed = rng.randrange(2 ** 32)
        if rng.random() < 0.3:
            what = "valid sequence"
            problems, lines, result = check_valid(host, model, script_seed, valgrind)
        else:
            pool = [c for c in fuzz_cases.CASES
                    if c in fuzz_cases.ALL_MODELS or model.name == "Accelerometer"]
            chosen = rng.sample(pool, rng.randint(1, 4))
            what = "cases %s" % ", ".join(chosen)
            other = models[rng.choice([n for n in names if n != model.name])]
            result, problems, lines = fuzz_cases.run_case(host, chosen, model, other,
                                                          script_seed, valgrind=valgrind)
        if problems:
            failures += 1
            keep.mkdir(parents=True, exist_ok=True)
            stem = keep / ("%s-%d" % (model.name, script_seed))
            stem.with_suffix(".script").write_text("\n".join(lines) + "\n")
            stem.with_suffix(".out").write_text(result.output)
            print("FAIL %s, %s%s (seed %d): %s\n  script: %s"
                  % (model.name, what, " under valgrind" if valgrind else "", script_seed,
                     "; ".join(problems)[:500], stem.with_suffix(".script")), flush=True)
    print("fuzz: %d scripts, %d failed (seed %d)" % (runs, failures, seed))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
