"""Internal (not a stable API; use the out= of the functions of driftfmu instead).

Writing results whole or not at all, and the plots.

Files are written into a hidden staging folder beside the destination and moved into place only
when every file of the set has been written (:class:`Staging`, :func:`staged`).  The moves are
one commit: after an error or Ctrl-C during them the destination is as it was, and after a
SIGKILL at any instant the next run that stages results there completes the commit
(:func:`recover`), so the destination holds its complete old files or its complete new ones.

The commit, step by step (each step one rename, write or removal; :func:`folders.checkpoint`
before each):

1. every staged file is written to disk (``fsync``), and so is each staging folder's record;
2. the commit takes the lock of each of its destinations (one writer at a time: a second
   driftfmu process committing into the same place waits for the first, saying so in one
   line, at most :data:`WAIT` seconds; :func:`destinations_locked`), and plans its moves;
3. each staging folder but the first gets :data:`MEMBER`, naming the commit and its first
   folder;
4. the first staging folder gets :data:`JOURNAL`: every folder to make, every file in the way
   to move aside into its staging folder (``.replaced-N``) and every staged file to move in,
   each with the device and inode it has.  From here on the commit is recorded;
5. the moves, in the journal's order.  Once the last is done the results are in place: the
   commit is decided, and what follows cannot make the run fail;
6. the folders the moves changed are written to disk, and the journal becomes :data:`DONE`;
7. the staging folders go, the first one last, each with its bookkeeping files last.

A process killed before step 4 leaves staging folders without a journal: the next run removes
them (they hold only the staged files of a run that never committed), and the destination has
its old files.  Killed in steps 4 to 6: the next run completes the moves from the journal,
each one only where the file is still the one the journal names (a rename keeps the inode;
anything else stops the recovery, keeps every folder and says so); then steps 6 and 7.  Killed
in 7: the next run removes what is left.  An error or Ctrl-C in step 5 rolls the moves back at
once (the journal first says so, so that a kill during the roll-back is rolled back by the next
run too; a second Ctrl-C or SIGTERM waits until the roll-back is done).  Each recovery says
what it did in one line (a :class:`CommitRecovered` warning: ``driftfmu: warning: ...`` from
the command line).  A staging folder is removed only when :func:`folders.claim` proves it a
dead process's, and never while it holds a file that a commit still needs.

What the caller is told is what happened.  Before step 5 every error, an ``fsync`` that fails
included, fails the commit (:class:`CommitFailed` or the error) and changes nothing of the
destination.  An error in step 5 fails it too, after the roll-back; when the roll-back fails as
well, the message says where the files of before are kept and that the next run puts them
back (the journal and the staging folders stay for it).  After step 5 the commit succeeds: an
error in steps 6 and 7 is a :class:`CommitLeftovers` warning naming what is left and how it
goes (the next run there removes it, or ``rm -r``), and what holds a file of before always
keeps the bookkeeping (its lock file and the journal or its done mark) that lets the next run
finish the job.
"""
import contextlib
import errno
import hashlib
import json
import os
import secrets
import signal
import stat
import threading
import time
import warnings
from pathlib import Path

from driftfmu.simulations import folders
from driftfmu.simulations.errors import UsageError

#: The prefix of the hidden staging folders.
STAGE = ".driftfmu-stage-"

#: In the first staging folder of a commit, from the moment it is decided until every file is
#: in place: the commit's steps (JSON).
JOURNAL = ".driftfmu-journal"

#: The journal once every file is in place: what the staging folders still hold is not needed.
DONE = ".driftfmu-done"

#: In each other staging folder of a commit: the commit and its first folder (JSON).
MEMBER = ".driftfmu-commit"

#: The bookkeeping files, removed after the rest of a staging folder.
BOOKKEEPING = (MEMBER, JOURNAL, DONE)

#: The folder of the destinations' locks, in the private folder of the work folders.
LOCKS = "locks"

#: Seconds a commit waits for another process's commit into one of its destinations.
WAIT = 600.0

#: The commits this process has put in place (one number in a list): the command line tells
#: an error after them from one before.
COMMITS = [0]


class CommitRecovered(UserWarning):
    """A results commit that a killed process left unfinished was completed or rolled back,
    or could not be and its staging folders are kept (the message says which)."""


class CommitLeftovers(UserWarning):
    """The results are in place, but something of the commit's bookkeeping could not be
    removed or written to disk: the message names it and how it goes."""


class DestinationBusy(UserWarning):
    """Another process is moving its results into a destination of this commit: this one
    waits for it (at most :data:`WAIT` seconds)."""


class CommitFailed(OSError):
    """The results could not be moved into place (the message says why and what is left)."""


class _Conflict(OSError):
    """A file of a commit is not the one its journal names: the commit stops there."""


def nearest_existing(path):
    """``path`` if it exists, else its nearest parent that does (a folder, or a file in the
    way of the folders to make)."""
    path = Path(path)
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def probe(folder):
    """Make a staging folder in ``folder`` and remove it: OSError when none can be made there
    (a folder that cannot be written, a read-only file system, for root too).  A process
    killed in between leaves a staging folder that the next staging there removes."""
    folders.remove(folders.make(STAGE, dir=folder))


