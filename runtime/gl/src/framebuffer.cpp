#include "strata/gl/framebuffer.h"

#include <string>

namespace strata {
namespace gl {

Framebuffer::~Framebuffer()
{
    release();
}

void Framebuffer::release()
{
    const GLuint fbos[] = {fbo_, resolveFbo_};
    const GLuint renderbuffers[] = {color_, depth_, resolveColor_};
    if (fbo_ || resolveFbo_)
        glDeleteFramebuffers(2, fbos);
    if (color_ || depth_ || resolveColor_)
        glDeleteRenderbuffers(3, renderbuffers);
    fbo_ = resolveFbo_ = color_ = depth_ = resolveColor_ = 0;
}

Status Framebuffer::create(int width, int height, int samples)
{
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
        return Status(StatusCode::InvalidArgument, "framebuffer size " + std::to_string(width) + "x" +
                                                       std::to_string(height) + " is out of range");
    release();
    width_ = width;
    height_ = height;
    glCreateRenderbuffers(1, &color_);
    glNamedRenderbufferStorageMultisample(color_, samples, GL_RGBA8, width, height);
    glCreateRenderbuffers(1, &depth_);
    glNamedRenderbufferStorageMultisample(depth_, samples, GL_DEPTH_COMPONENT24, width, height);
    glCreateFramebuffers(1, &fbo_);
    glNamedFramebufferRenderbuffer(fbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_);
    glNamedFramebufferRenderbuffer(fbo_, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_);
    glCreateRenderbuffers(1, &resolveColor_);
    glNamedRenderbufferStorage(resolveColor_, GL_RGBA8, width, height);
    glCreateFramebuffers(1, &resolveFbo_);
    glNamedFramebufferRenderbuffer(resolveFbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, resolveColor_);
    if (glCheckNamedFramebufferStatus(fbo_, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE ||
        glCheckNamedFramebufferStatus(resolveFbo_, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        release();
        return Status(StatusCode::Unsupported, "the offscreen framebuffer is incomplete");
    }
    return Status::ok();
}

void Framebuffer::bind() const
{
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, width_, height_);
}

void Framebuffer::readRGB(std::vector<uint8_t>* rgb)
{
    glBlitNamedFramebuffer(fbo_, resolveFbo_, 0, 0, width_, height_, 0, 0, width_, height_, GL_COLOR_BUFFER_BIT,
                           GL_NEAREST);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, resolveFbo_);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    std::vector<uint8_t> bottomUp(size_t(width_) * size_t(height_) * 3);
    glReadPixels(0, 0, width_, height_, GL_RGB, GL_UNSIGNED_BYTE, bottomUp.data());
    rgb->resize(bottomUp.size());
    const size_t row = size_t(width_) * 3;
    for (int y = 0; y < height_; ++y)
        std::copy(bottomUp.begin() + std::ptrdiff_t(size_t(height_ - 1 - y) * row),
                  bottomUp.begin() + std::ptrdiff_t(size_t(height_ - y) * row),
                  rgb->begin() + std::ptrdiff_t(size_t(y) * row));
}

}  // namespace gl
}  // namespace strata
