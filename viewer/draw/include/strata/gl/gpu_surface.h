// The viewer's drawing of a rig on the GPU, on top of the embeddable
// evaluator (strata/gl/evaluator.h), which refines, displaces and computes
// shading normals: surface.vert samples the map at the vertex's UV and
// displaces along the direction with the same formula as the CPU
// (displacement_math.h), surface.frag shades (colour modes, materials,
// lighting, wireframe).  readPositions() runs the same vertex shader with
// transform feedback, so what is drawn is what is compared with the CPU.
#pragma once

#include "strata/displacement_map.h"
#include "strata/gl/evaluator.h"
#include "strata/gl/gl.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace gl {

enum class ColorMode { Shaded = 0, Displacement = 1, Error = 2, Flat = 3 };

struct DrawParams {
    glm::mat4 viewProjection{1.0f};
    glm::vec3 eye{0.0f, 0.0f, 1.0f};
    ColorMode colorMode = ColorMode::Shaded;
    glm::vec2 colorRange{0.0f, 1.0f};
    glm::vec3 baseColor{0.78f, 0.74f, 0.70f};
    bool wireframe = false;  ///< overlay the refined triangles' edges
    /// Shade with face normals (each triangle's own plane) instead of the
    /// surface's normals, where no material range says otherwise.
    bool flatShading = false;
};

/// One of a material's textures: RGBA8 pixels (null: none; copied at
/// setMaterials()), read through the corner UVs or, with `second`, the
/// second corner UVs (glTF's texCoord on another set or transform).
struct SurfaceTexture {
    int width = 0, height = 0;
    const uint8_t* rgba = nullptr;
    bool second = false;
};

/// A material as the draw pass applies it, glTF's metallic-roughness model:
/// base colour factor times an optional texture, metallic and roughness
/// factors times an optional metallic-roughness texture (B, G), ambient
/// occlusion, emission, and the alpha mode.
struct SurfaceMaterial {
    glm::vec4 baseColor{1.0f};
    SurfaceTexture baseColorTexture;  ///< sRGB-coded, through the first UV channel
    /// The wrap modes of the first and second UV channels' textures (GL's
    /// codes, as glTF's samplers give them).
    int wrapS = 0x2901, wrapT = 0x2901, secondWrapS = 0x2901, secondWrapT = 0x2901;
    int alphaMode = 0;  ///< 0 opaque, 1 mask, 2 blend
    float alphaCutoff = 0.5f;
    /// glTF's emissive colour (linear), times its texture (sRGB-coded),
    /// added to the lit colour.
    glm::vec3 emissive{0.0f};
    SurfaceTexture emissiveTexture;
    float metallic = 1.0f, roughness = 1.0f;  ///< glTF's factors (and defaults)
    /// The metallic-roughness texture (linear: G roughness, B metallic) and
    /// the occlusion texture (linear R, mixed in by occlusionStrength).
    SurfaceTexture metallicRoughnessTexture, occlusionTexture;
    float occlusionStrength = 1.0f;
    /// The tangent-space normal texture (linear, glTF's: X along +u, Y
    /// along -v, each frame derived per pixel from the surface's position
    /// and UV derivatives), its X and Y times normalScale.
    SurfaceTexture normalTexture;
    float normalScale = 1.0f;
};

/// A run of refined faces drawn with one material.
struct MaterialRange {
    size_t firstFace = 0, faceCount = 0;
    int material = 0;
    bool flat = false;  ///< shaded with face normals (a glTF primitive drawn flat)
};

/// Stage times of the last update() and draw(), in milliseconds, as
/// EvaluatorTimings measures them (only filled while timing is enabled,
/// which finishes each stage before the next).
struct GpuTimings {
    double uploadMs = 0.0, stencilMs = 0.0, normalsMs = 0.0, drawMs = 0.0;
};

/// The viewer's line shaders (grid, axes): the source of one stage
/// (GL_VERTEX_SHADER or GL_FRAGMENT_SHADER), ready for buildProgram.
std::string linesShaderSource(GLenum stage);

class GpuSurface {
public:
    /// Needs a current GL 4.5 context.  shadingNormals: run the normal pass
    /// (off: shade with the interpolated direction).
    static Status create(std::unique_ptr<GpuSurface>* out, const Plan& plan, bool shadingNormals = true);
    ~GpuSurface();
    GpuSurface(const GpuSurface&) = delete;
    GpuSurface& operator=(const GpuSurface&) = delete;

    /// The evaluator that refines and displaces what is drawn.
    Evaluator& evaluator() { return *evaluator_; }

    /// Forwarded to the evaluator (evaluator.h).
    Status setDisplacementMap(const DisplacementMap& map) { return evaluator_->setDisplacementMap(map); }
    Status setDisplacements(const float* values, size_t count) { return evaluator_->setDisplacements(values, count); }
    void setDisplacementScale(float scale) { evaluator_->setDisplacementScale(scale); }
    void setSampleFilter(SampleFilter filter) { evaluator_->setSampleFilter(filter); }
    void setShadingNormals(bool on) { evaluator_->setShadingNormals(on); }
    /// Per refined vertex values for ColorMode::Error (null clears them).
    void setVertexErrors(const float* errors);