class Staging:
    """All the outputs of one job, or none of them (``driftfmu build``: FMUs, native FMUs,
    cross-check folders, the SSP archive; a master's result folder, through :func:`staged`).

    :meth:`path` hands out a staged stand-in for each destination, a hidden folder
    ``.driftfmu-stage-*`` in the destination's nearest existing folder (the same file system,
    so the move is a rename); the job writes there.  Leaving the ``with`` block normally commits
    every staged file into place (the module's steps); an exception or interrupt in the block
    removes the staged files, and one during the moves rolls them back: the files moved in go
    back, those they replaced return, the folders made for them go when empty.  A process
    killed outright leaves its staging folders to the next :meth:`path` in or above the same
    place (:func:`recover`).  ``committed`` is True once every output is in place.
    """

    def __init__(self):
        self._pairs = []  # (hidden folder, staged path, destination)
        self._shown = []  # (staged path, destination as given): for the log's lines
        self._held = []   # (log, line) of the lines about written files, until the commit
        self._open = False  # a journal is written and the commit neither done nor rolled back
        self.committed = False

    def path(self, target, folder=True):
        """The staged stand-in for ``target`` (a folder, or with ``folder=False`` a file).
        First the commits that killed processes left unfinished in the places of ``target``
        (its folder and the folders above it) are completed or rolled back (:func:`recover`).

        A ``target`` that is an existing folder where a file is asked for (the commit would
        move the folder aside and remove it with everything in it), an existing file where a
        folder is asked for, or a path under an existing file, is a UsageError: nothing is
        staged."""
        shown = Path(target)
        target = shown.absolute()
        anchor = target if folder else target.parent
        existing = nearest_existing(anchor)
        if not existing.is_dir():
            raise UsageError("%s: %s is an existing file; allowed: %s" % (
                shown, existing, "a folder (created if missing)" if folder
                else "a file path in a folder"))
        if not folder and target.is_dir():
            raise UsageError("%s is an existing folder; allowed: a file path (an existing file "
                             "is replaced; a folder is not)" % shown)
        recover(anchor)
        stage = Path(folders.make(STAGE, dir=existing))
        staged = stage / target.name
        self._pairs.append((stage, staged, target))
        self._shown.append((staged, shown))
        return staged

    def log(self, log):
        """``log`` with the staged paths in its lines named by their destinations; a line
        naming a staged path (what was written: "built ...") is held back until every output
        is in place, so a job that fails names no file it leaves behind."""
        def staged_log(line):
            held = False
            for staged, shown in self._shown:
                held = held or str(staged) in line
                line = line.replace(str(staged), str(shown))
            if held:
                self._held.append((log, line))
            else:
                log(line)
        return staged_log

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        try:
            if kind is None:
                self._commit()
        finally:
            stages = [str(stage) for stage, _, _ in self._pairs]
            if self._open:  # left for the next run, which finishes the commit
                for stage in stages:
                    folders.release(stage)
            else:  # the first one last: while it is there, so is the commit's record
                left = []
                for stage in stages[1:] + stages[:1]:
                    error = folders.remove(stage, last=BOOKKEEPING)
                    if error is not None:
                        left.append((stage, error))
                for stage, error in left:
                    _leftover(stage, error, self.committed)
        if kind is None:  # (and the commit did not raise): every output is in place
            for log, line in self._held:
                log(line)
        return False

    def _plan(self):
        """The commit's steps: ("mkdir", folder), ("aside", file in the way, where it goes,
        its [device, inode]), ("in", staged file, destination, its [device, inode])."""
        steps, made, asides = [], set(), {}
        for stage, staged, target in self._pairs:
            if staged.is_dir() and not staged.is_symlink():
                files = sorted(p for p in staged.rglob("*") if p.is_symlink() or not p.is_dir())
            else:
                files = [staged] if _exists(staged) else []
            for f in files:
                dest = target / f.relative_to(staged) if f != staged else target
                missing = []
                top = dest.parent
                while not _exists(top) and top != top.parent:
                    missing.append(top)
                    top = top.parent
                for d in reversed(missing):
                    if d not in made:
                        made.add(d)
                        steps.append(["mkdir", str(d)])
                if _exists(dest):
                    n = asides.get(stage, 0)
                    asides[stage] = n + 1
                    steps.append(["aside", str(dest), str(stage / (".replaced-%d" % n)),
                                  _inode(dest)])
                steps.append(["in", str(f), str(dest), _inode(f)])
        return steps

    def _commit(self):
        stages = [str(stage) for stage, _, _ in self._pairs]
        for stage in stages:  # the staged files and the records that prove the folders ours
            _sync_tree(stage)
            fd = folders._HELD.get(stage)  # noqa: SLF001 (the lock this process holds)
            if fd is not None:
                _sync(fd)
        targets = [str(t) for _, _, t in self._pairs]
        with destinations_locked(targets):
            steps = self._plan()
            if not steps:
                self.committed = True
                COMMITS[0] += 1
                return
            commit = {"commit of": targets, "id": secrets.token_hex(8),
                      "stages": [os.path.realpath(s) for s in stages], "state": "forward",
                      "steps": steps}
            for stage in stages[1:]:
                _write_json(os.path.join(stage, MEMBER),
                            {"id": commit["id"], "first": commit["stages"][0]})
            journal = os.path.join(stages[0], JOURNAL)
            _write_json(journal, commit)
            self._open = True
            try:
                _forward(steps)
            except BaseException as exc:
                self._roll_back(commit, journal, steps, exc)
                raise
            # every new file is in place: decided; nothing from here on fails the commit
            self.committed = True
            COMMITS[0] += 1
            what = ", ".join(targets)
            try:
                _sync_moved(steps)
            except OSError as exc:
                _warn("the results are in place in %s, but the folders the commit changed could "
                      "not be written to disk (%s); its journal is kept in %s, so the next "
                      "driftfmu run there completes it even after a power loss"
                      % (what, _reason(exc), stages[0]), CommitLeftovers)
                return  # (self._open: the staging folders stay for that run)
            try:
                folders.checkpoint("journal done")
                os.rename(journal, os.path.join(stages[0], DONE))
            except OSError as exc:
                _warn("the results are in place in %s; the commit's journal could not be marked "
                      "done (%s), so its staging folders %s stay until the next driftfmu run "
                      "there removes them (or rm -r %s)" % (
                          what, _reason(exc), ", ".join(stages), " ".join(stages)),
                      CommitLeftovers)
                return
            self._open = False
            with contextlib.suppress(OSError):  # a done mark lost to a power loss: the next
                _sync_dir(stages[0])            # run finds the journal, every move done

    def _roll_back(self, commit, journal, steps, first):
        """Move the files of ``steps`` back after ``first`` (the error or interrupt that
        stopped the moves); raise :class:`CommitFailed` when that fails too (the journal and
        the staging folders stay: the next run finishes the roll-back)."""
        what = ", ".join(commit["commit of"])
        with _interrupts_held():
            commit["state"] = "back"
            try:
                _write_json(journal, commit)
                recorded = True
            except OSError:  # the roll-back goes on: killed now, the next run completes instead
                recorded = False
            try:
                _back(steps)
            except (OSError, KeyboardInterrupt) as exc:
                raise CommitFailed(
                    "the results could not be moved into %s (%s), and moving the files of "
                    "before back failed too (%s): they are kept in %s until the next driftfmu "
                    "run there %s" % (what, _reason(first), _reason(exc),
                                      ", ".join(commit["stages"]),
                                      "puts them back" if recorded else
                                      "completes this commit (its journal could not be "
                                      "changed)")) from first
            # every file as it was: nothing left to finish
            try:
                os.rename(journal, os.path.join(os.path.dirname(journal), DONE))
            except OSError:
                try:
                    os.unlink(journal)
                except OSError as exc:
                    raise CommitFailed(
                        "the results could not be moved into %s (%s) and were moved back, but "
                        "the commit's journal %s could not be removed (%s): remove its staging "
                        "folders (rm -r %s) before the next driftfmu run there" % (
                            what, _reason(first), journal, _reason(exc),
                            " ".join(commit["stages"]))) from first
            self._open = False
        if isinstance(first, OSError):
            raise CommitFailed("the results could not be moved into %s (%s); it is as it was "
                               "before this run" % (what, _reason(first))) from first


