/* text.h: the one JSON string and number writer of wrt, and UTF-8-safe truncation of
 * names. Every JSON output (--scan --json, the bake's --json, wrt-play's --stats-json and
 * --bench, the .gto's provenance) writes its strings through wrt_json_str, so that it
 * parses whatever the names hold: quotes, backslashes and control characters are
 * escaped, and bytes that are not valid UTF-8 become U+FFFD. Depends on the C library
 * only. Thread-safe (no state). */
#ifndef WRT_TEXT_H
#define WRT_TEXT_H

#include <stddef.h>
#include <stdio.h>

/* Writes s (at most max bytes of it, or up to its NUL) as a JSON string literal. */
void wrt_json_strn(FILE *f, const char *s, size_t max);
/* The same for a NUL-terminated string; NULL writes "". */
void wrt_json_str(FILE *f, const char *s);
/* A number with `digits` significant digits; null where it is not finite (JSON has no
 * inf or NaN). */
void wrt_json_num(FILE *f, double x, int digits);

/* Length in bytes of the valid UTF-8 sequence at s (1..4), or 0 if the bytes at s are
 * not one (overlong, surrogate, past U+10FFFF, cut short by NUL or by `avail`). */
size_t wrt_utf8_seq(const unsigned char *s, size_t avail);

/* Copies src into dst (cap bytes, cap >= 1), cut at a character boundary so that dst
 * never ends inside a UTF-8 sequence; invalid bytes are copied as they are (the JSON
 * writer replaces them). Returns dst. */
char *wrt_utf8_copy(char *dst, size_t cap, const char *src);

/* Text from a file (names, provenance) shown on a terminal: one unit of it, at p (avail
 * bytes). A valid UTF-8 character that is not a control is copied to out as it is; a
 * control byte (C0 except tab, and newline unless keep_newlines; DEL), a C1 control
 * (U+0080..U+009F, e.g. CSI) and a byte that is not valid UTF-8 are written as \xNN
 * (each byte). out holds at least WRT_SAFE_UNIT_MAX bytes, no NUL added; *outlen gets its
 * length. Returns the bytes of p consumed (>= 1; 0 only when avail is 0). The one rule
 * for every message and report that can carry text from a file. */
#define WRT_SAFE_UNIT_MAX 8
size_t wrt_text_safe_unit(const unsigned char *p, size_t avail, int keep_newlines, char *out, size_t *outlen);
/* src made safe for a one-line message (newlines escaped too) into dst (cap >= 1 bytes,
 * always NUL-terminated, cut between units). Returns dst. */
char *wrt_text_safe(char *dst, size_t cap, const char *src);

#endif
