"""pytest plugin of tools/mutation_survey.py: which test reaches which line.

Loaded with ``-p survey_coverage`` (``tools/`` on ``PYTHONPATH``) in a run of the loop, it
measures the run with coverage.py, each test's lines under a context of its own, its node id
(setup, call and teardown alike), and what the test's subprocesses run too (coverage's
``patch = subprocess``: the node id travels to them as their static context).  Each process
writes its data beside ``SURVEY_COVERAGE_DATA`` (``.coverage.<host>.<pid>...``) and one JSON line
per test to ``SURVEY_COVERAGE_DATA.<pid>.tests``: node id, outcome, seconds, and whether the test
is marked ``integration``.  ``SURVEY_COVERAGE_RC`` names coverage's configuration.
"""
import json
import os
import time

import coverage
import pytest

_cov = None
_tests = None


def pytest_configure(config):
    global _cov, _tests
    if _cov is not None:
        return
    _cov = coverage.Coverage(config_file=os.environ["SURVEY_COVERAGE_RC"],
                             data_file=os.environ["SURVEY_COVERAGE_DATA"], data_suffix=True)
    _cov.start()
    _tests = open("%s.%d.tests" % (os.environ["SURVEY_COVERAGE_DATA"], os.getpid()), "a")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if _cov is None:
        yield
        return
    _cov.switch_context(item.nodeid)
    # the test's subprocesses (coverage's patch = subprocess reads this when they start)
    _cov.config.context = item.nodeid
    os.environ["COVERAGE_PROCESS_CONFIG"] = _cov.config.serialize()
    item._survey = dict(test=item.nodeid, outcome="passed", seconds=0.0,
                        integration=item.get_closest_marker("integration") is not None)
    t0 = time.perf_counter()
    yield
    item._survey["seconds"] = round(time.perf_counter() - t0, 3)
    _tests.write(json.dumps(item._survey) + "\n")
    _tests.flush()
    _cov.switch_context("")
    _cov.config.context = None


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    report = (yield).get_result()
    survey = getattr(item, "_survey", None)
    if survey is None:
        return
    # only a test that passed is evidence: a failed or skipped one is not selected
    if report.outcome == "failed":
        survey["outcome"] = "failed"
    elif report.outcome == "skipped" and survey["outcome"] == "passed":
        survey["outcome"] = "skipped"


def pytest_unconfigure(config):
    global _cov
    if _cov is not None:
        _cov.stop()
        _cov.save()
        _cov = None
        _tests.close()
