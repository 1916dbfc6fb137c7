"""Fixtures shared by the test modules."""
import contextlib
import json
import os
import sys
import tempfile
from pathlib import Path

import pytest

from driftfmu.fmu_src.builder import NAMES, build_fmus
from leftovers import copy_libraries, left_in

try:
    import fcntl
except ImportError:  # (Windows) each pytest-xdist worker builds its own
    fcntl = None


def built_once(tmp_path_factory, name, build):
    """``build(folder)`` (a JSON-ready result) once per test run, shared by all its pytest-xdist
    workers: the first one to ask builds in the run's common temporary folder under a file lock,
    the others wait for it and read the recorded result."""
    root = tmp_path_factory.getbasetemp()
    if fcntl is None or not os.environ.get("PYTEST_XDIST_WORKER"):
        return build(tmp_path_factory.mktemp(name))
    root = root.parent  # <basetemp>/pytest-N/popen-gwK: pytest-N is the run's
    with open(root / ("%s.lock" % name), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        record = root / name / "built.json"
        if record.exists():
            return json.loads(record.read_text())
        (root / name).mkdir(exist_ok=True)
        result = build(root / name)
        record.write_text(json.dumps(result))
        return result


@pytest.fixture(scope="session")
def built_fmus(python_fmus):
    """The project's FMUs, built once per test run: dict name -> path of ``<Name>.fmu``."""
    return python_fmus


@pytest.fixture(scope="session")
def python_fmus(tmp_path_factory):
    """The pythonfmu FMUs (``built_fmus``; a module may override that name, this one stays)."""
    paths = built_once(tmp_path_factory, "fmus",
                       lambda out: [str(p) for p in build_fmus(out, names=NAMES)])
    return dict(zip(NAMES, map(Path, paths)))


#: The platforms of :func:`native_fmus`: those the tests run here (the C host and fmpy; wine
#: runs the Windows binaries in the qualification). The cross-built ones (zig: aarch64, macOS),
#: which only :func:`native_fmus_all`'s tests read or run under qemu, cost most of the build,
#: so the other tests do not wait for them.
HOST_PLATFORMS = ("x86_64-linux", "x86_64-windows")
#: The everyday loop runs no Windows binary (the wine tests are qualification): it compiles
#: for this machine alone.
LOOP_PLATFORMS = ("x86_64-linux",)


#: The compiled libraries of :func:`_native_build`, kept from run to run (keyed by their
#: sources, compiler, compiler version and flags: a changed source or compiler compiles anew;
#: an entry unused for ``native_build.CACHE_DAYS`` days is removed, as in ``driftfmu build``'s
#: cache). ``DRIFTFMU_TEST_NATIVE_CACHE`` names another folder.
NATIVE_CACHE = Path(os.environ.get("DRIFTFMU_TEST_NATIVE_CACHE") or os.path.join(
    tempfile.gettempdir(),
    "driftfmu-test-native-libraries-%d" % getattr(os, "getuid", lambda: 0)()))
#: ``driftfmu build --native`` run by a test keeps its libraries there too, not in the user's
#: cache folder (its default, ``native_build.user_cache``)
os.environ["DRIFTFMU_CACHE"] = str(NATIVE_CACHE)


def _native_build(tmp_path_factory, name, platforms):
    from driftfmu.fmu_src.native_build import build_native_fmus

    def build(out):  # the layout of build/fmus/native; libraries shared by both builds
        return {v: {n: str(p) for n, p in fmus.items()}
                for v, fmus in build_native_fmus(out / "native", platforms=platforms(),
                                                 log=lambda line: None,
                                                 cache=NATIVE_CACHE).items()}
    built = built_once(tmp_path_factory, name, build)
    return {int(v): {n: Path(p) for n, p in fmus.items()} for v, fmus in built.items()}


@pytest.fixture(scope="session")
def native_fmus(tmp_path_factory, request):
    """The native (C) twins for this machine's hosts (x86-64 Linux; in the qualification also
    x86-64 Windows when a compiler for it is installed), built once per test run:
    {2: {name: path}, 3: {name: path}}."""
    from driftfmu.fmu_src import native_build
    wanted = HOST_PLATFORMS if request.config.getoption("--qualification") else LOOP_PLATFORMS
    return _native_build(tmp_path_factory, "fmus_native", lambda: [
        p for p in wanted if native_build.compiler(p) is not None])


@pytest.fixture(scope="session")
def fmus_in_build_layout(python_fmus, native_fmus, tmp_path_factory):
    """The session's FMUs (linked) in the layout ``driftfmu build`` writes: ``<Name>.fmu`` and
    ``native/fmi2|fmi3/<Name>.fmu``, for an ``fmu_dir`` argument."""
    d = tmp_path_factory.mktemp("fmus_in_build_layout")
    for path in python_fmus.values():
        (d / path.name).symlink_to(path)
    for v, paths in native_fmus.items():
        (d / "native" / ("fmi%d" % v)).mkdir(parents=True)
        for path in paths.values():
            (d / "native" / ("fmi%d" % v) / path.name).symlink_to(path)
    return d


@pytest.fixture(scope="session")
def native_fmus_all(native_fmus, tmp_path_factory):
    """The native twins as ``build_native_fmus`` ships them (every platform whose compiler is
    installed: the zig cross-builds for aarch64 and macOS too, and ``fmi2-aarch64/``), built
    once per test run, and only when a test asks (the platform tests).  The libraries of
    :func:`native_fmus` (built first) are reused, not compiled again."""
    from driftfmu.fmu_src import native_build
    return _native_build(tmp_path_factory, "fmus_native_all",
                         lambda: native_build.available_platforms(log=lambda line: None))


#: The FMUs a behaviour test runs on: the pythonfmu FMUs and their native twins, FMI 2.0 and
#: FMI 3.0 (fmpy's FMU3Slave behind the FMI 2.0 method names, simulations.cosim.Fmi3Slave).
BACKENDS = ("python", "native-fmi2", "native-fmi3")


class _NativeFmus(dict):
    """The native FMUs by name; a model without a native twin skips the test."""

    def __missing__(self, name):
        pytest.skip("%s has no native twin (fmu_src/native/models/%s_step.c)" % (name, name))


@pytest.fixture(params=BACKENDS)
def backend_fmus(request):
    """The FMUs of each backend, by name; the test runs once per backend."""
    if request.param == "python":
        return request.getfixturevalue("python_fmus")
    return _NativeFmus(request.getfixturevalue("native_fmus")[int(request.param[-1])])


@pytest.fixture
def closed_figures(monkeypatch):
    """Every figure that the code under test closes with ``plt.close``, kept open for the test
    to inspect (closed after it)."""
    import matplotlib.pyplot as plt
    kept = []
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: kept.append(fig))
    yield kept
    for fig in kept:
        close(fig)


