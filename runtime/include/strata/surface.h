// Strata runtime: a rig at a level, posed and evaluated every frame.
//
// Surface is the one object every front end draws through: strata-reconstruct
// (io::reconstruct), the C API, the Python module, the viewer and the benches.
// It holds the plan in the rig's own scheme, the rig's displacements, the
// animator, the control normals of the current pose and the frame evaluator,
// in the one order that gives the baked surface:
//
//     Plan::create(rig.mesh, rig.displacement.scheme, level)
//     applyRigDisplacement(plan, rig, map)        once
//     pose -> control positions -> computeControlNormals
//     FrameEvaluator::evaluate                     every frame
//
// Inputs that would draw another surface are errors, never a different
// surface: a scheme other than the one the rig was baked against (with its
// displacement), a glTF whose layer a tool dropped, a map-coded rig without
// its map, joint matrices or control positions of another count, buffers of
// another size.
//
//     std::unique_ptr<strata::Surface> surface;
//     strata::Surface::create(&surface, rig, &map);        // rig, map: io::loadRig
//     surface->setAnimationTime(0, t);                      // or joint matrices, positions
//     surface->evaluate(positions, normals, surface->vertexCount());
#pragma once

#include "strata/adaptive.h"
#include "strata/animation.h"
#include "strata/displacement_map.h"
#include "strata/frame.h"
#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <memory>
#include <string>
#include <vector>

namespace strata {

struct SurfaceOptions {
    /// Refinement level 0..kMaxLevel; -1: the rig's recommended level (0
    /// for a rig without displacement).
    int level = -1;
    /// false: the bare control mesh refined, without the displacement (then
    /// any scheme may be asked for).
    bool displace = true;
    /// Only with displace = false: the scheme to refine the bare cage in.
    /// With the displacement the rig's own scheme is used, and asking for
    /// another (schemeGiven) is refused.
    Scheme scheme = Scheme::Linear;
    bool schemeGiven = false;
    /// Multiplies every displacement (1: the baked surface).
    float scale = 1.0f;
    /// The order of the frame's vertices (frame.h).
    FrameLayout layout = FrameLayout::Plan;
    /// How setAnimationTime skins the control mesh.
    SkinningMethod method = SkinningMethod::Linear;
};

class Surface {
public:
    /// The rig at options.level in its own scheme with its displacement,
    /// in the bind pose (control positions as stored).  `map` is the rig's
    /// map when rigNeedsMap(rig) (io::loadRigDisplacementMap), else unused
    /// and may be null; for a rig assembled in memory without a layer
    /// (hasDisplacement false, not from a file) it is the caller's own map,
    /// sampled in options.scheme.  The surface keeps its own copy of the control mesh
    /// and skeleton: the rig and map need not outlive it.
    static Status create(std::unique_ptr<Surface>* out, const Rig& rig, const DisplacementMap* map,
                         const SurfaceOptions& options = {});
    /// What create would refuse about the rig and options alone, before any
    /// work (a tool checks this before it reads the map or writes a file):
    /// a level out of range, a scheme other than the baked one, a dropped
    /// layer.  Messages name no file; front ends add it and their advice.
    static Status check(const Rig& rig, const SurfaceOptions& options);
    /// The level create uses for these options.
    static int levelFor(const Rig& rig, const SurfaceOptions& options);
    /// The scheme create uses for these options.
    static Scheme schemeFor(const Rig& rig, const SurfaceOptions& options);
    ~Surface();
    Surface(const Surface&) = delete;
    Surface& operator=(const Surface&) = delete;

    int level() const;
    Scheme scheme() const;
    /// Whether the rig's displacement is applied.
    bool displaced() const { return displaced_; }
    /// Refined vertices: the size of every per-vertex buffer evaluate writes.
    size_t vertexCount() const;
    size_t triangleCount() const;
    /// The refined triangles (3 per triangle), indexing the frame's vertices.
    const std::vector<uint32_t>& triangles() const;
    /// Per frame vertex, its refined vertex in the plan (the identity in the
    /// plan's layout): to place per-vertex attributes.
    const std::vector<uint32_t>& vertexOrder() const;
    /// The refined UVs (face-varying: values and 3 indices per triangle,
    /// in the plan's vertex order); empty when the rig has no UVs.
    void refinedUVs(std::vector<glm::vec2>* values, std::vector<uint32_t>* indices) const;

