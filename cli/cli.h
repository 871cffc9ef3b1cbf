/* cli.h: what every wrt command line shares, so that the tools speak one language: the
 * exit-code table (printed by each --help from here), --version, number and vector
 * options with one wording of their errors, the light-override options (the same
 * meaning and 1-based light numbers in wrt-play, wrt-ref and wrt-compare), JSON string
 * escaping, and the progress line of long work on a terminal.
 * Depends on common/wrt_common.h, common/scene_types.h (wrt_light) and, for the
 * version, formats/gto.h. The progress line is one per process, guarded by a mutex. */
#ifndef WRT_CLI_H
#define WRT_CLI_H

#include <stdio.h>

#include "../common/wrt_common.h"
#include "../common/scene_types.h"

/* The exit codes of every tool. */
enum {
    WRT_EXIT_OK = 0,
    WRT_EXIT_USAGE = 1,       /* bad command line (unknown option, bad value, no such light) */
    WRT_EXIT_INPUT = 2,       /* bad input: the scene or the .gto cannot be read or is refused */
    WRT_EXIT_OUTPUT = 3,      /* an output file cannot be written */
    WRT_EXIT_INTERRUPTED = 4, /* SIGINT / SIGTERM, after cleaning up */
    WRT_EXIT_ACCURACY = 5,    /* a required accuracy was not met */
    WRT_EXIT_GL = 6,          /* no display, OpenGL unavailable */
    WRT_EXIT_INTERNAL = 7     /* out of memory or internal error */
};

/* The table above as --help prints it ("exit codes:\n  0 ok\n ..."). */
void wrt_cli_exit_table(FILE *f);
/* "TOOL 0.1.0 (.gto version N)" on stdout. */
void wrt_cli_version(const char *tool);

/* Option values. Each prints "TOOL: bad value for OPT: 'VAL' (WANT)" on stderr and
 * returns 0 when the value is missing, malformed, not finite or out of range. */
int wrt_cli_int(const char *tool, const char *opt, const char *val, long lo, long hi, long *out);
int wrt_cli_num(const char *tool, const char *opt, const char *val, double lo, double hi, double *out);
int wrt_cli_vec3(const char *tool, const char *opt, const char *val, double out[3]);

/* ---- light overrides, one vocabulary for every tool that shows a scene's lights ----
 *   --light N                the light the next four options change (1-based; default 1)
 *   --light-pos X,Y,Z        move it
 *   --light-dir X,Y,Z        aim it (a spot light; refused on a point light without --light-cone)
 *   --light-cone IN,OUT      make it a spot with these cone angles in radians
 *   --light-intensity I      candela
 *   --light-color R,G,B      linear RGB
 *   --light-scale N=S        multiply light N by S (repeatable)
 *   --lights-off N[,M..]     switch lights off
 * A light number the scene does not have is refused with a message (exit 1). */
#define WRT_CLI_MAX_LIGHTS 64
typedef struct wrt_cli_lights {
    int which;                      /* 1-based; 0 = not given (1) */
    int has_pos, has_dir, has_cone, has_intensity, has_color;
    double pos[3], dir[3], cone[2], intensity, color[3];
    float scale[WRT_CLI_MAX_LIGHTS]; /* multipliers (1 unless given) */
    unsigned char scaled[WRT_CLI_MAX_LIGHTS]; /* named by --light-scale or --lights-off */
    int max_named;                  /* the largest light number named (0 if none) */
} wrt_cli_lights;

void wrt_cli_lights_init(wrt_cli_lights *L);
/* If argv[*i] is one of the options above, parses it and its value (advancing *i) and
 * returns 1, or prints the error and returns -1; returns 0 if it is not a light option. */
int wrt_cli_lights_option(const char *tool, wrt_cli_lights *L, int argc, char **argv, int *i);
/* Applies the overrides to lights[0..n) and fills scales[0..n) (may be NULL when the
 * tool folds the scales into the intensities: then it does so). Returns 0, or prints
 * "TOOL: OPT N: the scene has M light(s)" (or why a --light-dir is refused) and returns
 * WRT_EXIT_USAGE. */
int wrt_cli_lights_apply(const char *tool, const wrt_cli_lights *L, wrt_light *lights, int n, float *scales);
/* Whether any light option was given. */
int wrt_cli_lights_any(const wrt_cli_lights *L);
/* The help text of the options above, indented two spaces. */
void wrt_cli_lights_help(FILE *f);

/* Tone mapping of every 8-bit picture the tools write: x * 2^ev, Reinhard x / (1 + x)
 * per channel, sRGB encoding; NaN and negatives become 0. The same curve as the window's. */
void wrt_tonemap_rgb8(const float *rgb, size_t npixels, float exposure_ev, uint8_t *out);

/* A JSON string literal, quotes, backslashes and control characters escaped. */
void wrt_cli_json_str(FILE *f, const char *s);

/* What every program sets up first thing in main (`tool` must stay valid: a literal):
 *  - results written to stdout must not be lost silently (a full disk, a closed pipe):
 *    an exit handler flushes stdout and, if that or any earlier write failed, prints
 *    "TOOL: error: cannot write the results to standard output: REASON" and ends the
 *    process with WRT_EXIT_OUTPUT (3);
 *  - out of memory in wrt_xmalloc and friends (any thread): "TOOL: error: out of memory
 *    allocating N bytes", the temporaries being written removed, exit WRT_EXIT_INTERNAL
 *    (7), never abort(). */
void wrt_cli_init(const char *tool);

/* Writes text that came from a file (names, provenance) for a terminal: control
 * characters (escape sequences included) other than newline and tab, DEL, C1 controls
 * and bytes that are not UTF-8 are shown as \xNN, so a file cannot drive the terminal.
 * At most `max` bytes of s (a NUL ends it earlier). */
void wrt_cli_print_safe(FILE *f, const char *s, size_t max);
/* Runs print(user, f) into memory, then writes what it printed to `out` through
 * wrt_cli_print_safe. Returns print's result. For reports that print names from files. */
int wrt_cli_print_safely(FILE *out, int (*print)(void *user, FILE *f), void *user);

/* ---- progress on a terminal ----
 * One line per phase: "  dto      [#######.......]  48%   3.1 s  ~3.4 s left"; a new
 * phase (or wrt_cli_progress_end) ends the previous line with its total time on a line
 * of its own. Prints nothing unless wrt_cli_progress_enable(1) (the caller decides:
 * on when stderr is a terminal, unless --quiet). done < 0: no fraction known. */
void wrt_cli_progress_enable(int on);
int wrt_cli_progress_enabled(void);
void wrt_cli_progress(const char *phase, double done);
void wrt_cli_progress_end(void);

#endif
