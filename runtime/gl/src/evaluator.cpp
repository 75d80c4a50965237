#include "strata/gl/evaluator.h"

#include "strata/gl/shaders.h"
#include "strata/normals.h"

#include <glm/vec4.hpp>

#include <algorithm>
#include <chrono>
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

Status Evaluator::create(std::unique_ptr<Evaluator>* out, const Plan& plan, bool shadingNormals)
{
    if (!glCreateBuffers)
        return Status(StatusCode::InvalidArgument, "the GPU evaluator needs a current OpenGL 4.5 context");
    std::unique_ptr<Evaluator> e(new Evaluator());
    e->vertexCount_ = plan.refinedVertexCount();
    e->faceCount_ = plan.refinedFaceCount();
    e->controlCount_ = plan.controlVertexCount();
    e->smooth_ = plan.scheme() == Scheme::Smooth;
    e->shadingNormals_ = shadingNormals;
    if (e->vertexCount_ >= (size_t(1) << 31) / 32)
        return Status(StatusCode::InvalidArgument, "too many refined vertices for one GPU surface");

    const std::string defines = e->smooth_ ? "#define STRATA_SMOOTH 1\n" : "";
    Status st = buildProgram(&e->refine_, "refine.comp", {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Refine, defines)}});
    if (st.isOk())
        st = buildProgram(&e->displace_, "displace.comp", {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Displace)}});
    if (st.isOk())
        st = buildProgram(&e->normals_, "normals.comp", {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Normals)}});
    if (!st.isOk())
        return st;

    // Static tables, uploaded once.
    Plan::FlatStencils stencils;
    plan.flattenStencils(&stencils);
    const size_t nv = e->vertexCount_, nf = e->faceCount_;
    const std::vector<uint32_t>& tris = plan.refinedTriangles();
    // Per vertex, its faces as fans of its one-ring: the normal pass reads
    // one position per face instead of two.
    std::vector<uint32_t> fanOffsets, fanEntries;
    buildVertexFans(&fanOffsets, &fanEntries, tris.data(), nf, nv);
    std::vector<glm::vec2> uvs;
    plan.sampleUVs(&uvs);
    if (uvs.empty())
        uvs.assign(nv, glm::vec2(0.0f));
    size_t& bytes = e->gpuBytes_;
    GLuint* b = e->buffers_;
    b[kControlPositions] = makeBuffer(nullptr, e->controlCount_ * 12, true, &bytes);
    b[kControlNormals] = makeBuffer(nullptr, e->controlCount_ * 12, true, &bytes);
    b[kStencilOffsets] = makeBuffer(stencils.offsets.data(), stencils.offsets.size() * 4, false, &bytes);
    b[kStencilIndices] = makeBuffer(stencils.indices.data(), stencils.indices.size() * 4, false, &bytes);
    b[kStencilWeights] = makeBuffer(stencils.weights.data(), stencils.weights.size() * 4, false, &bytes);
    b[kSurface] = makeBuffer(nullptr, nv * 32, false, &bytes);
    b[kDisplaced] = makeBuffer(nullptr, nv * 16, false, &bytes);
    b[kSampleUVs] = makeBuffer(uvs.data(), nv * 8, false, &bytes);
    b[kTriangles] = makeBuffer(tris.data(), tris.size() * 4, false, &bytes);
    b[kFanOffsets] = makeBuffer(fanOffsets.data(), fanOffsets.size() * 4, false, &bytes);
    b[kFanEntries] = makeBuffer(fanEntries.data(), fanEntries.size() * 4, false, &bytes);
    b[kNormals] = makeBuffer(nullptr, nv * 16, false, &bytes);
    b[kVertexDisplacements] = makeBuffer(nullptr, std::max<size_t>(nv, 1) * 4, true, &bytes);

    // A 1x1 zero map until one is set.
    glCreateTextures(GL_TEXTURE_2D, 1, &e->texture_);
    DisplacementMap zero;
    zero.width = zero.height = 1;
    zero.texels = {0.0f};
    if (!(st = e->setDisplacementMap(zero)))
        return st;
    e->haveMap_ = false;
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL reported an error while uploading the plan");
    *out = std::move(e);
    return Status::ok();
}

Evaluator::~Evaluator()
{
    for (GLuint& b : buffers_)
        if (b)
            glDeleteBuffers(1, &b);
    glDeleteTextures(1, &texture_);
    for (GLuint& b : adaptive_)
        if (b)
            glDeleteBuffers(1, &b);
    for (GLuint p : {refine_, displace_, normals_, adaptiveRefine_, adaptiveDisplace_})
        if (p)
            glDeleteProgram(p);
}

Status Evaluator::setDisplacementMap(const DisplacementMap& map)
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

Status Evaluator::setDisplacements(const float* values, size_t count)
{
    if (!values) {
        perVertex_ = false;
        return Status::ok();
    }
    if (count != vertexCount_)
        return Status(StatusCode::InvalidArgument, std::to_string(count) + " displacements for " +
                                                       std::to_string(vertexCount_) + " refined vertices");
    glNamedBufferSubData(buffers_[kVertexDisplacements], 0, GLsizeiptr(count * 4), values);
    perVertex_ = true;
    return Status::ok();
}

