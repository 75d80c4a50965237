#include "strata/gl/gpu_surface.h"

#include "strata/gl/shaders.h"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <chrono>
#include <string>

namespace strata {
namespace gl {

namespace embedded {
extern const char* const surfaceVert;
extern const char* const surfaceFrag;
extern const char* const linesVert;
extern const char* const linesFrag;
}  // namespace embedded

std::string linesShaderSource(GLenum stage)
{
    return std::string("#version 450 core\n") + (stage == GL_VERTEX_SHADER ? embedded::linesVert : embedded::linesFrag);
}

namespace {

// Binding points of the draw pass's own buffers (surface.vert.glsl).
constexpr GLuint kErrors = 12, kCornerUVs = 14, kCornerColours = 15, kCornerUVs2 = 16;

}  // namespace

Status GpuSurface::create(std::unique_ptr<GpuSurface>* out, const Plan& plan, bool shadingNormals)
{
    std::unique_ptr<GpuSurface> s(new GpuSurface());
    Status st = Evaluator::create(&s->evaluator_, plan, shadingNormals);
    if (!st)
        return st;
    const std::string vertex = samplingPrelude() + embedded::surfaceVert;
    const std::string fragment = std::string("#version 450 core\n") + embedded::surfaceFrag;
    if (!(st = buildProgram(&s->surface_, "surface", {{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, fragment}})) ||
        !(st = buildProgram(&s->feedbackProgram_, "surface.vert (transform feedback)", {{GL_VERTEX_SHADER, vertex}},
                            {"v_position"})))
        return st;
    const size_t nv = plan.refinedVertexCount();
    glCreateBuffers(1, &s->errors_);
    glNamedBufferStorage(s->errors_, GLsizeiptr(std::max<size_t>(nv, 4) * 4), nullptr, GL_DYNAMIC_STORAGE_BIT);
    glCreateBuffers(1, &s->feedback_);
    glNamedBufferStorage(s->feedback_, GLsizeiptr(std::max<size_t>(nv, 1) * 12), nullptr, 0);
    s->ownBytes_ = std::max<size_t>(nv, 4) * 4 + std::max<size_t>(nv, 1) * 12;
    const Evaluator& e = *s->evaluator_;
    glCreateVertexArrays(1, &s->vao_);
    glVertexArrayVertexBuffer(s->vao_, 0, e.buffer(kSampleUVs), 0, 8);
    glVertexArrayAttribFormat(s->vao_, 0, 2, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(s->vao_, 0, 0);
    glEnableVertexArrayAttrib(s->vao_, 0);
    glVertexArrayVertexBuffer(s->vao_, 1, s->errors_, 0, 4);
    glVertexArrayAttribFormat(s->vao_, 1, 1, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(s->vao_, 1, 1);
    glVertexArrayElementBuffer(s->vao_, e.buffer(kTriangles));
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL reported an error while setting up the draw pass");
    *out = std::move(s);
    return Status::ok();
}

GpuSurface::~GpuSurface()
{
    for (GLuint b : {errors_, feedback_, cornerUVs_, cornerColours_, cornerUVs2_, triangleLevels_, adaptiveCornerUVs_,
                     adaptiveCornerColours_, adaptiveCornerUVs2_})
        if (b)
            glDeleteBuffers(1, &b);
    glDeleteVertexArrays(1, &vao_);
    glDeleteVertexArrays(1, &adaptiveVao_);
    if (adaptiveProgram_)
        glDeleteProgram(adaptiveProgram_);
    glDeleteVertexArrays(1, &cornerVao_);
    deleteMaterialTextures();
    for (GLuint p : {surface_, feedbackProgram_})
        glDeleteProgram(p);
    glDeleteFramebuffers(1, &feedbackTarget_);
    glDeleteRenderbuffers(1, &feedbackColor_);
}

void GpuSurface::deleteMaterialTextures()
{
    for (GpuMaterial& m : materials_)
        for (GLuint* t : {&m.texture, &m.emissiveTexture, &m.metallicRoughnessTexture, &m.occlusionTexture,
                          &m.normalTexture})
            glDeleteTextures(1, t);
}

void GpuSurface::setTiming(bool on)
{
    timing_ = on;
    evaluator_->setTiming(on);
}

void GpuSurface::setVertexErrors(const float* errors)
{
    haveErrors_ = errors != nullptr;
    if (errors)
        glNamedBufferSubData(errors_, 0, GLsizeiptr(vertexCount() * 4), errors);
    if (haveErrors_)
        glEnableVertexArrayAttrib(vao_, 1);
    else
        glDisableVertexArrayAttrib(vao_, 1);
}

namespace {

// Whether every range lies within `faces` faces and names one of `materials`.
bool rangesFit(const std::vector<MaterialRange>& ranges, size_t faces, size_t materials)
{
    for (const MaterialRange& r : ranges)
        if (r.material < 0 || size_t(r.material) >= materials || r.firstFace > faces || r.faceCount > faces - r.firstFace)
            return false;
    return true;
}

}  // namespace

Status GpuSurface::setMaterials(const std::vector<SurfaceMaterial>& materials, const std::vector<MaterialRange>& ranges,
                                const std::vector<glm::vec2>& cornerUVs, const std::vector<glm::vec4>& cornerColours,
                                const std::vector<glm::vec2>& cornerUVs2)
{
    const size_t faceCount_ = faceCount();
    if (cornerUVs.size() != 3 * faceCount_ || (!cornerColours.empty() && cornerColours.size() != cornerUVs.size()) ||
        (!cornerUVs2.empty() && cornerUVs2.size() != cornerUVs.size()))
        return Status(StatusCode::InvalidArgument, "setMaterials: " + std::to_string(cornerUVs.size()) +
                                                       " corner UVs, " + std::to_string(cornerColours.size()) +
                                                       " corner colours and " + std::to_string(cornerUVs2.size()) +
                                                       " second UVs for " + std::to_string(faceCount_) + " faces");
    if (!rangesFit(ranges, faceCount_, materials.size()))
        return Status(StatusCode::InvalidArgument, "setMaterials: a face range is out of bounds");
    deleteMaterialTextures();
    materials_.clear();
    // Base colour and emissive textures are sRGB-coded (read linear by the
    // sampler); metallic-roughness and occlusion are linear already.  Each
    // through its UV channel's wraps.
    const auto texture = [](const SurfaceMaterial& in, const SurfaceTexture& tex, bool srgb) {
        GLuint t = 0;
        if (!tex.rgba || tex.width <= 0 || tex.height <= 0)
            return t;
        glCreateTextures(GL_TEXTURE_2D, 1, &t);
        int levels = 1;
        while ((std::max(tex.width, tex.height) >> levels) > 0)
            ++levels;
        glTextureStorage2D(t, levels, srgb ? GL_SRGB8_ALPHA8 : GL_RGBA8, tex.width, tex.height);
        glTextureSubImage2D(t, 0, 0, 0, tex.width, tex.height, GL_RGBA, GL_UNSIGNED_BYTE, tex.rgba);
        glGenerateTextureMipmap(t);
        glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
        glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTextureParameteri(t, GL_TEXTURE_WRAP_S, tex.second ? in.secondWrapS : in.wrapS);
        glTextureParameteri(t, GL_TEXTURE_WRAP_T, tex.second ? in.secondWrapT : in.wrapT);
        return t;
    };
    for (const SurfaceMaterial& in : materials) {
        GpuMaterial m;
        m.material = in;
        m.texture = texture(in, in.baseColorTexture, true);
        m.emissiveTexture = texture(in, in.emissiveTexture, true);
        m.metallicRoughnessTexture = texture(in, in.metallicRoughnessTexture, false);
        m.occlusionTexture = texture(in, in.occlusionTexture, false);
        m.normalTexture = texture(in, in.normalTexture, false);
        for (SurfaceTexture* t : {&m.material.baseColorTexture, &m.material.emissiveTexture,
                                  &m.material.metallicRoughnessTexture, &m.material.occlusionTexture,
                                  &m.material.normalTexture})
            t->rgba = nullptr;
        materials_.push_back(m);
    }
    ranges_ = ranges;
    sortBlendedLast(&ranges_);
    adaptiveRanges_.clear();
    if (cornerUVs_)
        glDeleteBuffers(1, &cornerUVs_);
    glCreateBuffers(1, &cornerUVs_);
    glNamedBufferStorage(cornerUVs_, GLsizeiptr(std::max<size_t>(cornerUVs.size(), 1) * sizeof(glm::vec2)),
                         cornerUVs.empty() ? nullptr : cornerUVs.data(), 0);
    // Optional per-corner data: a buffer where given, else none.
    const auto optional = [](GLuint* buffer, const void* data, size_t bytes) {
        if (*buffer)
            glDeleteBuffers(1, buffer);
        *buffer = 0;
        if (bytes) {
            glCreateBuffers(1, buffer);
            glNamedBufferStorage(*buffer, GLsizeiptr(bytes), data, 0);
        }
    };
    optional(&cornerColours_, cornerColours.data(), cornerColours.size() * sizeof(glm::vec4));
    optional(&cornerUVs2_, cornerUVs2.data(), cornerUVs2.size() * sizeof(glm::vec2));
    if (!cornerVao_)
        glCreateVertexArrays(1, &cornerVao_);  // no attributes: the shader reads buffers by corner
    return Status::ok();
}

// `bytes` of `data` into *buffer, grown (by a quarter more) when it holds less.
void GpuSurface::upload(GLuint* buffer, size_t* capacity, const void* data, size_t bytes)
{
    const size_t need = std::max<size_t>(bytes, 4);
    if (*capacity < need) {
        if (*buffer)
            glDeleteBuffers(1, buffer);
        ownBytes_ = ownBytes_ - *capacity + need + need / 4;
        *capacity = need + need / 4;
        glCreateBuffers(1, buffer);
        glNamedBufferStorage(*buffer, GLsizeiptr(*capacity), nullptr, GL_DYNAMIC_STORAGE_BIT);
    }
    if (bytes)
        glNamedBufferSubData(*buffer, 0, GLsizeiptr(bytes), data);
}

// Blended ranges last (drawn without depth writes).
void GpuSurface::sortBlendedLast(std::vector<MaterialRange>* ranges) const
{
    std::stable_sort(ranges->begin(), ranges->end(), [&](const MaterialRange& a, const MaterialRange& b) {
        return (materials_[size_t(a.material)].material.alphaMode == 2) <
               (materials_[size_t(b.material)].material.alphaMode == 2);
    });
}

Status GpuSurface::setAdaptiveMaterials(const std::vector<MaterialRange>& ranges, const std::vector<glm::vec2>& cornerUVs,
                                        const std::vector<glm::vec4>& cornerColours,
                                        const std::vector<glm::vec2>& cornerUVs2)
{
    const size_t triangles = evaluator_->adaptiveTriangleCount();
    if (cornerUVs.size() != 3 * triangles || (!cornerColours.empty() && cornerColours.size() != cornerUVs.size()) ||
        (!cornerUVs2.empty() && cornerUVs2.size() != cornerUVs.size()))
        return Status(StatusCode::InvalidArgument, "setAdaptiveMaterials: " + std::to_string(cornerUVs.size()) +
                                                       " corner UVs, " + std::to_string(cornerColours.size()) +
                                                       " corner colours and " + std::to_string(cornerUVs2.size()) +
                                                       " second UVs for " + std::to_string(triangles) + " triangles");
    if (!rangesFit(ranges, triangles, materials_.size()))
        return Status(StatusCode::InvalidArgument, "setAdaptiveMaterials: a triangle range is out of bounds");
    upload(&adaptiveCornerUVs_, &adaptiveCornerUVsCapacity_, cornerUVs.data(), cornerUVs.size() * sizeof(glm::vec2));
    adaptiveHasColours_ = !cornerColours.empty();
    if (adaptiveHasColours_)
        upload(&adaptiveCornerColours_, &adaptiveCornerColoursCapacity_, cornerColours.data(),
               cornerColours.size() * sizeof(glm::vec4));
    adaptiveHasUVs2_ = !cornerUVs2.empty();
    if (adaptiveHasUVs2_)
        upload(&adaptiveCornerUVs2_, &adaptiveCornerUVs2Capacity_, cornerUVs2.data(),
               cornerUVs2.size() * sizeof(glm::vec2));
    adaptiveRanges_ = ranges;
    sortBlendedLast(&adaptiveRanges_);
    return Status::ok();
}

// The shaded view with materials: corner-ordered draws (gl_VertexID is a
// corner of `triangles`), one per range.
void GpuSurface::drawMaterials(GLuint prog, const std::vector<MaterialRange>& ranges, GLuint triangles, GLuint cornerUVs,
                               GLuint cornerColours, GLuint cornerUVs2, GLuint vao)
{
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kCornerUVs2, cornerUVs2 ? cornerUVs2 : cornerUVs);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kCornerColours, cornerColours);
    glUniform1i(glGetUniformLocation(prog, "u_hasColours"), cornerColours ? 1 : 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kSampleUVs, evaluator_->buffer(kSampleUVs));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kTriangles, triangles);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kErrors, errors_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kCornerUVs, cornerUVs);
    glUniform1i(glGetUniformLocation(prog, "u_corners"), 1);
    glUniform1i(glGetUniformLocation(prog, "u_baseColorTexture"), 1);
    glUniform1i(glGetUniformLocation(prog, "u_emissiveTexture"), 2);
    glUniform1i(glGetUniformLocation(prog, "u_metallicRoughnessTexture"), 3);
    glUniform1i(glGetUniformLocation(prog, "u_occlusionTexture"), 4);
    glUniform1i(glGetUniformLocation(prog, "u_normalTexture"), 5);
    glUniform1i(glGetUniformLocation(prog, "u_hasSecondUVs"), cornerUVs2 ? 1 : 0);
    glBindVertexArray(vao);
    bool blending = false;
    for (const MaterialRange& r : ranges) {
        const GpuMaterial& m = materials_[size_t(r.material)];
        const bool blend = m.material.alphaMode == 2;
        if (blend && !blending) {
            glEnable(GL_BLEND);
            glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
            glDepthMask(GL_FALSE);
            blending = true;
        }
        glUniform1i(glGetUniformLocation(prog, "u_material"), 1);
        glUniform4fv(glGetUniformLocation(prog, "u_materialColor"), 1, glm::value_ptr(m.material.baseColor));
        glUniform1i(glGetUniformLocation(prog, "u_hasTexture"), m.texture ? 1 : 0);
        glUniform1i(glGetUniformLocation(prog, "u_alphaMode"), m.material.alphaMode);
        glUniform3fv(glGetUniformLocation(prog, "u_emissive"), 1, glm::value_ptr(m.material.emissive));
        glUniform1i(glGetUniformLocation(prog, "u_hasEmissiveTexture"), m.emissiveTexture ? 1 : 0);
        glUniform1i(glGetUniformLocation(prog, "u_emissiveSecond"), m.material.emissiveTexture.second ? 1 : 0);
        glUniform1f(glGetUniformLocation(prog, "u_metallic"), m.material.metallic);
        glUniform1f(glGetUniformLocation(prog, "u_roughness"), m.material.roughness);
        glUniform1i(glGetUniformLocation(prog, "u_hasMetallicRoughnessTexture"), m.metallicRoughnessTexture ? 1 : 0);
        glUniform1i(glGetUniformLocation(prog, "u_metallicRoughnessSecond"),
                    m.material.metallicRoughnessTexture.second ? 1 : 0);
        glBindTextureUnit(3, m.metallicRoughnessTexture);
        glUniform1i(glGetUniformLocation(prog, "u_hasOcclusionTexture"), m.occlusionTexture ? 1 : 0);
        glUniform1i(glGetUniformLocation(prog, "u_occlusionSecond"), m.material.occlusionTexture.second ? 1 : 0);
        glUniform1f(glGetUniformLocation(prog, "u_occlusionStrength"), m.material.occlusionStrength);
        glBindTextureUnit(4, m.occlusionTexture);
        glUniform1i(glGetUniformLocation(prog, "u_hasNormalTexture"), m.normalTexture ? 1 : 0);
        glUniform1i(glGetUniformLocation(prog, "u_normalSecond"), m.material.normalTexture.second ? 1 : 0);
        glUniform1f(glGetUniformLocation(prog, "u_normalScale"), m.material.normalScale);
        glBindTextureUnit(5, m.normalTexture);
        glBindTextureUnit(2, m.emissiveTexture);
        glUniform1i(glGetUniformLocation(prog, "u_flatShading"), r.flat ? 1 : 0);
        glUniform1f(glGetUniformLocation(prog, "u_alphaCutoff"), m.material.alphaCutoff);
        glBindTextureUnit(1, m.texture);
        glDrawArrays(GL_TRIANGLES, GLint(3 * r.firstFace), GLsizei(3 * r.faceCount));
    }
    if (blending) {
        glDisable(GL_BLEND);
        glDepthMask(GL_TRUE);
    }
    for (GLuint unit = 1; unit <= 5; ++unit)
        glBindTextureUnit(unit, 0);
    glUniform1i(glGetUniformLocation(prog, "u_material"), 0);
    glUniform1i(glGetUniformLocation(prog, "u_corners"), 0);
    glUniform1i(glGetUniformLocation(prog, "u_hasColours"), 0);
}

