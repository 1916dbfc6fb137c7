"""No one else's code runs in driftfmu's processes (simulations/trust.py, docs/hardening.md "Who
can write where"): the libraries driftfmu compiles (the batch kernel, the fast master's loop)
are loaded only from the private folder's libraries folder and only when they are this user's,
writable by no one else and the bytes that were built; a library planted by another user (made
with ``setpriv`` as uid 4242; these tests need root) never runs, wherever it is put.  The
folders on the way to what driftfmu loads are walked as the kernel resolves them
(``trust.path_problem``), each permission bit on its own."""
import hashlib
import json
import os
import shutil
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from waiting import BOUND

from driftfmu.simulations import folders, trust

ROOT = Path(__file__).resolve().parent.parent
#: The other user of these tests.
OTHER = 4242
AS_ROOT = pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("setpriv") is None,
    reason="needs root and setpriv(1) to act as another user and to give files away")
NEEDS_CC = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")


def as_other(*command, **kw):
    """Run ``command`` as uid/gid :data:`OTHER` with no other groups."""
    return subprocess.run(["setpriv", "--reuid=%d" % OTHER, "--regid=%d" % OTHER,
                           "--clear-groups", *map(str, command)],
                          capture_output=True, text=True, timeout=BOUND, **kw)


#: What another user's library does when it is loaded: it writes the marker file it was built
#: with (the proof that it ran) and has every symbol the kernel and the loop are looked up by.
PLANTED_C = r"""
#include <stdio.h>
__attribute__((constructor)) static void planted(void)
{
    FILE *f = fopen(MARKER, "w");
    if (f) {
        fputs("another user's code ran\n", f);
        fclose(f);
    }
}
void driftfmu_loop(void) {}
void driftfmu_batch_init(void) {}
void driftfmu_batch_run(void) {}
int driftfmu_adxl203(void) { return 0; }
int driftfmu_dual(void) { return 0; }
"""

#: The child that loads a library: prints {"loaded", "stem", "error"} (one JSON line); the
#: warnings on standard error.
LOADER = textwrap.dedent("""
    import json, sys, warnings
    warnings.simplefilter("always")
    from driftfmu.simulations import fastcosim, kernel
    from driftfmu.simulations.errors import UsageError
    place = sys.argv[1]
    stem = kernel.target() if place == "kernel" else fastcosim.loop_target()
    try:
        lib = kernel.library() if place == "kernel" else fastcosim.loop_library()
        error = None
    except UsageError as exc:
        lib, error = None, str(exc)
    print(json.dumps({"loaded": lib is not None, "stem": stem, "error": error}))
""")

#: A compiler that copies the library it is asked for (kernel.so, loop.so) from the folder of
#: genuine ones, counting its runs: "compiled again" is seen, in no time.
FAKE_CC = """#!/bin/sh
for a; do [ "$a" = --version ] && { echo "fakecc 1.0 (driftfmu's tests)"; exit 0; }; done
out=; prev=
for a; do [ "$prev" = -o ] && out=$a; prev=$a; done
echo "$out" >> '@COUNT@'
case "$out" in
  *kernel.so) cp '@GENUINE@/kernel.so' "$out" ;;
  *loop.so) cp '@GENUINE@/loop.so' "$out" ;;
  *) exit 1 ;;
esac
"""


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """A folder with the genuine kernel.so and loop.so, compiled once for this module."""
    tmp = tmp_path_factory.mktemp("genuine")
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
    env.pop("DRIFTFMU_KERNEL", None)  # (the kernel switched off is never compiled nor loaded)
    for place in ("kernel", "loop"):
        r = subprocess.run([sys.executable, "-c", LOADER, place], env=env,
                           capture_output=True, text=True, timeout=BOUND)
        assert r.returncode == 0 and json.loads(r.stdout)["loaded"], r.stderr
    libraries = tmp / ("driftfmu-%d" % os.geteuid()) / trust.LIBRARIES
    out = tmp / "genuine"
    out.mkdir()
    for lib in libraries.iterdir():
        shutil.copy(lib, out / (lib.name.split("-")[0] + ".so"))
    assert sorted(p.name for p in out.iterdir()) == ["kernel.so", "loop.so"]
    return out


