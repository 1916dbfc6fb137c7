"""Internal (not a stable API; use driftfmu.experiment_dual_axis instead).

Drift from axis cross-correlation in a dual-axis accelerometer (the letter's conclusion, built).

Two true accelerations ``x, y`` and two outputs, each with its own polynomial and a bilinear
cross term:

.. math::

    z_x = a_0 + a_1 x + a_2 x^2 + b_x x y + v_x, \\qquad
    z_y = a_{0y} + a_{1y} y + a_{2y} y^2 + b_y x y + v_y

so the drift (DC offset) of each axis is ``a2 E[x^2] + bx E[x y]`` and ``a2y E[y^2] + by E[x y]``.
For ``x = X sin(theta)``, ``y = Y sin(theta - dphi)``: ``E[x y] = X Y cos(dphi) / 2``; for the 2-D
Gauss-Markov excitation (:func:`driftfmu.models.excitation.gaussian_pair`): ``E[x y] = rho sigma_x sigma_y``.
A single-axis estimator cannot see the cross term.

The filter is an EKF over ``s = (x, y)`` (Gauss-Markov process ``s_k = A s_{k-1} + w_k``,
``Cov w = [[Q, rho sqrt(Q Qy)], [., Qy]]``) or over two harmonic oscillators at the known
frequency, ``s = (c_x, d_x, c_y, d_y)`` (each rotated as in :mod:`driftfmu.models.harmonic`), with both
outputs as the measurement vector and the 2 x n Jacobian with the cross terms,

.. math::

    H = \\begin{pmatrix} a_1 + 2 a_2 x + b_x y & b_x x \\\\ b_y y & a_{1y} + 2 a_{2y} y + b_y x
        \\end{pmatrix} \\quad \\text{(columns } x, y\\text{; zero columns for } d_x, d_y)

    K = P^- H^T (H P^- H^T + \\mathrm{diag}(R, R_y))^{-1}, \\quad
    s^+ = s^- + K (z - h(s^-)), \\quad
    P^+ = (I - K H) P^- (I - K H)^T + K\\, \\mathrm{diag}(R, R_y) K^T

With a diagonal ``R`` this joint update equals two scalar Joseph updates in turn, both
linearised at the prediction, the second with the innovation corrected by the first,
``e_y = z_y - h_y(s^-) - H_y (s^{(1)} - s^-)`` (the linear Kalman update of the linearised model
processed one output at a time; algebraically identical, no 2 x 2 inverse).  The small matrices
are written out with scalars so an FMU needs only the standard library, and the same code runs
on floats and on NumPy arrays with the same bits.  Each scalar update is arranged so that with
``bx = by = 0`` and no cross covariance (``rho = 0``) every cross contribution is an exact zero:
the filter is then the single-axis filters of :mod:`driftfmu.models.ekf` / :mod:`driftfmu.models.harmonic` on
each axis, bit for bit.

Drift estimators, generalised (``k = 1, 2, ...``, posterior moments of the measured components):

.. math::

    \\text{EKF1:}\\; dc_x = a_2 \\overline{(x^{+2} + P_{xx})} + b_x \\overline{(x^+ y^+ + P_{xy})}

    \\text{EKF2:}\\; dc_{x,k} = \\text{running mean of } a_2 x^{+2}_k + b_x x^+_k y^+_k

    \\text{EKF3:}\\; s_{xx}, s_{xy} = \\text{running means of } x^{+2}, x^+ y^+, \\quad
                    dc_{x,k} = \\text{running mean of } a_2 s_{xx,k} + b_x s_{xy,k}

and likewise for ``y`` with ``a2y, by``; ``b = 0`` gives :mod:`driftfmu.models.drift` bit for bit.
"""
import math
from collections import namedtuple

from . import _ops, covariance, drift, excitation, harmonic, parameters, sensor
from .noise import STREAM_MEASUREMENT, STREAM_MEASUREMENT_Y, normal

GAUSS_MARKOV = harmonic.GAUSS_MARKOV
HARMONIC = harmonic.HARMONIC