void GpuSurface::setDrawUniforms(GLuint prog, const DrawParams& p, ColorMode mode) const
{
    glUniformMatrix4fv(glGetUniformLocation(prog, "u_viewProjection"), 1, GL_FALSE, glm::value_ptr(p.viewProjection));
    glUniform1i(glGetUniformLocation(prog, "u_haveNormals"), evaluator_->shadingNormals() ? 1 : 0);
    glUniform3fv(glGetUniformLocation(prog, "u_eye"), 1, glm::value_ptr(p.eye));
    glUniform2fv(glGetUniformLocation(prog, "u_colorRange"), 1, glm::value_ptr(p.colorRange));
    glUniform3fv(glGetUniformLocation(prog, "u_baseColor"), 1, glm::value_ptr(p.baseColor));
    glUniform1i(glGetUniformLocation(prog, "u_colorMode"), int(mode));
    glUniform1i(glGetUniformLocation(prog, "u_flatShading"), p.flatShading ? 1 : 0);
    glUniform1i(glGetUniformLocation(prog, "u_corners"), 0);
    glUniform1i(glGetUniformLocation(prog, "u_material"), 0);
}

void GpuSurface::beginWireframe(const DrawParams& p)
{
    if (p.wireframe) {  // the surface behind its edges
        glEnable(GL_POLYGON_OFFSET_FILL);
        glPolygonOffset(1.0f, 1.0f);
    }
}

