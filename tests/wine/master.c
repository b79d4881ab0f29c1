/* A minimal FMI 2.0 Co-Simulation master for comparing an FMU's win64 and linux64 binaries: the same source is
 * built for Windows (LoadLibrary, run under wine) and for Linux (dlopen); it steps one FMU binary with varied inputs
 * and prints every output after every step as the bit pattern of its double, so the two runs compare exactly.
 *
 * usage: master LIBRARY GUID RESOURCE_URI STEP_SIZE STEPS INPUTS OUTPUTS
 *   INPUTS   comma-separated vr:lo:hi; input j follows a triangle wave between lo and hi (period 200 + 37 j steps,
 *            shifted by 13 j steps), computed with + - * / only so both platforms feed the same bits ("-" for none)
 *   OUTPUTS  comma-separated value references of the Real outputs to print
 * Output: one line per step, the outputs as 16 hex digits each, separated by spaces; "done" at the end.
 * Exit status 0 when every call returned fmi2OK or fmi2Warning; otherwise a one-line reason on stderr and 1. */
#ifndef _WIN32
#define _POSIX_C_SOURCE 200809L
#endif

#include "fmi2.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
typedef HMODULE Library;
static Library open_library(const char *path) { return LoadLibraryA(path); }
static void *symbol(Library lib, const char *name) { return (void *)GetProcAddress(lib, name); }
static void close_library(Library lib) { FreeLibrary(lib); }
static void print_load_error(const char *path) {
    fprintf(stderr, "master: LoadLibrary(%s) failed with error %lu\n", path, (unsigned long)GetLastError());
}
#else
#include <dlfcn.h>
typedef void *Library;
static Library open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(Library lib, const char *name) { return dlsym(lib, name); }
static void close_library(Library lib) { dlclose(lib); }
static void print_load_error(const char *path) { fprintf(stderr, "master: dlopen(%s): %s\n", path, dlerror()); }
#endif

typedef fmi2Component (*InstantiateFn)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                       fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*SetupExperimentFn)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
typedef fmi2Status (*ComponentFn)(fmi2Component);
typedef fmi2Status (*RealsFn)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
typedef fmi2Status (*SetRealsFn)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
typedef fmi2Status (*DoStepFn)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
typedef void (*FreeInstanceFn)(fmi2Component);

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list args;
    (void)env;
    fprintf(stderr, "[%s] status %d, %s: ", instance ? instance : "?", (int)status, category ? category : "?");
    if (message != NULL) {
        va_start(args, message);
        vfprintf(stderr, message, args);
        va_end(args);
    }
    fputc('\n', stderr);
}

static void fail(const char *what) {
    fprintf(stderr, "master: %s\n", what);
    exit(1);
}

/* fmi2OK and fmi2Warning go on (a warning is logged through the logger); anything else stops the run. */
static void check(fmi2Status status, const char *call) {
    if (status != fmi2OK && status != fmi2Warning) {
        fprintf(stderr, "master: %s returned status %d\n", call, (int)status);
        exit(1);
    }
}

/* The number of comma-separated fields of `list` ("-" is none). */
static size_t count_fields(const char *list) {
    size_t n = 1;
    if (strcmp(list, "-") == 0 || *list == '\0')
        return 0;
    for (; *list; list++)
        n += *list == ',';
    return n;
}

/* Input j at step k: a triangle wave between lo and hi. */
static double input_at(size_t j, size_t k, double lo, double hi) {
    size_t period = 200 + 37 * j;
    size_t position = (k + 13 * j) % period;
    double x = (double)position / (double)period;
    double wave = x < 0.5 ? 2.0 * x : 2.0 - 2.0 * x;
    return lo + (hi - lo) * wave;
}

static void print_bits(double value, int first) {
    unsigned long long bits;
    memcpy(&bits, &value, sizeof bits);
    printf("%s%08x%08x", first ? "" : " ", (unsigned)(bits >> 32), (unsigned)(bits & 0xffffffffu));
}

