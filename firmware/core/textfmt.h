/* Numbers and strings written the way the protocol's reference (Python) writes them. */
#ifndef IRDAQ_TEXTFMT_H
#define IRDAQ_TEXTFMT_H

#include <stdbool.h>
#include <stddef.h>

/* repr(float): the shortest digits that read back as the same double ("20000.0"). */
void irdaq_format_shortest(char *out, size_t size, double value);
/* format(value, "g") ("1e+06", "250000", "inf", "nan"). */
void irdaq_format_g(char *out, size_t size, double value);
/* repr(str) of n bytes, quotes included ("'FOO'"); bytes outside ASCII as \xNN. */
void irdaq_format_repr(char *out, size_t size, const char *text, size_t n);
/* float(text): decimal or inf/nan, underscores only between digits; false if not. */
bool irdaq_parse_float(const char *text, double *value);

#endif
