"""No OK carries a negative variance, in every twin (issue 31): the Python FMU, the native FMI 2.0
and FMI 3.0 FMUs refuse the sample whose covariance leaves the rule of models/covariance.py with
the same message, change nothing, and accept back every state they gave after an OK call; a
state whose covariance is not valid is refused by each (tests/test_covariance.py has the rule
and the Python slaves in-process)."""
import json
import math

import pytest

from fuzz import differential as diff
from fuzz import native_state as ns

pytestmark = pytest.mark.integration
CAUSE = "the inputs and parameters exceed what double precision can carry"


@pytest.fixture(scope="module")
def twins(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("covariance"))


def _run(dirs, script):
    """``{backend: rows}`` of diff.run_script, and after every call that answered OK a state
    got then and set back at once (``gst``/``sst`` into slot 9): its statuses."""
    out = {}
    for backend in diff.BACKENDS:
        drv = diff.Driver(dirs[backend], 3 if backend.endswith("3") else 2)
        try:
            rows, restores = [], []
            for call in script:
                rows += diff.run_script(drv, [call])
                if rows[-1][0] == diff.OK and call[0] in ("exit", "step", "getr", "setr"):
                    restores.append((json.dumps(call), drv.gst(9)[0], drv.sst(9)[0]))
            out[backend] = (rows, restores)
        finally:
            drv.free()
    return out


def _steps(t0, h, n, inputs):
    script, t = [], t0
    for _ in range(n):
        script += [["setr", list(inputs), list(inputs.values())], ["getr", ["P" if "z" in
                                                                           inputs else "P_xx"]],
                   ["step", t, h]]
        t += h
    return script


CASES = {
    # the issue: P0 = 1e154, x0 = 3e8, z = 0, six steps of 0.1 s
    "harmonic-1e154": ("DriftEstimator", [["seti", ["process"], [2]],
                                          ["setr", ["P0", "x0"], [1e154, 3e8]]],
                       _steps(0.0, 0.1, 6, {"z": 0.0}), 76, "hidden state _state.P22"),
    # P0 = 1e16, steps of 10 Ts: sample 16, predict-only inside the second step (sample 20,
    # the step's end, is valid again)
    "harmonic-1e16": ("DriftEstimator", [["seti", ["process"], [2]], ["setr", ["P0"], [1e16]]],
                      _steps(0.0, 1e-2, 4, {"z": 0.0}), 16, "hidden state _state.P22"),
    # P0 = 1e16, steps of 2 Ts: sample 3, pending at t = 2 ms (read there: refused)
    "harmonic-1e16-read": ("DriftEstimator", [["seti", ["process"], [2]],
                                              ["setr", ["P0"], [1e16]]],
                           _steps(0.0, 2e-3, 4, {"z": 0.0}), 3, "hidden state _state.P22"),
    # the DualDriftEstimator's hidden P44, P0y = 1e16, steps of 10 Ts (sample 16: predict-only)
    "dual-P44": ("DualDriftEstimator", [["seti", ["process"], [2]], ["setr", ["P0y"], [1e16]]],
                 _steps(0.0, 1e-2, 3, {"z_x": 0.0, "z_y": 0.0}), 16,
                 "hidden state _state.P44"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_issues_cases_are_refused_alike_and_every_ok_state_restores(twins, case, report):
    name, setup, steps, sample, subject = CASES[case]
    script = [["setup", 0.0], ["enter"]] + setup + [["exit"]] + steps
    results = _run(twins[name], script)
    assert diff.compare(script, {b: r[0] for b, r in results.items()}) == []
    rows, restores = results["python"]
    refused = [(call, row) for call, row in zip(script, rows) if row[0] != diff.OK]
    assert refused and all(call[0] in ("step", "getr") for call, _ in refused), refused
    texts = {b: [row[3][0] for row in r[0] if row[0] != diff.OK] for b, r in results.items()}
    assert texts["python"] == texts["native-fmi2"] == texts["native-fmi3"], texts
    first = texts["python"][0]
    assert first.startswith("fuzz: %s would be " % subject) and " at sample %d (" % sample \
        in first and CAUSE in first and "(nothing was changed)" in first, first
    # no OK value is a negative variance, and every state got after an OK call restores
    for backend, (rows, restores) in results.items():
        for call, row in zip(script, rows):
            if call[0] == "getr" and row[0] == diff.OK:
                assert float.fromhex(row[1][0]) >= 0.0, (backend, call, row)
        assert restores and all(g == s == diff.OK for _, g, s in restores), (backend, restores)
    report("COVARIANCE %s: %d calls, refused alike in the three twins: %s"
           % (case, len(script), first))


#: A crafted filter state whose covariance is not valid: (model, native field, Python index in
#: the JSON ``_state`` list, value).
CRAFTED = [("DriftEstimator", "P12", 3, 10.0), ("DriftEstimator", "P22", 4, -1e-300),
           ("DualDriftEstimator", "P44", 13, -1.0), ("DualDriftEstimator", "P13", 10, 10.0)]


@pytest.mark.parametrize("backend", diff.BACKENDS)
@pytest.mark.parametrize("name, field, index, value", CRAFTED,
                         ids=["%s-%s" % (c[0], c[1]) for c in CRAFTED])
def test_a_state_whose_covariance_is_not_valid_is_refused(twins, backend, name, field, index,
                                                          value):
    drv = diff.Driver(twins[name][backend], 3 if backend.endswith("3") else 2)
    try:
        for call in (["setup", 0.0], ["enter"], ["seti", ["process"], [2]], ["exit"],
                     ["step", 0.0, 2e-3]):
            assert getattr(drv, call[0])(*call[1:])[0] == diff.OK, drv.logged
        assert drv.gst(0)[0] == diff.OK
        data = drv.ser(0)[1]
        if backend == "python":
            state = json.loads(data)
            state["_state"][index] = value
            blob = json.dumps(state).encode()
        else:
            S = ns.snapshot_type(twins[name][backend])
            path = "h.state.%s%s" % ("h." if name == "DualDriftEstimator" else "", field)
            blob = ns.crafted(S, data, path, value)
        drv.logged = []
        status = drv.des(blob, 1)[0]
        if status == diff.OK:  # (a Python state is checked when set)
            status = drv.sst(1)[0]
        text = " ".join(m for _, m in drv.logged)
        assert status == diff.ERROR, text
        assert "negative variance" in text or "not positive semi-definite" in text, text
        assert drv.des(data, 1)[0] == diff.OK and drv.sst(1)[0] == diff.OK  # the real one does
        assert math.isfinite(float.fromhex(drv.getr(["x_hat"])[1][0]))
    finally:
        drv.free()
