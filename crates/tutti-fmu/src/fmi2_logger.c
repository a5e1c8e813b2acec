/*
 * The FMI 2.0 logger callback is variadic (printf-style), which stable Rust cannot define:
 * this shim formats the message and hands it to tutti_fmu_fmi2_log (src/fmi2.rs), which
 * accepts NULL strings (PythonFMU passes a NULL category for Python exceptions).
 */
#include <stdarg.h>
#include <stdio.h>

extern void tutti_fmu_fmi2_log(void *env, const char *instance, unsigned int status, const char *category,
                               const char *message);

void tutti_fmu_fmi2_logger(void *env, const char *instance, unsigned int status, const char *category,
                           const char *message, ...)
{
    char text[4096];
    text[0] = '\0';
    if (message) {
        va_list args;
        va_start(args, message);
        vsnprintf(text, sizeof text, message, args);
        va_end(args);
    }
    tutti_fmu_fmi2_log(env, instance, status, category, text);
}
