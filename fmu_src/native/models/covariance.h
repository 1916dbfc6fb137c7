/* covariance: C port of models/covariance.py (when a filter's covariance is valid: every
 * variance >= 0 and the matrix positive semi-definite within rounding), with the messages
 * character for character as Python writes them. */
#ifndef DRIFTFMU_COVARIANCE_H
#define DRIFTFMU_COVARIANCE_H

#include <stddef.h>

/* models.covariance.SLACK = 2^-20 and BOUND = 1 + SLACK. */
#define COVARIANCE_SLACK 9.5367431640625e-07
#define COVARIANCE_BOUND 1.0000009536743164
/* The largest matrix (the dual-axis harmonic filter's 4x4). */
#define COVARIANCE_MAX 4
/* models.covariance.CAUSE and ALLOWED. */
#define COVARIANCE_CAUSE "the inputs and parameters exceed what double precision can carry"
#define COVARIANCE_ALLOWED "values whose covariances stay positive semi-definite"

/* models.covariance.valid2: 1 if [[P11, P12], [P12, P22]] is valid, else 0. */
int covariance_valid2(double P11, double P12, double P22);
/* models.covariance.valid of the n x n matrix (n <= COVARIANCE_MAX) whose lower triangle is
 * `lower`, packed by rows (P00, P10, P11, P20, P21, P22, ...): 1 if valid, else 0. */
int covariance_valid(int n, const double *lower);
/* models.covariance.problem: 0 if valid; else 1 and the subject, the values and what is wrong
 * written into the three buffers (`names` as `lower`, packed by rows; `listing` the matrix's
 * name as a whole, or NULL for "the covariance (<names>)"). */
int covariance_problem(int n, const double *lower, const char *const *names,
                       const char *listing, char *subject, size_t n_subject, char *values,
                       size_t n_values, const char **what);
/* models.covariance.refusal into out (size n_out): the FMUs' message refusing sample k at time
 * t for the (invalid) covariance. */
void covariance_refusal(int n, const double *lower, const char *const *names,
                        const char *listing, long long k, double t, char *out, size_t n_out);
/* models.covariance.state_problems: 0, or 1 and the problem of a covariance read back from an
 * FMU state written into out. */
int covariance_state_problem(int n, const double *lower, const char *const *names,
                             const char *listing, char *out, size_t n_out);

#endif
