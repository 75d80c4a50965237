// Strata GL: the runtime's reconstruction on the GPU, for engines to embed.
//
// Like OpenSubdiv's GL evaluators: built once from a Plan (stencil tables,
// refined triangles, sample UVs and the vertex adjacency go up), then per
// frame only the control positions and normals (the CPU Animator skins the
// few control vertices), and update() runs
//   1. refine.comp    stencils -> surface point and direction per vertex
//   2. displace.comp  surface + d * direction, d sampled from the map (or the
//                     rig's per-vertex values) with the CPU's own formula
//                     (displacement_math.h, sample_map.glsl)
//   3. normals.comp   (optional) shading normals of the displaced mesh,
//                     gathered per vertex in face order from each incident
//                     face's other two corners.
// The results stay in storage buffers the engine binds as it likes:
// displaced positions and normals as vec4 per refined vertex, the refined
// triangles as uint triples.  An engine that displaces in its own vertex
// shader instead reads surfaceBuffer() and starts the shader with
// samplingPrelude() (shaders.h), after bindSampling().
//
// Drawing (colour modes, materials, lighting) is not here: the viewer's
// GpuSurface (viewer/draw) is one user of this class.
#pragma once

#include "strata/adaptive.h"
#include "strata/displacement_map.h"
#include "strata/gl/gl.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <memory>
#include <vector>

namespace strata {
namespace gl {

/// How the map is sampled: the CPU's formula over four texelFetch reads
/// (bit-compatible with the CPU), or the texture unit's bilinear filter.
enum class SampleFilter { Shared = 0, Hardware = 1 };

/// Shader storage binding points of the evaluator's buffers, as the shaders
/// in shaders/ declare them.  std430 layouts: vec4 per refined vertex for
/// Surface (two: point, direction), Displaced and Normals; float for
/// VertexDisplacements; vec2 for SampleUVs; uint triples for Triangles;
/// FanOffsets and FanEntries are buildVertexFans's layout (strata/normals.h):
/// each vertex's faces as fans of its one-ring.
enum Binding : GLuint {
    kControlPositions = 0, kControlNormals = 1, kStencilOffsets = 2, kStencilIndices = 3, kStencilWeights = 4,
    kSurface = 5, kDisplaced = 6, kSampleUVs = 7, kTriangles = 8, kFanOffsets = 9, kFanEntries = 10,
    kNormals = 11, kFrameVertices = 13, kVertexDisplacements = 15
};

/// The adaptive frame's own buffers (Evaluator::adaptiveBuffer): displaced
/// positions and shading normals as vec4 per frame vertex, the frame's
/// triangles as uint triples (also its element buffer), each frame
/// vertex's refined vertex, and one DrawElementsIndirectCommand.
enum class AdaptiveBuffer { Displaced, Normals, Triangles, FrameVertices, Indirect };

/// Stage times of the last update(), in milliseconds: only filled while
/// timing is on, which finishes each stage before the next (the wall clock
/// between glFinish calls: exact on a software renderer, an upper bound by
/// one synchronisation per stage on a GPU).
struct EvaluatorTimings {
    double uploadMs = 0.0, stencilMs = 0.0, normalsMs = 0.0;
};

class Evaluator {
public:
    /// Needs a current GL 4.5 context.  shadingNormals: run the normal pass.
    static Status create(std::unique_ptr<Evaluator>* out, const Plan& plan, bool shadingNormals = true);
    ~Evaluator();
    Evaluator(const Evaluator&) = delete;
    Evaluator& operator=(const Evaluator&) = delete;

