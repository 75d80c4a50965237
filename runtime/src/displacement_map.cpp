// Bilinear displacement sampling (paper section 2.3: "sampling the
// displacement image D^H for any point on the low-resolution model").
#include "strata/displacement_map.h"

#include "strata/displacement_math.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace strata {

Status validateDisplacementMap(const DisplacementMap& map)
{
    if (map.width <= 0 || map.height <= 0)
        return Status(StatusCode::InvalidData, "displacement map has no texels (" + std::to_string(map.width) + "x" +
                                                   std::to_string(map.height) + ")");
    if (map.width > kMaxDisplacementMapSize || map.height > kMaxDisplacementMapSize)
        return Status(StatusCode::InvalidData, "displacement map is " + std::to_string(map.width) + "x" +
                                                   std::to_string(map.height) + ", larger than the supported " +
                                                   std::to_string(kMaxDisplacementMapSize) + " per side");
    if (map.texels.size() != size_t(map.width) * size_t(map.height))
        return Status(StatusCode::InvalidData, "displacement map holds " + std::to_string(map.texels.size()) +
                                                   " texels, expected " + std::to_string(map.width) + "x" +
                                                   std::to_string(map.height));
    if (!std::isfinite(map.factor) || !std::isfinite(map.offset))
        return Status(StatusCode::InvalidData, "displacement map scale or bias is not finite");
    for (size_t i = 0; i < map.texels.size(); ++i) {
        if (!std::isfinite(map.texels[i]))
            return Status(StatusCode::InvalidData, "displacement map texel (" + std::to_string(i % size_t(map.width)) +
                                                       ", " + std::to_string(i / size_t(map.width)) +
                                                       ") is not finite");
    }
    return Status::ok();
}

float sampleDisplacement(const DisplacementMap& map, glm::vec2 uv)
{
    glm::ivec2 t0;
    glm::vec2 frac;
    shared::strata_bilinear_footprint(uv, glm::ivec2(map.width, map.height), t0, frac);
    const glm::ivec2 t1 = shared::strata_far_texel(t0, glm::ivec2(map.width, map.height));
    const float v = shared::strata_bilinear(map.texel(t0.x, t0.y), map.texel(t1.x, t0.y), map.texel(t0.x, t1.y),
                                            map.texel(t1.x, t1.y), frac);
    return shared::strata_decode_distance(v, map.factor, map.offset);
}

}  // namespace strata
