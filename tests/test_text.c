/* test_text.c: tests of common/text.h (the one JSON string writer and UTF-8-safe name
 * truncation) and common/outfile.h (outputs only as regular files), against truths
 * written out by hand: the escaped bytes of hostile strings, where a name is cut, which
 * targets are refused. End to end through the tools: tests/harden.sh. */
#include "tests/test.h"
#include "common/outfile.h"
#include "common/text.h"
#include "tests/json_check.h"

#include <errno.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

/* The JSON literal wrt_json_strn writes for (s, max), in out. */
static void lit(const char *s, size_t max, char *out, size_t n) {
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_json_strn(f, s, max);
    fclose(f);
    snprintf(out, n, "%s", buf);
    free(buf);
}

static void test_json_escapes(void) {
    char o[256];
    lit("plain", (size_t)-1, o, sizeof o);
    CHECK(!strcmp(o, "\"plain\""), "%s", o);
    lit("q\"b\\s", (size_t)-1, o, sizeof o);
    CHECK(!strcmp(o, "\"q\\\"b\\\\s\""), "%s", o);
    lit("\x01\x1b[1m\n\x7f", (size_t)-1, o, sizeof o);
    CHECK(!strcmp(o, "\"\\u0001\\u001b[1m\\u000a\\u007f\""), "%s", o);
    /* valid UTF-8 passes unchanged: e-acute (2 bytes), euro (3), U+1F600 (4) */
    lit("\xc3\xa9\xe2\x82\xac\xf0\x9f\x98\x80", (size_t)-1, o, sizeof o);
    CHECK(!strcmp(o, "\"\xc3\xa9\xe2\x82\xac\xf0\x9f\x98\x80\""), "%s", o);
    /* invalid: a lone continuation byte, a lead byte cut short, an overlong '/' (C0 AF),
     * a UTF-16 surrogate (ED A0 80), past U+10FFFF (F4 90 80 80), 0xFF */
    lit("a\x80" "b\xc3" "c\xc0\xaf" "d\xed\xa0\x80" "e\xf4\x90\x80\x80" "f\xff", (size_t)-1, o, sizeof o);
    CHECK(!strcmp(o, "\"a\\ufffdb\\ufffdc\\ufffd\\ufffdd\\ufffd\\ufffd\\ufffde\\ufffd\\ufffd\\ufffd\\ufffdf\\ufffd\""),
          "%s", o);
    /* a sequence cut by max is invalid too */
    lit("x\xe2\x82\xac", 3, o, sizeof o);
    CHECK(!strcmp(o, "\"x\\ufffd\\ufffd\""), "%s", o);
    lit(NULL, 5, o, sizeof o);
    CHECK(!strcmp(o, "\"\""), "%s", o);
}

/* The checker the fuzz target relies on, against hand-made truths. */
static void test_json_checker(void) {
    static const char *good[] = {"{}", "[]", " {\"a\": [1, -2.5e+3, 0, true, false, null, \"\\u00e9\\n\"]} ",
                                 "\"\xc3\xa9\"", "0.5", "[[[]]]"};
    static const char *bad[] = {"", "{", "{\"a\" 1}", "[1,]", "[01]", "[.5]", "[1.]", "[inf]", "[nan]", "[-]",
                                "\"\x01\"", "\"\xc3\"", "\"\\x41\"", "\"\\u12\"", "{} {}", "[1] x",
                                "{1: 2}", "tru", "\"abc"};
    for (size_t i = 0; i < sizeof good / sizeof *good; i++) CHECK(json_check(good[i], strlen(good[i])), "good %zu: %s", i, good[i]);
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) CHECK(!json_check(bad[i], strlen(bad[i])), "bad %zu: %s", i, bad[i]);
    /* what the writer makes of every byte value passes the checker */
    char s[256], *buf = NULL;
    for (int i = 0; i < 255; i++) s[i] = (char)(i + 1);
    s[255] = 0;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_json_str(f, s);
    fclose(f);
    CHECK(json_check(buf, len), "the writer's output of bytes 1..255 is JSON: %s", buf);
    free(buf);
}

static void test_json_numbers(void) {
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_json_num(f, 1.5, 9);
    fputc(' ', f);
    wrt_json_num(f, INFINITY, 9);
    fputc(' ', f);
    wrt_json_num(f, NAN, 9);
    fclose(f);
    CHECK(!strcmp(buf, "1.5 null null"), "%s", buf);
    free(buf);
}

