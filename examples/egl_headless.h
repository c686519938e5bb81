/* egl_headless.h - a desktop GL 4.3 core context with no window and no surface, for programs
   that render into textures and read them back (build/gimany-demo). Everything is static.

   Which display: a hardware EGL device (EGL_EXT_platform_device) when a GPU driver offers one,
   else Mesa's surfaceless platform (EGL_MESA_platform_surfaceless: llvmpipe on a machine with
   no GPU and no display server). Mesa's own software device is skipped in the first step, so
   a machine without a GPU always lands on surfaceless.

       egl_headless h;
       char why[256];
       if (!egl_headless_open(&h, why, sizeof why)) { fprintf(stderr, "%s\n", why); return 1; }
       ... GL calls, gim_create(&d, &ctx) with d.get_proc_address = egl_headless_proc ...
       egl_headless_close(&h);
*/
#ifndef GIMANY_EXAMPLES_EGL_HEADLESS_H
#define GIMANY_EXAMPLES_EGL_HEADLESS_H

#include <stdio.h>
#include <string.h>
#include <EGL/egl.h>
#include <EGL/eglext.h>

#if defined(__GNUC__) || defined(__clang__)
#define EGL_HEADLESS_FN static __attribute__((unused))
#else
#define EGL_HEADLESS_FN static
#endif

typedef struct egl_headless {
    EGLDisplay display;
    EGLContext context;
    const char *platform;   /* "device" or "surfaceless" */
} egl_headless;

/* 1 when the space-separated list holds ext as a whole word. */
static int egl_headless_has(const char *list, const char *ext) {
    size_t n = strlen(ext);
    const char *p = list;
    while (p && (p = strstr(p, ext)) != NULL) {
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == 0)) return 1;
        p += n;
    }
    return 0;
}

/* Initialise d and make a 4.3 core context current on it; 1 on success (d terminated on failure). */
static int egl_headless_try(egl_headless *h, EGLDisplay d) {
    static const EGLint ctx_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    static const EGLint cfg_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0, EGL_NONE};
    EGLint major, minor, n = 0;
    EGLConfig cfg = (EGLConfig)0;
    const char *ext;
    if (d == EGL_NO_DISPLAY || !eglInitialize(d, &major, &minor)) return 0;
    ext = eglQueryString(d, EGL_EXTENSIONS);
    /* without EGL_KHR_no_config_context a config is needed even though nothing is drawn to it */
    if (!eglBindAPI(EGL_OPENGL_API) ||
        (!(ext && egl_headless_has(ext, "EGL_KHR_no_config_context")) &&
         (!eglChooseConfig(d, cfg_attribs, &cfg, 1, &n) || n < 1))) {
        eglTerminate(d);
        return 0;
    }
    h->context = eglCreateContext(d, cfg, EGL_NO_CONTEXT, ctx_attribs);
    if (h->context == EGL_NO_CONTEXT) { eglTerminate(d); return 0; }
    if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, h->context)) {
        eglDestroyContext(d, h->context);
        eglTerminate(d);
        return 0;
    }
    h->display = d;
    return 1;
}

/* Opens the context (current on this thread). 0 with one line in why when there is none. */
EGL_HEADLESS_FN int egl_headless_open(egl_headless *h, char *why, size_t why_cap) {
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display;
    const char *client;
    memset(h, 0, sizeof *h);
    client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    get_display = (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!client || !get_display) {
        snprintf(why, why_cap, "EGL has no client extensions (no eglGetPlatformDisplayEXT)");
        return 0;
    }
    if (egl_headless_has(client, "EGL_EXT_platform_device")) {
        PFNEGLQUERYDEVICESEXTPROC query_devices = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
        PFNEGLQUERYDEVICESTRINGEXTPROC query_string =
            (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
        EGLDeviceEXT devices[16];
        EGLint count = 0, i;
        if (query_devices && query_string && query_devices(16, devices, &count)) {
            for (i = 0; i < count; ++i) {
                const char *ext = query_string(devices[i], EGL_EXTENSIONS);
                if (ext && egl_headless_has(ext, "EGL_MESA_device_software")) continue;
                if (egl_headless_try(h, get_display(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL))) {
                    h->platform = "device";
                    return 1;
                }
            }
        }
    }
    if (egl_headless_has(client, "EGL_MESA_platform_surfaceless") &&
        egl_headless_try(h, get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL))) {
        h->platform = "surfaceless";
        return 1;
    }
    snprintf(why, why_cap, "no EGL display gives a desktop GL 4.3 core context (EGL error 0x%x)", (unsigned)eglGetError());
    return 0;
}

/* The loader gimany (and any GL loader) is handed. */
EGL_HEADLESS_FN void (*egl_headless_proc(const char *name))(void) { return (void (*)(void))eglGetProcAddress(name); }

/* Releases the context. The display stays initialised: Mesa 22's llvmpipe leaks in
   eglTerminate once anything was drawn, and the process ends right after anyway. */
EGL_HEADLESS_FN void egl_headless_close(egl_headless *h) {
    if (h->context == EGL_NO_CONTEXT || !h->display) return;
    eglMakeCurrent(h->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(h->display, h->context);
    h->context = EGL_NO_CONTEXT;
}

#endif