@pytest.fixture
def report(request):
    """``report(line)``: note what a passing test saw (which importer stepped the FMUs, the
    error texts of bad inputs, the memory figure).  The lines are listed together after the
    test session, under their own heading and each with its test's name, so that the CI log
    shows them (``pytest -ra`` hides passing tests' output) without mixing them into the
    progress lines, where they read as failures; ``pytest -q`` leaves them out.  They travel as the test's user properties,
    so pytest-xdist's workers hand them on too."""
    def write(line):
        request.node.user_properties.append(("report", str(line)))
    return write


@pytest.hookimpl(trylast=True)  # after pytest's own (its tmp_path factory)
def pytest_configure(config):
    # libxml2's schema set-up done before any test's threads parse a schema (fmu_src/schemas.py)
    from driftfmu.fmu_src import schemas
    schemas.prime()
    if not hasattr(config, "workerinput"):  # the run itself (pytest-xdist's controller)
        _temporary_folder_of_the_run(config)


#: (the temporary folder of the run, the one it replaced, the session).
_RUN_TMP = []


def _temporary_folder_of_the_run(config):
    """The test run's own temporary folder: ``TMPDIR`` of this process and of every process
    it starts (pytest-xdist's workers, the commands the tests run), made in the temporary
    folder the run was given (other runs, another engineer's, may use that one meanwhile), and
    checked when the run ends (:func:`pytest_unconfigure`): a test that leaves a file or folder
    there fails the run.  pytest's own folders (``tmp_path``) stay where they were; the
    compiled libraries of driftfmu's private folder (tests/leftovers.py) are taken from there
    and handed back."""
    outer = Path(tempfile.gettempdir())
    config._tmp_path_factory.getbasetemp()  # pytest's folders: in the outer folder, as ever
    os.environ.setdefault("DRIFTFMU_TEST_NATIVE_CACHE", str(NATIVE_CACHE))
    run = Path(tempfile.mkdtemp(prefix="driftfmu-test-run-", dir=outer))
    # others may pass through it, not list or write it: the tests that act as another user
    # (tests/test_trust.py) make folders of their own inside
    os.chmod(run, 0o711)
    copy_libraries(outer, run)
    os.environ["TMPDIR"] = str(run)
    tempfile.tempdir = None  # read TMPDIR again
    _RUN_TMP[:] = [run, outer, None]


