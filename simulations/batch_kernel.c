/* The compiled batch kernel: the chains of simulations/batch.py (simulate), models/adxl203.py
 * (simulate) and models/dualaxis.py (simulate) written out over the C port of models/
 * (fmu_src/native/models), one run after another.  Built by simulations/kernel.py with the
 * flags of the native FMUs (-std=c99 -O2 -ffp-contract=off -fno-fast-math, and inlining), so
 * every sample gives the bits of the NumPy batch engine and of the FMUs.  No state of its own:
 * the caller owns every array. */
#include <stddef.h>
#include <stdint.h>

#include "adxl203.h"
#include "bias.h"
#include "chain.h"
#include "covariance.h"
#include "drift.h"
#include "dualaxis.h"
#include "errors.h"
#include "excitation.h"
#include "harmonic.h"
#include "noise.h"
#include "sensor.h"

/* One run of simulations.batch.simulate between blocks: the excitation, the filter, the two
 * running means, the general sensor's realised drift, the bias filter's part and where its
 * covariance first left the PSD cone, and the sensor's slow errors (thirty-three 8-byte
 * fields, the layout of a (runs, 33) float64 array: kernel.py's STATE_FIELDS). */
typedef struct {
    double x, zbar, x2bar;
    EstimatorState est;
    double hbar;  /* running mean of a2 x^2 + a3 x^3 + a4 x^4 (the general sensor only) */
    Bias b;       /* the bias part (bias = 1 only; 0 otherwise) */
    double bad_k; /* the first sample whose covariance (P, Pxb, Pbb) is not valid (0: none) */
    double bad[3];/* that covariance */
    ErrorState err; /* models.errors' state (chain.SensorErrors; the slow errors only) */
} RunState;

/* models.errors.OFF["T0"]: the DriftEstimator's T0 when its class-2 coefficients are off
 * (any finite value gives the same offset then). */
#define ERRORS_T0_OFF 298.15

/* The per-run parameters of batch.simulate, in this order, each an array of `runs` values
 * (the general model's: a3, a4, B, the known input's drive, Qu, Xu, fu; then the sensor's
 * slow errors, chain.SENSOR_ERRORS_OFF: models.errors' parameters, the tilt and temperature
 * held over a run, the ADC's bits). */
enum { P_A0, P_A1, P_A2, P_A, P_Q, P_R, P_X0, P_P0, P_TS, P_X, P_F, P_PHI, P_FA, P_FQ,
       P_A3, P_A4, P_B, P_DRIVE, P_QU, P_XU, P_FU, P_BIAS, P_QB, P_TAU_B, P_B0, P_PB0,
       P_BIAS_ON, P_RANDOM_WALK, P_BIAS_GM, P_TAU_GM, P_FLICKER, P_TAU_MIN, P_TAU_MAX,
       P_D_INF, P_E_TAU, P_THETA, P_T, P_T0, P_KT_BIAS, P_KT_SCALE, P_RANGE, P_BITS,
       N_PARAMS };

/* The slow errors' constants of run r (chain.SensorErrors: errors.config with the run's seed,
 * adxl203.config with its sensor and the ADC). */
static void slow_config(const double *const *p, int64_t r, uint64_t seed, ErrorConfig *ecfg,
                        Config *cfg)
{
    *ecfg = errors_config((int64_t)seed, p[P_TS][r], p[P_BIAS_ON][r], p[P_RANDOM_WALK][r],
                          p[P_BIAS_GM][r], p[P_TAU_GM][r], p[P_FLICKER][r], p[P_TAU_MIN][r],
                          p[P_TAU_MAX][r], p[P_D_INF][r], p[P_E_TAU][r], p[P_T0][r],
                          p[P_KT_BIAS][r], p[P_KT_SCALE][r], p[P_RANGE][r]);
    *cfg = adxl203_config_ranged(p[P_A0][r], p[P_A1][r], p[P_A2][r], p[P_R][r], p[P_A3][r], 0.0,
                                 0.0, 0.0, (int64_t)p[P_BITS][r], 0.0, p[P_TS][r], p[P_A4][r],
                                 p[P_RANGE][r]);
}

/* batch.TRAJECTORIES and batch.BIAS_OUTPUTS, in this order; a NULL pointer is a trajectory not
 * recorded. */
enum { T_X, T_Z, T_XHAT, T_P, T_DC1, T_DC2, T_DC3, T_EMPIRICAL, T_REALISED, T_BHAT, T_PBB,
       T_PXB, N_TRAJ };

