// Strata GL: an offscreen colour + depth target (multisampled, resolved
// for readback), for headless rendering and screenshots.
#pragma once

#include "strata/gl/gl.h"
#include "strata/status.h"

#include <cstdint>
#include <vector>

namespace strata {
namespace gl {

class Framebuffer {
public:
    Framebuffer() = default;
    ~Framebuffer();
    Framebuffer(const Framebuffer&) = delete;
    Framebuffer& operator=(const Framebuffer&) = delete;

    Status create(int width, int height, int samples = 4);
    void bind() const;
    /// Resolves and reads the colour as RGB8, top row first.
    void readRGB(std::vector<uint8_t>* rgb);

    int width() const { return width_; }
    int height() const { return height_; }

private:
    void release();
    int width_ = 0, height_ = 0;
    GLuint fbo_ = 0, color_ = 0, depth_ = 0, resolveFbo_ = 0, resolveColor_ = 0;
};

}  // namespace gl
}  // namespace strata
