/*
 * realcode_host.c -- a minimal import host for IEEE/Cigre real-code DLLs (CIGRE TB958, API V2),
 * built for linux64 (dlopen) and win64 (LoadLibrary, run under wine) by tests/tests/win64.rs.
 *
 * usage: realcode_host DLL SCRIPT...
 *
 * Each SCRIPT is one instance of the DLL, all alive in this one process and stepped in turn:
 *   param NAME HEX     a parameter (HEX: the 16 hex digits of the double's bits)
 *   input NAME ...     the inputs the init and step lines give, in order
 *   output NAME ...    the outputs printed after each call, in order
 *   init T HEX...      the inputs at time T, then Model_CheckParameters and Model_Initialize
 *   step T HEX...      the inputs at time T, then Model_Outputs
 * It prints, per instance and call, "I K HEX..." (instance I, call K, the outputs' bits); then
 * for each instance the run of its second half again from a snapshot of its state arrays taken
 * at the middle, "snapshot I ok" if every output repeats bit for bit; then "done".
 */
#include "IEEE_Cigre_DLLInterface.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define LOAD(path) ((void *)LoadLibraryA(path))
#define SYMBOL(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#else
#include <dlfcn.h>
#define LOAD(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define SYMBOL(lib, name) dlsym(lib, name)
#endif

typedef const IEEE_Cigre_DLLInterface_Model_Info *(*GetInfoFn)(void);
typedef int32_T (*CallFn)(IEEE_Cigre_DLLInterface_Instance *);

#define MAX_PORTS 256
#define MAX_CALLS 4096

static const IEEE_Cigre_DLLInterface_Model_Info *info;
static CallFn first_call, check, initialize, outputs, terminate_fn;

/* Byte offsets of a struct of the described scalars, each at its natural alignment. */
static size_t scalar_size(int t) {
    switch (t) {
    case IEEE_Cigre_DLLInterface_DataType_real64_T: return 8;
    case IEEE_Cigre_DLLInterface_DataType_int32_T:
    case IEEE_Cigre_DLLInterface_DataType_uint32_T:
    case IEEE_Cigre_DLLInterface_DataType_real32_T: return 4;
    case IEEE_Cigre_DLLInterface_DataType_int16_T:
    case IEEE_Cigre_DLLInterface_DataType_uint16_T: return 2;
    default: return 1;
    }
}

static size_t layout(int n, const int *types, size_t *offsets) {
    size_t at = 0, align = 1;
    for (int k = 0; k < n; k++) {
        size_t s = scalar_size(types[k]);
        at = (at + s - 1) / s * s;
        offsets[k] = at;
        at += s;
        if (s > align) align = s;
    }
    return (at + align - 1) / align * align;
}

typedef struct {
    IEEE_Cigre_DLLInterface_Instance inst;
    size_t in_off[MAX_PORTS], out_off[MAX_PORTS], par_off[MAX_PORTS];
    int in_type[MAX_PORTS], out_type[MAX_PORTS], par_type[MAX_PORTS];
    int n_in, n_out; /* the script's inputs and outputs */
    int in_index[MAX_PORTS], out_index[MAX_PORTS];
    char *script;
    int calls;
    double *times;
    double *inputs;   /* calls x n_in */
    uint64_t *outs;   /* calls x n_out */
} Host;

static int find(const IEEE_Cigre_DLLInterface_Signal *s, int n, const char *name) {
    for (int k = 0; k < n; k++)
        if (strcmp(s[k].Name, name) == 0) return k;
    return -1;
}