void Evaluator::bindBuffers() const
{
    for (GLuint i = 0; i < 16; ++i)
        if (buffers_[i])
            glBindBufferBase(GL_SHADER_STORAGE_BUFFER, i, buffers_[i]);
}

void Evaluator::bindSampling(GLuint program) const
{
    glBindTextureUnit(0, texture_);
    glProgramUniform1i(program, glGetUniformLocation(program, "u_map"), 0);
    glProgramUniform2i(program, glGetUniformLocation(program, "u_mapSize"), mapSize_.x, mapSize_.y);
    glProgramUniform1f(program, glGetUniformLocation(program, "u_factor"), factor_);
    glProgramUniform1f(program, glGetUniformLocation(program, "u_offset"), offset_);
    glProgramUniform1f(program, glGetUniformLocation(program, "u_scale"), haveMap_ || perVertex_ ? scale_ : 0.0f);
    glProgramUniform1i(program, glGetUniformLocation(program, "u_filter"), int(filter_));
    glProgramUniform1i(program, glGetUniformLocation(program, "u_perVertex"), perVertex_ ? 1 : 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kVertexDisplacements, buffers_[kVertexDisplacements]);
}

Status Evaluator::update(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count)
{
    return runPasses(controlPositions, controlNormals, count, false);
}

Status Evaluator::updateAdaptive(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count)
{
    if (!adaptiveRefine_)
        return Status(StatusCode::InvalidArgument, "GPU evaluator: no adaptive frame set (setAdaptive)");
    return runPasses(controlPositions, controlNormals, count, true);
}

namespace {
// Indices into Evaluator::adaptive_ past the AdaptiveBuffer ones.
constexpr int kAdaptiveSurface = 5, kAdaptiveFanOffsets = 6, kAdaptiveFanEntries = 7;
}  // namespace

