/* test.h: the test harness. Each tests/test_*.c is one program named after the module
 * it tests; it calls its cases through TEST_RUN and ends with TEST_END, which prints
 * "<program>: N passed, N failed" and returns non-zero on any failure. Checks stay on
 * in every build. A capturing log sink lets a test assert which error fired. */
#ifndef WRT_TEST_H
#define WRT_TEST_H

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include "common/wrt_common.h"

static int test_passed, test_failed, test_case_failed, test_skipped;
static const char *test_current = "";

#define CHECK(cond, ...) do { \
    if (cond) { test_passed++; } else { \
        test_failed++; test_case_failed = 1; \
        fprintf(stderr, "FAIL %s (%s:%d): %s: ", test_current, __FILE__, __LINE__, #cond); \
        fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); \
    } } while (0)

#define CHECK_NEAR(a, b, tol, ...) do { \
    double check_a_ = (a), check_b_ = (b), check_t_ = (tol); \
    if (fabs(check_a_ - check_b_) <= check_t_) { test_passed++; } else { \
        test_failed++; test_case_failed = 1; \
        fprintf(stderr, "FAIL %s (%s:%d): %s = %.6g, expected %.6g +- %.3g: ", test_current, \
                __FILE__, __LINE__, #a, check_a_, check_b_, check_t_); \
        fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); \
    } } while (0)

/* A check that cannot run here (a tool missing): never silent, it prints "skipped" with
 * the reason and is counted; TEST_END's totals then end with ", N skipped". */
#define SKIP(...) do { \
    test_skipped++; fprintf(stderr, "skipped %s: ", test_current); \
    fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); } while (0)

/* An accuracy the README claims (tests/claims.h): the relative error |err| must be within
 * tol. Prints "claim ID: measured M%, tolerance T%, margin (T - M)%" and the context on
 * stdout, so every run shows how close each claim is to failing (docs/claims.md). */
#define CHECK_CLAIM(id, err, tol, ...) do { \
    double claim_e_ = fabs(err), claim_t_ = (tol); \
    printf("claim %s: measured %.4f%%, tolerance %.4f%% (%s), margin %.4f%%: ", id, 100 * claim_e_, 100 * claim_t_, \
           #tol, 100 * (claim_t_ - claim_e_)); \
    printf(__VA_ARGS__); putchar('\n'); \
    CHECK(claim_e_ <= claim_t_, "claim %s: error %.4f%% above its tolerance %.4f%%", id, 100 * claim_e_, 100 * claim_t_); \
    } while (0)

/* Runs a case if argv selects it (no argument: all cases); prints its wall and CPU
 * seconds (all threads of the process). */
#define TEST_RUN(fn) do { \
    if (test_selected(argc, argv, #fn)) { \
        test_current = #fn; test_case_failed = 0; double t0_ = wrt_now(); clock_t c0_ = clock(); fn(); \
        fprintf(stderr, "%s %s (%.2f s, cpu %.2f s)\n", test_case_failed ? "not ok" : "ok", #fn, wrt_now() - t0_, \
                (double)(clock() - c0_) / CLOCKS_PER_SEC); \
    } } while (0)

#define TEST_END() do { \
    if (test_skipped) printf("%s: %d passed, %d failed, %d skipped\n", argv[0], test_passed, test_failed, test_skipped); \
    else printf("%s: %d passed, %d failed\n", argv[0], test_passed, test_failed); \
    return test_failed ? 1 : 0; } while (0)

static inline int test_selected(int argc, char **argv, const char *name) {
    if (argc < 2) return 1;
    for (int i = 1; i < argc; i++) if (strcmp(argv[i], name) == 0) return 1;
    return 0;
}

/* Capturing logger: collects every message logged since test_capture_begin(). */
static char test_log[16384];
static inline void test_log_sink(void *user, int level, const char *msg) {
    (void)level; (void)user;
    size_t n = strlen(test_log);
    snprintf(test_log + n, sizeof test_log - n, "%s\n", msg);
}
static inline void test_capture_begin(void) { test_log[0] = 0; wrt_log_set_sink(test_log_sink, NULL); }
static inline void test_capture_end(void) { wrt_log_set_sink(NULL, NULL); }

#endif
