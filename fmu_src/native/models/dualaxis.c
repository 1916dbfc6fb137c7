/* dualaxis: C port of models/dualaxis.py; see dualaxis.h.  Same order of operations as the
 * Python (the parenthesised groups and the row-by-row updates keep the b = 0 bits). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "covariance.h"
#include "drift.h"
#include "dualaxis.h"
#include "harmonic.h"
#include "noise.h"
#include "ops.h"
#include "sensor.h"

void dualaxis_axes(double a0, double a1, double a2, double bx, double R, double a0y, double a1y,
                   double a2y, double by, double Ry, Axis *ax, Axis *ay)
{
    ax->a0 = a0;
    ax->a1 = a1;
    ax->a2 = a2;
    ax->b = bx;
    ax->R = R;
    ay->a0 = a0y;
    ay->a1 = a1y;
    ay->a2 = a2y;
    ay->b = by;
    ay->R = Ry;
}

void dualaxis_measure(double x, double y, Axis ax, Axis ay, double vx, double vy, double *zx,
                      double *zy)
{
    *zx = sensor_measure_bilinear(x, y, ax.a0, ax.a1, ax.a2, ax.b, ax.R, vx);
    *zy = sensor_measure_bilinear(y, x, ay.a0, ay.a1, ay.a2, ay.b, ay.R, vy);
}

void dualaxis_noise(int64_t seed, int64_t k, double *vx, double *vy)
{
    *vx = noise_normal((uint64_t)seed, NOISE_STREAM_MEASUREMENT, (uint64_t)k);
    *vy = noise_normal((uint64_t)seed, NOISE_STREAM_MEASUREMENT_Y, (uint64_t)k);
}

int dualaxis_sensor_problems(int64_t dual, double a3, double cross, double fc, double Vs,
                             int64_t bits, double density, driftfmu_report report, void *ctx)
{
    const char *names[6] = {"a3", "cross", "fc", "Vs", "bits", "density"};
    double values[6];
    char on[PARAMETERS_MESSAGE_MAX], msg[PARAMETERS_MESSAGE_MAX], r[40];
    int i, n_on = 0;
    size_t len = 0;
    if (dual == 0) return 0;
    values[0] = a3;
    values[1] = cross;
    values[2] = fc;
    values[3] = Vs;
    values[4] = (double)bits;
    values[5] = density;
    on[0] = '\0';
    for (i = 0; i < 6; i++) {
        if (!(values[i] != 0.0)) continue; /* p.get(n, 0) is falsy (NaN is truthy) */
        if (i == 4)
            snprintf(r, sizeof r, "%lld", (long long)bits);
        else
            parameters_repr_float(values[i], r, sizeof r);
        len += (size_t)snprintf(on + len, sizeof on - len, "%s%s = %s", n_on ? ", " : "",
                                names[i], r);
        if (len >= sizeof on) len = sizeof on - 1;
        n_on++;
    }
    if (!n_on) return 0;
    snprintf(msg, sizeof msg, "dual = 1 is not allowed with %s; allowed: dual = 1 with a3 = "
             "cross = fc = Vs = bits = density = 0 (the bilinear sensor has none of the ADXL203 "
             "extras)", on);
    report(ctx, msg);
    return 1;
}

void dualaxis__row2(double o, double t, double Poo, double Pot, double Ptt, double H, double G,
                    double e, double R, double *o_post, double *t_post, double *poo,
                    double *pot, double *ptt)
{
    double S = H * H * Poo + (2.0 * H * G * Pot + G * G * Ptt) + R;
    double Ko = (Poo * H + Pot * G) / S;
    double Kt = (Pot * H + Ptt * G) / S;
    double moo = 1.0 - Ko * H;
    double mot = -Ko * G;
    double mto = -Kt * H;
    double mtt = 1.0 - Kt * G;
    double col_o, col_t;
    *poo = moo * moo * Poo + (2.0 * moo * mot * Pot + mot * mot * Ptt) + Ko * Ko * R;
    col_o = mto * Poo + mtt * Pot;
    col_t = mto * Pot + mtt * Ptt;
    *pot = moo * col_o + mot * col_t + Ko * Kt * R;
    *ptt = mto * col_o + mtt * col_t + Kt * Kt * R;
    *o_post = o + Ko * e;
    *t_post = t + Kt * e;
}

