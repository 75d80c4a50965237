// Angle-weighted control vertex normals (paper eq. 1's n_r, n_s, n_t).
#include "strata/normals.h"

#include <glm/geometric.hpp>

#include <cmath>

namespace strata {
namespace {

// Interior angle between unit-free edge vectors a and b, robust near 0 and pi
// (atan2 of |a x b| and a.b avoids acos's loss of precision).
float angleBetween(const glm::vec3& a, const glm::vec3& b, const glm::vec3& cross)
{
    return std::atan2(glm::length(cross), glm::dot(a, b));
}

}  // namespace

void computeControlNormals(glm::vec3* dst, const glm::vec3* positions, size_t vertexCount, const uint32_t* triangles,
                           size_t faceCount)
{
    for (size_t i = 0; i < vertexCount; ++i)
        dst[i] = glm::vec3(0.0f);

    for (size_t f = 0; f < faceCount; ++f) {
        const uint32_t i0 = triangles[3 * f + 0], i1 = triangles[3 * f + 1], i2 = triangles[3 * f + 2];
        const glm::vec3 p0 = positions[i0], p1 = positions[i1], p2 = positions[i2];
        const glm::vec3 e01 = p1 - p0, e12 = p2 - p1, e20 = p0 - p2;
        const glm::vec3 n = glm::cross(e01, -e20);
        const float len = glm::length(n);
        if (!(len > 0.0f))
            continue;  // degenerate triangle: no direction to contribute
        const glm::vec3 unit = n / len;
        // The cross product of the two edges at a corner has length 2*area for
        // every corner, so |n| serves as the sine term for all three angles.
        dst[i0] += unit * angleBetween(e01, -e20, n);
        dst[i1] += unit * angleBetween(e12, -e01, n);
        dst[i2] += unit * angleBetween(e20, -e12, n);
    }

    for (size_t i = 0; i < vertexCount; ++i) {
        const float len = glm::length(dst[i]);
        dst[i] = len > 0.0f ? dst[i] / len : glm::vec3(0.0f);
    }
}

void buildVertexFaces(std::vector<uint32_t>* offsets, std::vector<uint32_t>* faces, const uint32_t* triangles,
                      size_t faceCount, size_t vertexCount)
{
    offsets->assign(vertexCount + 1, 0);
    for (size_t i = 0; i < 3 * faceCount; ++i)
        ++(*offsets)[triangles[i] + 1];
    for (size_t v = 0; v < vertexCount; ++v)
        (*offsets)[v + 1] += (*offsets)[v];
    faces->resize(3 * faceCount);
    std::vector<uint32_t> fill(offsets->begin(), offsets->end() - 1);
    for (size_t f = 0; f < faceCount; ++f)
        for (int k = 0; k < 3; ++k)
            (*faces)[fill[triangles[3 * f + size_t(k)]]++] = uint32_t(f);
}

}  // namespace strata
