// Strata baker: nearest-point queries on triangle meshes, and the surface
// distance metric used by the closed-loop error and the evidence report.
#pragma once


#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

namespace strata {
namespace baker {

class Bvh;

class TriangleIndex {
public:
    TriangleIndex();
    ~TriangleIndex();
    TriangleIndex(TriangleIndex&&) noexcept;
    TriangleIndex& operator=(TriangleIndex&&) noexcept;

    /// Indexes faceCount triangles (on `threads` threads; the same index for
    /// any count).  The index keeps its own copy of the corners.
    void build(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount, int threads = 1);
    /// Distance from x to the nearest triangle; face and barycentrics of the
    /// nearest point when the pointers are non-null.  -1 when empty.
    /// `hint` (a face to try first, or -1) only speeds the search up.
    double nearest(const glm::dvec3& x, uint32_t* face = nullptr, double* b1 = nullptr, double* b2 = nullptr,
                   int64_t hint = -1) const;
    /// nearest() among the faces f with labels[f] == label (-1 when none;
    /// null labels: every face).
    double nearestLabelled(const glm::dvec3& x, const uint32_t* labels, uint32_t label, uint32_t* face = nullptr,
                           double* b1 = nullptr, double* b2 = nullptr, int64_t hint = -1) const;
    /// The same, for a run of nearby queries: starts from *hint and leaves
    /// the answer's face there (-1 when none) for the next query.
    double nearest(const glm::dvec3& x, int64_t* hint) const
    {
        uint32_t face = 0;
        const double d = nearest(x, &face, nullptr, nullptr, *hint);
        *hint = d >= 0.0 ? int64_t(face) : -1;
        return d;
    }

    /// min(distance to the nearest triangle, maxDistance), with the run's
    /// hint as above: a walk that prunes every box farther than maxDistance,
    /// so a point far from the mesh costs a few boxes, not every triangle
    /// the mesh has within its distance.
    double nearestWithin(const glm::dvec3& x, double maxDistance, int64_t* hint) const;

    /// The intersection of the line origin + t * dir with the mesh that has
    /// the smallest |t| within |t| <= maxT (Moller-Trumbore); false if none.
    /// alongOnly: only triangles whose normal points along dir (the line
    /// leaves the surface's inside there), so a neighbouring part seen
    /// across a gap is not taken for the surface itself.
    bool intersectLine(const glm::dvec3& origin, const glm::dvec3& dir, double maxT, double* t,
                       bool alongOnly = false) const;

private:
    // The walk: the nearest face within sqrt(bound2) (-1: none, or x not finite).
    int64_t nearestFace(const glm::dvec3& x, float bound2, int64_t hint, const uint32_t* labels = nullptr,
                        uint32_t label = 0) const;
    // Face f's point closest to x, and its barycentrics.
    glm::dvec3 closestOn(uint32_t f, const glm::dvec3& x, double* b1, double* b2) const;

    std::vector<glm::vec3> corners_;  // three per triangle, in order: one load each, no index
    std::unique_ptr<Bvh> bvh_;  // private (bvh.h)
};

struct DistanceStats {
    double rms = 0.0;
    double max = 0.0;
    size_t samples = 0;
    size_t beyond = 0;  ///< samples farther than the bound asked for, counted at the bound
};

/// One-sided distance from the samples to the indexed surface.  With a
/// finite maxDistance, a sample farther than it counts as that far (the
/// RMS and maximum are then lower bounds, and `beyond` says how many).
/// A non-finite sample counts as infinitely far.
DistanceStats sampleDistance(const std::vector<glm::vec3>& samples, const TriangleIndex& to, int threads,
                             double maxDistance = std::numeric_limits<double>::infinity());

/// Points spread over a mesh by area, `density` per unit area on average
/// (each of equal weight, so an RMS over them is the area-weighted RMS an
/// independent tool measures).  Each triangle's samples depend on that
/// triangle alone (its corner positions seed them): a mesh measured in
/// pieces gets the same samples as measured whole.  Deterministic.
std::vector<glm::vec3> areaSamplesAtDensity(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount,
                                            double density);
/// About `count` such points over the whole mesh.
std::vector<glm::vec3> areaSamples(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount,
                                   size_t count);
/// The mesh's area.
double surfaceArea(const glm::vec3* positions, const uint32_t* triangles, size_t faceCount);

/// Points that sample a mesh densely: every vertex and every face centroid.
std::vector<glm::vec3> surfaceSamples(const glm::vec3* positions, size_t vertexCount, const uint32_t* triangles,
                                      size_t faceCount);

}  // namespace baker
}  // namespace strata