template <typename Draw>
void GpuSurface::endWireframe(const DrawParams& p, GLuint prog, const Draw& draw)
{
    if (!p.wireframe)
        return;
    glDisable(GL_POLYGON_OFFSET_FILL);
    glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    glUniform1i(glGetUniformLocation(prog, "u_colorMode"), int(ColorMode::Flat));
    glUniform3f(glGetUniformLocation(prog, "u_baseColor"), 0.12f, 0.12f, 0.14f);
    draw();
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
}

Status GpuSurface::setAdaptive(const AdaptiveFrame& frame)
{
    if (!adaptiveProgram_) {
        const std::string defines = "#define STRATA_ADAPTIVE_DRAW 1\n";
        const std::string vertex = samplingPrelude(defines) + embedded::surfaceVert;
        const std::string fragment = std::string("#version 450 core\n") + defines + embedded::surfaceFrag;
        if (Status st = buildProgram(&adaptiveProgram_, "surface (adaptive)",
                                     {{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, fragment}});
            !st)
            return st;
        glCreateVertexArrays(1, &adaptiveVao_);
    }
    if (Status st = evaluator_->setAdaptive(frame); !st)
        return st;
    adaptiveRanges_.clear();
    // Each triangle's level (its quarter's), for the false colour.
    std::vector<float> levels(frame.triangleCount());
    for (size_t t = 0; t < levels.size(); ++t)
        levels[t] = float(frame.triangleLevel(t));
    upload(&triangleLevels_, &triangleLevelsCapacity_, levels.data(), levels.size() * sizeof(float));
    glVertexArrayElementBuffer(adaptiveVao_, evaluator_->adaptiveBuffer(AdaptiveBuffer::Triangles));
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL reported an error while setting up the adaptive draw");
    return Status::ok();
}