static void test_utf8_cut(void) {
    char d[64], src[128];
    /* 62 ASCII bytes then e-acute (bytes 62..63): a 64-byte buffer holds 63 bytes, so
     * the e-acute does not fit whole and the name ends after the 62 ASCII bytes */
    memset(src, 'a', 62);
    strcpy(src + 62, "\xc3\xa9tail");
    wrt_utf8_copy(d, sizeof d, src);
    CHECK(strlen(d) == 62 && d[61] == 'a', "len %zu", strlen(d));
    /* 61 + euro (3 bytes: 61..63) -> 61; 60 + U+1F600 (4 bytes) -> 60; 61 + e-acute fits: 63 */
    memset(src, 'b', 61);
    strcpy(src + 61, "\xe2\x82\xac");
    wrt_utf8_copy(d, sizeof d, src);
    CHECK(strlen(d) == 61, "len %zu", strlen(d));
    memset(src, 'c', 60);
    strcpy(src + 60, "\xf0\x9f\x98\x80");
    wrt_utf8_copy(d, sizeof d, src);
    CHECK(strlen(d) == 60, "len %zu", strlen(d));
    memset(src, 'e', 61);
    strcpy(src + 61, "\xc3\xa9zz");
    wrt_utf8_copy(d, sizeof d, src);
    CHECK(strlen(d) == 63 && !strcmp(d + 61, "\xc3\xa9"), "len %zu", strlen(d));
    wrt_utf8_copy(d, sizeof d, "short");
    CHECK(!strcmp(d, "short"), "%s", d);
    char one[1];
    wrt_utf8_copy(one, 1, "x");
    CHECK(one[0] == 0, "cap 1 gives the empty string");
}

static void test_outputs_regular_only(void) {
    char dir[] = "/tmp/wrt_text_XXXXXX";
    CHECK(mkdtemp(dir) != NULL, "mkdtemp");
    char fifo[256], link[256], target[256], reg[256], sub[256];
    snprintf(fifo, sizeof fifo, "%s/fifo", dir);
    snprintf(link, sizeof link, "%s/link", dir);
    snprintf(target, sizeof target, "%s/target", dir);
    snprintf(reg, sizeof reg, "%s/out.txt", dir);
    snprintf(sub, sizeof sub, "%s/sub", dir);
    CHECK(mkfifo(fifo, 0600) == 0, "mkfifo");
    FILE *t = fopen(target, "w");
    fputs("keep", t);
    fclose(t);
    CHECK(symlink(target, link) == 0, "symlink");
    CHECK(mkdir(sub, 0700) == 0, "mkdir");
    CHECK(wrt_output_check(fifo) == WRT_ERR_IO && strstr(wrt_last_error(), "is a FIFO"), "%s", wrt_last_error());
    CHECK(wrt_output_check(link) == WRT_ERR_IO && strstr(wrt_last_error(), "is a symbolic link"), "%s", wrt_last_error());
    CHECK(wrt_output_check(sub) == WRT_ERR_IO && strstr(wrt_last_error(), "is a directory"), "%s", wrt_last_error());
    CHECK(wrt_output_check(reg) == WRT_OK, "a new file is fine");
    wrt_output o;
    CHECK(wrt_output_begin(link, "w", &o) == WRT_ERR_IO && o.f == NULL, "begin on a link refused");
    /* a regular file: written through a temporary, renamed, nothing left behind */
    CHECK(wrt_output_begin(reg, "w", &o) == WRT_OK, "%s", wrt_last_error());
    fputs("hello", o.f);
    CHECK(wrt_output_commit(&o) == WRT_OK, "%s", wrt_last_error());
    char buf[16] = {0};
    t = fopen(reg, "r");
    CHECK(t && fread(buf, 1, sizeof buf - 1, t) == 5 && !strcmp(buf, "hello"), "%s", buf);
    if (t) fclose(t);
    /* the target turned into a link while the output was written: refused at commit */
    CHECK(wrt_output_begin(reg, "w", &o) == WRT_OK, "%s", wrt_last_error());
    fputs("new", o.f);
    unlink(reg);
    CHECK(symlink(target, reg) == 0, "symlink");
    CHECK(wrt_output_commit(&o) == WRT_ERR_IO && strstr(wrt_last_error(), "is a symbolic link"), "%s", wrt_last_error());
    t = fopen(target, "r");
    memset(buf, 0, sizeof buf);
    CHECK(t && fread(buf, 1, sizeof buf - 1, t) == 4 && !strcmp(buf, "keep"), "the link's target unchanged: %s", buf);
    if (t) fclose(t);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "ls %s | grep -c tmp", dir);
    FILE *p = popen(cmd, "r");
    int ntmp = -1;
    if (p) { if (fscanf(p, "%d", &ntmp) != 1) ntmp = -1; pclose(p); }
    CHECK(ntmp == 0, "%d temporaries left", ntmp);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CHECK(system(cmd) == 0, "cleanup");
}

