// Strata baker: gutters (paper 3.2 leaves them implicit).  Bilinear sampling
// near a chart border reads texels just outside it; they must hold the
// surface's continuation, not zeros.
#pragma once

#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

/// Grows the valid region of a size x size map by `passes` texels.  Each new
/// texel is the mean, over the 8 directions with a valid neighbour, of the
/// linear extrapolation 2 v1 - v2 (or v1 where the next texel is unset), so
/// bilinear samples at chart borders stay second-order accurate.  Texels still
/// unset afterwards are set to `fill`.  Deterministic (Jacobi passes): the
/// same result for any number of threads.
void dilate(std::vector<float>* values, std::vector<uint8_t>* valid, int size, int passes, float fill,
            int threads = 1);

}  // namespace baker
}  // namespace strata
