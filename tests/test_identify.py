"""Identification by harmonic analysis: known a0, a1, a2, R recovered within tolerances derived
from the noise level; CSV recordings; bad input refused with nothing written."""
import json
import math
import os
import warnings

import numpy as np
import pytest

from driftfmu.models import adxl203, identify
from driftfmu.simulations.adxl203 import run_identify
from waiting import BOUND

TRUE = dict(a0=0.3, a1=1.2, a2=0.05, R=0.01 ** 2)
N, SETS, X, F, TS = 4000, 20, 1.0, 50.0, 1e-3


@pytest.fixture(scope="module")
def recordings():
    seeds = np.arange(11, 11 + SETS, dtype=np.uint64)
    phis = np.linspace(0.0, 6.0, SETS)
    c = adxl203.simulate(N, dict(kind=2, X=X, f=F, phi=phis, seed=seeds),
                         dict(TRUE, seed=seeds), dict(), TS)
    return c


def test_whole_periods():
    assert identify.whole_periods(2000, 150.0, 1e-3) == 2000
    assert identify.whole_periods(2010, 150.0, 1e-3) == 2000
    assert identify.whole_periods(60000, 175.0, 1e-4) == 60000


def test_recovers_known_model_within_noise_derived_tolerances(recordings):
    c = recordings
    fits = [identify.fit_set(c["time"][i], c["x"][i], c["z"][i], F) for i in range(SETS)]
    se = identify.standard_errors(math.sqrt(TRUE["R"]), X, N)
    for name, true in TRUE.items():
        v = np.array([getattr(f, name) for f in fits])
        # each set within 5 standard errors; the average of SETS sets within 5 / sqrt(SETS)
        assert np.all(np.abs(v - true) <= 5 * se[name]), name
        assert abs(v.mean() - true) <= 5 * se[name] / math.sqrt(SETS), name
    avg = identify.average(fits)
    assert avg["sets"] == SETS and avg["a2"] == pytest.approx(TRUE["a2"], abs=5 * se["a2"])


def test_a_delay_between_drive_and_output_does_not_leak_into_R():
    # the same part behind a low-pass: harmonic analysis keeps R at the noise level, where a
    # sample-by-sample least-squares fit of z on x would read the lag as noise
    n, f, Ts = 6000, 200.0, 1e-4
    c = adxl203.simulate(n, dict(kind=2, X=1.5, f=f, seed=3), dict(a0=2.5, a1=1.0, a2=0.01,
                         fc=1000.0, density=110e-6, seed=3), dict(), Ts)
    skip = adxl203.settling_samples(1000.0, Ts)
    assert skip == 16
    fit = identify.fit_set(c["time"], c["x"], c["z"], f, skip=skip)
    alpha = math.exp(-2 * math.pi * 1000.0 * Ts)
    noise_var = (110e-6 * math.sqrt(0.5 / Ts)) ** 2 * (1 - alpha) / (1 + alpha)
    assert fit.R == pytest.approx(noise_var, rel=0.1)
    G = (1 - alpha) / (1 - alpha * np.exp(-2j * math.pi * f * Ts))  # the discrete RC filter
    assert fit.lag == pytest.approx(-np.angle(G), rel=0.01)
    assert fit.a1 == pytest.approx(abs(G), rel=2e-3)
    xs, zs = np.array(c["x"]), np.array(c["z"])
    B = np.column_stack([np.ones(n), xs, xs ** 2])
    r = zs - B @ np.linalg.lstsq(B, zs, rcond=None)[0]
    assert r.var() > 50 * fit.R


def _write(path, t, x, z, header="time,x,z"):
    with open(path, "w") as fh:
        fh.write(header + "\n")
        for row in zip(t, x, z):
            fh.write("%.17g,%.17g,%.17g\n" % row)