/* The state of every run before sample 1: x = x0, the filter at (x0, P0), means 0, the slow
 * errors' initial state (errors.initial_state of the run's seed; all 0.0 while they are off). */
void driftfmu_batch_init(int64_t runs, const uint64_t *seeds, const double *const *p,
                         RunState *state)
{
    for (int64_t r = 0; r < runs; r++) {
        ErrorConfig ecfg;
        Config cfg;
        state[r].x = p[P_X0][r];
        state[r].zbar = 0.0;
        state[r].x2bar = 0.0;
        state[r].est = chain_estimator_init(p[P_X0][r], p[P_P0][r]);
        state[r].hbar = 0.0;
        if (p[P_BIAS][r] != 0.0) {
            state[r].b = bias_init(p[P_B0][r], p[P_PB0][r]);
        } else {
            state[r].b.b = state[r].b.Pxb = state[r].b.Pbb = 0.0;
        }
        state[r].bad_k = 0.0;
        state[r].bad[0] = state[r].bad[1] = state[r].bad[2] = 0.0;
        slow_config(p, r, seeds[r], &ecfg, &cfg);
        state[r].err = errors_initial_state((int64_t)seeds[r], &ecfg);
    }
}

/* Runs advanced side by side, sample by sample: their chains are independent, so the
 * processor overlaps the divisions and square roots of one with those of the others. */
#define LANES 8

/* Standard normal draw k under the key of (seed, stream): noise_normal with noise_key(seed,
 * stream) computed once per run instead of at every sample (noise_bits is mix(key + k golden),
 * noise_uniform and noise_inverse_normal_cdf as in noise.c), the same bits. */
static double keyed_normal(uint64_t key, int64_t k)
{
    uint64_t bits = noise_mix(key + (uint64_t)k * NOISE_GOLDEN);
    return noise_inverse_normal_cdf(((double)(bits >> 12) + 0.5) * 2.220446049250313e-16);
}

/* The Gaussian chain without recorded trajectories (the sweep's case), laid out so that the
 * compiler can vectorise it across runs: every stage of a sample is a loop over VLANES runs
 * (structure of arrays), and the only branch of the chain, the tails of the inverse normal CDF
 * (p < NOISE_P_LOW or p > 1 - NOISE_P_LOW, about 5 % of the draws), is redone one draw at a
 * time after the central branch was computed for all.  The operations are those of
 * keyed_normal, excitation_gauss_markov, sensor_measure, chain_estimator_step and
 * drift_running_mean in the same order (inlined from the same units; vector division, square
 * root, multiplication and addition are the IEEE operations of the scalar code, and
 * -ffp-contract=off forbids fusing them), so the bits are those of the scalar loop below.
 * Needs every run's drift counter at k0 - 1 (as driftfmu_batch_init and earlier calls leave
 * it); returns 0 without touching anything otherwise. */
#define VLANES 16

