/* parameters: C port of the checks of models/parameters.py; see parameters.h.  The table of
 * parameters is generated from models/parameters.py (parameters_table.h, by generate.py). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "parameters.h"

typedef struct {
    const char *name;
    int has_low;
    double low;
    int has_high;
    double high;
    int low_open, high_open;
    int integer; /* the default is an int: a fractional value is not an integer */
    int nonzero; /* parameters.NONZERO: 0 is refused beyond the range */
    const char *allowed;
} ParameterRow;

#include "parameters_table.h"

static const ParameterRow *find(const char *name)
{
    int i;
    for (i = 0; i < PARAMETERS_COUNT; i++)
        if (strcmp(PARAMETER_ROWS[i].name, name) == 0) return &PARAMETER_ROWS[i];
    return NULL;
}

static int put(char *out, size_t n, const char *s)
{
    int len = (int)strlen(s);
    if (n > 0) {
        size_t c = (size_t)len < n - 1 ? (size_t)len : n - 1;
        memcpy(out, s, c);
        out[c] = '\0';
    }
    return len;
}

int parameters_repr_float(double v, char *out, size_t n)
{
    char buf[64], digits[32], res[64];
    int p, nd = 0, decpt, neg, i, len = 0;
    const char *c;
    if (v != v) return put(out, n, "nan");
    if (v == HUGE_VAL) return put(out, n, "inf");
    if (v == -HUGE_VAL) return put(out, n, "-inf");
    neg = signbit(v) != 0;
    if (v == 0.0) return put(out, n, neg ? "-0.0" : "0.0");
    /* shortest correctly rounded %e form that reads back to the same double */
    for (p = 1; p <= 17; p++) {
        snprintf(buf, sizeof buf, "%.*e", p - 1, fabs(v));
        if (strtod(buf, NULL) == fabs(v)) break;
    }
    for (c = buf; *c && *c != 'e'; c++)
        if (*c >= '0' && *c <= '9') digits[nd++] = *c;
    while (nd > 1 && digits[nd - 1] == '0') nd--; /* %e pads; repr does not */
    digits[nd] = '\0';
    decpt = atoi(c + 1) + 1; /* v = 0.d1d2... 10^decpt */
    if (neg) res[len++] = '-';
    if (decpt <= -4 || decpt > 16) { /* Python's repr switches to exponent form here */
        res[len++] = digits[0];
        if (nd > 1) {
            res[len++] = '.';
            for (i = 1; i < nd; i++) res[len++] = digits[i];
        }
        len += snprintf(res + len, sizeof res - (size_t)len, "e%c%02d", decpt - 1 < 0 ? '-' : '+',
                        abs(decpt - 1));
    } else if (decpt <= 0) {
        res[len++] = '0';
        res[len++] = '.';
        for (i = 0; i < -decpt; i++) res[len++] = '0';
        for (i = 0; i < nd; i++) res[len++] = digits[i];
    } else if (decpt >= nd) {
        for (i = 0; i < nd; i++) res[len++] = digits[i];
        for (i = nd; i < decpt; i++) res[len++] = '0';
        res[len++] = '.';
        res[len++] = '0';
    } else {
        for (i = 0; i < decpt; i++) res[len++] = digits[i];
        res[len++] = '.';
        for (i = decpt; i < nd; i++) res[len++] = digits[i];
    }
    res[len] = '\0';
    return put(out, n, res);
}

int parameters_allowed(const char *name, char *out, size_t n)
{
    const ParameterRow *p = find(name);
    if (!p) return -1;
    return put(out, n, p->allowed);
}

int parameters_problem(const char *name, double value, int is_integer, char *out, size_t n)
{
    const ParameterRow *p = find(name);
    char r[40];
    int bad;
    if (!p) return -1;
    if (!isfinite(value)) {
        parameters_repr_float(value, r, sizeof r);
        if (n > 0) snprintf(out, n, "%s = %s is not finite; allowed: %s%s", name, r,
                            strcmp(p->allowed, "any finite value") ? "a finite value with " : "",
                            p->allowed);
        return 1;
    }
    if (p->integer && value != floor(value)) { /* a wrong type, whatever its range */
        parameters_repr_float(value, r, sizeof r);
        if (n > 0) snprintf(out, n, "%s = %s is not an integer; allowed: %s", name, r, p->allowed);
        return 1;
    }
    bad = 0;
    if (p->has_low) bad = p->low_open ? value <= p->low : value < p->low;
    if (!bad && p->has_high) bad = p->high_open ? value >= p->high : value > p->high;
    if (!bad && p->nonzero) bad = value == 0.0;
    if (!bad) return 0;
    if (is_integer)
        snprintf(r, sizeof r, "%.0f", value);
    else
        parameters_repr_float(value, r, sizeof r);
    if (n > 0) snprintf(out, n, "%s = %s is out of range; allowed: %s", name, r, p->allowed);
    return 1;
}