void dualaxis__row4(double o, double od, double t, double td, const double P[10], double H,
                    double G, double e, double R, double *o_post, double *od_post,
                    double *t_post, double *td_post, double out[10])
{
    double P11 = P[0], P12 = P[1], P22 = P[2], P13 = P[3], P14 = P[4], P23 = P[5], P24 = P[6],
           P33 = P[7], P34 = P[8], P44 = P[9];
    double S = H * H * P11 + (2.0 * H * G * P13 + G * G * P33) + R;
    double K1 = (P11 * H + P13 * G) / S;
    double K2 = (P12 * H + P23 * G) / S;
    double K3 = (P13 * H + P33 * G) / S;
    double K4 = (P14 * H + P34 * G) / S;
    double m11 = 1.0 - K1 * H, m13 = -K1 * G;
    double m21 = -K2 * H, m23 = -K2 * G;
    double m31 = -K3 * H, m33 = 1.0 - K3 * G;
    double m41 = -K4 * H, m43 = -K4 * G;
    double p11 = m11 * m11 * P11 + (2.0 * m11 * m13 * P13 + m13 * m13 * P33) + K1 * K1 * R;
    double a1 = m21 * P11 + P12 + m23 * P13;
    double a3 = m21 * P13 + P23 + m23 * P33;
    double p12 = m11 * a1 + m13 * a3 + K1 * K2 * R;
    double p22 = (m21 * m21 * P11 + 2.0 * m21 * P12 + P22
                  + (2.0 * m21 * m23 * P13 + 2.0 * m23 * P23 + m23 * m23 * P33) + K2 * K2 * R);
    double b1 = m31 * P11 + m33 * P13;
    double b2 = m31 * P12 + m33 * P23;
    double b3 = m31 * P13 + m33 * P33;
    double c1 = m41 * P11 + m43 * P13 + P14;
    double c2 = m41 * P12 + m43 * P23 + P24;
    double c3 = m41 * P13 + m43 * P33 + P34;
    double c4 = m41 * P14 + m43 * P34 + P44;
    out[0] = p11;
    out[1] = p12;
    out[2] = p22;
    out[3] = m11 * b1 + m13 * b3 + K1 * K3 * R;           /* p13 */
    out[4] = m11 * c1 + m13 * c3 + K1 * K4 * R;           /* p14 */
    out[5] = m21 * b1 + b2 + m23 * b3 + K2 * K3 * R;      /* p23 */
    out[6] = m21 * c1 + c2 + m23 * c3 + K2 * K4 * R;      /* p24 */
    out[7] = m31 * b1 + m33 * b3 + K3 * K3 * R;           /* p33 */
    out[8] = m31 * c1 + m33 * c3 + K3 * K4 * R;           /* p34 */
    out[9] = m41 * c1 + m43 * c3 + c4 + K4 * K4 * R;      /* p44 */
    *o_post = o + K1 * e;
    *od_post = od + K2 * e;
    *t_post = t + K3 * e;
    *td_post = td + K4 * e;
}

void dualaxis_jacobian(double x, double y, Axis ax, Axis ay, double *Hxx, double *Hxy,
                       double *Hyx, double *Hyy)
{
    *Hxx = sensor_dh_dx(x, ax.a1, ax.a2) + ax.b * y;
    *Hxy = ax.b * x;
    *Hyx = ay.b * y;
    *Hyy = sensor_dh_dx(y, ay.a1, ay.a2) + ay.b * x;
}

void dualaxis_innovations(double x, double y, double zx, double zy, Axis ax, Axis ay,
                          double *ex, double *ey)
{
    *ex = zx - sensor_h_bilinear(x, y, ax.a0, ax.a1, ax.a2, ax.b);
    *ey = zy - sensor_h_bilinear(y, x, ay.a0, ay.a1, ay.a2, ay.b);
}

