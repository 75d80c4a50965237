// Strata runtime: the texels a UV triangle covers, with their barycentrics,
// and a triangle's rates against its UVs.
// One home for the loop over a triangle's texels: its rectangle
// (texelRect: the baker's UV overlap check, chart owners and the rig
// writer's map coverage) and the texels with their barycentrics
// (forEachTexelInUVTriangle: the per-vertex displacements' map, the
// baker's colour transfer).
#pragma once

#include "strata/plane.h"

#include <glm/ext/vector_double2.hpp>
#include <glm/ext/vector_double3.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>

namespace strata {

/// Texels (x0..x1, y0..y1, inclusive, clamped to the map) whose squares the
/// bounding box of a triangle in texel units (texel (x, y) spans [x, x + 1]
/// x [y, y + 1]) touches, widened by `reach` texels.  Empty (x0 > x1 or
/// y0 > y1) when it misses the map.
struct TexelRect {
    int x0, x1, y0, y1;
};
inline TexelRect texelRect(const glm::dvec2 t[3], int width, int height, double reach = 0.0)
{
    TexelRect r;
    r.x0 = std::max(0, int(std::floor(std::min({t[0].x, t[1].x, t[2].x}) - reach)));
    r.x1 = std::min(width - 1, int(std::ceil(std::max({t[0].x, t[1].x, t[2].x}) + reach)));
    r.y0 = std::max(0, int(std::floor(std::min({t[0].y, t[1].y, t[2].y}) - reach)));
    r.y1 = std::min(height - 1, int(std::ceil(std::max({t[0].y, t[1].y, t[2].y}) + reach)));
    return r;
}

/// Calls f(x, y, b0, b1, b2) for every texel (x, y) of a width x height map
/// whose centre lies in the triangle of UVs uv[0..2] (inclusive edges: a
/// centre on an edge shared by two triangles is visited by both), with the
/// centre's barycentrics.  A triangle of no area visits nothing.
template <typename F>
void forEachTexelInUVTriangle(const glm::vec2 uv[3], int width, int height, F&& f)
{
    glm::dvec2 p[3];
    for (int k = 0; k < 3; ++k)  // texel-centre space: texel (x, y) at (x, y)
        p[k] = glm::dvec2(double(uv[k].x) * width - 0.5, double(uv[k].y) * height - 0.5);
    const double area = orient2(p[0], p[1], p[2]);
    if (!(std::fabs(area) > 0.0))
        return;
    const int x0 = std::max(0, int(std::ceil(std::min({p[0].x, p[1].x, p[2].x}))));
    const int x1 = std::min(width - 1, int(std::floor(std::max({p[0].x, p[1].x, p[2].x}))));
    const int y0 = std::max(0, int(std::ceil(std::min({p[0].y, p[1].y, p[2].y}))));
    const int y1 = std::min(height - 1, int(std::floor(std::max({p[0].y, p[1].y, p[2].y}))));
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
            const glm::dvec2 q(x, y);
            const double b1 = orient2(p[0], q, p[2]) / area;
            const double b2 = orient2(p[0], p[1], q) / area;
            const double b0 = 1.0 - b1 - b2;
            const double eps = -1e-9;
            if (b0 < eps || b1 < eps || b2 < eps)
                continue;
            f(x, y, b0, b1, b2);
        }
}

/// A triangle's rates of change of its points against its UVs, dP/du and
/// dP/dv, from its edges e1 = P1 - P0, e2 = P2 - P0 and the same edges d1,
/// d2 in UV.  False where its UVs have no area.
inline bool uvDerivatives(const glm::dvec3& e1, const glm::dvec3& e2, const glm::dvec2& d1, const glm::dvec2& d2,
                          glm::dvec3* dPdu, glm::dvec3* dPdv)
{
    const double det = d1.x * d2.y - d2.x * d1.y;
    if (!(std::fabs(det) > 0.0))
        return false;
    *dPdu = (e1 * d2.y - e2 * d1.y) / det;
    *dPdv = (e2 * d1.x - e1 * d2.x) / det;
    return true;
}

/// The frame a glTF viewer derives per pixel for a normal texture on a
/// mesh without TANGENT (three.js's cotangent frame), at a point of unit
/// normal n on a triangle with dP/du and dP/dv (uvDerivatives): the
/// gradients of u and v in the plane across n, (grad u, -grad v), both over
/// the longer of the two.  A texel (x, y, z) reads as the direction
/// x decodeX + y decodeY + z n (normalised); a unit direction s is stored
/// as (s . encodeX, s . encodeY, s . n), the dual basis.  False where the
/// UV gradients are degenerate there.
inline bool normalTextureFrame(const glm::dvec3& n, const glm::dvec3& dPdu, const glm::dvec3& dPdv,
                               glm::dvec3* decodeX, glm::dvec3* decodeY, glm::dvec3* encodeX, glm::dvec3* encodeY)
{
    const glm::dvec3 a = dPdu - n * glm::dot(n, dPdu), b = dPdv - n * glm::dot(n, dPdv);
    const double aa = glm::dot(a, a), ab = glm::dot(a, b), bb = glm::dot(b, b), gram = aa * bb - ab * ab;
    if (!(gram > 1e-12 * aa * bb) || !std::isfinite(gram))
        return false;
    const glm::dvec3 gradU = (bb * a - ab * b) / gram, gradV = (aa * b - ab * a) / gram;
    const double m = std::sqrt(std::max(glm::dot(gradU, gradU), glm::dot(gradV, gradV)));
    *decodeX = gradU / m;
    *decodeY = -gradV / m;
    *encodeX = m * a;
    *encodeY = -m * b;
    return true;
}

}  // namespace strata
