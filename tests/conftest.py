"""Fixtures shared by the test modules."""
import pytest

from driftfmu.fmu_src.builder import NAMES, build_fmus


@pytest.fixture(scope="session")
def built_fmus(python_fmus):
    """The project's FMUs, built once per test session: dict name -> path of ``<Name>.fmu``."""
    return python_fmus


@pytest.fixture(scope="session")
def python_fmus(tmp_path_factory):
    """The pythonfmu FMUs (``built_fmus``; a module may override that name, this one stays)."""
    out = tmp_path_factory.mktemp("fmus")
    return dict(zip(NAMES, build_fmus(out, names=NAMES)))


@pytest.fixture(scope="session")
def native_fmus(tmp_path_factory):
    """The native (C) twins, built once per session: {2: {name: path}, 3: {name: path}}."""
    from driftfmu.fmu_src.native_build import build_native_fmus
    out = tmp_path_factory.mktemp("fmus_native") / "native"  # the layout of build/fmus/native
    return build_native_fmus(out, log=lambda line: None)


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
def report(request):
    """``report(line)``: note what a passing test saw (which importer stepped the FMUs, the
    error texts of bad inputs, the memory figure).  The lines are listed together after the
    test session, under their own heading and each with its test's name, so that the CI log
    shows them (``pytest -ra`` hides passing tests' output) without mixing them into the
    progress lines, where they read as failures.  They travel as the test's user properties,
    so pytest-xdist's workers hand them on too."""
    def write(line):
        request.node.user_properties.append(("report", str(line)))
    return write


#: ``(test id, line)`` of every :func:`report` line of this session.
_REPORTED = []


def pytest_runtest_logreport(report):
    if report.when == "call":
        _REPORTED.extend((report.nodeid, v) for k, v in report.user_properties if k == "report")


def pytest_terminal_summary(terminalreporter):
    if _REPORTED:
        terminalreporter.section("what passing tests saw (their report lines; not failures)",
                                 sep="-")
        for nodeid, line in _REPORTED:
            terminalreporter.write_line("%s: %s" % (nodeid, line))
