/* The master's C-variadic FMI 2.0 logger: formats an FMU's printf-style message and hands it to Rust. */
#include "fmi2.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

/* Defined in Rust (src/fmu/log.rs): records one formatted message; never unwinds. */
void dvpp_cosim_log_sink(void *env, const char *instance, int status, const char *category, const char *formatted);

void dvpp_cosim_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                       fmi2String message, ...);

/* Checked by the compiler: the logger has exactly the type fmi2CallbackFunctions expects. */
const fmi2CallbackLogger dvpp_cosim_logger_type_check = dvpp_cosim_logger;

/* The header has the layout of the Rust definitions (the fmi2 crate asserts the same sizes). */
_Static_assert(sizeof(fmi2CallbackFunctions) == 5 * sizeof(void *), "fmi2CallbackFunctions: five pointers");
_Static_assert(sizeof(fmi2Status) == sizeof(int), "fmi2Status: a C int");
_Static_assert(sizeof(fmi2ValueReference) == 4, "fmi2ValueReference: 32 bits");

void dvpp_cosim_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                       fmi2String message, ...) {
    va_list args, again;
    char *text;
    int length;
    if (message == NULL) {
        dvpp_cosim_log_sink(env, instance, (int)status, category, NULL);
        return;
    }
    va_start(args, message);
    va_copy(again, args);
    /* First pass measures, second writes into a buffer of exactly that size: no truncation. */
    length = vsnprintf(NULL, 0, message, args);
    va_end(args);
    text = length >= 0 ? (char *)malloc((size_t)length + 1) : NULL;
    if (text != NULL && vsnprintf(text, (size_t)length + 1, message, again) == length) {
        dvpp_cosim_log_sink(env, instance, (int)status, category, text);
    } else {
        /* Unformattable (encoding error) or out of memory: pass the format itself rather than nothing. */
        dvpp_cosim_log_sink(env, instance, (int)status, category, message);
    }
    va_end(again);
    free(text);
}