#: One axis of the sensor model: ``z = a0 + a1 own + a2 own^2 + b own other + sqrt(R) v``.
Axis = namedtuple("Axis", "a0 a1 a2 b R")

#: Drift estimators of both axes after ``k`` samples: EKF1 sums ``s1``, EKF2 ``dc2``, EKF3
#: ``s3`` and ``dc3``, for the moments ``xx``, ``xy``, ``yy`` and the axes ``x``, ``y``.
DualDrift = namedtuple("DualDrift", "k s1xx s1xy s1yy dc2x dc2y s3xx s3xy s3yy dc3x dc3y")
#: Gauss-Markov filter: posterior ``(x, y)``, covariance ``Pxx, Pxy, Pyy``, drift state.
DualState = namedtuple("DualState", "x y Pxx Pxy Pyy drift")
#: Harmonic filter over ``(c_x, d_x, c_y, d_y)`` = indices 1..4: covariance ``Pij``, drift state.
DualHarmonicState = namedtuple(
    "DualHarmonicState", "x dx y dy P11 P12 P22 P33 P34 P44 P13 P14 P23 P24 drift")

#: Sensor parameters that must be off when ``dual = 1`` (the ADXL203 extras).
EXTRAS = ("a3", "cross", "fc", "Vs", "bits", "density")


# -- the sensor ---------------------------------------------------------------------------------

def axes(p):
    """``(Axis x, Axis y)`` from a mapping of parameters ``a0 a1 a2 bx R a0y a1y a2y by Ry``."""
    return (Axis(p["a0"], p["a1"], p["a2"], p["bx"], p["R"]),
            Axis(p["a0y"], p["a1y"], p["a2y"], p["by"], p["Ry"]))


def measure(x, y, ax, ay, vx, vy):
    """``(z_x, z_y)`` of the dual-axis sensor for standard normal draws ``vx, vy``."""
    return (sensor.measure_bilinear(x, y, ax.a0, ax.a1, ax.a2, ax.b, ax.R, vx),
            sensor.measure_bilinear(y, x, ay.a0, ay.a1, ay.a2, ay.b, ay.R, vy))


def noise(seed, k):
    """The two axes' standard normal measurement draws at sample ``k`` (streams of
    :mod:`driftfmu.models.adxl203`: the x axis is the single-axis sensor's stream)."""
    return normal(seed, STREAM_MEASUREMENT, k), normal(seed, STREAM_MEASUREMENT_Y, k)


def sensor_problems(p):
    """Problems of a dual-axis sensor's parameters (``dual = 1`` needs the extras off)."""
    if not p.get("dual", 0):
        return []
    on = [n for n in EXTRAS if p.get(n, 0)]
    if on:
        return ["dual = 1 is not allowed with %s; allowed: dual = 1 with a3 = cross = fc = "
                "Vs = bits = density = 0 (the bilinear sensor has none of the ADXL203 extras)"
                % ", ".join("%s = %r" % (n, p[n]) for n in on)]
    return []


def cross_moment(kind, X=0.0, Xy=0.0, dphi=0.0, Q=0.0, Qy=0.0, rho=0.0, A=0.0):
    """``E[x y]``: ``X Xy cos(dphi) / 2`` (sinusoids, ``dphi = phi - phiy``) or
    ``rho sqrt(Q Qy) / (1 - A^2)`` (Gauss-Markov)."""
    if kind == excitation.SINUSOIDAL:
        return X * Xy * math.cos(dphi) / 2.0
    return rho * math.sqrt(Q * Qy) / (1.0 - A * A)


def expected_drift(ax, ay, Exx, Exy, Eyy):
    """``(a2 E[x^2] + bx E[xy], a2y E[y^2] + by E[xy])``."""
    return ax.a2 * Exx + ax.b * Exy, ay.a2 * Eyy + ay.b * Exy


def scale(ax, ay, Exx, Exy_max, Eyy):
    """The drifts' scale ``(|a2| E[x^2] + |bx| max|E[xy]|, ...)``, so that an error is judged
    against the size of the drift's terms, not against a drift that crosses zero."""
    return (abs(ax.a2) * Exx + abs(ax.b) * Exy_max, abs(ay.a2) * Eyy + abs(ay.b) * Exy_max)


