/* platform_egl.c: the headless backend of platform.h. Opens Mesa's surfaceless EGL
 * platform (EGL_MESA_platform_surfaceless via eglGetPlatformDisplayEXT), creates an
 * OpenGL 4.5 core context without a config (EGL_KHR_no_config_context) and makes it
 * current with no surface; the renderer draws into its own framebuffer object. Works
 * without any display or GPU (llvmpipe). Depends on EGL and wrt_common. */
#include "platform.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <stdlib.h>
#include <string.h>

typedef struct egl_platform {
    wrt_platform base;
    EGLDisplay dpy;
    EGLContext ctx;
} egl_platform;

static void egl_poll(wrt_platform *p, wrt_input *in) { (void)p; memset(in, 0, sizeof *in); }
static void egl_swap(wrt_platform *p) { (void)p; }
static void egl_set_title(wrt_platform *p, const char *title) { (void)p; (void)title; }

static void egl_destroy(wrt_platform *p) {
    egl_platform *e = (egl_platform *)p;
    if (e->ctx != EGL_NO_CONTEXT) {
        eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(e->dpy, e->ctx);
    }
    if (e->dpy != EGL_NO_DISPLAY) eglTerminate(e->dpy);
    eglReleaseThread();
    free(e);
}

static int has_ext(const char *list, const char *name) {
    size_t n = strlen(name);
    for (const char *s = list; s && (s = strstr(s, name)); s += n)
        if ((s == list || s[-1] == ' ') && (s[n] == ' ' || s[n] == 0)) return 1;
    return 0;
}

wrt_status wrt_platform_egl_create(wrt_platform **out) {
    *out = NULL;
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!has_ext(client, "EGL_MESA_platform_surfaceless"))
        return wrt_fail(WRT_ERR_GL, "EGL: the surfaceless platform (EGL_MESA_platform_surfaceless) is not available");
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_display) return wrt_fail(WRT_ERR_GL, "EGL: eglGetPlatformDisplayEXT is missing");
    egl_platform *e = wrt_xcalloc(1, sizeof *e);
    e->dpy = EGL_NO_DISPLAY;
    e->ctx = EGL_NO_CONTEXT;
    e->base.name = "egl-surfaceless";
    e->base.poll = egl_poll;
    e->base.swap = egl_swap;
    e->base.set_title = egl_set_title;
    e->base.destroy = egl_destroy;
    e->dpy = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    EGLint major = 0, minor = 0;
    if (e->dpy == EGL_NO_DISPLAY || !eglInitialize(e->dpy, &major, &minor)) {
        e->dpy = EGL_NO_DISPLAY;
        egl_destroy(&e->base);
        return wrt_fail(WRT_ERR_GL, "EGL: cannot initialise the surfaceless display");
    }
    const char *ext = eglQueryString(e->dpy, EGL_EXTENSIONS);
    if (!has_ext(ext, "EGL_KHR_no_config_context") && !has_ext(ext, "EGL_MESA_configless_context")) {
        egl_destroy(&e->base);
        return wrt_fail(WRT_ERR_GL, "EGL %d.%d: no config-less contexts (EGL_KHR_no_config_context)", major, minor);
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        egl_destroy(&e->base);
        return wrt_fail(WRT_ERR_GL, "EGL: desktop OpenGL is not available (eglBindAPI)");
    }
    const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                            EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                            EGL_NONE};
    e->ctx = eglCreateContext(e->dpy, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attrs);
    if (e->ctx == EGL_NO_CONTEXT) {
        EGLint err = eglGetError();
        egl_destroy(&e->base);
        return wrt_fail(WRT_ERR_GL, "EGL: cannot create an OpenGL 4.5 core context (error 0x%x)", (unsigned)err);
    }
    if (!eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, e->ctx)) {
        EGLint err = eglGetError();
        egl_destroy(&e->base);
        return wrt_fail(WRT_ERR_GL, "EGL: cannot make the context current (error 0x%x)", (unsigned)err);
    }
    *out = &e->base;
    return WRT_OK;
}
