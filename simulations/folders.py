"""Internal (not a stable API; use the functions of driftfmu instead).

Work folders that a killed process does not leave behind for good, removed only when they are
provably the work folders of a process that is gone.

A process removes the folders it made (FMUs extracted, libraries compiled, result files staged)
when it is done with them, and when it ends normally or is stopped by Ctrl-C or by SIGTERM in
the command-line tools.  A process killed outright (SIGKILL, or SIGTERM to a script that set no
handler for it) cannot: its folders stay, and the next process removes them.  What it removes,
and only that:

- **Where.**  The work folders (``driftfmu_*``) live in one private folder per user,
  ``driftfmu-<uid>`` in the temporary folder, which driftfmu makes with mode
  0700 and uses only while it is a real folder (not a symbolic link) owned by the user with no
  permission for anyone else, in a temporary folder that no other user can change on the way
  to it (:func:`driftfmu.simulations.trust.path_problem`: ``/tmp``, sticky, is fine);
  otherwise it refuses, in one line.  Its other folders (:func:`private_subfolder`: the
  compiled libraries, the locks of destinations) are checked the same way and never swept.  Staging folders
  (``.driftfmu-stage-*``, simulations/output.py) live beside their destinations.  Nothing else
  of the temporary folder, and no folder of another user, is looked at.
- **Which.**  :func:`make` writes into each folder a lock file (:data:`LOCK`) holding the
  folder's identity: this host, the folder's real path, its device and inode.  A copy
  (``cp -a``: a new inode), a renamed or moved folder (another path), the same folder seen
  through another mount (an overlay's upper layer: another path and device) or from another
  host does not match its record and is never touched.
- **When.**  The lock file is locked (``flock``) for as long as the process that made it, a
  child it forked, or a program it started that was handed the lock's descriptor lives; the
  kernel releases the lock when they end, however they end.  ``subprocess`` closes every
  descriptor it is not told to pass, so driftfmu starts each program that works in a folder
  (a compiler, the doctor's trial host) with ``pass_fds=held_fds(folder)``
  (:func:`held_fds`): a program still running after its parent was killed keeps the folder.
  (``os.exec*``, ``os.fork`` and ``close_fds=False`` keep the descriptor as they are; a worker
  or program that ends with its parent, by a parent-death signal, lets the folder go as it
  ends.)  A folder is removed only once its lock is free.
- **Half made.**  A process killed inside :func:`make` leaves a folder that is empty or holds
  only the half-made lock file :data:`PART` (no longer locked): nothing that anyone wrote, so it
  is removed too.  A process that finds its half-made folder removed under it makes another.
- **Half removed.**  A folder is removed with its lock file last, so a process killed while it
  removed a folder leaves one that is still provably dead (or empty).

:func:`sweep`, run by the next process that makes such a folder in the same place, removes
them.  Where the platform has no ``flock`` (Windows) or the file system refuses the lock, the
folders are made without it (directly in the temporary folder on Windows) and never swept.
"""
import contextlib
import errno
import json
import os
import secrets
import shutil
import socket
import stat
import tempfile

from driftfmu.simulations import trust
from driftfmu.simulations.errors import UsageError

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

#: The prefix of every temporary folder driftfmu makes (FMUs extracted by the masters, the fast
#: master's loop, the batch kernel and the FMUs built, the doctor's trial): ``driftfmu_*`` in
#: the private folder :func:`parent`.
TEMPORARY = ("driftfmu_",)

#: The lock file in each folder: locked while the folder is in use, holding its identity.
LOCK = ".driftfmu-lock"

#: The lock file while :func:`make` writes it.
PART = LOCK + ".part"

#: In a folder made where the file system refuses the lock: never swept.
UNLOCKED = ".driftfmu-unlocked"

#: Folders made by this process (or by the process it was forked from) -> their lock's file
#: descriptor.
_HELD = {}

#: Folders made by this process in the private folder (which goes when its last folder does).
_PRIVATE = set()

#: (process, folder, prefixes) already swept by this process: once is enough.
_SWEPT = set()


