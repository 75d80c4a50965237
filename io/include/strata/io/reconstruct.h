// Strata io: one-call reconstruction of a rig at level N, for tools and tests.
#pragma once

#include "strata/displacement_map.h"
#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace io {

struct Reconstruction {
    std::unique_ptr<Plan> plan;
    std::vector<glm::vec3> controlNormals;  ///< of the pose that was evaluated
    std::vector<glm::vec3> positions;       ///< displaced refined positions
    std::vector<glm::vec3> normals;         ///< shading normals of the displaced mesh
};

/// Builds a plan for rig.mesh, applies `map` (nullptr: no displacement) scaled
/// by `scale`, and evaluates the bind pose.
Status reconstruct(Reconstruction* out, const Rig& rig, const DisplacementMap* map, Scheme scheme, int level,
                   float scale = 1.0f);

/// Writes a reconstruction (positions, shading normals, refined UVs) by extension.
Status writeReconstruction(const std::string& path, const Reconstruction& rec);

}  // namespace io
}  // namespace strata