static double from_hex(const char *h) {
    uint64_t bits = strtoull(h, NULL, 16);
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

static void put(void *base, size_t off, int type, double x) {
    char *p = (char *)base + off;
    if (type == IEEE_Cigre_DLLInterface_DataType_real64_T) {
        memcpy(p, &x, 8);
    } else {
        int32_T k = (int32_T)x;
        memcpy(p, &k, 4);
    }
}

static uint64_t get_bits(void *base, size_t off, int type) {
    char *p = (char *)base + off;
    double x;
    if (type == IEEE_Cigre_DLLInterface_DataType_real64_T) {
        memcpy(&x, p, 8);
    } else {
        int32_T k;
        memcpy(&k, p, 4);
        x = (double)k;
    }
    uint64_t bits;
    memcpy(&bits, &x, 8);
    return bits;
}

static void fail(const char *what, const Host *h) {
    fprintf(stderr, "%s: %s\n", what,
            h && h->inst.LastErrorMessage ? h->inst.LastErrorMessage : "(no message)");
    exit(1);
}

/* Read a script: the parameters into the host's struct, the inputs of every call. */
static void load(Host *h, const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) fail(path, NULL);
    memset(h, 0, sizeof *h);
    int types[MAX_PORTS];
    for (int k = 0; k < info->NumInputPorts; k++) types[k] = info->InputPortsInfo[k].DataType;
    size_t in_size = layout(info->NumInputPorts, types, h->in_off);
    memcpy(h->in_type, types, sizeof types);
    for (int k = 0; k < info->NumOutputPorts; k++) types[k] = info->OutputPortsInfo[k].DataType;
    size_t out_size = layout(info->NumOutputPorts, types, h->out_off);
    memcpy(h->out_type, types, sizeof types);
    for (int k = 0; k < info->NumParameters; k++) types[k] = info->ParametersInfo[k].DataType;
    size_t par_size = layout(info->NumParameters, types, h->par_off);
    memcpy(h->par_type, types, sizeof types);
    h->inst.ExternalInputs = calloc(1, in_size + 8);
    h->inst.ExternalOutputs = calloc(1, out_size + 8);
    h->inst.Parameters = calloc(1, par_size + 8);
    h->inst.IntStates = calloc((size_t)info->NumIntStates + 1, sizeof(int32_T));
    h->inst.FloatStates = calloc((size_t)info->NumFloatStates + 1, sizeof(real32_T));
    h->inst.DoubleStates = calloc((size_t)info->NumDoubleStates + 1, sizeof(real64_T));
    /* Parameters start at their defaults. */
    for (int k = 0; k < info->NumParameters; k++) {
        const IEEE_Cigre_DLLInterface_Parameter *p = &info->ParametersInfo[k];
        double x = p->DataType == IEEE_Cigre_DLLInterface_DataType_real64_T
                       ? p->DefaultValue.Real64_Val
                       : (double)p->DefaultValue.Int32_Val;
        put(h->inst.Parameters, h->par_off[k], p->DataType, x);
    }
    h->times = malloc(sizeof(double) * MAX_CALLS);
    h->inputs = malloc(sizeof(double) * MAX_CALLS * MAX_PORTS);
    h->outs = malloc(sizeof(uint64_t) * MAX_CALLS * MAX_PORTS);
    char line[65536];
    while (fgets(line, sizeof line, f)) {
        char *tok = strtok(line, " \n");
        if (!tok) continue;
        if (strcmp(tok, "param") == 0) {
            char *name = strtok(NULL, " \n"), *hex = strtok(NULL, " \n");
            int k = -1;
            for (int j = 0; j < info->NumParameters; j++)
                if (strcmp(info->ParametersInfo[j].Name, name) == 0) k = j;
            if (k < 0) { fprintf(stderr, "no parameter %s\n", name); exit(1); }
            put(h->inst.Parameters, h->par_off[k], h->par_type[k], from_hex(hex));
        } else if (strcmp(tok, "input") == 0 || strcmp(tok, "output") == 0) {
            int out = tok[0] == 'o';
            for (char *n = strtok(NULL, " \n"); n; n = strtok(NULL, " \n")) {
                int k = out ? find(info->OutputPortsInfo, info->NumOutputPorts, n)
                            : find(info->InputPortsInfo, info->NumInputPorts, n);
                if (k < 0) { fprintf(stderr, "no port %s\n", n); exit(1); }
                if (out) h->out_index[h->n_out++] = k; else h->in_index[h->n_in++] = k;
            }
        } else if (strcmp(tok, "init") == 0 || strcmp(tok, "step") == 0) {
            if (h->calls >= MAX_CALLS) { fprintf(stderr, "too many calls\n"); exit(1); }
            h->times[h->calls] = atof(strtok(NULL, " \n"));
            for (int j = 0; j < h->n_in; j++)
                h->inputs[h->calls * MAX_PORTS + j] = from_hex(strtok(NULL, " \n"));
            h->calls++;
        }
    }
    fclose(f);
}

