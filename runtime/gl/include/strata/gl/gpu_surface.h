// Strata GL: the runtime's reconstruction on the GPU (issue: GPU path).
//
// Built once from a Plan: the stencil tables, refined triangles, canonical
// sample UVs and the vertex adjacency are uploaded; the displacement map is
// an R32F texture with linear filtering and no mipmaps.  Per frame only the
// control positions and normals go up (the CPU Animator skins the few
// control vertices), then:
//   1. refine.comp   stencils -> surface point and direction per vertex
//   2. displace.comp + normals.comp   (optional) shading normals of the
//      displaced mesh, gathered per vertex in face order
//   3. surface.vert   samples the map at the vertex's UV and displaces along
//      the direction: the same formula as the CPU (displacement_math.h).
// readPositions() runs the same vertex shader with transform feedback, so
// what is drawn is what is compared with the CPU.
#pragma once

#include "strata/displacement_map.h"
#include "strata/gl/gl.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <memory>
#include <vector>

namespace strata {
namespace gl {

/// How the vertex shader samples the map: the CPU's formula over four
/// texelFetch reads (bit-compatible), or the texture unit's bilinear filter.
enum class SampleFilter { Shared = 0, Hardware = 1 };

enum class ColorMode { Shaded = 0, Displacement = 1, Error = 2, Flat = 3 };

struct DrawParams {
    glm::mat4 viewProjection{1.0f};
    glm::vec3 eye{0.0f, 0.0f, 1.0f};
    ColorMode colorMode = ColorMode::Shaded;
    glm::vec2 colorRange{0.0f, 1.0f};
    glm::vec3 baseColor{0.78f, 0.74f, 0.70f};
    bool wireframe = false;  ///< overlay the refined triangles' edges
};

/// A material as the draw pass applies it (glTF metallic-roughness reduced
/// to what a preview needs): base colour factor times an optional RGBA8
/// texture, and the alpha mode.
struct SurfaceMaterial {
    glm::vec4 baseColor{1.0f};
    int textureWidth = 0, textureHeight = 0;
    const uint8_t* textureRGBA = nullptr;  ///< null: untextured; copied at setMaterials()
    int alphaMode = 0;                     ///< 0 opaque, 1 mask, 2 blend
    float alphaCutoff = 0.5f;
};

/// A run of refined faces drawn with one material.
struct MaterialRange {
    size_t firstFace = 0, faceCount = 0;
    int material = 0;
};

/// GPU times of the last update() and draw(), in milliseconds (timer
/// queries; only filled while timing is enabled, which waits for the GPU).
struct GpuTimings {
    double uploadMs = 0.0, stencilMs = 0.0, normalsMs = 0.0, drawMs = 0.0;
};

class GpuSurface {
public:
    /// Needs a current GL 4.5 context.  shadingNormals: run the normal pass
    /// (off: shade with the interpolated direction).
    static Status create(std::unique_ptr<GpuSurface>* out, const Plan& plan, bool shadingNormals = true);
    ~GpuSurface();
    GpuSurface(const GpuSurface&) = delete;
    GpuSurface& operator=(const GpuSurface&) = delete;

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
    /// Per refined vertex values for ColorMode::Error (null clears them).
    void setVertexErrors(const float* errors);

    /// Materials for the shaded view: ranges of refined faces, each drawn
    /// with its material, the texture sampled through cornerUVs (3 per
    /// refined face, refined like the plan's UVs).  Without materials the
    /// surface is drawn in DrawParams::baseColor.  Blended ranges are drawn
    /// last, without depth writes.
    Status setMaterials(const std::vector<SurfaceMaterial>& materials, const std::vector<MaterialRange>& ranges,
                        const std::vector<glm::vec2>& cornerUVs);

    /// Uploads the control positions and normals (count must match the
    /// plan) and runs the compute passes.
    Status update(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count);
    void draw(const DrawParams& params);

    /// Displaced positions as the vertex shader computes them.
    Status readPositions(std::vector<glm::vec3>* out);
    /// Shading normals from the normal pass.
    Status readNormals(std::vector<glm::vec3>* out);

    void setTiming(bool on) { timing_ = on; }
    const GpuTimings& timings() const { return timings_; }

    size_t vertexCount() const { return vertexCount_; }
    size_t faceCount() const { return faceCount_; }
    size_t gpuBytes() const { return gpuBytes_; }

private:
    GpuSurface() = default;
    void setSampleUniforms(GLuint program);
    double elapsedMs(GLuint begin, GLuint end);

    size_t vertexCount_ = 0, faceCount_ = 0, controlCount_ = 0, gpuBytes_ = 0;
    bool smooth_ = false, shadingNormals_ = true, timing_ = false, haveErrors_ = false;
    float scale_ = 1.0f;
    SampleFilter filter_ = SampleFilter::Shared;
    glm::ivec2 mapSize_{1, 1};
    float factor_ = 1.0f, offset_ = 0.0f;
    bool haveMap_ = false;
    bool perVertex_ = false;

    enum Buffer {
        ControlPositions, ControlNormals, StencilOffsets, StencilIndices, StencilWeights, Surface, Displaced,
        SampleUVs, Triangles, AdjacencyOffsets, AdjacentFaces, Normals, Errors, Feedback, CornerUVs,
        VertexDisplacements, BufferCount
    };
    struct GpuMaterial {
        SurfaceMaterial material;
        GLuint texture = 0;
    };
    std::vector<GpuMaterial> materials_;
    std::vector<MaterialRange> ranges_;
    GLuint cornerVao_ = 0;
    void drawMaterials(GLuint program);
    GLuint buffers_[BufferCount] = {};
    GLuint vao_ = 0, texture_ = 0;
    GLuint refine_ = 0, displace_ = 0, normals_ = 0, surface_ = 0, feedback_ = 0;
    GLuint queries_[6] = {};
    GLuint feedbackTarget_ = 0, feedbackColor_ = 0;
    GpuTimings timings_;
};

}  // namespace gl
}  // namespace strata