def checkpoint(what):
    """A point of :func:`make`, of a removal or of a results commit (simulations/output.py)
    just before it changes a file or folder: nothing.  A test replaces it to stop the process
    there (tests/test_folders.py, tests/test_commit.py)."""


def _parent_path():
    return os.path.join(tempfile.gettempdir(), "driftfmu-%d" % os.geteuid())


def _open_parent(path, create=True):
    """A descriptor of the private folder ``path`` once checked (made first if missing and
    ``create``; None if missing and not): no one but this user (and root) can change the
    folders on the way to it (:func:`driftfmu.simulations.trust.path_problem`), and it is a
    folder of this user's, not a symbolic link, with no permission for anyone else."""
    allowed = ("allowed: a folder of this user's (uid %d) with mode 0700, which driftfmu makes "
               "where none is, in a temporary folder that no other user can change; remove it "
               "or set TMPDIR to another folder" % os.geteuid())
    above = trust.path_problem(os.path.dirname(path), final=trust.entries_kept)
    if above:
        raise UsageError("the work folder %s cannot be trusted: %s; %s" % (path, above, allowed))
    for _ in range(100):
        try:
            fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
        except FileNotFoundError:
            if not create:
                return None
            with contextlib.suppress(FileExistsError):
                os.mkdir(path, 0o700)
            continue
        except OSError as exc:
            if exc.errno not in (errno.ELOOP, errno.ENOTDIR):
                raise  # (an I/O error: not a usage error)
            what = "is a symbolic link" if os.path.islink(path) else "is not a folder"
            raise UsageError("the work folder %s %s (%s); %s"
                             % (path, what, exc.strerror, allowed)) from None
        st = os.fstat(fd)
        problem = trust.private_problem(st)
        if problem:
            os.close(fd)
            raise UsageError("the work folder %s %s; %s" % (path, problem, allowed))
        if st.st_mode & 0o700 != 0o700:  # made under a umask that took the owner's bits
            os.fchmod(fd, 0o700)
        return fd
    raise OSError("cannot make the work folder %s: it keeps going" % path)


def private_path(name):
    """The path of ``name`` in the private folder (:func:`private_subfolder`)."""
    return os.path.join(_parent_path(), name)


def private_subfolder(name, create=True):
    """A descriptor of the folder ``name`` of the private folder (the compiled libraries, the
    locks of destinations), checked as the private folder is (this user's, mode 0700, not a
    link): made where missing with ``create``, else None where missing.  The name does not
    start with a prefix of :data:`TEMPORARY`: no sweep removes it.  The caller closes it."""
    pfd = _open_parent(_parent_path(), create=create)
    if pfd is None:
        return None
    try:
        for _ in range(100):
            try:
                fd = os.open(name, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW, dir_fd=pfd)
            except FileNotFoundError:
                if not create:
                    return None
                with contextlib.suppress(FileExistsError):
                    os.mkdir(name, 0o700, dir_fd=pfd)
                continue
            except OSError as exc:
                if exc.errno not in (errno.ELOOP, errno.ENOTDIR):
                    raise  # (an I/O error: not a usage error)
                raise UsageError("the work folder %s is not a folder (%s); allowed: a folder "
                                 "of this user's with mode 0700, which driftfmu makes; remove "
                                 "it" % (private_path(name), exc.strerror)) from None
            problem = trust.private_problem(os.fstat(fd))
            if problem:
                os.close(fd)
                raise UsageError("the work folder %s %s; allowed: a folder of this user's "
                                 "with mode 0700, which driftfmu makes; remove it"
                                 % (private_path(name), problem))
            return fd
        raise OSError("cannot make the work folder %s: it keeps going" % private_path(name))
    finally:
        os.close(pfd)


