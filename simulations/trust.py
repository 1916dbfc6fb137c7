"""Internal (not a stable API; use the functions of driftfmu instead).

What driftfmu loads or runs comes from folders that no one but this user (and root) can change.

- :func:`path_problem` walks a path as the kernel resolves it, symbolic links included, and says
  why another user could change what it names, or None: a folder on the way or a symbolic link
  owned by another user, a folder on the way that others can write (unless it is sticky, like
  ``/tmp``, and the entry taken from it is this user's or root's: the sticky bit keeps others
  from renaming or removing it), and at the end a folder that others can write at all.
- :func:`others_can_write` is the test of one file or folder's status: owned by this user or
  root, not writable by everyone, writable by its group only where that group has no member but
  this user (a user private group, the default of Debian and Ubuntu with ``umask 002``).
- :func:`load_library` loads a compiled library of driftfmu's (the batch kernel, the fast
  master's loop) from the private folder's ``libraries`` folder (:func:`library_folder`, mode
  0700, checked as the work folders are): only a regular file owned by this user that no one
  else can write, whose SHA-256 is the one its name records (written when it was built).  A
  file that fails a check is removed (the folder is this user's) and the library compiled
  again, with one warning line; nothing else is ever loaded.  The file is checked and loaded
  through one open descriptor (``/proc/self/fd``), so it cannot be swapped in between.

docs/hardening.md ("Who can write where") has the threat model.
"""
import contextlib
import functools
import hashlib
import os
import re
import stat
import warnings

try:
    import grp
    import pwd
except ImportError:  # Windows
    grp = pwd = None


class UntrustedFile(UserWarning):
    """A file driftfmu would have loaded failed a check: it was not loaded (the message says
    why and what was done instead)."""


def _me():
    return os.geteuid() if hasattr(os, "geteuid") else None


@functools.lru_cache(maxsize=None)
def _group_is_mine(gid, uid):
    """True when group ``gid`` has no member but user ``uid`` (by its primary group or by the
    group's member list) and has that user as a member: a user private group."""
    if grp is None:
        return False
    try:
        group = grp.getgrgid(gid)
        me = pwd.getpwuid(uid).pw_name
    except KeyError:
        return False
    members = set(group.gr_mem) | {user.pw_name for user in pwd.getpwall()
                                   if user.pw_gid == gid}
    return members == {me}


def others_can_write(st, owners=None):
    """Why a user other than this one (or root) can change the file or folder with status
    ``st`` (``os.stat_result``), or None.  ``owners``: the owners allowed (default this user
    and root)."""
    me = _me()
    if me is None:  # Windows: no owners to compare
        return None
    owners = (me, 0) if owners is None else owners
    mode = stat.S_IMODE(st.st_mode)
    if st.st_uid not in owners:
        return "is owned by uid %d, not by this user (uid %d)%s" % (
            st.st_uid, me, " or root" if 0 in owners and me != 0 else "")
    if mode & 0o002:
        return "can be written by every user (mode %04o)" % mode
    if mode & 0o020 and not _group_is_mine(st.st_gid, me):
        return "can be written by its group (gid %d, mode %04o), which has other members " \
               "than this user" % (st.st_gid, mode)
    return None


#: Symbolic links followed at most on one path (the kernel's limit).
MAX_LINKS = 40

#: The answers of ``lstat`` that make a path unusable (a problem to say); any other error (an
#: I/O error) is raised: it says nothing about who can write there.
_UNUSABLE = (FileNotFoundError, NotADirectoryError, PermissionError)


