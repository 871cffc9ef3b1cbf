/* test_cli.c: tests of cli/cli.h, the command-line vocabulary every tool shares: the light
 * options (1-based numbers; a light the scene lacks, a --light-dir on a point light and
 * malformed values refused with a message), their effect on the lights, the tone curve
 * against its closed form, and JSON escaping. The tools' exit codes and messages end to
 * end are in tests/cli.sh. */
#include "tests/test.h"
#include "cli/cli.h"

#include <stdlib.h>

/* Runs wrt_cli_lights_option over a command line; returns the number of options it
 * refused, and the stderr text in err. */
static int parse(wrt_cli_lights *L, const char *const *args, int n, char *err, size_t errn) {
    char *argv[32];
    argv[0] = (char *)"tool";
    for (int i = 0; i < n; i++) argv[i + 1] = (char *)args[i];
    wrt_cli_lights_init(L);
    char *buf = NULL;
    size_t len = 0;
    FILE *mem = open_memstream(&buf, &len);
    fflush(stderr);
    FILE *old = stderr; /* the module prints its refusals on stderr: captured here */
    stderr = mem;
    int bad = 0;
    for (int i = 1; i <= n; i++) {
        int r = wrt_cli_lights_option("tool", L, n + 1, argv, &i);
        bad += r < 0;
    }
    stderr = old;
    fclose(mem);
    snprintf(err, errn, "%s", buf ? buf : "");
    free(buf);
    return bad;
}

static int apply(const wrt_cli_lights *L, wrt_light *l, int n, float *scales, char *err, size_t errn) {
    char *buf = NULL;
    size_t len = 0;
    FILE *mem = open_memstream(&buf, &len);
    FILE *old = stderr;
    stderr = mem;
    int rc = wrt_cli_lights_apply("tool", L, l, n, scales);
    stderr = old;
    fclose(mem);
    snprintf(err, errn, "%s", buf ? buf : "");
    free(buf);
    return rc;
}

static void two_lights(wrt_light l[2]) {
    memset(l, 0, 2 * sizeof *l);
    l[0].type = WRT_LIGHT_POINT;
    l[0].pos = v3(0, 1, 0);
    l[0].intensity = 2;
    snprintf(l[0].name, sizeof l[0].name, "lamp");
    l[1].type = WRT_LIGHT_SPOT;
    l[1].pos = v3(1, 1, 1);
    l[1].dir = v3(0, -1, 0);
    l[1].intensity = 5;
    l[1].outer_cone = 0.7f;
    for (int k = 0; k < 3; k++) l[0].color[k] = l[1].color[k] = 1;
}

static void test_numbers_from_one(void) {
    wrt_cli_lights L;
    char err[512];
    wrt_light l[2];
    float sc[2];
    const char *a[] = {"--light", "2", "--light-pos", "3,4,5", "--light-scale", "1=0.5", "--light-intensity", "7"};
    CHECK(parse(&L, a, 8, err, sizeof err) == 0, "%s", err);
    two_lights(l);
    CHECK(apply(&L, l, 2, sc, err, sizeof err) == 0, "%s", err);
    CHECK(l[1].pos.x == 3 && l[1].pos.y == 4 && l[1].pos.z == 5 && l[1].intensity == 7, "light 2 moved");
    CHECK(l[0].pos.y == 1 && l[0].intensity == 2, "light 1 untouched");
    CHECK(sc[0] == 0.5f && sc[1] == 1, "scales %g %g", sc[0], sc[1]);
    /* without a scales array the factors fold into the intensities */
    two_lights(l);
    const char *b[] = {"--lights-off", "2", "--light-scale", "1=3"};
    CHECK(parse(&L, b, 4, err, sizeof err) == 0, "%s", err);
    CHECK(apply(&L, l, 2, NULL, err, sizeof err) == 0, "%s", err);
    CHECK(l[0].intensity == 6 && l[1].intensity == 0, "intensities %g %g", l[0].intensity, l[1].intensity);
}

