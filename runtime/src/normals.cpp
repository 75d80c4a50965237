// Angle-weighted control vertex normals (paper eq. 1's n_r, n_s, n_t).
#include "strata/normals.h"

#include "simd.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {
namespace {

// The interior angle whose sine and cosine are proportional to y >= 0 and
// x: atan2(y, x) in [0, pi], written so that a loop of them vectorises (no
// branches, no library call).  The ratio of the smaller to the larger of y
// and |x| is in [0, 1]; above tan(pi/8) it is reduced by the pi/4 identity,
// and atan there is Cephes's single-precision polynomial (about 2 ulp).
STRATA_KERNEL_INLINE float cornerAngle(float y, float x)
{
    const float ax = std::fabs(x);
    const float big = std::max(ax, y), small = std::min(ax, y);
    const float t = small / std::max(big, std::numeric_limits<float>::min());  // 0 when both are 0
    // Every branch is a blend with a 0/1 factor or a selected constant: GCC
    // does not if-convert a condition that guards arithmetic (it may trap),
    // and the loop then stays scalar.  The division is always done (t + 1 >= 1).
    const float reduce = t > 0.414213562373095f ? 1.0f : 0.0f;  // tan(pi/8)
    const float reduced = (t - 1.0f) / (t + 1.0f);
    const float u = t + reduce * (reduced - t);
    const float z = u * u;
    const float poly = (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
                        3.33329491539e-1f) * z * u + u;
    const float r = reduce * 0.785398163397448f + poly;  // atan(small / big)
    const bool steep = y > ax, obtuse = x < 0.0f;
    const float q = (steep ? 1.57079632679490f : 0.0f) + (steep ? -1.0f : 1.0f) * r;
    return (obtuse ? 3.14159265358979f : 0.0f) + (obtuse ? -1.0f : 1.0f) * q;
}

STRATA_KERNEL_CLONES void cornerAngles(size_t n, const float* y, const float* x, float* __restrict angle)
{
    for (size_t i = 0; i < n; ++i)
        angle[i] = cornerAngle(y[i], x[i]);
}

}  // namespace

