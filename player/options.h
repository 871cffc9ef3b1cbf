/* options.h: wrt-play's command line, shared by main.c (which runs it) and options.c
 * (which parses it and prints the usage). Internal to the program. Depends on
 * cli/cli.h (the lights options) and player/render.h (the render modes). */
#ifndef WRT_PLAY_OPTIONS_H
#define WRT_PLAY_OPTIONS_H

#include "../cli/cli.h"
#include "render.h"

typedef struct options {
    const char *file, *out, *script, *pattern, *stats, *screenshot;
    int headless, width, height, bench, frames, threads, max_tex_res, shadow_res, msaa, no_overlay, supersample;
    int linear_display;
    double budget_ms, skip_below;    /* --budget, --skip-below (wrt_runtime_set_budget) */
    wrt_render_mode mode;
    float exposure;
    double script_fps;
    int has_cam_pos, has_cam_target, has_fov;
    double cam_pos[3], cam_target[3], fov;
    wrt_cli_lights lights;
    int nemit;                       /* --emitter-scale M=S[,M=S...] (docs/emitters.md) */
    int emit_mat[16];
    float emit_scale[16];
} options;

/* Parses argv into *o (defaults first); 0 after printing the error on a bad command
 * line. --help and --version print and exit(0). */
int parse_args(int argc, char **argv, options *o);

#endif