static void test_missing_light_refused(void) {
    wrt_cli_lights L;
    char err[512];
    wrt_light l[2];
    struct { const char *args[4]; int n; const char *msg; } cases[] = {
        {{"--light-scale", "3=2"}, 2, "--light-scale 3: the scene has 2 lights"},
        {{"--lights-off", "1,3"}, 2, "--lights-off 3: the scene has 2 lights"},
        {{"--light", "3", "--light-pos", "0,0,0"}, 4, "--light 3: the scene has 2 lights"},
        {{"--light", "3"}, 2, "--light 3: the scene has 2 lights"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
        CHECK(parse(&L, cases[c].args, cases[c].n, err, sizeof err) == 0, "%s", err);
        two_lights(l);
        int rc = apply(&L, l, 2, NULL, err, sizeof err);
        CHECK(rc == WRT_EXIT_USAGE && strstr(err, cases[c].msg), "case %zu: rc %d, '%s'", c, rc, err);
        CHECK(l[0].intensity == 2 && l[1].intensity == 5, "case %zu: nothing changed on refusal", c);
    }
    /* one light: the singular */
    const char *a[] = {"--light-scale", "2=3"};
    parse(&L, a, 2, err, sizeof err);
    two_lights(l);
    CHECK(apply(&L, l, 1, NULL, err, sizeof err) == WRT_EXIT_USAGE && strstr(err, "has 1 light ("), "%s", err);
}

static void test_light_dir_rule(void) {
    wrt_cli_lights L;
    char err[512];
    wrt_light l[2];
    const char *a[] = {"--light-dir", "0,0,-1"};
    parse(&L, a, 2, err, sizeof err);
    two_lights(l);
    CHECK(apply(&L, l, 2, NULL, err, sizeof err) == WRT_EXIT_USAGE && strstr(err, "point light") &&
              strstr(err, "'lamp'"), "%s", err);
    /* a spot may be aimed */
    const char *b[] = {"--light", "2", "--light-dir", "0,0,-2"};
    parse(&L, b, 4, err, sizeof err);
    two_lights(l);
    CHECK(apply(&L, l, 2, NULL, err, sizeof err) == 0 && l[1].dir.z == -1 && l[1].type == WRT_LIGHT_SPOT, "%s", err);
    /* --light-cone turns the point light into a spot along the direction */
    const char *c[] = {"--light-dir", "1,0,0", "--light-cone", "0.1,0.4"};
    parse(&L, c, 4, err, sizeof err);
    two_lights(l);
    CHECK(apply(&L, l, 2, NULL, err, sizeof err) == 0 && l[0].type == WRT_LIGHT_SPOT && l[0].dir.x == 1 &&
              fabsf(l[0].inner_cone - 0.1f) < 1e-7f && fabsf(l[0].outer_cone - 0.4f) < 1e-7f, "%s", err);
}

static void test_bad_values(void) {
    wrt_cli_lights L;
    char err[512];
    const char *cases[][2] = {
        {"--light-scale", "0=1"}, {"--light-scale", "1=-2"}, {"--light-scale", "1"}, {"--lights-off", "1,,2"},
        {"--lights-off", "0"}, {"--light-pos", "1,2"}, {"--light-pos", "1,2,nan"}, {"--light-dir", "0,0,0"},
        {"--light-cone", "0.5,0.2"}, {"--light-cone", "0,2"}, {"--light-intensity", "-1"},
        {"--light-color", "1,-1,0"}, {"--light", "0"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
        int bad = parse(&L, cases[c], 2, err, sizeof err);
        CHECK(bad == 1 && strstr(err, "bad value for") && strstr(err, cases[c][0]), "%s %s: '%s'", cases[c][0],
              cases[c][1], err);
    }
    const char *none[] = {"--light-pos"};
    CHECK(parse(&L, none, 1, err, sizeof err) == 1 && strstr(err, "needs a value"), "%s", err);
    const char *other[] = {"--width", "3"};
    CHECK(parse(&L, other, 2, err, sizeof err) == 0 && !wrt_cli_lights_any(&L), "not a light option");
}

/* x 2^ev, x / (1 + x), sRGB: at x 2^ev = 1 the curve gives 0.5, encoded 0.7354 -> 188 */
static void test_tone_curve(void) {
    float px[12] = {1, 1, 1, 0.5f, 0.5f, 0.5f, 0, -1, NAN, 1e9f, 1e9f, 1e9f};
    uint8_t o[12], o1[12];
    wrt_tonemap_rgb8(px, 4, 0, o);
    double enc = 1.055 * pow(0.5, 1 / 2.4) - 0.055;
    CHECK(o[0] == (uint8_t)(enc * 255 + 0.5) && o[0] == 188, "1 -> %d", o[0]);
    double y = 0.5 / 1.5, e2 = 1.055 * pow(y, 1 / 2.4) - 0.055;
    CHECK(o[3] == (uint8_t)(e2 * 255 + 0.5), "0.5 -> %d", o[3]);
    CHECK(o[6] == 0 && o[7] == 0 && o[8] == 0 && o[9] == 255, "0, negative, NaN, huge: %d %d %d %d", o[6], o[7],
          o[8], o[9]);
    wrt_tonemap_rgb8(px + 3, 1, 1, o1); /* one stop up: 0.5 -> 1 */
    CHECK(o1[0] == o[0], "+1 EV on 0.5 = 1: %d vs %d", o1[0], o[0]);
}

static void test_json_and_table(void) {
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_cli_json_str(f, "a\"b\\c\n\x01");
    fclose(f);
    CHECK(!strcmp(buf, "\"a\\\"b\\\\c\\u000a\\u0001\""), "%s", buf);
    free(buf);
    f = open_memstream(&buf, &len);
    wrt_cli_exit_table(f);
    fclose(f);
    const char *lines[] = {"0 ok", "1 bad command line", "2 bad input", "3 output cannot be written",
                           "4 interrupted", "5 accuracy not met", "6 no display", "7 out of memory"};
    for (size_t k = 0; k < 8; k++) CHECK(strstr(buf, lines[k]) != NULL, "'%s' in the table", lines[k]);
    free(buf);
    CHECK(WRT_EXIT_USAGE == 1 && WRT_EXIT_INPUT == 2 && WRT_EXIT_OUTPUT == 3 && WRT_EXIT_INTERRUPTED == 4 &&
              WRT_EXIT_ACCURACY == 5 && WRT_EXIT_GL == 6 && WRT_EXIT_INTERNAL == 7, "the numbers agreed on");
}

int main(int argc, char **argv) {
    TEST_RUN(test_numbers_from_one);
    TEST_RUN(test_missing_light_refused);
    TEST_RUN(test_light_dir_rule);
    TEST_RUN(test_bad_values);
    TEST_RUN(test_tone_curve);
    TEST_RUN(test_json_and_table);
    TEST_END();
}
