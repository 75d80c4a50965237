// Strata runtime: the scalar displacement map D^H (paper sections 2.2, 3.2.4).
#pragma once

#include "strata/status.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <vector>

namespace strata {

/// A single-channel image of distances, row-major, row 0 at v = 0 (glTF's
/// UV convention).  Distances decode as texel * factor + offset.
struct DisplacementMap {
    int width = 0;
    int height = 0;
    std::vector<float> texels;  ///< width * height values
    float factor = 1.0f;        ///< displacementGeometryFactor
    float offset = 0.0f;        ///< displacementGeometryOffset

    float texel(int x, int y) const { return texels[size_t(y) * size_t(width) + size_t(x)]; }
};

/// Largest map side the runtime accepts (the baker caps at 8192 as well).
constexpr int kMaxDisplacementMapSize = 16384;

/// Checks dimensions, texel count, finiteness of every texel, factor and offset.
Status validateDisplacementMap(const DisplacementMap& map);

/// Bilinear sample of the decoded distance at uv (clamp-to-edge), using the
/// formulas of displacement_math.h.  \pre validateDisplacementMap(map) passed.
float sampleDisplacement(const DisplacementMap& map, glm::vec2 uv);

}  // namespace strata