# -- the filter: one scalar Joseph update of a measurement row with a cross term -----------------

def _row2(o, t, Poo, Pot, Ptt, H, G, e, R):
    """Update ``(own, other)`` with one output whose Jacobian row is ``(H, G)`` (own, other) and
    innovation ``e``; Joseph form.  ``G = Pot = 0`` is :func:`driftfmu.models.ekf.update`, same bits."""
    S = H * H * Poo + (2.0 * H * G * Pot + G * G * Ptt) + R
    Ko = (Poo * H + Pot * G) / S
    Kt = (Pot * H + Ptt * G) / S
    moo = 1.0 - Ko * H
    mot = -Ko * G
    mto = -Kt * H
    mtt = 1.0 - Kt * G
    poo = moo * moo * Poo + (2.0 * moo * mot * Pot + mot * mot * Ptt) + Ko * Ko * R
    col_o = mto * Poo + mtt * Pot      # (P m_t^T), own row
    col_t = mto * Pot + mtt * Ptt      # (P m_t^T), other row
    pot = moo * col_o + mot * col_t + Ko * Kt * R
    ptt = mto * col_o + mtt * col_t + Kt * Kt * R
    return o + Ko * e, t + Kt * e, poo, pot, ptt


def _row4(o, od, t, td, P, H, G, e, R):
    """The same for the harmonic model, states ``1 = own c, 2 = own d, 3 = other c, 4 = other
    d``, Jacobian row ``(H, 0, G, 0)``, ``P = (P11, P12, P22, P13, P14, P23, P24, P33, P34,
    P44)``.  ``G = 0`` with no cross covariance is :func:`driftfmu.models.harmonic.update`, same bits."""
    P11, P12, P22, P13, P14, P23, P24, P33, P34, P44 = P
    S = H * H * P11 + (2.0 * H * G * P13 + G * G * P33) + R
    K1 = (P11 * H + P13 * G) / S
    K2 = (P12 * H + P23 * G) / S
    K3 = (P13 * H + P33 * G) / S
    K4 = (P14 * H + P34 * G) / S
    # M = I - K h, h = (H, 0, G, 0): rows (m11, 0, m13, 0), (m21, 1, m23, 0), (m31, 0, m33, 0),
    # (m41, 0, m43, 1)
    m11, m13 = 1.0 - K1 * H, -K1 * G
    m21, m23 = -K2 * H, -K2 * G
    m31, m33 = -K3 * H, 1.0 - K3 * G
    m41, m43 = -K4 * H, -K4 * G
    p11 = m11 * m11 * P11 + (2.0 * m11 * m13 * P13 + m13 * m13 * P33) + K1 * K1 * R
    a1 = m21 * P11 + P12 + m23 * P13   # (P m_2^T)_1, _3
    a3 = m21 * P13 + P23 + m23 * P33
    p12 = m11 * a1 + m13 * a3 + K1 * K2 * R
    p22 = (m21 * m21 * P11 + 2.0 * m21 * P12 + P22
           + (2.0 * m21 * m23 * P13 + 2.0 * m23 * P23 + m23 * m23 * P33) + K2 * K2 * R)
    b1 = m31 * P11 + m33 * P13         # (P m_3^T)_1.._3
    b2 = m31 * P12 + m33 * P23
    b3 = m31 * P13 + m33 * P33
    c1 = m41 * P11 + m43 * P13 + P14   # (P m_4^T)_1.._4
    c2 = m41 * P12 + m43 * P23 + P24
    c3 = m41 * P13 + m43 * P33 + P34
    c4 = m41 * P14 + m43 * P34 + P44
    p13 = m11 * b1 + m13 * b3 + K1 * K3 * R
    p14 = m11 * c1 + m13 * c3 + K1 * K4 * R
    p23 = m21 * b1 + b2 + m23 * b3 + K2 * K3 * R
    p24 = m21 * c1 + c2 + m23 * c3 + K2 * K4 * R
    p33 = m31 * b1 + m33 * b3 + K3 * K3 * R
    p34 = m31 * c1 + m33 * c3 + K3 * K4 * R
    p44 = m41 * c1 + m43 * c3 + c4 + K4 * K4 * R
    return (o + K1 * e, od + K2 * e, t + K3 * e, td + K4 * e,
            (p11, p12, p22, p13, p14, p23, p24, p33, p34, p44))


