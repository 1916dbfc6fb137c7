"""The general sensor in the FMUs' step logic, at communication steps longer and shorter than
``Ts`` (issue 32): the samples of a long step that have no measurement, with the known input.

The three slaves (Python, without building FMUs) run under a Gauss-Seidel master that wires
``Excitation.u -> DriftEstimator.u``; Hypothesis draws ``Ts``, ``A``, ``B`` (both signs),
``a2``, ``a3``, ``a4`` (both signs, alone and together), the input's drive (0: the host's
``u_in``, changed at every communication point; 1 Gaussian; 2 sinusoidal at ``fu``), the
estimator feeding ``z_comp`` and a sequence of steps of 1/4 to 5 sample periods.  Every
output at every communication point is compared with a reference written here from the FMI
timing rule alone (docs/method.md, "The input in every master"; docs/evidence.md, FMU step
logic) and the letter's equations written out in plain Python (not models/):

- the Excitation computes every sample, ``x_k = A x_{k-1} + B u_k + sqrt(Q) w_k``, with the
  drive's ``u_k`` at each sample, or the host's ``u_in`` held from the step's start;
- the Accelerometer measures ``h(x) + sqrt(R) v_k`` with its input held, every sample;
- the DriftEstimator updates once per step at its first instant, with the ``z`` and ``u`` held
  from the step's start, and only predicts, ``A x + B u`` with that held ``u``, at the other
  instants of the step; the three estimators fold in one posterior per update.

Also the harmonic filter with ``a3``, ``a4`` (its three estimators; the 2x2 update written out
here) and the ADXL203 stand-in's ratiometric supply scaling of ``a4``.
"""
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, strategies as st

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.models import noise

from general_closed_forms import prop
from test_hardening import get, put, ready, vr

#: Relative agreement of the slaves with the reference written here: the same operations in
#: other orders, and math.sin against models/' arithmetic-only sine.
CLOSE = 1e-9
QUOTIENTS = [Fraction(1, 4), Fraction(3, 10), Fraction(1, 2), Fraction(1), Fraction(3, 2),
             Fraction(2), Fraction(5, 2), Fraction(3), Fraction(5)]










DE_OUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")


def run_slaves(p, quotients, host_u):
    """The chain stepped by ``h_i = q_i Ts``: per communication point ``(x, u, z, x_hat, P,
    dc_ekf1, dc_ekf2, dc_ekf3, z_comp)``.  ``host_u[i]``: the host's ``u_in`` at point ``i``
    (``drive = 0``)."""
    e = ready(Excitation, A=p["A"], Q=p["Q"], B=p["B"], drive=p["drive"], Qu=p["Qu"],
              Xu=p["Xu"], fu=p["fu"], Ts=p["Ts"], seed=p["seed"])
    a = ready(Accelerometer, a0=p["a0"], a1=p["a1"], a2=p["a2"], a3=p["a3"], a4=p["a4"],
              R=p["R"], Ts=p["Ts"], seed=p["seed"])
    d = ready(DriftEstimator, a0=p["a0"], a1=p["a1"], a2=p["a2"], a3=p["a3"], a4=p["a4"],
              R=p["R"], A=p["A"], Q=p["Q"], B=p["B"], x0=0.0, P0=p["P0"], Ts=p["Ts"],
              estimator=p["estimator"])
    rows, t = [], 0.0
    for i in range(len(quotients) + 1):
        if p["drive"] == 0:
            put(e, "u_in", host_u[i])
        put(a, "x", get(e, "x"))
        put(d, "z", get(a, "z"))
        put(d, "u", get(e, "u"))
        rows.append((get(e, "x"), get(e, "u"), get(a, "z")) + tuple(get(d, n)
                                                                      for n in DE_OUTS))
        if i == len(quotients):
            break
        h = float(quotients[i]) * p["Ts"]
        assert [s.do_step(t, h) for s in (e, a, d)] == [True] * 3, \
            [m.msg for s in (e, a, d) for m in s.log_queue]
        t += h
    return rows


