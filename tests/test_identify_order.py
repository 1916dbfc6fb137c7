"""``identify --order 2|3|4``: the harmonic analysis of the general sensor (issue 16).

- noise-free: a0..a4 recovered to rounding, also behind a delay (the lag of the fundamental);
- the standard errors of the fit equal the closed forms over whole periods;
- over many seeds the estimates fall within their own standard errors as often as a normal
  variable does (coverage of the 95 % interval, with a binomial tolerance for the number of
  seeds);
- an order whose harmonics alias (order * f at or above the Nyquist rate) is refused, naming
  the order the data resolve;
- order 2 computes what the 2nd-order fit computed.
"""
import math

import numpy as np
import pytest

from driftfmu.models import identify, noise

TRUE = dict(a0=0.3, a1=1.1, a2=0.05, a3=-0.02, a4=0.01)
F, TS, N, X = 50.0, 1e-3, 4000, 1.4


def _record(seed, sigma, coeffs=TRUE, delay=0.0, X=X, f=F, n=N):
    k = np.arange(n)
    t = k * TS
    theta = 2 * math.pi * f * t + 0.3
    x = X * np.sin(theta)
    u = X * np.sin(theta - delay)  # what the sensor senses, lagging the drive
    z = sum(coeffs.get("a%d" % i, 0.0) * u ** i for i in range(5))
    v = np.array([noise.normal(seed, noise.STREAM_MEASUREMENT, int(i) + 1) for i in k]) \
        if sigma else 0.0
    return t, x, z + sigma * v


@pytest.mark.parametrize("delay", [0.0, 0.2])
def test_noise_free_recovers_every_coefficient(delay):
    fit = identify.fit_set(*_record(1, 0.0, delay=delay), F, order=4)
    for i in range(5):
        assert getattr(fit, "a%d" % i) == pytest.approx(TRUE["a%d" % i], abs=1e-11)
    assert fit.order == 4 and fit.R < 1e-20
    # order 3 on a cubic sensor, order 2 on a quadratic one
    cubic = {k: v for k, v in TRUE.items() if k != "a4"}
    fit3 = identify.fit_set(*_record(1, 0.0, coeffs=cubic, delay=delay), F, order=3)
    for i in range(4):
        assert getattr(fit3, "a%d" % i) == pytest.approx(TRUE["a%d" % i], abs=1e-11)
    assert fit3.a4 == 0.0


def test_a_missing_order_is_bias_not_noise():
    # a quartic sensor fitted at order 2: a2 absorbs a4 X^2 (a0 gets - a4 X^4/8: the test of
    # tests/test_evidence_general_experiments.py)
    fit = identify.fit_set(*_record(1, 0.0), F, order=2)
    assert fit.a2 == pytest.approx(TRUE["a2"] + TRUE["a4"] * X * X, abs=1e-11)
    assert fit.a1 == pytest.approx(TRUE["a1"] + 0.75 * TRUE["a3"] * X * X, abs=1e-11)


@pytest.mark.parametrize("order", [2, 3, 4])
def test_standard_errors_are_the_closed_forms(order):
    sigma = 0.02
    fit = identify.fit_set(*_record(3, sigma, delay=0.15), F, order=order)
    closed = identify.standard_errors(math.sqrt(fit.R), fit.X, fit.samples, order)
    assert set(fit.se) == {"a%d" % i for i in range(order + 1)}
    for name, se in fit.se.items():
        assert se == pytest.approx(closed[name], rel=1e-9), name


def test_order_two_is_the_second_order_fit_bit_for_bit():
    rec = _record(4, 0.01, delay=0.1)
    a, b = identify.fit_set(*rec, F), identify.fit_set(*rec, F, order=2)
    assert a == b
    assert (a.a3, a.a4, a.order) == (0.0, 0.0, 2)


