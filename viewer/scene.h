// strata-view: what the viewer shows, independent of the window system, so
// the windowed viewer and headless screenshots render the same thing.
#pragma once

#include "strata/animation.h"
#include "strata/gl/gpu_surface.h"
#include "strata/io/materials.h"
#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/surface.h"

#include <glm/vec3.hpp>

#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace viewer {

struct Settings {
    int level = -1;  ///< -1: the rig's recommended level
    Scheme scheme = Scheme::Linear;
    bool schemeGiven = false;
    bool displacement = true;
    float scale = 1.0f;
    int animation = -1;  ///< -1: bind pose
    float time = 0.0f;
    bool playing = false;
    SkinningMethod skinning = SkinningMethod::Linear;
    bool wireframe = false, cage = false, grid = true;
    bool materials = true;  ///< draw each primitive's material (else flat grey)
    gl::ColorMode colorMode = gl::ColorMode::Shaded;
    /// Adaptive level of detail (adaptive.h): each control face at the
    /// lowest level within pixelError pixels of `level` for the current view.
    bool adaptive = false;
    float pixelError = 1.0f;
    bool levelColours = true;  ///< adaptive: each face's level in false colour
};

struct Camera {
    glm::vec3 target{0.0f};
    float distance = 3.0f, yaw = 0.5f, pitch = 0.25f, fovY = 0.7f;
};

class Scene {
public:
    Scene();
    ~Scene();

    /// Loads a rig (.glb/.gltf, with its EXR when it has one) or a plain
    /// glTF / OBJ.  On failure the previous model stays and the message
    /// says why (it is also kept in lastError()).
    Status open(const std::string& path);
    /// The high-resolution mesh for the error view (distance of every
    /// refined vertex to it, in the bind pose).
    Status openHigh(const std::string& path);

    bool loaded() const { return rig_ != nullptr; }
    const std::string& path() const { return path_; }
    const Rig* rig() const { return rig_.get(); }
    const std::string& lastError() const { return lastError_; }
    const std::string& description() const { return description_; }

    Settings settings;
    Camera camera;

    /// Applies changed settings (rebuilds the plan when level or scheme
    /// changed), advances the animation by dt when playing, and runs the
    /// GPU passes.  Errors are kept in lastError(), never thrown.
    void update(float dt);
    /// Draws into the bound framebuffer.
    void render(int width, int height);
    /// Frames the model's bounds (posed, for skinned models) so that all of
    /// it is in view at the current aspect ratio.
    void frameModel();
    /// Set once the user moves the camera: resizes stop re-framing.
    bool userCamera_ = false;

    size_t vertexCount() const { return surface_ ? surface_->vertexCount() : 0; }
    size_t faceCount() const { return surface_ ? surface_->faceCount() : 0; }
    int currentLevel() const { return builtLevel_; }
    float displacementMin() const { return dMin_; }
    float displacementMax() const { return dMax_; }
    float errorMax() const { return errorMax_; }
    bool hasHigh() const { return !highPositions_.empty(); }
    float animationLength() const;
    double cpuFrameMs() const { return cpuFrameMs_; }
    /// The adaptive frame drawn last (settings.adaptive): its vertices and
    /// triangles, its lowest and highest level, and the level choice's time.
    size_t adaptiveVertexCount() const { return adaptiveVertices_; }
    size_t adaptiveTriangleCount() const { return adaptiveTriangles_; }
    int adaptiveLevelMin() const { return adaptiveLevels_[0]; }
    int adaptiveLevelMax() const { return adaptiveLevels_[1]; }
    double adaptiveChooseMs() const { return adaptiveChooseMs_; }
    const gl::GpuTimings& gpuTimings() const;
    void setTiming(bool on);

private:
    Status rebuild();
    Status uploadMaterials();
    Status uploadAdaptiveMaterials(const AdaptiveFrame& frame);
    void computeErrors();
    void buildLines();

    std::unique_ptr<Rig> rig_;
    std::string path_, lastError_, description_;
    DisplacementMap map_;
    io::SceneMaterials materials_;
    bool builtMaterials_ = false;
    bool framePose_ = false;  ///< frame the first posed frame (skinned models)
    void drawColorScale(int width, int height);
    bool haveMap_ = false;
    // The rig's Surface at the built level: the plan and displacements the
    // GPU surface is made from, and the pose (control positions, normals).
    std::unique_ptr<Surface> cpu_;
    std::unique_ptr<gl::GpuSurface> surface_;
    bool animated_ = false;
    int builtLevel_ = -1;
    Scheme builtScheme_ = Scheme::Linear;
    bool timing_ = false;
    float dMin_ = 0.0f, dMax_ = 0.0f, errorMax_ = 0.0f, radius_ = 1.0f, aspect_ = 1.6f;
    glm::vec3 lo_{0.0f}, hi_{0.0f};
    double cpuFrameMs_ = 0.0;
    void renderAdaptive(const glm::vec3& eye, int height, gl::DrawParams* params);
    std::vector<uint8_t> drawnLevels_;  ///< the levels the GPU frame was last set up with
    size_t adaptiveVertices_ = 0, adaptiveTriangles_ = 0;
    int adaptiveLevels_[2] = {0, 0};
    double adaptiveChooseMs_ = 0.0;
    std::vector<glm::vec3> highPositions_;
    std::vector<uint32_t> highTriangles_;

    unsigned lineProgram_ = 0, lineVao_ = 0, lineBuffer_ = 0;
    int gridFirst_ = 0, gridCount_ = 0, cageFirst_ = 0, cageCount_ = 0;
    std::vector<glm::vec3> lines_;
    std::vector<uint32_t> cageEdges_;  ///< control vertex pairs, one per unique edge
};

}  // namespace viewer
}  // namespace strata
