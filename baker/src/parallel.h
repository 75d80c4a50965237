// Internal: the baker's one way to split work over threads.  Contiguous
// chunks, joined before returning; every caller writes disjoint output (or
// per-chunk output merged in chunk order), so results are byte-identical
// for any thread count.
#pragma once

#include "cancel.h"

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace strata {
namespace baker {

/// Runs f(chunk, begin, end) for chunk 0..threads-1 over [0, n) split into
/// `threads` contiguous ranges (some may be empty), one thread each; in the
/// calling thread when threads <= 1.
template <typename F>
void parallelChunks(size_t n, int threads, F&& f)
{
    threads = std::max(1, threads);
    const size_t chunk = (n + size_t(threads) - 1) / size_t(threads);
    if (threads == 1) {
        f(0, size_t(0), n);
        return;
    }
    std::vector<std::thread> pool;
    const std::atomic<bool>* cancel = cancelFlag();
    for (int t = 0; t < threads; ++t) {
        const size_t b = std::min(n, chunk * size_t(t)), e = std::min(n, b + chunk);
        pool.emplace_back([&f, t, b, e, cancel] {
            CancelScope scope(cancel);  // nested loops see the bake's flag
            f(t, b, e);
        });
    }
    for (std::thread& th : pool)
        th.join();
}

/// Runs f(begin, end) over [0, n) in contiguous chunks, serially below 1024
/// items (threads cost more than they save there).
template <typename F>
void parallelFor(size_t n, int threads, F&& f)
{
    // A cancelled bake skips the work; its next stage boundary unwinds it.
    if (cancelRequested())
        return;
    if (threads <= 1 || n < 1024) {
        f(size_t(0), n);
        return;
    }
    parallelChunks(n, threads, [&f](int, size_t b, size_t e) {
        if (b < e && !cancelRequested())
            f(b, e);
    });
}

}  // namespace baker
}  // namespace strata
