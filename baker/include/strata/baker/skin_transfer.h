// Strata baker: skin weights carried from a captured character onto the
// control mesh made from it (--control auto on a skinned glTF).
#pragma once

#include "strata/animation.h"
#include "strata/baker/bake.h"
#include "strata/baker/distance.h"
#include "strata/control_mesh.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <utility>
#include <vector>

namespace strata {
namespace baker {

/// The pieces of a capture of separate parts (bake.h's ShellLabels) for the
/// weights' nearest-point searches: a cage vertex, and a point of its
/// refinement, take their weights from their own piece of the capture
/// alone, not from a neighbouring part that passes close by.  Null: any.
struct SkinShells {
    const uint32_t* cageVertex = nullptr;  ///< per cage vertex: its piece
    const uint32_t* highFace = nullptr;    ///< per capture triangle: its piece
};

/// Weights for every vertex of `cage` from the capture's (`highWeights`,
/// one set per capture vertex): each cage vertex takes the weights at its
/// nearest point on the capture (`index`, built over `high`), blended over
/// that triangle's corners by its barycentrics, keeping the strongest
/// highWeights.influences joints, renormalised to sum to 1.
Status transferSkinWeights(const ControlMesh& cage, const TriangleMesh& high, const TriangleIndex& index,
                           const VertexWeights& highWeights, VertexWeights* out, int threads = 1,
                           SkinShells shells = {});

/// What fitSkinWeights did: how far the layered surface's points move from
/// where the capture moves them, RMS over the points and poses, in model
/// units, with the weights it was given and with the fitted ones.
struct SkinFitReport {
    size_t poses = 0, points = 0;
    double before = 0.0, after = 0.0;
};

/// The poses fitSkinWeights fits over (and the automatic cage's
/// decimation weighs): 12 evenly spaced times of every animation, between
/// its ends, at most 48 in all (fewer where their skin matrices would pass
/// 64 MB: 16 for 65,535 joints).  Each pose's skin matrices, pose-major
/// (skeleton.skin.joints.size() per pose); empty without animations.
/// `times`, when given, receives each pose's animation and time.
void sampleSkinPoses(const Skeleton& skeleton, std::vector<glm::mat4>* skins,
                     std::vector<std::pair<size_t, float>>* times = nullptr);

/// `count` positions, skinned by `weights` (one set per position, each
/// joint below jointCount, as finalizeSkeleton checks), posed by the
/// runtime's skinLinear at each pose of `skins` (jointCount matrices a
/// pose): out[pose * count + v].
void skinPositions(const glm::vec3* positions, size_t count, const VertexWeights& weights,
                   const std::vector<glm::mat4>& skins, size_t jointCount, std::vector<glm::vec3>* out,
                   int threads = 1);

/// Refits a cage's skin `weights` (transferSkinWeights's) over the
/// skeleton's animations.  A weight taken at one nearest point samples the
/// capture's weight field where it changes fastest, at the joints: posed,
/// the layered surface bent differently from the capture around it.
///
/// Every refined vertex of `plan` (the cage's refinement, its layer's
/// displacements set) is a point b = sum_k a_k c_k of the cage, displaced
/// to the capture.  The capture moves it with its own weights W at its
/// nearest point: sum_j W_j S_j b, S_j the skin matrices of a pose.  The
/// layered surface moves it by sum_k a_k (sum_j w_kj S_j) c_k.  The fit
/// minimises the squared difference over every point and pose (12 evenly
/// spaced times per animation, at most 48 in all, between the times
/// BakeJob measures), cage vertex by cage vertex (Gauss-Seidel, until a
/// sweep gains under 1%), each vertex's weights non-negative, summing to 1,
/// on at most weights->influences of the joints its points' capture
/// weights name, drawn weakly towards the weights it was given.  A vertex
/// whose fit would not lower the sum keeps its weights.  The displacement
/// is taken to turn with the capture (the posed normal is not part of the
/// fit).  Without animations the weights are left as they are.
Status fitSkinWeights(const Plan& plan, const ControlMesh& cage, const TriangleMesh& high, const TriangleIndex& index,
                      const VertexWeights& highWeights, const Skeleton& skeleton, VertexWeights* weights,
                      SkinFitReport* report = nullptr, int threads = 1, SkinShells shells = {});

}  // namespace baker
}  // namespace strata
