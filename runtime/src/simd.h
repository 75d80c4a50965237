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
#include <vector>

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

// The border pass of both frames: vertex u (of [begin, end)) sums its
// shares partials[entries[offsets[u] .. offsets[u + 1])] in order (its
// tiles' partial sums; in the adaptive frame also small tiles' triangle
// normals), and its unit normal goes to normals[vertices[u]].
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


// The tile loops run in whole vectors of 8 floats (AVX2's width): short
// rows (8 slots at level 3) then need no scalar remainder.  Scratch arrays
// are padded to match; values past a row's end are scratch that the next
// row overwrites and nothing reads.
constexpr size_t kLanes = 8;
inline size_t wholeVectors(size_t n) { return (n + kLanes - 1) / kLanes * kLanes; }

// A regular tile grid of a control face at R = 2^level segments per edge,
// as both frames' tile passes lay it out: slot (i, j) at barycentrics
// (1 - i/R - j/R, i/R, j/R), slots row by row (i), j within a row; row i
// starts at rows[i] = i (R + 1) - i (i - 1) / 2 and holds R + 1 - i slots.
// GridScratch holds one tile's arrays, structure of arrays so the loops
// vectorise: displacements, displaced positions and sums of face normals
// per slot; the face normals of three row pairs in turn (up and down
// triangles, padded) and a zero pair for the grid's edges.
struct GridScratch {
    std::vector<float> d, px, py, pz;
    std::vector<float> face[3][2][3];  // [pair % 3][up, down][x, y, z]
    std::vector<float> zero;
    std::vector<float> sum[3];         // per slot
    void resize(size_t slots, size_t row)
    {
        for (std::vector<float>* v : {&d, &px, &py, &pz, &sum[0], &sum[1], &sum[2]})
            v->assign(wholeVectors(slots) + wholeVectors(row) + kLanes, 0.0f);
        for (auto& pair : face)
            for (auto& kind : pair)
                for (std::vector<float>& v : kind)
                    v.assign(wholeVectors(row + 2) + kLanes, 0.0f);
        zero.assign(wholeVectors(row + 2) + kLanes, 0.0f);
    }
    size_t bytes() const { return (7 * px.capacity() + 19 * face[0][0][0].capacity()) * 4; }
};

// The grid's tables: row starts (R + 2, the last one past the grid) and
// each slot's barycentrics i / R, j / R, padded with zeros to whole vectors.
inline void gridTables(uint32_t R, std::vector<uint32_t>* rows, std::vector<float>* w1, std::vector<float>* w2)
{
    const size_t slots = size_t(R + 1) * (R + 2) / 2;
    rows->resize(R + 2);
    for (uint32_t i = 0; i <= R + 1; ++i)
        (*rows)[i] = i * (R + 1) - i * (i - 1) / 2;  // row i holds R + 1 - i slots
    w1->assign(wholeVectors(slots), 0.0f);
    w2->assign(wholeVectors(slots), 0.0f);
    for (uint32_t i = 0; i <= R; ++i)
        for (uint32_t j = 0; i + j <= R; ++j) {
            (*w1)[(*rows)[i] + j] = float(i) / float(R);
            (*w2)[(*rows)[i] + j] = float(j) / float(R);
        }
}

// A tile's displaced positions: eq. 2 at each slot's barycentrics, the same
// expression as Plan::evaluate (bit-identical), as structure of arrays.
STRATA_KERNEL_INLINE void displaceGrid(size_t n, const float* w1, const float* w2, const float* d, glm::vec3 A,
                                       glm::vec3 B, glm::vec3 C, glm::vec3 NA, glm::vec3 NB, glm::vec3 NC,
                                       float* __restrict px, float* __restrict py, float* __restrict pz)
{
    for (size_t k = 0; k < n; ++k) {
        const float b1 = w1[k], b2 = w2[k], b0 = 1.0f - b1 - b2;
        px[k] = (b0 * A.x + b1 * B.x + b2 * C.x) + (b0 * NA.x + b1 * NB.x + b2 * NC.x) * d[k];
        py[k] = (b0 * A.y + b1 * B.y + b2 * C.y) + (b0 * NA.y + b1 * NB.y + b2 * NC.y) * d[k];
        pz[k] = (b0 * A.z + b1 * B.z + b2 * C.z) + (b0 * NA.z + b1 * NB.z + b2 * NC.z) * d[k];
    }
}

