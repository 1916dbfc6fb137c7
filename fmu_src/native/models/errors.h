/* errors: C port of models/errors.py (the sensor's slow errors: the letter's drift classes 2
 * to 4 and the measurement range), function for function.  A Python tuple of flicker
 * components is a fixed array of ERRORS_FLICKER_MAX with its length in ErrorConfig.fl_n (the
 * components beyond it are 0.0); Python's keyword arguments are positional, in the order of
 * models.errors.config. */
#ifndef DRIFTFMU_ERRORS_H
#define DRIFTFMU_ERRORS_H

#include <stdint.h>

#include "parameters.h"

/* models.errors.FLICKER_MAX, FLICKER_DECADES_MAX, LN10 */
#define ERRORS_FLICKER_MAX 8
#define ERRORS_FLICKER_DECADES_MAX 7
#define ERRORS_LN10 2.302585092994046

/* models.errors.ErrorConfig, same fields in the same order (on a flag). */
typedef struct {
    int64_t on;
    double bias_on, b_on, rw, gm_sigma, gm_a, gm_c;
    int64_t fl_n;
    double fl_sigma;
    double fl_a[ERRORS_FLICKER_MAX], fl_c[ERRORS_FLICKER_MAX];
    double d_inf, E_tau, Ts, T0, kT_bias, kT_scale, range;
} ErrorConfig;

/* models.errors.ErrorState: fl has ErrorConfig.fl_n components, the others 0.0. */
typedef struct {
    double rw, gm, E;
    double fl[ERRORS_FLICKER_MAX];
} ErrorState;

/* -- one function per process ---------------------------------------------------------- */
double errors_turn_on(double bias_on, int64_t seed);
double errors_random_walk(double b, double step, double n);
void errors_gauss_markov_coefficients(double sigma, double tau, double Ts, double *a,
                                      double *c);
double errors_gauss_markov(double b, double a, double c, double n);
/* The components' correlation times into taus[ERRORS_FLICKER_MAX]; returns their number. */
int64_t errors_flicker_taus(double tau_min, double tau_max, double *taus);
double errors_allan_variance_gm(double variance, double tau, double T);
double errors_flicker_sigma(double flicker, const double *taus, int64_t m);
/* One step of the flicker bias: the m components of `components` into `out` (which may be
 * `components`); their sum. */
double errors_flicker(const double *components, const double *a, const double *c,
                      const double *n, int64_t m, double *out);
/* One step of the exposure drift: the new E into *E_out; the drift d. */
double errors_exposure(double E, double x, double Ts, double d_inf, double E_tau, double *E_out);
/* The sine of the tilt held from sample to sample: models.errors' _TILT (there one per
 * process, here one per instance, in the FMU state): the last theta and ops_sin(theta). */
typedef struct {
    double theta, sine;
} ErrorTilt;
/* x + sin(theta), the sine from `held` while theta is the one held there (else computed and
 * kept there; held NULL: computed). */
double errors_tilt(double x, double theta, ErrorTilt *held);
void errors_temperature(double T, double T0, double kT_bias, double kT_scale, double *scale,
                        double *bias);
/* The letter's class 2 at x: the sensed acceleration (1 + kT_scale dT)(x + sin theta) into *u
 * (the tilt only when theta != 0, the scale only when kT_scale != 0), the thermal offset
 * kT_bias dT into *c. */
void errors_class2(double x, double theta, double T, double T0, double kT_bias, double kT_scale,
                   ErrorTilt *held, double *u, double *c);
/* The class-2 offset at x = 0: c + h(u; 0, a1, a2, a3, a4) of errors_class2(0, ...). */
double errors_class2_offset(double theta, double T, double a1, double a2, double T0,
                            double kT_bias, double kT_scale, double a3, double a4);
double errors_saturate(double u, double limit);

/* -- the constants, the initial state, the draws ------------------------------------------ */
ErrorConfig errors_config(int64_t seed, double Ts, double bias_on, double random_walk,
                          double bias_gm, double tau_gm, double flicker, double tau_min,
                          double tau_max, double d_inf, double E_tau, double T0,
                          double kT_bias, double kT_scale, double range);
/* Number of problems of models.errors.problems (the flicker band), each written to
 * report(ctx, message) in order. */
int errors_problems(double flicker, double tau_min, double tau_max, driftfmu_report report,
                    void *ctx);
ErrorState errors_initial_state(int64_t seed, const ErrorConfig *ecfg);
/* The draws of sample k: *n_rw, *n_gm and n_fl[ERRORS_FLICKER_MAX] (fl_n of them). */
void errors_draws(int64_t seed, int64_t k, const ErrorConfig *ecfg, double *n_rw,
                  double *n_gm, double *n_fl);

/* -- the composition ---------------------------------------------------------------------- */
/* The processes one sample on: the new state into *out (which may be `state`); *b the sum of
 * their samples. */
void errors_advance(const ErrorState *state, double x, double n_rw, double n_gm,
                    const double *n_fl, const ErrorConfig *ecfg, ErrorState *out, double *b);
/* errors_advance's new state alone, in place (a sample whose output no one sees: no sum, no
 * exposure drift's exponential). */
void errors_advance_state(ErrorState *state, double x, double n_rw, double n_gm,
                          const double *n_fl, const ErrorConfig *ecfg);
double errors_thermal_bias(double T, const ErrorConfig *ecfg);
double errors_sensed(double x, double theta, double T, const ErrorConfig *ecfg,
                     ErrorTilt *held);
/* The state after samples k0 + 1 .. k0 + m - 1 with x held. */
ErrorState errors_hold(ErrorState state, double x, int64_t seed, int64_t k0, int64_t m,
                       const ErrorConfig *ecfg);

#endif
