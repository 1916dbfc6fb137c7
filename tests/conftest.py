"""Fixtures shared by the test modules."""
import pytest

from fmu_src.builder import NAMES, build_fmus


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """The project's FMUs, built once per test session: dict name -> path of ``<Name>.fmu``."""
    out = tmp_path_factory.mktemp("fmus")
    return dict(zip(NAMES, build_fmus(out, names=NAMES)))