static int run_gaussian_vector(int64_t k0, int64_t k1, int64_t r0, int lanes,
                               const uint64_t *seeds, const double *const *p, RunState *state)
{
    double x[VLANES], zbar[VLANES], x2bar[VLANES], ex[VLANES], eP[VLANES];
    double s1[VLANES], dc2[VLANES], s3[VLANES], dc3[VLANES];
    double a0[VLANES], a1[VLANES], a2[VLANES], A[VLANES], Q[VLANES], R[VLANES];
    double fA[VLANES], fQ[VLANES], up[VLANES], um[VLANES], wp[VLANES], wm[VLANES];
    uint64_t kp[VLANES], km[VLANES];
    for (int i = 0; i < lanes; i++)
        if (state[r0 + i].est.drift.k != k0 - 1) return 0;
    for (int i = 0; i < VLANES; i++) {  /* lanes past the last run repeat run r0 (not stored) */
        const int64_t r = r0 + (i < lanes ? i : 0);
        const RunState *s = &state[r];
        x[i] = s->x; zbar[i] = s->zbar; x2bar[i] = s->x2bar; ex[i] = s->est.x; eP[i] = s->est.P;
        s1[i] = s->est.drift.s1; dc2[i] = s->est.drift.dc2; s3[i] = s->est.drift.s3;
        dc3[i] = s->est.drift.dc3;
        a0[i] = p[P_A0][r]; a1[i] = p[P_A1][r]; a2[i] = p[P_A2][r]; A[i] = p[P_A][r];
        Q[i] = p[P_Q][r]; R[i] = p[P_R][r]; fA[i] = p[P_FA][r]; fQ[i] = p[P_FQ][r];
        kp[i] = noise_key(seeds[r], NOISE_STREAM_PROCESS);
        km[i] = noise_key(seeds[r], NOISE_STREAM_MEASUREMENT);
    }
    for (int64_t k = k0; k < k1; k++) {
        const uint64_t step = (uint64_t)k * NOISE_GOLDEN;
        for (int i = 0; i < VLANES; i++) {
            /* keyed_normal's uniform; (double)(b >> 12) built from the bits of 2^52 + (b >> 12)
             * minus 2^52, both exact (b >> 12 < 2^52), so that it vectorises without a
             * 64-bit integer conversion instruction */
            uint64_t bp = noise_mix(kp[i] + step) >> 12, bm = noise_mix(km[i] + step) >> 12;
            union { uint64_t u; double d; } cp = {bp | 0x4330000000000000ULL},
                                             cm = {bm | 0x4330000000000000ULL};
            up[i] = ((cp.d - 4503599627370496.0) + 0.5) * 2.220446049250313e-16;
            um[i] = ((cm.d - 4503599627370496.0) + 0.5) * 2.220446049250313e-16;
        }
        for (int i = 0; i < VLANES; i++) {
            wp[i] = noise_central(up[i]);
            wm[i] = noise_central(um[i]);
        }
        for (int i = 0; i < VLANES; i++) {  /* the tails, one draw at a time */
            if (up[i] < NOISE_P_LOW || up[i] > 1.0 - NOISE_P_LOW)
                wp[i] = noise_inverse_normal_cdf(up[i]);
            if (um[i] < NOISE_P_LOW || um[i] > 1.0 - NOISE_P_LOW)
                wm[i] = noise_inverse_normal_cdf(um[i]);
        }
        for (int i = 0; i < VLANES; i++) {
            EstimatorState est;
            double z;
            x[i] = excitation_gauss_markov(x[i], A[i], Q[i], wp[i]);
            z = sensor_measure(x[i], a0[i], a1[i], a2[i], R[i], wm[i]);
            est.x = ex[i];
            est.P = eP[i];
            est.drift.k = k - 1;
            est.drift.s1 = s1[i]; est.drift.dc2 = dc2[i]; est.drift.s3 = s3[i];
            est.drift.dc3 = dc3[i];
            est.drift.t1 = est.drift.q1 = est.drift.t3 = est.drift.q3 = 0.0;
            est = chain_estimator_step(est, z, a0[i], a1[i], a2[i], fA[i], fQ[i], R[i]);
            ex[i] = est.x; eP[i] = est.P;
            s1[i] = est.drift.s1; dc2[i] = est.drift.dc2; s3[i] = est.drift.s3;
            dc3[i] = est.drift.dc3;
            zbar[i] = drift_running_mean(zbar[i], z, k);
            x2bar[i] = drift_running_mean(x2bar[i], x[i] * x[i], k);
        }
    }
    for (int i = 0; i < lanes; i++) {  /* (the quadratic chain keeps t1, q1, t3, q3 as they are) */
        RunState *s = &state[r0 + i];
        s->x = x[i]; s->zbar = zbar[i]; s->x2bar = x2bar[i]; s->est.x = ex[i]; s->est.P = eP[i];
        s->est.drift.k = k1 - 1;
        s->est.drift.s1 = s1[i]; s->est.drift.dc2 = dc2[i]; s->est.drift.s3 = s3[i];
        s->est.drift.dc3 = dc3[i];
    }
    return 1;
}

/* Samples k = k0 .. k1 - 1 of every run (the loop body of batch.simulate); the recorded
 * trajectories are (runs, n) arrays, sample k in column k - 1.  `general`: the batch has the
 * general sensor or the known input (a3, a4 or B not 0; batch.simulate's NumPy path then calls
 * the same functions with them, the letter's with zeros, which the C functions of the letter's
 * sensor are); `quadratic`: a3 = a4 = 0 in every run (no realised h to average); `slow`: the
 * sensor's slow errors, tilt or ADC are on (chain.SensorErrors not plain: its measure, that is
 * adxl203_measure_errors, gives z). */