def jacobian(x, y, ax, ay):
    """``((Hxx, Hxy), (Hyx, Hyy))``: rows of ``dh/ds`` at ``(x, y)``, columns ``x, y``."""
    return ((sensor.dh_dx(x, ax.a1, ax.a2) + ax.b * y, ax.b * x),
            (ay.b * y, sensor.dh_dx(y, ay.a1, ay.a2) + ay.b * x))


def innovations(x, y, zx, zy, ax, ay):
    """``(z_x - h_x(x, y), z_y - h_y(x, y))``."""
    return (zx - sensor.h_bilinear(x, y, ax.a0, ax.a1, ax.a2, ax.b),
            zy - sensor.h_bilinear(y, x, ay.a0, ay.a1, ay.a2, ay.b))


def update2(x, y, Pxx, Pxy, Pyy, zx, zy, ax, ay):
    """Joint measurement update of the Gauss-Markov filter with ``(z_x, z_y)``, linearised at the
    prediction ``(x, y)``: the two rows in turn (see the module docstring)."""
    (Hxx, Hxy), (Hyx, Hyy) = jacobian(x, y, ax, ay)
    ex, ey = innovations(x, y, zx, zy, ax, ay)
    x1, y1, Pxx1, Pxy1, Pyy1 = _row2(x, y, Pxx, Pxy, Pyy, Hxx, Hxy, ex, ax.R)
    ey = ey - (Hyx * (x1 - x) + Hyy * (y1 - y))
    y2, x2, Pyy2, Pxy2, Pxx2 = _row2(y1, x1, Pyy1, Pxy1, Pxx1, Hyy, Hyx, ey, ay.R)
    return x2, y2, Pxx2, Pxy2, Pyy2


def predict2(x, y, Pxx, Pxy, Pyy, A, Q, Qy, Qxy):
    """Time update ``(A s, A^2 P + Q)`` of the Gauss-Markov filter (as :func:`driftfmu.models.ekf.predict`
    per axis)."""
    AA = A * A
    return A * x, A * y, AA * Pxx + Q, AA * Pxy + Qxy, AA * Pyy + Qy


def predict4(st, C, S, Qh):
    """Time update of the two oscillators: each block as :func:`driftfmu.models.harmonic.predict`, the
    cross block ``F B F^T`` (no cross process noise).  ``st`` is a :class:`DualHarmonicState`;
    returns the tuple ``(x, dx, y, dy, P11, P12, P22, P33, P34, P44, P13, P14, P23, P24)``."""
    return _predict4(st.x, st.dx, st.y, st.dy, st.P11, st.P12, st.P22, st.P33, st.P34, st.P44,
                     st.P13, st.P14, st.P23, st.P24, C, S, Qh)


def _predict4(x, dx, y, dy, P11, P12, P22, P33, P34, P44, P13, P14, P23, P24, C, S, Qh):
    """:func:`predict4` of the state's fields (in the order it returns them)."""
    x, dx, p11, p12, p22 = harmonic.predict(x, dx, P11, P12, P22, C, S, Qh)
    y, dy, p33, p34, p44 = harmonic.predict(y, dy, P33, P34, P44, C, S, Qh)
    f11 = C * P13 + S * P23
    f12 = C * P14 + S * P24
    f21 = C * P23 - S * P13
    f22 = C * P24 - S * P14
    return (x, dx, y, dy, p11, p12, p22, p33, p34, p44,
            C * f11 + S * f12, C * f12 - S * f11, C * f21 + S * f22, C * f22 - S * f21)


