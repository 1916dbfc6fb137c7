/*
 * widen.c - an LD_PRELOAD library for tests/test_state_handles_threads.py that holds open the
 * windows the Python FMUs' loader shim guards with its locks (fmu_src/loader/fmi2_shim.c): every
 * symlink (the link to a resources folder pythonfmu cannot read) and the load of pythonfmu's
 * library wait 200 ms first, so that the other threads, released together, arrive while one is
 * inside.  A lock keeps them out until it is done; without the lock they run into each other
 * every time (two links of one name: the second fails).  It changes no result, only timing.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <string.h>
#include <time.h>
static void pause_ms(long ms)
{
    struct timespec t = {0, ms * 1000000L};
    nanosleep(&t, NULL);
}
int symlink(const char *target, const char *link)
{
    static int (*real)(const char *, const char *);
    if (!real)
        real = (int (*)(const char *, const char *))dlsym(RTLD_NEXT, "symlink");
    pause_ms(200);
    return real(target, link);
}
void *dlopen(const char *file, int flags)
{
    static void *(*real)(const char *, int);
    if (!real)
        real = (void *(*)(const char *, int))dlsym(RTLD_NEXT, "dlopen");
    if (file && strstr(file, "pythonfmu") && !(flags & RTLD_NOLOAD))
        pause_ms(200);
    return real(file, flags);
}
