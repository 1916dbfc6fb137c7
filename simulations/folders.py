"""Internal (not a stable API; use the functions of driftfmu instead).

Work folders that a killed process does not leave behind for good.

A process removes the folders it made (FMUs extracted, libraries compiled, result files staged)
when it is done with them, and when it ends normally or is stopped by Ctrl-C or by SIGTERM in
the command-line tools.  A process killed outright (SIGKILL, or SIGTERM to a script that set no
handler for it) cannot: its folders stay.  So each folder made by :func:`make` holds a lock
file, locked (``flock``) for as long as the process that made it, or a child it forked, lives;
the kernel releases the lock when they end, however they end.  :func:`sweep`, run by the next
process that makes such a folder in the same place, removes those whose lock nobody holds.

Where the platform has no ``flock`` (Windows) or the file system refuses the lock file, the
folders are made without it and never swept.
"""
import contextlib
import os
import shutil
import tempfile

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

#: The prefix of every temporary folder driftfmu makes (FMUs extracted by the masters, the fast
#: master's loop, the batch kernel and the FMUs built, the doctor's trial): ``driftfmu_*``.  The
#: lock file, not the name, tells a folder that :func:`make` made.
TEMPORARY = ("driftfmu_",)

#: The lock file in each folder.
LOCK = ".driftfmu-lock"

#: Folders made by this process (or by the process it was forked from) -> their lock's file
#: descriptor.
_HELD = {}

#: (process, folder, prefixes) already swept by this process: once is enough.
_SWEPT = set()


def make(prefix, dir=None):
    """A new folder ``prefix*`` in ``dir`` (the temporary folder by default), locked for as long
    as this process lives (or until :func:`remove`)."""
    folder = tempfile.mkdtemp(prefix=prefix, dir=dir)
    if fcntl is not None:
        part = os.path.join(folder, LOCK + ".part")
        try:
            fd = os.open(part, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError:
            return folder
        try:
            # locked before it has its name: a lock file found under LOCK is always held by a
            # live process or by none
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            os.rename(part, os.path.join(folder, LOCK))
        except OSError:
            os.close(fd)
            return folder
        _HELD[folder] = fd
    return folder


@contextlib.contextmanager
def temporary(prefix):
    """``tempfile.TemporaryDirectory(prefix=prefix)`` whose folder a killed process does not
    leave for good: yields a new folder of the temporary folder (:func:`make`; the folders
    left there by processes killed outright are removed first) and removes it at the end."""
    assert prefix.startswith(TEMPORARY), prefix
    sweep(TEMPORARY)
    folder = make(prefix)
    try:
        yield folder
    finally:
        remove(folder)


def remove(folder):
    """Remove ``folder`` (made by :func:`make`) and release its lock."""
    shutil.rmtree(folder, ignore_errors=True)
    fd = _HELD.pop(folder, None)
    if fd is not None:
        os.close(fd)


def stale(folder):
    """True when ``folder`` holds a lock file that no live process holds (its maker is gone)."""
    if fcntl is None:
        return False
    try:
        fd = os.open(os.path.join(folder, LOCK), os.O_RDWR)
    except OSError:  # no lock file (being made, or not ours): not stale
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    finally:
        os.close(fd)
    return True


def sweep(prefixes, dir=None, keep=None):
    """Remove the folders of ``dir`` (the temporary folder by default) named with one of
    ``prefixes``, owned by this user and :func:`stale`; leave those for which ``keep(path)`` is
    true.  Once per process and place; returns the paths removed."""
    if fcntl is None:
        return []
    dir = os.path.abspath(dir or tempfile.gettempdir())
    key = (os.getpid(), dir, tuple(prefixes))
    if key in _SWEPT:
        return []
    _SWEPT.add(key)
    removed = []
    try:
        entries = list(os.scandir(dir))
    except OSError:
        return removed
    for entry in entries:
        try:
            if not (entry.name.startswith(tuple(prefixes)) and entry.is_dir(follow_symlinks=False)
                    and entry.stat(follow_symlinks=False).st_uid == os.getuid()):
                continue
        except OSError:
            continue
        if stale(entry.path) and not (keep is not None and keep(entry.path)):
            shutil.rmtree(entry.path, ignore_errors=True)
            removed.append(entry.path)
    return removed
