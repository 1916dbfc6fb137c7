"""Internal (not a stable API; use driftfmu.build_fmus instead).

The FMUs' documentation, generated from the slaves' ``VARIABLES`` tables (never by hand).

Two outputs from one source:

- :func:`index_html`: ``documentation/index.html`` inside every FMU (FMI 2.0 and 3.0 both
  define the folder, and importing tools show it), a page that stands alone: the chain's
  general model (to 4th order, the known input ``B u``) and the FMU's own equations, what a
  host must do (sampling, wiring, input files, the step rule, which input matters for which
  settings), what the FMU needs on a host, its variables table (value reference, causality,
  variability, type, unit, range, start, description; FMI 3.0 with its type names and
  ``time``), its units as the model description's UnitDefinitions define them (from
  :func:`driftfmu.fmu_src.builder.unit_definition`, as the model description), and the
  letter.  It links only to files the FMU carries (its model description; the native FMUs'
  ``binaries.txt``; FMI 3.0's ``sources/buildDescription.xml`` and ``licenses/``,
  :func:`entries`) and names no other file.
- :func:`reference_markdown`: the site's FMU reference page ``docs/fmus.md``
  (``python -m driftfmu.fmu_src.documentation > docs/fmus.md`` regenerates it; a test
  regenerates and compares).

Value references follow the order of ``VARIABLES`` (pythonfmu registers in that order; the
native FMUs use the same numbers, FMI 3.0 adds the independent variable ``time`` after them).
"""
import html
from pathlib import Path

from driftfmu import __version__

NAMES = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")

LETTER = ("A. Chorti, D. Karatzas, N. M. White and C. J. Harris, \"Use of the EKF for State "
          "Dependent Drift Estimation in Weakly Nonlinear Sensors\", Sensor Letters 4(4):377-379, "
          "2006")

#: The model of the whole chain, on every FMU's page (sample k at t_k = t_start + (k - 1) Ts).
CHAIN = (
    "x_k = A x_{k-1} + B u_k + w_k,      w_k ~ N(0, Q)      true acceleration [g] (Excitation)\n"
    "u_k = the known input [g]: drive = 0 the host's u_in, 1 N(0, Qu), 2 Xu sin(2 pi fu t_k)\n"
    "z_k = h(x_k) + v_k,                 v_k ~ N(0, R)      sensor output [V] (Accelerometer)\n"
    "h(x) = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4\n"
    "drift dc = E[h(x)] - a0 - a1 E[x] = a2 E[x^2] + a3 E[x^3] + a4 E[x^4]\n"
    "         = a2 E[x^2] + a4 E[x^4] for the zero-mean symmetric states of these FMUs\n"
    "           (E[x^3] = 0: a3 bends h, which the filter models, but adds no drift)\n"
    "x+_k, P+_k = the EKF's estimate of x_k from z_1..z_k and u_1..u_k  (DriftEstimator)\n"
    "z_comp_k = z_k - dc_k                                  drift-compensated output [V]\n"
    "The letter's case: a3 = a4 = 0 and B = 0 (the defaults).")

