// Strata baker: mapping every high-resolution vertex onto the bake surface
// (paper 2.1: the parameters (r_i, alpha_i, beta_i, d_i) of each vertex).
#pragma once

#include "bvh.h"
#include "strata/baker/distance.h"
#include "strata/baker/normal_volume.h"
#include "strata/baker/surface.h"
#include "strata/status.h"

#include <vector>

namespace strata {
namespace baker {

struct VertexMapping {
    uint32_t face;   ///< r: the bake-surface triangle
    float b1, b2;    ///< barycentrics of its corners 1 and 2
    float d;         ///< eq. 2 distance parameter
};

struct MappingStats {
    size_t vertices = 0;
    size_t fallbacks = 0;         ///< in no normal volume: mapped to the nearest surface point
    double searchDistance = 0.0;  ///< |d| bound of the normal-volume index
};

/// Spatial indices over one bake surface: normal-volume prisms (bounded by
/// |d| <= searchDistance) and the triangles themselves (nearest point).
class SurfaceIndex {
public:
    void build(const BakeSurface& surface, double searchDistance);
    /// The two halves of build(): the triangles (nearest-point queries, the
    /// per-face cubics), then the prisms once the search distance is known.
    void buildFaces(const BakeSurface& surface);
    void buildPrisms(double searchDistance);
    const BakeSurface& surface() const { return *surface_; }
    double searchDistance() const { return searchDistance_; }
    NormalVolumeTriangle triangle(uint32_t face) const;
    const NormalVolumeCubic& cubic(uint32_t face) const { return cubics_[face]; }

    /// Closed-form mapping of x: among the normal volumes around the nearest
    /// surface triangle (the rings of its corners) the containing one with the
    /// smallest |d|; if none contains x, the same over every volume of the
    /// index.  False when x lies in none.
    /// `hint`: a face to start the nearest-triangle search from (speed only).
    /// `shell`: only faces of that piece (setShells), or kAnyShell.
    bool map(const glm::dvec3& x, VertexMapping* out, int64_t hint = -1, uint32_t shell = kAnyShell) const;
    /// Fallback: the nearest surface point, with d the projection of the
    /// offset onto the interpolated normal there.
    VertexMapping mapNearest(const glm::dvec3& x, uint32_t shell = kAnyShell) const;
    /// Nearest distance from x to the surface triangles (of `shell`).
    double nearestDistance(const glm::vec3& x, uint32_t shell = kAnyShell) const;
    /// Per surface face, the capture piece it stands for (ShellLabels), or
    /// empty: a point of a piece then maps onto that piece's faces alone.
    void setShells(std::vector<uint32_t> faceShells) { faceShells_ = std::move(faceShells); }
    static constexpr uint32_t kAnyShell = 0xffffffffu;

private:
    const BakeSurface* surface_ = nullptr;
    double searchDistance_ = 0.0;
    Bvh prisms_;
    std::vector<Box> prismBoxes_;  // per face: the box of its prism
    TriangleIndex faces_;
    std::vector<NormalVolumeTriangle> triangles_;  // per face, in double
    std::vector<NormalVolumeCubic> cubics_;        // per face: the point-independent part of eq. 2's cubic
    std::vector<uint32_t> faceShells_;             // per face: its piece, or empty
    // The nearest face of `shell` (any without shells), or -1.
    double nearestFace(const glm::dvec3& x, uint32_t shell, uint32_t* face, double* b1, double* b2,
                       int64_t hint) const;
};

/// Maps n points in parallel (threads >= 1; the result does not depend on
/// the thread count).  The search distance is 2x the largest nearest
/// distance over a deterministic sample of the points, capped at
/// maxSearchFraction of the surface's bounding-box diagonal.
/// pointShells (optional, with index->setShells done): per point, the
/// piece whose faces it maps onto, or kAnyShell.
Status mapVertices(std::vector<VertexMapping>* out, SurfaceIndex* index, const BakeSurface& surface,
                   const glm::vec3* points, size_t n, int threads, MappingStats* stats,
                   double maxSearchFraction = 0.25, const uint32_t* pointShells = nullptr);

}  // namespace baker
}  // namespace strata