def update4(s, zx, zy, ax, ay):
    """Joint measurement update of the harmonic filter (tuple as :func:`predict4` returns)."""
    x, dx, y, dy, P11, P12, P22, P33, P34, P44, P13, P14, P23, P24 = s
    (Hxx, Hxy), (Hyx, Hyy) = jacobian(x, y, ax, ay)
    ex, ey = innovations(x, y, zx, zy, ax, ay)
    x1, dx1, y1, dy1, (q11, q12, q22, q13, q14, q23, q24, q33, q34, q44) = _row4(
        x, dx, y, dy, (P11, P12, P22, P13, P14, P23, P24, P33, P34, P44), Hxx, Hxy, ex, ax.R)
    ey = ey - (Hyx * (x1 - x) + Hyy * (y1 - y))
    # own = y: (cy, dy, cx, dx); P(cy, dx) = P23 and P(dy, cx) = P14 in the storage order
    y2, dy2, x2, dx2, (r33, r34, r44, r13, r23, r14, r24, r11, r12, r22) = _row4(
        y1, dy1, x1, dx1, (q33, q34, q44, q13, q23, q14, q24, q11, q12, q22), Hyy, Hyx, ey, ay.R)
    return x2, dx2, y2, dy2, r11, r12, r22, r33, r34, r44, r13, r14, r23, r24


# -- the drift estimators -----------------------------------------------------------------------

