/* play.h: what wrt-play's main.c (the application, its window, main) shares with
 * headless.c (the scripted frames and the benchmark): the exit codes, the application
 * state, one frame's stage times and the functions headless.c calls back. Internal to
 * the program. Depends on cli/cli.h, include/wrt.h (the runtime: the player opens,
 * reads and relights the .gto through it alone), player/platform.h, player/render.h
 * and player/options.h. */
#ifndef WRT_PLAY_PLAY_H
#define WRT_PLAY_PLAY_H

#include <sys/stat.h>

#include "../cli/cli.h"
#include "../include/wrt.h"
#include "platform.h"
#include "render.h"
#include "options.h"

/* The exit codes of every tool (cli/cli.h). */
enum {
    EXIT_USAGE = WRT_EXIT_USAGE,      /* bad command line, a light the file does not have */
    EXIT_INPUT = WRT_EXIT_INPUT,      /* the .gto (or script) cannot be read: missing, truncated, corrupt, foreign, newer */
    EXIT_OUTPUT = WRT_EXIT_OUTPUT,    /* an output file cannot be written */
    EXIT_GL = WRT_EXIT_GL,            /* no OpenGL 4.5 context, no window, shader or framebuffer failure */
    EXIT_RUNTIME = WRT_EXIT_INTERNAL  /* the relighting core failed */
};

typedef struct stage_ms {
    double projection, multiply, brdf, synthesis, upload, draw, frame;
    int relit; /* the frame relit (a light or the eye moved) */
} stage_ms;

typedef struct app {
    options *o;
    wrt_runtime_file_info info; /* what the open file holds (wrt_runtime_get_file_info) */
    int nquads;
    struct stat gto_st;  /* the file as it was before it was read: a change is noticed in the window */
    wrt_platform *plat;
    wrt_runtime *rl;
    struct wrt_play_geom *geom; /* the quads for the default camera and the lights' walls (view.h) */
    wrt_render *rd;
    wrt_runtime_light *lights; /* the API's light struct, which goes to the runtime unchanged */
    int nlights;
    float scales[WRT_RENDER_MAX_LIGHTS];
    wrt_view view;
    wrt_render_mode mode;
    int relit_once;
} app;

/* A light's position and direction as vectors (wrt_runtime_light keeps arrays). */
static inline wrt_v3 light_pos(const wrt_runtime_light *l) { return v3(l->position[0], l->position[1], l->position[2]); }
static inline wrt_v3 light_dir(const wrt_runtime_light *l) { return v3(l->direction[0], l->direction[1], l->direction[2]); }
static inline void light_set_pos(wrt_runtime_light *l, wrt_v3 p) { l->position[0] = p.x; l->position[1] = p.y; l->position[2] = p.z; }
static inline void light_set_dir(wrt_runtime_light *l, wrt_v3 d) { l->direction[0] = d.x; l->direction[1] = d.y; l->direction[2] = d.z; }

/* main.c */
int run_frame(app *a, stage_ms *t);            /* one frame: relight what changed, upload, draw */
int save_picture(app *a, const char *path);    /* the headless picture to a file */
void scene_up(const app *a, wrt_v3 *up);       /* the view's up direction */
int chosen_light(const app *a);                /* the light --light names (0-based) */
void scene_bounds(const app *a, double lo[3], double hi[3]); /* the quads' box (-1..1 without quads) */

/* headless.c */
int run_script(app *a);  /* --script: one picture per frame of the keyframed sequence */
int run_bench(app *a);   /* --bench: frame times */

#endif
