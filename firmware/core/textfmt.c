/* Python-compatible text for numbers and strings, so replies match the reference byte for byte. */
#include "textfmt.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void irdaq_format_shortest(char *out, size_t size, double value)
{
    if (isnan(value)) {
        snprintf(out, size, "nan");
        return;
    }
    if (isinf(value)) {
        snprintf(out, size, value < 0 ? "-inf" : "inf");
        return;
    }
    char buffer[40];
    int precision = 1;
    for (; precision <= 17; precision++) {
        snprintf(buffer, sizeof buffer, "%.*e", precision - 1, value);
        if (strtod(buffer, NULL) == value) {
            break;
        }
    }
    /* buffer: [-]d[.ddd]e(+|-)XX -> the digits and the decimal exponent */
    char digits[20];
    int n_digits = 0;
    const char *p = buffer;
    bool negative = *p == '-';
    if (negative) {
        p++;
    }
    for (; *p && *p != 'e'; p++) {
        if (isdigit((unsigned char)*p) && n_digits < (int)sizeof digits - 1) {
            digits[n_digits++] = *p;
        }
    }
    digits[n_digits] = '\0';
    int exponent = *p == 'e' ? atoi(p + 1) : 0;
    while (n_digits > 1 && digits[n_digits - 1] == '0') { /* %.*e may pad with zeros */
        digits[--n_digits] = '\0';
    }
    char fixed[48];
    size_t at = 0;
    if (negative) {
        fixed[at++] = '-';
    }
    if (exponent < -4 || exponent >= 16) {
        snprintf(out, size, "%s%c%s%se%c%02d", negative ? "-" : "", digits[0],
                 n_digits > 1 ? "." : "", digits + 1, exponent < 0 ? '-' : '+', abs(exponent));
        return;
    }
    if (exponent < 0) { /* 0.000ddd */
        fixed[at++] = '0';
        fixed[at++] = '.';
        for (int k = 0; k < -exponent - 1; k++) {
            fixed[at++] = '0';
        }
        for (int k = 0; k < n_digits; k++) {
            fixed[at++] = digits[k];
        }
    } else { /* ddd.ddd, or ddd000.0 */
        for (int k = 0; k <= exponent || k < n_digits; k++) {
            if (k == exponent + 1) {
                fixed[at++] = '.';
            }
            fixed[at++] = k < n_digits ? digits[k] : '0';
        }
        if (exponent >= n_digits - 1) {
            fixed[at++] = '.';
            fixed[at++] = '0';
        }
    }
    fixed[at] = '\0';
    snprintf(out, size, "%s", fixed);
}

void irdaq_format_g(char *out, size_t size, double value)
{
    if (isnan(value)) {
        snprintf(out, size, "nan");
    } else {
        snprintf(out, size, "%g", value);
    }
}

void irdaq_format_repr(char *out, size_t size, const char *text, size_t n)
{
    bool has_single = memchr(text, '\'', n) != NULL;
    bool has_double = memchr(text, '"', n) != NULL;
    char quote = has_single && !has_double ? '"' : '\'';
    size_t at = 0;
    if (size < 8) {
        if (size) {
            out[0] = '\0';
        }
        return;
    }
    out[at++] = quote;
    for (size_t i = 0; i < n && at + 6 < size; i++) {
        unsigned char c = (unsigned char)text[i];
        if (c == '\\' || c == (unsigned char)quote) {
            out[at++] = '\\';
            out[at++] = (char)c;
        } else if (c == '\n') {
            out[at++] = '\\';
            out[at++] = 'n';
        } else if (c == '\r') {
            out[at++] = '\\';
            out[at++] = 'r';
        } else if (c == '\t') {
            out[at++] = '\\';
            out[at++] = 't';
        } else if (c < 0x20 || c >= 0x7F) {
            at += (size_t)snprintf(out + at, size - at, "\\x%02x", c);
        } else {
            out[at++] = (char)c;
        }
    }
    out[at++] = quote;
    out[at] = '\0';
}

static bool word_is(const char *text, const char *word)
{
    size_t n = strlen(word);
    if (strlen(text) != n) {
        return false;
    }
    for (size_t i = 0; i < n; i++) {
        if (tolower((unsigned char)text[i]) != word[i]) {
            return false;
        }
    }
    return true;
}

bool irdaq_parse_float(const char *text, double *value)
{
    char clean[64];
    size_t n = strlen(text);
    if (n == 0 || n >= sizeof clean) {
        return false;
    }
    const char *body = text + (text[0] == '+' || text[0] == '-');
    if (word_is(body, "inf") || word_is(body, "infinity") || word_is(body, "nan")) {
        double special = word_is(body, "nan") ? NAN : INFINITY;
        *value = text[0] == '-' ? -special : special;
        return true;
    }
    /* [sign] digits [. digits] [e [sign] digits], at least one mantissa digit;
       an underscore only between two digits */
    size_t at = 0, out = 0;
    int mantissa_digits = 0;
    bool seen_point = false, seen_exponent = false;
    int exponent_digits = 0;
    if (text[at] == '+' || text[at] == '-') {
        clean[out++] = text[at++];
    }
    for (; at < n; at++) {
        char c = text[at];
        if (isdigit((unsigned char)c)) {
            if (seen_exponent) {
                exponent_digits++;
            } else {
                mantissa_digits++;
            }
            clean[out++] = c;
        } else if (c == '_') {
            if (at == 0 || at + 1 >= n || !isdigit((unsigned char)text[at - 1]) ||
                !isdigit((unsigned char)text[at + 1])) {
                return false;
            }
        } else if (c == '.' && !seen_point && !seen_exponent) {
            seen_point = true;
            clean[out++] = c;
        } else if ((c == 'e' || c == 'E') && !seen_exponent && mantissa_digits > 0) {
            seen_exponent = true;
            clean[out++] = c;
            if (at + 1 < n && (text[at + 1] == '+' || text[at + 1] == '-')) {
                clean[out++] = text[++at];
            }
        } else {
            return false;
        }
    }
    if (mantissa_digits == 0 || (seen_exponent && exponent_digits == 0)) {
        return false;
    }
    clean[out] = '\0';
    *value = strtod(clean, NULL);
    return true;
}