@pytest.mark.parametrize("order", [3, 4])
def test_coverage_of_the_standard_errors_over_seeds(order):
    coeffs = TRUE if order == 4 else {k: v for k, v in TRUE.items() if k != "a4"}
    seeds, sigma = 300, 0.05
    inside = {"a%d" % i: 0 for i in range(order + 1)}
    for seed in range(1, seeds + 1):
        fit = identify.fit_set(*_record(seed, sigma, coeffs=coeffs, delay=0.1, n=2000), F,
                               order=order)
        for name in inside:
            if abs(getattr(fit, name) - coeffs[name]) <= 1.959964 * fit.se[name]:
                inside[name] += 1
    band = 4.0 * math.sqrt(0.95 * 0.05 / seeds)  # four binomial standard deviations
    for name, count in inside.items():
        assert abs(count / seeds - 0.95) <= band, (name, count / seeds)


def test_unresolvable_orders_are_refused():
    # f = 150 Hz at Ts = 1 ms: the 4th harmonic (600 Hz) is above the Nyquist rate (500 Hz)
    t, x, z = _record(1, 0.0, f=150.0)
    with pytest.raises(identify.IdentificationError,
                       match=r"order 4 needs harmonic 4 of f = 150 Hz, 600 Hz, below the Nyquist "
                             r"rate .* allowed: order <= 3"):
        identify.fit_set(t, x, z, 150.0, order=4)
    assert identify.fit_set(t, x, z, 150.0, order=3).order == 3
    with pytest.raises(identify.IdentificationError, match="order = 5; allowed: 2, 3, 4"):
        identify.fit_set(t, x, z, 150.0, order=5)
    assert identify.resolvable_order(150.0, 1e-3) == 3
    assert identify.resolvable_order(124.0, 1e-3) == 4
    assert identify.resolvable_order(125.0, 1e-3) == 3


def test_average_carries_the_order():
    fits = [identify.fit_set(*_record(s, 0.01), F, order=4) for s in (1, 2, 3)]
    avg = identify.average(fits)
    assert avg["order"] == 4 and avg["sets"] == 3
    assert avg["a4"] == pytest.approx(np.mean([f.a4 for f in fits]), rel=1e-12)
    assert avg["sd_a3"] > 0
    assert "a3" not in identify.average([identify.fit_set(*_record(1, 0.01), F)])


def _csv(path, t, x, z):
    with open(path, "w") as fh:
        fh.write("time,x,z\n")
        for row in zip(t, x, z):
            fh.write("%.17g,%.17g,%.17g\n" % row)


def test_cli_identify_order_writes_the_order_and_refuses_an_aliased_one(tmp_path, capsys):
    import json

    from driftfmu.simulations.cli import main
    for s in (1, 2, 3):
        _csv(tmp_path / ("s%d.csv" % s), *_record(s, 0.002, delay=0.1))
    files = [str(tmp_path / ("s%d.csv" % s)) for s in (1, 2, 3)]
    assert main(["identify", *files, "--f", "50", "--order", "4", "--held-out", "1",
                 "--out", str(tmp_path / "o")]) == 0
    out = json.loads((tmp_path / "o" / "identify.json").read_text())
    assert out["order"] == 4 and out["model"]["order"] == 4
    for i in range(5):
        se = out["fits"][0]["se"]["a%d" % i]
        assert abs(out["model"]["a%d" % i] - TRUE["a%d" % i]) <= 5 * se, i
    printed = capsys.readouterr().out
    assert "order 4: a3" in printed and "standard errors" in printed
    # at 150 Hz and Ts = 1 ms the 4th harmonic aliases: a usage error (exit 2, as a drive
    # frequency above the recording's Nyquist rate), one line, nothing written
    _csv(tmp_path / "fast.csv", *_record(1, 0.002, f=150.0))
    rc = main(["identify", str(tmp_path / "fast.csv"), "--f", "150", "--order", "4",
               "--out", str(tmp_path / "p")])
    err = capsys.readouterr().err
    assert rc == 2 and "order 4 needs harmonic 4" in err and "allowed: order <= 3" in err
    assert not (tmp_path / "p").exists()
    with pytest.raises(SystemExit) as exc:  # a usage error
        main(["identify", str(tmp_path / "fast.csv"), "--f", "150", "--order", "5"])
    assert exc.value.code == 2 and "order = 5 is not allowed; allowed: 2, 3, 4" in \
        capsys.readouterr().err