def path_problem(path, final=None):
    """Why another user could change what ``path`` names (see the module), or None.  The path
    is walked as the kernel resolves it; each folder passed must be this user's or root's, and
    one that others can write must be sticky, with the entry taken from it this user's or
    root's.  ``final(st)``: the check of the folder ``path`` names (default
    :func:`others_can_write`); a missing path, or one this user may not look into, is a problem
    too; an I/O error is raised (OSError)."""
    me = _me()
    if me is None:
        return None
    final = final or others_can_write
    path = os.fspath(path)
    if not os.path.isabs(path):  # (not normalised: ".." after a link is the link's target's)
        path = os.path.join(os.getcwd(), path)
    parts = [p for p in path.split(os.sep) if p][::-1]  # a stack
    current = os.sep
    try:
        st = os.lstat(current)
    except _UNUSABLE as exc:
        return "%s: %s" % (current, exc.strerror)
    links = 0
    while parts:
        name = parts.pop()
        if name in (".", ""):
            continue
        if name == "..":
            current = os.path.dirname(current)
            st = os.lstat(current)
            continue
        shared = others_can_write(st) if stat.S_ISDIR(st.st_mode) else None
        if shared:
            if not st.st_mode & stat.S_ISVTX or st.st_uid not in (me, 0):
                return "the folder %s %s" % (current, shared)
        entry = os.path.join(current, name)
        try:
            est = os.lstat(entry)
        except _UNUSABLE as exc:
            return "%s: %s" % (entry, exc.strerror)
        if shared and est.st_uid not in (me, 0):
            return ("%s is owned by uid %d in %s, which every user can write to"
                    % (entry, est.st_uid, current))
        if stat.S_ISLNK(est.st_mode):
            links += 1
            if links > MAX_LINKS:
                return "%s: too many symbolic links" % path
            if est.st_uid not in (me, 0):
                return "the symbolic link %s is owned by uid %d" % (entry, est.st_uid)
            target = os.readlink(entry)
            if os.path.isabs(target):
                current = os.sep
                st = os.lstat(current)
            parts.extend(p for p in target.split(os.sep)[::-1] if p)
            continue
        if not stat.S_ISDIR(est.st_mode):
            if parts:
                return "%s is not a folder" % entry
        elif est.st_uid not in (me, 0):
            return "the folder %s is owned by uid %d" % (entry, est.st_uid)
        current, st = entry, est
    problem = final(st)
    return None if problem is None else "%s %s" % (current, problem)


def entries_kept(st):
    """Why another user could replace an entry of this user's in the folder with status ``st``,
    or None: a folder that only this user (and root) can write, or a sticky folder of root's or
    this user's (``/tmp``), where others can make entries of their own but cannot rename or
    remove this user's."""
    problem = others_can_write(st)
    if problem is None or (st.st_mode & stat.S_ISVTX and st.st_uid in (_me(), 0)):
        return None
    return problem


def private_problem(st):
    """Why the status ``st`` of a private folder of driftfmu's is not private: another owner,
    or any permission for its group or for others (setgid and sticky give no one access to a
    folder of mode 0700, and are allowed: a folder made in a setgid folder inherits the
    bit)."""
    me = _me()
    if me is None:
        return None
    if st.st_uid != me:
        return "is owned by uid %d, not by this user" % st.st_uid
    if st.st_mode & 0o077:
        return "has mode %04o: others may use it" % stat.S_IMODE(st.st_mode)
    return None


# -- compiled libraries ------------------------------------------------------------------------

#: The folder of compiled libraries in the private folder of the work folders.
LIBRARIES = "libraries"


def library_folder():
    """A descriptor of ``<private folder>/libraries`` (:func:`folders.private_subfolder`:
    made with mode 0700 where missing, refused in one line where not private).  The caller
    closes it."""
    from driftfmu.simulations import folders
    return folders.private_subfolder(LIBRARIES)


def library_name(stem, digest):
    """The file name of the library ``stem`` (``kernel-<key>``) whose bytes have the SHA-256
    ``digest`` (hex): ``<stem>-<digest>.so``."""
    return "%s-%s.so" % (stem, digest)


def _candidates(dir_fd, stem):
    pattern = re.compile(r"%s-([0-9a-f]{64})\.so\Z" % re.escape(stem))
    names = []
    with contextlib.suppress(OSError):
        names = sorted(os.listdir(dir_fd))
    return [(n, m.group(1)) for n in names for m in [pattern.match(n)] if m]


