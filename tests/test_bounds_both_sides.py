"""Every declared bound, tested on both of its sides (issue 38: bounds tested on one side).

For each bound: the bound itself, the value just inside it and the value just outside (the
next double, or the next integer), through every check that applies it: the model parameters'
rule (:func:`parameters.problem`, which the API and the FMUs' setters word their errors with),
the API's check of a number (``checks.number_problem``) and the command line's option type
(``cli.param_type``); the counts of the API and of the command line; the port of a Dask
scheduler's address (1..65535); the size checks' workers, which never count more workers than
there is work.  The FMUs' setters, in both twins, are tested at every declared ``min`` and
``max`` and the next double outside by ``test_declarations.py`` and ``test_hardening.py``.
"""
import argparse
import math

import pytest

from driftfmu import _api
from driftfmu.models import parameters
from driftfmu.simulations import budget, checks, cli

BOUNDED = sorted(name for name, p in parameters.PARAMETERS.items()
                 if p.low is not None or p.high is not None)


def _sides(name):
    """``(value, allowed)`` at each bound of ``name``: the bound, just inside, just outside."""
    p = parameters.PARAMETERS[name]
    integer = isinstance(p.default, int)
    out = []
    for bound, is_open, outward in ((p.low, p.low_open, -1), (p.high, p.high_open, 1)):
        if bound is None:
            continue
        if integer:
            out += [(bound, True), (bound - outward, True), (bound + outward, False)]
            continue
        bound = float(bound)
        inside = parameters.next_float(bound, -outward * math.inf)
        outside = parameters.next_float(bound, outward * math.inf)
        out += [(bound, not is_open), (inside, True), (outside, False)]
    return out


def test_every_bounded_parameter_has_both_sides_here():
    # the list is the parameters module's, not a copy: a new bound is tested here too
    assert {"A", "R", "Ts", "seed", "n", "runs", "Vs", "bits", "cross", "rho", "axes",
            "drive"} <= set(BOUNDED)
    for name in BOUNDED:
        values = _sides(name)
        assert any(ok for _, ok in values) and any(not ok for _, ok in values), name


@pytest.mark.parametrize("name", BOUNDED)
def test_each_bound_at_just_inside_and_just_outside_through_every_check(name):
    convert = cli.param_type(name)
    wrong = []
    for value, allowed in _sides(name):
        if name in parameters.NONZERO and value == 0:
            allowed = False
        for check in ("parameters", "api", "cli"):
            if check == "parameters":
                msg = parameters.problem(name, value)
            elif check == "api":
                msg = checks.number_problem(name, value)
            else:
                try:
                    convert(repr(value))
                    msg = None
                except argparse.ArgumentTypeError as e:
                    msg = str(e)
            if (msg is None) != allowed:
                wrong.append("%s %s = %r: %s" % (check, name, value, msg or "accepted"))
            elif msg is not None:
                assert msg.startswith("%s = %r is out of range; allowed: " % (name, value)) \
                    and parameters.allowed(name) in msg, msg
    assert wrong == []


@pytest.mark.parametrize("name,low", [("sets", 1), ("held_out", 1), ("held_out", 0),
                                      ("workers", 1), ("points", 2), ("chunk", 1), ("n", 1),
                                      ("runs", 1)])
def test_each_count_at_its_least_value_and_one_below(name, low):
    option = checks.count_option(name, low)
    for value, allowed in ((low, True), (low + 1, True), (low - 1, False)):
        msg = checks.count_problem(name, value, low)
        assert (msg is None) == allowed, (name, value, msg)
        api = [p for p in _api._settings_problems({name: value}, counts={name: low}) if p]
        assert (not api) == allowed, (name, value, api)
        try:
            option(str(value))
            assert allowed, (name, value)
        except argparse.ArgumentTypeError as e:
            assert not allowed and "out of range" in str(e), (name, value, e)


