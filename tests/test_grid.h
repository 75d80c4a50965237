// The flat grid cage several tests share.  Runtime types only, so that the
// runtime-alone test build (-DSTRATA_BUILD_IO=OFF) can include it.
#pragma once

#include "strata/control_mesh.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstdint>

namespace strata {
namespace test {

/// The unit square as a grid of n x n cells, two triangles each, UV = (x, y).
inline ControlMesh makeGrid(int n)
{
    ControlMesh m;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) {
            m.positions.push_back(glm::vec3(float(x) / float(n), float(y) / float(n), 0.0f));
            m.uvs.push_back(glm::vec2(float(x) / float(n), float(y) / float(n)));
        }
    auto id = [n](int x, int y) { return uint32_t(y * (n + 1) + x); };
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            for (uint32_t v : {id(x, y), id(x + 1, y), id(x + 1, y + 1), id(x, y), id(x + 1, y + 1), id(x, y + 1)})
                m.triangles.push_back(v);
        }
    m.uvIndices = m.triangles;
    return m;
}

} // namespace test
} // namespace strata
