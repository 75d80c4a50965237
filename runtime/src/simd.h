// Strata runtime (private): compiling hot loops for several x86-64 levels,
// and the loops both frames' tile passes (frame.cpp, adaptive.cpp) share.
//
// STRATA_KERNEL_CLONES compiles a function twice on x86-64 Linux with GCC,
// for AVX2 and for the baseline, and the loader picks one (ifunc).  Neither
// enables FMA, so both round every operation the same way: results are
// bit-identical on any CPU, and AVX2 doubles the vector width.  Helpers a
// cloned kernel calls are STRATA_KERNEL_INLINE, so each clone inlines them
// compiled for its own target.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define STRATA_KERNEL_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define STRATA_KERNEL_CLONES
#endif
#define STRATA_KERNEL_INLINE __attribute__((always_inline)) inline

#include <glm/vec3.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace strata {
namespace detail {

// A tile pass's unit normal: one division per vertex (zero stays zero).
STRATA_KERNEL_INLINE float inverseLength(float x, float y, float z)
{
    const float len = std::sqrt(x * x + y * y + z * z);
    return len > 0.0f ? 1.0f / len : 0.0f;
}

// Normalises sums of face normals in place, as inverseLength.
STRATA_KERNEL_INLINE void normalizeGrid(size_t n, float* __restrict x, float* __restrict y, float* __restrict z)
{
    for (size_t k = 0; k < n; ++k) {
        const float s = inverseLength(x[k], y[k], z[k]);
        x[k] *= s;
        y[k] *= s;
        z[k] *= s;
    }
}

// The border pass of both frames: border vertex u (of [begin, end)) sums
// its tiles' partial sums entries[offsets[u] .. offsets[u + 1]) in tile
// order, and its unit normal goes to normals[vertices[u]].
inline void finishBorders(glm::vec3* normals, const uint32_t* vertices, const uint32_t* offsets,
                          const uint32_t* entries, const glm::vec3* partials, size_t begin, size_t end)
{
    for (size_t u = begin; u < end; ++u) {
        glm::vec3 n(0.0f);
        for (uint32_t e = offsets[u]; e < offsets[u + 1]; ++e)
            n += partials[entries[e]];
        normals[vertices[u]] = n * inverseLength(n.x, n.y, n.z);
    }
}

// Face normals of a row of grid triangles (a[j], b[j], c[j]): cross(b - a,
// c - a), whose length is twice the area.  Structure of arrays, restrict
// outputs: the loop vectorises.
STRATA_KERNEL_INLINE void crossRow(size_t n, const float* ax, const float* ay, const float* az, const float* bx,
                                   const float* by, const float* bz, const float* cx, const float* cy, const float* cz,
                                   float* __restrict fx, float* __restrict fy, float* __restrict fz)
{
    for (size_t j = 0; j < n; ++j) {
        const float ex = bx[j] - ax[j], ey = by[j] - ay[j], ez = bz[j] - az[j];
        const float gx = cx[j] - ax[j], gy = cy[j] - ay[j], gz = cz[j] - az[j];
        fx[j] = ey * gz - ez * gy;
        fy[j] = ez * gx - ex * gz;
        fz[j] = ex * gy - ey * gx;
    }
}

}  // namespace detail
}  // namespace strata
