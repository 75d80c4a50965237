// Nearest-point distances between meshes (closed-loop error, paper 2.3's bound).
#include "strata/baker/distance.h"
#include "parallel.h"

#include "bvh.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace strata {
namespace baker {

TriangleIndex::TriangleIndex() : bvh_(std::make_unique<Bvh>()) {}
TriangleIndex::~TriangleIndex() = default;
TriangleIndex::TriangleIndex(TriangleIndex&&) noexcept = default;
TriangleIndex& TriangleIndex::operator=(TriangleIndex&&) noexcept = default;

void TriangleIndex::build(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount, int threads)
{
    corners_.resize(3 * faceCount);
    std::vector<Box> boxes(faceCount);
    parallelFor(faceCount, threads, [&](size_t begin, size_t end) {
        for (size_t f = begin; f < end; ++f) {
            Box box;
            bool finite = true;
            for (int k = 0; k < 3; ++k) {
                const glm::vec3 p = positions[triangles[3 * f + k]];
                corners_[3 * f + size_t(k)] = p;
                box.extend(p);
                finite = finite && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
            }
            // A triangle with a non-finite corner keeps the empty box: no
            // query meets it, and no node's box turns NaN (which would make
            // every walk visit the whole tree).
            if (finite)
                boxes[f] = box;
        }
    });
    bvh_->build(boxes, threads);
}

glm::dvec3 TriangleIndex::closestOn(uint32_t f, const glm::dvec3& x, double* b1, double* b2) const
{
    return closestPointOnTriangle(x, glm::dvec3(corners_[3 * size_t(f)]), glm::dvec3(corners_[3 * size_t(f) + 1]),
                                  glm::dvec3(corners_[3 * size_t(f) + 2]), b1, b2);
}

int64_t TriangleIndex::nearestFace(const glm::dvec3& x, float bound2, int64_t hint, const uint32_t* labels,
                                   uint32_t label) const
{
    // A non-finite point is near nothing: its box distances compare false
    // with everything, which would walk every triangle.
    if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
        return -1;
    float best2 = 0.0f;
    return bvh_->nearest(glm::vec3(x), bound2, [&](uint32_t t) {
        if (labels && labels[t] != label)
            return std::numeric_limits<float>::infinity();  // never nearer than the bound
        double u, v;
        const glm::dvec3 c = closestOn(t, x, &u, &v);
        return float(glm::dot(c - x, c - x));
    }, &best2, hint);
}

double TriangleIndex::nearestLabelled(const glm::dvec3& x, const uint32_t* labels, uint32_t label, uint32_t* face,
                                      double* b1, double* b2, int64_t hint) const
{
    const int64_t f = nearestFace(x, 3.0e38f, hint, labels, label);
    if (f < 0)
        return -1.0;
    if (face)
        *face = uint32_t(f);
    double u, v;
    const glm::dvec3 c = closestOn(uint32_t(f), x, &u, &v);
    if (b1)
        *b1 = u;
    if (b2)
        *b2 = v;
    return glm::length(c - x);
}

double TriangleIndex::nearest(const glm::dvec3& x, uint32_t* face, double* b1, double* b2, int64_t hint) const
{
    return nearestLabelled(x, nullptr, 0, face, b1, b2, hint);
}

double TriangleIndex::nearestWithin(const glm::dvec3& x, double maxDistance, int64_t* hint) const
{
    if (!(maxDistance < 1.0e19))
        return nearest(x, hint);
    // The walk's float bound, a little over maxDistance: a triangle right at
    // it is measured in double and clamped.
    const int64_t f = nearestFace(x, float(maxDistance * maxDistance) * 1.0001f, *hint);
    *hint = f;
    if (f < 0)  // nothing within reach, or x not finite (near nothing)
        return std::isfinite(x.x) && std::isfinite(x.y) && std::isfinite(x.z) ? maxDistance : -1.0;
    double u, v;
    const glm::dvec3 c = closestOn(uint32_t(f), x, &u, &v);
    return std::min(glm::length(c - x), maxDistance);
}

bool TriangleIndex::intersectLine(const glm::dvec3& origin, const glm::dvec3& dir, double maxT, double* tOut,
                                  bool alongOnly) const
{
    bool found = false;
    double best = maxT;
    bvh_->forEachOnSegment(glm::vec3(origin), glm::vec3(dir), float(-maxT), float(maxT), [&](uint32_t f) {
        const glm::dvec3 a(corners_[3 * size_t(f)]), b(corners_[3 * size_t(f) + 1]), c(corners_[3 * size_t(f) + 2]);
        const glm::dvec3 e1 = b - a, e2 = c - a;
        const glm::dvec3 pv = glm::cross(dir, e2);
        const double det = glm::dot(e1, pv);  // = -dot(dir, the face's normal) * 2 area
        if (std::fabs(det) < 1e-300 || (alongOnly && det > 0.0))
            return;
        const double inv = 1.0 / det;
        const glm::dvec3 tv = origin - a;
        const double u = glm::dot(tv, pv) * inv;
        if (u < 0.0 || u > 1.0)
            return;
        const glm::dvec3 qv = glm::cross(tv, e1);
        const double v = glm::dot(dir, qv) * inv;
        if (v < 0.0 || u + v > 1.0)
            return;
        const double t = glm::dot(e2, qv) * inv;
        if (std::fabs(t) <= best) {
            best = std::fabs(t);
            *tOut = t;
            found = true;
        }
    });
    return found;
}

DistanceStats sampleDistance(const std::vector<glm::vec3>& samples, const TriangleIndex& to, int threads,
                             double maxDistance)
{
    std::vector<double> d(samples.size());
    parallelFor(samples.size(), threads, [&](size_t b, size_t e) {
        // Consecutive samples lie close: the previous answer, tried first,
        // prunes most of the walk (the answer does not depend on it).
        int64_t hint = -1;
        for (size_t i = b; i < e; ++i) {
            const double di = to.nearestWithin(glm::dvec3(samples[i]), maxDistance, &hint);
            d[i] = di >= 0.0 ? di : std::numeric_limits<double>::infinity();  // a non-finite sample is lost
        }
    });
    DistanceStats s;
    double sum = 0.0;
    for (double v : d) {
        sum += v * v;
        s.max = std::max(s.max, v);
        s.beyond += v >= maxDistance;
    }
    s.samples = d.size();
    s.rms = d.empty() ? 0.0 : std::sqrt(sum / double(d.size()));
    return s;
}

namespace {

// 64-bit mix of a triangle's corner bits (splitmix64 steps): a face's own
// random stream, the same wherever and in whatever company it is measured.
uint64_t faceSeed(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c)
{
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (const glm::vec3* p : {&a, &b, &c})
        for (int k = 0; k < 3; ++k) {
            uint32_t bits;
            const float v = (*p)[k] == 0.0f ? 0.0f : (*p)[k];
            std::memcpy(&bits, &v, 4);
            h ^= bits;
            h += 0x9e3779b97f4a7c15ull;
            h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
            h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
            h ^= h >> 31;
        }
    return h;
}

}  // namespace

std::vector<glm::vec3> areaSamplesAtDensity(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount,
                                            double density)
{
    std::vector<glm::vec3> s;
    if (!(density > 0.0) || !std::isfinite(density))
        return s;
    // Each triangle takes area * density samples, the fraction rounded up
    // or down by its own seed (so the count is right on average and each
    // triangle's samples depend on it alone), placed by the R2 sequence
    // (Roberts 2018) from a seeded start, folded into the triangle.
    const double a1 = 0.7548776662466927, a2 = 0.5698402909980532;
    for (size_t f = 0; f < faceCount; ++f) {
        const glm::vec3 pa = positions[triangles[3 * f]], pb = positions[triangles[3 * f + 1]],
                        pc = positions[triangles[3 * f + 2]];
        const glm::dvec3 a(pa), b(pb), c(pc);
        const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
        if (!(area > 0.0) || !std::isfinite(area))
            continue;
        const uint64_t seed = faceSeed(pa, pb, pc);
        const double expected = area * density;
        const double u0 = double(seed >> 11) * 0x1.0p-53;  // [0, 1)
        const size_t n = size_t(expected) + (u0 < expected - std::floor(expected) ? 1 : 0);
        const double start1 = double((seed >> 7) & 0xffff) / 65536.0, start2 = double(seed & 0xffff) / 65536.0;
        for (size_t i = 0; i < n; ++i) {
            double u = std::fmod(start1 + a1 * double(i + 1), 1.0), v = std::fmod(start2 + a2 * double(i + 1), 1.0);
            if (u + v > 1.0) {
                u = 1.0 - u;
                v = 1.0 - v;
            }
            s.push_back(glm::vec3(a + u * (b - a) + v * (c - a)));
        }
    }
    return s;
}

std::vector<glm::vec3> areaSamples(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount,
                                   size_t count)
{
    const double total = surfaceArea(positions, triangles, faceCount);
    return total > 0.0 ? areaSamplesAtDensity(positions, triangles, faceCount, double(count) / total)
                       : std::vector<glm::vec3>();
}

double surfaceArea(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount)
{
    double total = 0.0;
    for (size_t f = 0; f < faceCount; ++f) {
        const glm::dvec3 a(positions[triangles[3 * f]]), b(positions[triangles[3 * f + 1]]),
            c(positions[triangles[3 * f + 2]]);
        const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
        total += std::isfinite(area) ? area : 0.0;
    }
    return total;
}

std::vector<glm::vec3> surfaceSamples(const glm::vec3* positions, size_t vertexCount, const uint32_t* triangles,
                                      size_t faceCount)
{
    std::vector<glm::vec3> s(positions, positions + vertexCount);
    s.reserve(vertexCount + faceCount);
    for (size_t f = 0; f < faceCount; ++f)
        s.push_back((positions[triangles[3 * f]] + positions[triangles[3 * f + 1]] + positions[triangles[3 * f + 2]]) /
                    3.0f);
    return s;
}

}  // namespace baker
}  // namespace strata