@pytest.mark.parametrize("port,allowed", [(0, False), (1, True), (2, True), (65534, True),
                                          (65535, True), (65536, False), (99999, False)])
@pytest.mark.parametrize("form", ["tcp://127.0.0.1:%d", "localhost:%d", "tls://[::1]:%d"])
def test_a_schedulers_port_is_1_to_65535(form, port, allowed):
    msg = checks.scheduler_problem(form % port)
    refused = msg is not None and "is not allowed" in msg
    assert refused != allowed, (form % port, msg)


# -- the size checks: never more workers than work ----------------------------------------------

def test_parallel_is_the_workers_capped_by_the_work(monkeypatch):
    assert budget.parallel(8, 2) == 2 and budget.parallel(2, 8) == 2
    assert budget.parallel(3, 3) == 3 and budget.parallel(4, 3) == 3 and budget.parallel(2, 3) == 2
    assert budget.parallel(5, 0) == 1 and budget.parallel(None, 1) == 1
    # no workers given: one per core, capped the same; no core count known: one
    monkeypatch.setattr(budget.os, "cpu_count", lambda: 4)
    assert budget.parallel(None, 8) == 4 and budget.parallel(None, 3) == 3
    assert budget.parallel(0, 8) == 4
    monkeypatch.setattr(budget.os, "cpu_count", lambda: None)
    assert budget.parallel(None, 8) == 1


@pytest.mark.parametrize("which", ["montecarlo", "sweep", "adxl203", "dual_axis"])
def test_each_size_check_counts_no_more_workers_than_work(which):
    """At work below the workers the estimate is that of as many workers as work (not more);
    at work above it is that of the workers; one more worker than work changes nothing."""
    def check(work, workers):
        if which == "montecarlo":
            return budget.check_montecarlo("gaussian", work, 1000, workers, None, announce=False)
        if which == "sweep":
            return budget.check_sweep(work, 1, 1000, workers, None, announce=False)
        if which == "adxl203":
            return budget.check_adxl203((100.0,), work, 1000, workers, None, announce=False)
        return budget.check_dual_axis(1, work, 1000, "fmu", workers, None, announce=False)
    unit = 2 if which == "dual_axis" else 1  # dual-axis: two sweeps of the runs
    for work in (1, 2, 3):
        total = work * unit
        assert check(work, total + 1) == check(work, total), (which, work)  # one more: same
        assert check(work, 8) == check(work, total), (which, work)          # capped
    # below the work, the workers count
    assert check(4, 2)["seconds"] > check(4, 4 * unit)["seconds"]


# -- a drive frequency: 0 < f (the option's check), f < 1/(2 Ts) (the run's) -------------------

@pytest.mark.parametrize("Ts", [1e-3, 3e-4])
def test_a_drive_frequency_is_above_0_and_below_the_nyquist_rate(Ts):
    from driftfmu.simulations import sinusoidal
    from driftfmu.simulations.errors import UsageError
    nyquist = 0.5 / Ts
    tiny = parameters.next_float(0.0, 1.0)
    for f, allowed in ((0.0, False), (-tiny, False), (tiny, True), (1.0, True),
                       (parameters.next_float(nyquist, 0.0), True), (nyquist, False),
                       (parameters.next_float(nyquist, math.inf), False)):
        try:
            sinusoidal.check_frequency(f, Ts)
            refused = None
        except UsageError as e:
            refused = str(e)
        assert (refused is None) == allowed, (f, Ts, refused)
        if refused:
            assert "allowed: 0 < f < 1/(2 Ts) = %r Hz" % nyquist in refused
    # the option's check (no Ts there): > 0 and finite, on both sides of 0
    for f, allowed in ((0.0, False), (-tiny, False), (tiny, True), (math.inf, False)):
        assert (checks.frequency_problem(f) is None) == allowed, f
        assert (checks.freqs_problem([100.0, f]) is None) == allowed, f