class Filter:
    """The letter's scalar EKF with ``B u`` and ``h`` up to 4th order, and its three drift
    estimators (docs/method.md sections 2, 3 and 9), written out."""

    def __init__(self, p):
        self.p = p
        self.x, self.P = 0.0, p["P0"]
        self.k = 0
        self.s1 = self.t1 = self.q1 = self.dc2 = self.s3 = self.t3 = self.q3 = self.dc3 = 0.0

    def predict(self, u):
        p = self.p
        self.x, self.P = p["A"] * self.x + p["B"] * u, p["A"] ** 2 * self.P + p["Q"]

    def update(self, z):
        p, x, P = self.p, self.x, self.P
        H = p["a1"] + 2 * p["a2"] * x + 3 * p["a3"] * x ** 2 + 4 * p["a4"] * x ** 3
        K = P * H / (H * H * P + p["R"])
        hx = p["a0"] + p["a1"] * x + p["a2"] * x ** 2 + p["a3"] * x ** 3 + p["a4"] * x ** 4
        self.x = x + K * (z - hx)
        self.P = (1 - K * H) ** 2 * P + K * K * p["R"]
        self.fold(self.x, self.P)

    def fold(self, x, P):
        p = self.p
        self.k += 1
        k = self.k

        def mean(m, v):
            return ((k - 1) * m + v) / k
        self.s1 = mean(self.s1, x * x + P)
        self.t1 = mean(self.t1, x ** 3 + 3 * x * P)
        self.q1 = mean(self.q1, x ** 4 + 6 * x * x * P + 3 * P * P)
        self.dc2 = mean(self.dc2, p["a2"] * x * x + p["a3"] * x ** 3 + p["a4"] * x ** 4)
        self.s3, self.t3, self.q3 = (mean(self.s3, x * x), mean(self.t3, x ** 3),
                                     mean(self.q3, x ** 4))
        self.dc3 = mean(self.dc3, p["a2"] * self.s3 + p["a3"] * self.t3 + p["a4"] * self.q3)

    def outputs(self, z_in):
        p = self.p
        dcs = (p["a2"] * self.s1 + p["a3"] * self.t1 + p["a4"] * self.q1, self.dc2, self.dc3)
        return (self.x, self.P) + dcs + (z_in - dcs[p["estimator"] - 1],)

    def copy(self):
        other = Filter(self.p)
        other.__dict__.update(self.__dict__)
        return other


def reference(p, quotients, host_u):
    """The rows of :func:`run_slaves` from the timing rule: sample ``k`` (instant ``(k-1) Ts``)
    takes the inputs set at the communication point that starts the step it falls in; at an
    instant the outputs are that sample's, between instants they hold the last one's."""
    positions = [Fraction(0)]
    for q in quotients:
        positions.append(positions[-1] + q)
    K = math.floor(positions[-1]) + 1
    step_of = [None] + [max(i for i, pos in enumerate(positions[:-1]) if pos <= k - 1)
                        if k - 1 < positions[-1] else len(quotients) for k in range(1, K + 1)]
    u = [None]
    for k in range(1, K + 1):
        if p["drive"] == 1:
            u.append(math.sqrt(p["Qu"]) * noise.normal(p["seed"], noise.STREAM_INPUT, k))
        elif p["drive"] == 2:
            u.append(p["Xu"] * math.sin(2 * math.pi * p["fu"] * p["Ts"] * (k - 1)))
        else:  # the host's u_in, held from the start of the step the instant falls in
            u.append(host_u[step_of[k]])
    x = [0.0]
    for k in range(1, K + 1):
        x.append(p["A"] * x[-1] + p["B"] * u[k]
                 + math.sqrt(p["Q"]) * noise.normal(p["seed"], noise.STREAM_PROCESS, k))

    def h(s, k):
        return (p["a0"] + p["a1"] * s + p["a2"] * s ** 2 + p["a3"] * s ** 3 + p["a4"] * s ** 4
                + math.sqrt(p["R"]) * noise.normal(p["seed"], noise.STREAM_MEASUREMENT, k))

    f = Filter(p)
    z_shown = 0.0
    de_shown = None
    rows = []
    for i, pos in enumerate(positions):
        J = math.floor(pos) + 1                     # the latest instant at or before t_i
        held_x, held_u = x[J], u[J]                 # what the master sets from the Excitation
        if pos == J - 1:                            # at instant J: its sample, from the inputs
            z_shown = h(held_x, J)
            pending = f.copy()
            pending.predict(held_u)
            pending.update(z_shown)
            de_shown = pending.outputs(z_shown)
        z_in = z_shown
        rows.append((held_x, held_u, z_shown) + de_shown)
        if i == len(quotients):
            break
        first = math.ceil(pos) + 1                  # instants in [t_i, t_{i+1})
        for k in range(first, math.ceil(positions[i + 1]) + 1):
            z_shown = h(held_x, k)                  # the Accelerometer: input held
            f.predict(held_u)                       # the DriftEstimator: u held
            if k == first:
                f.update(z_in)                      # z held from the step's start
            de_shown = f.outputs(z_in)
    return rows