void computeControlNormals(glm::vec3* dst, const glm::vec3* positions, size_t vertexCount, const uint32_t* triangles,
                           size_t faceCount)
{
    for (size_t i = 0; i < vertexCount; ++i)
        dst[i] = glm::vec3(0.0f);

    // Faces in blocks: their corners' (|a x b|, a . b) into arrays, the
    // angles in one vector loop, then each face adds its unit normal times
    // its corners' angles.  The cross product of the two edges at a corner
    // has length 2*area for every corner, so |n| is the sine term of all
    // three angles.
    constexpr size_t kBlock = 256;
    float y[3 * kBlock], x[3 * kBlock], angle[3 * kBlock];
    glm::vec3 unit[kBlock];
    for (size_t first = 0; first < faceCount; first += kBlock) {
        const size_t count = std::min(kBlock, faceCount - first);
        for (size_t k = 0; k < count; ++k) {
            const uint32_t* t = triangles + 3 * (first + k);
            const glm::vec3 p0 = positions[t[0]], p1 = positions[t[1]], p2 = positions[t[2]];
            const glm::vec3 e01 = p1 - p0, e12 = p2 - p1, e20 = p0 - p2;
            const glm::vec3 n = glm::cross(e01, -e20);
            const float len = glm::length(n);
            unit[k] = len > 0.0f ? n / len : glm::vec3(0.0f);  // degenerate: no direction to contribute
            y[3 * k] = y[3 * k + 1] = y[3 * k + 2] = len;
            x[3 * k] = glm::dot(e01, -e20);
            x[3 * k + 1] = glm::dot(e12, -e01);
            x[3 * k + 2] = glm::dot(e20, -e12);
        }
        cornerAngles(3 * count, y, x, angle);
        for (size_t k = 0; k < count; ++k) {
            if (!(y[3 * k] > 0.0f))
                continue;
            const uint32_t* t = triangles + 3 * (first + k);
            dst[t[0]] += unit[k] * angle[3 * k];
            dst[t[1]] += unit[k] * angle[3 * k + 1];
            dst[t[2]] += unit[k] * angle[3 * k + 2];
        }
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

void buildVertexFans(std::vector<uint32_t>* offsets, std::vector<uint32_t>* entries, const uint32_t* triangles,
                     size_t faceCount, size_t vertexCount)
{
    std::vector<uint32_t> faceOffsets, faces;
    buildVertexFaces(&faceOffsets, &faces, triangles, faceCount, vertexCount);
    offsets->assign(vertexCount + 1, 0);
    entries->clear();
    entries->reserve(faces.size() + faces.size() / 4);
    struct Step {
        uint32_t a, b;
        bool used;
    };
    std::vector<Step> steps;
    // A vertex's few steps are searched in place; past kFewSteps (a fan
    // of many faces), through step indices sorted by a and every b, sorted,
    // so that no vertex costs the square of its faces.  Either way the same
    // steps are found: the first unused one in face order.
    constexpr size_t kFewSteps = 16;
    std::vector<uint32_t> byA, bs;
    for (size_t v = 0; v < vertexCount; ++v) {
        steps.clear();
        uint32_t previous = UINT32_MAX;
        for (uint32_t k = faceOffsets[v]; k < faceOffsets[v + 1]; ++k) {
            const uint32_t f = faces[k];
            if (f == previous)
                continue;  // a face listed once per corner at v: two corners there, no normal at v
            previous = f;
            const uint32_t* t = triangles + 3 * size_t(f);
            const int at = t[0] == v ? 0 : t[1] == v ? 1 : 2;
            const uint32_t a = t[(at + 1) % 3], b = t[(at + 2) % 3];
            if (a != v && b != v && a != b)
                steps.push_back({a, b, false});
        }
        const uint32_t count = uint32_t(steps.size());
        const bool few = count <= kFewSteps;
        if (!few) {
            byA.resize(count);
            bs.resize(count);
            for (uint32_t i = 0; i < count; ++i) {
                byA[i] = i;
                bs[i] = steps[i].b;
            }
            std::stable_sort(byA.begin(), byA.end(), [&](uint32_t x, uint32_t y) { return steps[x].a < steps[y].a; });
            std::sort(bs.begin(), bs.end());
        }
        // Whether some step (used or not) leads into ring vertex a.
        auto isTarget = [&](uint32_t a) {
            if (!few)
                return std::binary_search(bs.begin(), bs.end(), a);
            for (uint32_t i = 0; i < count; ++i)
                if (steps[i].b == a)
                    return true;
            return false;
        };
        // The first unused step leaving ring vertex a, in face order.
        auto next = [&](uint32_t a) -> uint32_t {
            if (few) {
                for (uint32_t i = 0; i < count; ++i)
                    if (steps[i].a == a && !steps[i].used)
                        return i;
                return UINT32_MAX;
            }
            auto it = std::lower_bound(byA.begin(), byA.end(), a,
                                       [&](uint32_t i, uint32_t value) { return steps[i].a < value; });
            for (; it != byA.end() && steps[*it].a == a; ++it)
                if (!steps[*it].used)
                    return *it;
            return UINT32_MAX;
        };
        auto walk = [&](uint32_t s) {
            const uint32_t first = steps[s].a;
            entries->push_back(first | kFanStart);
            for (uint32_t i = s; i != UINT32_MAX;) {
                steps[i].used = true;
                if (steps[i].b == first) {  // back at the start: the last step closes the ring
                    entries->back() |= kFanClose;
                    break;
                }
                entries->push_back(steps[i].b);
                i = next(steps[i].b);
            }
        };
        // Open fans first, from steps that no other step leads into (a
        // boundary), then the closed rings that remain.
        for (uint32_t i = 0; i < count; ++i)
            if (!steps[i].used && !isTarget(steps[i].a))
                walk(i);
        for (uint32_t i = 0; i < count; ++i)
            if (!steps[i].used)
                walk(i);
        (*offsets)[v + 1] = uint32_t(entries->size());
    }
}

void computeFanNormals(glm::vec3* dst, const glm::vec3* positions, size_t vertexCount, const uint32_t* offsets,
                       const uint32_t* entries)
{
    for (size_t v = 0; v < vertexCount; ++v) {
        const glm::vec3 p = positions[v];
        glm::vec3 sum(0.0f), first(0.0f), prev(0.0f);
        for (uint32_t k = offsets[v]; k < offsets[v + 1]; ++k) {
            const uint32_t e = entries[k];
            const glm::vec3 q = positions[e & kFanIndexMask] - p;
            if (e & kFanStart)
                first = q;
            else
                sum += glm::cross(prev, q);
            if (e & kFanClose)
                sum += glm::cross(q, first);
            prev = q;
        }
        const float len = glm::length(sum);
        dst[v] = len > 0.0f ? sum / len : glm::vec3(0.0f);
    }
}

}  // namespace strata
