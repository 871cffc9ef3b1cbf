/* options.c: wrt-play's command line: the usage text (with the exit codes of cli/cli.h)
 * and parse_args, which fills the options of options.h from argv (defaults, every
 * option and its range, an option given twice refused, the combinations checked).
 * Exits only for --help and --version. The program itself is main.c. Depends on
 * cli/cli.h (numbers, vectors, the lights options) and player/render.h. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../cli/cli.h"
#include "../common/limits.h"
#include "options.h"

static void usage(FILE *f) {
    fprintf(f,
        "usage: wrt-play FILE.gto [options]\n"
        "Relights a scene baked by wrt-bake (Wavelet Radiance Transport) in real time, in a\n"
        "window or headless into pictures. In the window (H shows the overlay, F1 these keys in it):\n"
        "  mouse (left button) look       W A S D move, Q E down/up, Shift faster\n"
        "  Tab / 1-9 select a light       arrows or I J K L move it, U O lower/raise it (a sun: turn it)\n"
        "  Space switch it on/off         + - brighter/dimmer, C cycle its colour\n"
        "  [ ] exposure -/+ 1/2 stop      T both/direct/indirect, R reset view and lights\n"
        "  F5 reload the .gto             F12 screenshot (wrt-play-N.png), P print as options\n"
        "  Esc quit\n"
        "\n"
        "Output:\n"
        "  --headless            no window (EGL surfaceless); needs -o, --script, --stats-json or --bench\n"
        "  -o, --out IMG         write the picture: .exr = linear radiance (float RGB),\n"
        "                        anything else (.png) = tone mapped 8-bit sRGB\n"
        "  --width W --height H  picture or window size (default 640 x 480)\n"
        "  --exposure EV         exposure in stops (default 0): x 2^EV, then Reinhard x/(1+x),\n"
        "                        then sRGB; the same curve as wrt-ref's and wrt-compare's PNGs\n"
        "  --msaa N              samples per pixel of the rasterizer: 1, 2, 4 or 8 (default 4)\n"
        "  --supersample N       headless pictures: render N x N times the pixels and average\n"
        "                        them (smooths shadow edges too; N = 1..4, default 1)\n"
        "  --direct-only | --indirect-only   show one part (default: both)\n"
        "  --stats-json FILE     per quad: area, centroid, normal, mesh name, mean direct and\n"
        "                        indirect incident irradiance (RGB) for the current lights\n"
        "  --bench N             move light 1 along a fixed circle (turn a sun 2 degrees a frame)\n"
        "                        for N frames; print one JSON object with the median\n"
        "                        milliseconds of each stage and the fps\n"
        "  --frames N            window: quit after N frames; --screenshot IMG saves the last one\n"
        "  --no-overlay          window: start with the on-screen overlay hidden\n"
        "  --script FILE --out-pattern PATTERN   render one frame per keyframe (see below) to\n"
        "                        PATTERN with one %%d or %%0Nd, e.g. frame_%%04d.png\n"
        "  --script-fps F        instead, sample the keyframes (linear interpolation in t) at F frames/s\n"
        "\n"
        "Camera:\n"
        "  --camera-pos X,Y,Z --camera-target X,Y,Z --fov DEG (vertical)\n"
        "Lights (default: the file's):\n");
    wrt_cli_lights_help(f);
    fprintf(f,
        "  --emitter-scale M=S[,M=S...]  scale emissive material M's light by S >= 0 (0: off;\n"
        "                        materials numbered as --scan and --info list them)\n"
        "Other:\n"
        "  --threads N           relighting threads (0 = all cores)\n"
        "  --max-tex-res N       cap on a quad's texture resolution (default 64)\n"
        "  --budget MS           each relight works within about MS milliseconds and carries\n"
        "                        the rest to the next frame (default 0: no budget; wrt.h)\n"
        "  --skip-below F        a light change that moves the direct light by less than the\n"
        "                        fraction F (0 <= F < 1) of the light last applied costs no\n"
        "                        multiply and no texture (default 0: none skipped)\n"
        "  --linear-display      the linear smooth display: textures superpose across lights\n"
        "                        (no slope limiter, no clamp; see wrt.h, linear_display)\n"
        "  --shadow-res N        shadow cube map face size (default 512; 2048 for a scene\n"
        "                        with curved meshes, whose smooth shading needs it)\n"
        "  --version, -h, --help\n"
        "\n"
        "Script: one keyframe per line, '#' starts a comment. A line is a time t in seconds\n"
        "followed by any of the keys below with their values (they change light 1 or the one\n"
        "--light names); a key left out keeps its previous value:\n"
        "  t light_pos X Y Z light_dir X Y Z light_intensity I camera_pos X Y Z camera_target X Y Z\n"
        "e.g.  0.0 light_pos 0 1.9 0 camera_pos 0 1 3.5 camera_target 0 1 0\n"
        "      1.0 light_pos 0.5 1.9 0\n"
        "\n");
    wrt_cli_exit_table(f);
}

static const char *T = "wrt-play";

/* --emitter-scale's value: M=S pairs, comma-separated; 0 with a message if malformed. */
static int parse_emitters(const char *v, options *o) {
    const char *p = v;
    while (*p) {
        char *end;
        long m = strtol(p, &end, 10);
        if (end == p || *end != '=' || m < 0 || m > 1000000) break;
        p = end + 1;
        double s = strtod(p, &end);
        if (end == p || !(s >= 0) || !(s <= WRT_MAX_LIGHT_SCALE) || (*end && *end != ',')) break;
        if (o->nemit == (int)(sizeof o->emit_mat / sizeof *o->emit_mat)) {
            fprintf(stderr, "wrt-play: error: --emitter-scale: more than %d emitters\n", o->nemit);
            return 0;
        }
        o->emit_mat[o->nemit] = (int)m;
        o->emit_scale[o->nemit++] = (float)s;
        p = *end ? end + 1 : end;
        if (!*end) return 1;
    }
    fprintf(stderr, "wrt-play: error: --emitter-scale '%s': expected M=S[,M=S...] with M a material index and S in "
                    "[0, %g]\n", v, (double)WRT_MAX_LIGHT_SCALE);
    return 0;
}

