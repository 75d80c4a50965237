// Internal: the milliseconds since a time point, for the stage timings the
// bake reports (bake.cpp's passes, bake_rig.cpp's stages).
#pragma once

#include <chrono>

namespace strata {
namespace baker {

inline double msSince(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace baker
}  // namespace strata
