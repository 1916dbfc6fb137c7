"""A fuzz harness for the FMUs: call scripts run by a C host, one process per script.

``fuzz_host.c`` (this folder) runs a script of FMI 2.0 calls and prints each call's status, the
values read, ``CHANGED`` when a rejected call changed the instance (all Reals and the
serialised FMU state are compared before and after it) and ``NONFINITE`` when an accepted call
left a Real variable non-finite.  This module writes the scripts and judges the output:

- :func:`valid_sequence`: random valid call sequences (inputs, steps of whole and fractional
  sample periods, reads, FMU state get/set/serialise round trips), replayed in a fresh
  instance of the same process and through an FMU state restore; the outputs must be identical.
- ``cases.CASES`` (tests/fuzz/cases.py): every kind of bad call of issue 9 (resource locations, GUIDs, NULLs,
  garbage, foreign and crafted FMU states, bad step sizes and times, overflowing inputs,
  out-of-order calls, out-of-range value references).  Each is run between the calls of a
  valid sequence, and the outputs of that sequence must be those of the same sequence without
  the bad calls: a rejected call changes nothing, and the instance stays usable.

Every script runs in its own process with a time limit: a signal is a crash, the limit a hang.
``python -m tests.fuzz.run --seconds 600`` runs random scripts for ten minutes.

``differential.py`` (this folder) is the differential fuzz: one script on the Python FMU, the
native FMI 2.0 FMU and the native FMI 3.0 FMU of a model, compared call by call
(``python -m tests.fuzz.differential --seconds 1200``); ``native_state.py`` mirrors the native
FMUs' serialised state for the field-by-field tampering test (tests/test_native_hardening.py).
"""
import os
import random
import shutil
import signal
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import fmpy

HERE = Path(__file__).resolve().parent
HOST_SOURCE = HERE / "fuzz_host.c"
TIME_LIMIT = 60.0
#: Status codes as the host prints them.
OK, WARNING, DISCARD, ERROR, FATAL = range(5)


def compile_host(out_dir):
    """Compile fuzz_host.c into ``out_dir``; the path of the executable (None without cc)."""
    cc = shutil.which(os.environ.get("CC", "cc"))
    if not cc:
        return None
    exe = Path(out_dir) / "fuzz_host"
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([cc, "-O1", "-g", "-o", str(exe), str(HOST_SOURCE), "-I%s" % headers,
                    "-ldl", "-lm"], check=True)
    return str(exe)


@dataclass
class Model:
    """What a script needs to know of one unzipped FMU."""
    name: str
    dir: str
    guid: str
    identifier: str
    vr: dict           # name -> value reference
    inputs: list       # names of the Real inputs
    outputs: list      # names of the Real outputs
    reals: list        # value references of every Real variable
    integers: list     # value references of the Integer variables
    Ts: float
    start: dict = field(default_factory=dict)

    @classmethod
    def read(cls, unzipped):
        md = fmpy.read_model_description(str(unzipped))
        variables = md.modelVariables
        vr = {v.name: v.valueReference for v in variables}
        start = {v.name: float(v.start) for v in variables
                 if v.start is not None and v.type in ("Real", "Integer")}
        return cls(name=md.modelName, dir=str(unzipped), guid=md.guid,
                   identifier=md.coSimulation.modelIdentifier, vr=vr,
                   inputs=[v.name for v in variables if v.causality == "input"
                           and v.type == "Real"],
                   outputs=[v.name for v in variables if v.causality == "output"],
                   reals=[v.valueReference for v in variables if v.type == "Real"],
                   integers=[v.valueReference for v in variables if v.type == "Integer"],
                   Ts=start.get("Ts", 1e-3), start=start)