def _checked(dir_fd, name, digest):
    """An open descriptor of the library ``name`` in the folder ``dir_fd`` once it passed the
    checks (a regular file, not a link, this user's, no one else may write it, its bytes'
    SHA-256 ``digest``), or the reason it did not."""
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0),
                     dir_fd=dir_fd)
    except OSError as exc:
        return None, "cannot be opened (%s)" % exc.strerror
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            problem = "is not a regular file"
        elif st.st_uid != _me():
            problem = "is owned by uid %d, not by this user" % st.st_uid
        elif st.st_mode & 0o022:
            problem = "can be written by others (mode %04o)" % stat.S_IMODE(st.st_mode)
        else:
            h = hashlib.sha256()
            while True:
                block = os.read(fd, 1 << 20)
                if not block:
                    break
                h.update(block)
            problem = None if h.hexdigest() == digest else \
                "does not have the SHA-256 its name records (changed since it was built)"
        if problem is None:
            return fd, None
    except OSError as exc:
        problem = "cannot be read (%s)" % exc.strerror
    os.close(fd)
    return None, problem


#: Descriptors of the libraries loaded through ``/proc/self/fd``: kept open, so that no other
#: library is ever loaded under the same name (the dynamic loader knows a library by its name).
_LOADED = []


def _dlopen(fd, path):
    import ctypes
    proc = "/proc/self/fd/%d" % fd
    if os.path.exists(proc):
        lib = ctypes.CDLL(proc)
        _LOADED.append(fd)
        return lib
    try:  # (no /proc: the folder is this user's alone, so the path names the file checked)
        return ctypes.CDLL(path)
    finally:
        os.close(fd)


def load_library(stem, build, what):
    """The library ``stem`` of the libraries folder, loaded (``ctypes.CDLL``) once it passes
    the checks (see the module); compiled first when there is none that does, by
    ``build(install)``: it compiles the library in a work folder of its own and hands its path
    to ``install``, which moves it into the libraries folder (one rename) under the name that
    records its SHA-256.  A file named as the library that fails a check is removed and said
    in one line (:class:`UntrustedFile`).  ``what`` names the library for people."""
    from driftfmu.simulations import folders
    dir_fd = folders.private_subfolder(LIBRARIES, create=False)
    try:
        for name, digest in _candidates(dir_fd, stem) if dir_fd is not None else ():
            fd, problem = _checked(dir_fd, name, digest)
            if fd is not None:
                return _dlopen(fd, os.path.join(folders.private_path(LIBRARIES), name))
            warnings.warn("%s %s %s: not loaded; it is removed and %s compiled again"
                          % (what, os.path.join(folders.private_path(LIBRARIES), name),
                             problem, what), UntrustedFile, stacklevel=2)
            try:
                os.unlink(name, dir_fd=dir_fd)
            except OSError:  # (a folder: removed while empty)
                with contextlib.suppress(OSError):
                    os.rmdir(name, dir_fd=dir_fd)
    finally:
        if dir_fd is not None:
            os.close(dir_fd)
    installed = []

    def install(path):
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
        try:
            os.fchmod(fd, 0o700)
            h = hashlib.sha256()
            while True:
                block = os.read(fd, 1 << 20)
                if not block:
                    break
                h.update(block)
        finally:
            os.close(fd)
        name = library_name(stem, h.hexdigest())
        dir_fd = folders.private_subfolder(LIBRARIES)
        try:  # one rename within the private folder: whole or absent, also beside another build
            os.rename(path, name, dst_dir_fd=dir_fd)
        finally:
            os.close(dir_fd)
        installed.append((name, h.hexdigest()))

    build(install)
    name, digest = installed[-1]
    dir_fd = folders.private_subfolder(LIBRARIES)
    try:
        fd, problem = _checked(dir_fd, name, digest)
    finally:
        os.close(dir_fd)
    path = os.path.join(folders.private_path(LIBRARIES), name)
    if fd is None:
        raise OSError("%s %s, just compiled, %s" % (what, path, problem))
    return _dlopen(fd, path)
