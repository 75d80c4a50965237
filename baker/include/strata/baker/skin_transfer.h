// Strata baker: skin weights carried from a captured character onto the
// control mesh made from it (--control auto on a skinned glTF).
#pragma once

#include "strata/animation.h"
#include "strata/baker/bake.h"
#include "strata/baker/distance.h"
#include "strata/control_mesh.h"
#include "strata/status.h"

namespace strata {
namespace baker {

/// Weights for every vertex of `cage` from the capture's (`highWeights`,
/// one set per capture vertex): each cage vertex takes the weights at its
/// nearest point on the capture (`index`, built over `high`), blended over
/// that triangle's corners by its barycentrics, keeping the strongest
/// highWeights.influences joints, renormalised to sum to 1.
Status transferSkinWeights(const ControlMesh& cage, const TriangleMesh& high, const TriangleIndex& index,
                           const VertexWeights& highWeights, VertexWeights* out, int threads = 1);

}  // namespace baker
}  // namespace strata