Status Evaluator::runPasses(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count,
                            bool adaptive)
{
    if (count != controlCount_)
        return Status(StatusCode::InvalidArgument, "GPU evaluator: got " + std::to_string(count) +
                                                       " control vertices, the plan has " +
                                                       std::to_string(controlCount_));
    if (!controlPositions || (!smooth_ && !controlNormals))
        return Status(StatusCode::InvalidArgument, "GPU evaluator: null control data");
    // Stages are timed by the wall clock between glFinish calls: exact on a
    // software renderer, whose timestamp queries land a stage late
    // (llvmpipe's normal pass read 0.1 ms by them, 85 ms by the clock), and
    // on a GPU an upper bound by one synchronisation per stage.
    std::chrono::steady_clock::time_point at[4];
    auto stamp = [&](int i) {
        if (timing_) {
            glFinish();
            at[i] = std::chrono::steady_clock::now();
        }
    };
    stamp(0);
    glNamedBufferSubData(buffers_[kControlPositions], 0, GLsizeiptr(count * 12), controlPositions);
    if (controlNormals)
        glNamedBufferSubData(buffers_[kControlNormals], 0, GLsizeiptr(count * 12), controlNormals);
    stamp(1);
    bindBuffers();
    size_t vertices = vertexCount_;
    GLuint refine = refine_, displace = displace_;
    if (adaptive) {
        // The frame's own outputs at the binding points the passes write.
        vertices = adaptiveVertices_;
        refine = adaptiveRefine_;
        displace = adaptiveDisplace_;
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kSurface, adaptive_[kAdaptiveSurface]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kDisplaced, adaptive_[int(AdaptiveBuffer::Displaced)]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kNormals, adaptive_[int(AdaptiveBuffer::Normals)]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kTriangles, adaptive_[int(AdaptiveBuffer::Triangles)]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kFanOffsets, adaptive_[kAdaptiveFanOffsets]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kFanEntries, adaptive_[kAdaptiveFanEntries]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kFrameVertices, adaptive_[int(AdaptiveBuffer::FrameVertices)]);
    }
    const GLuint n = GLuint(vertices);
    glUseProgram(refine);
    glUniform1ui(glGetUniformLocation(refine, "u_vertexCount"), n);
    glDispatchCompute(groups(vertices), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    bindSampling(displace);
    glUseProgram(displace);
    glUniform1ui(glGetUniformLocation(displace, "u_vertexCount"), n);
    glDispatchCompute(groups(vertices), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    stamp(2);
    if (shadingNormals_) {
        glUseProgram(normals_);
        glUniform1ui(glGetUniformLocation(normals_, "u_vertexCount"), n);
        glDispatchCompute(groups(vertices), 1, 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_VERTEX_ATTRIB_ARRAY_BARRIER_BIT | GL_ELEMENT_ARRAY_BARRIER_BIT |
                        GL_COMMAND_BARRIER_BIT);
    }
    stamp(3);
    if (timing_) {
        auto ms = [&](int a, int b) { return std::chrono::duration<double, std::milli>(at[b] - at[a]).count(); };
        timings_.uploadMs = ms(0, 1);
        timings_.stencilMs = ms(1, 2);
        timings_.normalsMs = ms(2, 3);
    }
    if (adaptive)
        bindBuffers();  // the plan's own buffers back at their binding points
    glUseProgram(0);
    return Status::ok();
}

Status Evaluator::setAdaptive(const AdaptiveFrame& frame)
{
    if (!adaptiveRefine_) {
        const std::string defines = std::string("#define STRATA_ADAPTIVE 1\n") + (smooth_ ? "#define STRATA_SMOOTH 1\n" : "");
        Status st = buildProgram(&adaptiveRefine_, "refine.comp (adaptive)",
                                 {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Refine, defines)}});
        if (st.isOk())
            st = buildProgram(&adaptiveDisplace_, "displace.comp (adaptive)",
                              {{GL_COMPUTE_SHADER, shaderSource(ShaderId::Displace, "#define STRATA_ADAPTIVE 1\n")}});
        if (!st.isOk())
            return st;
    }
    const size_t n = frame.vertexCount(), nt = frame.triangleCount();
    for (uint32_t v : frame.vertices())
        if (v >= vertexCount_)
            return Status(StatusCode::InvalidArgument, "the adaptive frame is not of this evaluator's plan");
    std::vector<uint32_t> fanOffsets, fanEntries;
    buildVertexFans(&fanOffsets, &fanEntries, frame.triangles().data(), nt, n);
    struct {
        GLuint count, instances, firstIndex;
        GLint baseVertex;
        GLuint baseInstance;
    } command{GLuint(3 * nt), 1, 0, 0, 0};
    // Storage grows to the largest frame so far (immutable storage: a new
    // buffer when it must grow), then takes each frame's data in place.
    auto put = [&](int index, const void* data, size_t bytes) {
        if (adaptiveCapacity_[index] < bytes || !adaptive_[index]) {
            if (adaptive_[index]) {
                gpuBytes_ -= adaptiveCapacity_[index];
                glDeleteBuffers(1, &adaptive_[index]);
            }
            const size_t capacity = std::max<size_t>(bytes + bytes / 4, 64);
            glCreateBuffers(1, &adaptive_[index]);
            glNamedBufferStorage(adaptive_[index], GLsizeiptr(capacity), nullptr, GL_DYNAMIC_STORAGE_BIT);
            adaptiveCapacity_[index] = capacity;
            gpuBytes_ += capacity;
        }
        if (data && bytes)
            glNamedBufferSubData(adaptive_[index], 0, GLsizeiptr(bytes), data);
    };
    put(int(AdaptiveBuffer::Displaced), nullptr, n * 16);
    put(int(AdaptiveBuffer::Normals), nullptr, n * 16);
    put(int(AdaptiveBuffer::Triangles), frame.triangles().data(), frame.triangles().size() * 4);
    put(int(AdaptiveBuffer::FrameVertices), frame.vertices().data(), n * 4);
    put(int(AdaptiveBuffer::Indirect), &command, sizeof(command));
    put(kAdaptiveSurface, nullptr, n * 32);
    put(kAdaptiveFanOffsets, fanOffsets.data(), fanOffsets.size() * 4);
    put(kAdaptiveFanEntries, fanEntries.data(), fanEntries.size() * 4);
    adaptiveVertices_ = n;
    adaptiveTriangles_ = nt;
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, "OpenGL reported an error while uploading the adaptive frame");
    return Status::ok();
}

namespace {

// The xyz of a vec4-per-vertex storage buffer, read back.
Status readVec4(GLuint buffer, size_t count, std::vector<glm::vec3>* out, const char* what)
{
    std::vector<glm::vec4> v(count);
    glGetNamedBufferSubData(buffer, 0, GLsizeiptr(count * 16), v.data());
    out->resize(count);
    for (size_t i = 0; i < count; ++i)
        (*out)[i] = glm::vec3(v[i]);
    if (glGetError() != GL_NO_ERROR)
        return Status(StatusCode::Unsupported, std::string("OpenGL reported an error reading the ") + what + " back");
    return Status::ok();
}

}  // namespace

Status Evaluator::readPositions(std::vector<glm::vec3>* out) const
{
    return readVec4(buffers_[kDisplaced], vertexCount_, out, "positions");
}

Status Evaluator::readNormals(std::vector<glm::vec3>* out) const
{
    return readVec4(buffers_[kNormals], vertexCount_, out, "normals");
}

Status Evaluator::readAdaptivePositions(std::vector<glm::vec3>* out) const
{
    return readVec4(adaptive_[int(AdaptiveBuffer::Displaced)], adaptiveVertices_, out, "adaptive positions");
}

Status Evaluator::readAdaptiveNormals(std::vector<glm::vec3>* out) const
{
    return readVec4(adaptive_[int(AdaptiveBuffer::Normals)], adaptiveVertices_, out, "adaptive normals");
}

}  // namespace gl
}  // namespace strata