void driftfmu_batch_run(int64_t k0, int64_t k1, int64_t n, int64_t runs, const uint64_t *seeds,
                        int64_t kind, int64_t general, int64_t quadratic, int64_t slow,
                        const double *const *p, RunState *state, double *const *traj)
{
    const int gaussian = kind == EXCITATION_GAUSSIAN;
    int64_t done = 0;  /* runs before this index ran in run_gaussian_vector */
    if (gaussian && !traj && !general && !slow)
        while (done < runs && run_gaussian_vector(k0, k1, done, runs - done < VLANES ?
                                                  (int)(runs - done) : VLANES, seeds, p, state))
            done += VLANES;
    for (int64_t r0 = done; r0 < runs; r0 += LANES) {
        const int lanes = runs - r0 < LANES ? (int)(runs - r0) : LANES;
        RunState s[LANES];
        double q[N_PARAMS][LANES];  /* this block's parameters, out of reach of the stores */
        double Fb[LANES];           /* the bias filter's bias_factor(tau_b, Ts) */
        uint64_t key_process[LANES], key_measurement[LANES];
        ErrorConfig ecfg[LANES];
        Config cfg[LANES];
        ErrorTilt tilt[LANES];      /* the sine of each run's tilt, held over the run */
        for (int i = 0; i < lanes; i++) {
            s[i] = state[r0 + i];
            for (int j = 0; j < N_PARAMS; j++) q[j][i] = p[j][r0 + i];
            key_process[i] = noise_key(seeds[r0 + i], NOISE_STREAM_PROCESS);
            key_measurement[i] = noise_key(seeds[r0 + i], NOISE_STREAM_MEASUREMENT);
            Fb[i] = bias_factor(q[P_TAU_B][i], q[P_TS][i]);
            if (slow) slow_config(p, r0 + i, seeds[r0 + i], &ecfg[i], &cfg[i]);
            tilt[i].theta = tilt[i].sine = 0.0;
        }
        for (int64_t k = k0; k < k1; k++) {
            for (int i = 0; i < lanes; i++) {
                const double a0 = q[P_A0][i], a1 = q[P_A1][i], a2 = q[P_A2][i], R = q[P_R][i];
                const double a3 = q[P_A3][i], a4 = q[P_A4][i];
                double z, ze, x2, dc1, dc2, dc3, B = 0.0, u = 0.0;
                if (gaussian) {
                    const int64_t drive = (int64_t)q[P_DRIVE][i];
                    B = q[P_B][i];
                    if (drive != EXCITATION_DRIVE_OFF)
                        u = excitation_input_sample(drive, (int64_t)seeds[r0 + i], k, q[P_QU][i],
                                                    q[P_XU][i], q[P_FU][i], q[P_TS][i]);
                    s[i].x = excitation_gauss_markov_general(s[i].x, q[P_A][i], q[P_Q][i],
                                                             keyed_normal(key_process[i], k),
                                                             B, u);
                } else {
                    s[i].x = excitation_sine(k, q[P_X][i], q[P_F][i], q[P_TS][i], q[P_PHI][i]);
                }
                if (slow) { /* chain.SensorErrors.measure */
                    double n_rw, n_gm, n_fl[ERRORS_FLICKER_MAX];
                    int64_t e_set;
                    double e;
                    errors_draws((int64_t)seeds[r0 + i], k, &ecfg[i], &n_rw, &n_gm, n_fl);
                    adxl203_measure_errors(0, 0.0, &s[i].err, s[i].x, 0.0,
                                           keyed_normal(key_measurement[i], k), n_rw, n_gm,
                                           n_fl, q[P_THETA][i], q[P_T][i], &cfg[i], &ecfg[i],
                                           &tilt[i], &e_set, &e, &z);
                } else {
                    z = sensor_measure_general(s[i].x, a0, a1, a2, R,
                                               keyed_normal(key_measurement[i], k), a3, a4);
                }
                /* the tilt wired to the estimator: models.chain.wired_offset */
                ze = q[P_THETA][i] != 0.0
                     ? z - errors_class2_offset(q[P_THETA][i], q[P_T][i], a1, a2,
                                                ERRORS_T0_OFF, 0.0, 0.0, a3, a4)
                     : z;
                if (q[P_BIAS][i] != 0.0) { /* models.bias.estimator_step and check */
                    s[i].est = bias_estimator_step(s[i].est, &s[i].b, ze, a0, a1, a2, q[P_FA][i],
                                                   q[P_FQ][i], R, Fb[i], q[P_QB][i], a3, a4, B,
                                                   u);
                    if (s[i].bad_k == 0.0 &&
                        !covariance_valid2(s[i].est.P, s[i].b.Pxb, s[i].b.Pbb)) {
                        s[i].bad_k = (double)k;
                        s[i].bad[0] = s[i].est.P;
                        s[i].bad[1] = s[i].b.Pxb;
                        s[i].bad[2] = s[i].b.Pbb;
                    }
                } else {
                    s[i].est = chain_estimator_step_general(s[i].est, ze, a0, a1, a2, q[P_FA][i],
                                                            q[P_FQ][i], R, a3, a4, B, u);
                }
                s[i].zbar = drift_running_mean(s[i].zbar, z, k);
                x2 = s[i].x * s[i].x;
                s[i].x2bar = drift_running_mean(s[i].x2bar, x2, k);
                if (!quadratic)
                    s[i].hbar = drift_running_mean(s[i].hbar,
                                                   a2 * x2 + a3 * x2 * s[i].x + a4 * x2 * x2, k);
                if (traj) {
                    size_t j = (size_t)(r0 + i) * (size_t)n + (size_t)(k - 1);
                    drift_estimates_general(s[i].est.drift, a2, a3, a4, &dc1, &dc2, &dc3);
                    if (traj[T_X]) traj[T_X][j] = s[i].x;
                    if (traj[T_Z]) traj[T_Z][j] = z;
                    if (traj[T_XHAT]) traj[T_XHAT][j] = s[i].est.x;
                    if (traj[T_P]) traj[T_P][j] = s[i].est.P;
                    if (traj[T_DC1]) traj[T_DC1][j] = dc1;
                    if (traj[T_DC2]) traj[T_DC2][j] = dc2;
                    if (traj[T_DC3]) traj[T_DC3][j] = dc3;
                    if (traj[T_EMPIRICAL]) traj[T_EMPIRICAL][j] = s[i].zbar - a0;
                    if (traj[T_REALISED])  /* batch._realised */
                        traj[T_REALISED][j] = quadratic || (a3 == 0.0 && a4 == 0.0)
                                              ? a2 * s[i].x2bar : s[i].hbar;
                    if (traj[T_BHAT]) traj[T_BHAT][j] = s[i].b.b;
                    if (traj[T_PBB]) traj[T_PBB][j] = s[i].b.Pbb;
                    if (traj[T_PXB]) traj[T_PXB][j] = s[i].b.Pxb;
                }
            }
        }
        for (int i = 0; i < lanes; i++) state[r0 + i] = s[i];
    }
}

