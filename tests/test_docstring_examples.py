"""The public functions' docstring examples run as doctests, in a folder whose ``build/fmus``
holds the session's FMUs (as ``driftfmu build`` leaves them), so they show what a user gets."""
import doctest
import inspect
import io

import pytest

import driftfmu

API = [n for n in driftfmu.__all__ if n != "__version__"]
WITH_EXAMPLES = [n for n in API if ">>>" in (inspect.getdoc(getattr(driftfmu, n)) or "")]
#: Examples that build FMUs: the qualification tier (a build takes seconds).
BUILDS = {"build_fmus"}


def run_examples(name):
    """Run the examples of ``driftfmu.<name>``'s docstring; the doctest report on failure."""
    out = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in doctest.DocTestFinder().find(getattr(driftfmu, name), "driftfmu.%s" % name,
                                             globs={}):
        runner.run(test, out=out.write)
    return runner.tries, runner.failures, out.getvalue()


def test_the_documented_functions_have_examples_and_none_is_skipped():
    assert {"simulate", "build_fmus"} <= set(WITH_EXAMPLES)
    for name in WITH_EXAMPLES:
        doc = inspect.getdoc(getattr(driftfmu, name))
        assert "+SKIP" not in doc, "%s: an example that is skipped is not checked" % name


@pytest.fixture
def user_folder(python_fmus, tmp_path, monkeypatch):
    """A folder with the session's Python FMUs in ``build/fmus``, the working directory."""
    fmus = tmp_path / "build" / "fmus"
    fmus.mkdir(parents=True)
    for path in python_fmus.values():
        (fmus / path.name).symlink_to(path)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.integration
@pytest.mark.parametrize("name", [n for n in WITH_EXAMPLES if n not in BUILDS])
def test_docstring_examples_run(name, user_folder):
    tries, failures, report = run_examples(name)
    assert tries and not failures, report


@pytest.mark.integration
@pytest.mark.qualification
@pytest.mark.parametrize("name", sorted(BUILDS))
def test_docstring_examples_that_build_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    tries, failures, report = run_examples(name)
    assert tries and not failures, report