/* Text from a file in a message: control bytes, C1 controls and invalid UTF-8 as \xNN,
 * valid characters kept, cut between units; and wrt_fail applies it to every message. */
static void test_message_escapes(void) {
    char d[64];
    wrt_text_safe(d, sizeof d, "a\x1b[31m\nb\tc\x7f");
    CHECK(!strcmp(d, "a\\x1b[31m\\x0ab\tc\\x7f"), "%s", d);
    wrt_text_safe(d, sizeof d, "\xc2\x9b" "2J \xc3\xa9 \xe2\x82\xac \xff \xc3");
    CHECK(!strcmp(d, "\\xc2\\x9b" "2J \xc3\xa9 \xe2\x82\xac \\xff \\xc3"), "%s", d);
    wrt_text_safe(d, 7, "ab\x01" "cd"); /* "ab\x01" is 6 bytes + NUL: the next unit does not fit */
    CHECK(!strcmp(d, "ab\\x01"), "%s", d);
    wrt_text_safe(d, 6, "ab\x01" "cd"); /* the escape does not fit whole: cut before it */
    CHECK(!strcmp(d, "ab"), "%s", d);
    wrt_fail(WRT_ERR_PARSE, "light '%s'", "x\ny\x1b");
    CHECK(!strcmp(wrt_last_error(), "light 'x\\x0ay\\x1b'"), "%s", wrt_last_error());
    char unit[WRT_SAFE_UNIT_MAX];
    size_t ulen, n = wrt_text_safe_unit((const unsigned char *)"\n", 1, 1, unit, &ulen);
    CHECK(n == 1 && ulen == 1 && unit[0] == '\n', "a newline kept in a report: n %zu ulen %zu", n, ulen);
}

/* An input registered with wrt_output_protect is refused as an output under any name (a
 * hard link too); another regular file is not. Runs last: the registry stays. */
static void test_output_protect(void) {
    char dir[] = "/tmp/wrt_text_XXXXXX";
    CHECK(mkdtemp(dir) != NULL, "mkdtemp");
    char in[256], hard[256], other[256];
    snprintf(in, sizeof in, "%s/in.gto", dir);
    snprintf(hard, sizeof hard, "%s/hard.json", dir);
    snprintf(other, sizeof other, "%s/other.json", dir);
    FILE *f = fopen(in, "w");
    fputs("input", f);
    fclose(f);
    CHECK(link(in, hard) == 0, "link");
    CHECK(wrt_output_check(in) == WRT_OK, "before it is registered, a regular file is fine");
    wrt_output_protect(in);
    wrt_output_protect(other); /* does not exist: ignored */
    CHECK(wrt_output_check(in) == WRT_ERR_IO && strstr(wrt_last_error(), "an input of this run"), "%s",
          wrt_last_error());
    CHECK(wrt_output_check(hard) == WRT_ERR_IO && strstr(wrt_last_error(), "in.gto, an input of this run"), "%s",
          wrt_last_error());
    CHECK(wrt_output_check(other) == WRT_OK, "another file: %s", wrt_last_error());
    unlink(in);
    unlink(hard);
    rmdir(dir);
}

int main(int argc, char **argv) {
    TEST_RUN(test_json_escapes);
    TEST_RUN(test_json_checker);
    TEST_RUN(test_json_numbers);
    TEST_RUN(test_utf8_cut);
    TEST_RUN(test_message_escapes);
    TEST_RUN(test_outputs_regular_only);
    TEST_RUN(test_output_protect);
    TEST_END();
}