/* models.adxl203.simulate's start values, in these orders. */
enum { E_KIND, E_A, E_Q, E_X0, E_X, E_F, E_PHI, E_XY, E_PHIY, E_SEED, N_EXCITATION };
enum { S_A0, S_A1, S_A2, S_R, S_A3, S_CROSS, S_FC, S_VS, S_BITS, S_DENSITY, S_SEED, S_NOISE,
       S_AXES, N_SENSOR };
enum { D_A0, D_A1, D_A2, D_A, D_Q, D_R, D_X0, D_P0, D_ESTIMATOR, D_PROCESS, D_F, D_QH,
       D_A3, D_A4, N_ESTIMATOR };
/* Its columns, in this order (each n values; NULL: not wanted). */
enum { C_TIME, C_X, C_Y, C_Z, C_ZY, C_XHAT, C_P, C_DC1, C_DC2, C_DC3, C_ZCOMP, N_COLUMNS };

/* models.adxl203.simulate for one run: Excitation -> Accelerometer -> DriftEstimator, samples
 * k = 1..n.  Returns 0, 1 for an estimator or process the Python refuses, or 2 when the harmonic
 * filter's covariance is not valid after a sample (models.harmonic.check): bad[0] is that
 * sample, bad[1..3] the covariance (P, P12, P22). */
