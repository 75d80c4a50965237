#include "strata/gl/context.h"

#include "strata/gl/gl.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstring>
#include <string>

namespace strata {
namespace gl {

namespace {

std::string eglError(const char* what)
{
    char buf[64];
    std::snprintf(buf, sizeof(buf), " (EGL error 0x%04x)", unsigned(eglGetError()));
    return std::string(what) + buf;
}

bool hasExtension(const char* list, const char* name)
{
    if (!list)
        return false;
    const size_t n = std::strlen(name);
    for (const char* p = std::strstr(list, name); p; p = std::strstr(p + n, name))
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0'))
            return true;
    return false;
}

// Surfaceless Mesa (llvmpipe, no X) first, then the first EGL device
// (NVIDIA's headless path), then the default display.
EGLDisplay openDisplay()
{
    const char* clientExtensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    auto getPlatformDisplay =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (getPlatformDisplay && hasExtension(clientExtensions, "EGL_MESA_platform_surfaceless")) {
        EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
        if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr))
            return d;
    }
    auto queryDevices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    if (getPlatformDisplay && queryDevices && hasExtension(clientExtensions, "EGL_EXT_platform_device")) {
        EGLDeviceEXT devices[8];
        EGLint count = 0;
        if (queryDevices(8, devices, &count)) {
            for (EGLint i = 0; i < count; ++i) {
                EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
                if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr))
                    return d;
            }
        }
    }
    EGLDisplay d = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr))
        return d;
    return EGL_NO_DISPLAY;
}

}  // namespace

Status loadGL(void* (*getProcAddress)(const char*))
{
    const int version = gladLoadGL(reinterpret_cast<GLADloadfunc>(getProcAddress));
    if (version == 0)
        return Status(StatusCode::Unsupported, "could not load the OpenGL entry points");
    if (GLAD_VERSION_MAJOR(version) < 4 || (GLAD_VERSION_MAJOR(version) == 4 && GLAD_VERSION_MINOR(version) < 5))
        return Status(StatusCode::Unsupported, "OpenGL 4.5 core is required; the context gives " +
                                                   std::to_string(GLAD_VERSION_MAJOR(version)) + "." +
                                                   std::to_string(GLAD_VERSION_MINOR(version)));
    return Status::ok();
}

Status HeadlessContext::create(std::unique_ptr<HeadlessContext>* out)
{
    EGLDisplay display = openDisplay();
    if (display == EGL_NO_DISPLAY)
        return Status(StatusCode::Unsupported, eglError("no EGL display (install libegl1-mesa / libgl1-mesa-dri)"));
    std::unique_ptr<HeadlessContext> ctx(new HeadlessContext());
    ctx->display_ = display;
    if (!eglBindAPI(EGL_OPENGL_API))
        return Status(StatusCode::Unsupported, eglError("EGL cannot bind desktop OpenGL"));
    const EGLint configAttributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint configCount = 0;
    if (!eglChooseConfig(display, configAttributes, &config, 1, &configCount) || configCount == 0)
        config = nullptr;  // EGL_KHR_no_config_context: surfaceless needs none
    const EGLint contextAttributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                        EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                        EGL_NONE};
    EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, contextAttributes);
    if (context == EGL_NO_CONTEXT)
        return Status(StatusCode::Unsupported, eglError("EGL cannot create an OpenGL 4.5 core context"));
    ctx->context_ = context;
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context))
        return Status(StatusCode::Unsupported, eglError("EGL cannot make a surfaceless context current"));
    if (Status st = loadGL(reinterpret_cast<void* (*)(const char*)>(eglGetProcAddress)); !st.isOk())
        return st;
    *out = std::move(ctx);
    return Status::ok();
}

HeadlessContext::~HeadlessContext()
{
    if (display_) {
        eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        if (context_)
            eglDestroyContext(display_, static_cast<EGLContext>(context_));
        eglTerminate(display_);
    }
}

std::string HeadlessContext::description() const
{
    const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    const auto* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
    return std::string(renderer ? renderer : "?") + ", " + (version ? version : "?");
}

}  // namespace gl
}  // namespace strata
