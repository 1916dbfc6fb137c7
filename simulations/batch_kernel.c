/* The compiled batch kernel: the chains of simulations/batch.py (simulate) and of
 * models/adxl203.py (simulate) written out over the C port of models/ (fmu_src/native/models),
 * one run after another.  Built by simulations/kernel.py with the flags of the native FMUs
 * (-std=c99 -O2 -ffp-contract=off -fno-fast-math), so every sample gives the bits of the NumPy
 * batch engine and of the FMUs.  No state of its own: the caller owns every array. */
#include <stddef.h>
#include <stdint.h>

#include "adxl203.h"
#include "chain.h"
#include "drift.h"
#include "excitation.h"
#include "harmonic.h"
#include "noise.h"
#include "sensor.h"

/* One run of simulations.batch.simulate between blocks: the excitation, the filter and the two
 * running means (ten 8-byte fields, the layout of a (runs, 10) float64 array). */
typedef struct {
    double x, zbar, x2bar;
    EstimatorState est;
} RunState;

/* The per-run parameters of batch.simulate, in this order, each an array of `runs` values. */
enum { P_A0, P_A1, P_A2, P_A, P_Q, P_R, P_X0, P_P0, P_TS, P_X, P_F, P_PHI, P_FA, P_FQ,
       N_PARAMS };

/* batch.TRAJECTORIES, in this order; a NULL pointer is a trajectory not recorded. */
enum { T_X, T_Z, T_XHAT, T_P, T_DC1, T_DC2, T_DC3, T_EMPIRICAL, T_REALISED, N_TRAJ };

/* The state of every run before sample 1: x = x0, the filter at (x0, P0), means 0. */
void driftfmu_batch_init(int64_t runs, const double *const *p, RunState *state)
{
    for (int64_t r = 0; r < runs; r++) {
        state[r].x = p[P_X0][r];
        state[r].zbar = 0.0;
        state[r].x2bar = 0.0;
        state[r].est = chain_estimator_init(p[P_X0][r], p[P_P0][r]);
    }
}

/* Runs advanced side by side, sample by sample: their chains are independent, so the
 * processor overlaps the divisions and square roots of one with those of the others. */
#define LANES 8

/* Samples k = k0 .. k1 - 1 of every run (the loop body of batch.simulate); the recorded
 * trajectories are (runs, n) arrays, sample k in column k - 1. */
void driftfmu_batch_run(int64_t k0, int64_t k1, int64_t n, int64_t runs, const uint64_t *seeds,
                        int64_t kind, const double *const *p, RunState *state,
                        double *const *traj)
{
    const int gaussian = kind == EXCITATION_GAUSSIAN;
    for (int64_t r0 = 0; r0 < runs; r0 += LANES) {
        const int lanes = runs - r0 < LANES ? (int)(runs - r0) : LANES;
        RunState s[LANES];
        for (int i = 0; i < lanes; i++) s[i] = state[r0 + i];
        for (int64_t k = k0; k < k1; k++) {
            for (int i = 0; i < lanes; i++) {
                const int64_t r = r0 + i;
                const uint64_t seed = seeds[r];
                const double a0 = p[P_A0][r], a1 = p[P_A1][r], a2 = p[P_A2][r],
                             R = p[P_R][r];
                double z, dc1, dc2, dc3;
                if (gaussian)
                    s[i].x = excitation_gauss_markov(
                        s[i].x, p[P_A][r], p[P_Q][r],
                        noise_normal(seed, NOISE_STREAM_PROCESS, (uint64_t)k));
                else
                    s[i].x = excitation_sine(k, p[P_X][r], p[P_F][r], p[P_TS][r], p[P_PHI][r]);
                z = sensor_measure(s[i].x, a0, a1, a2, R,
                                   noise_normal(seed, NOISE_STREAM_MEASUREMENT, (uint64_t)k));
                s[i].est = chain_estimator_step(s[i].est, z, a0, a1, a2, p[P_FA][r], p[P_FQ][r],
                                                R);
                s[i].zbar = drift_running_mean(s[i].zbar, z, k);
                s[i].x2bar = drift_running_mean(s[i].x2bar, s[i].x * s[i].x, k);
                if (traj) {
                    size_t j = (size_t)r * (size_t)n + (size_t)(k - 1);
                    drift_estimates(s[i].est.drift, a2, &dc1, &dc2, &dc3);
                    if (traj[T_X]) traj[T_X][j] = s[i].x;
                    if (traj[T_Z]) traj[T_Z][j] = z;
                    if (traj[T_XHAT]) traj[T_XHAT][j] = s[i].est.x;
                    if (traj[T_P]) traj[T_P][j] = s[i].est.P;
                    if (traj[T_DC1]) traj[T_DC1][j] = dc1;
                    if (traj[T_DC2]) traj[T_DC2][j] = dc2;
                    if (traj[T_DC3]) traj[T_DC3][j] = dc3;
                    if (traj[T_EMPIRICAL]) traj[T_EMPIRICAL][j] = s[i].zbar - a0;
                    if (traj[T_REALISED]) traj[T_REALISED][j] = a2 * s[i].x2bar;
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
       N_ESTIMATOR };
/* Its columns, in this order (each n values; NULL: not wanted). */
enum { C_TIME, C_X, C_Y, C_Z, C_ZY, C_XHAT, C_P, C_DC1, C_DC2, C_DC3, C_ZCOMP, N_COLUMNS };

/* models.adxl203.simulate for one run: Excitation -> Accelerometer -> DriftEstimator, samples
 * k = 1..n.  Returns 0, or 1 for an estimator or process the Python refuses. */
int driftfmu_adxl203(int64_t n, double Ts, const double *ex, const double *sp,
                     const double *es, double *const *cols)
{
    const int64_t kind = (int64_t)ex[E_KIND], ex_seed = (int64_t)ex[E_SEED];
    const int64_t sp_seed = (int64_t)sp[S_SEED], estimator = (int64_t)es[D_ESTIMATOR],
                  process = (int64_t)es[D_PROCESS];
    const int noise_on = sp[S_NOISE] != 0.0, axes = (int)sp[S_AXES];
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
        state = harmonic_estimator_step(state, z, es[D_A0], es[D_A1], es[D_A2], es[D_R],
                                        process, es[D_A], es[D_Q], C, S, es[D_QH]);
        drift_estimates(state.drift, es[D_A2], &dcs[0], &dcs[1], &dcs[2]);
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
