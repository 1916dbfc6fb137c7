"""The layout of a native FMU's serialised state (fmu_src/native/cosimulation.c, ``Snapshot``),
mirrored in ctypes so that a test can change one field of the bytes and put the checksum right
again (a crafted state, as opposed to a corrupted one).

The mirror is checked against the C one where it can be: its size must be the size the FMU
reports, and a real state read through it must show the values the FMU has
(tests/test_native_hardening.py).
"""
import ctypes
from ctypes import c_char, c_double, c_int, c_int32, c_int64, c_uint64

from fmpy import read_model_description

D, I64 = c_double, c_int64


def _struct(name, fields):
    return type(name, (ctypes.Structure,), {"_fields_": fields})


DriftState = _struct("DriftState", [("k", I64)] + [(n, D) for n in (
    "s1", "dc2", "s3", "dc3", "t1", "q1", "t3", "q3")])
HarmonicState = _struct("HarmonicState", [(n, D) for n in ("x", "d", "P", "P12", "P22")]
                        + [("drift", DriftState)])
Bias = _struct("Bias", [(n, D) for n in ("b", "Pxb", "Pbb")])
Axis = _struct("Axis", [(n, D) for n in ("a0", "a1", "a2", "b", "R")])
DualDrift = _struct("DualDrift", [("k", I64)] + [(n, D) for n in (
    "s1xx", "s1xy", "s1yy", "dc2x", "dc2y", "s3xx", "s3xy", "s3yy", "dc3x", "dc3y")])
DualState = _struct("DualState", [(n, D) for n in ("x", "y", "Pxx", "Pxy", "Pyy")]
                    + [("drift", DualDrift)])
DualHarmonicState = _struct("DualHarmonicState", [(n, D) for n in (
    "x", "dx", "y", "dy", "P11", "P12", "P22", "P33", "P34", "P44", "P13", "P14", "P23",
    "P24")] + [("drift", DualDrift)])
DualEstimator = _struct("DualEstimator", [("g", DualState), ("h", DualHarmonicState)])
DualModel = _struct("DualModel", [("process", I64)] + [(n, D) for n in (
    "A", "Q", "Qy", "Qxy", "C", "S", "Qh")])
Config = _struct("Config", [("plain", I64)] + [(n, D) for n in (
    "a0", "a1", "a2", "a3", "R", "sigma", "cross")] + [("has_alpha", I64), ("alpha", D),
                                                        ("lsb", D), ("levels", I64),
                                                        ("a4", D), ("lo", D)])
FLICKER_MAX = 8  # models.errors.FLICKER_MAX
ErrorConfig = _struct("ErrorConfig", [("on", I64)] + [(n, D) for n in (
    "bias_on", "b_on", "rw", "gm_sigma", "gm_a", "gm_c")] + [
    ("fl_n", I64), ("fl_sigma", D), ("fl_a", D * FLICKER_MAX), ("fl_c", D * FLICKER_MAX)] + [
    (n, D) for n in ("d_inf", "E_tau", "Ts", "T0", "kT_bias", "kT_scale", "range")])
ErrorState = _struct("ErrorState", [("rw", D), ("gm", D), ("E", D),
                                    ("fl", D * FLICKER_MAX)])
ErrorKeys = _struct("ErrorKeys", [("rw", c_uint64), ("gm", c_uint64),
                                  ("fl", c_uint64 * FLICKER_MAX), ("v", c_uint64),
                                  ("v_y", c_uint64)])
ErrorTilt = _struct("ErrorTilt", [("theta", D), ("sine", D)])

#: ModelHidden of each model (fmu_src/native/models/<Model>_step.h).
HIDDEN = {
    "Excitation": [("x", D), ("y", D), ("has_pending", c_int32), ("x_pending", D),
                   ("y_pending", D)],
    "Accelerometer": [("cfg", Config), ("ax", Axis), ("ay", Axis), ("ecfg", ErrorConfig),
                      ("keys", ErrorKeys), ("lp_set", I64), ("lpy_set", I64), ("lp", D),
                      ("lpy", D), ("lp_pending_set", I64), ("lpy_pending_set", I64),
                      ("lp_pending", D), ("lpy_pending", D), ("err", ErrorState),
                      ("err_pending", ErrorState), ("tilt", ErrorTilt)],
    "DriftEstimator": [("C", D), ("S", D), ("state", HarmonicState),
                       ("pending", HarmonicState), ("Fb", D), ("bias", Bias),
                       ("bias_pending", Bias)],
    "DualDriftEstimator": [("ax", Axis), ("ay", Axis), ("m", DualModel),
                           ("state", DualEstimator), ("pending", DualEstimator)],
}
#: Hidden values derived from the parameters (model_start computes them).
DERIVED = {"Excitation": (), "Accelerometer": ("cfg", "ax", "ay", "ecfg", "keys"),
           "DriftEstimator": ("C", "S", "Fb"), "DualDriftEstimator": ("ax", "ay", "m")}
#: Hidden variances (>= 0).
VARIANCES = {"P", "P22", "Pxx", "Pyy", "P11", "P33", "P44", "Pbb"}

StateHeader = _struct("StateHeader", [("magic", c_char * 24), ("model", c_char * 32),
                                      ("token", c_char * 64), ("version", c_char * 24),
                                      ("size", c_uint64)])


def snapshot_type(unzipped):
    """The ctypes Snapshot of the native FMU unzipped in ``unzipped``."""
    md = read_model_description(str(unzipped), validate=False)
    variables = [(v.name, D if v.type in ("Real", "Float64") else c_int)
                 for v in md.modelVariables if v.name != "time"]
    ModelVariables = _struct("ModelVariables", variables)
    ModelHidden = _struct("ModelHidden", HIDDEN[md.modelName])
    return _struct("Snapshot", [
        ("header", StateHeader), ("checksum", c_uint64), ("v", ModelVariables),
        ("h", ModelHidden), ("startTime", D), ("time", D), ("elapsed", D), ("elapsed_c", D),
        ("stopTime", D), ("k", I64), ("pending", c_int32), ("dirty", c_int32), ("initialised", c_int32),
        ("state", c_int32)])


def checksum(data):
    """FNV-1a 64 of the snapshot bytes with the checksum field (bytes 152..159) taken as 0."""
    at = ctypes.sizeof(StateHeader)
    h = 14695981039346656037
    for i, byte in enumerate(data):
        h ^= 0 if at <= i < at + 8 else byte
        h = (h * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def leaves(struct, prefix=""):
    """``(path, ctype)`` of every number in a ctypes structure, depth first (path "h.state.P")."""
    out = []
    for name, kind in struct._fields_:
        path = prefix + name
        if isinstance(kind, type) and issubclass(kind, ctypes.Structure):
            out += leaves(kind, path + ".")
        elif not (isinstance(kind, type) and issubclass(kind, ctypes.Array)):
            out.append((path, kind))
    return out


def read(snapshot, data):
    return snapshot.from_buffer_copy(data)


def get(obj, path):
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def put(obj, path, value):
    parts = path.split(".")
    for part in parts[:-1]:
        obj = getattr(obj, part)
    setattr(obj, parts[-1], value)


def crafted(snapshot, data, path, value, fix_checksum=True):
    """``data`` with field ``path`` set to ``value`` (and the checksum made right again)."""
    s = read(snapshot, data)
    put(s, path, value)
    out = bytearray(bytes(s))
    if fix_checksum:
        s.checksum = checksum(out)
        out = bytearray(bytes(s))
    return bytes(out)