def unzip(fmu, folder):
    """Extract ``fmu`` into ``folder`` (created); its :class:`Model`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fmpy.extract(str(fmu), unzipdir=str(folder))
    return Model.read(folder)


# -- running a script --------------------------------------------------------------------------

@dataclass
class Result:
    """What the host printed for a script."""
    returncode: int
    output: str
    timed_out: bool = False

    @property
    def lines(self):
        return self.output.splitlines()

    @property
    def crashed(self):
        return self.returncode < 0 or self.returncode in (128 + signal.SIGSEGV,
                                                          128 + signal.SIGABRT)

    def statuses(self):
        """Script line number -> status of its call."""
        return {int(p[1]): int(p[3]) for p in (line.split() for line in self.lines)
                if len(p) == 4 and p[0] == "S"}

    def values(self):
        """Script line number -> the values its getter printed (strings, exact)."""
        return {int(p[1]): p[2:] for p in (line.split() for line in self.lines)
                if len(p) >= 2 and p[0] == "V"}

    def marked(self, word):
        return [line for line in self.lines if line.startswith(word + " ")]

    def problems(self):
        """Crash, hang, unfinished script, changes by rejected calls, non-finite outputs."""
        found = []
        if self.timed_out:
            found.append("hang: no end within %g s" % TIME_LIMIT)
        elif self.returncode != 0:
            found.append("exit code %d (%s)" % (self.returncode, _signal_name(self.returncode)))
        elif "END" not in self.lines:
            found.append("the script did not run to its end")
        found += ["a rejected call changed the instance: " + line for line in
                  self.marked("CHANGED")]
        found += ["an accepted call left a non-finite value: " + line for line in
                  self.marked("NONFINITE")]
        return found


def _signal_name(code):
    number = -code if code < 0 else code - 128
    try:
        return signal.Signals(number).name
    except ValueError:
        return "no signal"


def run_script(host, lines, valgrind=None, time_limit=TIME_LIMIT, env=None):
    """Run ``lines`` (str each) in a fresh host process; a :class:`Result`.

    ``valgrind`` is a list of valgrind options to run the host under, or None.
    """
    command = [host] if valgrind is None else ["valgrind", *valgrind, host]
    environment = dict(os.environ if env is None else env)
    if valgrind is not None:
        environment["PYTHONMALLOC"] = "malloc"  # valgrind sees every allocation
    try:
        done = subprocess.run(command, input="\n".join(lines) + "\n", capture_output=True,
                              text=True, timeout=time_limit, env=environment,
                              errors="replace")
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout or b""
        return Result(-1, out.decode(errors="replace") if isinstance(out, bytes) else out,
                      timed_out=True)
    return Result(done.returncode, done.stdout + done.stderr)


# -- scripts -----------------------------------------------------------------------------------

def word(text):
    """``text`` as one word of a script (spaces and backslashes escaped)."""
    return text.replace("\\", "\\\\").replace(" ", "\\s")


def header(model, slot=0, lib=0, name="fuzz"):
    """Load ``model`` as library ``lib`` and instantiate it in ``slot``."""
    return ["load %d %s %s" % (lib, word(model.dir), model.identifier),
            "inst %d %d %s 1 %s DEFAULT" % (slot, lib, name, model.guid),
            "reals %d %d %s" % (slot, len(model.reals), " ".join(map(str, model.reals)))]


def initialise(model, slot, inputs=None):
    lines = ["setup %d 0" % slot, "enter %d" % slot]
    for name, value in (inputs or {}).items():
        lines.append("setr %d 1 %d %r" % (slot, model.vr[name], value))
    return lines + ["exit %d" % slot]


class Sequence:
    """A valid call sequence on one instance; ``lines(slot)`` writes it for that slot.

    Calls are kept as format strings with ``{I}`` (instance), ``{S}`` (a state slot of this
    sequence) and ``{B}`` (a buffer slot), so one sequence runs in several instances.
    """

    def __init__(self, model, rng, n_calls, state_calls=True, t0=None, parameters=True):
        self.model = model
        self.calls = []
        #: per call, the time and the inputs before it
        self.context = []
        self.t = 0.0 if t0 is None else t0
        self.inputs = {name: model.start.get(name, 0.0) for name in model.inputs}
        if t0 is None:  # from instantiation: initialise first
            self.add("setup {I} 0", "enter {I}")
            if parameters and "seed" in model.vr:
                self.add("seti {I} 1 %d %d" % (model.vr["seed"], rng.randint(2, 10 ** 6)))
            for name in model.inputs:
                self.set(name, round(rng.uniform(-2, 2), 6))
            self.add("exit {I}", self.read())
        #: index of the first call after initialisation
        self.body = len(self.calls)
        saved = None
        for _ in range(n_calls):
            r = rng.random()
            if r < 0.35 and model.inputs:
                self.set(rng.choice(model.inputs), round(rng.gauss(0, 1.5), 9))
            elif r < 0.75:
                # whole sample periods mostly; any positive step is valid (the sampled-data
                # step rule: instants inside a step see the inputs held from its start)
                h = model.Ts * rng.choice((1, 1, 1, 2, 3, 0.5, 0.3, 2.5))
                self.add("step {I} %r %r" % (self.t, h))
                self.t += h
                self.add(self.read())
            elif r < 0.85 and state_calls:
                self.add("gst {I} {S}")
                saved = (self.t, dict(self.inputs))
            elif r < 0.95 and state_calls and saved is not None:
                self.add("ser {I} {S} {B}", "des {I} {B} {S1}", "sst {I} {S1}")
                self.t, self.inputs = saved[0], dict(saved[1])
                self.add("fst {I} {S1}", self.read())
            else:
                self.add(self.read())

    def add(self, *calls):
        for call in calls:
            self.context.append((self.t, dict(self.inputs)))
            self.calls.append(call)

    def set(self, name, value):
        self.add("setr {I} 1 %d %r" % (self.model.vr[name], value))
        self.inputs[name] = value

    def read(self):
        vrs = [self.model.vr[n] for n in self.model.outputs]
        return "getr {I} %d %s" % (len(vrs), " ".join(map(str, vrs)))

    def lines(self, slot, state_base=None):
        base = 8 * slot if state_base is None else state_base
        return [c.format(I=slot, S=base, S1=base + 1, B=base) for c in self.calls]


def valid_sequence(model, seed, n_calls=40):
    """A script running one random valid sequence in instance 0, then in a fresh instance 1,
    then (in 1) a state restore replay, then another sequence in an instance of 0's name (made
    after 0 was freed) and in a new one; and the line ranges whose reads must agree.

    Returns
    -------
    lines : list of str
    pairs : list of (range, range)
        Script line ranges (1-based, as the host numbers them) whose getter values must be
        equal in order.
    """
    rng = random.Random(seed)
    seq = Sequence(model, rng, n_calls)
    tail = Sequence(model, rng, n_calls // 2, state_calls=False, t0=seq.t)
    lines = header(model, 0) + ["inst 1 0 second 1 %s DEFAULT" % model.guid,
                                "reals 1 %d %s" % (len(model.reals),
                                                   " ".join(map(str, model.reals)))]
    first = _span(lines, seq.lines(0))
    second = _span(lines, seq.lines(1))
    # state restore: save, run the tail's calls, restore, run them again
    lines.append("gst 1 20")
    tail_calls = tail.lines(1)
    before = _span(lines, tail_calls)
    lines.append("sst 1 20")
    after = _span(lines, tail_calls)
    lines += ["fst 1 20", "free 0"]
    # a fresh sequence in an instance of the freed one's name (the shim hands back the freed
    # instance, reset) and in one of a new name
    fresh = Sequence(model, rng, n_calls // 2, parameters=False)
    lines.append("inst 2 0 fuzz 1 %s DEFAULT" % model.guid)
    reused = _span(lines, fresh.lines(2))
    lines.append("inst 3 0 third 1 %s DEFAULT" % model.guid)
    new = _span(lines, fresh.lines(3))
    lines += ["free 1", "free 2", "free 3"]
    return lines, [(first, second), (before, after), (reused, new)]


def _span(lines, new):
    start = len(lines) + 1
    lines.extend(new)
    return range(start, len(lines) + 1)


def reads(result, span):
    """The getter values printed for script lines in ``span``, in order."""
    values = result.values()
    return [values[n] for n in span if n in values]
