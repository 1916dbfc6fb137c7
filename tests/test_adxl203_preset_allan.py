"""The ADXL203 preset's noise read back as a datasheet reader would: ``driftfmu allan`` on the
preset's output at rest gives the white-noise figure ``N`` of its noise density, within the
tolerance of the reading's own degrees of freedom."""
import math

import pytest

import driftfmu
from driftfmu.models import adxl203


def _preset_start_values():
    p = adxl203.ADXL203
    sv = {"Q": 0.0}  # the excitation at rest: z is the preset's noise (and its ADC's)
    sv.update({"Accelerometer.%s" % k: p[k] for k in ("a0", "a1", "a2", "a3", "density", "fc",
                                                        "Vs", "bits")})
    return sv


@pytest.mark.integration
def test_allan_reads_the_presets_noise_density_back(built_fmus):
    """The preset's density (110 ug/sqrt(Hz), the datasheet's typical noise floor at 5 V) is a
    one-sided density: white noise of ``sigma = density sqrt(fs / 2)`` [g], ``a1 = 1 V/g``;
    its 12-bit ratiometric ADC over 5 V adds ``LSB^2 / 12``.  The Allan reading of white noise
    is ``N = sqrt(sigma_V^2 Ts)`` (``sigma(tau) = N / sqrt(tau)``), that is ``density / sqrt(2)``
    plus the ADC's share (1 %).  20 s at 1 ms: the reading's standard error in log is about
    1 % (``se_log``, from the equivalent degrees of freedom of the octaves it is fitted on);
    the test allows three of them, both sides."""
    p = adxl203.ADXL203
    res = driftfmu.allan(None, column="z", start_values=_preset_start_values(), stop_time=20.0,
                         fmu_dir=built_fmus["Accelerometer"].parent)
    N = res["N"]
    assert N["reason"] is None and N["value"] is not None
    Ts = res["Ts"]
    sigma = p["a1"] * adxl203.noise_sigma(p["density"], Ts)  # [V]
    lsb = p["Vs"] / 2 ** p["bits"]
    expected = math.sqrt((sigma * sigma + lsb * lsb / 12.0) * Ts)
    tol = 3.0 * N["se_log"]
    assert 0.0 < N["se_log"] < 0.05
    assert abs(math.log(N["value"] / expected)) <= tol, (N, expected)
    # the datasheet's figure, read off as a user would (N sqrt(2) / a1), within the tolerance
    # and the ADC's share
    density = N["value"] * math.sqrt(2.0) / p["a1"]
    assert abs(math.log(density / p["density"])) <= tol + math.log(expected * math.sqrt(2.0)
                                                                   / (p["a1"] * p["density"]))
    # two-sided: a density 10 % off would be seen
    assert abs(math.log(N["value"] / (1.1 * expected))) > tol