void GpuSurface::takeTimings()
{
    if (!timing_)
        return;
    const EvaluatorTimings& t = evaluator_->timings();
    timings_.uploadMs = t.uploadMs;
    timings_.stencilMs = t.stencilMs;
    timings_.normalsMs = t.normalsMs;
}

Status GpuSurface::updateAdaptive(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count)
{
    Status st = evaluator_->updateAdaptive(controlPositions, controlNormals, count);
    if (st)
        takeTimings();
    return st;
}

void GpuSurface::drawAdaptive(const DrawParams& p)
{
    if (!adaptiveProgram_ || !evaluator_->adaptiveBuffer(AdaptiveBuffer::Indirect))
        return;
    std::chrono::steady_clock::time_point start;
    if (timing_) {
        glFinish();
        start = std::chrono::steady_clock::now();
    }
    const GLuint prog = adaptiveProgram_;
    evaluator_->bindSampling(prog);
    glUseProgram(prog);
    Evaluator& e = *evaluator_;
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kDisplaced, e.adaptiveBuffer(AdaptiveBuffer::Displaced));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kNormals, e.adaptiveBuffer(AdaptiveBuffer::Normals));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kFrameVertices, e.adaptiveBuffer(AdaptiveBuffer::FrameVertices));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kSampleUVs, e.buffer(kSampleUVs));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kErrors, triangleLevels_);
    setDrawUniforms(prog, p, p.colorMode);
    glBindVertexArray(adaptiveVao_);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, e.adaptiveBuffer(AdaptiveBuffer::Indirect));
    const auto drawAll = [] { glDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, nullptr); };
    beginWireframe(p);
    if (p.colorMode == ColorMode::Shaded && !adaptiveRanges_.empty()) {
        drawMaterials(prog, adaptiveRanges_, e.adaptiveBuffer(AdaptiveBuffer::Triangles), adaptiveCornerUVs_,
                      adaptiveHasColours_ ? adaptiveCornerColours_ : 0, adaptiveHasUVs2_ ? adaptiveCornerUVs2_ : 0,
                      adaptiveVao_);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kErrors, triangleLevels_);
        glBindVertexArray(adaptiveVao_);
    } else {
        drawAll();
    }
    endWireframe(p, prog, drawAll);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
    glBindVertexArray(0);
    glUseProgram(0);
    if (timing_) {
        glFinish();
        timings_.drawMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    }
}