#: The model equations, one block per FMU (sample k at t_k = t_start + (k - 1) Ts).
EQUATIONS = {
    "Excitation": (
        "kind = 1 (Gauss-Markov):  x_k = A x_{k-1} + B u_k + w_k,  w_k ~ N(0, Q),  x_0 = x0\n"
        "                          y_k = A y_{k-1} + w_y,k, w_y,k ~ N(0, Qy), corr(w_k, w_y,k) = rho\n"
        "kind = 2 (sinusoid):      x_k = X sin(2 pi f t_k + phi),   y_k = Xy sin(2 pi f t_k + phiy)\n"
        "known input (output u):   drive = 0: u_k = u_in (the host's, 0 unless set)\n"
        "                          drive = 1: u_k ~ N(0, Qu),   drive = 2: u_k = Xu sin(2 pi fu t_k)\n"
        "noise: a pure function of (seed, k), the same in any host and at any step size"),
    "Accelerometer": (
        "z_k = a0 + a1 x_k + a2 x_k^2 + a3 x_k^3 + a4 x_k^4 + v_k,   v_k ~ N(0, R)\n"
        "                                       (the letter's eqs. 1, 2, 6: a3 = a4 = 0)\n"
        "ADXL203 stand-in (axes, cross, fc, Vs, bits, density): cross-axis coupling (each axis\n"
        "senses its own acceleration plus cross times the other's), an output low-pass at fc, a\n"
        "ratiometric output at supply Vs, a bits-bit ADC over 0..Vs, noise from density\n"
        "dual = 1:   z_k   = a0  + a1 x_k  + a2 x_k^2  + bx x_k y_k + v_k\n"
        "            z_y,k = a0y + a1y y_k + a2y y_k^2 + by x_k y_k + v_y,k,   v_y,k ~ N(0, Ry)\n"
        "noise = 0: v_k = 0\n"
        "slow errors of the first axis (the letter's drift classes 2-4; each 0 = off):\n"
        "  u_k = clip_range((1 + kT_scale (T_k - T0)) (x_k + sin(theta_k)))   sensed [g]\n"
        "  z_k = Q(h(u_k) + v_k + b_on + rw_k + gm_k + fl_k + d_k + kT_bias (T_k - T0))\n"
        "  b_on = bias_on n_0                                   turn-on, once per seed\n"
        "  rw_k = rw_{k-1} + random_walk sqrt(Ts) n_k,  rw_0 = 0  random walk\n"
        "  gm_k = a gm_{k-1} + bias_gm sqrt(1 - a^2) n_k,  a = exp(-Ts/tau_gm),\n"
        "         gm_0 = bias_gm n_0 (stationary)                bias instability\n"
        "  fl_k = sum_i fl_i,k, fl_i,k = a_i fl_i,k-1 + s sqrt(1 - a_i^2) n_i,k,\n"
        "         a_i = exp(-Ts/tau_i), tau_i = one per decade from tau_min to tau_max,\n"
        "         s: Allan deviation = flicker at sqrt(tau_min tau_max)  flicker (1/f)\n"
        "  E_k = E_{k-1} + x_k^2 Ts,  d_k = d_inf (1 - exp(-E_k / E_tau))  exposure [g^2 s]\n"
        "  clip_range: to [-range, range] when range > 0; Q: the bits-bit ADC, over\n"
        "  a0 +- |a1| range when range > 0 and Vs = 0\n"
        "  each process draws its own noise stream n (a pure function of seed and k); the\n"
        "  FMU state holds rw, gm, E and the flicker components (hidden _err)"),
    "DriftEstimator": (
        "process = 1 (Gauss-Markov):  x- = A x+_{k-1} + B u_k,   P- = A^2 P+_{k-1} + Q\n"
        "process = 2: a harmonic oscillator at f (process noise Qh), no input term\n"
        "h(x) = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4\n"
        "H = h'(x-) = a1 + 2 a2 x- + 3 a3 x-^2 + 4 a4 x-^3,   K = P- H / (H^2 P- + R)\n"
        "x+_k = x- + K (z_k - h(x-)),   P+_k = (1 - K H)^2 P- + K^2 R        (Joseph form)\n"
        "EKF1: dc = a2 s1 + a3 t1 + a4 q1, running means over i <= k of the moments of\n"
        "      N(x+_i, P+_i): s1 <- x+^2 + P+,  t1 <- x+^3 + 3 x+ P+,  q1 <- x+^4 + 6 x+^2 P+ + 3 P+^2\n"
        "      (unbiased)\n"
        "EKF2: dc = mean_{i<=k}(a2 x+_i^2 + a3 x+_i^3 + a4 x+_i^4)        (plug-in: low by about a2 P+)\n"
        "EKF3: s3, t3, q3 = running means of x+^2, x+^3, x+^4;\n"
        "      dc = running mean of a2 s3 + a3 t3 + a4 q3                  (smoother, slower)\n"
        "dc = the estimate of EKF<estimator>,   z_comp = z - dc\n"
        "bias = 1 (process = 1): state [x, b], b_k = F_b b_{k-1} + w_b, w_b ~ N(0, Qb),\n"
        "      F_b = exp(-Ts/tau_b) (1 for tau_b = 0: a random walk), z_k = h(x_k) + b_k + v_k;\n"
        "      b- = F_b b+,  Pxb- = A F_b Pxb+,  Pbb- = F_b^2 Pbb+ + Qb;  update with the row\n"
        "      (H, 1), the innovation z - E[h(x)] - b- (E[h(x)] = h(x-) + a2 P- + ... under\n"
        "      N(x-, P-)) and the variance R + 2 a2^2 P-^2, Joseph form;  z_comp = z - dc - b_hat\n"
        "class 2: dc_class2 = kT_bias (T - T0) + h(g) - a0, g = (1 + kT_scale (T - T0)) sin theta\n"
        "      (the sensor senses (1 + kT_scale (T - T0)) (x + sin theta)); the filter's\n"
        "      measurement is z - dc_class2"),
    "DualDriftEstimator": (
        "state (x, y) (process = 1: Gauss-Markov, covariance [[Q, rho sqrt(Q Qy)], [., Qy]];\n"
        "process = 2: two harmonic oscillators at f), measurement (z_x, z_y) with\n"
        "h_x = a0 + a1 x + a2 x^2 + bx x y,   h_y = a0y + a1y y + a2y y^2 + by x y\n"
        "(the dual-axis bilinear sensor is of 2nd order: no a3, a4, no known input B u)\n"
        "Jacobian [[a1 + 2 a2 x + bx y, bx x], [by y, a1y + 2 a2y y + by x]]; the joint Joseph\n"
        "update with diagonal R is computed as two scalar updates in turn\n"
        "EKF1 per axis: dc_x = a2 mean(x+^2 + P_xx) + bx mean(x+ y+ + P_xy)  (likewise y)\n"
        "EKF2, EKF3 generalise the same way; z_comp_x = z_x - dc_x, z_comp_y = z_y - dc_y"),
}

