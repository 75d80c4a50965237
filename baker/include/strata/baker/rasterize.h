// Strata baker: forward mapping of the high-resolution triangles into the
// displacement map (paper 2.2 eq. 3-5 and 3.2.2), border triangles included.
#pragma once

#include "strata/baker/mapping.h"
#include "strata/baker/surface.h"

#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

/// What a texel keeps when several layers of the high-resolution surface
/// map onto it (overfolds, paper 3.2.3).
enum class OverlapPolicy {
    Max,      ///< the paper's rule: the largest distance (the outer envelope)
    Nearest,  ///< the smallest |d|: the layer closest to the control surface
};

struct RasterStats {
    size_t triangles = 0;
    size_t degenerateTriangles = 0;  ///< zero-area high-res triangles, skipped
    size_t borderTriangles = 0;      ///< vertices mapped to different control triangles
    size_t pieces = 0;               ///< (high-res triangle, control triangle) pairs rasterised
    size_t coveredTexels = 0;
    size_t multiLayerTexels = 0;     ///< texels hit by more than one layer
};

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