def pytest_sessionstart(session):
    if _RUN_TMP:
        _RUN_TMP[2] = session


def pytest_unconfigure(config):
    """After the run (its workers ended): what the tests left in the run's temporary folder
    fails it, named; the folder goes, the compiled libraries back to the outer folder."""
    if not _RUN_TMP or hasattr(config, "workerinput"):
        return
    import shutil
    run, outer, session = _RUN_TMP
    # what this process removes when it ends (the masters' unpacked FMUs: simulations/cosim.py
    # new_extract_folder), removed now: a run in one process (-n 0, the mutation survey's) is
    # judged as a run whose workers have ended
    cosim = sys.modules.get("driftfmu.simulations.cosim")
    if cosim is not None:
        cosim.remove_extracted()
        fast = sys.modules.get("driftfmu.simulations.fastcosim")
        if fast is not None:
            fast._UNPACKED.clear()  # (their folders gone)
    left = left_in(run)
    copy_libraries(run, outer)
    shutil.rmtree(run, ignore_errors=True)
    os.environ["TMPDIR"] = str(outer)
    tempfile.tempdir = None
    if left:
        sys.stderr.write("\nERROR: the tests left %d file(s) or folder(s) in the temporary "
                         "folder (TMPDIR): %s\n" % (len(left), ", ".join(left)))
        if session is not None and session.exitstatus == 0:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_addoption(parser):
    parser.addoption(
        "--qualification", action="store_true",
        help="run the release qualification (the tests marked qualification: valgrind, the "
             "cross-built platforms under qemu and wine, fmpy's CMake source builds, memory "
             "cycles, long fuzz, the mutation check, the figures at full size) instead of the "
             "everyday loop")


#: Fixtures too costly for the everyday loop: a test that takes one is a qualification test.
QUALIFICATION_FIXTURES = frozenset({"native_fmus_all"})


def pytest_collection_modifyitems(config, items):
    """Two tiers: without ``--qualification`` the everyday loop (every test not marked
    ``qualification``), with it the qualification alone; the other tier is deselected (pytest's
    summary counts it), not skipped."""
    qualification = config.getoption("--qualification")
    keep, other = [], []
    for item in items:
        tier = item.get_closest_marker("qualification") is not None
        (keep if tier == qualification else other).append(item)
        heavy = QUALIFICATION_FIXTURES.intersection(getattr(item, "fixturenames", ()))
        if heavy and not tier:
            raise pytest.UsageError(
                "%s uses %s, which only the qualification builds; mark it "
                "@pytest.mark.qualification" % (item.nodeid, ", ".join(sorted(heavy))))
    if other:
        config.hook.pytest_deselected(items=other)
        items[:] = keep


#: ``(test id, line)`` of every :func:`report` line of this session.
_REPORTED = []


def pytest_runtest_logreport(report):
    if report.when == "call":
        _REPORTED.extend((report.nodeid, v) for k, v in report.user_properties if k == "report")


def pytest_terminal_summary(terminalreporter, config):
    # a quiet run (-q) ends with pytest's own summary alone
    if _REPORTED and config.getoption("verbose") >= 0:
        terminalreporter.section("what passing tests saw (their report lines; not failures)",
                                 sep="-")
        for nodeid, line in _REPORTED:
            terminalreporter.write_line("%s: %s" % (nodeid, line))
