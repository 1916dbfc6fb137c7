/* parameters: C port of the checks of models/parameters.py (allowed, problem), with the
 * messages character for character as Python writes them (floats as Python's repr). */
#ifndef DRIFTFMU_PARAMETERS_H
#define DRIFTFMU_PARAMETERS_H

#include <stddef.h>
#include <stdint.h>

/* Receives one problem message (NUL-terminated, no newline) at a time, in order. */
typedef void (*driftfmu_report)(void *ctx, const char *message);

/* Longest message any check writes, NUL included. */
#define PARAMETERS_MESSAGE_MAX 512

/* Python's repr of a float (shortest round trip: '0.001', '1e-05', '1.0', 'inf', 'nan');
 * returns the length written (truncated to n - 1). */
int parameters_repr_float(double v, char *out, size_t n);
/* models.parameters.allowed(name) into out; -1 if name is not a parameter. */
int parameters_allowed(const char *name, char *out, size_t n);
/* models.parameters.problem(name, value): 1 and the message in out if value is not allowed,
 * 0 if it is, -1 if name is not a parameter.  is_integer: the value is a Python int (an
 * Integer variable), printed as an int; else a float. */
int parameters_problem(const char *name, double value, int is_integer, char *out, size_t n);

#endif