def drift_init():
    """Estimator state before the first sample."""
    return DualDrift(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def drift_update(d, x, y, Pxx, Pxy, Pyy, ax, ay):
    """Fold the ``k``-th posterior moments into the estimators of both axes."""
    k = d.k + 1
    rm = drift.running_mean
    xx, xy, yy = x * x, x * y, y * y
    s3xx, s3xy, s3yy = rm(d.s3xx, xx, k), rm(d.s3xy, xy, k), rm(d.s3yy, yy, k)
    return DualDrift(k, rm(d.s1xx, xx + Pxx, k), rm(d.s1xy, xy + Pxy, k), rm(d.s1yy, yy + Pyy, k),
                     rm(d.dc2x, ax.a2 * xx + ax.b * xy, k), rm(d.dc2y, ay.a2 * yy + ay.b * xy, k),
                     s3xx, s3xy, s3yy,
                     rm(d.dc3x, ax.a2 * s3xx + ax.b * s3xy, k),
                     rm(d.dc3y, ay.a2 * s3yy + ay.b * s3xy, k))


def estimates(d, ax, ay):
    """``((dc1, dc2, dc3) of x, (dc1, dc2, dc3) of y)``."""
    return ((ax.a2 * d.s1xx + ax.b * d.s1xy, d.dc2x, d.dc3x),
            (ay.a2 * d.s1yy + ay.b * d.s1xy, d.dc2y, d.dc3y))


# -- the estimator (EKF + drift estimators) -----------------------------------------------------

def model(process, A=0.0, Q=0.0, Qy=0.0, rho=0.0, f=150.0, Ts=1e-3, Qh=0.0):
    """Constants of the process model, computed once from the scalar parameters."""
    C, S = harmonic.rotation(f, Ts)
    return dict(process=process, A=A, Q=Q, Qy=Qy, Qxy=rho * math.sqrt(Q * Qy), C=C, S=S, Qh=Qh)


def estimator_init(process, x0=0.0, y0=0.0, P0=0.01, P0y=0.01):
    """Filter state before the first sample (no cross covariance, quadratures 0)."""
    if process == GAUSS_MARKOV:
        return DualState(x0, y0, P0, 0.0 * P0, P0y, drift_init())
    if process == HARMONIC:
        z = 0.0 * P0
        return DualHarmonicState(x0, 0.0 * x0, y0, 0.0 * y0, P0, z, P0, P0y, z, P0y, z, z, z, z,
                                 drift_init())
    raise ValueError("process = %r is not allowed; allowed: %s"
                     % (process, ", ".join("%d %s" % kv for kv in harmonic.PROCESSES.items())))


def moments(st):
    """``(x+, y+, Pxx, Pxy, Pyy)`` of the measured components of either filter state."""
    if isinstance(st, DualState):
        return st.x, st.y, st.Pxx, st.Pxy, st.Pyy
    return st.x, st.y, st.P11, st.P13, st.P33


def estimator_predict(st, m):
    """Time update only (a sample without a measurement); the drift state is kept."""
    if m["process"] == GAUSS_MARKOV:
        return DualState(*predict2(st.x, st.y, st.Pxx, st.Pxy, st.Pyy, m["A"], m["Q"], m["Qy"],
                                   m["Qxy"]), st.drift)
    return DualHarmonicState(*predict4(st, m["C"], m["S"], m["Qh"]), st.drift)


def predict_run(st, m, count):
    """Up to ``count`` time updates from ``st`` (samples without a measurement), each from a
    covariance that is valid (:func:`valid`): ``(state, i)`` after ``i`` updates, where ``i ==
    count`` or the covariance of that state is not valid.  The updates of
    :func:`estimator_predict` and the checks of :func:`valid`, the same bits, on the fields
    instead of a state made and checked per sample (a million-sample step of the FMU)."""
    if m["process"] == GAUSS_MARKOV:
        A, Q, Qy, Qxy = m["A"], m["Q"], m["Qy"], m["Qxy"]
        x, y, Pxx, Pxy, Pyy = st.x, st.y, st.Pxx, st.Pxy, st.Pyy
        valid2 = covariance.valid2
        i = 0
        while i < count and valid2(Pxx, Pxy, Pyy):
            x, y, Pxx, Pxy, Pyy = predict2(x, y, Pxx, Pxy, Pyy, A, Q, Qy, Qxy)
            i += 1
        return DualState(x, y, Pxx, Pxy, Pyy, st.drift), i
    C, S, Qh = m["C"], m["S"], m["Qh"]
    f = st[:14]  # x dx y dy P11 P12 P22 P33 P34 P44 P13 P14 P23 P24
    valid_lower = covariance.valid
    i = 0
    while i < count and valid_lower(((f[4],), (f[5], f[6]), (f[10], f[12], f[7]),
                                     (f[11], f[13], f[8], f[9]))):
        f = _predict4(*f, C, S, Qh)
        i += 1
    return DualHarmonicState(*f, st.drift), i


def estimator_step(st, zx, zy, ax, ay, m):
    """One predict/update with ``(z_x, z_y)`` and the drift estimators folded forward."""
    if m["process"] == GAUSS_MARKOV:
        s = update2(*predict2(st.x, st.y, st.Pxx, st.Pxy, st.Pyy, m["A"], m["Q"], m["Qy"],
                              m["Qxy"]), zx, zy, ax, ay)
        new = DualState(*s, st.drift)
    else:
        new = DualHarmonicState(*update4(predict4(st, m["C"], m["S"], m["Qh"]), zx, zy, ax, ay),
                                st.drift)
    return new._replace(drift=drift_update(st.drift, *moments(new), ax, ay))


def from_plain(values):
    """Estimator state from its JSON form (nested lists), either process model."""
    *head, d = values
    kind = DualState if len(values) == len(DualState._fields) else DualHarmonicState
    return kind(*head, DualDrift(*d))


#: Names of the filters' covariance entries (fields of :class:`DualState` and
#: :class:`DualHarmonicState`), in the shape :func:`covariance_of` gives them.
COVARIANCE_NAMES = {GAUSS_MARKOV: (("Pxx",), ("Pxy", "Pyy")),
                    HARMONIC: (("P11",), ("P12", "P22"), ("P13", "P23", "P33"),
                               ("P14", "P24", "P34", "P44"))}


def covariance_of(st):
    """``(process, rows)``: the rows of the lower triangle of the filter's covariance, 2x2 over
    ``(x, y)`` or 4x4 over ``(c_x, d_x, c_y, d_y)``."""
    if isinstance(st, DualState):
        return GAUSS_MARKOV, ((st.Pxx,), (st.Pxy, st.Pyy))
    return HARMONIC, ((st.P11,), (st.P12, st.P22), (st.P13, st.P23, st.P33),
                      (st.P14, st.P24, st.P34, st.P44))


def valid(st):
    """Whether the filter's covariance is valid (:mod:`driftfmu.models.covariance`); a boolean
    array for a batch of runs."""
    _, lower = covariance_of(st)
    if len(lower) == 2:
        return covariance.valid2(lower[0][0], lower[1][0], lower[1][1])
    return covariance.valid(lower)


def check(st, k, seeds=None):
    """Raise :class:`driftfmu.models.covariance.CovarianceError` unless the covariance of the
    filter state after sample ``k`` is valid (a batch: every run; the message names the first
    run that is not, and its ``seeds`` entry)."""
    process, lower = covariance_of(st)
    covariance.check(COVARIANCE_NAMES[process], lower, k, "the dual-axis filter", seeds)


# -- the chain: Excitation -> Accelerometer (dual) -> DualDriftEstimator + two single-axis ones ---

#: Columns of :func:`simulate`, one value per sample.
COLUMNS = ("time", "x", "y", "z_x", "z_y", "x_hat", "y_hat", "P_xx", "P_xy", "P_yy",
           "dc_ekf1_x", "dc_ekf2_x", "dc_ekf3_x", "dc_ekf1_y", "dc_ekf2_y", "dc_ekf3_y",
           "z_comp_x", "z_comp_y", "single_dc_ekf1_x", "single_dc_ekf1_y")


def excitation_values(**values):
    """Excitation start values: ``values`` over the defaults."""
    ex = dict(kind=excitation.GAUSSIAN, A=0.0, Q=0.01, Qy=0.0, rho=0.0, x0=0.0, X=1.0, f=150.0,
              phi=0.0, Xy=0.0, phiy=0.0, seed=1)
    ex.update(values)
    return ex


def sensor_values(**values):
    """Dual-axis accelerometer start values: ``values`` over the defaults (``dual = 1``)."""
    sp = dict(parameters.defaults("a0", "a1", "a2", "R", "bx", "a0y", "a1y", "a2y", "by", "Ry",
                                  "seed"), noise=1, dual=1)
    sp.update(values)
    return sp


def estimator_values(**values):
    """DualDriftEstimator start values: ``values`` over the defaults."""
    es = dict(parameters.defaults("a0", "a1", "a2", "R", "bx", "a0y", "a1y", "a2y", "by", "Ry",
                                  "A", "Q", "Qy", "rho", "x0", "y0", "P0", "P0y", "f", "Qh",
                                  "process"), estimator=1, Qy=0.01)
    es.update(values)
    return es


def single_values(es, axis):
    """Start values of the single-axis DriftEstimator of ``axis`` (1: x, 2: y) beside the dual
    one: that axis's polynomial and process model, blind to the cross term."""
    keys = ("a0", "a1", "a2", "R", "Q", "x0", "P0") if axis == 1 else \
        ("a0y", "a1y", "a2y", "Ry", "Qy", "y0", "P0y")
    out = dict(zip(("a0", "a1", "a2", "R", "Q", "x0", "P0"), (es[k] for k in keys)))
    out.update(A=es["A"], process=es["process"], f=es["f"], Qh=es["Qh"], estimator=1)
    return out


def simulate(n, ex, sp, es, Ts, record=COLUMNS):
    """Run the dual chain for samples ``k = 1..n`` through the same models/ functions as the FMUs
    (the FMUs' start values as dicts by variable name, completed by the defaults above).

    The seeds may be ``uint64`` arrays of shape ``(runs,)`` (a batch): every recorded column is
    then an array ``(runs, n)``; otherwise lists of floats.  Always returned: ``final_<c>`` of
    every column and the realised moments ``mean_xx``, ``mean_xy``, ``mean_yy`` over the run.
    A sample after which a filter's covariance is not valid (:mod:`driftfmu.models.covariance`),
    which the FMUs refuse, raises :class:`driftfmu.models.covariance.CovarianceError` naming the
    run (its seed), the sample and the covariance.
    """
    ex, sp, es = excitation_values(**ex), sensor_values(**sp), estimator_values(**es)
    sx, sy = axes(sp)
    fx, fy = axes(es)
    m = model(es["process"], A=es["A"], Q=es["Q"], Qy=es["Qy"], rho=es["rho"], f=es["f"], Ts=Ts,
              Qh=es["Qh"])
    st = estimator_init(es["process"], es["x0"], es["y0"], es["P0"], es["P0y"])
    singles = []
    for axis in (1, 2):
        s1 = single_values(es, axis)
        C, S = harmonic.rotation(s1["f"], Ts)
        singles.append((s1, dict(process=s1["process"], A=s1["A"], Q=s1["Q"], C=C, S=S,
                                 Qh=s1["Qh"]),
                        harmonic.estimator_init(s1["process"], s1["x0"], s1["P0"])))
    sst = [s[2] for s in singles]
    seeds = sp["seed"] if not _ops.is_scalar(sp["seed"]) else ex["seed"]
    cols = {c: [] for c in record}
    x, y = ex["x0"], 0.0
    mxx = mxy = myy = 0.0
    gaussian = ex["kind"] == excitation.GAUSSIAN
    for k in range(1, n + 1):
        if gaussian:
            x, y = excitation.gaussian_pair(x, y, ex["A"], ex["Q"], ex["Qy"], ex["rho"],
                                            ex["seed"], k)
        else:
            x = excitation.sine(k, ex["X"], ex["f"], Ts, ex["phi"])
            y = excitation.sine(k, ex["Xy"], ex["f"], Ts, ex["phiy"])
        vx, vy = noise(sp["seed"], k) if sp["noise"] else (0.0, 0.0)
        zx, zy = measure(x, y, sx, sy, vx, vy)
        st = estimator_step(st, zx, zy, fx, fy, m)
        check(st, k, seeds)
        dx, dy = estimates(st.drift, fx, fy)
        dcx, dcy = drift.select(dx, es["estimator"]), drift.select(dy, es["estimator"])
        for i, (s1, sm, _) in enumerate(singles):
            sst[i] = harmonic.estimator_step(sst[i], zx if i == 0 else zy, s1["a0"], s1["a1"],
                                             s1["a2"], s1["R"], **sm)
            harmonic.check(sst[i], k, seeds)
        mxx = drift.running_mean(mxx, x * x, k)
        mxy = drift.running_mean(mxy, x * y, k)
        myy = drift.running_mean(myy, y * y, k)
        xh, yh, Pxx, Pxy, Pyy = moments(st)
        row = {"time": (k - 1) * Ts, "x": x, "y": y, "z_x": zx, "z_y": zy, "x_hat": xh,
               "y_hat": yh, "P_xx": Pxx, "P_xy": Pxy, "P_yy": Pyy,
               "dc_ekf1_x": dx[0], "dc_ekf2_x": dx[1], "dc_ekf3_x": dx[2],
               "dc_ekf1_y": dy[0], "dc_ekf2_y": dy[1], "dc_ekf3_y": dy[2],
               "z_comp_x": zx - dcx, "z_comp_y": zy - dcy,
               "single_dc_ekf1_x": singles[0][0]["a2"] * sst[0].drift.s1,
               "single_dc_ekf1_y": singles[1][0]["a2"] * sst[1].drift.s1}
        for c in record:
            cols[c].append(row[c])
    out = {"final_" + c: v for c, v in row.items()}
    out.update(mean_xx=mxx, mean_xy=mxy, mean_yy=myy)
    batch = not _ops.is_scalar(ex["seed"]) or not _ops.is_scalar(sp["seed"])
    if batch:
        import numpy as np
        shape = np.broadcast(np.asarray(ex["seed"]), np.asarray(sp["seed"])).shape
        for c in record:
            cols[c] = np.stack([np.broadcast_to(np.asarray(v, dtype=float), shape)
                                for v in cols[c]], axis=-1)
        out = {key: np.broadcast_to(np.asarray(v, dtype=float), shape).copy()
               for key, v in out.items()}
    out.update(cols)
    return out