STEP_RULE = (
    "Sampled-data component: sample k sits at t = t_start + (k - 1) Ts. A step (t, h) accepts "
    "any finite h > 0 and processes the sample instants in [t, t + h) in order with the inputs "
    "held from t (zero-order hold); between instants the outputs hold the last sample. Outputs "
    "that depend on inputs are computed from the inputs set at the same communication point, "
    "so a Gauss-Seidel master (Excitation, Accelerometer, DriftEstimator) has no one-step lag. "
    "One step processes at most 1,000,000 samples. A bad parameter, a non-finite input or an "
    "overflowing output is an error naming the variable, the value and what is allowed, and "
    "the rejected call changes nothing. So is a sample after which a filter's covariance would "
    "have a negative variance or not be positive semi-definite (the numbers exceed what double "
    "precision can carry): every variance must be >= 0, a covariance with a variance of 0 must "
    "be 0, and P + 2^-20 diag(P) must be positive definite on the other rows.")

#: What a host must do, on every FMU's page: (title, paragraph).
HOST_RULES = (
    ("Sampling", "The parameter Ts is the sample period; sample k is taken at t_k = t_start + "
     "(k - 1) Ts. Give every FMU of a chain the same Ts and start time. Any communication step "
     "works (several samples per step, several steps per sample); to see every sample, record "
     "the outputs at every t_k (a result interval of Ts or a divisor of it)."),
    ("Wiring", "Step the FMUs in the order Excitation, Accelerometer, DriftEstimator and, at each "
     "communication point, set an FMU's inputs from the outputs just read upstream before "
     "reading its own outputs (x to x, z to z, u to u): row k then holds x_k, its measurement "
     "z_k and the estimator's k-th update. A master that copies outputs along the connections "
     "only after all FMUs have stepped (a Jacobi master) delays each connection by one step."),
    ("Input files", "A host that runs one FMU at a time from an input file and records the "
     "outputs at t_k before it sets the inputs of t_k (fmpy simulate --input-file, fmusim, the "
     "FMU Compliance Checker) must see the value of sample k already at a communication point "
     "between t_(k-1) and t_k and still at t_k: the file changes to it a quarter period after "
     "t_(k-1) (with two rows at that time, so that the change is a step) and holds it until "
     "a quarter period after t_k. The inputs are declared discrete, so such a host holds "
     "them between rows instead of interpolating. The command 'driftfmu inputs' of the "
     "driftfmu package writes these files from the results upstream; the host then gives the "
     "chain's numbers bit for bit. The Checker needs a step of at most Ts/2 (-h)."),
    ("Errors", "A refused call returns fmi2Error (fmi3Error) and logs its reason with status "
     "error (category logStatusError) whatever loggingOn says, so the host can show it."),
)