int driftfmu_adxl203(int64_t n, double Ts, const double *ex, const double *sp,
                     const double *es, double *const *cols, double *bad)
{
    const int64_t kind = (int64_t)ex[E_KIND], ex_seed = (int64_t)ex[E_SEED];
    const int64_t sp_seed = (int64_t)sp[S_SEED], estimator = (int64_t)es[D_ESTIMATOR],
                  process = (int64_t)es[D_PROCESS];
    const int noise_on = sp[S_NOISE] != 0.0, axes = (int)sp[S_AXES];
    /* the filter's model with the identified 3rd/4th-order terms (the DriftEstimator's a3, a4) */
    const int higher = es[D_A3] != 0.0 || es[D_A4] != 0.0;
    Config cfg = adxl203_config(sp[S_A0], sp[S_A1], sp[S_A2], sp[S_R], sp[S_A3], sp[S_CROSS],
                                sp[S_FC], sp[S_VS], (int64_t)sp[S_BITS], sp[S_DENSITY], Ts);
    double C, S, x = ex[E_X0], y, zy = 0.0, lp = 0.0, lpy = 0.0;
    int64_t lp_set = 0, lpy_set = 0;
    HarmonicState state;
    if (estimator < 1 || estimator > 3 ||
        (process != HARMONIC_GAUSS_MARKOV && process != HARMONIC_HARMONIC))
        return 1;
    harmonic_rotation(es[D_F], Ts, &C, &S);
    state = harmonic_estimator_init(process, es[D_X0], es[D_P0]);
    for (int64_t k = 1; k <= n; k++) {
        double v, vy, z, dcs[3], dc, row[N_COLUMNS];
        if (kind == EXCITATION_GAUSSIAN) {
            x = excitation_gaussian_sample(x, ex[E_A], ex[E_Q], ex_seed, k);
            y = 0.0;
        } else {
            x = excitation_sine(k, ex[E_X], ex[E_F], Ts, ex[E_PHI]);
            y = excitation_sine(k, ex[E_XY], ex[E_F], Ts, ex[E_PHIY]);
        }
        v = noise_on ? adxl203_noise(sp_seed, k, 1) : 0.0;
        adxl203_measure(lp_set, lp, x, y, v, &cfg, &lp_set, &lp, &z);
        if (axes == 2) {
            vy = noise_on ? adxl203_noise(sp_seed, k, 2) : 0.0;
            adxl203_measure(lpy_set, lpy, y, x, vy, &cfg, &lpy_set, &lpy, &zy);
        }
        if (higher) {
            state = harmonic_estimator_step_general(state, z, es[D_A0], es[D_A1], es[D_A2],
                                                    es[D_R], process, es[D_A], es[D_Q], C, S,
                                                    es[D_QH], es[D_A3], es[D_A4], 0.0, 0.0);
            drift_estimates_general(state.drift, es[D_A2], es[D_A3], es[D_A4], &dcs[0],
                                    &dcs[1], &dcs[2]);
        } else {
            state = harmonic_estimator_step(state, z, es[D_A0], es[D_A1], es[D_A2], es[D_R],
                                            process, es[D_A], es[D_Q], C, S, es[D_QH]);
            drift_estimates(state.drift, es[D_A2], &dcs[0], &dcs[1], &dcs[2]);
        }
        if (process == HARMONIC_HARMONIC && !covariance_valid2(state.P, state.P12, state.P22)) {
            bad[0] = (double)k;
            bad[1] = state.P;
            bad[2] = state.P12;
            bad[3] = state.P22;
            return 2;
        }
        dc = drift_select(dcs, estimator);
        row[C_TIME] = (double)(k - 1) * Ts;
        row[C_X] = x;
        row[C_Y] = y;
        row[C_Z] = z;
        row[C_ZY] = zy;
        row[C_XHAT] = state.x;
        row[C_P] = state.P;
        row[C_DC1] = dcs[0];
        row[C_DC2] = dcs[1];
        row[C_DC3] = dcs[2];
        row[C_ZCOMP] = z - dc;
        for (int c = 0; c < N_COLUMNS; c++)
            if (cols[c]) cols[c][k - 1] = row[c];
    }
    return 0;
}

/* models.dualaxis.simulate's start values (resolved by the caller: excitation_values,
 * sensor_values, estimator_values, single_values), in these orders. */
enum { DE_KIND, DE_A, DE_Q, DE_QY, DE_RHO, DE_X0, DE_X, DE_F, DE_PHI, DE_XY, DE_PHIY,
       N_DUAL_EXCITATION };
enum { DS_A0, DS_A1, DS_A2, DS_BX, DS_R, DS_A0Y, DS_A1Y, DS_A2Y, DS_BY, DS_RY, DS_NOISE,
       N_DUAL_SENSOR };
enum { DD_A0, DD_A1, DD_A2, DD_BX, DD_R, DD_A0Y, DD_A1Y, DD_A2Y, DD_BY, DD_RY, DD_A, DD_Q,
       DD_QY, DD_RHO, DD_X0, DD_Y0, DD_P0, DD_P0Y, DD_F, DD_QH, DD_PROCESS, DD_ESTIMATOR,
       N_DUAL_ESTIMATOR };
