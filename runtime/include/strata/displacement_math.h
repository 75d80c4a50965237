// Strata: the displacement formulas, in one source compiled as C++ and GLSL.
//
// This header is included by the CPU runtime (C++17 with GLM, where the GLSL
// vector types and built-ins exist under the same names) and embedded
// verbatim into the shaders (shaders/*.glsl), so the CPU and GPU paths cannot
// drift.  Keep it in the common subset of both languages: no references, no
// templates, no overloading, no integer/float implicit conversions.
//
// Conventions (docs/FORMAT.md):
//   * UV (0,0) is the top-left corner of the image's first row (glTF).
//   * Texel (i, j) covers [i, i+1] x [j, j+1] in texel space; its centre is
//     at uv = ((i + 0.5) / W, (j + 0.5) / H).  Sampling is bilinear between
//     texel centres with clamp-to-edge addressing.
//   * A texel value t decodes to a distance d = t * factor + offset.
//   * Paper equation 2: x = p + d * n, where p is the surface point and n the
//     direction (the barycentric interpolation of unit control normals in the
//     linear scheme, left unnormalised as eq. 2 has it; the unit limit normal
//     in the smooth scheme).
#ifndef STRATA_DISPLACEMENT_MATH_H
#define STRATA_DISPLACEMENT_MATH_H

#ifdef __cplusplus
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#define STRATA_FN inline
#define STRATA_OUT(T) T&
namespace strata {
namespace shared {
using glm::clamp;
using glm::cross;
using glm::floor;
using glm::length;
using glm::max;
using glm::min;
using glm::ivec2;
using glm::vec2;
using glm::vec3;
#else
#define STRATA_FN
#define STRATA_OUT(T) out T
#endif

/// Bilinear footprint of uv in a size.x by size.y map: the top-left texel of
/// the 2x2 block (clamped so the block stays inside the map) and the weights
/// of its right and bottom columns.  Clamp-to-edge: outside the texel-centre
/// range the weight saturates, so the border texel's value is returned.
STRATA_FN void strata_bilinear_footprint(vec2 uv, ivec2 size, STRATA_OUT(ivec2) texel0, STRATA_OUT(vec2) frac)
{
    vec2 fsize = vec2(float(size.x), float(size.y));
    vec2 t = uv * fsize - vec2(0.5, 0.5);
    vec2 maxT = fsize - vec2(1.0, 1.0);
    t = clamp(t, vec2(0.0, 0.0), maxT);
    vec2 base = floor(t);
    // Keep the 2x2 block inside the map; at the last row/column the weight
    // of the (clamped) far texel becomes 1 or the block degenerates to one.
    base = clamp(base, vec2(0.0, 0.0), max(maxT - vec2(1.0, 1.0), vec2(0.0, 0.0)));
    texel0 = ivec2(int(base.x), int(base.y));
    frac = clamp(t - base, vec2(0.0, 0.0), vec2(1.0, 1.0));
}

/// The far corner (right column, bottom row) of the 2x2 block at texel0,
/// clamped to the map (a one-texel-wide map repeats its only column).
STRATA_FN ivec2 strata_far_texel(ivec2 texel0, ivec2 size)
{
    return ivec2(min(texel0.x + 1, size.x - 1), min(texel0.y + 1, size.y - 1));
}

/// Bilinear blend of the 2x2 block t00 (top-left), t10 (right), t01 (below), t11.
STRATA_FN float strata_bilinear(float t00, float t10, float t01, float t11, vec2 frac)
{
    float top = t00 + (t10 - t00) * frac.x;
    float bottom = t01 + (t11 - t01) * frac.x;
    return top + (bottom - top) * frac.y;
}

/// Texel value to distance (the rig's displacementGeometryFactor / Offset).
STRATA_FN float strata_decode_distance(float texel, float factor, float offset)
{
    return texel * factor + offset;
}

/// Paper eq. 12: a distance d in [dmin, dmax] quantised to one of `levels`
/// steps (levels - 1 = 2^n - 1 for an n-bit image, so dmax maps to the top
/// level): q = round((levels - 1) (d - dmin) / (dmax - dmin)), clamped.
STRATA_FN float strata_quantize(float d, float dmin, float dmax, float levels)
{
    float range = dmax - dmin;
    float t = range > float(0.0) ? clamp((d - dmin) / range, float(0.0), float(1.0)) : float(0.0);
    return floor(t * (levels - float(1.0)) + float(0.5));
}

/// Eq. 12 inverted as a decode: the factor and offset that turn a quantised
/// level back into a distance (d = q * factor + offset, strata_decode_distance).
STRATA_FN vec2 strata_dequantize_factor_offset(float dmin, float dmax, float levels)
{
    return vec2((dmax - dmin) / (levels - float(1.0)), dmin);
}

/// Paper eq. 2: displaced point = surface point + d * direction.
STRATA_FN vec3 strata_displace(vec3 surface, vec3 direction, float d)
{
    return surface + direction * d;
}

/// The smooth scheme's direction: the unit normal of the Loop limit surface
/// from its two tangents (d/ds and d/dt of the limit stencils), or zero
/// where the tangents are parallel (Displaced Subdivision Surfaces).
STRATA_FN vec3 strata_limit_normal(vec3 du, vec3 dv)
{
    vec3 n = cross(du, dv);
    float len = length(n);
    return len > 0.0 ? n / len : vec3(0.0, 0.0, 0.0);
}

#ifdef __cplusplus
}  // namespace shared
}  // namespace strata
#endif
#undef STRATA_FN
#undef STRATA_OUT

#endif  // STRATA_DISPLACEMENT_MATH_H
