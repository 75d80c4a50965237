// Strata baker: the closed-form normal-volume mapping (paper section 2.1,
// equations 1-2; Sun, Hilton, Smith and Illingworth 1999).
//
// For a triangle with vertices v_k and vertex normals n_k, the offset
// triangle T(d) = (v_k + d n_k) sweeps the triangle's normal volume.  A point
// x lies in T(d) when det[T1(d) - T0(d), T2(d) - T0(d), x - T0(d)] = 0, a
// cubic in d.  Each real root gives barycentrics (b0, b1, b2) of x in T(d),
// and x = sum_k b_k (v_k + d n_k) (eq. 2) holds exactly.
#pragma once

#include <glm/vec3.hpp>

namespace strata {
namespace baker {

/// A triangle of the surface being mapped onto, with its vertex normals
/// (unit control normals in the linear scheme, limit normals in smooth).
struct NormalVolumeTriangle {
    glm::dvec3 v[3];
    glm::dvec3 n[3];
};

/// The point-independent part of the cubic, precomputed once per triangle:
/// with e_k = v_k - v_0, f_k = n_k - n_0, h = -n_0 and g = x - v_0, the
/// coefficients are c0 = g.A, c1 = g.B + h.A, c2 = g.C + h.B, c3 = h.C where
/// A = e1 x e2, B = f1 x e2 + e1 x f2, C = f1 x f2.
struct NormalVolumeCubic {
    glm::dvec3 A, B, C;
    double hA, hB, hC;
    static NormalVolumeCubic of(const NormalVolumeTriangle& t);
};

struct NormalVolumeHit {
    double b1 = 0.0, b2 = 0.0;  ///< barycentrics of corners 1 and 2 (b0 = 1 - b1 - b2)
    double d = 0.0;             ///< distance parameter of eq. 2
};

/// Solves eq. 2 for x in triangle tri: among the real roots d of the cubic
/// with |d| <= maxDistance, returns the one with the smallest |d| whose
/// barycentrics are all >= -tolerance (inside the normal volume).  Returns
/// false when x is in no part of this normal volume within range.
bool mapToNormalVolume(const NormalVolumeTriangle& tri, const glm::dvec3& x, double maxDistance, double tolerance,
                       NormalVolumeHit* hit);
/// The same with the triangle's cubic precomputed (the baker's hot path).
bool mapToNormalVolume(const NormalVolumeTriangle& tri, const NormalVolumeCubic& cubic, const glm::dvec3& x,
                       double maxDistance, double tolerance, NormalVolumeHit* hit);

/// The same solve without the inside test (paper 3.2.2: a border triangle's
/// vertices re-mapped into the plane of a neighbouring control triangle, with
/// negative barycentrics allowed).  Of the roots within maxDeviation of
/// nearD (the vertex's distance in its own triangle), the closest to it: the
/// offset planes also sweep through the far side of the volume, and that
/// root is not the continuation of the vertex's mapping.
bool mapToNormalVolumePlane(const NormalVolumeTriangle& tri, const glm::dvec3& x, double nearD, double maxDeviation,
                            NormalVolumeHit* hit);
/// The same with the triangle's cubic precomputed.
bool mapToNormalVolumePlane(const NormalVolumeTriangle& tri, const NormalVolumeCubic& cubic, const glm::dvec3& x,
                            double nearD, double maxDeviation, NormalVolumeHit* hit);

/// Paper eq. 2, forward: sum_k b_k (v_k + d n_k).
glm::dvec3 evaluateNormalVolume(const NormalVolumeTriangle& tri, double b1, double b2, double d);

}  // namespace baker
}  // namespace strata
