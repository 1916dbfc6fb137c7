/*
 * chain_host.c - an FMI 2.0 / FMI 3.0 co-simulation host for wired FMUs, with no Python in the
 * process (Linux: dlopen; Windows: LoadLibrary, cross-compiled with mingw-w64, run under wine).
 *
 * usage: chain_host SCRIPT     (SCRIPT "-" reads standard input)
 *
 * The script, one command a line ('#' starts a comment):
 *   fmi 2|3                              FMI version of every FMU below
 *   fmu NAME UNZIPDIR IDENTIFIER TOKEN   load UNZIPDIR/binaries/<platform>/IDENTIFIER.<so|dll>
 *                                        and instantiate it (instance NAME, debug logging off)
 *   real NAME VR VALUE                   set in initialisation mode (all FMUs: setup, enter)
 *   int NAME VR VALUE
 *   link SRC VR DST VR                   copied at every communication point, in this order
 *   record NAME VR                       printed at every communication point
 *   run STEPS STEP_SIZE [quiet]          exit initialisation, then STEPS communication points
 *                                        (Gauss-Seidel: links, then records), the same loop as
 *                                        simulations/cosim.py; "quiet" prints no rows
 *
 * Output: "ROW t v1 v2 ..." per point, every double as the 16 hex digits of its bits; then
 * "NS_PER_STEP x" (wall time of the stepping loop per communication point of all FMUs) and, not
 * on Windows, "CPU_NS_PER_STEP x" (the process's CPU time of that loop, all threads).
 * Log messages: "LOG <status> <message>".  Exit codes: 0 ok, 2 instantiation failed, 3 a call
 * failed, 4 a library or function could not be loaded, 1 a bad script.
 */
#define _POSIX_C_SOURCE 200809L
#define __USE_MINGW_ANSI_STDIO 1
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define PLATFORM2 "win64"
#define PLATFORM3 "x86_64-windows"
#define SUFFIX ".dll"
#else
#include <dlfcn.h>
#include <time.h>
/* FMI 2.0 names no architecture: linux64 on every 64-bit Linux, as fmpy and FMI Library */
#define PLATFORM2 "linux64"
#if defined(__aarch64__)
#define PLATFORM3 "aarch64-linux"
#else
#define PLATFORM3 "x86_64-linux"
#endif
#define SUFFIX ".so"
#endif

#include "fmi2Functions.h"
#include "fmi3Functions.h"

#define MAX_FMUS 8
#define MAX_LINKS 32
#define MAX_RECORDS 64

typedef struct {
    char name[64];
    void *lib;
    void *c;   /* fmi2Component or fmi3Instance */
    /* FMI 2 */
    fmi2SetupExperimentTYPE *setup2;
    fmi2EnterInitializationModeTYPE *enter2;
    fmi2ExitInitializationModeTYPE *exit2;
    fmi2DoStepTYPE *step2;
    fmi2GetRealTYPE *get2;
    fmi2SetRealTYPE *set2;
    fmi2SetIntegerTYPE *seti2;
    fmi2TerminateTYPE *term2;
    fmi2FreeInstanceTYPE *free2;
    /* FMI 3 */
    fmi3EnterInitializationModeTYPE *enter3;
    fmi3ExitInitializationModeTYPE *exit3;
    fmi3DoStepTYPE *step3;
    fmi3GetFloat64TYPE *get3;
    fmi3SetFloat64TYPE *set3;
    fmi3SetInt32TYPE *seti3;
    fmi3TerminateTYPE *term3;
    fmi3FreeInstanceTYPE *free3;
} Fmu;

static int fmi = 2;
static Fmu fmus[MAX_FMUS];
static int n_fmus = 0;
static int initialising = 0;

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                    fmi2String category, fmi2String message, ...)
{
    (void)env, (void)name, (void)category;
    va_list args;
    va_start(args, message);
    printf("LOG %d ", (int)status);
    vprintf(message, args);
    printf("\n");
    va_end(args);
    fflush(stdout);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                    fmi3String message)
{
    (void)env, (void)category;
    printf("LOG %d %s\n", (int)status, message);
    fflush(stdout);
}

static void *sym(void *lib, const char *name)
{
#ifdef _WIN32
    void *f = (void *)GetProcAddress((HMODULE)lib, name);
#else
    void *f = dlsym(lib, name);
#endif
    if (!f) {
        printf("MISSING %s\n", name);
        exit(4);
    }
    return f;
}

static void check(const char *call, int status)
{
    if (status > 1) {
        printf("CALL %s returned %d\n", call, status);
        exit(3);
    }
}

static Fmu *find(const char *name)
{
    for (int i = 0; i < n_fmus; i++)
        if (strcmp(fmus[i].name, name) == 0)
            return &fmus[i];
    printf("SCRIPT unknown FMU %s\n", name);
    exit(1);
}

