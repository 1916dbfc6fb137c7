"""Internal (not a stable API; use the driftfmu command instead).

Size checks before a run starts: memory, disk and time, estimated from the settings.

A run that cannot fit this machine is refused (a usage error, exit 2: one line with the
estimate, what the machine has, and how to proceed) before anything runs; a long or large one
is announced on standard error first.  The estimates are per sample (or per run and sample)
costs measured on the default settings (the constants below); memory and disk are rounded up,
to tell a 56 GB run from a 56 MB one.  Time is the CPU seconds of the work on one core of an
idle machine (measured by benchmarks/bench_estimates.py, which prints each estimate against
the run it estimates) spread over the cores the run's workers get on this machine now
(:func:`cores_for`: a machine busy with other work gives them less), plus the command's own
start-up and files; the benchmark holds it within a factor of 2 of the run.
"""
import os
import shutil
import sys
from pathlib import Path

from driftfmu.simulations.errors import UsageError

#: Memory of the command itself (Python, NumPy, matplotlib, the FMUs), bytes.
BASE_MEMORY = 250e6
#: Bytes of memory per kept trajectory value in ``montecarlo`` (the workers' chunks, the
#: gathered arrays and their concatenation: about twice the 8 bytes of each of 7 trajectories).
MONTECARLO_MEMORY = 2 * 7 * 8 + 8
#: Bytes written per run and sample by ``montecarlo`` (montecarlo.npz, 7 float64 trajectories).
MONTECARLO_DISK = 7 * 8
#: Bytes per run of ``--summary-only``'s per-run summaries (6 settling samples, 2 drifts).
SUMMARY_BYTES = 8 * 8
#: Seconds per run and sample of the batch engine on one core (the compiled kernel, every
#: trajectory kept, then its percentiles for the figure and montecarlo.npz: ~1.1e-6 measured).
MONTECARLO_SECONDS = 1e-6
#: Bytes of memory per run of ``sweep`` (seeds, per-run parameters, the final estimates of each
#: run gathered and concatenated, the references; measured ~153 over 6 million runs).
SWEEP_MEMORY = 200
#: Bytes written per run by ``sweep`` (sweep.npz: 5 or 6 float64 per run).
SWEEP_DISK = 6 * 8
#: Seconds per run and sample of ``sweep``'s batch engine on one core (the compiled kernel
#: ~3.4e-8 measured; NumPy is about ten times slower).
SWEEP_SECONDS = 1.5e-8
#: Bytes of memory per sample of one co-simulation (``run``): the recorded columns, the models/
#: reference run and the comparison (measured ~1.4 kB).
RUN_MEMORY = 1500
#: Bytes written per sample by ``run`` (results.csv, 12 columns at 17 significant digits).
RUN_DISK = 250
#: Seconds per sample of one co-simulation on one core, by backend: the three FMUs stepped
#: and recorded and the run checked against models/ (``run``, and each run of the FMU engine
#: of ``montecarlo`` and ``sweep``; ~6.5e-5 and ~2.4e-5 measured: the check dominates the
#: native FMUs' time).
RUN_SECONDS = {"python": 7e-5, "native": 2.5e-5}
#: Seconds of every command on one core besides its work: Python's start-up and imports, the
#: figures and files.
COMMAND_SECONDS = 2.0
#: Memory that may be planned for: this share of what the machine has available.
MEMORY_SHARE = 0.8
#: Announce a run on standard error when it is expected to take longer than this (seconds) or
#: to need more than ``LARGE`` bytes of memory or disk.
LONG = 60.0
LARGE = 1e9


def available_memory():
    """Bytes of memory this process may use: the smaller of the machine's available memory
    (``MemAvailable`` of /proc/meminfo, else free pages) and the address-space limit
    (``ulimit -v``) less what the process already maps; None when unknown."""
    avail = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            avail = None
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            used = 0
            try:
                with open("/proc/self/status") as fh:
                    for line in fh:
                        if line.startswith("VmSize:"):
                            used = int(line.split()[1]) * 1024
            except OSError:
                pass
            limit = max(0, soft - used)
            avail = limit if avail is None else min(avail, limit)
    except (ImportError, ValueError, OSError):
        pass
    return avail


def free_disk(folder):
    """Free bytes on the file system that would hold ``folder`` (its nearest existing
    parent); None when unknown."""
    path = Path(folder or ".").absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None