def _reason(exc):
    """An error in a few words: an OSError's file and reason, else its text."""
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    if isinstance(exc, OSError) and exc.strerror:
        return "%s: %s" % (exc.filename, exc.strerror) if exc.filename else exc.strerror
    return str(exc) or type(exc).__name__


def _warn(text, category):
    warnings.warn(text, category, stacklevel=3)


def _leftover(stage, error, committed):
    """Say that the staging folder ``stage`` could not be removed (``error``) and how it goes."""
    _warn("%s%s could not be removed (%s): the next driftfmu run there removes it, or rm -r %s"
          % ("the results are in place; their staging folder " if committed
             else "the staging folder ", stage, _reason(error), stage), CommitLeftovers)


@contextlib.contextmanager
def _interrupts_held(signals=(signal.SIGINT, signal.SIGTERM)):
    """Hold SIGINT and SIGTERM (those handled in Python) back for the block: a second Ctrl-C
    during a roll-back lands once the files of before are back (its handler is called then)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending, held = [], {}
    for s in signals:
        h = signal.getsignal(s)
        if callable(h):
            try:
                signal.signal(s, lambda signum, frame: pending.append(signum))
                held[s] = h
            except (OSError, ValueError):  # not held: the block runs all the same
                pass
    try:
        yield
    finally:
        for s, h in held.items():
            with contextlib.suppress(OSError, ValueError):
                signal.signal(s, h)
    if pending:  # (an error in the block wins: it says what is left)
        held[pending[0]](pending[0], None)


# -- one writer at a time ------------------------------------------------------------------

def destination_key(target):
    """What names the destination ``target`` for its lock: the real path of its nearest
    existing folder (links resolved) joined with the rest of the path."""
    target = os.path.abspath(target)
    existing = str(nearest_existing(target))
    rest = os.path.relpath(target, existing)
    return os.path.normpath(os.path.join(os.path.realpath(existing), rest))


def _holder(fd):
    try:
        record = json.loads(os.pread(fd, 4096, 0) or b"null")
        return " (process %d)" % record["pid"]
    except (OSError, ValueError, TypeError, KeyError):
        return ""


def _lock_destination(dir_fd, key, wait):
    """The descriptor holding the lock of the destination ``key`` (a file of the locks
    folder ``dir_fd``, named by the key's hash), once no other process holds it; a
    :class:`DestinationBusy` line while it waits, :class:`CommitFailed` after ``wait``
    seconds."""
    name = hashlib.sha256(key.encode()).hexdigest()[:32]
    deadline = None
    while True:
        fd = os.open(name, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600,
                     dir_fd=dir_fd)
        try:
            folders.fcntl.flock(fd, folders.fcntl.LOCK_EX | folders.fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            if deadline is None:
                deadline = time.monotonic() + wait
                if wait > 0:
                    _warn("%s: another driftfmu run%s is moving its results into it; this one "
                          "waits for it (at most %s)" % (key, holder, _seconds(wait)),
                          DestinationBusy)
            if time.monotonic() >= deadline:
                raise CommitFailed("%s: another driftfmu run%s is moving its results into it%s; "
                                   "this run's results are not written (allowed: one run at a "
                                   "time into one place)" % (
                                       key, holder, " for %s" % _seconds(wait) if wait else ""))
            time.sleep(0.02)
            continue
        try:  # still the file of that name (a holder removes it as it lets go)
            same = os.stat(name, dir_fd=dir_fd, follow_symlinks=False).st_ino == \
                os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if not same:
            os.close(fd)
            continue
        record = json.dumps({"pid": os.getpid(), "destination": key}).encode()
        os.ftruncate(fd, 0)
        os.pwrite(fd, record, 0)
        return fd, name


def _seconds(s):
    return "%g s" % s if s < 120 else "%g min" % (s / 60.0)


@contextlib.contextmanager
def destinations_locked(targets, wait=None):
    """Hold the lock of each destination of ``targets`` (:func:`destination_key`; in the
    ``locks`` folder of the private folder, in the order of their keys) for the block:
    another process committing into one of them meanwhile waits (see
    :func:`_lock_destination`; ``wait``: default :data:`WAIT`)."""
    if folders.fcntl is None:
        yield
        return
    wait = WAIT if wait is None else wait
    keys = sorted({destination_key(t) for t in targets})
    dir_fd = folders.private_subfolder(LOCKS)
    held = []
    try:
        for key in keys:
            held.append(_lock_destination(dir_fd, key, wait))
        yield
    finally:  # (an error here cannot undo what the block did: the kernel lets go anyway)
        for fd, name in reversed(held):
            with contextlib.suppress(OSError):
                os.unlink(name, dir_fd=dir_fd)
            with contextlib.suppress(OSError):
                os.close(fd)
        with contextlib.suppress(OSError):
            os.close(dir_fd)


def _inode(path):
    st = os.lstat(path)
    return [st.st_dev, st.st_ino]


def _lstat(path):
    """``os.lstat(path)``, or None where nothing is there; any other error (an I/O error) is
    raised: a commit never takes a file it cannot see for one that is not there."""
    try:
        return os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None


def _exists(path):
    """True when something is at ``path`` (not followed); an error other than its absence is
    raised (:func:`_lstat`)."""
    return _lstat(path) is not None


def _is_dir(path):
    """True when ``path`` (not followed) is a folder; an error other than its absence is
    raised (:func:`_lstat`)."""
    st = _lstat(path)
    return st is not None and stat.S_ISDIR(st.st_mode)


def _is(path, inode):
    """True when ``path`` (not followed) is the file with ``inode`` ([device, inode]); an
    error other than its absence is raised (:func:`_lstat`)."""
    st = _lstat(path)
    return st is not None and [st.st_dev, st.st_ino] == list(inode)


def _forward(steps):
    """Do the steps not done yet (each only where its file is the one named): the number of
    moves done now (the folders made are no moves).  A file that is not the one named raises
    :class:`_Conflict`."""
    done = 0
    for step in steps:
        if step[0] == "mkdir":
            if not _is_dir(step[1]):
                folders.checkpoint("mkdir")
                os.mkdir(step[1])
        elif step[0] == "aside":
            _, dest, aside, inode = step
            if _is(aside, inode) or not _exists(dest):
                continue  # moved aside before (or gone: nothing to keep)
            if not _is(dest, inode):
                if any(s[0] == "in" and s[2] == dest and _is(dest, s[3]) for s in steps):
                    continue  # the new file is in place already
                raise _Conflict("%s is not the file that was there" % dest)
            folders.checkpoint("aside")
            os.replace(dest, aside)
            done += 1
        else:
            _, staged, dest, inode = step
            if _is(dest, inode):
                continue
            if not _is(staged, inode):
                raise _Conflict("the staged file %s is gone" % staged)
            if _exists(dest):
                raise _Conflict("%s is in the way" % dest)
            folders.checkpoint("in")
            os.replace(staged, dest)
            done += 1
    return done


def _back(steps):
    """Undo the steps done (each only where its file is the one named), last first.  A move
    back goes to a free name (checked), so it is a rename.  A folder made that is not empty
    stays (it holds someone else's file); one that cannot be removed for another reason is an
    error."""
    for step in reversed(steps):
        if step[0] == "mkdir":
            if _is_dir(step[1]):
                folders.checkpoint("rmdir")
                try:
                    os.rmdir(step[1])
                except OSError as exc:
                    if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                        raise
        else:  # a file moved aside returns, one moved in goes back to its staging folder
            _, was, now, inode = step
            if _is(now, inode):
                if _exists(was):
                    raise _Conflict("%s is in the way of the file that was there" % was)
                folders.checkpoint("back")
                os.rename(now, was)


def _sync(fd):
    """Write the file open as ``fd`` to disk (``fsync``): what a commit needs after a power
    loss; a process killed outright loses nothing that the kernel has."""
    os.fsync(fd)


#: What ``fsync`` of a folder answers on a file system that cannot write folders to disk
#: that way (the call is not supported there, nothing failed).
_NO_FOLDER_SYNC = (errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP)


def _sync_dir(path):
    """Write the folder ``path``'s entries to disk (where folders can be opened: not
    Windows).  An error is raised, but the answer of a file system that does not sync
    folders (:data:`_NO_FOLDER_SYNC`)."""
    if os.name == "nt":
        return
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        _sync(fd)
    except OSError as exc:
        if exc.errno not in _NO_FOLDER_SYNC:
            raise
    finally:
        os.close(fd)


def _sync_tree(path):
    """Write every file and folder under ``path`` to disk."""
    for top, dirs, files in os.walk(path, onerror=_raise):
        for name in files:
            f = os.path.join(top, name)
            if not os.path.islink(f):
                with open(f, "rb" if os.name == "posix" else "r+b") as fh:
                    _sync(fh.fileno())
        _sync_dir(top)


def _raise(exc):
    raise exc


def _sync_moved(steps):
    """Write to disk the folders the moves changed."""
    changed = set()
    for step in steps:
        if step[0] == "mkdir":
            changed.update((step[1], os.path.dirname(step[1])))
        else:
            changed.update(os.path.dirname(p) for p in step[1:3])
    for d in sorted(changed):
        _sync_dir(d)


def _write_json(path, obj):
    """Write ``obj`` to ``path`` whole or not at all, to disk."""
    part = path + ".part"
    folders.checkpoint("write " + os.path.basename(path))
    fd = os.open(part, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0),
                 0o600)
    try:
        data = json.dumps(obj, indent=1).encode()
        if os.write(fd, data) != len(data):
            raise OSError(errno.ENOSPC, "written in part", part)
        _sync(fd)
    finally:
        os.close(fd)
    folders.checkpoint("name " + os.path.basename(path))
    os.rename(part, path)
    _sync_dir(os.path.dirname(path))


def _read_json(path):
    try:
        with open(path, "rb") as fh:
            return json.loads(fh.read(1 << 24))
    except (OSError, ValueError):
        return None


def _valid(commit):
    """True when ``commit`` (read from a journal) has the form :meth:`Staging._commit`
    writes."""
    def inode(v):
        return isinstance(v, list) and len(v) == 2 and all(isinstance(i, int) for i in v)
    try:
        return (isinstance(commit["id"], str) and commit["state"] in ("forward", "back")
                and all(isinstance(s, str) for s in commit["stages"]) and commit["stages"]
                and all(isinstance(t, str) for t in commit["commit of"])
                and all((s[0] == "mkdir" and len(s) == 2 and isinstance(s[1], str))
                        or (s[0] in ("aside", "in") and len(s) == 4
                            and isinstance(s[1], str) and isinstance(s[2], str)
                            and inode(s[3]))
                        for s in commit["steps"]))
    except (KeyError, TypeError, IndexError):
        return False


def _say(text):
    warnings.warn(text, CommitRecovered, stacklevel=2)


def recover(place):
    """Complete or roll back the commits that processes killed outright left unfinished in
    ``place`` and the folders above it, and remove their staging folders and the other
    staging folders of dead processes there (:func:`folders.sweep`; once per process and
    folder).  Says what it did, one line a commit (:class:`CommitRecovered`)."""
    place = Path(place).absolute()
    for folder in [place, *place.parents]:
        if folder.is_dir():
            folders.sweep((STAGE,), dir=folder, dead=_recover_stage, other=_elsewhere)


def _elsewhere(stage):
    """A staging folder that is not provably a dead process's: says so when it holds an
    unfinished commit that is not this place's to finish (made elsewhere: moved or copied here
    since, or made on another host); it is left as it is."""
    names = set(_listdir(stage))
    if not names & {JOURNAL, MEMBER}:
        return
    here, record = folders.made_here(stage)
    if here or record is None:  # in use by a live process, or not driftfmu's
        return
    _say("left %s as it is: it holds an unfinished results commit made as %s on %s (moved or "
         "copied since), which only a run there can finish; its files are kept"
         % (stage, record.get("path"), record.get("host")))


def _recover_stage(stage):
    """A staging folder of a dead process (its lock held by the sweep): its commit resolved
    and the folder removed where that is safe.  True when it is removed."""
    names = set(_listdir(stage))
    if names & {JOURNAL, DONE}:
        return _resolve(stage, {os.path.realpath(stage)})
    if MEMBER in names:
        member = _read_json(os.path.join(stage, MEMBER))
        first = member.get("first") if isinstance(member, dict) else None
        if isinstance(first, str) and _exists(first):
            fd = folders.claim(first)
            if fd is not None:
                try:
                    _resolve(first, {os.path.realpath(stage), first}, member.get("id"))
                finally:
                    os.close(fd)
                if not _exists(stage):
                    return True
                if _exists(first):
                    return False  # kept, and said why
                # the commit was undecided: its first folder is gone, so goes this one
            elif not folders.stale(first):  # in use, or not provably a dead process's
                return False
            # else the first folder half removed: its commit is resolved
    if any(n.startswith(".replaced-") for n in names):
        # files that were in place before, and no journal (its first folder gone): kept
        _say("kept %s: it holds files that a results commit moved aside, and its journal is "
             "gone; they may be the only copies" % stage)
        return False
    # no commit decided: the staged files of a run that never committed
    return _discarded(stage)


def _discarded(stage):
    """Remove the staging folder ``stage`` of a dead process (:func:`folders.discard`); True
    when it is gone, else it is said (:class:`CommitLeftovers`) and kept with its
    bookkeeping for a later run."""
    error = folders.discard(stage, last=BOOKKEEPING)
    if error is None:
        return True
    _leftover(stage, error, False)
    return False


def _listdir(path):
    try:
        return os.listdir(path)
    except OSError:
        return []


def _resolve(first, held, member_id=None):
    """Finish the commit whose journal is in its first staging folder ``first`` (locked, as
    are the folders in ``held``, real paths, by the caller), then remove its staging folders.
    True when they are removed."""
    names = set(_listdir(first))
    record = os.path.join(first, DONE if DONE in names else JOURNAL)
    if not names & {JOURNAL, DONE}:  # undecided (killed before the journal): nothing moved
        return _discarded(first)
    commit = _read_json(record)
    if (not _valid(commit) or commit["stages"][0] != os.path.realpath(first)
            or (member_id is not None and commit["id"] != member_id)):
        _say("kept %s: its results commit journal cannot be read" % first)
        return False
    claimed = []
    try:
        for stage in commit["stages"][1:]:
            if stage in held or not _exists(stage):
                continue
            fd = folders.claim(stage)
            if fd is None:
                if folders.stale(stage):  # emptied (half removed): nothing in it
                    continue
                return False  # in use, or not provably a dead process's: later
            claimed.append(fd)
        what = ", ".join(commit["commit of"])
        if DONE not in names:
            # one writer at a time: no live commit moves files there meanwhile
            with destinations_locked(commit["commit of"]):
                try:
                    if commit["state"] == "forward":
                        left = _forward(commit["steps"])
                        _sync_moved(commit["steps"])
                    else:
                        _back(commit["steps"])
                except _Conflict as exc:
                    _say("kept the staging folders of an unfinished results commit of %s (%s): "
                         "%s" % (what, ", ".join(commit["stages"]), exc))
                    return False
                folders.checkpoint("journal done")
                os.rename(record, os.path.join(first, DONE))
            with contextlib.suppress(OSError):
                _sync_dir(first)
            if commit["state"] == "forward":
                moves = sum(s[0] != "mkdir" for s in commit["steps"])
                _say("completed the results commit of %s that a killed process left "
                     "unfinished: %d of its %d moves were left; every new file is in place"
                     % (what, left, moves) if left else
                     "completed the results commit of %s that a killed process left "
                     "unfinished: every new file was in place already" % what)
            else:
                _say("rolled back the results commit of %s that a killed process left "
                     "unfinished: the files of before are back in place" % what)
        for stage in commit["stages"][1:]:
            if _exists(stage) and not _discarded(stage):
                return False
        if any(_exists(s) for s in commit["stages"][1:]):
            return False  # the first folder goes last
        return _discarded(first)
    finally:
        for fd in claimed:
            os.close(fd)


@contextlib.contextmanager
def staged(out_dir):
    """Yield a folder for the files of ``out_dir``; when the block succeeds they are moved into
    ``out_dir`` (created if missing), all of them or none (:class:`Staging`: on an error or an
    interrupt in the block or during the moves, ``out_dir`` is left as it was; after a kill
    during the moves the next run completes them).

    ``out_dir`` naming an existing file, or a path under one, is a UsageError (one line, raised
    before the block runs, nothing written)."""
    out = Path(out_dir)
    existing = nearest_existing(out)
    if not existing.is_dir():
        raise UsageError("%s is an existing file; allowed: a folder (created if missing)"
                         % existing)
    with Staging() as staging:
        stage = staging.path(out)
        stage.mkdir()
        yield stage


def write_csv(path, columns, names):
    """Write ``columns[name]`` for ``name`` in ``names`` as CSV with a header, full precision."""
    import numpy as np
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")


def write_json(path, obj):
    """Write ``obj`` as indented JSON."""
    with open(path, "w") as fh:
        json.dump(obj, fh, indent=2, sort_keys=False)
        fh.write("\n")


def _limits(values, pad=0.08, include=()):
    """Axis limits around the finite ``values`` (and ``include``), padded; never empty."""
    import numpy as np
    v = np.concatenate([np.ravel(np.asarray(a, dtype=float)) for a in values]
                       + [np.asarray(include, dtype=float)])
    v = v[np.isfinite(v)]
    if not v.size:
        return -1.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    span = hi - lo if hi > lo else max(abs(hi), 1e-12)
    return lo - pad * span, hi + pad * span


#: Units for people: the parameters' units as models.parameters writes them ("V/g2").
_UNIT_TEXT = {"V/g2": "V/g²", "V/g3": "V/g³", "V/g4": "V/g⁴", "g2": "g²", "V2": "V²"}


def value_text(name, value):
    """``"a4 = 0.05 V/g⁴"``: a parameter with its unit (none for a unit of 1)."""
    from driftfmu.models import parameters
    unit = parameters.PARAMETERS[name].unit
    return "%s = %g%s" % (name, value, "" if unit == "1" else " " + _UNIT_TEXT.get(unit, unit))


def general_text(general):
    """The general model's parameters that are not off (``a3, a4, B`` and the known input
    ``drive, Qu, Xu, fu``), for a title: ``"a4 = 0.05 V/g⁴, B = 1, known input u: sinusoidal,
    Xu = 1 g, fu = 5 Hz"``; ``""`` for the letter's sensor."""
    from driftfmu.models import excitation
    from driftfmu.models import chain
    general = {k: v for k, v in (general or {}).items()
               if v != chain.SENSOR_ERRORS_OFF.get(k, 0.0)}
    parts = [value_text(k, general[k]) for k in ("a3", "a4", "B") if k in general]
    drive = general.get("drive", excitation.DRIVE_OFF)
    if drive != excitation.DRIVE_OFF:
        parts.append("known input u: %s" % excitation.DRIVES.get(drive, drive))
        parts += [value_text(k, general[k]) for k in ("Qu", "Xu", "fu") if k in general]
    slow = [value_text(k, general[k]) for k in chain.SENSOR_ERRORS_OFF if k in general]
    if slow:  # the sensor's slow errors (issue 42)
        parts.append("slow errors: " + ", ".join(slow))
    return ", ".join(parts)


