"""Internal (not a stable API; use the driftfmu command instead).

Size checks before a run starts: memory, disk and time, estimated from the settings.

A run that cannot fit this machine is refused (a usage error, exit 2: one line with the
estimate, what the machine has, and how to proceed) before anything runs; a long or large one
is announced on standard error first.  The estimates are per sample (or per run and sample)
costs measured on the default settings (``per_*`` below), rounded up; they are meant to tell
a 56 GB run from a 56 MB one, not to be exact.
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
#: Seconds per run and sample of the batch engine on one core (measured ~5e-6 under load).
MONTECARLO_SECONDS = 5e-6
#: Bytes of memory per run of ``sweep`` (seeds, per-run parameters, the final estimates of each
#: run gathered and concatenated, the references; measured ~153 over 6 million runs).
SWEEP_MEMORY = 200
#: Bytes written per run by ``sweep`` (sweep.npz: 5 or 6 float64 per run).
SWEEP_DISK = 6 * 8
#: Seconds per run and sample of ``sweep``'s batch engine on one core (NumPy ~1e-7, the compiled
#: kernel ~2e-8).
SWEEP_SECONDS = 1e-7
#: Bytes of memory per sample of one co-simulation (``run``): the recorded columns, the models/
#: reference run and the comparison (measured ~1.4 kB).
RUN_MEMORY = 1500
#: Bytes written per sample by ``run`` (results.csv, 12 columns at 17 significant digits).
RUN_DISK = 250
#: Seconds per sample of one co-simulation of the Python FMUs (measured ~1 ms under load; the
#: native FMUs are faster).
RUN_SECONDS = 1e-3
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
            return "%.3g %s" % (n / scale, unit)
    return "%d B" % n


def duration(seconds):
    """Seconds for people: ``"3 s"``, ``"12 min"``, ``"28 h"``."""
    if seconds < 90:
        return "%.0f s" % seconds
    if seconds < 5400:
        return "%.0f min" % (seconds / 60)
    return "%.0f h" % (seconds / 3600)


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


def check_montecarlo(command, runs, n, workers, out, summary_only=False):
    """The size check of ``driftfmu montecarlo``: every trajectory of every run is kept, or
    (``summary_only``) per-run summaries and the figure's runs' trajectories."""
    cores = max(1, workers or os.cpu_count() or 1)
    what = "montecarlo %s --runs %d --n %d%s" % (command, runs, n,
                                                " --summary-only" if summary_only else "")
    seconds = MONTECARLO_SECONDS * runs * n / cores
    if summary_only:
        from driftfmu.simulations.montecarlo import FIGURE_RUNS
        kept = min(runs, FIGURE_RUNS)
        # workers hold their chunk's trajectories while they reduce them
        chunk = min(runs, 4096) * min(cores, 2)
        memory = MONTECARLO_MEMORY * (kept + chunk) * n + SUMMARY_BYTES * runs
        disk = (MONTECARLO_DISK * kept * n + SUMMARY_BYTES * runs) if out else 0

        def fit_summaries(share):
            # the trajectories kept grow with --n, the summaries with --runs: name the largest
            # --runs at this --n when it is the runs that do not fit
            room = share * memory - MONTECARLO_MEMORY * (kept + chunk) * n
            if room >= SUMMARY_BYTES:
                return "at most --runs %d at --n %d" % (room // SUMMARY_BYTES, n)
            return "a smaller --n"
        return check(what, memory, disk, seconds, out, "fewer --runs or a smaller --n",
                     fit_summaries)

    def fit(share):
        return "at most --runs %d at --n %d" % (max(1, int(runs * share)), n)
    return check(what, MONTECARLO_MEMORY * runs * n, MONTECARLO_DISK * runs * n if out else 0,
                 seconds, out,
                 "--summary-only, which keeps per-run summaries instead of trajectories; or "
                 "fewer --runs or a smaller --n", fit)


def check_sweep(points, runs, n, workers, out, announce=True):
    """The size check of ``driftfmu sweep`` (and :func:`driftfmu.sweep`): ``points`` grid
    points of ``runs`` runs of ``n`` samples; each run keeps its final estimates only, so the
    memory grows with the runs, not with ``n``."""
    cores = max(1, workers or os.cpu_count() or 1)
    total = points * runs

    def fit(share):
        return "at most --runs %d for the %d grid points" % (max(1, int(runs * share)), points)
    return check("sweep of %d grid points x --runs %d --n %d" % (points, runs, n),
                 SWEEP_MEMORY * total, SWEEP_DISK * total if out else 0,
                 SWEEP_SECONDS * total * n / cores, out, "fewer grid points", fit,
                 announce=announce)


def check_run(command, n, out, backend="python"):
    """The size check of ``driftfmu run``: one co-simulation of ``n`` samples, every sample
    recorded (results.csv)."""
    def fit(share):
        return "at most --n %d" % max(1, int(n * share))
    return check("run %s --n %d" % (command, n), RUN_MEMORY * n, RUN_DISK * n if out else 0,
                 RUN_SECONDS * n / (20 if backend == "native" else 1), out,
                 "a smaller --n",
                 fit)