static double now(void)
{
#ifdef _WIN32
    LARGE_INTEGER f, t;
    QueryPerformanceFrequency(&f);
    QueryPerformanceCounter(&t);
    return (double)t.QuadPart / (double)f.QuadPart;
#else
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
#endif
}

#ifndef _WIN32
/* CPU time of the process (all its threads), s: a step's cost on a machine shared with others. */
static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}
#endif

static fmi2CallbackFunctions callbacks2 = {logger2, calloc, free, NULL, NULL};

static void load(const char *name, const char *dir, const char *id, const char *token)
{
    if (n_fmus == MAX_FMUS) {
        printf("SCRIPT too many FMUs\n");
        exit(1);
    }
    Fmu *f = &fmus[n_fmus++];
    memset(f, 0, sizeof *f);
    snprintf(f->name, sizeof f->name, "%s", name);
    char path[4096], resources[4096];
    snprintf(path, sizeof path, "%s/binaries/%s/%s%s", dir, fmi == 2 ? PLATFORM2 : PLATFORM3, id,
             SUFFIX);
#ifdef _WIN32
    f->lib = (void *)LoadLibraryA(path);
    if (!f->lib) {
        printf("LOADLIBRARY %s failed (%lu)\n", path, (unsigned long)GetLastError());
        exit(4);
    }
#else
    f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->lib) {
        printf("DLOPEN %s\n", dlerror());
        exit(4);
    }
#endif
    if (fmi == 2) {
        fmi2InstantiateTYPE *inst = sym(f->lib, "fmi2Instantiate");
        f->setup2 = sym(f->lib, "fmi2SetupExperiment");
        f->enter2 = sym(f->lib, "fmi2EnterInitializationMode");
        f->exit2 = sym(f->lib, "fmi2ExitInitializationMode");
        f->step2 = sym(f->lib, "fmi2DoStep");
        f->get2 = sym(f->lib, "fmi2GetReal");
        f->set2 = sym(f->lib, "fmi2SetReal");
        f->seti2 = sym(f->lib, "fmi2SetInteger");
        f->term2 = sym(f->lib, "fmi2Terminate");
        f->free2 = sym(f->lib, "fmi2FreeInstance");
        snprintf(resources, sizeof resources, "file://%s%s/resources", dir[0] == '/' ? "" : "/",
                 dir);
        f->c = inst(name, fmi2CoSimulation, token, resources, &callbacks2, fmi2False, fmi2False);
    } else {
        fmi3InstantiateCoSimulationTYPE *inst = sym(f->lib, "fmi3InstantiateCoSimulation");
        f->enter3 = sym(f->lib, "fmi3EnterInitializationMode");
        f->exit3 = sym(f->lib, "fmi3ExitInitializationMode");
        f->step3 = sym(f->lib, "fmi3DoStep");
        f->get3 = sym(f->lib, "fmi3GetFloat64");
        f->set3 = sym(f->lib, "fmi3SetFloat64");
        f->seti3 = sym(f->lib, "fmi3SetInt32");
        f->term3 = sym(f->lib, "fmi3Terminate");
        f->free3 = sym(f->lib, "fmi3FreeInstance");
        snprintf(resources, sizeof resources, "%s/resources/", dir);
        f->c = inst(name, token, resources, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0,
                    NULL, logger3, NULL);
    }
    if (!f->c) {
        printf("INSTANTIATE %s FAILED\n", name);
        exit(2);
    }
}