def _compare(got, want):
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want)):
        scale = max(1.0, max(abs(v) for v in w))
        assert all(abs(a - b) <= CLOSE * scale for a, b in zip(g, w)), (i, g, w)


def _coefficient(low, high):
    return st.one_of(st.just(0.0), st.floats(low, high), st.floats(-high, -low))


@st.composite
def chains(draw):
    Ts = 10.0 ** draw(st.floats(-4.0, -2.0))
    drive = draw(st.sampled_from((0, 1, 2)))
    return dict(Ts=Ts, A=draw(st.floats(-0.9, 0.9)), Q=draw(st.floats(0.01, 0.3)),
                B=draw(st.one_of(st.floats(0.3, 1.5), st.floats(-1.5, -0.3))), drive=drive,
                Qu=draw(st.floats(0.1, 1.0)) if drive == 1 else 0.0,
                Xu=draw(st.floats(0.3, 1.5)) if drive == 2 else 0.0,
                fu=draw(st.floats(0.02, 0.45)) * 0.5 / Ts if drive == 2 else 0.0,
                a0=draw(st.floats(-0.5, 0.5)), a1=draw(st.floats(0.5, 1.5)),
                a2=draw(_coefficient(0.01, 0.2)), a3=draw(_coefficient(0.01, 0.2)),
                a4=draw(_coefficient(0.01, 0.1)), R=10.0 ** draw(st.floats(-4.0, -1.0)),
                P0=draw(st.floats(0.01, 1.0)), estimator=draw(st.sampled_from((1, 2, 3))),
                seed=draw(st.integers(1, 10 ** 6)))


#: Steps of 5/2 Ts with a sinusoidal input at Ts = 0.4 ms: two predicts per step with u held.
LONG_STEPS = dict(Ts=4e-4, A=0.8, Q=0.05, B=1.2, drive=2, Qu=0.0, Xu=1.0, fu=180.0, a0=0.1,
                  a1=1.0, a2=0.1, a3=0.05, a4=-0.04, R=1e-3, P0=0.3, estimator=1, seed=8)


@prop(20)
@given(p=chains(), quotients=st.lists(st.sampled_from(QUOTIENTS), min_size=8, max_size=30),
       host=st.floats(-2.0, 2.0))
@example(p=LONG_STEPS, quotients=[Fraction(5, 2)] * 12, host=0.0)
@example(p=dict(LONG_STEPS, drive=0, Xu=0.0, fu=0.0), quotients=[Fraction(3)] * 6 +
         [Fraction(1, 2)] * 6, host=1.5)
@example(p=dict(LONG_STEPS, drive=1, Qu=0.5, Xu=0.0, fu=0.0, estimator=3),
         quotients=[Fraction(3, 10)] * 10 + [Fraction(5)] * 4, host=0.0)
def test_the_chain_with_the_input_follows_the_timing_rule_at_any_step(p, quotients, host):
    host_u = [host * math.cos(0.7 * i) for i in range(len(quotients) + 1)]
    _compare(run_slaves(p, quotients, host_u), reference(p, quotients, host_u))


def test_the_reference_tells_a_held_input_from_a_fresh_one():
    """The reference's rule matters at these steps: a filter that predicted the samples without
    a measurement with the input of each sample, or without it, is far off."""
    p, quotients = LONG_STEPS, [Fraction(5, 2)] * 12
    want = reference(p, quotients, None)
    got = run_slaves(p, quotients, None)
    _compare(got, want)
    blind = reference(dict(p, B=0.0), quotients, None)  # (x itself changes too)
    assert max(abs(g[3] - b[3]) for g, b in zip(got, blind)) > 0.1


# -- the harmonic filter's three estimators with a3, a4 ---------------------------------------