Status GpuSurface::update(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count)
{
    Status st = evaluator_->update(controlPositions, controlNormals, count);
    if (st)
        takeTimings();
    return st;
}

void GpuSurface::draw(const DrawParams& p)
{
    std::chrono::steady_clock::time_point start;
    if (timing_) {
        glFinish();  // timed as the evaluator's stages are
        start = std::chrono::steady_clock::now();
    }
    evaluator_->bindSampling(surface_);
    const GLuint prog = surface_;
    const size_t faceCount_ = faceCount();
    glUseProgram(prog);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kSurface, evaluator_->buffer(kSurface));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kNormals, evaluator_->buffer(kNormals));
    const ColorMode mode = p.colorMode == ColorMode::Error && !haveErrors_ ? ColorMode::Shaded : p.colorMode;
    setDrawUniforms(prog, p, mode);
    if (!haveErrors_)
        glVertexAttrib1f(1, 0.0f);
    const auto drawAll = [&] { glDrawElements(GL_TRIANGLES, GLsizei(3 * faceCount_), GL_UNSIGNED_INT, nullptr); };
    beginWireframe(p);
    if (mode == ColorMode::Shaded && !materials_.empty()) {
        drawMaterials(prog, ranges_, evaluator_->buffer(kTriangles), cornerUVs_, cornerColours_, cornerUVs2_,
                      cornerVao_);
    } else {
        glBindVertexArray(vao_);
        drawAll();
    }
    glBindVertexArray(vao_);
    endWireframe(p, prog, drawAll);
    glBindVertexArray(0);
    glUseProgram(0);
    if (timing_) {
        glFinish();
        timings_.drawMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    }
}

