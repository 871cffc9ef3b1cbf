/* platform_glfw.c: the window backend of platform.h. A GLFW window (X11) with an
 * OpenGL 4.5 core context, vsync off, key presses queued by GLFW's key callback (as
 * events, so that taps shorter than a frame are kept) and the held keys and mouse
 * motion the player's camera and light controls read. Depends on GLFW 3.3 and wrt_common. */
#include "platform.h"

#include <GLFW/glfw3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct glfw_platform {
    wrt_platform base;
    GLFWwindow *win;
    wrt_key_event queue[WRT_MAX_EVENTS];
    int nqueue;
    unsigned char tapped[WRT_KEY_COUNT]; /* went down since the last poll */
    double mx, my;
    int have_mouse;
} glfw_platform;

static const int key_map[WRT_KEY_COUNT] = {
    [WRT_KEY_W] = GLFW_KEY_W, [WRT_KEY_A] = GLFW_KEY_A, [WRT_KEY_S] = GLFW_KEY_S,
    [WRT_KEY_D] = GLFW_KEY_D, [WRT_KEY_Q] = GLFW_KEY_Q, [WRT_KEY_E] = GLFW_KEY_E,
    [WRT_KEY_UP] = GLFW_KEY_UP, [WRT_KEY_DOWN] = GLFW_KEY_DOWN,
    [WRT_KEY_LEFT] = GLFW_KEY_LEFT, [WRT_KEY_RIGHT] = GLFW_KEY_RIGHT,
    [WRT_KEY_I] = GLFW_KEY_I, [WRT_KEY_J] = GLFW_KEY_J, [WRT_KEY_K] = GLFW_KEY_K,
    [WRT_KEY_L] = GLFW_KEY_L, [WRT_KEY_U] = GLFW_KEY_U, [WRT_KEY_O] = GLFW_KEY_O,
    [WRT_KEY_T] = GLFW_KEY_T, [WRT_KEY_P] = GLFW_KEY_P,
    [WRT_KEY_SHIFT] = GLFW_KEY_LEFT_SHIFT, [WRT_KEY_ESCAPE] = GLFW_KEY_ESCAPE,
    [WRT_KEY_1] = GLFW_KEY_1, [WRT_KEY_2] = GLFW_KEY_2, [WRT_KEY_3] = GLFW_KEY_3,
    [WRT_KEY_4] = GLFW_KEY_4, [WRT_KEY_5] = GLFW_KEY_5, [WRT_KEY_6] = GLFW_KEY_6,
    [WRT_KEY_7] = GLFW_KEY_7, [WRT_KEY_8] = GLFW_KEY_8, [WRT_KEY_9] = GLFW_KEY_9,
    [WRT_KEY_TAB] = GLFW_KEY_TAB, [WRT_KEY_SPACE] = GLFW_KEY_SPACE, [WRT_KEY_PLUS] = GLFW_KEY_EQUAL,
    [WRT_KEY_MINUS] = GLFW_KEY_MINUS, [WRT_KEY_C] = GLFW_KEY_C, [WRT_KEY_R] = GLFW_KEY_R,
    [WRT_KEY_H] = GLFW_KEY_H, [WRT_KEY_LBRACKET] = GLFW_KEY_LEFT_BRACKET,
    [WRT_KEY_RBRACKET] = GLFW_KEY_RIGHT_BRACKET, [WRT_KEY_F1] = GLFW_KEY_F1, [WRT_KEY_F5] = GLFW_KEY_F5,
    [WRT_KEY_F12] = GLFW_KEY_F12,
};

/* GLFW key -> ours (the keypad's + and -, the right Shift, count as the main ones). */
static int our_key(int key) {
    if (key == GLFW_KEY_KP_ADD) return WRT_KEY_PLUS;
    if (key == GLFW_KEY_KP_SUBTRACT) return WRT_KEY_MINUS;
    if (key == GLFW_KEY_RIGHT_SHIFT) return WRT_KEY_SHIFT;
    for (int k = 0; k < WRT_KEY_COUNT; k++)
        if (key_map[k] == key) return k;
    return -1;
}