def harmonic_reference(p, zs, steps):
    """The 2-state harmonic EKF (docs/method.md section 2) with the full ``h``, the three
    estimators folded with ``x+`` and ``P+_11``; ``steps[j]`` samples per communication step,
    the first updated with the step's ``z`` (and read), the others predict-only."""
    C, S = math.cos(2 * math.pi * p["f"] * p["Ts"]), math.sin(2 * math.pi * p["f"] * p["Ts"])
    F = np.array([[C, S], [-S, C]])
    s, P = np.array([0.0, 0.0]), np.eye(2) * p["P0"]
    f = Filter(dict(p, A=0.0, Q=0.0, B=0.0))
    rows = []
    for z, m in zip(zs, steps):
        for j in range(m):
            s, P = F @ s, F @ P @ F.T + p["Qh"] * np.eye(2)
            if j == 0:
                c = s[0]
                H = np.array([[p["a1"] + 2 * p["a2"] * c + 3 * p["a3"] * c ** 2
                               + 4 * p["a4"] * c ** 3, 0.0]])
                hx = (p["a0"] + p["a1"] * c + p["a2"] * c ** 2 + p["a3"] * c ** 3
                      + p["a4"] * c ** 4)
                K = P @ H.T / (H @ P @ H.T + p["R"])
                s = s + (K * (z - hx)).ravel()
                IKH = np.eye(2) - K @ H
                P = IKH @ P @ IKH.T + p["R"] * K @ K.T
                f.fold(s[0], P[0, 0])
                rows.append((s[0], P[0, 0], *f.outputs(z)[2:5]))  # read before the step
    return rows


@prop(12)
@given(Ts=st.sampled_from([1e-4, 5e-4, 2e-3]), f_frac=st.floats(0.02, 0.2), X=st.floats(0.5, 1.5),
       a2=_coefficient(0.01, 0.1), a3=_coefficient(0.01, 0.1), a4=_coefficient(0.01, 0.1),
       steps=st.lists(st.sampled_from([1, 1, 2, 3]), min_size=30, max_size=60))