def drift_labels(general=None):
    """(realised, expected): how the realised and the expected drift are computed, for labels:
    ``a2·mean(x²)`` and ``a2·E[x²]`` for the letter's sensor, ``mean(a2 x² + a4 x⁴)`` and
    ``E[a2 x² + a4 x⁴]`` with the general sensor's terms that are on."""
    general = general or {}
    terms = ["a2 x²"] + ["a%d x%s" % (i, "³⁴"[i - 3]) for i in (3, 4)
                         if general.get("a%d" % i)]
    if len(terms) == 1:
        return "a2·mean(x²)", "a2·E[x²]"
    return "mean(%s)" % " + ".join(terms), "E[%s]" % " + ".join(terms)


def plot_drift(path, cols, title, general=None, labels=None):
    """The letter's Fig. 1, done right (one run): EKF1-3 against the realised and the expected
    drift (top) and EKF1 against the empirical drift ``z̄ - a0``, the letter's reference, whose
    linear term ``a1 x̄`` dwarfs the drift for a Gaussian state (bottom).

    Drifts in mV over the sample number on a log axis (the start-up and the settled estimate
    both visible); the y range of the top panel is that of its curves after the first 1 % of
    the samples (at least 10), of the bottom one after the first 10 %, so a start-up transient
    does not flatten the rest; legends sit beside the axes, off the curves.  ``general``: the
    general model's parameters (``a3, a4``: the realised and expected drift's terms);
    ``labels``: (realised, expected), how the two are computed, instead.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    mv = {c: 1e3 * np.asarray(cols[c], dtype=float) for c in
          ("dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_realised", "dc_expected", "dc_empirical")}
    n = len(mv["dc_ekf1"])
    k = np.arange(1, n + 1)
    start = min(n - 1, max(10, n // 100))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 7), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 2]})
    realised, expected = labels or drift_labels(general)
    top.plot(k, mv["dc_realised"], color="0.55", lw=3.2, alpha=0.6,
             label="realised  %s" % realised)
    top.plot(k, mv["dc_expected"], color="k", lw=1.0, ls=":", label="expected  %s" % expected)
    top.plot(k, mv["dc_ekf3"], color="C2", lw=1.3, label="EKF3")
    top.plot(k, mv["dc_ekf1"], color="C0", lw=2.0, label="EKF1")
    top.plot(k, mv["dc_ekf2"], color="C1", lw=1.1, ls=(0, (3, 3)),
             label="EKF2 (dashed, over EKF1)")
    top.set_ylim(*_limits([mv[c][start:] for c in ("dc_ekf1", "dc_ekf2", "dc_ekf3",
                                                   "dc_realised", "dc_expected")]))
    top.set_title("estimates against the realised and the expected drift", fontsize=10)
    bottom.plot(k, mv["dc_empirical"], color="C3", lw=0.9, label="empirical  z̄ − a0")
    bottom.plot(k, mv["dc_ekf1"], color="C0", lw=1.3, label="EKF1")
    bottom.axhline(0.0, color="k", lw=0.6)
    late = min(n - 1, max(10, n // 10))
    bottom.set_ylim(*_limits([mv["dc_empirical"][late:], mv["dc_ekf1"][late:]],
                             include=(0.0,)))
    bottom.set_title("EKF1 against the empirical drift z̄ − a0 (the letter's reference)",
                     fontsize=10)
    for ax in (top, bottom):
        log_sample_axis(ax)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_ylabel("drift [mV]")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
    bottom.set_xlim(1, max(n, 2))
    bottom.set_xlabel("sample k (log scale)")
    caption(fig, title)
    layout(fig)
    savefig(fig, path, dpi=120)
    plt.close(fig)


#: The label of the note :func:`mark_clipping` writes (a text, or a legend holding it).
CLIPPING_NOTE = "_clipping note"


def mark_clipping(ax):
    """Mark every curve of ``ax`` that leaves the y range: small triangles on the frame where
    it is off the scale (pointing the way it went; one per sample off the scale, at most 12 per
    curve and side, spread from the first such sample to the last), and a note naming the
    curve, the samples and how far it went.  Nothing is clipped without a mark (issue 19:
    drift.png's bottom panel hid k = 1-99 of the empirical drift), and the note covers no
    curve: beside the axes under their legend where the legend sits beside them, in the legend
    where it sits on the axes, else inside where it covers the fewest points (a legend's
    ``loc="best"``).  Log axes: values <= 0 are not drawable and not counted.  Returns the
    notes."""
    import numpy as np
    y0, y1 = sorted(ax.get_ylim())
    x0, x1 = sorted(ax.get_xlim())
    logy = ax.get_yscale() == "log"
    xname = "k" if any(a.get_xlabel().startswith("sample k")
                       for a in ax.get_shared_x_axes().get_siblings(ax)) else "x"
    ylabel = ax.get_ylabel()
    unit = (" " + ylabel[ylabel.rindex("[") + 1:ylabel.rindex("]")]
            if "[" in ylabel and ylabel.rstrip().endswith("]") else "")
    notes = []
    for line in list(ax.get_lines()):
        label = line.get_label()
        if label.startswith(("_child", "_nolegend_", "_clipped")):
            continue  # unnamed helpers (axhline, axvline) and the marks themselves
        label = label.lstrip("_")  # "_EKF1 5 %": named, kept out of the legend
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        if x.shape != y.shape or not x.size:
            continue
        ok = np.isfinite(x) & np.isfinite(y) & (x >= x0) & (x <= x1)
        if logy:
            ok &= y > 0
        for side, off, edge, marker in (("above", ok & (y > y1), y1, "^"),
                                        ("below", ok & (y < y0), y0, "v")):
            if not off.any():
                continue
            xs = x[off]
            pick = np.unique(np.linspace(0, xs.size - 1, min(xs.size, 12)).astype(int))
            ax.plot(xs[pick], np.full(pick.size, edge), ls="none", marker=marker, ms=5,
                    color=line.get_color(), clip_on=False, zorder=5,
                    label="_clipped %s" % label)
            far = float(np.max(y[off]) if side == "above" else np.min(y[off]))
            where = ("%g" % xs.min() if xs.min() == xs.max()
                     else "%g to %g" % (xs.min(), xs.max()))
            notes.append("%s off the scale %s at %s = %s (to %.3g%s)"
                         % (label.split("  ")[0].split(" (")[0], side, xname, where, far,
                            unit))
    title = ax.title
    if any(" above " in t for t in notes) and title.get_text():
        # the marks sit on the top edge: lift the axes' title clear of them
        ax.set_title(title.get_text(), fontsize=title.get_fontsize(), pad=11)
    if notes:
        _clipping_note(ax, notes)
    return notes


def _clipping_note(ax, notes):
    """The note of :func:`mark_clipping`, where it covers no curve."""
    legend = ax.get_legend()
    beside = legend is not None and \
        legend.get_bbox_to_anchor().transformed(ax.transAxes.inverted()).x0 >= 1.0
    lines = []
    for t in notes:  # beside: two lines each, what and where, about a legend's width
        mark = "▲" if " above " in t else "▼"
        if beside:
            cut = t.index(" at ", t.index(" off the scale "))
            lines += ["%s %s" % (mark, t[:cut]), "   %s" % t[cut + 1:]]
        else:
            lines.append("%s %s" % (mark, t))
    text = "\n".join(lines)
    if beside:  # in the margin the legend has made, under it
        ax.text(1.01, 0.0, text, transform=ax.transAxes, ha="left", va="bottom", fontsize=7,
                color="0.25", label=CLIPPING_NOTE)
        return
    if legend is not None:  # a legend on the axes: the note goes with it, where it is placed
        title = legend.get_title().get_text()
        legend.set_title(title + "\n" + text if title else text,
                         prop={"size": 7})
        legend.set_label(CLIPPING_NOTE)
        return
    from matplotlib.legend import Legend  # where it covers the fewest points
    note = Legend(ax, [], [], title=text, loc="best", title_fontsize=7, framealpha=0.85,
                  edgecolor="0.7")
    note.get_title().set_color("0.25")
    note.set_label(CLIPPING_NOTE)
    ax.add_artist(note)


def clipping_notes(ax):
    """The notes of :func:`mark_clipping` on ``ax`` (texts, or legends holding them): the
    artists and their text."""
    from matplotlib.legend import Legend
    found = []
    for artist in list(ax.texts) + list(ax.artists) + [ax.get_legend()]:
        if artist is not None and artist.get_label() == CLIPPING_NOTE:
            text = artist.get_title().get_text() if isinstance(artist, Legend) \
                else artist.get_text()
            found.append((artist, text))
    return found


def mark_figure(fig):
    """:func:`mark_clipping` on every axes of ``fig`` not marked yet."""
    for ax in fig.axes:  # get_ylim() autoscales what is still stale
        if ax.get_visible() and ax.get_lines() and not getattr(ax, "_driftfmu_marked", False):
            mark_clipping(ax)
            ax._driftfmu_marked = True


def layout(fig, **kw):
    """``fig.tight_layout(**kw)`` after the curves that leave their axes are marked
    (:func:`mark_figure`), so that the layout makes room for what the marks move (a title
    lifted clear of the marks on the top edge)."""
    mark_figure(fig)
    fig.tight_layout(**kw)


def savefig(fig, path, dpi=120):
    """Save ``fig``: first every axes' curves that leave its y range are marked
    (:func:`mark_clipping`), where :func:`layout` has not done it."""
    mark_figure(fig)
    skip_layout_draw(fig)
    fig.savefig(path, dpi=dpi)


def fork_is_cheap():
    """More than one core, and a worker would be forked (this process is single-threaded)
    with matplotlib already imported, so that drawing a figure beside costs no start-up."""
    import os
    import sys
    import threading
    return ((os.cpu_count() or 1) > 1 and threading.active_count() == 1
            and "matplotlib.pyplot" in sys.modules and hasattr(os, "fork"))


def draw_beside(first, *others):
    """Call ``first()`` here and each of ``others`` (picklable: ``functools.partial`` of a
    module-level plotting function) in a forked worker at the same time, when forking is cheap
    (:func:`fork_is_cheap`); all in this process, in order, otherwise.  Returns when every one
    is done; an exception in a worker is raised here."""
    if not others or not fork_is_cheap():
        first()
        for other in others:
            other()
        return
    from driftfmu.simulations import batch
    with batch.process_pool(len(others), "driftfmu.simulations.output") as pool:
        later = [pool.submit(other) for other in others]
        first()
        for future in later:
            future.result()


def skip_layout_draw(fig):
    """After ``fig.tight_layout()`` the figure keeps a placeholder layout engine, and with any
    engine ``savefig`` first draws the whole figure without rendering it, only to lay it out
    (about 40 % of a figure's time): a placeholder lays out nothing, so it is dropped and the
    figure is drawn once, to the same pixels."""
    try:
        from matplotlib.layout_engine import PlaceHolderLayoutEngine
    except ImportError:  # matplotlib < 3.6: no layout engines, no extra draw
        return
    if isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):
        fig.set_layout_engine(None)


def caption(fig, text, width=95):
    """A caption-like title over the whole figure, wrapped to ``width`` characters."""
    import textwrap
    text = text.replace(" = ", "\u00a0=\u00a0")  # "a1 = 1" stays on one line
    fig.suptitle("\n".join(textwrap.wrap(text, width)), fontsize=10.5)


#: Digits and minus as Unicode superscripts.
_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075"
                                            "\u2076\u2077\u2078\u2079")


def decade_label(value, pos=None):
    """A log axis' tick label: ``10⁻³`` at a power of ten (Unicode superscripts: the same
    look as matplotlib's default, without its mathtext, whose parsing was a quarter of a
    sweep figure's drawing time), ``%g`` elsewhere."""
    import math
    if value > 0.0:
        e = round(math.log10(value))
        if abs(math.log10(value) - e) < 1e-9:
            return "10" + str(int(e)).translate(_SUPERSCRIPT)
    return "%g" % value


def decade_labels(axis):
    """:func:`decade_label` for the major ticks of ``axis`` (``ax.xaxis`` or ``ax.yaxis``)."""
    from matplotlib.ticker import FuncFormatter
    axis.set_major_formatter(FuncFormatter(decade_label))


def log_sample_axis(ax):
    """A log x axis of sample numbers with plain tick labels (1, 10, 100, 1000)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(base=10))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: "%g" % v))
    ax.xaxis.set_minor_formatter(NullFormatter())