void dualaxis_update2(const double s[5], double zx, double zy, Axis ax, Axis ay,
                      double s_post[5])
{
    double x = s[0], y = s[1], Pxx = s[2], Pxy = s[3], Pyy = s[4];
    double Hxx, Hxy, Hyx, Hyy, ex, ey, x1, y1, Pxx1, Pxy1, Pyy1;
    dualaxis_jacobian(x, y, ax, ay, &Hxx, &Hxy, &Hyx, &Hyy);
    dualaxis_innovations(x, y, zx, zy, ax, ay, &ex, &ey);
    dualaxis__row2(x, y, Pxx, Pxy, Pyy, Hxx, Hxy, ex, ax.R, &x1, &y1, &Pxx1, &Pxy1, &Pyy1);
    ey = ey - (Hyx * (x1 - x) + Hyy * (y1 - y));
    dualaxis__row2(y1, x1, Pyy1, Pxy1, Pxx1, Hyy, Hyx, ey, ay.R, &s_post[1], &s_post[0],
                   &s_post[4], &s_post[3], &s_post[2]);
}

void dualaxis_predict2(double x, double y, double Pxx, double Pxy, double Pyy, double A,
                       double Q, double Qy, double Qxy, double out[5])
{
    double AA = A * A;
    out[0] = A * x;
    out[1] = A * y;
    out[2] = AA * Pxx + Q;
    out[3] = AA * Pxy + Qxy;
    out[4] = AA * Pyy + Qy;
}

void dualaxis_predict4(DualHarmonicState st, double C, double S, double Qh, double out[14])
{
    double f11, f12, f21, f22;
    harmonic_predict(st.x, st.dx, st.P11, st.P12, st.P22, C, S, Qh, &out[0], &out[1], &out[4],
                     &out[5], &out[6]);
    harmonic_predict(st.y, st.dy, st.P33, st.P34, st.P44, C, S, Qh, &out[2], &out[3], &out[7],
                     &out[8], &out[9]);
    f11 = C * st.P13 + S * st.P23;
    f12 = C * st.P14 + S * st.P24;
    f21 = C * st.P23 - S * st.P13;
    f22 = C * st.P24 - S * st.P14;
    out[10] = C * f11 + S * f12;
    out[11] = C * f12 - S * f11;
    out[12] = C * f21 + S * f22;
    out[13] = C * f22 - S * f21;
}

void dualaxis_update4(const double s[14], double zx, double zy, Axis ax, Axis ay,
                      double out[14])
{
    double x = s[0], dx = s[1], y = s[2], dy = s[3];
    double Hxx, Hxy, Hyx, Hyy, ex, ey, x1, dx1, y1, dy1;
    double P[10], q[10], Q2[10], r[10];
    /* (P11, P12, P22, P13, P14, P23, P24, P33, P34, P44) from the storage order */
    P[0] = s[4];
    P[1] = s[5];
    P[2] = s[6];
    P[3] = s[10];
    P[4] = s[11];
    P[5] = s[12];
    P[6] = s[13];
    P[7] = s[7];
    P[8] = s[8];
    P[9] = s[9];
    dualaxis_jacobian(x, y, ax, ay, &Hxx, &Hxy, &Hyx, &Hyy);
    dualaxis_innovations(x, y, zx, zy, ax, ay, &ex, &ey);
    dualaxis__row4(x, dx, y, dy, P, Hxx, Hxy, ex, ax.R, &x1, &dx1, &y1, &dy1, q);
    ey = ey - (Hyx * (x1 - x) + Hyy * (y1 - y));
    /* own = y: (q33, q34, q44, q13, q23, q14, q24, q11, q12, q22); q = (q11, q12, q22, q13,
     * q14, q23, q24, q33, q34, q44) */
    Q2[0] = q[7];
    Q2[1] = q[8];
    Q2[2] = q[9];
    Q2[3] = q[3];
    Q2[4] = q[5];
    Q2[5] = q[4];
    Q2[6] = q[6];
    Q2[7] = q[0];
    Q2[8] = q[1];
    Q2[9] = q[2];
    /* r = (r33, r34, r44, r13, r23, r14, r24, r11, r12, r22) */
    dualaxis__row4(y1, dy1, x1, dx1, Q2, Hyy, Hyx, ey, ay.R, &out[2], &out[3], &out[0],
                   &out[1], r);
    out[4] = r[7];  /* r11 */
    out[5] = r[8];  /* r12 */
    out[6] = r[9];  /* r22 */
    out[7] = r[0];  /* r33 */
    out[8] = r[1];  /* r34 */
    out[9] = r[2];  /* r44 */
    out[10] = r[3]; /* r13 */
    out[11] = r[5]; /* r14 */
    out[12] = r[4]; /* r23 */
    out[13] = r[6]; /* r24 */
}

