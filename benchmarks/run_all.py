"""Run every benchmark, one after the other, each recording its rows in benchmarks/figures.json
and rendering docs/performance.md (see benchmarks/figures.py).

    python benchmarks/run_all.py              # the sizes of the page (about 10 minutes idle)
    python benchmarks/run_all.py --quick      # smaller sizes, a few minutes
    python benchmarks/run_all.py bench_step.py bench_sweep.py    # only these

Run it from the project root after ``driftfmu build --native`` (the benchmarks take the FMUs
from ``build/fmus``), on a machine with nothing else running: each figure is measured against a
baseline in the same run, but wall times are the machine's.
"""
import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: Each benchmark's arguments: (the page's sizes, --quick's sizes).
RUNS = [
    ("bench_step.py", ["--repeats", "9"], ["--steps", "2000", "--repeats", "5"]),
    ("bench_fmu_hosts.py", ["--repeats", "5"], ["--steps", "2000", "--repeats", "3"]),
    ("bench_native.py", ["--repeats", "5"],
     ["--steps", "50000", "--python-steps", "2000", "--repeats", "3"]),
    ("bench_long_step.py", ["--repeats", "3"], ["--samples", "200000", "--repeats", "3"]),

    ("bench_errors.py", ["--repeats", "5"],
     ["--steps", "100000", "--python-steps", "10000", "--repeats", "3"]),
    ("bench_batch.py", ["--repeats", "3"], ["--repeats", "2"]),
    ("bench_sweep.py", ["--repeats", "5"], ["--repeats", "3"]),
    ("bench_adxl203.py", [], []),
    ("bench_adxl203.py", ["--backend", "python", "--no-baseline"],
     ["--backend", "python", "--sets", "6", "--freqs", "150", "--no-baseline"]),
    ("bench_estimates.py", [], ["--only", "run gaussian", "experiment adxl203 native",
                                "experiment dual-axis native"]),
]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes (a few minutes)")
    ap.add_argument("only", nargs="*", help="run only these benchmarks (file names)")
    args = ap.parse_args(argv)
    failed = []
    for name, full, quick in RUNS:
        if args.only and name not in args.only:
            continue
        command = [sys.executable, str(HERE / name)] + (quick if args.quick else full)
        print("== python benchmarks/%s %s" % (name, " ".join(command[2:])), flush=True)
        t0 = time.perf_counter()
        if subprocess.run(command).returncode:
            failed.append(name)
        print("== %s: %.0f s" % (name, time.perf_counter() - t0), flush=True)
    if failed:
        sys.exit("failed: %s" % ", ".join(failed))


if __name__ == "__main__":
    main()
