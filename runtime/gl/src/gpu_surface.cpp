#include "strata/gl/gpu_surface.h"

#include "strata/gl/shaders.h"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <string>

namespace strata {
namespace gl {

namespace {

constexpr GLuint kGroupSize = 128;

GLuint groups(size_t n)
{
    return GLuint((n + kGroupSize - 1) / kGroupSize);
}

// Immutable storage; `dynamic` allows per-frame glNamedBufferSubData.
GLuint makeBuffer(const void* data, size_t bytes, bool dynamic, size_t* total)
{
    GLuint b = 0;
    glCreateBuffers(1, &b);
    glNamedBufferStorage(b, GLsizeiptr(std::max<size_t>(bytes, 16)), data,
                         dynamic ? GL_DYNAMIC_STORAGE_BIT : GLbitfield(0));
    *total += std::max<size_t>(bytes, 16);
    return b;
}

}  // namespace

Status GpuSurface::create(std::unique_ptr<GpuSurface>* out, const Plan& plan, bool shadingNormals)
{
    if (!glCreateBuffers)
        return Status(StatusCode::InvalidArgument, "GpuSurface::create needs a current OpenGL 4.5 context");
    std::unique_ptr<GpuSurface> s(new GpuSurface());
    s->vertexCount_ = plan.refinedVertexCount();
    s->faceCount_ = plan.refinedFaceCount();
    s->controlCount_ = plan.controlVertexCount();
    s->smooth_ = plan.scheme() == Scheme::Smooth;
    s->shadingNormals_ = shadingNormals;
    if (s->vertexCount_ >= (size_t(1) << 31) / 32)
        return Status(StatusCode::InvalidArgument, "too many refined vertices for one GPU surface");

    // Programs.
    const std::string defines = s->smooth_ ? "#define STRATA_SMOOTH 1\n" : "";
    Status st = buildProgram(&s->refine_, "refine.comp", {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Refine, defines)}});
    if (st.isOk())
        st = buildProgram(&s->displace_, "displace.comp",
                          {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Displace)}});
    if (st.isOk())
        st = buildProgram(&s->normals_, "normals.comp", {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Normals)}});
    if (st.isOk())
        st = buildProgram(&s->surface_, "surface",
                          {{GL_VERTEX_SHADER, shaderSource(ShaderId::SurfaceVertex)},
                           {GL_FRAGMENT_SHADER, shaderSource(ShaderId::SurfaceFragment)}});
    if (st.isOk())
        st = buildProgram(&s->feedback_, "surface.vert (transform feedback)",
                          {{GL_VERTEX_SHADER, shaderSource(ShaderId::SurfaceVertex)}}, {"v_position"});
    if (!st.isOk())
        return st;

    // Static tables, uploaded once.
    Plan::FlatStencils stencils;
    plan.flattenStencils(&stencils);
    const size_t nv = s->vertexCount_, nf = s->faceCount_;
    const std::vector<uint32_t>& tris = plan.refinedTriangles();
    std::vector<uint32_t> adjacencyOffsets(nv + 1, 0), adjacentFaces(3 * nf);
    for (uint32_t i : tris)
        ++adjacencyOffsets[i + 1];
    for (size_t v = 0; v < nv; ++v)
        adjacencyOffsets[v + 1] += adjacencyOffsets[v];
    {
        std::vector<uint32_t> fill(adjacencyOffsets.begin(), adjacencyOffsets.end() - 1);
        for (size_t f = 0; f < nf; ++f)
            for (int k = 0; k < 3; ++k)
                adjacentFaces[fill[tris[3 * f + size_t(k)]]++] = uint32_t(f);
    }
    std::vector<glm::vec2> uvs = plan.sampleUVs();
    if (uvs.empty())
        uvs.assign(nv, glm::vec2(0.0f));
    size_t& bytes = s->gpuBytes_;
    GLuint* b = s->buffers_;
    b[ControlPositions] = makeBuffer(nullptr, s->controlCount_ * 12, true, &bytes);
    b[ControlNormals] = makeBuffer(nullptr, s->controlCount_ * 12, true, &bytes);
    b[StencilOffsets] = makeBuffer(stencils.offsets.data(), stencils.offsets.size() * 4, false, &bytes);
    b[StencilIndices] = makeBuffer(stencils.indices.data(), stencils.indices.size() * 4, false, &bytes);
    b[StencilWeights] = makeBuffer(stencils.weights.data(), stencils.weights.size() * 4, false, &bytes);
    b[Surface] = makeBuffer(nullptr, nv * 32, false, &bytes);
    b[Displaced] = makeBuffer(nullptr, nv * 16, false, &bytes);
    b[SampleUVs] = makeBuffer(uvs.data(), nv * 8, false, &bytes);
    b[Triangles] = makeBuffer(tris.data(), tris.size() * 4, false, &bytes);
    b[AdjacencyOffsets] = makeBuffer(adjacencyOffsets.data(), adjacencyOffsets.size() * 4, false, &bytes);
    b[AdjacentFaces] = makeBuffer(adjacentFaces.data(), adjacentFaces.size() * 4, false, &bytes);
    b[Normals] = makeBuffer(nullptr, nv * 16, false, &bytes);
    b[Errors] = makeBuffer(nullptr, nv * 4, true, &bytes);
    b[Feedback] = makeBuffer(nullptr, nv * 12, false, &bytes);
    b[VertexDisplacements] = makeBuffer(nullptr, std::max<size_t>(nv, 1) * 4, true, &bytes);

    glCreateVertexArrays(1, &s->vao_);
    glVertexArrayVertexBuffer(s->vao_, 0, b[SampleUVs], 0, 8);
    glVertexArrayAttribFormat(s->vao_, 0, 2, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(s->vao_, 0, 0);
    glEnableVertexArrayAttrib(s->vao_, 0);
    glVertexArrayVertexBuffer(s->vao_, 1, b[Errors], 0, 4);
    glVertexArrayAttribFormat(s->vao_, 1, 1, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(s->vao_, 1, 1);
    glVertexArrayElementBuffer(s->vao_, b[Triangles]);

    // A 1x1 zero map until one is set.
    glCreateTextures(GL_TEXTURE_2D, 1, &s->texture_);
    DisplacementMap zero;
    zero.width = zero.height = 1;
    zero.texels = {0.0f};
    if (!(st = s->setDisplacementMap(zero)))
        return st;
    s->haveMap_ = false;
    glCreateQueries(GL_TIMESTAMP, 6, s->queries_);
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL reported an error while uploading the plan");
    *out = std::move(s);
    return Status::ok();
}

GpuSurface::~GpuSurface()
{
    glDeleteBuffers(BufferCount, buffers_);
    glDeleteVertexArrays(1, &vao_);
    glDeleteVertexArrays(1, &cornerVao_);
    glDeleteTextures(1, &texture_);
    for (GpuMaterial& m : materials_)
        glDeleteTextures(1, &m.texture);
    for (GLuint p : {refine_, displace_, normals_, surface_, feedback_})
        glDeleteProgram(p);
    glDeleteQueries(6, queries_);
    glDeleteFramebuffers(1, &feedbackTarget_);
    glDeleteRenderbuffers(1, &feedbackColor_);
}

Status GpuSurface::setDisplacementMap(const DisplacementMap& map)
{
    if (Status st = validateDisplacementMap(map); !st.isOk())
        return st;
    GLint maxSize = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
    if (map.width > maxSize || map.height > maxSize)
        return Status(StatusCode::Unsupported, "the displacement map is larger than this GPU's " +
                                                   std::to_string(maxSize) + " texels per side");
    // Immutable storage cannot be resized: a new texture per map.
    glDeleteTextures(1, &texture_);
    glCreateTextures(GL_TEXTURE_2D, 1, &texture_);
    glTextureStorage2D(texture_, 1, GL_R32F, map.width, map.height);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage2D(texture_, 0, 0, 0, map.width, map.height, GL_RED, GL_FLOAT, map.texels.data());
    glTextureParameteri(texture_, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(texture_, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(texture_, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(texture_, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    mapSize_ = glm::ivec2(map.width, map.height);
    factor_ = map.factor;
    offset_ = map.offset;
    haveMap_ = true;
    return Status::ok();
}

Status GpuSurface::setDisplacements(const float* values, size_t count)
{
    if (!values) {
        perVertex_ = false;
        return Status::ok();
    }
    if (count != vertexCount_)
        return Status(StatusCode::InvalidArgument, std::to_string(count) + " displacements for " +
                                                       std::to_string(vertexCount_) + " refined vertices");
    glNamedBufferSubData(buffers_[VertexDisplacements], 0, GLsizeiptr(count * 4), values);
    perVertex_ = true;
    return Status::ok();
}

void GpuSurface::setVertexErrors(const float* errors)
{
    haveErrors_ = errors != nullptr;
    if (errors)
        glNamedBufferSubData(buffers_[Errors], 0, GLsizeiptr(vertexCount_ * 4), errors);
    if (haveErrors_)
        glEnableVertexArrayAttrib(vao_, 1);
    else
        glDisableVertexArrayAttrib(vao_, 1);
}

Status GpuSurface::setMaterials(const std::vector<SurfaceMaterial>& materials, const std::vector<MaterialRange>& ranges,
                                const std::vector<glm::vec2>& cornerUVs)
{
    if (cornerUVs.size() != 3 * faceCount_)
        return Status(StatusCode::InvalidArgument, "setMaterials: " + std::to_string(cornerUVs.size()) +
                                                       " corner UVs for " + std::to_string(faceCount_) + " faces");
    for (const MaterialRange& r : ranges)
        if (r.material < 0 || size_t(r.material) >= materials.size() || r.firstFace > faceCount_ ||
            r.faceCount > faceCount_ - r.firstFace)
            return Status(StatusCode::InvalidArgument, "setMaterials: a face range is out of bounds");
    for (GpuMaterial& m : materials_)
        glDeleteTextures(1, &m.texture);
    materials_.clear();
    for (const SurfaceMaterial& in : materials) {
        GpuMaterial m;
        m.material = in;
        if (in.textureRGBA && in.textureWidth > 0 && in.textureHeight > 0) {
            glCreateTextures(GL_TEXTURE_2D, 1, &m.texture);
            int levels = 1;
            while ((std::max(in.textureWidth, in.textureHeight) >> levels) > 0)
                ++levels;
            glTextureStorage2D(m.texture, levels, GL_RGBA8, in.textureWidth, in.textureHeight);
            glTextureSubImage2D(m.texture, 0, 0, 0, in.textureWidth, in.textureHeight, GL_RGBA, GL_UNSIGNED_BYTE,
                                in.textureRGBA);
            glGenerateTextureMipmap(m.texture);
            glTextureParameteri(m.texture, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
            glTextureParameteri(m.texture, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
            glTextureParameteri(m.texture, GL_TEXTURE_WRAP_S, GL_REPEAT);
            glTextureParameteri(m.texture, GL_TEXTURE_WRAP_T, GL_REPEAT);
        }
        m.material.textureRGBA = nullptr;
        materials_.push_back(m);
    }
    ranges_ = ranges;
    // Blended ranges last.
    std::stable_sort(ranges_.begin(), ranges_.end(), [&](const MaterialRange& a, const MaterialRange& b) {
        return (materials_[size_t(a.material)].material.alphaMode == 2) <
               (materials_[size_t(b.material)].material.alphaMode == 2);
    });
    if (buffers_[CornerUVs])
        glDeleteBuffers(1, &buffers_[CornerUVs]);
    glCreateBuffers(1, &buffers_[CornerUVs]);
    glNamedBufferStorage(buffers_[CornerUVs], GLsizeiptr(std::max<size_t>(cornerUVs.size(), 1) * sizeof(glm::vec2)),
                         cornerUVs.empty() ? nullptr : cornerUVs.data(), 0);
    if (!cornerVao_)
        glCreateVertexArrays(1, &cornerVao_);  // no attributes: the shader reads buffers by corner
    return Status::ok();
}

// The shaded view with materials: corner-ordered draws (gl_VertexID is the
// refined corner), one per face range.
void GpuSurface::drawMaterials(GLuint prog)
{
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SampleUVs, buffers_[SampleUVs]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, Triangles, buffers_[Triangles]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, Errors, buffers_[Errors]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, CornerUVs, buffers_[CornerUVs]);
    glUniform1i(glGetUniformLocation(prog, "u_corners"), 1);
    glUniform1i(glGetUniformLocation(prog, "u_baseColorTexture"), 1);
    glBindVertexArray(cornerVao_);
    bool blending = false;
    for (const MaterialRange& r : ranges_) {
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
        glUniform1f(glGetUniformLocation(prog, "u_alphaCutoff"), m.material.alphaCutoff);
        glBindTextureUnit(1, m.texture);
        glDrawArrays(GL_TRIANGLES, GLint(3 * r.firstFace), GLsizei(3 * r.faceCount));
    }
    if (blending) {
        glDisable(GL_BLEND);
        glDepthMask(GL_TRUE);
    }
    glBindTextureUnit(1, 0);
    glUniform1i(glGetUniformLocation(prog, "u_material"), 0);
    glUniform1i(glGetUniformLocation(prog, "u_corners"), 0);
}

void GpuSurface::setSampleUniforms(GLuint program)
{
    glBindTextureUnit(0, texture_);
    glProgramUniform1i(program, glGetUniformLocation(program, "u_map"), 0);
    glProgramUniform2i(program, glGetUniformLocation(program, "u_mapSize"), mapSize_.x, mapSize_.y);
    glProgramUniform1f(program, glGetUniformLocation(program, "u_factor"), factor_);
    glProgramUniform1f(program, glGetUniformLocation(program, "u_offset"), offset_);
    glProgramUniform1f(program, glGetUniformLocation(program, "u_scale"), haveMap_ || perVertex_ ? scale_ : 0.0f);
    glProgramUniform1i(program, glGetUniformLocation(program, "u_filter"), int(filter_));
    glProgramUniform1i(program, glGetUniformLocation(program, "u_perVertex"), perVertex_ ? 1 : 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, VertexDisplacements, buffers_[VertexDisplacements]);
}

double GpuSurface::elapsedMs(GLuint begin, GLuint end)
{
    GLuint64 a = 0, b = 0;
    glGetQueryObjectui64v(begin, GL_QUERY_RESULT, &a);
    glGetQueryObjectui64v(end, GL_QUERY_RESULT, &b);
    return double(b - a) * 1e-6;
}

Status GpuSurface::update(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count)
{
    if (count != controlCount_)
        return Status(StatusCode::InvalidArgument, "GpuSurface::update: got " + std::to_string(count) +
                                                       " control vertices, the plan has " +
                                                       std::to_string(controlCount_));
    if (!controlPositions || (!smooth_ && !controlNormals))
        return Status(StatusCode::InvalidArgument, "GpuSurface::update: null control data");
    if (timing_)
        glQueryCounter(queries_[0], GL_TIMESTAMP);
    glNamedBufferSubData(buffers_[ControlPositions], 0, GLsizeiptr(count * 12), controlPositions);
    if (controlNormals)
        glNamedBufferSubData(buffers_[ControlNormals], 0, GLsizeiptr(count * 12), controlNormals);
    if (timing_)
        glQueryCounter(queries_[1], GL_TIMESTAMP);

    for (GLuint i = 0; i < BufferCount; ++i)
        if (i != Feedback && i != Errors)
            glBindBufferBase(GL_SHADER_STORAGE_BUFFER, i, buffers_[i]);
    const GLuint n = GLuint(vertexCount_);
    glUseProgram(refine_);
    glUniform1ui(glGetUniformLocation(refine_, "u_vertexCount"), n);
    glDispatchCompute(groups(vertexCount_), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    if (timing_)
        glQueryCounter(queries_[2], GL_TIMESTAMP);
    if (shadingNormals_) {
        setSampleUniforms(displace_);
        glUseProgram(displace_);
        glUniform1ui(glGetUniformLocation(displace_, "u_vertexCount"), n);
        glDispatchCompute(groups(vertexCount_), 1, 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
        glUseProgram(normals_);
        glUniform1ui(glGetUniformLocation(normals_, "u_vertexCount"), n);
        glDispatchCompute(groups(vertexCount_), 1, 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    if (timing_) {
        glQueryCounter(queries_[3], GL_TIMESTAMP);
        timings_.uploadMs = elapsedMs(queries_[0], queries_[1]);
        timings_.stencilMs = elapsedMs(queries_[1], queries_[2]);
        timings_.normalsMs = elapsedMs(queries_[2], queries_[3]);
    }
    glUseProgram(0);
    return Status::ok();
}

void GpuSurface::draw(const DrawParams& p)
{
    if (timing_)
        glQueryCounter(queries_[4], GL_TIMESTAMP);
    setSampleUniforms(surface_);
    const GLuint prog = surface_;
    glUseProgram(prog);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, Surface, buffers_[Surface]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, Normals, buffers_[Normals]);
    glUniformMatrix4fv(glGetUniformLocation(prog, "u_viewProjection"), 1, GL_FALSE, glm::value_ptr(p.viewProjection));
    glUniform1i(glGetUniformLocation(prog, "u_haveNormals"), shadingNormals_ ? 1 : 0);
    glUniform3fv(glGetUniformLocation(prog, "u_eye"), 1, glm::value_ptr(p.eye));
    glUniform2fv(glGetUniformLocation(prog, "u_colorRange"), 1, glm::value_ptr(p.colorRange));
    glUniform3fv(glGetUniformLocation(prog, "u_baseColor"), 1, glm::value_ptr(p.baseColor));
    const ColorMode mode = p.colorMode == ColorMode::Error && !haveErrors_ ? ColorMode::Shaded : p.colorMode;
    glUniform1i(glGetUniformLocation(prog, "u_colorMode"), int(mode));
    if (!haveErrors_)
        glVertexAttrib1f(1, 0.0f);
    glUniform1i(glGetUniformLocation(prog, "u_corners"), 0);
    glUniform1i(glGetUniformLocation(prog, "u_material"), 0);
    if (p.wireframe) {
        glEnable(GL_POLYGON_OFFSET_FILL);
        glPolygonOffset(1.0f, 1.0f);
    }
    if (mode == ColorMode::Shaded && !materials_.empty()) {
        drawMaterials(prog);
    } else {
        glBindVertexArray(vao_);
        glDrawElements(GL_TRIANGLES, GLsizei(3 * faceCount_), GL_UNSIGNED_INT, nullptr);
    }
    glBindVertexArray(vao_);
    if (p.wireframe) {
        glDisable(GL_POLYGON_OFFSET_FILL);
        glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
        glUniform1i(glGetUniformLocation(prog, "u_colorMode"), int(ColorMode::Flat));
        glUniform3f(glGetUniformLocation(prog, "u_baseColor"), 0.12f, 0.12f, 0.14f);
        glDrawElements(GL_TRIANGLES, GLsizei(3 * faceCount_), GL_UNSIGNED_INT, nullptr);
        glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    }
    glBindVertexArray(0);
    glUseProgram(0);
    if (timing_) {
        glQueryCounter(queries_[5], GL_TIMESTAMP);
        timings_.drawMs = elapsedMs(queries_[4], queries_[5]);
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
    setSampleUniforms(feedback_);
    glUseProgram(feedback_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, Surface, buffers_[Surface]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, Normals, buffers_[Normals]);
    glUniform1i(glGetUniformLocation(feedback_, "u_haveNormals"), 0);
    glUniformMatrix4fv(glGetUniformLocation(feedback_, "u_viewProjection"), 1, GL_FALSE,
                       glm::value_ptr(glm::mat4(1.0f)));
    glBindVertexArray(vao_);
    if (!haveErrors_)
        glVertexAttrib1f(1, 0.0f);
    glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, buffers_[Feedback]);
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
    glGetNamedBufferSubData(buffers_[Feedback], 0, GLsizeiptr(vertexCount_ * 12), out->data());
    if (const GLenum e = glGetError(); e != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL error " + std::to_string(e) +
                                                   " while reading the displaced positions back");
    return Status::ok();
}

Status GpuSurface::readNormals(std::vector<glm::vec3>* out)
{
    std::vector<glm::vec4> n(vertexCount_);
    glGetNamedBufferSubData(buffers_[Normals], 0, GLsizeiptr(vertexCount_ * 16), n.data());
    out->resize(vertexCount_);
    for (size_t v = 0; v < vertexCount_; ++v)
        (*out)[v] = glm::vec3(n[v]);
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL reported an error reading the normals back");
    return Status::ok();
}

}  // namespace gl
}  // namespace strata
