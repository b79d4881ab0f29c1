/* A minimal FMI 2.0 Co-Simulation master for comparing an FMU's win64 and linux64 binaries: the same source is
 * built for Windows (LoadLibrary, run under wine) and for Linux (dlopen). Plain C, no dependencies. Two modes:
 *
 * usage: master LIBRARY GUID RESOURCE_URI STEP_SIZE STEPS INPUTS OUTPUTS
 *   steps one FMU binary with varied inputs and prints every output after every step as the bit pattern of its
 *   double, so the two runs compare exactly.
 *   INPUTS   comma-separated vr:lo:hi; input j follows a triangle wave between lo and hi (period 200 + 37 j steps,
 *            shifted by 13 j steps), computed with + - * / only so both platforms feed the same bits ("-" for none)
 *   OUTPUTS  comma-separated value references of the Real outputs to print
 *   Output: one line per step, the outputs as 16 hex digits each, separated by spaces; "done" at the end.
 *
 * usage: master replay LIBRARY GUID RESOURCE_URI TRACE OUTPUTS
 *   makes the calls of TRACE (a file `cosim --trace DIR` wrote for one unit, format in cosim/src/fmu/trace.rs) in
 *   order against one instance of LIBRARY, instantiated with GUID (which must be the one the trace recorded) and
 *   RESOURCE_URI (the resources unpacked on this machine).
 *   OUTPUTS  comma-separated outputs ("-" for none): a value reference of a Real, or i:VR of an Integer, b:VR of a
 *            Boolean; each must be among the references the trace's reads (get_real, ...) read
 *   Output: at every "sample T" of the trace (where the master recorded a communication point with the outputs as it
 *   read them last), one line: T, then OUTPUTS as read last, each as the 16 hex digits of the double the master
 *   records (an Integer converted exactly, a Boolean 0 or 1); "done" at the end.
 *
 * Exit status 0 when every call returned fmi2OK or fmi2Warning; otherwise a one-line reason on stderr and 1 (a
 * trace that cannot be read: its path, the line number and why). */
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
typedef fmi2Status (*IntegersFn)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[]);
typedef fmi2Status (*SetIntegersFn)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[]);
typedef fmi2Status (*StringsFn)(fmi2Component, const fmi2ValueReference[], size_t, fmi2String[]);
typedef fmi2Status (*SetStringsFn)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2String[]);
typedef fmi2Status (*GetStateFn)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*SetStateFn)(fmi2Component, fmi2FMUstate);

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

/* The address of `name` in `lib` (the run stops when it is missing). */
static void *lookup(Library lib, const char *name) {
    void *found = symbol(lib, name);
    if (found == NULL) {
        fprintf(stderr, "master: the library does not export %s\n", name);
        exit(1);
    }
    return found;
}

#define LOOKUP(var, name)                                                                                             \
    do {                                                                                                              \
        void *found = lookup(lib, name);                                                                              \
        memcpy(&var, &found, sizeof var);                                                                             \
    } while (0)

static int replay(int argc, char **argv);

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

    if (argc >= 2 && strcmp(argv[1], "replay") == 0)
        return replay(argc, argv);
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

/* ---- replay of a trace ---------------------------------------------------------------------------------------- */

/* Where the trace is being read, for messages. */
static const char *trace_path;
static unsigned long trace_line;

/* Stop on a trace that cannot be replayed, naming the file and line. */
static void bad_trace(const char *why, const char *word) {
    fprintf(stderr, "master: %s:%lu: %s%s%s%s\n", trace_path, trace_line, why, word ? " (\"" : "", word ? word : "",
            word ? "\")" : "");
    exit(1);
}

