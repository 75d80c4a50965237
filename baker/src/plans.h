// The baker's refinement plans.  One bake makes several plans of a cage's
// topology at one level with other positions or UVs (the cage fit, the
// smooth bake surface, each closed loop of the scheme probe and the map
// size search).  The smooth scheme's limit stencils, most of such a plan's
// cost, follow from the topology and level alone, so the last smooth plan's
// are kept and lent (Plan::create's sameTopology).
#pragma once

#include "strata/plan.h"

#include <memory>

namespace strata {
namespace baker {

/// Plan::create, lending the limit stencils of the last smooth plan made
/// here when the topology and level are the same.  Thread-safe.
Status createPlan(std::unique_ptr<Plan>* out, const ControlMesh& mesh, Scheme scheme, int level);

}  // namespace baker
}  // namespace strata