/* single_values of one axis: a0, a1, a2, R, Q, x0, P0, A, process, f, Qh. */
enum { D1_A0, D1_A1, D1_A2, D1_R, D1_Q, D1_X0, D1_P0, D1_A, D1_PROCESS, D1_F, D1_QH,
       N_SINGLE };
/* models.dualaxis.COLUMNS, in this order, then the realised moments (finals only). */
enum { DC_TIME, DC_X, DC_Y, DC_ZX, DC_ZY, DC_XHAT, DC_YHAT, DC_PXX, DC_PXY, DC_PYY,
       DC_DC1X, DC_DC2X, DC_DC3X, DC_DC1Y, DC_DC2Y, DC_DC3Y, DC_ZCOMPX, DC_ZCOMPY,
       DC_SINGLE1X, DC_SINGLE1Y, N_DUAL_COLUMNS };
enum { DM_XX = N_DUAL_COLUMNS, DM_XY, DM_YY, N_DUAL_FINALS };

/* The first covariance of driftfmu_dual that is not valid, in the order the NumPy form
 * (models.dualaxis.simulate) meets it: the earliest sample, then the filter (0 the dual one,
 * 1 and 2 the single-axis ones), then the run.  bad: (sample, filter, run, the covariance's
 * lower triangle packed by rows); bad[0] = 0 while none is found. */
static void first_bad(double *bad, int64_t k, int filter, int64_t r, int size,
                      const double *lower)
{
    if (bad[0] != 0.0 && (bad[0] < (double)k || (bad[0] == (double)k && bad[1] <= filter)))
        return; /* (runs go up: an earlier run at the same sample and filter is kept) */
    bad[0] = (double)k;
    bad[1] = filter;
    bad[2] = (double)r;
    for (int i = 0; i < size * (size + 1) / 2; i++) bad[3 + i] = lower[i];
}

/* models.dualaxis.simulate for `runs` runs (FMU seed seeds[r] for the Excitation and the
 * Accelerometer), the other start values shared: the recorded columns are (runs, n) arrays
 * (NULL: not recorded), finals[c] (runs,) arrays of every column's last sample and the three
 * realised moments.  Returns 0, 1 for an estimator or process the Python refuses, or 2 when a
 * filter's covariance is not valid after a sample (models.dualaxis.check, harmonic.check): a
 * run stops there, and bad (13 values) says where first (first_bad). */