#: Which input matters for which settings: (FMU, input) -> when the FMU uses it.
INPUT_USE = {
    ("Excitation", "u_in"):
        "used when drive = 0: it is the known input u_k (the output u), and x adds B u_k when "
        "kind = 1 and B != 0; ignored when drive = 1 or 2",
    ("Accelerometer", "x"): "always: the acceleration the first axis measures",
    ("Accelerometer", "y"):
        "only with a second axis: z_y when axes = 2, z too when cross != 0, both when "
        "dual = 1 (the terms bx x y, by x y); ignored otherwise (the defaults)",
    ("Accelerometer", "theta"):
        "the tilt [rad]: the first axis senses x + sin(theta) (the letter's g-offset); 0 "
        "(the start value): no tilt; ignored when dual = 1",
    ("Accelerometer", "T"):
        "the temperature [K], only when kT_bias != 0 or kT_scale != 0 (the first axis's bias "
        "kT_bias (T - T0) and scale factor 1 + kT_scale (T - T0)); ignored otherwise (the "
        "defaults)",
    ("DriftEstimator", "z"): "always: the measurement z_k",
    ("DriftEstimator", "u"):
        "only when B != 0 and process = 1 (the prediction x- = A x+ + B u_k); connect the "
        "Excitation's u; ignored otherwise (the defaults)",
    ("DriftEstimator", "theta"):
        "whenever it is not 0: the class-2 offset of the tilt (with the temperature's, "
        "dc_class2) is removed from z before filtering; 0 by default (no tilt)",
    ("DriftEstimator", "T"):
        "only when kT_bias != 0 or kT_scale != 0 (the class-2 offset kT_bias (T - T0) and the "
        "scale 1 + kT_scale (T - T0) of the sensed tilt); ignored otherwise (the defaults)",
    ("DualDriftEstimator", "z_x"): "always: the first axis's measurement",
    ("DualDriftEstimator", "z_y"): "always: the second axis's measurement",
}

def input_use(name, row):
    """When FMU ``name`` uses its input ``row`` (:func:`variable_rows`): :data:`INPUT_USE`, or
    for a model of another table its description."""
    return INPUT_USE.get((name, row["name"])) or "as described: %s" % _without_unit(
        row["description"], row["unit"])


#: What each kind of FMU needs and where it is tested.
KINDS = {
    "python": (
        "Python FMU (pythonfmu 0.7.0, FMI 2.0 co-simulation). The model runs in CPython: the "
        "Linux binary (binaries/linux64) is driftfmu's loader shim, which finds a shared "
        "libpython 3.8-3.13 on the host (DRIFTFMU_LIBPYTHON may point at one). Tested here: "
        "linux64 only, the one binary it carries (pythonfmu's stock Windows library is left "
        "out: nothing here loads it); for Windows, macOS, ARM and hosts without Python take "
        "the native FMU."),
    "native": (
        "Native FMU (C, no Python needed). It carries binaries for the platforms listed above "
        "and all its C sources in sources/ (a source FMU: compile with any C99 compiler). "
        "Its results equal the Python FMU's bit for bit (run on x86-64 Linux, on x86-64 "
        "Windows under wine and on aarch64 Linux under qemu; the macOS and ARM Windows "
        "binaries are cross-built and checked by reading them, not run)."),
}


def slave_class(name):
    """The slave class of FMU ``name`` (its ``VARIABLES``)."""
    import importlib
    return getattr(importlib.import_module("driftfmu.fmu_src." + name), name)


def _text(value, kind):
    if value is None:
        return ""
    return str(int(value)) if kind == "Integer" else repr(float(value))


#: FMI 3.0 type names of the tables' types (the native FMI 3.0 FMUs).
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32"}