def size(n):
    """Bytes for people: ``"56 GB"``, ``"120 MB"``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return ("%.3g %s" if n < 999.5 * scale else "%.0f %s") % (n / scale, unit)
    return "%d B" % n


def cores_for(workers, load=None):
    """The cores that ``workers`` busy processes (or threads) of a run get on this machine
    now: at most one each and at most the machine's, shared evenly among them and the
    processes that already want a core (``load``: the load average of the last minute, less
    this command's own process; :func:`os.getloadavg`)."""
    cores = os.cpu_count() or 1
    workers = max(1, workers or 1)
    if load is None:
        try:
            load = os.getloadavg()[0]
        except (OSError, AttributeError):  # no load average (Windows): an idle machine
            load = 0.0
    others = max(0.0, load - 1.0)
    return min(float(workers), float(cores), cores * workers / (others + workers))


def duration(seconds):
    """Seconds for people: ``"3 s"``, ``"12 min"``, ``"28 h"``."""
    if seconds < 90:
        return "%.0f s" % seconds
    if seconds < 5400:
        return "%.0f min" % (seconds / 60)
    return "%.0f h" % (seconds / 3600)


def _plus_command(seconds, command=None):
    """``seconds`` of work and the command's own (:data:`COMMAND_SECONDS` of one core, on the
    core this command gets now)."""
    return seconds + (COMMAND_SECONDS if command is None else command) / cores_for(1)


def check(what, memory, disk, seconds, out, proceed, fit=None, announce=True):
    """Refuse ``what`` (a UsageError) when ``memory`` or ``disk`` (bytes) exceed what this
    machine has, naming the estimate and ``proceed`` (how to make it fit; ``fit(share)``, when
    given, says what fits in ``share`` of the estimate); with ``announce``, announce it on
    standard error when it is long or large.  Returns the estimate as a dict."""
    grows = memory  # what scales with the run; the command's own memory does not
    memory += BASE_MEMORY
    have_memory = available_memory()
    have_disk = free_disk(out) if out is not None else None
    problems = []
    if have_memory is not None and memory > MEMORY_SHARE * have_memory:
        problems.append(("memory", memory, "%s of memory available" % size(have_memory),
                         max(0.0, MEMORY_SHARE * have_memory - BASE_MEMORY) / grows
                         if grows else 0.0))
    if disk and have_disk is not None and disk > have_disk:
        problems.append(("disk", disk, "%s free at %s" % (size(have_disk), out),
                         have_disk / disk))
    if problems:
        share = min(p[3] for p in problems)
        hint = proceed if fit is None else "%s; or %s" % (fit(share), proceed)
        raise UsageError("%s needs about %s; this machine has %s; allowed: a run that fits: "
                         "%s" % (what, " and ".join("%s of %s" % (size(b), k)
                                                     for k, b, _, _ in problems),
                                 " and ".join(h for _, _, h, _ in problems), hint))
    if announce and (seconds > LONG or memory > LARGE or (disk or 0) > LARGE):
        sys.stderr.write("driftfmu: note: %s: about %s of memory, %s on disk, %s (estimates)\n"
                         % (what, size(memory), size(disk or 0), duration(seconds)))
        sys.stderr.flush()
    return {"memory": memory, "disk": disk, "seconds": seconds}


def parallel(workers, work):
    """How many workers run at once: ``workers`` (None: one per core), but never more than the
    ``work`` there is (units that can run side by side: runs, grid points, sets); at least 1."""
    return max(1, min(workers or os.cpu_count() or 1, work))


def _setting(name, value, api):
    """A setting as its caller writes it: ``runs=1000`` (the Python API) or ``--runs 1000``
    (the command line)."""
    if api:
        return "%s=%r" % (name, value)
    return "--%s %s" % (name.replace("_", "-"), value)


def _name(name, api):
    """A setting's name as its caller writes it: ``summary_only`` or ``--summary-only``."""
    return name if api else "--" + name.replace("_", "-")


def check_montecarlo(command, runs, n, workers, out, summary_only=False, api=False,
                     announce=True, engine="batch", backend="python"):
    """The size check of ``driftfmu montecarlo`` (``api``: of :func:`driftfmu.montecarlo`,
    its settings named as keywords): every trajectory of every run is kept, or
    (``summary_only``) per-run summaries and the figure's runs' trajectories; ``engine`` and
    ``backend`` (the FMU engine's) for the time."""
    cores = parallel(workers, runs)
    if api:
        what = "montecarlo(%r, runs=%d, n=%d%s)" % (command, runs, n, ", summary_only=True"
                                                   if summary_only else "")
    else:
        what = "montecarlo %s --runs %d --n %d%s" % (command, runs, n, " --summary-only"
                                                    if summary_only else "")
    seconds = _plus_command(_run_seconds(engine, backend, MONTECARLO_SECONDS) * runs * n
                            / cores_for(cores))
    runs_, n_ = _name("runs", api), _name("n", api)
    if summary_only:
        from driftfmu.simulations.montecarlo import FIGURE_RUNS
        kept = min(runs, FIGURE_RUNS)
        # workers hold their chunk's trajectories while they reduce them
        chunk = min(runs, 4096) * min(cores, 2)
        memory = MONTECARLO_MEMORY * (kept + chunk) * n + SUMMARY_BYTES * runs
        disk = (MONTECARLO_DISK * kept * n + SUMMARY_BYTES * runs) if out else 0

        def fit_summaries(share):
            # the trajectories kept grow with n, the summaries with runs: name the largest
            # runs at this n when it is the runs that do not fit
            room = share * memory - MONTECARLO_MEMORY * (kept + chunk) * n
            if room >= SUMMARY_BYTES:
                return "at most %s at %s" % (_setting("runs", int(room // SUMMARY_BYTES), api),
                                             _setting("n", n, api))
            return "a smaller %s" % n_
        return check(what, memory, disk, seconds, out, "fewer %s or a smaller %s"
                     % (runs_, n_), fit_summaries, announce=announce)

    def fit(share):
        if runs * share >= 1:
            return "at most %s at %s" % (_setting("runs", int(runs * share), api),
                                         _setting("n", n, api))
        return "at most %s at %s" % (_setting("n", max(1, int(n * runs * share)), api),
                                     _setting("runs", 1, api))
    return check(what, MONTECARLO_MEMORY * runs * n, MONTECARLO_DISK * runs * n if out else 0,
                 seconds, out,
                 "%s, which keeps per-run summaries instead of trajectories; or fewer %s or a "
                 "smaller %s" % ("summary_only=True" if api else "--summary-only", runs_, n_),
                 fit, announce=announce)


def _run_seconds(engine, backend, batch_seconds):
    """Seconds per run and sample on one core: ``batch_seconds`` for the batch engine, a
    co-simulation's (:data:`RUN_SECONDS`) for the FMU engine."""
    if engine == "fmu":
        return RUN_SECONDS.get(backend, RUN_SECONDS["python"])
    return batch_seconds


def check_sweep(points, runs, n, workers, out, announce=True, api=False, engine="batch",
                backend="python"):
    """The size check of ``driftfmu sweep`` (``api``: of :func:`driftfmu.sweep`): ``points``
    grid points of ``runs`` runs of ``n`` samples; each run keeps its final estimates only, so
    the memory grows with the runs, not with ``n``."""
    total = points * runs
    cores = parallel(workers, total)

    def fit(share):
        if runs * share < 1:
            return "at most %d grid points at %s" % (max(1, int(points * runs * share)),
                                                     _setting("runs", 1, api))
        return "at most %s for the %d grid points" % (_setting("runs", int(runs * share), api),
                                                      points)
    what = ("sweep(runs=%d, n=%d) of %d grid points" % (runs, n, points) if api
            else "sweep of %d grid points x --runs %d --n %d" % (points, runs, n))
    return check(what, SWEEP_MEMORY * total, SWEEP_DISK * total if out else 0,
                 _plus_command(_run_seconds(engine, backend, SWEEP_SECONDS) * total * n
                               / cores_for(cores)), out, "fewer grid points", fit,
                 announce=announce)


def check_run(command, n, out, backend="python", api=False, announce=True):
    """The size check of ``driftfmu run`` (``api``: of :func:`driftfmu.run_gaussian` and
    :func:`driftfmu.run_sinusoidal`): one co-simulation of ``n`` samples, every sample
    recorded (results.csv)."""
    def fit(share):
        return "at most %s" % _setting("n", max(1, int(n * share)), api)
    what = "run_%s(n=%d)" % (command, n) if api else "run %s --n %d" % (command, n)
    return check(what, RUN_MEMORY * n, RUN_DISK * n if out else 0,
                 _plus_command(RUN_SECONDS.get(backend, RUN_SECONDS["python"]) * n
                               / cores_for(1)), out, "a smaller %s" % _name("n", api), fit,
                 announce=announce)


#: Bytes a recorded value of :func:`driftfmu.simulate` takes while the master runs (a Python
#: float in a list, then its place in the result array).
SIMULATE_VALUE = 40
#: Seconds per communication point of :func:`driftfmu.simulate` (per FMU; the Python FMUs).
SIMULATE_SECONDS = 3e-4


def check_simulate(n_steps, columns, fmus, stop_time, step_size, backend="python"):
    """The size check of :func:`driftfmu.simulate`: ``columns`` values recorded at each of
    ``n_steps`` communication points of ``fmus`` FMUs."""
    def fit(share):
        return "at most about %d communication points (an earlier stop_time or a longer " \
               "step_size)" % max(1, int(n_steps * share))
    return check("simulate(stop_time=%r, step_size=%r), recording %d values at each of %d "
                 "communication points," % (stop_time, step_size, columns, n_steps),
                 SIMULATE_VALUE * float(columns) * n_steps, 0,
                 SIMULATE_SECONDS * fmus * n_steps / (20 if backend == "native" else 1), None,
                 "fewer output variables or FMUs", fit, announce=False)


#: Bytes of memory per sample of one set of ``experiment adxl203`` in a worker (the recorded
#: columns, the reference and the comparison; measured ~250).
ADXL203_MEMORY = 300
#: Memory of one worker of ``experiment adxl203`` (its Python, NumPy, the FMUs loaded), bytes.
ADXL203_WORKER_MEMORY = 150e6
#: Seconds of one worker per co-simulation step of a set of ``experiment adxl203``,
#: identification and validation included, by backend (~1.6e-5 and ~4e-7 measured), and
#: the command's own seconds on one core (start-up, the two figures, files).
ADXL203_SECONDS = {"python": 1.4e-5, "native": 5e-7}
ADXL203_COMMAND_SECONDS = 3.0
#: Bytes ``experiment adxl203`` writes (tables, summary, figures).
ADXL203_DISK = 2e6


def check_adxl203(freqs, sets, n, workers, out, backend="python", api=False, announce=True):
    """The size check of ``driftfmu experiment adxl203`` (``api``: of
    :func:`driftfmu.experiment_adxl203`): ``sets`` sets of ``n`` samples at each of
    ``freqs`` frequencies, as many at once as there are workers."""
    total = len(freqs) * sets
    at_once = parallel(workers, total)

    def fit(share):
        return "at most %s" % _setting("n", max(1, int(n * share)), api)
    at = "%d frequenc%s" % (len(freqs), "y" if len(freqs) == 1 else "ies")
    what = ("experiment_adxl203(sets=%d, n=%d) at %s" % (sets, n, at) if api
            else "experiment adxl203 --sets %d --n %d at %s" % (sets, n, at))
    return check(what, (ADXL203_WORKER_MEMORY + ADXL203_MEMORY * n) * at_once,
                 ADXL203_DISK if out else 0,
                 _plus_command(ADXL203_SECONDS.get(backend, ADXL203_SECONDS["python"]) * total
                               * n / cores_for(at_once), ADXL203_COMMAND_SECONDS),
                 out, "a smaller %s or fewer %s" % (_name("n", api), _name("workers", api)),
                 fit, announce=announce)


#: Bytes of memory per run and sweep point of ``experiment dual-axis``'s batch engine (the
#: finals of every run gathered; measured ~400).
DUAL_BATCH_MEMORY = 500
#: Bytes of memory per sample of each run of ``experiment dual-axis``'s FMU engine (every
#: run's recorded columns are kept for the check against models/; measured ~900).
DUAL_FMU_MEMORY = 1000
#: Seconds per run and sample of ``experiment dual-axis`` on one core: the FMU engine by
#: backend (five FMU instances and the check against models/; ~2e-4 and ~5e-6 measured), the
#: batch engine (the compiled kernel, ~3.5e-7; NumPy is about ten times slower).
DUAL_SECONDS = {"python": 2e-4, "native": 1e-5, "batch": 3.5e-7}
#: Bytes ``experiment dual-axis`` writes (table, summary, figure).
DUAL_DISK = 1e6


def check_dual_axis(points, runs, n, engine, workers, out, backend="python", api=False,
                    announce=True):
    """The size check of ``driftfmu experiment dual-axis`` (``api``: of
    :func:`driftfmu.experiment_dual_axis`): two sweeps of ``points`` points of ``runs`` runs of
    ``n`` samples."""
    total = 2 * points * runs
    cores = parallel(workers, total)
    memory = DUAL_BATCH_MEMORY * total if engine == "batch" else DUAL_FMU_MEMORY * total * n
    seconds = DUAL_SECONDS.get("batch" if engine == "batch" else backend,
                               DUAL_SECONDS["python"]) * total * n / cores_for(cores)
    seconds = _plus_command(seconds)

    def fit(share):
        if runs * share >= 1:
            return "at most %s" % _setting("runs", int(runs * share), api)
        if engine == "batch":
            return "at most %s at %s" % (_setting("points", max(1, int(points * runs * share)),
                                                  api), _setting("runs", 1, api))
        return "at most %s at %s" % (_setting("n", max(1, int(n * runs * share)), api),
                                     _setting("runs", 1, api))
    what = ("experiment_dual_axis(points=%d, runs=%d, n=%d, engine=%r)" % (points, runs, n,
                                                                           engine)
            if api else "experiment dual-axis --points %d --runs %d --n %d --engine %s"
            % (points, runs, n, engine))
    return check(what, memory, DUAL_DISK if out else 0, seconds, out, "fewer %s or %s%s" % (
        _name("points", api), _name("runs", api),
        "" if engine == "batch" else ", or a smaller %s" % _name("n", api)), fit,
        announce=announce)


#: Bytes of memory per sample of each run of ``experiment drift-classes`` (the recorded columns
#: of the FMU runs and of the models/ reference they are checked against, ~8 columns of 8 bytes
#: twice, and the block means).
DRIFT_CLASSES_MEMORY = 300
#: Seconds per run and sample of ``experiment drift-classes`` on one core, by backend (three
#: FMU instances, as ``run gaussian``, and the models/ reference on arrays).
DRIFT_CLASSES_SECONDS = {"python": 1.5e-4, "native": 1e-5}
#: Bytes ``experiment drift-classes`` writes (table, summary, figure).
DRIFT_CLASSES_DISK = 1e6


def check_drift_classes(runs, n, workers, out, backend="python", api=False, announce=True):
    """The size check of ``driftfmu experiment drift-classes`` (``api``: of
    :func:`driftfmu.experiment_drift_classes`): every case of
    :data:`driftfmu.simulations.drift_classes.CASES`, ``runs`` runs of ``n`` samples."""
    from driftfmu.simulations.drift_classes import CASES
    total = len(CASES) * runs
    cores = parallel(workers, total)
    memory = DRIFT_CLASSES_MEMORY * total * n
    seconds = DRIFT_CLASSES_SECONDS.get(backend, DRIFT_CLASSES_SECONDS["python"]) * total * n \
        / cores_for(cores) + 1e-4 * total * n
    seconds = _plus_command(seconds)

    def fit(share):
        if runs * share >= 1:
            return "at most %s" % _setting("runs", int(runs * share), api)
        return "at most %s at %s" % (_setting("n", max(2, int(n * runs * share)), api),
                                     _setting("runs", 1, api))
    what = ("experiment_drift_classes(runs=%d, n=%d)" % (runs, n) if api
            else "experiment drift-classes --runs %d --n %d" % (runs, n))
    return check(what, memory, DRIFT_CLASSES_DISK if out else 0, seconds, out,
                 "fewer %s or a smaller %s" % (_name("runs", api), _name("n", api)), fit,
                 announce=announce)


#: Bytes of memory per byte of the CSV recordings ``identify`` reads (the rows as text, then
#: as numbers; measured ~10).
IDENTIFY_MEMORY = 12
#: Seconds per byte of the recordings (reading and fitting; measured ~2e-7).
IDENTIFY_SECONDS = 3e-7


def check_identify(files, out, api=False, announce=True):
    """The size check of ``driftfmu identify`` (``api``: of :func:`driftfmu.identify`): every
    recording is read whole before anything is fitted.  Files that cannot be read count 0
    (reading them says why)."""
    total = 0
    for f in files:
        try:
            total += os.path.getsize(f)
        except (OSError, ValueError):
            pass
    what = ("identify() of %d recording(s), %s of CSV," if api
            else "identify of %d recording(s), %s of CSV,") % (len(files), size(total))
    return check(what, IDENTIFY_MEMORY * total, 0, _plus_command(IDENTIFY_SECONDS * total
                                                                 / cores_for(1)),
                 out, "fewer or shorter recordings", announce=announce)


def check_allan(path, out, api=False, announce=False):
    """The size check of ``driftfmu allan`` on a CSV file (``api``: of :func:`driftfmu.allan`):
    the recording is read whole, as ``identify`` reads one (a file that cannot be read counts
    0; reading it says why)."""
    try:
        total = os.path.getsize(path)
    except (OSError, ValueError):
        total = 0
    what = ("allan() of %s of CSV," if api else "allan of %s of CSV,") % size(total)
    return check(what, IDENTIFY_MEMORY * total, 0, _plus_command(IDENTIFY_SECONDS * total
                                                                 / cores_for(1)),
                 out, "a shorter recording", announce=announce)