    size_t controlVertexCount() const { return mesh_.vertexCount(); }
    /// The control mesh as stored (bind pose, with its UVs).
    const ControlMesh& controlMesh() const { return mesh_; }
    /// Skin joints (0 when the rig is not skinned): setJointMatrices' count.
    size_t jointCount() const { return skeleton_.skin.joints.size(); }
    size_t animationCount() const { return skeleton_.animations.size(); }

    /// The bind pose: control positions as stored.
    Status setRestPose();
    /// The largest control coordinate a pose may have: a normal's length
    /// squares a product of two coordinate differences, which overflows a
    /// float (to a zero or NaN normal) from about 1e9.5.
    static constexpr float kLargestCoordinate = 1e9f;
    /// The first of `count` positions with a coordinate that is not finite
    /// or lies beyond +-kLargestCoordinate, or `count` when none does: what
    /// a pose setter refuses (a baker posing a capture checks the same).
    static size_t firstOutOfRange(const glm::vec3* values, size_t count);
    /// The rig's animation `animation` at `time` seconds (-1: the nodes' rest
    /// pose), skinned with options.method.
    ///
    /// Every pose setter refuses a pose with a control position that is not
    /// finite or lies beyond +-kLargestCoordinate (a NaN or infinity given,
    /// a joint transform that blew up), naming the control vertex and, for
    /// a skinned pose, the joint; the surface keeps its last pose.
    Status setAnimationTime(int animation, float time);
    /// The skinning setAnimationTime uses from now on.
    void setSkinningMethod(SkinningMethod method) { method_ = method; }
    /// Skin matrices an engine computed (world * inverse bind, one per joint
    /// in the rig's order), linear blend skinning.
    Status setJointMatrices(const glm::mat4* matrices, size_t count);
    /// Control positions an engine deformed itself.
    Status setControlPositions(const glm::vec3* positions, size_t count);

    /// The current pose's displaced positions and (normals not null) shading
    /// normals into caller buffers of `count` = vertexCount() elements, on
    /// `threads` threads; bit-identical for any thread count.  Not
    /// re-entrant: serialise calls on one surface.
    Status evaluate(glm::vec3* positions, glm::vec3* normals, size_t count, int threads = 1);

    /// Adaptive level of detail (adaptive.h): each control face at its own
    /// level up to level(), stitched without cracks.  The frame's vertices
    /// and triangles follow the last setFaceLevels or chooseFaceLevels.
    /// \param levels  one per control face, each 0..level()
    Status setFaceLevels(const uint8_t* levels, size_t count);
    /// The same per quarter of each control face (AdaptiveFrame::setQuarterLevels:
    /// 4 per face, all 0 or each 1..level()).
    Status setQuarterLevels(const uint8_t* quarters, size_t count);
    /// Levels for a view of the current pose: per face (and quarter of a
    /// face) the smallest level within `pixelError` pixels of level() (errors
    /// measured once, in the rest pose, at the first call; the pose's stretch
    /// of each face, however the pose was given, and a skin's scale grow
    /// them: LevelChooser::choose).  Where the frame's levels came from the last
    /// choice, each keeps its level while that still meets the tolerance
    /// and is not finer than LevelChooser::kHoldTolerance of it would
    /// choose, else takes the lowest within LevelChooser::kMotionTolerance
    /// of it, so that faces near the tolerance rise together (levels do not
    /// flip, and the frame rebuild, every frame of a moving pose or
    /// camera); for the same view, tolerance and pose as the last choice,
    /// the frame stands as it is, and while the last choice still meets the
    /// tolerance (and at most one face in LevelChooser::kRepairShare could
    /// fall to a coarser level) it stands without being made again
    /// (LevelChooser::choose).
    Status chooseFaceLevels(const ViewSpec& view, float pixelError);
    /// The chooser behind chooseFaceLevels (null before the first choice
    /// or faceLevelErrors()): its counts of full and kept choices.
    const LevelChooser* levelChooser() const { return chooser_.get(); }
    /// The errors chooseFaceLevels projects (measured on first use).
    const FaceLevelErrors& faceLevelErrors();
    /// The adaptive frame's topology: vertexCount(), triangles(),
    /// vertices() (each frame vertex's refined vertex in plan()), levels().
    /// Empty until setFaceLevels or chooseFaceLevels.
    const AdaptiveFrame& adaptiveFrame();
    /// The current pose's adaptive frame: `count` = adaptiveFrame().vertexCount()
    /// positions and (normals not null) shading normals of the adaptive
    /// triangles; allocates nothing once warmed up.
    Status evaluateAdaptive(glm::vec3* positions, glm::vec3* normals, size_t count, int threads = 1);