def variable_rows(name, slave=None, fmi_version=2):
    """One dict per variable of FMU ``name``, in value-reference order (FMI 3.0: with its type
    names and the independent variable ``time`` last, as its model description).

    Keys: ``vr``, ``name``, ``causality``, ``variability``, ``type``, ``unit``, ``min``,
    ``max``, ``start``, ``description`` (all str except ``vr``).
    """
    rows = []
    slave = slave_class(name) if slave is None else slave
    for vr, spec in enumerate(slave.VARIABLES):
        kind = spec["type"]
        rows.append({"vr": vr, "name": spec["name"], "causality": spec["causality"],
                     "variability": spec["variability"],
                     "type": FMI3_TYPES[kind] if fmi_version == 3 else kind,
                     "unit": (spec.get("unit") or "") if kind == "Real" else "",
                     "min": _text(spec.get("min"), kind), "max": _text(spec.get("max"), kind),
                     "start": _text(spec.get("start"), kind),
                     "description": spec.get("description") or ""})
    if fmi_version == 3:
        from driftfmu.fmu_src.native_build import TIME_VARIABLE
        rows.append(dict(TIME_VARIABLE, vr=len(slave.VARIABLES), type="Float64", min="",
                         max="", start=""))
    return rows


COLUMNS = ("vr", "name", "causality", "variability", "type", "unit", "min", "max", "start",
           "description")

_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076"
                                           "\u2077\u2078\u2079")


def unit_text(unit):
    """A unit name as it reads: ``V/g2`` -> ``V/g²``, ``g/sqrt(Hz)`` -> ``g/√Hz``."""
    import re
    unit = re.sub(r"sqrt\(([^)]*)\)", "\u221a\\1", unit)
    return re.sub(r"([A-Za-z])(-?\d+)", lambda m: m.group(1) + m.group(2).translate(
        _SUPERSCRIPT), unit)


def unit_rows(rows):
    """The units the variables ``rows`` use, each as the model description defines it:
    ``(name, how it reads, factor, {SI base unit: exponent} or None)``, sorted by name (None:
    FMI's integer exponents cannot express it, so the model description gives no base units)."""
    from driftfmu.fmu_src.builder import unit_definition
    out = []
    for unit in sorted({r["unit"] for r in rows if r["unit"]}):
        definition = unit_definition(unit)
        if definition is None or any(e.denominator != 1 for e in definition[1].values()):
            out.append((unit, unit_text(unit), None, None))
        else:
            factor, exponents = definition
            out.append((unit, unit_text(unit), factor,
                        {b: int(e) for b, e in exponents.items()}))
    return out


def unit_definition_text(unit, reads, factor, exponents):
    """A unit's definition in SI base units as its ``BaseUnit`` gives it:
    ``1 V/g² = 0.010398211550100477 kg·s·A⁻¹``."""
    from driftfmu.fmu_src.builder import _BASE_UNITS
    if exponents is None:
        return "no base-unit form (FMI's BaseUnit takes integer exponents)"
    bases = "\u00b7".join(b + (str(exponents[b]).translate(_SUPERSCRIPT)
                                if exponents[b] != 1 else "")
                          for b in _BASE_UNITS if b in exponents)
    if not bases and factor == 1.0:
        return "dimensionless"
    if bases == unit and factor == 1.0:
        return "an SI base unit"
    return "1 %s = %s" % (reads, " ".join(p for p in (
        "" if factor == 1.0 else repr(factor), bases) if p))


def _without_unit(description, unit):
    """``description`` without the ``" [unit]"`` that ``slave_base.var`` appends."""
    tail = " [%s]" % (unit or "1")
    return description[:-len(tail)] if description.endswith(tail) else description


def _anchor(unit):
    return "unit-" + unit


