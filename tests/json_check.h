/* json_check.h: a strict JSON (RFC 8259) checker for the tests and the fuzz targets, so
 * that "every JSON output parses" is checked inside the process, on every input the
 * fuzzer makes: objects, arrays, strings (escapes, no raw control characters, valid
 * UTF-8), numbers (the grammar: no inf, nan, leading zeros or a bare '.'), literals, and
 * nothing but whitespace after the value. Header-only (static functions); depends on
 * common/text.h for the UTF-8 rule. Not a parser: it builds nothing. */
#ifndef WRT_JSON_CHECK_H
#define WRT_JSON_CHECK_H

#include <stddef.h>
#include <string.h>

#include "common/text.h"

typedef struct json_checker { const unsigned char *p, *end; int depth; } json_checker;

static void jc_ws(json_checker *c) {
    while (c->p < c->end && (*c->p == ' ' || *c->p == '\t' || *c->p == '\n' || *c->p == '\r')) c->p++;
}
static int jc_value(json_checker *c);
static int jc_digits(json_checker *c) {
    const unsigned char *s = c->p;
    while (c->p < c->end && *c->p >= '0' && *c->p <= '9') c->p++;
    return c->p > s;
}
static int jc_number(json_checker *c) {
    if (c->p < c->end && *c->p == '-') c->p++;
    if (c->p < c->end && *c->p == '0') c->p++;
    else if (!jc_digits(c)) return 0;
    if (c->p < c->end && *c->p == '.') { c->p++; if (!jc_digits(c)) return 0; }
    if (c->p < c->end && (*c->p == 'e' || *c->p == 'E')) {
        c->p++;
        if (c->p < c->end && (*c->p == '+' || *c->p == '-')) c->p++;
        if (!jc_digits(c)) return 0;
    }
    return 1;
}
static int jc_string(json_checker *c) {
    if (c->p >= c->end || *c->p != '"') return 0;
    c->p++;
    while (c->p < c->end) {
        unsigned char ch = *c->p;
        if (ch == '"') { c->p++; return 1; }
        if (ch < 0x20) return 0;
        if (ch == '\\') {
            if (++c->p >= c->end) return 0;
            ch = *c->p;
            if (ch == 'u') {
                for (int i = 0; i < 4; i++) {
                    if (++c->p >= c->end) return 0;
                    unsigned char h = *c->p;
                    if (!((h >= '0' && h <= '9') || (h >= 'a' && h <= 'f') || (h >= 'A' && h <= 'F'))) return 0;
                }
            } else if (!strchr("\"\\/bfnrt", ch) || ch == 0) {
                return 0;
            }
            c->p++;
        } else if (ch < 0x80) {
            c->p++;
        } else {
            size_t n = wrt_utf8_seq(c->p, (size_t)(c->end - c->p));
            if (n == 0) return 0;
            c->p += n;
        }
    }
    return 0;
}
static int jc_lit(json_checker *c, const char *w) {
    size_t n = strlen(w);
    if ((size_t)(c->end - c->p) < n || memcmp(c->p, w, n)) return 0;
    c->p += n;
    return 1;
}
static int jc_value(json_checker *c) {
    jc_ws(c);
    if (c->p >= c->end) return 0;
    unsigned char ch = *c->p;
    if (ch == '{' || ch == '[') {
        if (++c->depth > 512) return 0;
        unsigned char close = ch == '{' ? '}' : ']';
        c->p++;
        jc_ws(c);
        if (c->p < c->end && *c->p == close) { c->p++; c->depth--; return 1; }
        for (;;) {
            if (ch == '{') {
                jc_ws(c);
                if (!jc_string(c)) return 0;
                jc_ws(c);
                if (c->p >= c->end || *c->p != ':') return 0;
                c->p++;
            }
            if (!jc_value(c)) return 0;
            jc_ws(c);
            if (c->p < c->end && *c->p == ',') { c->p++; continue; }
            if (c->p < c->end && *c->p == close) { c->p++; c->depth--; return 1; }
            return 0;
        }
    }
    if (ch == '"') return jc_string(c);
    if (ch == 't') return jc_lit(c, "true");
    if (ch == 'f') return jc_lit(c, "false");
    if (ch == 'n') return jc_lit(c, "null");
    return jc_number(c);
}
/* 1 if text[0..n) is exactly one JSON value (surrounding whitespace allowed). */
static inline int json_check(const char *text, size_t n) {
    json_checker c = {(const unsigned char *)text, (const unsigned char *)text + n, 0};
    if (!jc_value(&c)) return 0;
    jc_ws(&c);
    return c.p == c.end;
}

#endif