    /// Uploads the map (R32F texels; factor and offset decode them).
    Status setDisplacementMap(const DisplacementMap& map);
    /// Displacements per refined vertex instead of a map (a rig that stores
    /// them so: Plan::displacements() after applyRigDisplacement), used as
    /// they are, so the GPU draws the CPU's surface.  nullptr returns to the map.
    Status setDisplacements(const float* values, size_t count);
    /// Scales the decoded displacement (0: none), like Plan::setDisplacement's scale.
    void setDisplacementScale(float scale) { scale_ = scale; }
    void setSampleFilter(SampleFilter filter) { filter_ = filter; }
    void setShadingNormals(bool on) { shadingNormals_ = on; }
    bool shadingNormals() const { return shadingNormals_; }

    /// Uploads the control positions and normals (count must match the
    /// plan; the smooth scheme needs no normals) and runs the passes.
    Status update(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count);

    /// Binds every buffer at its Binding point (what update() and a shader
    /// written against shaders/ expect).
    void bindBuffers() const;
    /// Sets the sampling uniforms of `program` (u_map, u_mapSize, u_factor,
    /// u_offset, u_scale, u_filter, u_perVertex), binds the map to texture
    /// unit 0 and the per-vertex values at kVertexDisplacements: what a
    /// shader built on samplingPrelude() needs before it calls
    /// strata_sample_displacement.
    void bindSampling(GLuint program) const;

    GLuint buffer(Binding b) const { return buffers_[b]; }
    GLuint mapTexture() const { return texture_; }

    /// Displaced positions and shading normals (the normal pass must be on)
    /// of the last update(), read back.
    Status readPositions(std::vector<glm::vec3>* out) const;
    Status readNormals(std::vector<glm::vec3>* out) const;

    /// Adaptive level of detail (adaptive.h) on the GPU: the frame's
    /// vertices and triangles go up when its levels change; then
    /// updateAdaptive() evaluates only the frame's vertices (the same
    /// stencils, displacements and passes as update(), indexed through the
    /// frame's vertex list) and the shading normals of its triangles, and a
    /// draw reads them with glDrawElementsIndirect on the indirect buffer.
    /// `frame` must come from this evaluator's plan.
    Status setAdaptive(const AdaptiveFrame& frame);
    Status updateAdaptive(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count);
    size_t adaptiveVertexCount() const { return adaptiveVertices_; }
    size_t adaptiveTriangleCount() const { return adaptiveTriangles_; }
    GLuint adaptiveBuffer(AdaptiveBuffer b) const { return adaptive_[int(b)]; }
    Status readAdaptivePositions(std::vector<glm::vec3>* out) const;
    Status readAdaptiveNormals(std::vector<glm::vec3>* out) const;

    void setTiming(bool on) { timing_ = on; }
    const EvaluatorTimings& timings() const { return timings_; }
    size_t vertexCount() const { return vertexCount_; }
    size_t faceCount() const { return faceCount_; }
    size_t gpuBytes() const { return gpuBytes_; }

private:
    Evaluator() = default;

    size_t vertexCount_ = 0, faceCount_ = 0, controlCount_ = 0, gpuBytes_ = 0;
    bool smooth_ = false, shadingNormals_ = true, timing_ = false;
    float scale_ = 1.0f;
    SampleFilter filter_ = SampleFilter::Shared;
    glm::ivec2 mapSize_{1, 1};
    float factor_ = 1.0f, offset_ = 0.0f;
    bool haveMap_ = false, perVertex_ = false;
    GLuint buffers_[16] = {};
    GLuint texture_ = 0;
    GLuint refine_ = 0, displace_ = 0, normals_ = 0;
    EvaluatorTimings timings_;
    Status runPasses(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count, bool adaptive);
    // The adaptive frame: programs, buffers by AdaptiveBuffer then surface
    // (point, direction per vertex), fan offsets and entries; capacities.
    GLuint adaptiveRefine_ = 0, adaptiveDisplace_ = 0;
    GLuint adaptive_[8] = {};
    size_t adaptiveCapacity_[8] = {};
    size_t adaptiveVertices_ = 0, adaptiveTriangles_ = 0;
};

}  // namespace gl
}  // namespace strata