    /// Materials for the shaded view: ranges of refined faces, each drawn
    /// with its material, the texture sampled through cornerUVs (3 per
    /// refined face, refined like the plan's UVs) and multiplied by
    /// cornerColours (linear RGBA, the same count; empty: white), as glTF
    /// multiplies COLOR_0.  Textures are read as sRGB-coded, the factor and
    /// colours as linear; the result is shown sRGB-coded.  Without
    /// materials the surface is drawn in DrawParams::baseColor.  Blended
    /// ranges are drawn last, without depth writes.  cornerUVs2: the second
    /// UV channel's (the same count), for materials whose emissive texture
    /// reads it; empty where none does.
    Status setMaterials(const std::vector<SurfaceMaterial>& materials, const std::vector<MaterialRange>& ranges,
                        const std::vector<glm::vec2>& cornerUVs, const std::vector<glm::vec4>& cornerColours = {},
                        const std::vector<glm::vec2>& cornerUVs2 = {});

    /// Uploads the control positions and normals (count must match the
    /// plan) and runs the evaluator's passes.
    Status update(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count);
    void draw(const DrawParams& params);

    /// Adaptive level of detail (adaptive.h): the frame goes up when its
    /// levels change (setAdaptive), each pose is evaluated over the frame's
    /// vertices (updateAdaptive) and drawn with one glDrawElementsIndirect
    /// (drawAdaptive).  ColorMode::Error then shows each control face's
    /// level in false colour over DrawParams::colorRange (0..finest).
    Status setAdaptive(const AdaptiveFrame& frame);
    /// The shaded view of the adaptive frame set last with setMaterials'
    /// materials: ranges of the frame's triangles (each range's material
    /// an index into setMaterials' list), the texture sampled through
    /// cornerUVs (3 per frame triangle) times cornerColours, and the second
    /// channel's cornerUVs2 (as setMaterials).  Cleared by setAdaptive.
    Status setAdaptiveMaterials(const std::vector<MaterialRange>& ranges, const std::vector<glm::vec2>& cornerUVs,
                                const std::vector<glm::vec4>& cornerColours = {},
                                const std::vector<glm::vec2>& cornerUVs2 = {});
    Status updateAdaptive(const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t count);
    void drawAdaptive(const DrawParams& params);

    /// Displaced positions as the vertex shader computes them.
    Status readPositions(std::vector<glm::vec3>* out);
    /// Shading normals from the normal pass.
    Status readNormals(std::vector<glm::vec3>* out) { return evaluator_->readNormals(out); }

    void setTiming(bool on);
    const GpuTimings& timings() const { return timings_; }

    size_t vertexCount() const { return evaluator_->vertexCount(); }
    size_t faceCount() const { return evaluator_->faceCount(); }
    size_t gpuBytes() const { return evaluator_->gpuBytes() + ownBytes_; }

private:
    GpuSurface() = default;
    // Corner-ordered draws of `ranges` (gl_VertexID a corner of `triangles`).
    // cornerColours, cornerUVs2: 0 for none.
    void drawMaterials(GLuint program, const std::vector<MaterialRange>& ranges, GLuint triangles, GLuint cornerUVs,
                       GLuint cornerColours, GLuint cornerUVs2, GLuint vao);
    void sortBlendedLast(std::vector<MaterialRange>* ranges) const;
    void deleteMaterialTextures();  // every material's GL textures
    void upload(GLuint* buffer, size_t* capacity, const void* data, size_t bytes);
    void takeTimings();  // the evaluator's stage times of the last update, when timing
    void setDrawUniforms(GLuint program, const DrawParams& params, ColorMode mode) const;
    static void beginWireframe(const DrawParams& params);
    template <typename Draw>
    static void endWireframe(const DrawParams& params, GLuint program, const Draw& draw);  // the edges over the surface

    std::unique_ptr<Evaluator> evaluator_;
    bool timing_ = false, haveErrors_ = false;
    size_t ownBytes_ = 0;
    struct GpuMaterial {
        SurfaceMaterial material;
        GLuint texture = 0, emissiveTexture = 0, metallicRoughnessTexture = 0, occlusionTexture = 0,
               normalTexture = 0;
    };
    std::vector<GpuMaterial> materials_;
    std::vector<MaterialRange> ranges_;
    GLuint errors_ = 0, feedback_ = 0, cornerUVs_ = 0, cornerColours_ = 0, cornerUVs2_ = 0;  // the draw pass's only
    GLuint vao_ = 0, cornerVao_ = 0;
    GLuint surface_ = 0, feedbackProgram_ = 0;
    GLuint adaptiveProgram_ = 0, adaptiveVao_ = 0, triangleLevels_ = 0;  // the adaptive draw
    size_t triangleLevelsCapacity_ = 0;
    std::vector<MaterialRange> adaptiveRanges_;  // over the adaptive frame's triangles
    GLuint adaptiveCornerUVs_ = 0, adaptiveCornerColours_ = 0, adaptiveCornerUVs2_ = 0;
    size_t adaptiveCornerUVsCapacity_ = 0, adaptiveCornerColoursCapacity_ = 0, adaptiveCornerUVs2Capacity_ = 0;
    bool adaptiveHasColours_ = false, adaptiveHasUVs2_ = false;
    GLuint feedbackTarget_ = 0, feedbackColor_ = 0;
    GpuTimings timings_;
};

}  // namespace gl
}  // namespace strata
