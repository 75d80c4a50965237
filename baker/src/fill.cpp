// Backward evaluation for texels the forward mapping missed (see fill.h).
#include "strata/baker/fill.h"
#include "strata/uv_raster.h"
#include "parallel.h"

#include "mapping.h"
#include "strata/plane.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace strata {
namespace baker {

std::vector<int32_t> chartOwners(const BakeSurface& s, int size, int rings, size_t* chartTexels)
{
    std::vector<int32_t> owner(size_t(size) * size_t(size), -1);
    for (size_t f = 0; f < s.faceCount(); ++f) {
        glm::dvec2 t[3];
        for (int k = 0; k < 3; ++k)
            t[k] = glm::dvec2(s.uvs[s.uvIndices[3 * f + k]]) * double(size);
        const double area = orient2(t[0], t[1], t[2]);
        if (area == 0.0)
            continue;
        const TexelRect r = texelRect(t, size, size);
        for (int y = r.y0; y <= r.y1; ++y)
            for (int x = r.x0; x <= r.x1; ++x) {
                const glm::dvec2 c(x + 0.5, y + 0.5);
                bool in = true;
                for (int k = 0; k < 3 && in; ++k) {
                    const glm::dvec2 a = t[k], b = t[(k + 1) % 3];
                    in = orient2(a, b, c) * area >= 0.0;
                }
                int32_t& o = owner[size_t(y) * size_t(size) + size_t(x)];
                if (in && o < 0)
                    o = int32_t(f);
            }
    }
    if (chartTexels)
        *chartTexels = size_t(std::count_if(owner.begin(), owner.end(), [](int32_t o) { return o >= 0; }));
    // Grow into the gutters: a texel takes the lowest face id among its
    // owned 8-neighbours (deterministic).
    static const int dx[8] = {1, -1, 0, 0, 1, 1, -1, -1}, dy[8] = {0, 0, 1, -1, 1, -1, 1, -1};
    for (int r = 0; r < rings; ++r) {
        std::vector<int32_t> next = owner;
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x) {
                const size_t i = size_t(y) * size_t(size) + size_t(x);
                if (owner[i] >= 0)
                    continue;
                int32_t best = -1;
                for (int k = 0; k < 8; ++k) {
                    const int x1 = x + dx[k], y1 = y + dy[k];
                    if (x1 < 0 || y1 < 0 || x1 >= size || y1 >= size)
                        continue;
                    const int32_t o = owner[size_t(y1) * size_t(size) + size_t(x1)];
                    if (o >= 0 && (best < 0 || o < best))
                        best = o;
                }
                next[i] = best;
            }
        owner.swap(next);
    }
    return owner;
}

size_t fillByLineIntersection(std::vector<float>* values, std::vector<uint8_t>* valid,
                              const std::vector<int32_t>& owners, const BakeSurface& s, const TriangleIndex& high,
                              int size, double maxDistance, int threads)
{
    std::vector<uint8_t> filled(values->size(), 0);
    parallelFor(size_t(size), threads, [&](size_t yb, size_t ye) {
        for (size_t y = yb; y < ye; ++y)
            for (int x = 0; x < size; ++x) {
                const size_t i = y * size_t(size) + size_t(x);
                if ((*valid)[i] || owners[i] < 0)
                    continue;
                const size_t f = size_t(owners[i]);
                glm::dvec2 t[3];
                glm::dvec3 v[3], n[3];
                for (int k = 0; k < 3; ++k) {
                    t[k] = glm::dvec2(s.uvs[s.uvIndices[3 * f + k]]) * double(size);
                    v[k] = glm::dvec3(s.positions[s.triangles[3 * f + k]]);
                    n[k] = glm::dvec3(s.normals[s.triangles[3 * f + k]]);
                }
                const glm::dvec2 c(double(x) + 0.5, double(y) + 0.5), e1 = t[1] - t[0], e2 = t[2] - t[0],
                                 r = c - t[0];
                const double det = cross2(e1, e2);
                if (det == 0.0)
                    continue;
                const double b1 = cross2(r, e2) / det, b2 = cross2(e1, r) / det;
                const double b0 = 1.0 - b1 - b2;
                const glm::dvec3 p = b0 * v[0] + b1 * v[1] + b2 * v[2];
                const glm::dvec3 dir = b0 * n[0] + b1 * n[1] + b2 * n[2];
                double d;
                if (glm::dot(dir, dir) > 0.0 && high.intersectLine(p, dir, maxDistance, &d)) {
                    (*values)[i] = float(d);
                    filled[i] = 1;
                }
            }
    });
    size_t count = 0;
    for (size_t i = 0; i < filled.size(); ++i)
        if (filled[i]) {
            (*valid)[i] = 1;
            ++count;
        }
    return count;
}

}  // namespace baker
}  // namespace strata