def test_csv_pipeline_equals_the_in_memory_fit(recordings, tmp_path):
    c = recordings
    files = []
    for i in range(6):
        p = tmp_path / ("set%d.csv" % i)
        _write(p, c["time"][i], c["x"][i], c["z"][i])
        files.append(p)
    s = run_identify(files, F, held_out=2, out=tmp_path / "out")
    direct = identify.average([identify.fit_set(c["time"][i], c["x"][i], c["z"][i], F)
                               for i in range(4)])
    for k in ("a0", "a1", "a2", "R"):
        assert s["model"][k] == pytest.approx(direct[k], rel=1e-12)
    js = json.loads((tmp_path / "out" / "identify.json").read_text())
    assert js["model"]["sets"] == 4 and len(js["held_out"]["dc_ekf1"]) == 2
    assert (tmp_path / "out" / "identify.csv").read_text().startswith("file,dc_empirical")
    for emp, ekf in zip(js["held_out"]["dc_empirical"], js["held_out"]["dc_ekf1"]):
        assert ekf == pytest.approx(TRUE["a2"] * X * X / 2, rel=0.05)


@pytest.mark.parametrize("content,match", [
    ("time,x\n0,1\n0.001,2\n0.002,3\n", r"missing column\(s\) z"),
    ("t,acc,out\n0,1,2\n", r"missing column\(s\) time, x, z: its first row, the header, holds "
                          r"'t', 'acc', 'out'; allowed: a header row"),
    # what the first row holds is quoted: a JSON file's "{", another separator's one cell
    ('{\n  "time": [0, 1]\n}\n', r"missing column\(s\) time, x, z: its first row, the "
                                r"header, holds '\{'; allowed: a header row with columns "
                                r"time, x, z, separated by commas$"),
    ("time;x;z\n0;1;2\n", r"holds 'time;x;z'; allowed"),
    ("\n0,1,2\n", r"holds nothing; allowed"),
    ("time,x,z\n0,1,2\n0.001,oops,3\n0.002,1,1\n", r"line 3, column x: 'oops'"),
    ("time,x,z\n0,1,2\n0.001,nan,3\n0.002,1,1\n", r"line 3, column x: 'nan'"),
    ("time,x,z\n0,1,2\n0.001,1\n0.002,1,1\n", r"line 3, column z"),
    ("time,x,z\n0,1,2\n", "at least 3"),
    ("", "empty file"),
])
def test_bad_csv_is_refused_and_nothing_is_written(recordings, tmp_path, content, match):
    c = recordings
    good = tmp_path / "good.csv"
    _write(good, c["time"][0], c["x"][0], c["z"][0])
    bad = tmp_path / "bad.csv"
    bad.write_text(content)
    with pytest.raises(ValueError, match=match):
        run_identify([good, bad], F, out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_cli_identify_and_its_errors(recordings, tmp_path, capsys):
    from driftfmu.simulations.cli import main
    c = recordings
    _write(tmp_path / "a.csv", c["time"][0], c["x"][0], c["z"][0])
    _write(tmp_path / "b.csv", c["time"][1], c["x"][1], c["z"][1])
    assert main(["identify", str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--f", "50",
                 "--out", str(tmp_path / "o")]) == 0
    assert json.loads((tmp_path / "o" / "identify.json").read_text())["model"]["sets"] == 2
    (tmp_path / "c.csv").write_text("time,x\n0,1\n")
    rc = main(["identify", str(tmp_path / "c.csv"), "--f", "50", "--out", str(tmp_path / "p")])
    assert rc == 1 and "missing column(s) z" in capsys.readouterr().err
    assert not (tmp_path / "p").exists()
    rc = main(["identify", str(tmp_path / "a.csv"), "--f", "900", "--out", str(tmp_path / "q")])
    assert rc == 2 and "Nyquist" in capsys.readouterr().err


def test_one_recording_given_twice_is_refused_before_anything_runs(recordings, tmp_path, capsys):
    """Fitted and held out, the check is no check (45 dB where a recording not fitted gave 13);
    fitted twice, it weighs double."""
    from driftfmu.simulations.cli import main
    c = recordings
    _write(tmp_path / "a.csv", c["time"][0], c["x"][0], c["z"][0])
    _write(tmp_path / "b.csv", c["time"][1], c["x"][1], c["z"][1])
    (tmp_path / "copy.csv").write_bytes((tmp_path / "a.csv").read_bytes())
    a, b, copy = (str(tmp_path / n) for n in ("a.csv", "b.csv", "copy.csv"))
    for files, held_out, said in (
            ([a, b, a], 1, "a.csv is given twice (fitted, then held out)"),
            ([a, os.path.join(str(tmp_path), ".", "a.csv"), b], 1,
             "is given twice (fitted, then fitted)"),
            ([a, b, copy], 1, "copy.csv holds the same recording as %s (fitted, then held out)"
             % a)):
        rc = main(["identify", *files, "--f", "50", "--held-out", str(held_out),
                   "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert rc == 2 and said in err and "allowed: distinct recordings" in err, err
        assert not (tmp_path / "o").exists()
    assert main(["identify", a, b, "--f", "50", "--held-out", "1",
                 "--out", str(tmp_path / "o")]) == 0


# -- fits the data cannot support: errors; doubtful ones: warnings with the figure ---------------

def test_a_drive_frequency_the_recording_contradicts_is_refused(recordings):
    c = recordings
    with pytest.raises(identify.IdentificationError) as exc:
        identify.fit_set(c["time"][0], c["x"][0], c["z"][0], 51.3)  # recorded at 50 Hz
    msg = str(exc.value)
    assert "explains 0." in msg or "explains 1." in msg  # the diagnostic figure, in percent
    assert "strongest frequency is 50 Hz" in msg


def test_a_slightly_wrong_frequency_warns_with_the_share_explained(recordings):
    c = recordings
    with pytest.warns(identify.IdentificationWarning, match=r"explains 9\d\.\d %") as rec:
        fit = identify.fit_set(c["time"][0], c["x"][0], c["z"][0], 50.02)
    assert fit.explained < identify.GOOD_EXPLAINED
    assert "of the fitted R" in str(rec[0].message)
    # and the right frequency fits without a word
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = identify.fit_set(c["time"][0], c["x"][0], c["z"][0], F)
    assert fit.explained > 0.9999 and fit.periods == round(N * F * TS)


def test_too_few_periods_is_an_error_and_few_a_warning(recordings):
    c = recordings
    with pytest.raises(identify.IdentificationError, match=r"at least 2 whole periods"):
        identify.fit_set(c["time"][0][:10], c["x"][0][:10], c["z"][0][:10], F)
    with pytest.warns(identify.IdentificationWarning, match=r"only 6 whole periods"):
        identify.fit_set(c["time"][0][:120], c["x"][0][:120], c["z"][0][:120], F)


def test_one_set_has_no_spread_rather_than_a_spread_of_zero(recordings, tmp_path):
    c = recordings
    fit = identify.fit_set(c["time"][0], c["x"][0], c["z"][0], F)
    avg = identify.average([fit])
    assert avg["sets"] == 1 and avg["sd_a2"] is None and avg["sd_R"] is None
    _write(tmp_path / "one.csv", c["time"][0], c["x"][0], c["z"][0])
    with pytest.warns(identify.IdentificationWarning, match="one recording"):
        s = run_identify([tmp_path / "one.csv"], F)
    assert s["warnings"] and s["model"]["sd_a0"] is None


def test_cli_exit_1_for_a_contradicted_frequency_and_a_warning_line_for_a_doubtful_one(
        recordings, tmp_path, capsys):
    from driftfmu.simulations.cli import main
    c = recordings
    files = []
    for i in range(2):
        files.append(str(tmp_path / ("s%d.csv" % i)))
        _write(files[-1], c["time"][i], c["x"][i], c["z"][i])
    assert main(["identify", *files, "--f", "51.3", "--out", str(tmp_path / "a")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "s0.csv" in err[0] and "strongest frequency is 50 Hz" in err[0]
    assert not (tmp_path / "a").exists()
    assert main(["identify", *files, "--f", "50.02", "--out", str(tmp_path / "b")]) == 0
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("driftfmu: warning: ") for line in lines)
    assert "2 warning(s)" in cap.out
    assert len(json.loads((tmp_path / "b" / "identify.json").read_text())["warnings"]) == 2


# -- the same bits on every machine: the fit does not depend on the BLAS's thread count ----------
def test_a_fit_has_the_same_bits_whatever_the_blas_thread_count():
    """OpenBLAS splits the residual's long dot product between its threads (one per core by
    default), so ``R`` came out with other last bits on a 2-core machine than on a 1-core one;
    the fit calls no BLAS (identify._least_squares) and gives the same bits under any count."""
    from driftfmu.models import _blas
    if not _blas.libraries():
        pytest.skip("no OpenBLAS found in this process (another BLAS, or not Linux)")
    rng = np.random.default_rng(3)
    n, Ts, f = 60_000, 1e-4, 150.0   # long enough for OpenBLAS to thread the dot product
    t = np.arange(n) * Ts
    x = 2.0 * np.sin(2 * math.pi * f * t + 0.3)
    z = 0.01 + x + 0.02 * x * x + 0.01 * rng.standard_normal(n)
    fits = []
    for count in (1, 2, 4):
        with _blas.threads(count):
            fits.append(identify.fit_set(t, x, z, f))
            with _blas.threads(count):   # threads() restores what it found
                pass
            assert [get() for _, get in _blas.libraries()] == [count] * len(_blas.libraries())
    assert fits[0] == fits[1] == fits[2]


def test_a_fit_has_the_same_bits_on_every_processor():
    """OpenBLAS picks its kernels by processor, and LAPACK's least squares gave other last bits
    with its AVX-512 kernels than with its AVX2 ones (the ADXL203 experiment's margins moved):
    the fit calls no BLAS or LAPACK, and gives the same bits under the kernels of every
    processor generation this machine can run (OPENBLAS_CORETYPE picks them)."""
    import platform
    import subprocess
    import sys
    from driftfmu.models import _blas
    if platform.machine() not in ("x86_64", "AMD64") or not _blas.libraries():
        pytest.skip("needs OpenBLAS on x86-64")
    try:
        flags = open("/proc/cpuinfo").read().split()
    except OSError:
        flags = []
    cores = ["Prescott"] + ["Haswell"] * ("avx2" in flags) + ["SkylakeX"] * ("avx512f" in flags)
    script = ("import math, numpy as np\n"
              "from driftfmu.models import identify\n"
              "rng = np.random.default_rng(3)\n"
              "t = np.arange(60000) * 1e-4\n"
              "x = 2.0 * np.sin(2 * math.pi * 150.0 * t + 0.3)\n"
              "z = 0.01 + x + 0.02 * x * x + 0.001 * x ** 3 + 0.01 * rng.standard_normal(60000)\n"
              "for order in (2, 4):\n"
              "    print(repr(tuple(identify.fit_set(t, x, z, 150.0, order=order))))\n")
    outs = {}
    for core in cores:
        p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                           timeout=BOUND, env=dict(os.environ, OPENBLAS_CORETYPE=core))
        assert p.returncode == 0, p.stderr
        outs[core] = p.stdout
    assert len(set(outs.values())) == 1, outs


def test_read_csv_refuses_time_that_does_not_increase_and_reads_time_that_does(tmp_path):
    ok, repeated = tmp_path / "ok.csv", tmp_path / "repeated.csv"
    ok.write_text("time,x,z\n0.0,1,2\n0.001,1,2\n0.002,1,2\n")
    repeated.write_text("time,x,z\n0.0,1,2\n0.001,1,2\n0.001,1,2\n")
    assert list(identify.read_csv(ok)[0]) == [0.0, 0.001, 0.002]
    with pytest.raises(ValueError, match=r"repeated\.csv: time is not strictly increasing; "
                                         r"allowed: uniformly sampled, increasing time"):
        identify.read_csv(repeated)