def index_html(name, kind, fmi_version, archive_names=(), slave=None):
    """``documentation/index.html`` of FMU ``name``.

    Parameters
    ----------
    name : str
        One of :data:`NAMES`.
    kind : {"python", "native"}
        Which FMU.
    fmi_version : {2, 3}
        Its FMI version.
    archive_names : sequence of str
        The names of the files the FMU carries (its binaries, sources, documentation): the page
        links only to those, and names the folders under ``binaries/``.
    slave : class, optional
        The slave class (its ``VARIABLES``, ``DESCRIPTION``); default ``fmu_src/<name>.py``'s.
    """
    e = html.escape
    slave = slave_class(name) if slave is None else slave
    names = set(archive_names)
    platforms = platforms_of(names)
    description = getattr(slave, "DESCRIPTION", None) or (slave.__doc__ or name).strip()
    rows = variable_rows(name, slave, fmi_version)

    def cell(r, c):
        if c == "unit" and r["unit"]:
            return '<a href="#%s">%s</a>' % (e(_anchor(r["unit"])), e(unit_text(r["unit"])))
        if c == "description":  # (the unit the table's description repeats: in its column)
            return e(_without_unit(r["description"], r["unit"]))
        return e(str(r[c]))
    table = "\n".join("<tr>" + "".join("<td>%s</td>" % cell(r, c) for c in COLUMNS) + "</tr>"
                      for r in rows)
    units = "\n".join(
        '<tr id="%s"><td><code>%s</code></td><td>%s</td><td>%s</td></tr>' % (
            e(_anchor(unit)), e(unit), e(reads),
            e(unit_definition_text(unit, reads, factor, exponents)))
        for unit, reads, factor, exponents in unit_rows(rows))
    inputs = "\n".join("<tr><td>%s</td><td>%s</td></tr>" % (e(r["name"]), e(input_use(
        name, r))) for r in rows if r["causality"] == "input")
    links = ['<a href="../modelDescription.xml">modelDescription.xml</a> (its variables, '
             'units, dependencies)']
    if "documentation/binaries.txt" in names:
        links.append('<a href="binaries.txt">binaries.txt</a> (every binary, its platform '
                     'and compiler)')
    if "sources/buildDescription.xml" in names:
        links.append('<a href="../sources/buildDescription.xml">sources/buildDescription.xml'
                     '</a> (how to compile sources/)')
    extra = ("<p>FMI 3.0: Real is declared Float64 and Integer Int32, with the same value "
             "references; the independent variable <code>time</code> follows them.</p>\n"
             if fmi_version == 3 else "")
    licences = ('<p>Licence: MIT, <a href="licenses/LICENSE.txt">licenses/LICENSE.txt</a>.'
                '</p>\n' if fmi_version == 3 else "<p>Licence: MIT.</p>\n")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<title>%(name)s (driftfmu %(version)s)</title>\n"
        "<style>body{font-family:sans-serif;max-width:70em;margin:1em auto;padding:0 1em}"
        "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:2px 6px;"
        "text-align:left;vertical-align:top}pre{background:#f4f4f4;padding:.5em}</style>\n"
        "</head>\n<body>\n"
        "<h1>%(name)s</h1>\n<p>%(description)s.</p>\n"
        "<p>driftfmu %(version)s, %(kind_title)s FMU, FMI %(fmi)d.0 co-simulation; "
        "binaries: %(platforms)s. In this FMU: %(links)s.</p>\n"
        "<h2>The chain</h2>\n<p>Excitation, Accelerometer and DriftEstimator together are the "
        "general weakly nonlinear sensor of the letter (its eqs. 1-5) with an extended Kalman "
        "filter that estimates the state-dependent drift:</p>\n<pre>%(chain)s</pre>\n"
        "<h2>Equations of %(name)s</h2>\n<pre>%(equations)s</pre>\n"
        "<h2>What a host must do</h2>\n%(host)s"
        "<p>Step rule. %(step_rule)s</p>\n"
        "<h3>Inputs: which matter for which settings</h3>\n"
        "<table>\n<tr><th>input</th><th>used</th></tr>\n%(inputs)s\n</table>\n"
        "<h2>This FMU on a host</h2>\n<p>%(kind_text)s</p>\n"
        "<h2>Variables</h2>\n%(extra)s"
        "<table>\n<tr>%(head)s</tr>\n%(rows)s\n</table>\n"
        "<h2>Units</h2>\n<p>As the model description's UnitDefinitions define them (g is "
        "9.80665 m/s\u00b2).</p>\n"
        "<table>\n<tr><th>name</th><th>reads</th><th>definition</th></tr>\n%(units)s\n"
        "</table>\n"
        "<h2>Reference</h2>\n<p>%(letter)s.</p>\n%(licences)s"
        "</body>\n</html>\n") % dict(
            name=e(name), version=e(__version__), description=e(description.rstrip(".")),
            kind_title="Python" if kind == "python" else "native C", fmi=fmi_version,
            platforms=e(", ".join(platforms) or "none (compile from sources/)"),
            links="; ".join(links), chain=e(CHAIN),
            equations=e(EQUATIONS.get(name, description)),
            host="".join("<p>%s. %s</p>\n" % (e(t), e(p)) for t, p in HOST_RULES),
            step_rule=e(STEP_RULE), inputs=inputs or "<tr><td>none</td><td></td></tr>",
            kind_text=e(KINDS[kind]), extra=extra,
            head="".join("<th>%s</th>" % c for c in COLUMNS), rows=table, units=units,
            letter=e(LETTER), licences=licences)


