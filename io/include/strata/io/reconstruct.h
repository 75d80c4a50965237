// Strata io: one-call reconstruction of a rig at level N, for tools and tests.
#pragma once

#include <filesystem>

#include "strata/animation.h"
#include "strata/displacement_map.h"
#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/status.h"
#include "strata/surface.h"

#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace io {

/// A rig's Surface and one evaluated frame of it.
struct Reconstruction {
    std::unique_ptr<Surface> surface;
    std::vector<glm::vec3> positions;  ///< displaced refined positions
    std::vector<glm::vec3> normals;    ///< shading normals of the displaced mesh
    const Plan& plan() const { return surface->plan(); }
};

/// A pose of a skinned rig: animation index (-1: the nodes' rest pose) and time.
struct Pose {
    int animation = -1;
    float time = 0.0f;
    SkinningMethod method = SkinningMethod::Linear;
};

/// A Surface of the rig (options as Surface::create; `map` as there),
/// evaluated in the bind pose, or at `pose` when the rig is skinned.
Status reconstruct(Reconstruction* out, const Rig& rig, const DisplacementMap* map, const SurfaceOptions& options,
                   const Pose* pose = nullptr);

/// The same with the displacement applied when `map` is given (an empty
/// map for a rig that stores its values per vertex) in `scheme` at `level`.
Status reconstruct(Reconstruction* out, const Rig& rig, const DisplacementMap* map, Scheme scheme, int level,
                   float scale = 1.0f, const Pose* pose = nullptr);

/// Re-evaluates an existing reconstruction at another pose (same surface).
Status reconstructPose(Reconstruction* rec, const Pose& pose);

/// The adaptive frame of a reconstruction's surface for one view, in the
/// reconstruction's pose (Surface::chooseFaceLevels at its level as the
/// finest), and how far it strays from the finest surface on screen.
struct AdaptiveView {
    std::vector<glm::vec3> positions, normals;  ///< surface->adaptiveFrame().vertexCount() each
    float maxPixelError = 0.0f;                 ///< AdaptiveFrame::maxScreenDeviation against rec.positions (measure)
    std::vector<size_t> facesPerLevel;          ///< control faces at each level 0..finest (a split face: its finest quarter's)
    size_t splitFaces = 0;                      ///< control faces drawn as quarters of mixed levels
};
/// measure: also measure maxPixelError (a pass over every finest vertex; a
/// caller that only wants the mesh skips it).
Status reconstructView(AdaptiveView* out, Reconstruction& rec, const ViewSpec& view, float pixelError,
                       bool measure = true);

/// Writes an adaptive view (positions, shading normals unless `normals` is
/// false, UVs per corner when the rig has them) by extension.
Status writeAdaptiveView(const std::filesystem::path& path, Reconstruction& rec, const AdaptiveView& view,
                         bool normals = true);

/// Writes a reconstruction (positions, shading normals unless `normals` is
/// false, refined UVs) by extension.  Without normals a glTF viewer draws
/// the mesh with face normals (a rig whose parts are all RigPart::flat).
Status writeReconstruction(const std::filesystem::path& path, const Reconstruction& rec, bool normals = true);

/// Writes a bind-pose reconstruction of a rig loaded from glTF as the rig's
/// own scene (.glb/.gltf): every control primitive replaced by its refined,
/// displaced faces, in its mesh's space, with material UVs, colours and
/// custom attributes refined linearly through the same faces, and skinned
/// parts carrying JOINTS/WEIGHTS refined from the control vertices' (blended
/// by each refined vertex's barycentric weights, renormalised, at most 8).
/// Materials, textures, skin, skeleton, animations, names and extras stay,
/// so the detailed character plays in any glTF viewer.  The displacement
/// block and map are left out.  `notes` receives what was not carried
/// (tangents, morph targets).
Status writeReconstructedScene(const std::filesystem::path& path, const Rig& rig, const Reconstruction& rec,
                               std::vector<std::string>* notes = nullptr);

/// Peak memory, in bytes, of reconstructing `rig` at `level` in `scheme`
/// and writing it to a file with extension `outputExt` (".ply", ".obj",
/// ".glb", ".gltf"; `scene`: as writeReconstructedScene, with refined skin
/// and attributes), with a map of `mapTexels` texels: calibrated against
/// the measured peak of strata-reconstruct (CesiumMan and spot, levels 4-6,
/// both schemes, every format: docs/RESULTS.md), within 20% of it.
double reconstructionPeakBytes(const Rig& rig, Scheme scheme, int level, const std::string& outputExt, bool scene,
                               double mapTexels);

}  // namespace io
}  // namespace strata
