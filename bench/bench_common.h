// Shared timing helpers for Strata's benchmark programs: median of repeated
// runs, each run long enough to dwarf the clock's resolution.
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace strata {
namespace bench {

inline double nowMs()
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// Median over `runs` runs of the per-call time of f, in ms; each run
/// repeats f until it has taken at least minRunMs.
template <typename F>
double medianMs(F&& f, int runs = 7, double minRunMs = 30.0)
{
    f();  // warm caches and page in buffers
    std::vector<double> per;
    for (int r = 0; r < runs; ++r) {
        int calls = 0;
        const double t0 = nowMs();
        double t = t0;
        do {
            f();
            ++calls;
            t = nowMs();
        } while (t - t0 < minRunMs);
        per.push_back((t - t0) / calls);
    }
    std::sort(per.begin(), per.end());
    return per[per.size() / 2];
}

}  // namespace bench
}  // namespace strata