def _same(path, fd):
    """True when ``path`` (not followed) is the folder open as ``fd``."""
    try:
        a, b = os.lstat(path), os.fstat(fd)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def make(prefix, dir=None):
    """A new folder ``prefix*`` in ``dir`` (by default the private folder ``driftfmu-<uid>``
    of the temporary folder, made where missing, refused in one line where unsafe),
    locked for as long as this process (or a child forked from it, or a program handed its
    lock's descriptor: :func:`held_fds`) lives, or until :func:`remove`."""
    if fcntl is None:
        return tempfile.mkdtemp(prefix=prefix, dir=dir)
    for _ in range(100):
        where = _parent_path() if dir is None else os.path.abspath(dir)
        pfd = (_open_parent(where) if dir is None
               else os.open(where, os.O_RDONLY | os.O_DIRECTORY))
        try:
            name = prefix + secrets.token_hex(4)
            try:
                checkpoint("make folder")
                os.mkdir(name, 0o700, dir_fd=pfd)
            except (FileExistsError, FileNotFoundError):  # taken, or the parent went: again
                continue
            if dir is None and not _same(where, pfd):  # not the folder checked: not ours
                with contextlib.suppress(OSError):
                    os.rmdir(name, dir_fd=pfd)
                continue
        finally:
            os.close(pfd)
        folder = os.path.join(where, name)
        fd = _lock(folder)
        if fd is _GONE:  # swept as half made before it was locked: another one
            continue
        if fd is not None:
            _HELD[folder] = fd
        if dir is None:
            _PRIVATE.add(folder)
        return folder
    raise OSError("cannot make a work folder in %s" % where)


#: :func:`_lock`'s answer when the folder was removed under it.
_GONE = object()