static void initialise_all(void)
{
    if (initialising)
        return;
    for (int i = 0; i < n_fmus; i++) {
        Fmu *f = &fmus[i];
        if (fmi == 2) {
            check("fmi2SetupExperiment", f->setup2(f->c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
            check("fmi2EnterInitializationMode", f->enter2(f->c));
        } else {
            check("fmi3EnterInitializationMode",
                  f->enter3(f->c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
        }
    }
    initialising = 1;
}

static double get(Fmu *f, unsigned int vr)
{
    double v;
    if (fmi == 2)
        check("fmi2GetReal", f->get2(f->c, &vr, 1, &v));
    else
        check("fmi3GetFloat64", f->get3(f->c, &vr, 1, &v, 1));
    return v;
}

static void set(Fmu *f, unsigned int vr, double v)
{
    if (fmi == 2)
        check("fmi2SetReal", f->set2(f->c, &vr, 1, &v));
    else
        check("fmi3SetFloat64", f->set3(f->c, &vr, 1, &v, 1));
}

static void print_bits(double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    printf(" %016llx", (unsigned long long)u);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s SCRIPT\n", argv[0]);
        return 1;
    }
    FILE *in = strcmp(argv[1], "-") == 0 ? stdin : fopen(argv[1], "r");
    if (!in) {
        printf("SCRIPT cannot open %s\n", argv[1]);
        return 1;
    }
    struct { Fmu *src, *dst; unsigned int svr, dvr; } links[MAX_LINKS];
    struct { Fmu *f; unsigned int vr; } records[MAX_RECORDS];
    int n_links = 0, n_records = 0;
    char line[8192];
    while (fgets(line, sizeof line, in)) {
        char a[4096], b[4096], c[512], d[512], e[512];
        if (line[0] == '#' || line[0] == '\n')
            continue;
        if (sscanf(line, "fmi %d", &fmi) == 1)
            continue;
        if (sscanf(line, "fmu %63s %4095s %511s %511s", a, b, c, d) == 4) {
            load(a, b, c, d);
            continue;
        }
        if (sscanf(line, "real %63s %511s %511s", a, c, d) == 3) {
            initialise_all();
            set(find(a), (unsigned int)strtoul(c, NULL, 10), strtod(d, NULL));
            continue;
        }
        if (sscanf(line, "int %63s %511s %511s", a, c, d) == 3) {
            initialise_all();
            Fmu *f = find(a);
            unsigned int vr = (unsigned int)strtoul(c, NULL, 10);
            int v = atoi(d);
            if (fmi == 2)
                check("fmi2SetInteger", f->seti2(f->c, &vr, 1, &v));
            else
                check("fmi3SetInt32", f->seti3(f->c, &vr, 1, &v, 1));
            continue;
        }
        if (sscanf(line, "link %63s %511s %63s %511s", a, c, b, d) == 4) {
            links[n_links].src = find(a);
            links[n_links].svr = (unsigned int)strtoul(c, NULL, 10);
            links[n_links].dst = find(b);
            links[n_links].dvr = (unsigned int)strtoul(d, NULL, 10);
            n_links++;
            continue;
        }
        if (sscanf(line, "record %63s %511s", a, c) == 2) {
            records[n_records].f = find(a);
            records[n_records].vr = (unsigned int)strtoul(c, NULL, 10);
            n_records++;
            continue;
        }
        e[0] = 0;
        if (sscanf(line, "run %511s %511s %511s", c, d, e) >= 2) {
            long steps = strtol(c, NULL, 10);
            double h = strtod(d, NULL);
            int quiet = strcmp(e, "quiet") == 0;
            initialise_all();
            for (int i = 0; i < n_fmus; i++) {
                if (fmi == 2)
                    check("fmi2ExitInitializationMode", fmus[i].exit2(fmus[i].c));
                else
                    check("fmi3ExitInitializationMode", fmus[i].exit3(fmus[i].c));
            }
            double t = 0.0, start = now();
#ifndef _WIN32
            double cpu_start = cpu_now();
#endif
            for (long s = 0; s < steps; s++) {
                if (s) {
                    for (int i = 0; i < n_fmus; i++) {
                        if (fmi == 2) {
                            check("fmi2DoStep", fmus[i].step2(fmus[i].c, t, h, fmi2True));
                        } else {
                            fmi3Boolean ev, term, early;
                            fmi3Float64 last;
                            check("fmi3DoStep", fmus[i].step3(fmus[i].c, t, h, fmi3True, &ev,
                                                              &term, &early, &last));
                        }
                    }
                    t = s * h;
                }
                for (int l = 0; l < n_links; l++)
                    set(links[l].dst, links[l].dvr, get(links[l].src, links[l].svr));
                if (quiet) {
                    for (int r = 0; r < n_records; r++)
                        (void)get(records[r].f, records[r].vr);
                } else {
                    printf("ROW");
                    print_bits(t);
                    for (int r = 0; r < n_records; r++)
                        print_bits(get(records[r].f, records[r].vr));
                    printf("\n");
                }
            }
            double elapsed = now() - start;
            printf("NS_PER_STEP %.3f\n", steps > 1 ? 1e9 * elapsed / (steps - 1) : 0.0);
#ifndef _WIN32
            printf("CPU_NS_PER_STEP %.3f\n",
                   steps > 1 ? 1e9 * (cpu_now() - cpu_start) / (steps - 1) : 0.0);
#endif
            for (int i = 0; i < n_fmus; i++) {
                if (fmi == 2) {
                    check("fmi2Terminate", fmus[i].term2(fmus[i].c));
                    fmus[i].free2(fmus[i].c);
                } else {
                    check("fmi3Terminate", fmus[i].term3(fmus[i].c));
                    fmus[i].free3(fmus[i].c);
                }
            }
            fflush(stdout);
            return 0;
        }
        printf("SCRIPT cannot read: %s", line);
        return 1;
    }
    printf("SCRIPT has no run command\n");
    return 1;
}
