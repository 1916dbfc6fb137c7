/* covariance: C port of models/covariance.py; see covariance.h. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "covariance.h"
#include "ops.h"
#include "parameters.h"

/* (row i, column j <= i) of the packed lower triangle */
#define AT(lower, i, j) ((lower)[(i) * ((i) + 1) / 2 + (j)])

int covariance_valid2(double P11, double P12, double P22)
{
    double s1, s2, c;
    if (!(P11 >= 0.0 && P22 >= 0.0)) return 0;
    s1 = ops_sqrt(P11);
    s2 = ops_sqrt(P22);
    if (s2 * s1 == 0.0) return P12 == 0.0;
    c = P12 / s1 / s2;
    return COVARIANCE_BOUND - c * (c / COVARIANCE_BOUND) > 0.0;
}

/* models.covariance._valid_floats */
int covariance_valid(int n, const double *lower)
{
    double s[COVARIANCE_MAX], c[COVARIANCE_MAX][COVARIANCE_MAX], u[COVARIANCE_MAX][COVARIANCE_MAX];
    double d[COVARIANCE_MAX];
    int i, j, k;
    if (n < 1 || n > COVARIANCE_MAX) return 0;
    for (i = 0; i < n; i++)
        if (!(AT(lower, i, i) >= 0.0)) return 0;
    for (i = 0; i < n; i++) s[i] = ops_sqrt(AT(lower, i, i));
    for (i = 0; i < n; i++)
        for (j = 0; j < i; j++) {
            if (s[i] * s[j] == 0.0) {
                if (AT(lower, i, j) != 0.0) return 0;
                c[i][j] = 0.0;
            } else {
                c[i][j] = AT(lower, i, j) / s[j] / s[i];
            }
        }
    for (j = 0; j < n; j++) { /* L D L^T, u_ij = l_ij d_j */
        double dj = COVARIANCE_BOUND;
        for (k = 0; k < j; k++) dj = dj - u[j][k] * (u[j][k] / d[k]);
        if (!(dj > 0.0)) return 0;
        d[j] = dj;
        for (i = j + 1; i < n; i++) {
            double v = c[i][j];
            for (k = 0; k < j; k++) v = v - u[i][k] * (u[j][k] / d[k]);
            u[i][j] = v;
        }
    }
    return 1;
}

int covariance_problem(int n, const double *lower, const char *const *names,
                       const char *listing, char *subject, size_t n_subject, char *values,
                       size_t n_values, const char **what)
{
    const int m = n * (n + 1) / 2;
    char b[32];
    int i;
    size_t used;
    if (covariance_valid(n, lower)) return 0;
    for (i = 0; i < m; i++)
        if (!isfinite(lower[i])) {
            snprintf(subject, n_subject, "%s", names[i]);
            parameters_repr_float(lower[i], values, n_values);
            *what = "not finite";
            return 1;
        }
    for (i = 0; i < n; i++)
        if (!(AT(lower, i, i) >= 0.0)) {
            snprintf(subject, n_subject, "%s", names[i * (i + 1) / 2 + i]);
            parameters_repr_float(AT(lower, i, i), values, n_values);
            *what = "a negative variance";
            return 1;
        }
    if (listing) {
        snprintf(subject, n_subject, "%s", listing);
    } else {
        used = (size_t)snprintf(subject, n_subject, "the covariance (");
        for (i = 0; i < m && used < n_subject; i++)
            used += (size_t)snprintf(subject + used, n_subject - used, "%s%s", i ? ", " : "",
                                     names[i]);
        if (used < n_subject) snprintf(subject + used, n_subject - used, ")");
    }
    used = (size_t)snprintf(values, n_values, "(");
    for (i = 0; i < m && used < n_values; i++) {
        parameters_repr_float(lower[i], b, sizeof b);
        used += (size_t)snprintf(values + used, n_values - used, "%s%s", i ? ", " : "", b);
    }
    if (used < n_values) snprintf(values + used, n_values - used, ")");
    *what = "not positive semi-definite";
    return 1;
}

void covariance_refusal(int n, const double *lower, const char *const *names,
                        const char *listing, long long k, double t, char *out, size_t n_out)
{
    char subject[512], values[512], bt[32];
    const char *what = "";
    if (!covariance_problem(n, lower, names, listing, subject, sizeof subject, values,
                            sizeof values, &what)) {
        snprintf(out, n_out, "(the covariance is valid)");
        return;
    }
    parameters_repr_float(t, bt, sizeof bt);
    snprintf(out, n_out, "%s would be %s at sample %lld (t = %s s), %s: %s; allowed: %s (nothing "
             "was changed)", subject, values, k, bt, what, COVARIANCE_CAUSE, COVARIANCE_ALLOWED);
}

int covariance_state_problem(int n, const double *lower, const char *const *names,
                             const char *listing, char *out, size_t n_out)
{
    char subject[512], values[512];
    const char *what = "";
    if (!covariance_problem(n, lower, names, listing, subject, sizeof subject, values,
                            sizeof values, &what))
        return 0;
    snprintf(out, n_out, "%s = %s is %s; allowed: a covariance whose variances are >= 0 and that "
             "is positive semi-definite (docs/method.md)", subject, values, what);
    return 1;
}
