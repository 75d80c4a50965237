// Strata baker: texels forward mapping leaves empty.
//
// Where normal volumes overlap (concave control regions) a surface point
// belongs to one volume only, so parts of a neighbouring chart can stay
// unhit; gutters are never hit.  For those texels the displacement is
// measured directly: the line of paper eq. 2 through the texel's control
// point, x(d) = p + d n, is intersected with the high-resolution mesh.
#pragma once

#include "strata/baker/distance.h"
#include "strata/baker/surface.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

/// The bake-surface face whose UV triangle holds each texel centre (-1
/// outside every chart), then grown outward by `rings` texels so gutter
/// texels know which chart's plane to extend.  chartTexels receives the
/// count of texels inside charts (before growing).
std::vector<int32_t> chartOwners(const BakeSurface& surface, int size, int rings, size_t* chartTexels);

/// For every texel with an owner and no value: evaluates p and n of eq. 2 at
/// the texel centre's barycentrics in the owner's UV triangle (negative
/// outside it: the plane extension), and takes the intersection of p + d n
/// with the mesh nearest to p (|d| <= maxDistance).  Returns how many texels
/// were filled.  Parallel over rows, deterministic.
size_t fillByLineIntersection(std::vector<float>* values, std::vector<uint8_t>* valid,
                              const std::vector<int32_t>& owners, const BakeSurface& surface,
                              const TriangleIndex& high, int size, double maxDistance, int threads);

}  // namespace baker
}  // namespace strata