    /// A box that holds the current pose's surface at every level, uniform
    /// and adaptive, for culling and picking without reading the frame: the
    /// control positions' box grown on every side by the largest
    /// displacement times the longest control normal.  The refined surface
    /// lies in the control points' convex hull (the schemes' weights are not
    /// negative) and moves off it along a direction no longer than that.
    void bounds(glm::vec3* lo, glm::vec3* hi) const;

    /// The current pose's control positions and normals.
    const std::vector<glm::vec3>& controlPositions() const { return controlPositions_; }
    const std::vector<glm::vec3>& controlNormals() const { return controlNormals_; }
    /// The skin matrices of the last setAnimationTime or setJointMatrices.
    const std::vector<glm::mat4>& skinMatrices() const { return skinMatrices_; }
    /// The plan (for GPU upload and refined attributes) and its
    /// displacements, already applied.
    const Plan& plan() const { return *plan_; }

private:
    Surface() = default;
    // The refusal of a pose whose control vertex v is not finite or lies
    // beyond +-kLargestCoordinate, naming `what` (the pose), the vertex and
    // `cause` (may be empty).
    static Status poseError(const std::vector<glm::vec3>& positions, size_t v, const std::string& what,
                            const std::string& cause);
    // pendingPositions_ (and their normals) become the pose, with a new pose
    // version, where every coordinate is within +-kLargestCoordinate;
    // otherwise the pose stays (poseError).  No string is made unless refused.
    Status adoptPending(const char* what, const char* cause);
    // The first joint whose skin matrix is not finite, as "joint J (node N
    // "NAME")", or empty.
    std::string overflowingJoint(const glm::mat4* skin, size_t count) const;

    ControlMesh mesh_;
    Skeleton skeleton_;
    SkinningMethod method_ = SkinningMethod::Linear;
    bool displaced_ = false;
    float largestDisplacement_ = 0.0f;  // of plan_'s, in magnitude
    std::unique_ptr<Plan> plan_;
    std::unique_ptr<Animator> animator_;  // refers to mesh_ and skeleton_
    std::unique_ptr<FrameEvaluator> frame_;
    std::unique_ptr<AdaptiveFrame> adaptive_;
    std::unique_ptr<LevelChooser> chooser_;
    std::vector<uint8_t> chosen_;
    // The last choice: the frame's topology it set (or kept), and its
    // view, tolerance and pose.
    uint64_t chosenVersion_ = ~uint64_t(0);
    ViewSpec chosenView_;
    float chosenTolerance_ = 0.0f;
    uint64_t chosenPose_ = 0;
    // The pose: changes with every change of the control positions (and
    // their normals), never 0.
    uint64_t poseVersion_ = 1;
    std::vector<glm::vec3> controlPositions_, controlNormals_;
    std::vector<glm::vec3> pendingPositions_, pendingNormals_;  // a pose before it is adopted
    std::vector<glm::mat4> skinMatrices_;
};

}  // namespace strata