DualDrift dualaxis_drift_init(void)
{
    DualDrift d = {0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    return d;
}

DualDrift dualaxis_drift_update(DualDrift d, double x, double y, double Pxx, double Pxy,
                                double Pyy, Axis ax, Axis ay)
{
    DualDrift out;
    int64_t k = d.k + 1;
    double xx = x * x, xy = x * y, yy = y * y;
    out.k = k;
    out.s3xx = drift_running_mean(d.s3xx, xx, k);
    out.s3xy = drift_running_mean(d.s3xy, xy, k);
    out.s3yy = drift_running_mean(d.s3yy, yy, k);
    out.s1xx = drift_running_mean(d.s1xx, xx + Pxx, k);
    out.s1xy = drift_running_mean(d.s1xy, xy + Pxy, k);
    out.s1yy = drift_running_mean(d.s1yy, yy + Pyy, k);
    out.dc2x = drift_running_mean(d.dc2x, ax.a2 * xx + ax.b * xy, k);
    out.dc2y = drift_running_mean(d.dc2y, ay.a2 * yy + ay.b * xy, k);
    out.dc3x = drift_running_mean(d.dc3x, ax.a2 * out.s3xx + ax.b * out.s3xy, k);
    out.dc3y = drift_running_mean(d.dc3y, ay.a2 * out.s3yy + ay.b * out.s3xy, k);
    return out;
}

void dualaxis_estimates(DualDrift d, Axis ax, Axis ay, double dx[3], double dy[3])
{
    dx[0] = ax.a2 * d.s1xx + ax.b * d.s1xy;
    dx[1] = d.dc2x;
    dx[2] = d.dc3x;
    dy[0] = ay.a2 * d.s1yy + ay.b * d.s1xy;
    dy[1] = d.dc2y;
    dy[2] = d.dc3y;
}

DualModel dualaxis_model(int64_t process, double A, double Q, double Qy, double rho, double f,
                         double Ts, double Qh)
{
    DualModel m;
    harmonic_rotation(f, Ts, &m.C, &m.S);
    m.process = process;
    m.A = A;
    m.Q = Q;
    m.Qy = Qy;
    m.Qxy = rho * ops_sqrt(Q * Qy);
    m.Qh = Qh;
    return m;
}

DualEstimator dualaxis_estimator_init(int64_t process, double x0, double y0, double P0,
                                      double P0y)
{
    DualEstimator st;
    memset(&st, 0, sizeof st);
    st.g.drift = st.h.drift = dualaxis_drift_init();
    if (process == DUALAXIS_GAUSS_MARKOV) {
        st.g.x = x0;
        st.g.y = y0;
        st.g.Pxx = P0;
        st.g.Pxy = 0.0 * P0;
        st.g.Pyy = P0y;
    } else if (process == DUALAXIS_HARMONIC) {
        double z = 0.0 * P0;
        st.h.x = x0;
        st.h.dx = 0.0 * x0;
        st.h.y = y0;
        st.h.dy = 0.0 * y0;
        st.h.P11 = P0;
        st.h.P12 = z;
        st.h.P22 = P0;
        st.h.P33 = P0y;
        st.h.P34 = z;
        st.h.P44 = P0y;
        st.h.P13 = st.h.P14 = st.h.P23 = st.h.P24 = z;
    } else {
        st.g.x = st.g.y = st.g.Pxx = st.g.Pxy = st.g.Pyy = NAN;
        st.h.x = st.h.dx = st.h.y = st.h.dy = st.h.P11 = st.h.P12 = st.h.P22 = NAN;
        st.h.P33 = st.h.P34 = st.h.P44 = st.h.P13 = st.h.P14 = st.h.P23 = st.h.P24 = NAN;
    }
    return st;
}

void dualaxis_moments(const DualEstimator *st, int64_t process, double out[5])
{
    if (process == DUALAXIS_GAUSS_MARKOV) {
        out[0] = st->g.x;
        out[1] = st->g.y;
        out[2] = st->g.Pxx;
        out[3] = st->g.Pxy;
        out[4] = st->g.Pyy;
    } else {
        out[0] = st->h.x;
        out[1] = st->h.y;
        out[2] = st->h.P11;
        out[3] = st->h.P13;
        out[4] = st->h.P33;
    }
}

DualDrift dualaxis_drift_of(const DualEstimator *st, int64_t process)
{
    return process == DUALAXIS_GAUSS_MARKOV ? st->g.drift : st->h.drift;
}

int dualaxis_covariance_of(const DualEstimator *st, int64_t process, double lower[10])
{
    if (process == DUALAXIS_GAUSS_MARKOV) {
        lower[0] = st->g.Pxx;
        lower[1] = st->g.Pxy;
        lower[2] = st->g.Pyy;
        return 2;
    }
    lower[0] = st->h.P11;
    lower[1] = st->h.P12;
    lower[2] = st->h.P22;
    lower[3] = st->h.P13;
    lower[4] = st->h.P23;
    lower[5] = st->h.P33;
    lower[6] = st->h.P14;
    lower[7] = st->h.P24;
    lower[8] = st->h.P34;
    lower[9] = st->h.P44;
    return 4;
}

int dualaxis_valid(const DualEstimator *st, int64_t process)
{
    double lower[10];
    const int n = dualaxis_covariance_of(st, process, lower);
    if (n == 2) return covariance_valid2(lower[0], lower[1], lower[2]);
    return covariance_valid(n, lower);
}

static void set_harmonic(DualHarmonicState *h, const double s[14])
{
    h->x = s[0];
    h->dx = s[1];
    h->y = s[2];
    h->dy = s[3];
    h->P11 = s[4];
    h->P12 = s[5];
    h->P22 = s[6];
    h->P33 = s[7];
    h->P34 = s[8];
    h->P44 = s[9];
    h->P13 = s[10];
    h->P14 = s[11];
    h->P23 = s[12];
    h->P24 = s[13];
}

static void set_gauss(DualState *g, const double s[5])
{
    g->x = s[0];
    g->y = s[1];
    g->Pxx = s[2];
    g->Pxy = s[3];
    g->Pyy = s[4];
}

DualEstimator dualaxis_estimator_predict(DualEstimator st, const DualModel *m)
{
    if (m->process == DUALAXIS_GAUSS_MARKOV) {
        double s[5];
        dualaxis_predict2(st.g.x, st.g.y, st.g.Pxx, st.g.Pxy, st.g.Pyy, m->A, m->Q, m->Qy,
                          m->Qxy, s);
        set_gauss(&st.g, s);
    } else {
        double s[14];
        dualaxis_predict4(st.h, m->C, m->S, m->Qh, s);
        set_harmonic(&st.h, s);
    }
    return st;
}

DualEstimator dualaxis_estimator_step(DualEstimator st, double zx, double zy, Axis ax, Axis ay,
                                      const DualModel *m)
{
    double mom[5];
    if (m->process == DUALAXIS_GAUSS_MARKOV) {
        double p[5], s[5];
        dualaxis_predict2(st.g.x, st.g.y, st.g.Pxx, st.g.Pxy, st.g.Pyy, m->A, m->Q, m->Qy,
                          m->Qxy, p);
        dualaxis_update2(p, zx, zy, ax, ay, s);
        set_gauss(&st.g, s);
        dualaxis_moments(&st, m->process, mom);
        st.g.drift = dualaxis_drift_update(st.g.drift, mom[0], mom[1], mom[2], mom[3], mom[4],
                                           ax, ay);
    } else {
        double p[14], s[14];
        dualaxis_predict4(st.h, m->C, m->S, m->Qh, p);
        dualaxis_update4(p, zx, zy, ax, ay, s);
        set_harmonic(&st.h, s);
        dualaxis_moments(&st, m->process, mom);
        st.h.drift = dualaxis_drift_update(st.h.drift, mom[0], mom[1], mom[2], mom[3], mom[4],
                                           ax, ay);
    }
    return st;
}