static void on_key(GLFWwindow *win, int key, int scancode, int action, int mods) {
    (void)scancode;
    glfw_platform *g = glfwGetWindowUserPointer(win);
    int k = our_key(key);
    if (!g || k < 0 || action == GLFW_RELEASE) return;
    if (action == GLFW_PRESS) g->tapped[k] = 1;
    if (g->nqueue < WRT_MAX_EVENTS) {
        wrt_key_event *e = &g->queue[g->nqueue++];
        e->key = k;
        e->shift = (mods & GLFW_MOD_SHIFT) != 0;
        e->repeat = action == GLFW_REPEAT;
    }
}

static void glfw_poll(wrt_platform *p, wrt_input *in) {
    glfw_platform *g = (glfw_platform *)p;
    memset(in, 0, sizeof *in);
    glfwPollEvents();
    memcpy(in->events, g->queue, (size_t)g->nqueue * sizeof *g->queue);
    in->nevents = g->nqueue;
    g->nqueue = 0;
    for (int k = 0; k < WRT_KEY_COUNT; k++) {
        /* a key tapped and released between two polls still moves for one frame */
        in->down[k] = glfwGetKey(g->win, key_map[k]) == GLFW_PRESS || g->tapped[k];
        g->tapped[k] = 0;
    }
    if (glfwGetKey(g->win, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS) in->down[WRT_KEY_SHIFT] = 1;
    double x, y;
    glfwGetCursorPos(g->win, &x, &y);
    if (glfwGetMouseButton(g->win, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
        if (g->have_mouse) { in->mouse_dx = x - g->mx; in->mouse_dy = y - g->my; }
        g->have_mouse = 1;
    } else {
        g->have_mouse = 0;
    }
    g->mx = x;
    g->my = y;
    in->close_requested = glfwWindowShouldClose(g->win);
    glfwGetFramebufferSize(g->win, &p->fb_width, &p->fb_height);
}

static void glfw_wait(wrt_platform *p, double seconds) {
    (void)p;
    glfwWaitEventsTimeout(seconds);
}

static void glfw_swap(wrt_platform *p) { glfwSwapBuffers(((glfw_platform *)p)->win); }

static void glfw_set_title(wrt_platform *p, const char *title) {
    glfwSetWindowTitle(((glfw_platform *)p)->win, title);
}

static void glfw_destroy(wrt_platform *p) {
    glfw_platform *g = (glfw_platform *)p;
    if (g->win) glfwDestroyWindow(g->win);
    glfwTerminate();
    free(g);
}

static char glfw_error_text[256];
static void on_glfw_error(int code, const char *text) {
    snprintf(glfw_error_text, sizeof glfw_error_text, "GLFW error 0x%x: %s", (unsigned)code, text);
}

wrt_status wrt_platform_glfw_create(int width, int height, const char *title, wrt_platform **out) {
    *out = NULL;
    glfw_error_text[0] = 0;
    glfwSetErrorCallback(on_glfw_error);
    if (!glfwInit())
        return wrt_fail(WRT_ERR_GL, "cannot open a window (no X display? set DISPLAY or use --headless): %s",
                        glfw_error_text);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    GLFWwindow *win = glfwCreateWindow(width, height, title, NULL, NULL);
    if (!win) {
        glfwTerminate();
        return wrt_fail(WRT_ERR_GL, "cannot create an OpenGL 4.5 core window: %s", glfw_error_text);
    }
    glfwMakeContextCurrent(win);
    glfwSwapInterval(0);
    glfw_platform *g = wrt_xcalloc(1, sizeof *g);
    g->win = win;
    glfwSetWindowUserPointer(win, g);
    glfwSetKeyCallback(win, on_key);
    g->base.name = "glfw";
    g->base.has_window = 1;
    g->base.poll = glfw_poll;
    g->base.wait = glfw_wait;
    g->base.swap = glfw_swap;
    g->base.set_title = glfw_set_title;
    g->base.destroy = glfw_destroy;
    glfwGetFramebufferSize(win, &g->base.fb_width, &g->base.fb_height);
    *out = &g->base;
    return WRT_OK;
}