int main(int argc, char **argv) {
    Library lib;
    InstantiateFn instantiate;
    SetupExperimentFn setup_experiment;
    ComponentFn enter_init, exit_init, terminate;
    SetRealsFn set_real;
    RealsFn get_real;
    DoStepFn do_step;
    FreeInstanceFn free_instance;
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c;
    size_t n_in, n_out, j, k, steps;
    fmi2ValueReference *in_vr, *out_vr;
    double *lo, *hi, *u, *y, h;
    char *cursor, *end;

    if (argc != 8)
        fail("usage: master LIBRARY GUID RESOURCE_URI STEP_SIZE STEPS INPUTS OUTPUTS");
    h = strtod(argv[4], &end);
    if (*end != '\0' || !(h > 0.0))
        fail("STEP_SIZE must be a positive number");
    steps = (size_t)strtoul(argv[5], &end, 10);
    if (*end != '\0')
        fail("STEPS must be a whole number");

    n_in = count_fields(argv[6]);
    n_out = count_fields(argv[7]);
    in_vr = calloc(n_in + 1, sizeof *in_vr);
    lo = calloc(n_in + 1, sizeof *lo);
    hi = calloc(n_in + 1, sizeof *hi);
    u = calloc(n_in + 1, sizeof *u);
    out_vr = calloc(n_out + 1, sizeof *out_vr);
    y = calloc(n_out + 1, sizeof *y);
    if (!in_vr || !lo || !hi || !u || !out_vr || !y)
        fail("out of memory");
    cursor = argv[6];
    for (j = 0; j < n_in; j++) {
        in_vr[j] = (fmi2ValueReference)strtoul(cursor, &end, 10);
        if (*end != ':')
            fail("INPUTS must be vr:lo:hi,...");
        lo[j] = strtod(end + 1, &end);
        if (*end != ':')
            fail("INPUTS must be vr:lo:hi,...");
        hi[j] = strtod(end + 1, &end);
        if (*end != ',' && *end != '\0')
            fail("INPUTS must be vr:lo:hi,...");
        cursor = end + 1;
    }
    cursor = argv[7];
    for (j = 0; j < n_out; j++) {
        out_vr[j] = (fmi2ValueReference)strtoul(cursor, &end, 10);
        if (*end != ',' && *end != '\0')
            fail("OUTPUTS must be vr,vr,...");
        cursor = end + 1;
    }

    lib = open_library(argv[1]);
    if (lib == NULL) {
        print_load_error(argv[1]);
        return 1;
    }
#define LOOKUP(var, name)                                                                           \
    do {                                                                                            \
        void *found = symbol(lib, name);                                                            \
        if (found == NULL)                                                                          \
            fail("the library does not export " name);                                              \
        memcpy(&var, &found, sizeof var);                                                           \
    } while (0)
    LOOKUP(instantiate, "fmi2Instantiate");
    LOOKUP(setup_experiment, "fmi2SetupExperiment");
    LOOKUP(enter_init, "fmi2EnterInitializationMode");
    LOOKUP(exit_init, "fmi2ExitInitializationMode");
    LOOKUP(terminate, "fmi2Terminate");
    LOOKUP(set_real, "fmi2SetReal");
    LOOKUP(get_real, "fmi2GetReal");
    LOOKUP(do_step, "fmi2DoStep");
    LOOKUP(free_instance, "fmi2FreeInstance");

    c = instantiate("master", fmi2CoSimulation, argv[2], argv[3], &callbacks, fmi2False, fmi2False);
    if (c == NULL)
        fail("fmi2Instantiate returned NULL");
    check(setup_experiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment");
    check(enter_init(c), "fmi2EnterInitializationMode");
    for (j = 0; j < n_in; j++)
        u[j] = input_at(j, 0, lo[j], hi[j]);
    if (n_in > 0)
        check(set_real(c, in_vr, n_in, u), "fmi2SetReal");
    check(exit_init(c), "fmi2ExitInitializationMode");
    for (k = 0; k < steps; k++) {
        for (j = 0; j < n_in; j++)
            u[j] = input_at(j, k, lo[j], hi[j]);
        if (n_in > 0)
            check(set_real(c, in_vr, n_in, u), "fmi2SetReal");
        check(do_step(c, (double)k * h, h, fmi2True), "fmi2DoStep");
        if (n_out > 0)
            check(get_real(c, out_vr, n_out, y), "fmi2GetReal");
        for (j = 0; j < n_out; j++)
            print_bits(y[j], j == 0);
        putchar('\n');
    }
    check(terminate(c), "fmi2Terminate");
    free_instance(c);
    close_library(lib);
    printf("done\n");
    free(in_vr);
    free(lo);
    free(hi);
    free(u);
    free(out_vr);
    free(y);
    return 0;
}
