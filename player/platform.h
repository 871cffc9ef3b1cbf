/* platform.h: where the player's OpenGL 4.5 core context comes from, behind one small
 * interface with two sibling backends: platform_egl.c (headless: EGL on Mesa's
 * surfaceless platform, a context without a config, no default framebuffer: render
 * into an FBO) and platform_glfw.c (a GLFW window on X11 with keyboard and mouse).
 * render.c only needs a current context. Depends on wrt_common.h. Not thread-safe:
 * the context is current on the thread that created it. */
#ifndef WRT_PLATFORM_H
#define WRT_PLATFORM_H

#include "../common/wrt_common.h"

/* The keys the player reacts to (window backend only). */
enum {
    WRT_KEY_W, WRT_KEY_A, WRT_KEY_S, WRT_KEY_D, WRT_KEY_Q, WRT_KEY_E,
    WRT_KEY_UP, WRT_KEY_DOWN, WRT_KEY_LEFT, WRT_KEY_RIGHT,
    WRT_KEY_I, WRT_KEY_J, WRT_KEY_K, WRT_KEY_L, WRT_KEY_U, WRT_KEY_O,
    WRT_KEY_T, WRT_KEY_P, WRT_KEY_SHIFT, WRT_KEY_ESCAPE,
    WRT_KEY_1, WRT_KEY_2, WRT_KEY_3, WRT_KEY_4, WRT_KEY_5, WRT_KEY_6, WRT_KEY_7,
    WRT_KEY_8, WRT_KEY_9,
    WRT_KEY_TAB, WRT_KEY_SPACE, WRT_KEY_PLUS, WRT_KEY_MINUS, WRT_KEY_C, WRT_KEY_R, WRT_KEY_H,
    WRT_KEY_LBRACKET, WRT_KEY_RBRACKET, WRT_KEY_F1, WRT_KEY_F5, WRT_KEY_F12,
    WRT_KEY_COUNT
};

#define WRT_MAX_EVENTS 128

/* One key going down (or repeating while held), in the order they came. */
typedef struct wrt_key_event {
    int key;    /* WRT_KEY_* */
    int shift;  /* a Shift key was held */
    int repeat; /* auto-repeat of a held key */
} wrt_key_event;

/* What happened since the previous poll. Key presses are events (delivered by the
 * window system's callback, so a tap shorter than a frame is never lost); `down` is the
 * state of held keys for continuous motion. */
typedef struct wrt_input {
    unsigned char down[WRT_KEY_COUNT];    /* key held now, or pressed since the last poll */
    wrt_key_event events[WRT_MAX_EVENTS]; /* presses since the last poll, oldest first */
    int nevents;
    double mouse_dx, mouse_dy;            /* cursor motion in pixels while the left button is held */
    int close_requested;                  /* window closed by the user */
} wrt_input;

typedef struct wrt_platform wrt_platform;
struct wrt_platform {
    const char *name;        /* "egl-surfaceless" or "glfw" */
    int has_window;          /* 0: no default framebuffer, render into an FBO */
    int fb_width, fb_height; /* the window's framebuffer size (0 for headless) */
    void (*poll)(wrt_platform *p, wrt_input *in);
    void (*wait)(wrt_platform *p, double seconds); /* sleep until an event or the time; may be NULL */
    void (*swap)(wrt_platform *p);
    void (*set_title)(wrt_platform *p, const char *title);
    void (*destroy)(wrt_platform *p);
};

/* Headless context. Errors: WRT_ERR_GL with a message naming the failing EGL step. */
wrt_status wrt_platform_egl_create(wrt_platform **out);
/* A window of width x height with vsync off. Errors: WRT_ERR_GL (no display, no 4.5 core). */
wrt_status wrt_platform_glfw_create(int width, int height, const char *title, wrt_platform **out);

static inline void wrt_platform_destroy(wrt_platform *p) { if (p) p->destroy(p); }

#endif