/* One line of `f` into `*buf` (grown as needed, the newline and a carriage return removed); 0 at the end. */
static int read_line(FILE *f, char **buf, size_t *cap) {
    size_t len = 0;
    for (;;) {
        if (*cap - len < 2) {
            size_t grown = *cap ? 2 * *cap : 4096;
            char *p = realloc(*buf, grown);
            if (p == NULL)
                fail("out of memory");
            *buf = p;
            *cap = grown;
        }
        if (fgets(*buf + len, (int)(*cap - len > 1u << 30 ? 1u << 30 : *cap - len), f) == NULL) {
            if (ferror(f))
                bad_trace("read error", NULL);
            if (len == 0)
                return 0;
            break;
        }
        len += strlen(*buf + len);
        if (len > 0 && (*buf)[len - 1] == '\n')
            break;
    }
    while (len > 0 && ((*buf)[len - 1] == '\n' || (*buf)[len - 1] == '\r'))
        (*buf)[--len] = '\0';
    return 1;
}

/* The next space-separated word of `*cursor` (NULL at the end of the line). */
static char *next_word(char **cursor) {
    char *start = *cursor, *end;
    while (*start == ' ')
        start++;
    if (*start == '\0')
        return NULL;
    end = start;
    while (*end != ' ' && *end != '\0')
        end++;
    if (*end == ' ')
        *end++ = '\0';
    *cursor = end;
    return start;
}

/* The next word, which the call needs (`what` names it in the message). */
static char *need_word(char **cursor, const char *what) {
    char *w = next_word(cursor);
    if (w == NULL)
        bad_trace(what, NULL);
    return w;
}