@pytest.fixture
def machine(tmp_path, genuine):
    """A shared temporary folder (mode 1777, as /tmp) and the fake compiler: ``load(place)``
    runs :data:`LOADER` there -> (its JSON answer, its standard error, the compiles so far);
    ``shared``, ``private``, ``libraries``: the folders; ``marker``: what a planted library
    writes."""
    import tempfile
    # beside pytest's folders (which only root may enter), where the other user reaches it
    shared = Path(tempfile.mkdtemp(prefix="driftfmu-test-shared-"))
    shared.chmod(0o1777)
    count = tmp_path / "compiles"
    cc = tmp_path / "fakecc"
    cc.write_text(FAKE_CC.replace("@COUNT@", str(count)).replace("@GENUINE@", str(genuine)))
    cc.chmod(0o755)
    env = dict(os.environ, TMPDIR=str(shared), CC=str(cc), PYTHONPATH=str(ROOT))
    env.pop("DRIFTFMU_KERNEL", None)

    class Machine:
        private = shared / ("driftfmu-%d" % os.geteuid())
        libraries = private / trust.LIBRARIES
        marker = shared / "marker"

        def load(self, place):
            r = subprocess.run([sys.executable, "-c", LOADER, place], env=env,
                               capture_output=True, text=True, timeout=BOUND)
            assert r.returncode == 0, r.stderr
            compiles = len(count.read_text().splitlines()) if count.exists() else 0
            return json.loads(r.stdout), r.stderr, compiles
    m = Machine()
    m.shared = shared
    yield m
    shutil.rmtree(shared)


def planted_library(machine, name="planted.so"):
    """A library compiled by the other user in the shared folder (its constructor writes
    ``machine.marker``)."""
    source = machine.shared / "planted.c"
    r = as_other("sh", "-c", "cat > %s" % source, input=PLANTED_C)
    assert r.returncode == 0, r.stderr
    out = machine.shared / name
    r = as_other("cc", "-shared", "-fPIC", '-DMARKER="%s"' % machine.marker, "-o", out, source)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_uid == OTHER
    return out


