/*
 * host_common.h - what the C test hosts (Linux) share: loading an FMU's library and its
 * functions, the loggers, the resident memory.  Header-only: include it once, in the host's
 * one source file, after fmi2Functions.h and/or fmi3Functions.h (fmpy's c-code headers).
 *
 *   host_open(dir, fmi, id)      dlopen DIR/binaries/<linux64|x86_64-linux>/ID.so, or print
 *                                "DLOPEN <reason>" and exit 4
 *   host_lookup(lib, name)       dlsym, or print "MISSING <name>" and exit 4
 *   host_logger2, host_logger3   print "LOG <status> <category>: <message>" (unless host_quiet)
 *   host_rss_bytes()             resident memory of the process, bytes (/proc/self/statm)
 *   host_measure(what, i, every) print "RSS <what> <i+1> <bytes>" after every EVERY-th call
 */
#ifndef HOST_COMMON_H
#define HOST_COMMON_H

#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

static int host_quiet;

static inline void *host_lookup(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (!f) {
        printf("MISSING %s\n", name);
        exit(4);
    }
    return f;
}

/* The FMU's library for FMI version `fmi` (2 or 3) unzipped in `dir`. */
static inline void *host_open(const char *dir, int fmi, const char *id)
{
    char path[8192];
    snprintf(path, sizeof path, "%s/binaries/%s/%s.so", dir,
             fmi == 2 ? "linux64" : "x86_64-linux", id);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        printf("DLOPEN %s\n", dlerror());
        exit(4);
    }
    return lib;
}

static inline void host_vlog(int status, const char *category, const char *message,
                             va_list args)
{
    if (host_quiet)
        return;
    printf("LOG %d %s: ", status, category ? category : "");
    vprintf(message, args);
    printf("\n");
    fflush(stdout);
}

#ifdef fmi2Functions_h
static inline void host_logger2(fmi2ComponentEnvironment env, fmi2String name,
                                fmi2Status status, fmi2String category, fmi2String message,
                                ...)
{
    (void)env;
    (void)name;
    va_list args;
    va_start(args, message);
    host_vlog((int)status, category, message, args);
    va_end(args);
}
#endif

#ifdef fmi3Functions_h
static inline void host_logger3_(int status, const char *category, const char *message,
                                 ...)
{
    va_list args;
    va_start(args, message);
    host_vlog(status, category, message, args);
    va_end(args);
}

static inline void host_logger3(fmi3InstanceEnvironment env, fmi3Status status,
                                fmi3String category, fmi3String message)
{
    (void)env;
    host_logger3_((int)status, category, "%s", message ? message : "");
}
#endif

static inline long host_rss_bytes(void)
{
    long pages = 0, resident = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &resident) != 2)
            resident = 0;
        fclose(f);
    }
    return resident * 4096;
}

static inline void host_measure(const char *what, long i, long every)
{
    if (every > 0 && (i + 1) % every == 0) {
        printf("RSS %s %ld %ld\n", what, i + 1, host_rss_bytes());
        fflush(stdout);
    }
}

#endif
