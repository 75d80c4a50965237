// Strata runtime (private): compiling hot loops for several x86-64 levels.
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

#include <cstddef>

namespace strata {
namespace detail {

// Face normals of a row of grid triangles (a[j], b[j], c[j]): cross(b - a,
// c - a), whose length is twice the area.  Structure of arrays, restrict
// outputs: the loop vectorises.  Both frames' tile passes (frame.cpp,
// adaptive.cpp) run it.
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
