"""Declarations say what is accepted (issue 31): for every parameter and input of every built FMU
(the Python FMU, the native FMI 2.0 and FMI 3.0 twins), as its model description declares it,
the declared bounds and values between them are accepted and values just outside refused; a
Real takes values that are not whole numbers (a choice of a few is an Integer, as ``kind`` and
``drive`` are).

Where one min/max cannot say what is accepted, the exception is written in the variable's
description and listed in :data:`HOLES` (checked here both ways): a sensitivity of 0 and a supply
voltage between 0 and 3 V.  The other parameters are at their start values; the rules that tie
one parameter to another (a frequency below the Nyquist rate of Ts, the dual sensor without the
ADXL203 extras, effective values that overflow) are in the descriptions and their own tests.
"""
import math

import pytest
from fmpy import read_model_description

from fuzz import differential as diff

pytestmark = pytest.mark.integration

#: Values inside the declared range that are refused, with the words the description uses for
#: them: name -> (test of the value, text in the description).
HOLES = {
    "a1": (lambda v: v == 0.0, "must not be 0"),
    "a1y": (lambda v: v == 0.0, "must not be 0"),
    "Vs": (lambda v: 0.0 < v < 3.0, "otherwise 3 <= Vs <= 6"),
}
INT32 = (-2 ** 31, 2 ** 31 - 1)


@pytest.fixture(scope="module")
def twins(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("declarations"))


def _declared(folder):
    """``[(name, causality, kind, min, max, start, description)]`` of the parameters and inputs
    of the model description in ``folder`` (kind "Real" or "Integer", bounds None if absent)."""
    md = read_model_description(str(folder), validate=False)
    out = []
    for v in md.modelVariables:
        if v.causality not in ("parameter", "input"):
            continue
        kind = "Real" if v.type in ("Real", "Float64") else "Integer"
        convert = float if kind == "Real" else int
        low = None if v.min is None else convert(v.min)
        high = None if v.max is None else convert(v.max)
        out.append((v.name, v.causality, kind, low, high, convert(v.start), v.description))
    return out


def _candidates(kind, low, high, start):
    """``(inside, outside)``: the declared bounds, values between them (whole and not) and the
    start value; the values just outside each declared bound."""
    if kind == "Integer":
        lo, hi = (INT32[0] if low is None else low), (INT32[1] if high is None else high)
        inside = {lo, hi, start, (lo + hi) // 2, min(hi, lo + 1), max(lo, hi - 1)}
        inside |= {v for v in (-7, -1, 0, 1, 2, 3, 100) if lo <= v <= hi}
        outside = {v for v in (lo - 1, hi + 1) if INT32[0] <= v <= INT32[1] and
                   (v < lo or v > hi)}
        return sorted(inside), sorted(outside)
    inside = {start, 1.5, -1.5, 0.37, -0.37, 0.0, 1e-300, -1e-300, 1e-5, 1e5, -1e5, 1e300,
              -1e300}
    if low is not None and high is not None:
        inside |= {low + (high - low) * f for f in (0.25, 0.37, 0.5, 0.9)}
    inside = {v for v in inside if (low is None or v >= low) and (high is None or v <= high)}
    inside |= {b for b in (low, high) if b is not None}
    outside = set()
    if low is not None:
        outside |= {math.nextafter(low, -math.inf), low - 1.0}
    if high is not None:
        outside |= {math.nextafter(high, math.inf), high + 1.0}
    return sorted(inside), sorted(outside)


def _accepts(drv, name, causality, kind, value):
    """Whether the FMU takes ``value`` for ``name``: a parameter set in Initialization Mode with
    the exit that checks it, an input set in Step Mode."""
    drv.reset()
    assert drv.setup(0.0)[0] == diff.OK and drv.enter()[0] == diff.OK
    setter = drv.setr if kind == "Real" else drv.seti
    if causality == "input":
        assert drv.exit()[0] == diff.OK, drv.logged
        return setter([name], [value])[0] == diff.OK
    if setter([name], [value])[0] != diff.OK:
        return False
    return drv.exit()[0] == diff.OK


@pytest.mark.parametrize("backend", diff.BACKENDS)
@pytest.mark.parametrize("name", diff.MODELS)
def test_every_declared_range_is_the_accepted_set(twins, name, backend, report):
    folder = twins[name][backend]
    drv = diff.Driver(folder, 3 if backend.endswith("3") else 2)
    wrong, tried = [], 0
    try:
        for var, causality, kind, low, high, start, description in _declared(folder):
            hole = HOLES.get(var)
            if hole is not None:
                assert hole[1] in description, (var, description)
            inside, outside = _candidates(kind, low, high, start)
            for value in inside + outside:
                expected = value in inside and not (hole and hole[0](value))
                drv.logged = []
                got = _accepts(drv, var, causality, kind, value)
                tried += 1
                if got != expected:
                    wrong.append("%s = %r (%s %s, declared [%s, %s]): %s" % (
                        var, value, kind, causality, low, high,
                        "accepted" if got else "refused: %s" % [m for _, m in drv.logged][-1:]))
    finally:
        drv.free()
    report("DECLARATIONS %s %s: %d values tried against the model description, %d differ"
           % (name, backend, tried, len(wrong)))
    assert wrong == [], "\n".join(wrong)


def test_the_holes_are_refused_as_their_descriptions_say(twins):
    """The exceptions of HOLES are real: each is refused (a value of the hole) by the Python FMU
    (the twins agree call by call in the test above)."""
    cases = {"Accelerometer": [("a1", 0.0), ("a1y", 0.0), ("Vs", 1.5)],
             "DriftEstimator": [("a1", 0.0)], "DualDriftEstimator": [("a1y", 0.0)]}
    for name, values in cases.items():
        drv = diff.Driver(twins[name]["python"], 2)
        try:
            for var, value in values:
                assert not _accepts(drv, var, "parameter", "Real", value), (name, var)
                assert _accepts(drv, var, "parameter", "Real", 4.5 if var == "Vs" else 0.5)
        finally:
            drv.free()
