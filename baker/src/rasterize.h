// Internal: forward mapping of the high-resolution triangles into the
// displacement map (paper 2.2 eq. 3-5 and 3.2.2), border triangles included.
#pragma once

#include "mapping.h"
#include "strata/baker/bake.h"
#include "strata/baker/surface.h"

#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

struct RasterResult {
    int size = 0;
    std::vector<float> distance;    ///< size * size, valid where layers > 0
    std::vector<uint16_t> layers;   ///< how many surface layers hit each texel (paper Fig. 6f)
    RasterStats stats;
};

/// Rasterises every high-resolution triangle into a size x size map.  A
/// triangle whose vertices map to one bake-surface triangle r is drawn in r's
/// UV triangle with d interpolated linearly (eq. 5).  A border triangle is
/// re-mapped into the plane of each triangle it touches (its vertices'
/// triangles and, where those are not edge-adjacent, the triangles around
/// their shared vertices), with negative barycentrics allowed, and each copy
/// is clipped to that triangle's UV triangle (3.2.2).  Texel centres on shared
/// edges belong to exactly one triangle (a consistent fill rule), so layer
/// counts are exact.  Rows are split among threads; the result is identical
/// for any thread count.
void rasterize(RasterResult* out, const SurfaceIndex& index, const glm::vec3* highPositions,
               const uint32_t* highTriangles, size_t highFaceCount, const std::vector<VertexMapping>& mapping,
               int size, OverlapPolicy policy, int threads);

}  // namespace baker
}  // namespace strata
