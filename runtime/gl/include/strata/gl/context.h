// Strata GL: a headless OpenGL 4.5 core context through EGL, for tests,
// benchmarks and screenshots without a display.  Mesa's surfaceless
// platform first (llvmpipe in CI), then an EGL device (NVIDIA), then the
// default display.  Render into your own framebuffer (framebuffer.h).
#pragma once

#include "strata/status.h"

#include <memory>
#include <string>

namespace strata {
namespace gl {

class HeadlessContext {
public:
    /// Creates the context, makes it current on this thread and loads GL.
    static Status create(std::unique_ptr<HeadlessContext>* out);
    ~HeadlessContext();
    HeadlessContext(const HeadlessContext&) = delete;
    HeadlessContext& operator=(const HeadlessContext&) = delete;

    /// GL_RENDERER and GL_VERSION, e.g. "llvmpipe (LLVM 15.0.6, 256 bits), 4.5 (Core Profile) Mesa 22.3.6".
    std::string description() const;

private:
    HeadlessContext() = default;
    void* display_ = nullptr;
    void* context_ = nullptr;
};

/// Loads the GL entry points through a window system's getProcAddress
/// (e.g. glfwGetProcAddress) for a context current on this thread, and
/// checks for 4.5 core.
Status loadGL(void* (*getProcAddress)(const char*));

}  // namespace gl
}  // namespace strata
