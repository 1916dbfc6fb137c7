"""Internal (not a stable API; use driftfmu.identify instead).

The number of threads of the BLAS library NumPy calls (OpenBLAS), for a computation whose bits
must not depend on the machine.

OpenBLAS runs one thread per core by default and splits a long dot product (``r @ r`` over the
60,000 samples of a set) between them, adding the partial sums in another order: the last bits
of the result then depend on the core count (a fit of the same data once gave another ``R`` on
a 2-core machine than on a 1-core one), and they depend on the processor too, whose kernels
OpenBLAS picks.  So :func:`identify.fit_set <driftfmu.models.identify.fit_set>` calls no BLAS
at all.  In worker processes (one per core already) one thread is the fast choice: several BLAS
threads per worker oversubscribe the cores.  :func:`threads` sets the count for a block and
restores it after.

The libraries are found in ``/proc/self/maps`` (Linux); elsewhere, or with another BLAS, nothing
is changed.
"""
import contextlib
import ctypes

_FOUND = []


def libraries():
    """``(set, get)`` of the thread count of every OpenBLAS loaded in this process (NumPy's,
    SciPy's), found once; empty where none can be found."""
    if _FOUND:
        return _FOUND[0]
    found, seen = [], set()
    try:
        with open("/proc/self/maps") as fh:
            paths = [p[5].strip() for p in (line.split(None, 5) for line in fh)
                     if len(p) == 6 and "openblas" in p[5].lower()]
    except OSError:
        paths = []
    for path in paths:
        if path in seen:
            continue
        seen.add(path)
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in ("scipy_", ""):
            for suffix in ("64_", ""):
                set_ = getattr(lib, "%sopenblas_set_num_threads%s" % (prefix, suffix), None)
                get = getattr(lib, "%sopenblas_get_num_threads%s" % (prefix, suffix), None)
                if set_ is not None and get is not None:
                    set_.argtypes, set_.restype = [ctypes.c_int], None
                    get.argtypes, get.restype = [], ctypes.c_int
                    found.append((set_, get))
                    break
            else:
                continue
            break
    _FOUND.append(found)
    return found


def counts():
    """The thread count of every OpenBLAS of this process, as :func:`libraries` lists them."""
    return [get() for _, get in libraries()]


def set_threads(n):
    """Run every OpenBLAS of this process with ``n`` threads from now on."""
    for set_, _ in libraries():
        set_(n)


@contextlib.contextmanager
def threads(n):
    """A block in which every OpenBLAS of this process runs ``n`` threads; the counts of
    before are restored after it."""
    libs = libraries()
    before = [get() for _, get in libs]
    for set_, _ in libs:
        set_(n)
    try:
        yield
    finally:
        for (set_, _), count in zip(libs, before):
            set_(count)