int parse_args(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->width = 640;
    o->height = 480;
    o->max_tex_res = 64;
    o->msaa = 4;
    o->supersample = 1;
    wrt_cli_lights_init(&o->lights);
    const char *seen[64];
    int nseen = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        long n;
        double x;
        int lr = wrt_cli_lights_option(T, &o->lights, argc, argv, &i);
        if (lr < 0) return 0;
        if (lr > 0) continue;
        /* An option given twice is refused (`-o a -o b` would silently take the last), as in wrt-bake. */
        if (a[0] == '-' && a[1]) {
            const char *canon = !strcmp(a, "-o") ? "--out" : !strcmp(a, "-h") ? "--help" : a;
            for (int k = 0; k < nseen; k++)
                if (!strcmp(seen[k], canon)) {
                    fprintf(stderr, "wrt-play: error: %s given twice\n", a);
                    return 0;
                }
            if (nseen < (int)(sizeof seen / sizeof *seen)) seen[nseen++] = canon;
        }
#define NEED() do { if (!v) { fprintf(stderr, "wrt-play: error: %s needs a value\n", a); return 0; } i++; } while (0)
#define INT(lo, hi, dst) do { if (!wrt_cli_int(T, a, v, lo, hi, &n)) return 0; i++; dst = (int)n; } while (0)
#define NUM(lo, hi, dst) do { if (!wrt_cli_num(T, a, v, lo, hi, &x)) return 0; i++; dst = x; } while (0)
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) { usage(stdout); exit(0); }
        else if (!strcmp(a, "--version")) { wrt_cli_version(T); exit(0); }
        else if (!strcmp(a, "--headless")) o->headless = 1;
        else if (!strcmp(a, "--no-overlay")) o->no_overlay = 1;
        else if (!strcmp(a, "--linear-display")) o->linear_display = 1;
        else if (!strcmp(a, "--direct-only")) o->mode = WRT_MODE_DIRECT;
        else if (!strcmp(a, "--indirect-only")) o->mode = WRT_MODE_INDIRECT;
        else if (!strcmp(a, "-o") || !strcmp(a, "--out")) { NEED(); o->out = v; }
        else if (!strcmp(a, "--script")) { NEED(); o->script = v; }
        else if (!strcmp(a, "--out-pattern")) { NEED(); o->pattern = v; }
        else if (!strcmp(a, "--stats-json")) { NEED(); o->stats = v; }
        else if (!strcmp(a, "--screenshot")) { NEED(); o->screenshot = v; }
        else if (!strcmp(a, "--width")) INT(1, 16384, o->width);
        else if (!strcmp(a, "--height")) INT(1, 16384, o->height);
        else if (!strcmp(a, "--bench")) INT(1, 1000000, o->bench);
        else if (!strcmp(a, "--frames")) INT(1, 1000000000, o->frames);
        else if (!strcmp(a, "--threads")) INT(0, 1024, o->threads);
        else if (!strcmp(a, "--max-tex-res")) INT(1, 1024, o->max_tex_res);
        else if (!strcmp(a, "--shadow-res")) INT(16, 8192, o->shadow_res);
        else if (!strcmp(a, "--msaa")) {
            INT(1, 8, o->msaa);
            if (o->msaa & (o->msaa - 1)) { fprintf(stderr, "wrt-play: error: bad value for --msaa: '%s' (1, 2, 4 or 8)\n", v); return 0; }
        }
        else if (!strcmp(a, "--supersample")) INT(1, 4, o->supersample);
        else if (!strcmp(a, "--budget")) NUM(0, 1e6, o->budget_ms);
        else if (!strcmp(a, "--skip-below")) {
            NUM(0, 1, o->skip_below);
            if (o->skip_below >= 1) { fprintf(stderr, "wrt-play: error: bad value for --skip-below: '%s' (0 <= F < 1)\n", v); return 0; }
        }
        else if (!strcmp(a, "--exposure")) { double e; NUM(-64, 64, e); o->exposure = (float)e; }
        else if (!strcmp(a, "--script-fps")) NUM(1e-3, 1e4, o->script_fps);
        else if (!strcmp(a, "--emitter-scale")) { NEED(); if (!parse_emitters(v, o)) return 0; }
        else if (!strcmp(a, "--fov")) { NUM(1, 179, o->fov); o->has_fov = 1; }
        else if (!strcmp(a, "--camera-pos")) { if (!wrt_cli_vec3(T, a, v, o->cam_pos)) return 0; i++; o->has_cam_pos = 1; }
        else if (!strcmp(a, "--camera-target")) { if (!wrt_cli_vec3(T, a, v, o->cam_target)) return 0; i++; o->has_cam_target = 1; }
        else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "wrt-play: error: unknown option %s (see --help)\n", a);
            return 0;
        } else if (!o->file) o->file = a;
        else {
            fprintf(stderr, "wrt-play: error: more than one input file ('%s', '%s')\n", o->file, a);
            return 0;
        }
#undef NEED
#undef INT
#undef NUM
    }
    if (!o->file) { fprintf(stderr, "wrt-play: error: no input file (see --help)\n"); return 0; }
    if (o->has_cam_pos && o->has_cam_target && o->cam_pos[0] == o->cam_target[0] &&
        o->cam_pos[1] == o->cam_target[1] && o->cam_pos[2] == o->cam_target[2]) {
        fprintf(stderr, "wrt-play: error: --camera-pos equals --camera-target: the camera has no view direction\n");
        return 0;
    }
    if (o->script && !o->pattern) { fprintf(stderr, "wrt-play: error: --script needs --out-pattern\n"); return 0; }
    if (o->headless && !o->out && !o->script && !o->stats && !o->bench) {
        fprintf(stderr, "wrt-play: error: --headless needs -o/--out, --script, --stats-json or --bench\n");
        return 0;
    }
    return 1;
}
