"""Internal (not a stable API; use driftfmu.build_fmus instead).

The FMUs' documentation, generated from the slaves' ``VARIABLES`` tables (never by hand).

Two outputs from one source:

- :func:`index_html`: ``documentation/index.html`` inside every FMU (FMI 2.0 and 3.0 both
  define the folder, and importing tools show it): the model's equations, its step rule, its
  variables table (value reference, causality, unit, range, start, description), what the
  FMU needs on a host, and the reference to the letter.  FMI 3.0 FMUs also carry
  ``documentation/licenses/`` (:func:`entries`).
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

LETTER = ("A. Chorti, K. Karatzas, N. M. White and C. J. Harris, \"Use of the EKF for State "
          "Dependent Drift Estimation in Weakly Nonlinear Sensors\", Sensor Letters 4(4):377-379, "
          "2006")

#: The model equations, one block per FMU (sample k at t_k = t_start + (k - 1) Ts).
EQUATIONS = {
    "Excitation": (
        "kind = 1 (Gauss-Markov):  x_k = A x_{k-1} + w_k,   w_k ~ N(0, Q),   x_0 = x0\n"
        "                          y_k = A y_{k-1} + w_y,k, w_y,k ~ N(0, Qy), corr(w_k, w_y,k) = rho\n"
        "kind = 2 (sinusoid):      x_k = X sin(2 pi f t_k + phi),   y_k = Xy sin(2 pi f t_k + phiy)\n"
        "noise: a pure function of (seed, k), the same in any host and at any step size"),
    "Accelerometer": (
        "z_k = a0 + a1 x_k + a2 x_k^2 + v_k,   v_k ~ N(0, R)            (the letter's eqs. 1, 2, 6)\n"
        "dual = 1:   z_k   = a0  + a1 x_k  + a2 x_k^2  + bx x_k y_k + v_k\n"
        "            z_y,k = a0y + a1y y_k + a2y y_k^2 + by x_k y_k + v_y,k,   v_y,k ~ N(0, Ry)\n"
        "ADXL203 stand-in (axes, a3, cross, fc, Vs, bits, density): cubic term a3 x^3, cross-axis\n"
        "coupling, an output low-pass at fc and a bits-bit ADC over 0..Vs; noise from density\n"
        "noise = 0: v_k = 0"),
    "DriftEstimator": (
        "process = 1 (Gauss-Markov):  x- = A x+,  P- = A^2 P+ + Q   (process = 2: harmonic at f, Qh)\n"
        "H = a1 + 2 a2 x-,  K = P- H / (H^2 P- + R)\n"
        "x+ = x- + K (z - h(x-)),  h(x) = a0 + a1 x + a2 x^2\n"
        "P+ = (1 - K H)^2 P- + K^2 R                                   (Joseph form)\n"
        "EKF1: dc_k = a2 mean_{i<=k}(x+_i^2 + P+_i)                    (unbiased)\n"
        "EKF2: dc_k = mean_{i<=k}(a2 x+_i^2)                           (low by a2 P)\n"
        "EKF3: s_k = mean_{i<=k}(x+_i^2),  dc_k = mean_{i<=k}(a2 s_i)  (smoother, slower)\n"
        "dc = the estimate of EKF<estimator>,  z_comp = z - dc"),
    "DualDriftEstimator": (
        "state (x, y) (process = 1: Gauss-Markov, covariance [[Q, rho sqrt(Q Qy)], [., Qy]];\n"
        "process = 2: two harmonic oscillators at f), measurement (z_x, z_y) with\n"
        "h_x = a0 + a1 x + a2 x^2 + bx x y,   h_y = a0y + a1y y + a2y y^2 + by x y\n"
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
    "precision can carry; the rule: docs/method.md, section 2).")

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
        "binaries are cross-built and checked by reading them, not run). "
        "documentation/binaries.txt lists every binary, its architecture and its compiler."),
}


def slave_class(name):
    """The slave class of FMU ``name`` (its ``VARIABLES``)."""
    import importlib
    return getattr(importlib.import_module("driftfmu.fmu_src." + name), name)


def _text(value, kind):
    if value is None:
        return ""
    return str(int(value)) if kind == "Integer" else repr(float(value))


def variable_rows(name, slave=None):
    """One dict per variable of FMU ``name``, in value-reference order.

    Keys: ``vr``, ``name``, ``causality``, ``variability``, ``type``, ``unit``, ``min``,
    ``max``, ``start``, ``description`` (all str except ``vr``).
    """
    rows = []
    slave = slave_class(name) if slave is None else slave
    for vr, spec in enumerate(slave.VARIABLES):
        kind = spec["type"]
        rows.append({"vr": vr, "name": spec["name"], "causality": spec["causality"],
                     "variability": spec["variability"], "type": kind,
                     "unit": spec.get("unit") or "",
                     "min": _text(spec.get("min"), kind), "max": _text(spec.get("max"), kind),
                     "start": _text(spec.get("start"), kind),
                     "description": spec.get("description") or ""})
    return rows


COLUMNS = ("vr", "name", "causality", "variability", "type", "unit", "min", "max", "start",
           "description")


def index_html(name, kind, fmi_version, platforms=(), slave=None):
    """``documentation/index.html`` of FMU ``name``.

    Parameters
    ----------
    name : str
        One of :data:`NAMES`.
    kind : {"python", "native"}
        Which FMU.
    fmi_version : {2, 3}
        Its FMI version.
    platforms : sequence of str
        The folder names under ``binaries/`` it carries.
    slave : class, optional
        The slave class (its ``VARIABLES``, ``DESCRIPTION``); default ``fmu_src/<name>.py``'s.
    """
    e = html.escape
    slave = slave_class(name) if slave is None else slave
    description = getattr(slave, "DESCRIPTION", None) or (slave.__doc__ or name).strip()
    rows = "\n".join(
        "<tr>" + "".join("<td>%s</td>" % e(str(r[c])) for c in COLUMNS) + "</tr>"
        for r in variable_rows(name, slave))
    extra = ("<p>FMI 3.0: the types are Float64 and Int32 with the same value references; the "
             "independent variable <code>time</code> follows them.</p>\n"
             if kind == "native" and fmi_version == 3 else "")
    licences = ("<p>Licences: <a href=\"licenses/LICENSE.txt\">licenses/LICENSE.txt</a> (MIT)."
                "</p>\n" if fmi_version == 3 else "<p>Licence: MIT.</p>\n")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<title>%(name)s (driftfmu %(version)s)</title>\n"
        "<style>body{font-family:sans-serif;max-width:70em;margin:1em auto;padding:0 1em}"
        "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:2px 6px;"
        "text-align:left;vertical-align:top}pre{background:#f4f4f4;padding:.5em}</style>\n"
        "</head>\n<body>\n"
        "<h1>%(name)s</h1>\n<p>%(description)s</p>\n"
        "<p>driftfmu %(version)s, %(kind_title)s FMU, FMI %(fmi)d.0 co-simulation; "
        "binaries: %(platforms)s.</p>\n"
        "<h2>Equations</h2>\n<pre>%(equations)s</pre>\n"
        "<h2>Step rule</h2>\n<p>%(step_rule)s</p>\n"
        "<h2>This FMU on a host</h2>\n<p>%(kind_text)s</p>\n"
        "<h2>Variables</h2>\n%(extra)s"
        "<table>\n<tr>%(head)s</tr>\n%(rows)s\n</table>\n"
        "<h2>Reference</h2>\n<p>%(letter)s. Our reading of its equations (7)-(12) and the "
        "evidence behind every claim are in the driftfmu documentation "
        "(docs/method.md, docs/evidence.md).</p>\n%(licences)s"
        "</body>\n</html>\n") % dict(
            name=e(name), version=e(__version__), description=e(description),
            kind_title="Python" if kind == "python" else "native C", fmi=fmi_version,
            platforms=e(", ".join(platforms) or "none (compile from sources/)"),
            equations=e(EQUATIONS.get(name, description)), step_rule=e(STEP_RULE), kind_text=e(KINDS[kind]),
            extra=extra, head="".join("<th>%s</th>" % c for c in COLUMNS), rows=rows,
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
           index_html(name, kind, fmi_version, platforms_of(archive_names),
                      slave).encode("utf-8")}
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
        "independent variable `time` after them. Each FMU also carries this table, its "
        "equations and its step rule in `documentation/index.html`.",
        "",
        "**Step rule.** " + STEP_RULE,
        "",
    ]
    for name in NAMES:
        slave = slave_class(name)
        lines += ["## %s" % name, "", slave.DESCRIPTION.rstrip(".") + ".", "", "```text",
                  EQUATIONS[name], "```", "",
                  "| " + " | ".join(COLUMNS) + " |",
                  "|" + "---|" * len(COLUMNS)]
        for r in variable_rows(name):
            lines.append("| " + " | ".join(
                ("`%s`" % r[c]) if c == "name" else _cell(r[c]) for c in COLUMNS) + " |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    import sys
    sys.stdout.write(reference_markdown())