Status GpuSurface::readPositions(std::vector<glm::vec3>* out)
{
    while (glGetError() != GL_NO_ERROR) {
    }
    // A draw needs a complete framebuffer even with rasterisation discarded;
    // a surfaceless context has no default one.
    GLint previous = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
    if (!feedbackTarget_) {
        glCreateRenderbuffers(1, &feedbackColor_);
        glNamedRenderbufferStorage(feedbackColor_, GL_RGBA8, 1, 1);
        glCreateFramebuffers(1, &feedbackTarget_);
        glNamedFramebufferRenderbuffer(feedbackTarget_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, feedbackColor_);
    }
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, feedbackTarget_);
    const size_t vertexCount_ = vertexCount();
    evaluator_->bindSampling(feedbackProgram_);
    glUseProgram(feedbackProgram_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kSurface, evaluator_->buffer(kSurface));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kNormals, evaluator_->buffer(kNormals));
    glUniform1i(glGetUniformLocation(feedbackProgram_, "u_haveNormals"), 0);
    glUniformMatrix4fv(glGetUniformLocation(feedbackProgram_, "u_viewProjection"), 1, GL_FALSE,
                       glm::value_ptr(glm::mat4(1.0f)));
    glBindVertexArray(vao_);
    if (!haveErrors_)
        glVertexAttrib1f(1, 0.0f);
    glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, feedback_);
    glEnable(GL_RASTERIZER_DISCARD);
    glBeginTransformFeedback(GL_POINTS);
    glDrawArrays(GL_POINTS, 0, GLsizei(vertexCount_));
    glEndTransformFeedback();
    glDisable(GL_RASTERIZER_DISCARD);
    glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, 0);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(previous));
    glBindVertexArray(0);
    glUseProgram(0);
    out->resize(vertexCount_);
    glGetNamedBufferSubData(feedback_, 0, GLsizeiptr(vertexCount_ * 12), out->data());
    if (const GLenum e = glGetError(); e != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL error " + std::to_string(e) +
                                                   " while reading the displaced positions back");
    return Status::ok();
}

}  // namespace gl
}  // namespace strata