def license_text():
    """The project's licence (the LICENSE file), for FMI 3.0's ``documentation/licenses/``."""
    for base in (Path(__file__).resolve().parent.parent, Path(__file__).resolve().parent):
        path = base / "LICENSE"
        if path.is_file():
            return path.read_bytes()
    from importlib.metadata import distribution
    for f in distribution("driftfmu").files or ():
        if f.name in ("LICENSE", "LICENSE.txt"):
            return Path(f.locate()).read_bytes()
    return b"MIT License\n\nCopyright (c) driftfmu contributors\n"


def platforms_of(entries):
    """The folder names under ``binaries/`` among the archive names ``entries``."""
    return sorted({n.split("/")[1] for n in entries if n.startswith("binaries/")
                   and n.count("/") >= 2})


def entries(name, kind, fmi_version, archive_names=(), slave=None):
    """The ``documentation/`` files of an FMU: {archive name: bytes}."""
    out = {"documentation/index.html":
           index_html(name, kind, fmi_version, archive_names, slave).encode("utf-8")}
    if fmi_version == 3:
        out["documentation/licenses/LICENSE.txt"] = license_text()
    return out


def _cell(text):
    return str(text).replace("|", "\\|").replace("[", "\\[")


def reference_markdown():
    """The FMU reference page ``docs/fmus.md``: every variable of every FMU."""
    lines = [
        "# FMU reference",
        "",
        "<!-- Generated from the slaves' VARIABLES tables by",
        "     python -m driftfmu.fmu_src.documentation > docs/fmus.md",
        "     Do not edit: tests/test_documentation.py regenerates and compares. -->",
        "",
        "Every variable of every FMU, in value-reference order. The Python FMUs (FMI 2.0) and "
        "the native FMUs (FMI 2.0 and 3.0) share these names, value references, units, ranges "
        "and start values; FMI 3.0 declares Real as Float64 and Integer as Int32 and adds the "
        "independent variable `time` after them. Each FMU also carries this table, the "
        "equations, what a host must do and its units in `documentation/index.html`.",
        "",
        "**The chain.** Excitation, Accelerometer and DriftEstimator together are the general "
        "weakly nonlinear sensor of the letter with an extended Kalman filter that estimates "
        "the state-dependent drift:",
        "",
        "```text",
        CHAIN,
        "```",
        "",
        "**Step rule.** " + STEP_RULE,
        "",
    ] + ["**%s.** %s\n" % rule for rule in HOST_RULES]
    for name in NAMES:
        slave = slave_class(name)
        lines += ["## %s" % name, "", slave.DESCRIPTION.rstrip(".") + ".", "", "```text",
                  EQUATIONS[name], "```", ""]
        lines += ["Input `%s`: %s." % (r["name"], input_use(name, r))
                  for r in variable_rows(name, slave) if r["causality"] == "input"]
        lines += ["", "| " + " | ".join(COLUMNS) + " |",
                  "|" + "---|" * len(COLUMNS)]
        for r in variable_rows(name):
            lines.append("| " + " | ".join(
                ("`%s`" % r[c]) if c == "name" else _cell(r[c]) for c in COLUMNS) + " |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    import sys
    sys.stdout.write(reference_markdown())