// One grid row's sums of face normals.  The row lies between the row pair
// below it (p: its up triangles touch the row with corners b and c, its down
// triangles with a and b) and the pair above it (c: up triangles with a and
// c, down triangles with c).  Face normals are stored one slot to the right
// with zero pads at both ends, so the grid's edges need no tests.
STRATA_KERNEL_INLINE void rowSum(size_t m, const float* pu, const float* pd, const float* cu, const float* cd,
                                 float* __restrict sum)
{
    for (size_t j = 0; j < m; ++j)
        sum[j] = (pu[j + 1] + pd[j + 1] + pd[j]) + (cu[j + 1] + cu[j] + cd[j]);
}

// Each slot's sum of its grid triangles' normals (unnormalised, |cross| is
// twice the area), from the tile's positions p.  kR: R when fixed at
// compile time (0: the argument), so that rows of levels 3 and 4 unroll.
template <size_t kR>
STRATA_KERNEL_INLINE void gridNormalSums(size_t rRuntime, const uint32_t* rows, float* const* p,
                                         float* const (&face)[3][2][3], const float* zero, float* const* sum)
{
    const size_t R = kR ? kR : rRuntime;
    // Row by row: the face normals of the row pair (i, i + 1), then the
    // sums of row i - 1 from the pairs on both sides of it (|cross| is
    // twice the area).  Three pair buffers in turn: a row's sums read
    // pairs written an iteration earlier, whose stores have retired
    // (a vector load straddling fresh stores waits for them).  Rows 0
    // and R have no pair below or above: the zero buffer stands in.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 18  // kR = 8 or 16: every row's sizes become constants
#endif
    for (size_t i = 0; i <= R + 1; ++i) {
        if (i < R) {
            // Up triangles (i, j), (i + 1, j), (i, j + 1): R - i of them;
            // down triangles (i + 1, j), (i + 1, j + 1), (i, j + 1): one fewer.
            float* const(&pair)[2][3] = face[i % 3];
            const size_t r0 = rows[i], r1 = rows[i + 1], up = R - i, down = up - 1;
            crossRow(wholeVectors(up), p[0] + r0, p[1] + r0, p[2] + r0, p[0] + r1, p[1] + r1, p[2] + r1,
                     p[0] + r0 + 1, p[1] + r0 + 1, p[2] + r0 + 1, pair[0][0] + 1, pair[0][1] + 1, pair[0][2] + 1);
            crossRow(wholeVectors(down), p[0] + r1, p[1] + r1, p[2] + r1, p[0] + r1 + 1, p[1] + r1 + 1,
                     p[2] + r1 + 1, p[0] + r0 + 1, p[1] + r0 + 1, p[2] + r0 + 1, pair[1][0] + 1, pair[1][1] + 1,
                     pair[1][2] + 1);
            for (int a = 0; a < 3; ++a) {
                pair[0][a][0] = pair[0][a][up + 1] = 0.0f;
                pair[1][a][0] = pair[1][a][down + 1] = 0.0f;
            }
        }
        if (i >= 1) {
            const size_t row = i - 1, r0 = rows[row], m = R + 1 - row;  // row: m slots
            for (int a = 0; a < 3; ++a) {
                const float* pu = row == 0 ? zero : face[(row + 2) % 3][0][a];
                const float* pd = row == 0 ? zero : face[(row + 2) % 3][1][a];
                const float* cu = row == R ? zero : face[row % 3][0][a];
                const float* cd = row == R ? zero : face[row % 3][1][a];
                rowSum(wholeVectors(m), pu, pd, cu, cd, sum[a] + r0);
            }
        }
    }
}

}  // namespace detail
}  // namespace strata
