"""Defaults written into artifacts are models/parameters.py's, to the bit (issue 38: the SSP's
default stop time one sample late passed every test).

Each artifact that writes a default is read back and compared with ``PARAMETERS`` exactly (a
value one ulp or one sample off fails): the SSP archive's default experiment (its stop time
``(n - 1) Ts``, the last sample's instant), its master's step and its parameter sets; every FMU's
model description, Python and native FMI 2.0 and 3.0 (the default experiment, and each
parameter's start, min and max); docs/fmus.md, the reference page the users read.
"""
import inspect
import re
from pathlib import Path

import fmpy
import pytest

from driftfmu.fmu_src import ssp
from driftfmu.models import adxl203, parameters
from driftfmu.simulations import gaussian

ROOT = Path(__file__).resolve().parent.parent
P = parameters.PARAMETERS
#: Where an FMU declares other than PARAMETERS on purpose (its VARIABLES say so): the stand-in's
#: bandwidth is at most the datasheet's 2500 Hz; the dual filter's second axis moves by default.
OVERRIDES = {("Accelerometer", "fc", "max"): adxl203.MAX_BANDWIDTH,
             ("DualDriftEstimator", "Qy", "start"): 0.01}


def _declared(fmu, name, what):
    """What FMU ``fmu`` declares as the ``what`` (start, min, max) of parameter ``name``."""
    if (fmu, name, what) in OVERRIDES:
        return OVERRIDES[fmu, name, what]
    if what == "start":
        return P[name].default
    return parameters.declared_range(name)[what == "max"]


def _same(text, value):
    """``text`` (an XML or Markdown number) is exactly ``value``."""
    return (int(text) == value) if isinstance(value, int) else float(text) == float(value)


def test_the_ssps_defaults_are_the_parameters_defaults():
    sig = inspect.signature(ssp.build_ssp).parameters
    assert sig["n"].default == P["n"].default and sig["Ts"].default == P["Ts"].default
    starts = gaussian.start_values()
    for fmu, values in starts.items():
        for name, value in values.items():
            if name == "P0":  # the stationary variance Q / (1 - A^2) at the defaults
                assert value == P["Q"].default / (1 - P["A"].default ** 2)
            elif name in P:
                assert value == P[name].default, (fmu, name, value)


@pytest.mark.integration
@pytest.mark.parametrize("n,Ts", [(2000, 1e-3), (37, 2e-3), (1, 1e-3), (1000, 3e-4)])
def test_the_ssps_default_experiment_ends_at_the_last_sample(python_fmus, n, Ts, tmp_path):
    import zipfile
    import xml.etree.ElementTree as ET
    starts = gaussian.start_values(Ts=Ts, seed=3, A=0.4)
    archive = ssp.build_ssp(python_fmus, tmp_path / "chain.ssp", starts, n, Ts)
    with zipfile.ZipFile(archive) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
        sets = {name: ET.fromstring(z.read(name)) for name in z.namelist()
                if name.endswith(".ssv")}
    experiment = root.find("{%s}DefaultExperiment" % ssp.NS["ssd"])
    assert float(experiment.get("startTime")) == 0.0
    assert float(experiment.get("stopTime")) == (n - 1) * Ts  # sample n's instant, to the bit
    master = next(e for e in root.iter() if e.tag.endswith("FixedStepMaster"))
    assert float(master.get("stepSize")) == Ts
    written = {}
    for comp in root.iter("{%s}Component" % ssp.NS["ssd"]):
        # each component's values: its parameter set, the .ssv its ParameterBinding names
        for binding in comp.iter("{%s}ParameterBinding" % ssp.NS["ssd"]):
            for p in sets[binding.get("source")].iter("{%s}Parameter" % ssp.NS["ssv"]):
                written[comp.get("name"), p.get("name")] = p[0].get("value")
    expected = {(fmu, name): value for fmu, values in starts.items()
                for name, value in values.items()}
    assert set(written) == set(expected)
    for key, value in expected.items():
        assert _same(written[key], value), (key, written[key], value)


def _fmus(python_fmus, native_fmus):
    out = [("python", name, path) for name, path in python_fmus.items()]
    out += [("native-fmi%d" % v, name, path) for v, paths in native_fmus.items()
            for name, path in paths.items()]
    return out


@pytest.mark.integration
def test_every_fmus_model_description_writes_the_parameters_defaults(python_fmus, native_fmus):
    wrong, checked = [], 0
    for kind, name, path in _fmus(python_fmus, native_fmus):
        md = fmpy.read_model_description(str(path), validate=False)
        d = md.defaultExperiment
        # 0 to 2 s in steps of the default Ts: 2001 samples (slave_base.DEFAULT_EXPERIMENT)
        for what, got, want in (("startTime", d.startTime, 0.0),
                                ("stepSize", d.stepSize, P["Ts"].default),
                                ("stopTime", d.stopTime, 2000 * P["Ts"].default)):
            if float(got) != want:
                wrong.append("%s %s %s = %r, not %r" % (kind, name, what, got, want))
        for v in md.modelVariables:
            if v.causality != "parameter" or v.name not in P:
                continue
            for what in ("start", "min", "max"):
                got, want = getattr(v, what), _declared(name, v.name, what)
                checked += 1
                if (got is None) != (want is None) or (got is not None
                                                       and not _same(got, want)):
                    wrong.append("%s %s %s %s = %r, not %r" % (kind, name, v.name, what, got,
                                                               want))
    assert checked > 200
    assert wrong == []


def test_the_reference_page_writes_the_parameters_defaults():
    text = (ROOT / "docs" / "fmus.md").read_text(encoding="utf-8")
    row = re.compile(r"^\| \d+ \| `(\w+)` \| parameter \| \w+ \| (\w+) \| [^|]* \| ([^|]*) \| "
                     r"([^|]*) \| ([^|]*) \|", re.M)
    seen = 0
    for section in re.split(r"^## ", text, flags=re.M)[1:]:
        fmu = section.split()[0].strip("`")
        for name, kind, low, high, start in row.findall(section):
            if name not in P:
                continue
            seen += 1
            for what, got in (("start", start), ("min", low), ("max", high)):
                got, want = got.strip(), _declared(fmu, name, what)
                assert (got == "") == (want is None), (fmu, name, what, got, want)
                if want is not None:
                    assert _same(got, want), (fmu, name, what, got, want)
    assert seen > 40
