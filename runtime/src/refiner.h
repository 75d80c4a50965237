// Internal to strata_runtime: the OpenSubdiv refiner that plans and the
// per-vertex displacement codec's hierarchy share.  Not installed.
#pragma once

#include "strata/control_mesh.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <opensubdiv/far/topologyRefiner.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace strata {
namespace detail {

/// The sharp (linear) refiner of a control mesh, refined uniformly to
/// level; null when OpenSubdiv rejects the topology.
std::unique_ptr<OpenSubdiv::Far::TopologyRefiner> createUniformRefiner(const ControlMesh& mesh, int level);

/// Levels a plan and the helpers accept, with the one message for the rest.
Status checkLevel(int level);

/// refineFaceVarying, also handing back what the same refinement knows of
/// the refined vertices (when the pointers are not null): each refined
/// face's three vertices and the level's vertex count.
Status refineCorners(FaceVaryingRefinement* out, std::vector<uint32_t>* faceVertices, size_t* vertexCount,
                     const ControlMesh& mesh, const uint32_t* cornerValues, size_t valueCount, int level);

}  // namespace detail
}  // namespace strata
