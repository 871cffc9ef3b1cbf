/* text.c: JSON string and number writing, UTF-8 checks and truncation (see text.h). */
#include "text.h"

#include <math.h>
#include <string.h>

size_t wrt_utf8_seq(const unsigned char *s, size_t avail) {
    if (avail == 0 || s[0] == 0) return 0;
    unsigned c = s[0];
    if (c < 0x80) return 1;
    size_t n;
    unsigned cp, min;
    if (c >= 0xC2 && c <= 0xDF) { n = 2; cp = c & 0x1F; min = 0x80; }
    else if (c >= 0xE0 && c <= 0xEF) { n = 3; cp = c & 0x0F; min = 0x800; }
    else if (c >= 0xF0 && c <= 0xF4) { n = 4; cp = c & 0x07; min = 0x10000; }
    else return 0; /* a continuation byte, 0xC0/0xC1 (overlong) or 0xF5.. */
    if (avail < n) return 0;
    for (size_t i = 1; i < n; i++) {
        if ((s[i] & 0xC0) != 0x80) return 0; /* also a NUL */
        cp = (cp << 6) | (s[i] & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
    return n;
}

void wrt_json_strn(FILE *f, const char *s, size_t max) {
    fputc('"', f);
    const unsigned char *p = (const unsigned char *)(s ? s : "");
    size_t len = strnlen((const char *)p, max);
    for (size_t i = 0; i < len;) {
        unsigned char c = p[i];
        if (c == '"' || c == '\\') { fputc('\\', f); fputc(c, f); i++; }
        else if (c < 0x20 || c == 0x7f) { fprintf(f, "\\u%04x", c); i++; }
        else if (c < 0x80) { fputc(c, f); i++; }
        else {
            size_t n = wrt_utf8_seq(p + i, len - i);
            if (n == 0) { fputs("\\ufffd", f); i++; }
            else { fwrite(p + i, 1, n, f); i += n; }
        }
    }
    fputc('"', f);
}

void wrt_json_str(FILE *f, const char *s) { wrt_json_strn(f, s, (size_t)-1); }

void wrt_json_num(FILE *f, double x, int digits) {
    if (isfinite(x)) fprintf(f, "%.*g", digits, x);
    else fputs("null", f);
}

char *wrt_utf8_copy(char *dst, size_t cap, const char *src) {
    if (cap == 0) return dst;
    const unsigned char *s = (const unsigned char *)(src ? src : "");
    size_t len = strlen((const char *)s), used = 0;
    while (used < len) {
        size_t n = wrt_utf8_seq(s + used, len - used);
        if (n == 0) n = 1; /* an invalid byte: kept, one byte */
        if (used + n > cap - 1) break;
        used += n;
    }
    memcpy(dst, s, used);
    dst[used] = 0;
    return dst;
}

size_t wrt_text_safe_unit(const unsigned char *p, size_t avail, int keep_newlines, char *out, size_t *outlen) {
    static const char hex[] = "0123456789abcdef";
    *outlen = 0;
    if (avail == 0) return 0;
    unsigned char c = p[0];
    size_t n = c < 0x80 ? 1 : wrt_utf8_seq(p, avail);
    int bad = (c < 0x20 && c != '\t' && !(c == '\n' && keep_newlines)) || c == 0x7f || n == 0;
    size_t esc = bad ? 1 : (n == 2 && c == 0xC2 && p[1] < 0xA0) ? 2 : 0; /* C1 controls */
    if (esc == 0) {
        memcpy(out, p, n);
        *outlen = n;
        return n;
    }
    for (size_t i = 0; i < esc; i++) {
        char *o = out + 4 * i;
        o[0] = '\\'; o[1] = 'x'; o[2] = hex[p[i] >> 4]; o[3] = hex[p[i] & 15];
    }
    *outlen = 4 * esc;
    return esc;
}

char *wrt_text_safe(char *dst, size_t cap, const char *src) {
    if (cap == 0) return dst;
    const unsigned char *s = (const unsigned char *)(src ? src : "");
    size_t len = strlen((const char *)s), used = 0, i = 0;
    char unit[WRT_SAFE_UNIT_MAX];
    while (i < len) {
        size_t ulen, n = wrt_text_safe_unit(s + i, len - i, 0, unit, &ulen);
        if (used + ulen > cap - 1) break;
        memcpy(dst + used, unit, ulen);
        used += ulen;
        i += n;
    }
    dst[used] = 0;
    return dst;
}
