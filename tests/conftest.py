"""Fixtures shared by the test modules."""
import pytest

from driftfmu.fmu_src.builder import NAMES, build_fmus


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """The project's FMUs, built once per test session: dict name -> path of ``<Name>.fmu``."""
    out = tmp_path_factory.mktemp("fmus")
    return dict(zip(NAMES, build_fmus(out, names=NAMES)))


@pytest.fixture
def report(request):
    """``report(line)``: write a line to the terminal past pytest's output capture, so the CI
    log shows what a passing test saw (which importer stepped the FMUs, the error texts of bad
    inputs, the memory figure): ``pytest -ra`` hides passing tests' output."""
    plugins = request.config.pluginmanager
    reporter = plugins.get_plugin("terminalreporter")
    capture = plugins.get_plugin("capturemanager")

    def write(line):
        if reporter is None or capture is None:
            print(line)
            return
        with capture.global_and_fixture_disabled():
            reporter.ensure_newline()
            reporter.write_line(line)
    return write
