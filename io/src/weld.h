// Internal: welding by exact position, O(n log n) whatever the input (a sort,
// not a hash table an adversary could fill with collisions).
#pragma once

#include <glm/vec3.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <vector>

namespace strata {
namespace io {

/// ids[i]: the welded vertex of point i, numbered by first occurrence;
/// unique: one position per welded vertex.  -0 and +0 are one coordinate.
inline void weldByPosition(const glm::vec3* points, size_t n, std::vector<uint32_t>* ids, std::vector<glm::vec3>* unique)
{
    std::vector<std::array<uint32_t, 3>> keys(n);
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            const float v = points[i][c] == 0.0f ? 0.0f : points[i][c];
            std::memcpy(&keys[i][size_t(c)], &v, 4);
        }
    std::vector<uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return keys[a] != keys[b] ? keys[a] < keys[b] : a < b; });
    std::vector<uint32_t> first(n);
    for (size_t k = 0; k < n;) {
        size_t j = k;
        while (j < n && keys[order[j]] == keys[order[k]])
            first[order[j++]] = order[k];  // the group's smallest index
        k = j;
    }
    ids->assign(n, 0);
    unique->clear();
    for (size_t i = 0; i < n; ++i) {
        if (first[i] == i) {
            (*ids)[i] = uint32_t(unique->size());
            unique->push_back(points[i]);
        } else {
            (*ids)[i] = (*ids)[first[i]];
        }
    }
}

}  // namespace io
}  // namespace strata