def _lock(folder):
    """Lock the new ``folder`` and record its identity in its lock file; the lock's descriptor
    (inheritable: a program started with it keeps the folder in use), None where the
    file system has no lock, :data:`_GONE` when a sweep removed the folder meanwhile."""
    part = os.path.join(folder, PART)
    try:
        checkpoint("make lock file")
        fd = os.open(part, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except FileNotFoundError:
        return _GONE
    except OSError:
        return None  # a folder where nothing can be written: the caller finds out
    try:
        # locked before it has its name: a lock file found under LOCK is always held by a
        # live process or by none
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:  # a sweep holds it: it is removing the folder
        os.close(fd)
        return _GONE
    except OSError:  # no locks here: marked, and never swept
        os.close(fd)
        with contextlib.suppress(OSError):
            os.rename(part, os.path.join(folder, UNLOCKED))
        return None
    try:
        st = os.lstat(folder)
        checkpoint("write lock file")
        os.write(fd, json.dumps(_identity(folder, st)).encode())
        checkpoint("name lock file")
        os.rename(part, os.path.join(folder, LOCK))
    except FileNotFoundError:
        os.close(fd)
        return _GONE
    os.set_inheritable(fd, True)
    return fd


def _identity(folder, st):
    """What a copy, a rename or another view of ``folder`` cannot carry along."""
    return {"made by": "driftfmu", "host": socket.gethostname(),
            "path": os.path.realpath(folder), "dev": st.st_dev, "ino": st.st_ino,
            "pid": os.getpid()}


def _matches(record, folder, st):
    return (isinstance(record, dict) and record.get("made by") == "driftfmu"
            and record.get("host") == socket.gethostname()
            and record.get("path") == os.path.realpath(folder)
            and record.get("dev") == st.st_dev and record.get("ino") == st.st_ino)


@contextlib.contextmanager
def temporary(prefix):
    """``tempfile.TemporaryDirectory(prefix=prefix)`` whose folder a killed process does not
    leave for good: yields a new folder of the private folder (:func:`make`; the folders
    left there by processes killed outright are removed first) and removes it at the end."""
    assert prefix.startswith(TEMPORARY), prefix
    sweep(TEMPORARY)
    folder = make(prefix)
    try:
        yield folder
    finally:
        remove(folder)


def remove(folder, last=()):
    """Remove ``folder`` (made by :func:`make`) and release its lock: its files first, then
    those named in ``last`` in that order, the lock file and the folder (:func:`discard`).
    None when it is gone; else the error that left it (with its lock file: the next
    :func:`sweep` removes it once this process is gone)."""
    error = discard(folder, last)
    release(folder)
    if folder in _PRIVATE:
        _PRIVATE.discard(folder)
        with contextlib.suppress(OSError):  # the last one out; a folder with others stays
            os.rmdir(os.path.dirname(folder))
    return error


def held_fds(*paths):
    """The descriptors of the locks this process holds on the folders (made by :func:`make`)
    that are, or hold, ``paths``: for ``subprocess``'s ``pass_fds``, so that a program started
    there keeps the folder in use for as long as it runs, also after this process is gone
    (``subprocess`` closes every descriptor not passed)."""
    fds = []
    for path in paths:
        path = os.path.abspath(path)
        fds += [fd for folder, fd in list(_HELD.items())
                if (path == folder or path.startswith(folder + os.sep)) and fd not in fds]
    return tuple(fds)


def release(folder):
    """Let go of the lock of ``folder`` (made by this process) without removing it."""
    fd = _HELD.pop(folder, None)
    if fd is not None:
        with contextlib.suppress(OSError):  # (the descriptor is closed whatever it answers)
            os.close(fd)


def discard(folder, last=()):
    """Remove ``folder``'s files, those named in ``last`` after the others in that order, its
    lock file and then the folder: at any point a folder that is left is still provably dead
    (its lock file and record are there) or empty.  None when the folder is gone; else the
    first error (OSError): after one, the files of ``last`` and the lock file stay (so that the
    next :func:`sweep` finds the folder provably dead and finishes the job), the others are
    still tried."""
    keep = set(last) | {LOCK}
    try:
        names = sorted(os.listdir(folder))
    except FileNotFoundError:
        return None
    except OSError as exc:
        return exc
    failed = []

    def note(function, path, info):
        failed.append(info[1] if isinstance(info, tuple) else info)

    for name in names:
        if name in keep:
            continue
        checkpoint("remove " + name)
        path = os.path.join(folder, name)
        try:
            if os.path.isdir(path) and not os.path.islink(path):
                shutil.rmtree(path, onerror=note)
            else:
                os.unlink(path)
        except FileNotFoundError:
            pass
        except OSError as exc:
            failed.append(exc)
    if failed:
        return failed[0]
    for name in list(last) + [LOCK]:
        if name in names:
            checkpoint("remove " + name)
            try:
                os.unlink(os.path.join(folder, name))
            except FileNotFoundError:
                pass
            except OSError as exc:
                return exc
    checkpoint("remove folder")
    try:
        os.rmdir(folder)
    except FileNotFoundError:
        pass
    except OSError as exc:
        return exc
    return None


def _record(folder):
    """The record in ``folder``'s lock file, not followed if a link (JSON; None when empty),
    and the file's status.  OSError or ValueError when it cannot be read as one."""
    with open(os.path.join(folder, LOCK), "rb",
              opener=lambda p, f: os.open(p, f | os.O_NOFOLLOW)) as fh:
        return json.loads(fh.read(65536) or b"null"), os.fstat(fh.fileno())


def claim(folder):
    """A file descriptor holding the lock of ``folder`` when it is provably the work folder of
    a process that is gone: made by :func:`make` on this host at this very path (its record
    matches the folder's real path, device and inode) and its lock held by no process.  None
    otherwise.  The caller closes it (``os.close``) once done."""
    if fcntl is None:
        return None
    try:
        st = os.lstat(folder)
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid():
            return None
        # read and checked before it is opened for writing: another view of the folder (an
        # overlay's layer) is not even copied up
        record, seen = _record(folder)
        if not (stat.S_ISREG(seen.st_mode) and seen.st_uid == os.geteuid()
                and _matches(record, folder, st)):
            return None
        fd = os.open(os.path.join(folder, LOCK), os.O_RDWR | os.O_NOFOLLOW)
    except (OSError, ValueError):
        return None
    try:
        now = os.fstat(fd)
        if (now.st_dev, now.st_ino) != (seen.st_dev, seen.st_ino):
            raise OSError("the lock file changed")
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def made_here(folder):
    """(True, record) when ``folder``'s lock file records this very folder (made by
    :func:`make` at this path on this host: the original, not a copy, a moved folder or another
    view of it), (False, record or None) otherwise; its lock is not looked at."""
    try:
        st = os.lstat(folder)
        record = _record(folder)[0]
    except (OSError, ValueError):
        return False, None
    return _matches(record, folder, st), record if isinstance(record, dict) else None


def _half_made(folder):
    """(True, descriptor or None) when ``folder`` is what a process killed inside :func:`make`
    left: empty, or holding only :data:`PART` that no process locks (its descriptor, locked,
    returned).  (False, None) otherwise."""
    if fcntl is None:
        return False, None
    try:
        st = os.lstat(folder)
        names = os.listdir(folder)
    except OSError:
        return False, None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid():
        return False, None
    if not names:
        return True, None
    if names != [PART]:
        return False, None
    try:
        fd = os.open(os.path.join(folder, PART), os.O_RDWR | os.O_NOFOLLOW)
    except OSError:
        return False, None
    try:
        seen = os.fstat(fd)
        if not (stat.S_ISREG(seen.st_mode) and seen.st_uid == os.geteuid()):
            raise OSError("not a lock file")
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        text = os.pread(fd, 65536, 0)
        if text:  # a record written whole: it must be this folder's
            with contextlib.suppress(ValueError):
                if not _matches(json.loads(text), folder, st):
                    raise OSError("another folder's lock file")
    except OSError:
        os.close(fd)
        return False, None
    return True, fd


def stale(folder):
    """True when ``folder`` is provably left by a process that is gone (:func:`claim`, or half
    made: :func:`_half_made`), so that :func:`sweep` removes it."""
    fd = claim(folder)
    if fd is None:
        half, fd = _half_made(folder)
        if not half:
            return False
    if fd is not None:
        os.close(fd)
    return True


def sweep(prefixes, dir=None, dead=None, other=None, again=False):
    """Remove the folders of ``dir`` (by default the private folder of :func:`make`) named
    with one of ``prefixes`` that are provably left by a process that is gone (:func:`claim`)
    or half made (:func:`_half_made`).  With ``dead``, ``dead(path)`` is called for each of the
    former instead, its lock held, and removes it or not (returning True when it did); with
    ``other``, ``other(path)`` is called for each folder of theirs that is neither (in use, or
    not provably made there: :func:`made_here`).  Once per process and place (``again``: once
    more, after this process's workers were killed: the private folder goes too when that
    leaves it empty); returns the paths removed."""
    if fcntl is None:
        return []
    if dir is None:
        dir = _parent_path()
        fd = _open_parent(dir, create=False)  # refused when unsafe
        if fd is None:
            return []
        os.close(fd)
    dir = os.path.abspath(dir)
    key = (os.getpid(), dir, tuple(prefixes))
    if key in _SWEPT and not again:
        return []
    _SWEPT.add(key)
    removed = []
    try:
        entries = sorted(os.scandir(dir), key=lambda e: e.name)
    except OSError:
        return removed
    for entry in entries:
        try:
            if not (entry.name.startswith(tuple(prefixes)) and entry.is_dir(follow_symlinks=False)
                    and entry.stat(follow_symlinks=False).st_uid == os.geteuid()):
                continue
        except OSError:
            continue
        fd = claim(entry.path)
        if fd is not None:
            try:
                if dead is not None:
                    gone = dead(entry.path)
                else:
                    gone = discard(entry.path) is None
            finally:
                os.close(fd)
        else:
            half, fd = _half_made(entry.path)
            if not half:
                if other is not None:
                    other(entry.path)
                continue
            try:
                if fd is not None:
                    checkpoint("remove " + PART)
                    os.unlink(os.path.join(entry.path, PART))
                checkpoint("remove folder")
                os.rmdir(entry.path)  # only while empty: a folder being made meanwhile stays
                gone = True
            except OSError:
                gone = False
            finally:
                if fd is not None:
                    os.close(fd)
        if gone:
            removed.append(entry.path)
    if again and removed and dir == os.path.abspath(_parent_path()):
        with contextlib.suppress(OSError):  # only while empty: a folder of another stays
            os.rmdir(dir)
    return removed