def sha256(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@AS_ROOT
@NEEDS_CC
@pytest.mark.parametrize("place", ["kernel", "loop"])
def test_a_library_planted_by_another_user_in_the_temporary_folder_never_runs(place, machine):
    """The attack of issue 39: another user compiles a library and puts it where driftfmu
    once loaded its compiled libraries from (``$TMPDIR/driftfmu-kernel-<hash>-<uid>.so``, a
    name anyone can compute) and tries the libraries folder: it cannot write there, and what
    it put in the temporary folder is never looked at."""
    answer, err, compiles = machine.load(place)  # the private folder is made
    assert answer["loaded"] and compiles == 1, err
    planted = planted_library(machine)
    digest = answer["stem"].split("-")[1]
    old = machine.shared / ("driftfmu-%s-%s-%d.so" % (place, digest[:12], os.geteuid()))
    assert as_other("cp", planted, old).returncode == 0
    ours, = machine.libraries.iterdir()
    for target in (machine.libraries / ("%s-%s.so" % (answer["stem"], sha256(planted))),
                   machine.private / "driftfmu_fmu_mine"):
        r = as_other("cp", planted, target)
        assert r.returncode != 0 and "Permission denied" in r.stderr, r
    ours.unlink()  # compiled again: another user's file there would be loaded now, if at all
    answer, err, compiles = machine.load(place)
    assert answer["loaded"] and compiles == 2, err
    assert not machine.marker.exists()
    assert "warning" not in err


@AS_ROOT
@NEEDS_CC
@pytest.mark.parametrize("place", ["kernel", "loop"])
def test_a_private_folder_made_by_another_user_is_refused_and_nothing_loads(place, machine):
    """The other user makes the private folder first (the name is the uid's), with a planted
    library in it at the right name and with the right hash: refused in one line."""
    answer, err, compiles = machine.load(place)
    stem = answer["stem"]
    shutil.rmtree(machine.private)
    planted = planted_library(machine)
    for make in (["mkdir", "-m", "700", machine.private],
                 ["mkdir", "-m", "700", machine.libraries],
                 ["cp", planted, machine.libraries / ("%s-%s.so" % (stem, sha256(planted)))]):
        r = as_other(*make)
        assert r.returncode == 0, r.stderr
    answer, err, _ = machine.load(place)
    assert not answer["loaded"] and not machine.marker.exists()
    assert "\n" not in answer["error"]
    assert "is owned by uid %d, not by this user" % OTHER in answer["error"], answer


@AS_ROOT
@NEEDS_CC
@pytest.mark.parametrize("place", ["kernel", "loop"])
@pytest.mark.parametrize("fault", ["another owner", "another hash", "group-writable",
                                   "other-writable", "a symbolic link", "not a file"])
def test_a_library_that_fails_a_check_is_never_loaded_and_compiled_again(place, fault,
                                                                         machine):
    """In the libraries folder (which only root can put another user's file into) at the name
    of the library, each check alone: another user's file with the right hash; this user's
    file whose bytes are not the ones its name records; this user's file with the right hash
    that its group or others may write; a symbolic link to a library; a folder.  Each is said
    in one warning line, removed, and the library compiled again; the planted code never
    runs."""
    answer, err, compiles = machine.load(place)
    assert answer["loaded"] and compiles == 1
    stem = answer["stem"]
    ours, = machine.libraries.iterdir()
    ours.unlink()
    planted = planted_library(machine)
    if fault == "another hash":
        bad = machine.libraries / ("%s-%s.so" % (stem, hashlib.sha256(b"other").hexdigest()))
        shutil.copy(planted, bad)
        os.chmod(bad, 0o700)
        why = "does not have the SHA-256 its name records"
    else:
        bad = machine.libraries / ("%s-%s.so" % (stem, sha256(planted)))
        if fault == "a symbolic link":
            bad.symlink_to(planted)
            why = "cannot be opened (Too many levels of symbolic links)"
        elif fault == "not a file":
            bad.mkdir()
            why = "is not a regular file"
        else:
            shutil.copy(planted, bad)
            if fault == "another owner":
                os.chown(bad, OTHER, OTHER)
                os.chmod(bad, 0o755)
                why = "is owned by uid %d, not by this user" % OTHER
            else:
                os.chmod(bad, 0o720 if fault == "group-writable" else 0o702)
                why = "can be written by others (mode %04o)" % (
                    0o720 if fault == "group-writable" else 0o702)
    answer, err, compiles = machine.load(place)
    assert answer["loaded"] and compiles == 2, err
    assert not machine.marker.exists()
    lines = [line for line in err.splitlines() if "UntrustedFile" in line]
    assert len(lines) == 1 and ("%s %s" % (bad, why)) in lines[0], err
    assert "not loaded; it is removed and" in lines[0]
    assert not os.path.lexists(bad)
    library, = machine.libraries.iterdir()
    assert library.name == "%s-%s.so" % (stem, sha256(library))


@AS_ROOT
@NEEDS_CC
@pytest.mark.parametrize("mode", [0o755, 0o750, 0o705, 0o770, 0o707])
def test_a_libraries_folder_that_is_not_private_is_refused(mode, machine):
    """The libraries folder with any permission for its group or for others (made so by
    someone else than driftfmu, which makes it 0700): refused in one line, nothing loaded."""
    answer, err, compiles = machine.load("loop")
    machine.libraries.chmod(mode)
    answer, err, _ = machine.load("loop")
    assert not answer["loaded"] and "\n" not in answer["error"]
    assert "%s has mode %04o: others may use it" % (machine.libraries, mode) in answer["error"]


# -- the walk of a path ------------------------------------------------------------------------

def chain(tmp_path, *modes):
    """Folders tmp_path/d0/d1/... with the ``modes``; the last one's path."""
    path = tmp_path
    for i, mode in enumerate(modes):
        path = path / ("d%d" % i)
        path.mkdir()
        path.chmod(mode)
    return path


def test_a_path_of_private_folders_has_no_problem(tmp_path):
    assert trust.path_problem(chain(tmp_path, 0o755, 0o700)) is None
    assert trust.path_problem(tmp_path / "missing").endswith("No such file or directory")


@AS_ROOT
@pytest.mark.parametrize("case", [
    "every user may write a folder on the way", "sticky folder, this user's entry",
    "sticky folder, another user's entry", "sticky folder of another user",
    "another user's folder on the way", "another user's final folder",
    "group-writable, another group", "group-writable, the user's own group",
    "every user may write the final folder", "the final folder sticky and open to all"])
def test_each_way_another_user_could_change_a_path_is_found(case, tmp_path):
    """One folder of the path changed at a time, against the same path of private folders."""
    mine_only = trust._group_is_mine(0, 0)
    if case == "group-writable, the user's own group" and not mine_only:
        pytest.skip("root's group 0 has other members here")
    last = chain(tmp_path, 0o755, 0o755, 0o755)
    d0, d1, d2 = last.parent.parent, last.parent, last
    want = None
    if case == "every user may write a folder on the way":
        d0.chmod(0o777)
        want = "the folder %s can be written by every user (mode 0777)" % d0
    elif case.startswith("sticky folder"):
        d0.chmod(0o1777)
        if case == "sticky folder, another user's entry":
            os.chown(d1, OTHER, OTHER)
            want = "%s is owned by uid %d in %s, which every user can write to" % (d1, OTHER, d0)
        elif case == "sticky folder of another user":
            os.chown(d0, OTHER, OTHER)
            want = "the folder %s is owned by uid %d" % (d0, OTHER)
    elif case == "another user's folder on the way":
        os.chown(d1, OTHER, OTHER)
        want = "the folder %s is owned by uid %d" % (d1, OTHER)
    elif case == "another user's final folder":
        os.chown(d2, OTHER, OTHER)
        want = "the folder %s is owned by uid %d" % (d2, OTHER)
    elif case.startswith("group-writable"):
        d1.chmod(0o775)
        if case == "group-writable, another group":
            os.chown(d1, 0, OTHER)
            want = ("the folder %s can be written by its group (gid %d, mode 0775), which has "
                    "other members than this user" % (d1, OTHER))
    elif case == "every user may write the final folder":
        d2.chmod(0o777)
        want = "%s can be written by every user (mode 0777)" % d2
    else:
        d2.chmod(0o1777)
        want = "%s can be written by every user (mode 1777)" % d2
    assert trust.path_problem(d2) == want


@AS_ROOT
def test_symbolic_links_on_the_way_are_followed_and_checked(tmp_path):
    """A link of this user's is followed, and its target's folders are checked; another
    user's link is a problem, wherever it points; a loop of links ends."""
    good = chain(tmp_path, 0o755, 0o700)
    bad = tmp_path / "open"
    bad.mkdir()
    bad.chmod(0o777)
    (bad / "inner").mkdir(mode=0o700)
    links = tmp_path / "links"
    links.mkdir()
    (links / "good").symlink_to(good)
    (links / "relative").symlink_to(Path("..") / good.relative_to(tmp_path))
    (links / "bad").symlink_to(bad / "inner")
    (links / "theirs").symlink_to(good)
    os.lchown(links / "theirs", OTHER, OTHER)
    (links / "loop").symlink_to(links / "loop")
    assert trust.path_problem(links / "good") is None
    assert trust.path_problem(links / "relative") is None
    assert trust.path_problem(links / "bad") == \
        "the folder %s can be written by every user (mode 0777)" % bad
    assert trust.path_problem(links / "theirs") == \
        "the symbolic link %s is owned by uid %d" % (links / "theirs", OTHER)
    assert trust.path_problem(links / "loop").endswith("too many symbolic links")
    assert trust.path_problem(links / "good" / ".." / good.name) is None


def test_another_owner_is_named_with_the_owners_allowed(monkeypatch):
    """The message names who may own the file: this user, and root unless this user is root
    or the caller allows other owners."""
    def status(uid):
        return os.stat_result((stat.S_IFDIR | 0o700, 1, 1, 1, uid, uid, 0, 0, 0, 0))
    monkeypatch.setattr(trust, "_me", lambda: 1000)
    assert trust.others_can_write(status(OTHER)) == \
        "is owned by uid %d, not by this user (uid 1000) or root" % OTHER
    assert trust.others_can_write(status(OTHER), owners=(1000,)) == \
        "is owned by uid %d, not by this user (uid 1000)" % OTHER
    assert trust.others_can_write(status(0)) is None
    assert trust.others_can_write(status(0), owners=(1000,)) == \
        "is owned by uid 0, not by this user (uid 1000)"
    monkeypatch.setattr(trust, "_me", lambda: 0)
    assert trust.others_can_write(status(OTHER)) == \
        "is owned by uid %d, not by this user (uid 0)" % OTHER


@pytest.mark.parametrize("count", [trust.MAX_LINKS, trust.MAX_LINKS + 1])
def test_symbolic_links_are_followed_as_far_as_the_kernel_follows_them(count, tmp_path):
    """A path through MAX_LINKS links resolves (for the kernel and for path_problem); one
    more link is too many for both."""
    target = chain(tmp_path, 0o700)
    links = tmp_path / "links"
    links.mkdir(mode=0o700)
    last = target
    for i in range(count):
        link = links / ("l%d" % i)
        link.symlink_to(last)
        last = link
    if count <= trust.MAX_LINKS:
        assert os.path.samestat(os.stat(last), os.stat(target))
        assert trust.path_problem(last) is None
    else:
        with pytest.raises(OSError, match="symbolic links"):
            os.stat(last)
        assert trust.path_problem(last) == "%s: too many symbolic links" % last


@AS_ROOT
def test_a_group_is_this_users_alone_only_without_other_members(monkeypatch):
    """The user private group (group-writable folders of Debian's ``umask 002``): a group whose
    only member is the user; one with another member in its list or as a primary group, or
    with none at all, is not."""
    import grp
    import pwd
    me = pwd.getpwuid(0)

    def group(members):
        return grp.struct_group(("g", "x", 77, members))

    def users(*extra):
        return [me] + [pwd.struct_passwd((n, "x", uid, gid, "", "/", "/bin/sh"))
                       for n, uid, gid in extra]
    cases = [([], users(("root2", 0, 77)), False),  # another user's primary group
             ([], users(), False),                  # no member at all
             (["root"], users(), True),             # the user alone, in the list
             (["root", "bob"], users(), False),     # and another user
             (["bob"], users(), False)]
    for members, everyone, want in cases:
        monkeypatch.setattr(grp, "getgrgid", lambda gid, m=members: group(m))
        monkeypatch.setattr(pwd, "getpwall", lambda e=everyone: e)
        trust._group_is_mine.cache_clear()
        assert trust._group_is_mine(77, 0) is want, (members, want)
    monkeypatch.setattr(pwd, "getpwall", lambda: [pwd.struct_passwd(
        ("root", "x", 0, 77, "", "/", "/bin/sh"))])
    monkeypatch.setattr(grp, "getgrgid", lambda gid: group([]))
    trust._group_is_mine.cache_clear()
    assert trust._group_is_mine(77, 0) is True  # the user's primary group, alone
    trust._group_is_mine.cache_clear()


# -- the native builds' library cache (DRIFTFMU_CACHE) ------------------------------------------

def cache_entry_file(folder, data=b"\x7fELF a library"):
    """A whole cache entry in ``folder`` (its name as the cache names them); its path."""
    from driftfmu.fmu_src import native_build
    entry = folder / ("x86_64-linux-" + "ab" * 32)
    entry.write_bytes(native_build.cache_entry(data))
    entry.chmod(0o600)
    return entry


def test_a_missing_library_cache_is_made_private_on_the_way(tmp_path):
    from driftfmu.fmu_src import native_build
    old = os.umask(0o002)  # (Debian's umask of a user private group)
    try:
        assert native_build.open_cache(tmp_path / "a" / "b" / "cache") == tmp_path / "a/b/cache"
    finally:
        os.umask(old)
    for path in (tmp_path / "a", tmp_path / "a/b", tmp_path / "a/b/cache"):
        assert stat.S_IMODE(path.stat().st_mode) == 0o700, path
    (tmp_path / "file").write_text("not a folder")
    assert native_build.open_cache(tmp_path / "file" / "cache") is None  # skipped, as before


@AS_ROOT
@pytest.mark.parametrize("case", ["another user's folder", "every user may write it",
                                  "its group may write it", "another user's link to it",
                                  "a folder on the way every user may write"])
def test_a_library_cache_another_user_could_change_is_refused_in_one_line(case, tmp_path):
    """What a cache holds goes into FMUs: a cache folder another user could change is refused
    (DRIFTFMU_CACHE names it), before anything is built; a private one is taken."""
    from driftfmu.fmu_src import native_build
    from driftfmu.simulations.errors import UsageError
    assert native_build.open_cache(tmp_path / "mine") == tmp_path / "mine"  # the other side
    cache = tmp_path / "cache"
    cache.mkdir(mode=0o755)
    given = cache
    if case == "another user's folder":
        os.chown(cache, OTHER, OTHER)
        why = "the folder %s is owned by uid %d" % (cache, OTHER)
    elif case == "every user may write it":
        cache.chmod(0o777)
        why = "%s can be written by every user (mode 0777)" % cache
    elif case == "its group may write it":
        os.chown(cache, 0, OTHER)
        cache.chmod(0o775)
        why = "%s can be written by its group (gid %d, mode 0775)" % (cache, OTHER)
    elif case == "another user's link to it":
        given = tmp_path / "link"
        given.symlink_to(cache)
        os.lchown(given, OTHER, OTHER)
        why = "the symbolic link %s is owned by uid %d" % (given, OTHER)
    else:
        tmp_path.chmod(0o777)
        why = "the folder %s can be written by every user (mode 0777)" % tmp_path
    with pytest.raises(UsageError) as err:
        native_build.build_native_fmus(tmp_path / "out", names=("Excitation",),
                                       fmi_versions=(3,), platforms=("x86_64-linux",),
                                       log=lambda line: None, cache=given)
    text = str(err.value)
    assert "\n" not in text and why in text and "allowed: a folder that no other user" in text
    assert not (tmp_path / "out").exists()


@AS_ROOT
@pytest.mark.parametrize("case", ["whole and this user's", "another user's",
                                  "group-writable", "other-writable", "a symbolic link"])
def test_a_cache_entry_is_taken_only_when_this_users_and_no_one_elses_to_write(case,
                                                                             tmp_path):
    """A whole entry of this user's is read; the same bytes owned by another user, writable by
    its group or by others, or reached through a symbolic link, are not (the library is then
    compiled again and the entry replaced: tests/test_platforms.py)."""
    from driftfmu.fmu_src import native_build
    entry = cache_entry_file(tmp_path)
    if case == "another user's":
        os.chown(entry, OTHER, OTHER)
    elif case in ("group-writable", "other-writable"):
        entry.chmod(0o620 if case == "group-writable" else 0o602)
        if case == "group-writable":
            os.chown(entry, 0, OTHER)
    elif case == "a symbolic link":
        real = entry.rename(tmp_path / "elsewhere")
        entry.symlink_to(real)
    want = b"\x7fELF a library" if case == "whole and this user's" else None
    assert native_build._read_cache_entry(entry) == want


# -- the commands, end to end --------------------------------------------------------------------

@pytest.fixture
def shared_tmp():
    """A shared temporary folder (mode 1777, as /tmp) that the other user reaches."""
    import tempfile
    shared = Path(tempfile.mkdtemp(prefix="driftfmu-test-shared-"))
    shared.chmod(0o1777)
    yield shared
    shutil.rmtree(shared)


def driftfmu(*args, env):
    return subprocess.run([sys.executable, "-m", "driftfmu", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=BOUND)


@AS_ROOT
@NEEDS_CC
@pytest.mark.integration
def test_run_native_and_montecarlo_never_run_a_library_planted_in_the_temporary_folder(
        fmus_in_build_layout, shared_tmp, tmp_path):
    """Issue 39's finding, as it was found: uid 4242 puts a library at the names the kernel
    and the fast master's loop were once loaded from (``$TMPDIR/driftfmu-kernel-<hash>-0.so``,
    ``driftfmu-loop-...``); ``driftfmu run gaussian --backend native`` and ``driftfmu
    montecarlo gaussian`` as root run their own, and the planted code never runs."""
    from driftfmu.simulations import fastcosim, kernel
    env = dict(os.environ, TMPDIR=str(shared_tmp), PYTHONPATH=str(ROOT))
    env.pop("DRIFTFMU_KERNEL", None)
    marker = shared_tmp / "marker"
    source = shared_tmp / "planted.c"
    assert as_other("sh", "-c", "cat > %s" % source, input=PLANTED_C).returncode == 0
    planted = shared_tmp / "planted.so"
    assert as_other("cc", "-shared", "-fPIC", '-DMARKER="%s"' % marker, "-o", planted,
                    source).returncode == 0
    names = []
    for place, stem in (("kernel", kernel.target()), ("loop", fastcosim.loop_target())):
        names.append(shared_tmp / ("driftfmu-%s-%s-%d.so" % (place, stem.split("-")[1][:12],
                                                             os.geteuid())))
        assert as_other("cp", planted, names[-1]).returncode == 0
    for command in (["run", "gaussian", "--backend", "native", "--n", "200"],
                    ["montecarlo", "gaussian", "--runs", "4", "--n", "200"]):
        r = driftfmu(*command, "--out", tmp_path / command[0], "--fmu-dir",
                     fmus_in_build_layout, env=env)
        assert r.returncode == 0, r.stderr
        assert not marker.exists(), command
    libraries = shared_tmp / ("driftfmu-%d" % os.geteuid()) / trust.LIBRARIES
    assert sorted(p.name.split("-")[0] for p in libraries.iterdir()) == ["kernel", "loop"]
    assert all(p.stat().st_uid == OTHER for p in names)  # there, and never looked at


@AS_ROOT
@pytest.mark.integration
@pytest.mark.parametrize("case", ["a private folder made by another user",
                                  "a temporary folder every user may write"])
def test_a_run_whose_fmus_would_be_unpacked_where_another_user_can_write_is_refused(
        case, fmus_in_build_layout, shared_tmp, tmp_path):
    """The FMUs a run unpacks are loaded from the private folder: one that another user made
    first (with an FMU's library planted in it), or one in a temporary folder that another
    user could rename it out of (not sticky), is refused in one line (exit 2), for both
    backends' masters; nothing is loaded, nothing written."""
    if case == "a private folder made by another user":
        tmp = shared_tmp
        private = tmp / ("driftfmu-%d" % os.geteuid())
        assert as_other("mkdir", "-m", "700", private).returncode == 0
        want = "the work folder %s is owned by uid %d, not by this user" % (private, OTHER)
    else:
        tmp = shared_tmp / "open"
        tmp.mkdir()
        tmp.chmod(0o777)
        want = "%s can be written by every user (mode 0777)" % tmp
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
    for backend in ("python", "native"):
        r = driftfmu("run", "gaussian", "--backend", backend, "--n", "50", "--out",
                     tmp_path / backend, "--fmu-dir", fmus_in_build_layout, env=env)
        assert r.returncode == 2, r.stderr
        line, = r.stderr.splitlines()
        assert want in line and line.startswith("driftfmu: error: "), line
        assert not (tmp_path / backend).exists()


@AS_ROOT
@pytest.mark.integration
def test_build_native_refuses_a_library_cache_of_another_user_before_building(shared_tmp,
                                                                             tmp_path):
    """``DRIFTFMU_CACHE`` set to a folder another user made (with an entry planted in it, its
    checksum right): ``driftfmu build --native`` says so in one line (exit 2) and builds
    nothing; with ``--no-cache`` it would build without it."""
    from driftfmu.fmu_src import native_build
    cache = shared_tmp / "cache"
    assert as_other("mkdir", "-m", "755", cache).returncode == 0
    entry = cache / ("x86_64-linux-" + "ab" * 32)
    assert as_other("sh", "-c", "cat > %s" % entry,
                    input=native_build.cache_entry(b"planted").decode("latin-1")).returncode == 0
    env = dict(os.environ, DRIFTFMU_CACHE=str(cache), PYTHONPATH=str(ROOT))
    r = driftfmu("build", "--native", "--out", tmp_path / "out", env=env)
    assert r.returncode == 2, r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert "the library cache %s cannot be trusted: %s is owned by uid %d in %s, which every " \
        "user can write to" % (cache, cache, OTHER, shared_tmp) in line and "--no-cache" in line
    assert not (tmp_path / "out").exists()


#: A Python host that loads the Accelerometer unzipped into a folder whose name pythonfmu
#: cannot read ("a%20b": the loader shim reaches it through a link in a folder of its own in
#: TMPDIR), and prints, while the instance lives, what TMPDIR holds: name, mode, owner, and
#: for a folder its entries and where they lead.
SHIM_HOST = textwrap.dedent("""
    import json, os, sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    fmu, folder = sys.argv[1], sys.argv[2]
    extract(fmu, unzipdir=folder)
    md = read_model_description(folder)
    s = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="a")
    s.instantiate()
    tmp = os.environ["TMPDIR"]
    seen = []
    for name in sorted(os.listdir(tmp)):
        path = os.path.join(tmp, name)
        st = os.lstat(path)
        inside = {n: os.path.realpath(os.path.join(path, n)) for n in os.listdir(path)} \\
            if os.path.isdir(path) and not os.path.islink(path) else None
        seen.append([name, st.st_mode & 0o7777, st.st_uid, inside])
    s.freeInstance()
    print(json.dumps(seen))
""")


@AS_ROOT
@pytest.mark.integration
def test_the_loader_shims_link_to_the_resources_lives_in_a_folder_of_its_own(
        python_fmus, shared_tmp, tmp_path):
    """Where pythonfmu cannot read an FMU's folder name, the loader shim hands it a link to
    the resources from a folder it makes in TMPDIR (``mkdtemp``: a new name, mode 0700, this
    user's), beside the other user's folders of a shared temporary folder; pythonfmu imports
    the model's code through that link, which leads to the host's own folder."""
    for name in ("driftfmu-aaaaaa", "driftfmu-r0"):
        assert as_other("mkdir", "-m", "777", shared_tmp / name).returncode == 0
    folder = tmp_path / "a%20b"
    r = subprocess.run([sys.executable, "-c", SHIM_HOST, str(python_fmus["Accelerometer"]),
                        str(folder)], capture_output=True, text=True, timeout=BOUND,
                       env=dict(os.environ, TMPDIR=str(shared_tmp), PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr
    mine = [entry for entry in json.loads(r.stdout) if entry[2] == os.geteuid()]
    assert len(mine) == 1, r.stdout
    name, mode, uid, inside = mine[0]
    assert name.startswith("driftfmu-") and mode == 0o700
    assert inside == {"r0": str(folder / "resources")}
    assert not [p for p in shared_tmp.iterdir() if p.stat().st_uid == os.geteuid()]  # removed