@example(Ts=5e-4, f_frac=0.1, X=1.2, a2=0.05, a3=-0.04, a4=0.06, steps=[3] * 40)
def test_the_harmonic_filters_three_estimators_with_a3_and_a4(Ts, f_frac, X, a2, a3, a4,
                                                               steps):
    """The DriftEstimator (process = 2) on a sinusoid's outputs, with steps of 1 to 3 samples:
    its ``x_hat``, ``P`` and EKF1-3 equal the 2-state filter and the estimators written out."""
    f = f_frac * 0.5 / Ts
    p = dict(Ts=Ts, f=f, a0=0.2, a1=1.0, a2=a2, a3=a3, a4=a4, R=1e-3, Qh=1e-6, P0=X * X,
             estimator=1)
    d = ready(DriftEstimator, a0=0.2, a1=1.0, a2=a2, a3=a3, a4=a4, R=1e-3, process=2,
              f=f, Qh=1e-6, x0=0.0, P0=X * X, Ts=Ts)
    k, t, rows, zs = 1, 0.0, [], []
    for m in steps:
        x = X * math.sin(2 * math.pi * f * (k - 1) * Ts + 0.4)
        z = (0.2 + x + a2 * x * x + a3 * x ** 3 + a4 * x ** 4
             + 0.03 * noise.normal(3, noise.STREAM_MEASUREMENT, k))
        put(d, "z", z)  # at instant k: its sample, updated with this z, is what is read
        zs.append(z)
        rows.append(tuple(get(d, n) for n in ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3")))
        assert d.do_step(t, m * Ts)  # commits it, then predicts through the other m - 1
        k, t = k + m, t + m * Ts
    _compare(rows, harmonic_reference(p, zs, steps))


@prop(20)
@given(Vs=st.floats(3.0, 6.0), a1=st.floats(0.5, 1.5), a2=_coefficient(0.005, 0.05),
       a3=_coefficient(0.001, 0.02), a4=_coefficient(0.001, 0.02),
       density=st.sampled_from([0.0, 110e-6]), Ts=st.sampled_from([1e-4, 1e-3]),
       x=st.lists(st.floats(-1.7, 1.7), min_size=5, max_size=5))
@example(Vs=3.3, a1=1.0, a2=0.01, a3=0.002, a4=0.01, density=0.0, Ts=1e-4, x=[1.5, -1.5, 1.0,
                                                                             0.5, -0.2])
@example(Vs=5.0, a1=1.0, a2=0.01, a3=0.0, a4=1.0, density=0.0, Ts=1e-3, x=[1.2, -0.7, 0.3,
                                                                            1.0, -1.1])
def test_the_adxl203_stand_in_scales_a4_with_its_supply(Vs, a1, a2, a3, a4, density, Ts, x):
    """Ratiometric output: zero-g at ``Vs/2`` and ``a1 .. a4`` (and noise given as a density)
    scaled by the datasheet's sensitivity ``S(Vs) / S(5 V)`` (560 mV/g at 3 V, 1000 mV/g at
    5 V, linear); the noise from ``R`` is in volts, unscaled (docs/method.md section 6)."""
    scale = (0.56 + (1.0 - 0.56) * (Vs - 3.0) / 2.0) / 1.0
    R = 1e-4
    a = ready(Accelerometer, a0=0.7, a1=a1, a2=a2, a3=a3, a4=a4, R=R, Vs=Vs,
              density=density, Ts=Ts, seed=5)
    for k, xk in enumerate(x, start=1):
        put(a, "x", xk)
        v = noise.normal(5, noise.STREAM_MEASUREMENT, k)
        sigma = scale * a1 * density * math.sqrt(0.5 / Ts) if density else math.sqrt(R)
        want = Vs / 2 + scale * (a1 * xk + a2 * xk ** 2 + a3 * xk ** 3 + a4 * xk ** 4) \
            + sigma * v
        assert get(a, "z") == pytest.approx(want, rel=1e-12, abs=1e-12), (k, Vs)
        assert a.do_step((k - 1) * Ts, Ts)


@prop(25)
@given(fc=st.one_of(st.just(0.0), st.floats(-1.0, math.log10(2500.0)).map(lambda e: 10.0 ** e)),
       bits=st.one_of(st.just(0), st.integers(1, 16)), Vs=st.one_of(st.just(0.0),
                                                                    st.floats(3.0, 6.0)),
       a4=_coefficient(0.001, 0.02), Ts=st.sampled_from([1e-4, 1e-3]),
       x=st.lists(st.floats(-1.7, 1.7), min_size=6, max_size=6))
@example(fc=0.5, bits=1, Vs=0.0, a4=0.0, Ts=1e-3, x=[1.0, 0.5, -0.5, 1.5, -1.0, 0.2])
def test_the_adxl203_stand_ins_output_filter_and_adc_at_any_allowed_setting(fc, bits, Vs, a4,
                                                                            Ts, x):
    """The output low-pass at any allowed bandwidth (``0 < fc <= 2500`` Hz, a tenth of a hertz
    included), ``e_k = alpha e_{k-1} + (1 - alpha) s_k``, ``alpha = exp(-2 pi fc Ts)``, started
    at ``e_1 = s_1``; the ADC of any resolution (1 bit included): the nearest code of
    ``z0 + e`` on ``[0, 2^bits)`` times ``Vfs / 2^bits``, ``Vfs = Vs`` or 5 V (docs/method.md
    section 6, models/adxl203.py)."""
    a0, a1, a2, a3, R = 2.4, 1.0, 0.01, 0.002, 1e-4
    a = ready(Accelerometer, a0=a0, a1=a1, a2=a2, a3=a3, a4=a4, R=R, fc=fc, bits=bits,
              Vs=Vs, cross=0.01, Ts=Ts, seed=6)
    scale = 0.56 + 0.44 * (Vs - 3.0) / 2.0 if Vs else 1.0
    z0 = Vs / 2 if Vs else a0
    alpha = math.exp(-2 * math.pi * fc * Ts)
    lsb = (Vs if Vs else 5.0) / 2 ** bits
    e = None
    for k, xk in enumerate(x, start=1):
        put(a, "x", xk)
        put(a, "y", 0.5)
        u = xk + 0.01 * 0.5
        s = scale * (a1 * u + a2 * u ** 2 + a3 * u ** 3 + a4 * u ** 4) \
            + math.sqrt(R) * noise.normal(6, noise.STREAM_MEASUREMENT, k)
        e = s if e is None or not fc else alpha * e + (1 - alpha) * s
        want = z0 + e
        if bits:
            want = min(max(math.floor(want / lsb + 0.5), 0), 2 ** bits - 1) * lsb
        assert get(a, "z") == pytest.approx(want, rel=1e-12, abs=1e-12), (k, fc, bits, Vs)
        assert a.do_step((k - 1) * Ts, Ts)