static void call(Host *h, int k) {
    for (int j = 0; j < h->n_in; j++) {
        int port = h->in_index[j];
        put(h->inst.ExternalInputs, h->in_off[port], h->in_type[port],
            h->inputs[k * MAX_PORTS + j]);
    }
    h->inst.Time = h->times[k];
    if (k == 0) {
        if (check(&h->inst) == 2) fail("Model_CheckParameters", h);
        if (initialize(&h->inst) == 2) fail("Model_Initialize", h);
    } else if (outputs(&h->inst) == 2) {
        fail("Model_Outputs", h);
    }
    for (int j = 0; j < h->n_out; j++) {
        int port = h->out_index[j];
        h->outs[k * MAX_PORTS + j] = get_bits(h->inst.ExternalOutputs, h->out_off[port], h->out_type[port]);
    }
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: realcode_host DLL SCRIPT...\n");
        return 2;
    }
    void *lib = LOAD(argv[1]);
    if (!lib) { fprintf(stderr, "cannot load %s\n", argv[1]); return 1; }
    GetInfoFn get_info = (GetInfoFn)SYMBOL(lib, "Model_GetInfo");
    first_call = (CallFn)SYMBOL(lib, "Model_FirstCall");
    check = (CallFn)SYMBOL(lib, "Model_CheckParameters");
    initialize = (CallFn)SYMBOL(lib, "Model_Initialize");
    outputs = (CallFn)SYMBOL(lib, "Model_Outputs");
    terminate_fn = (CallFn)SYMBOL(lib, "Model_Terminate");
    if (!get_info || !first_call || !check || !initialize || !outputs || !terminate_fn ||
        !SYMBOL(lib, "Model_Iterate") || !SYMBOL(lib, "Model_PrintInfo")) {
        fprintf(stderr, "%s: a function of the interface is missing\n", argv[1]);
        return 1;
    }
    info = get_info();
    if (!info || info->NumInputPorts > MAX_PORTS || info->NumOutputPorts > MAX_PORTS ||
        info->NumParameters > MAX_PORTS) {
        fprintf(stderr, "%s: no usable model info\n", argv[1]);
        return 1;
    }
    int n = argc - 2;
    Host *hosts = calloc((size_t)n, sizeof(Host));
    int calls = 0;
    for (int i = 0; i < n; i++) {
        load(&hosts[i], argv[i + 2]);
        if (first_call(&hosts[i].inst) == 2) fail("Model_FirstCall", &hosts[i]);
        if (hosts[i].calls > calls) calls = hosts[i].calls;
    }
    /* Every instance stepped in turn; the middle's state arrays kept. */
    int32_T **snapshots = calloc((size_t)n, sizeof(int32_T *));
    for (int k = 0; k < calls; k++) {
        for (int i = 0; i < n; i++) {
            Host *h = &hosts[i];
            if (k >= h->calls) continue;
            if (k == h->calls / 2) {
                size_t bytes = sizeof(int32_T) * (size_t)info->NumIntStates;
                snapshots[i] = malloc(bytes);
                memcpy(snapshots[i], h->inst.IntStates, bytes);
            }
            call(h, k);
            printf("%d %d", i, k);
            for (int j = 0; j < h->n_out; j++) printf(" %016" PRIx64, h->outs[k * MAX_PORTS + j]);
            printf("\n");
        }
    }
    /* The second halves again from the snapshots. */
    for (int i = 0; i < n; i++) {
        Host *h = &hosts[i];
        memcpy(h->inst.IntStates, snapshots[i], sizeof(int32_T) * (size_t)info->NumIntStates);
        int same = 1;
        uint64_t *first = malloc(sizeof(uint64_t) * MAX_CALLS * MAX_PORTS);
        memcpy(first, h->outs, sizeof(uint64_t) * MAX_CALLS * MAX_PORTS);
        for (int k = h->calls / 2; k < h->calls; k++) {
            call(h, k);
            for (int j = 0; j < h->n_out; j++)
                same &= h->outs[k * MAX_PORTS + j] == first[k * MAX_PORTS + j];
        }
        printf("snapshot %d %s\n", i, same ? "ok" : "differs");
        free(first);
        terminate_fn(&h->inst);
    }
    printf("done\n");
    return 0;
}
