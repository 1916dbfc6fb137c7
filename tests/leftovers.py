"""What a run leaves in a temporary folder, besides what driftfmu keeps there by design."""
import contextlib
import os
import shutil
from pathlib import Path

#: The private folder driftfmu keeps in the temporary folder by design (simulations/folders.py:
#: this user's, mode 0700), and what it keeps there from run to run: the compiled libraries
#: (simulations/trust.py: the batch kernel and the fast master's loop) and the destinations'
#: locks (simulations/output.py).  Anything else in it (a work folder ``driftfmu_*``) is left by
#: a run.
PRIVATE = "driftfmu-%d" % os.geteuid() if hasattr(os, "geteuid") else None
PRIVATE_KEPT = ("libraries", "locks")


def left_in(tmp):
    """The names left in the temporary folder ``tmp``: everything but the private folder, and
    in the private folder everything but what it keeps (named ``driftfmu-<uid>/<name>``)."""
    left = []
    for name in sorted(os.listdir(tmp)):
        path = os.path.join(tmp, name)
        if name != PRIVATE or os.path.islink(path) or not os.path.isdir(path):
            left.append(name)
            continue
        left += ["%s/%s" % (name, inner) for inner in sorted(os.listdir(path))
                 if inner not in PRIVATE_KEPT]
    return left


def copy_libraries(src, dst):
    """The compiled libraries of the private folder of the temporary folder ``src`` into that
    of ``dst`` (made 0700 where missing), each file whole (copied beside, then renamed) and
    only where missing: their names are the SHA-256 of their bytes."""
    if PRIVATE is None:
        return
    src, dst = Path(src) / PRIVATE / "libraries", Path(dst) / PRIVATE / "libraries"
    if not src.is_dir():
        return
    with contextlib.suppress(OSError):
        for folder in (dst.parent, dst):
            with contextlib.suppress(FileExistsError):
                os.mkdir(folder, 0o700)
        for f in src.iterdir():
            if f.is_file() and not f.is_symlink() and not (dst / f.name).exists():
                part = dst / (".%s.part%d" % (f.name, os.getpid()))
                shutil.copy2(f, part)
                os.replace(part, dst / f.name)