static int hex_digit(char c) {
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/* A real given as the 16 hex digits of its bits. */
static double parse_real(char **cursor, const char *what) {
    char *w = need_word(cursor, what);
    unsigned long long bits = 0;
    double value;
    int k;
    for (k = 0; k < 16; k++) {
        int d = hex_digit(w[k]);
        if (d < 0)
            bad_trace("a real must be 16 hex digits", w);
        bits = bits << 4 | (unsigned long long)d;
    }
    if (w[16] != '\0')
        bad_trace("a real must be 16 hex digits", w);
    memcpy(&value, &bits, sizeof value);
    return value;
}

/* A whole number within [lo, hi]. */
static long long parse_int(char **cursor, const char *what, long long lo, long long hi) {
    char *w = need_word(cursor, what), *end;
    long long v = strtoll(w, &end, 10);
    if (*end != '\0' || end == w || v < lo || v > hi)
        bad_trace("not a whole number in range", w);
    return v;
}

/* Decode a percent-encoded word in place ("-" is the empty string). */
static char *decode_word(char *w) {
    char *in = w, *out = w;
    if (strcmp(w, "-") == 0) {
        *w = '\0';
        return w;
    }
    while (*in) {
        if (*in == '%') {
            int hi = hex_digit(in[1]), lo = hi < 0 ? -1 : hex_digit(in[2]);
            if (hi < 0 || lo < 0)
                bad_trace("% must be followed by two hex digits", w);
            *out++ = (char)(hi * 16 + lo);
            in += 3;
        } else {
            *out++ = *in++;
        }
    }
    *out = '\0';
    return w;
}

/* Grow-as-needed arrays for the arguments of one call. */
typedef struct {
    fmi2ValueReference *vr;
    fmi2Real *real;
    fmi2Integer *integer;
    fmi2String *string;
    size_t cap;
} Args;

static void reserve(Args *a, size_t n) {
    size_t cap = a->cap ? a->cap : 64;
    if (n <= a->cap)
        return;
    while (cap < n)
        cap *= 2;
    a->vr = realloc(a->vr, cap * sizeof *a->vr);
    a->real = realloc(a->real, cap * sizeof *a->real);
    a->integer = realloc(a->integer, cap * sizeof *a->integer);
    a->string = realloc(a->string, cap * sizeof *a->string);
    if (!a->vr || !a->real || !a->integer || !a->string)
        fail("out of memory");
    a->cap = cap;
}

/* The count N of a set_ or get_ call, with room for it. */
static size_t parse_count(char **cursor, Args *a) {
    size_t n = (size_t)parse_int(cursor, "no count of value references", 0, 1000000);
    reserve(a, n + 1);
    return n;
}

static int replay(int argc, char **argv) {
    Library lib;
    InstantiateFn instantiate;
    SetupExperimentFn setup_experiment;
    ComponentFn enter_init, exit_init, terminate, reset;
    SetRealsFn set_real;
    RealsFn get_real;
    SetIntegersFn set_integer, set_boolean;
    IntegersFn get_integer, get_boolean;
    SetStringsFn set_string;
    StringsFn get_string;
    DoStepFn do_step;
    GetStateFn get_state, free_state;
    SetStateFn set_state;
    FreeInstanceFn free_instance;
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = NULL;
    fmi2FMUstate state = NULL;
    fmi2ValueReference *out_vr;
    size_t n_out, j, k, n, *out_at;
    char *out_type;  /* 'r', 'i' or 'b' */
    double *out_value;
    int *out_seen;
    const char *guid, *resources;
    char *cursor, *end, *line = NULL, *word;
    size_t cap = 0;
    Args a = {NULL, NULL, NULL, NULL, 0};
    FILE *f;
    static char stdout_buffer[1 << 16];

    if (argc != 7)
        fail("usage: master replay LIBRARY GUID RESOURCE_URI TRACE OUTPUTS");
    guid = argv[3];
    resources = argv[4];
    trace_path = argv[5];
    n_out = count_fields(argv[6]);
    out_vr = calloc(n_out + 1, sizeof *out_vr);
    out_at = calloc(n_out + 1, sizeof *out_at);
    out_type = calloc(n_out + 1, sizeof *out_type);
    out_value = calloc(n_out + 1, sizeof *out_value);
    out_seen = calloc(n_out + 1, sizeof *out_seen);
    if (!out_vr || !out_at || !out_type || !out_value || !out_seen)
        fail("out of memory");
    cursor = argv[6];
    for (j = 0; j < n_out; j++) {
        out_type[j] = 'r';
        if ((cursor[0] == 'i' || cursor[0] == 'b') && cursor[1] == ':') {
            out_type[j] = cursor[0];
            cursor += 2;
        }
        out_vr[j] = (fmi2ValueReference)strtoul(cursor, &end, 10);
        if (end == cursor || (*end != ',' && *end != '\0'))
            fail("OUTPUTS must be VR, i:VR or b:VR, comma-separated, or -");
        cursor = end + 1;
    }
    setvbuf(stdout, stdout_buffer, _IOFBF, sizeof stdout_buffer);
    f = fopen(trace_path, "rb");
    if (f == NULL) {
        fprintf(stderr, "master: cannot open %s\n", trace_path);
        return 1;
    }

    lib = open_library(argv[2]);
    if (lib == NULL) {
        print_load_error(argv[2]);
        return 1;
    }
    LOOKUP(instantiate, "fmi2Instantiate");
    LOOKUP(setup_experiment, "fmi2SetupExperiment");
    LOOKUP(enter_init, "fmi2EnterInitializationMode");
    LOOKUP(exit_init, "fmi2ExitInitializationMode");
    LOOKUP(terminate, "fmi2Terminate");
    LOOKUP(reset, "fmi2Reset");
    LOOKUP(set_real, "fmi2SetReal");
    LOOKUP(get_real, "fmi2GetReal");
    LOOKUP(set_integer, "fmi2SetInteger");
    LOOKUP(get_integer, "fmi2GetInteger");
    LOOKUP(set_boolean, "fmi2SetBoolean");
    LOOKUP(get_boolean, "fmi2GetBoolean");
    LOOKUP(set_string, "fmi2SetString");
    LOOKUP(get_string, "fmi2GetString");
    LOOKUP(do_step, "fmi2DoStep");
    LOOKUP(get_state, "fmi2GetFMUstate");
    LOOKUP(set_state, "fmi2SetFMUstate");
    LOOKUP(free_state, "fmi2FreeFMUstate");
    LOOKUP(free_instance, "fmi2FreeInstance");

    trace_line = 1;
    if (!read_line(f, &line, &cap) || strcmp(line, "fmi2-trace 1") != 0)
        bad_trace("not a trace: the first line must be \"fmi2-trace 1\"", line);
    while (read_line(f, &line, &cap)) {
        const char *call;
        trace_line++;
        if (line[0] == '#' || line[0] == '\0')
            continue;
        cursor = line;
        call = next_word(&cursor);
        if (call == NULL)
            continue;
        if (strcmp(call, "unit") == 0 || strcmp(call, "source") == 0 || strcmp(call, "model") == 0) {
            need_word(&cursor, "no value");
        } else if (strcmp(call, "guid") == 0 || strcmp(call, "instantiate") == 0) {
            const char *name = NULL;
            fmi2Type type = fmi2CoSimulation;
            if (call[0] == 'i') {
                if (c != NULL)
                    bad_trace("a second instantiate", NULL);
                name = decode_word(need_word(&cursor, "no instance name"));
                type = (fmi2Type)parse_int(&cursor, "no fmuType", 0, 1);
            }
            word = decode_word(need_word(&cursor, "no GUID"));
            if (strcmp(word, guid) != 0) {
                fprintf(stderr, "master: %s:%lu: the trace was recorded with GUID %s, the FMU given has %s\n",
                        trace_path, trace_line, word, guid);
                return 1;
            }
            if (call[0] == 'i') {
                /* The recorded resource URI is the master's machine's: this machine's is RESOURCE_URI. */
                need_word(&cursor, "no resource URI");
                c = instantiate(name, type, guid, resources, &callbacks, fmi2False, fmi2False);
                if (c == NULL)
                    fail("fmi2Instantiate returned NULL");
            }
        } else if (c == NULL) {
            bad_trace("a call before instantiate", call);
        } else if (strcmp(call, "setup_experiment") == 0) {
            fmi2Boolean tol_defined = (fmi2Boolean)parse_int(&cursor, "no toleranceDefined", 0, 1);
            double tol = parse_real(&cursor, "no tolerance");
            double start = parse_real(&cursor, "no start time");
            fmi2Boolean stop_defined = (fmi2Boolean)parse_int(&cursor, "no stopTimeDefined", 0, 1);
            double stop = parse_real(&cursor, "no stop time");
            check(setup_experiment(c, tol_defined, tol, start, stop_defined, stop), "fmi2SetupExperiment");
        } else if (strcmp(call, "set_real") == 0) {
            n = parse_count(&cursor, &a);
            for (k = 0; k < n; k++) {
                a.vr[k] = (fmi2ValueReference)parse_int(&cursor, "no value reference", 0, 0xffffffffLL);
                a.real[k] = parse_real(&cursor, "no value");
            }
            check(set_real(c, a.vr, n, a.real), "fmi2SetReal");
        } else if (strcmp(call, "set_integer") == 0 || strcmp(call, "set_boolean") == 0) {
            int boolean = call[4] == 'b';
            n = parse_count(&cursor, &a);
            for (k = 0; k < n; k++) {
                a.vr[k] = (fmi2ValueReference)parse_int(&cursor, "no value reference", 0, 0xffffffffLL);
                a.integer[k] = (fmi2Integer)parse_int(&cursor, "no value", boolean ? 0 : -2147483647LL - 1,
                                                      boolean ? 1 : 2147483647LL);
            }
            check((boolean ? set_boolean : set_integer)(c, a.vr, n, a.integer),
                  boolean ? "fmi2SetBoolean" : "fmi2SetInteger");
        } else if (strcmp(call, "set_string") == 0) {
            n = parse_count(&cursor, &a);
            for (k = 0; k < n; k++) {
                a.vr[k] = (fmi2ValueReference)parse_int(&cursor, "no value reference", 0, 0xffffffffLL);
                a.string[k] = decode_word(need_word(&cursor, "no value"));
            }
            check(set_string(c, a.vr, n, a.string), "fmi2SetString");
        } else if (strcmp(call, "get_real") == 0 || strcmp(call, "get_integer") == 0 ||
                   strcmp(call, "get_boolean") == 0 || strcmp(call, "get_string") == 0) {
            n = parse_count(&cursor, &a);
            for (k = 0; k < n; k++)
                a.vr[k] = (fmi2ValueReference)parse_int(&cursor, "no value reference", 0, 0xffffffffLL);
            if (call[4] == 'r')
                check(get_real(c, a.vr, n, a.real), "fmi2GetReal");
            else if (call[4] == 'i')
                check(get_integer(c, a.vr, n, a.integer), "fmi2GetInteger");
            else if (call[4] == 'b')
                check(get_boolean(c, a.vr, n, a.integer), "fmi2GetBoolean");
            else
                check(get_string(c, a.vr, n, a.string), "fmi2GetString");
            /* The outputs of this type among the references read (the master reads the same ones each time, so the
             * place found last is tried first). */
            for (j = 0; j < n_out; j++) {
                if (out_type[j] != call[4])
                    continue;
                if (!(out_at[j] < n && a.vr[out_at[j]] == out_vr[j])) {
                    for (k = 0; k < n && a.vr[k] != out_vr[j]; k++)
                        ;
                    if (k == n)
                        continue;
                    out_at[j] = k;
                }
                out_value[j] = call[4] == 'r' ? a.real[out_at[j]]
                               : call[4] == 'i' ? (double)a.integer[out_at[j]]
                                                : (a.integer[out_at[j]] != fmi2False ? 1.0 : 0.0);
                out_seen[j] = 1;
            }
        } else if (strcmp(call, "do_step") == 0) {
            double t = parse_real(&cursor, "no communication point");
            double h = parse_real(&cursor, "no step size");
            fmi2Boolean no_set = (fmi2Boolean)parse_int(&cursor, "no noSetFMUStatePriorToCurrentPoint", 0, 1);
            check(do_step(c, t, h, no_set), "fmi2DoStep");
        } else if (strcmp(call, "sample") == 0) {
            double t = parse_real(&cursor, "no time");
            for (j = 0; j < n_out; j++) {
                if (!out_seen[j]) {
                    fprintf(stderr, "master: %s:%lu: output %s%u was not read before this sample\n", trace_path,
                            trace_line, out_type[j] == 'r' ? "" : out_type[j] == 'i' ? "i:" : "b:",
                            (unsigned)out_vr[j]);
                    return 1;
                }
            }
            print_bits(t, 1);
            for (j = 0; j < n_out; j++)
                print_bits(out_value[j], 0);
            putchar('\n');
        } else if (strcmp(call, "enter_initialization_mode") == 0) {
            check(enter_init(c), "fmi2EnterInitializationMode");
        } else if (strcmp(call, "exit_initialization_mode") == 0) {
            check(exit_init(c), "fmi2ExitInitializationMode");
        } else if (strcmp(call, "terminate") == 0) {
            check(terminate(c), "fmi2Terminate");
        } else if (strcmp(call, "reset") == 0) {
            check(reset(c), "fmi2Reset");
        } else if (strcmp(call, "get_fmu_state") == 0) {
            check(get_state(c, &state), "fmi2GetFMUstate");
        } else if (strcmp(call, "set_fmu_state") == 0) {
            if (state == NULL)
                bad_trace("set_fmu_state before get_fmu_state", NULL);
            check(set_state(c, state), "fmi2SetFMUstate");
        } else if (strcmp(call, "free_fmu_state") == 0) {
            check(free_state(c, &state), "fmi2FreeFMUstate");
            state = NULL;
        } else if (strcmp(call, "unsupported") == 0) {
            bad_trace("the master made a call a trace cannot replay", next_word(&cursor));
        } else {
            bad_trace("unknown call", call);
        }
        if (next_word(&cursor) != NULL)
            bad_trace("words after the call's arguments", call);
    }
    fclose(f);
    if (c == NULL)
        bad_trace("no instantiate in the trace", NULL);
    if (state != NULL)
        check(free_state(c, &state), "fmi2FreeFMUstate");
    free_instance(c);
    close_library(lib);
    printf("done\n");
    fflush(stdout);
    free(line);
    free(a.vr);
    free(a.real);
    free(a.integer);
    free(a.string);
    free(out_vr);
    free(out_at);
    free(out_type);
    free(out_value);
    free(out_seen);
    return 0;
}