int driftfmu_dual(int64_t n, int64_t runs, const uint64_t *seeds, double Ts, const double *ex,
                  const double *sp, const double *es, const double *single,
                  double *const *cols, double *const *finals, double *bad)
{
    const int64_t process = (int64_t)es[DD_PROCESS], estimator = (int64_t)es[DD_ESTIMATOR];
    const int gaussian = (int64_t)ex[DE_KIND] == EXCITATION_GAUSSIAN,
              noise_on = sp[DS_NOISE] != 0.0;
    Axis sx, sy, fx, fy;
    DualModel m;
    double C[2], S[2];
    if (estimator < 1 || estimator > 3 ||
        (process != DUALAXIS_GAUSS_MARKOV && process != DUALAXIS_HARMONIC))
        return 1;
    for (int i = 0; i < 2; i++) {
        const int64_t p1 = (int64_t)single[i * N_SINGLE + D1_PROCESS];
        if (p1 != HARMONIC_GAUSS_MARKOV && p1 != HARMONIC_HARMONIC) return 1;
        harmonic_rotation(single[i * N_SINGLE + D1_F], Ts, &C[i], &S[i]);
    }
    dualaxis_axes(sp[DS_A0], sp[DS_A1], sp[DS_A2], sp[DS_BX], sp[DS_R], sp[DS_A0Y],
                  sp[DS_A1Y], sp[DS_A2Y], sp[DS_BY], sp[DS_RY], &sx, &sy);
    dualaxis_axes(es[DD_A0], es[DD_A1], es[DD_A2], es[DD_BX], es[DD_R], es[DD_A0Y],
                  es[DD_A1Y], es[DD_A2Y], es[DD_BY], es[DD_RY], &fx, &fy);
    m = dualaxis_model(process, es[DD_A], es[DD_Q], es[DD_QY], es[DD_RHO], es[DD_F], Ts,
                       es[DD_QH]);
    bad[0] = 0.0;
    for (int64_t r = 0; r < runs; r++) {
        const int64_t seed = (int64_t)seeds[r];
        DualEstimator st = dualaxis_estimator_init(process, es[DD_X0], es[DD_Y0], es[DD_P0],
                                                   es[DD_P0Y]);
        HarmonicState sst[2];
        double x = ex[DE_X0], y = 0.0, mxx = 0.0, mxy = 0.0, myy = 0.0, row[N_DUAL_COLUMNS];
        int stopped = 0;
        for (int i = 0; i < 2; i++) {
            const double *s1 = single + i * N_SINGLE;
            sst[i] = harmonic_estimator_init((int64_t)s1[D1_PROCESS], s1[D1_X0], s1[D1_P0]);
        }
        for (int64_t k = 1; k <= n; k++) {
            double vx = 0.0, vy = 0.0, zx, zy, dx[3], dy[3], mom[5];
            if (gaussian) {
                excitation_gaussian_pair(x, y, ex[DE_A], ex[DE_Q], ex[DE_QY], ex[DE_RHO], seed,
                                         k, &x, &y);
            } else {
                x = excitation_sine(k, ex[DE_X], ex[DE_F], Ts, ex[DE_PHI]);
                y = excitation_sine(k, ex[DE_XY], ex[DE_F], Ts, ex[DE_PHIY]);
            }
            if (noise_on) dualaxis_noise(seed, k, &vx, &vy);
            dualaxis_measure(x, y, sx, sy, vx, vy, &zx, &zy);
            st = dualaxis_estimator_step(st, zx, zy, fx, fy, &m);
            if (!dualaxis_valid(&st, process)) {
                double lower[10];
                first_bad(bad, k, 0, r, dualaxis_covariance_of(&st, process, lower), lower);
                stopped = 1;
                break;
            }
            dualaxis_estimates(dualaxis_drift_of(&st, process), fx, fy, dx, dy);
            int stop = 0;
            for (int i = 0; i < 2 && !stop; i++) {
                const double *s1 = single + i * N_SINGLE;
                sst[i] = harmonic_estimator_step(sst[i], i == 0 ? zx : zy, s1[D1_A0],
                                                 s1[D1_A1], s1[D1_A2], s1[D1_R],
                                                 (int64_t)s1[D1_PROCESS], s1[D1_A], s1[D1_Q],
                                                 C[i], S[i], s1[D1_QH]);
                if ((int64_t)s1[D1_PROCESS] == HARMONIC_HARMONIC &&
                    !covariance_valid2(sst[i].P, sst[i].P12, sst[i].P22)) {
                    const double lower[3] = {sst[i].P, sst[i].P12, sst[i].P22};
                    first_bad(bad, k, 1 + i, r, 2, lower);
                    stop = 1;
                }
            }
            if (stop) {
                stopped = 1;
                break;
            }
            mxx = drift_running_mean(mxx, x * x, k);
            mxy = drift_running_mean(mxy, x * y, k);
            myy = drift_running_mean(myy, y * y, k);
            dualaxis_moments(&st, process, mom);
            row[DC_TIME] = (double)(k - 1) * Ts;
            row[DC_X] = x;
            row[DC_Y] = y;
            row[DC_ZX] = zx;
            row[DC_ZY] = zy;
            row[DC_XHAT] = mom[0];
            row[DC_YHAT] = mom[1];
            row[DC_PXX] = mom[2];
            row[DC_PXY] = mom[3];
            row[DC_PYY] = mom[4];
            for (int i = 0; i < 3; i++) {
                row[DC_DC1X + i] = dx[i];
                row[DC_DC1Y + i] = dy[i];
            }
            row[DC_ZCOMPX] = zx - drift_select(dx, estimator);
            row[DC_ZCOMPY] = zy - drift_select(dy, estimator);
            row[DC_SINGLE1X] = single[D1_A2] * sst[0].drift.s1;
            row[DC_SINGLE1Y] = single[N_SINGLE + D1_A2] * sst[1].drift.s1;
            for (int c = 0; c < N_DUAL_COLUMNS; c++)
                if (cols[c]) cols[c][(size_t)r * (size_t)n + (size_t)(k - 1)] = row[c];
        }
        if (stopped) continue; /* (the call returns 2: its results are not used) */
        for (int c = 0; c < N_DUAL_COLUMNS; c++) finals[c][r] = row[c];
        finals[DM_XX][r] = mxx;
        finals[DM_XY][r] = mxy;
        finals[DM_YY][r] = myy;
    }
    return bad[0] != 0.0 ? 2 : 0;
}
