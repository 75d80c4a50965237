// Internal: worker threads kept between frames, shared by the frame
// evaluators (frame.cpp, adaptive.cpp).
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace strata {
namespace detail {

// Worker threads kept between frames (thread start-up costs as much as a
// small frame).  run() splits [0, n) into contiguous chunks that the
// workers and the calling thread take in turn, and returns when all are done.
// A pass wakes the workers and waits for them; both sides spin for a short
// while (kSpin) before they sleep on a condition variable, because a frame
// is several passes a few hundred microseconds apart and a sleeping thread
// takes tens of microseconds to wake.
class WorkerPool {
public:
    explicit WorkerPool(int threads)
    {
        for (int t = 1; t < threads; ++t)
            workers_.emplace_back([this, t] { work(t); });
    }
    ~WorkerPool()
    {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        for (std::thread& w : workers_)
            w.join();
    }
    int size() const { return int(workers_.size()) + 1; }

    template <typename Body>
    void run(size_t n, const Body& body)
    {
        // Chunks taken in turn from a shared counter, eight per thread: a
        // thread the system slows down takes fewer (every chunk's output is
        // its own, so which thread runs it changes no result).
        const size_t chunks = std::min(n, size_t(size()) * 8);
        next_.store(0, std::memory_order_relaxed);
        // The pass as a plain function and its context on this stack: a
        // std::function here would allocate on every pass.
        struct Pass {
            const Body* body;
            size_t n, chunks;
            std::atomic<size_t>* next;
        } pass{&body, n, chunks, &next_};
        task_ = [](void* context, int t) {
            const Pass& p = *static_cast<const Pass*>(context);
            for (size_t c; (c = p.next->fetch_add(1, std::memory_order_relaxed)) < p.chunks;)
                (*p.body)(p.n * c / p.chunks, p.n * (c + 1) / p.chunks, t);
        };
        context_ = &pass;
        pending_.store(size() - 1, std::memory_order_relaxed);
        {
            std::lock_guard<std::mutex> lock(mutex_);
            generation_.fetch_add(1, std::memory_order_release);
        }
        wake_.notify_all();
        task_(context_, 0);
        if (!spinUntil([this] { return pending_.load(std::memory_order_acquire) == 0; })) {
            std::unique_lock<std::mutex> lock(mutex_);
            done_.wait(lock, [this] { return pending_.load(std::memory_order_acquire) == 0; });
        }
        task_ = nullptr;
        context_ = nullptr;
    }

private:
    static constexpr std::chrono::microseconds kSpin{100};

    template <typename Ready>
    static bool spinUntil(const Ready& ready)
    {
        const auto start = std::chrono::steady_clock::now();
        for (unsigned i = 1;; ++i) {
            if (ready())
                return true;
#if defined(__x86_64__) || defined(__i386__)
            __builtin_ia32_pause();
#endif
            if (i % 64 == 0 && std::chrono::steady_clock::now() - start > kSpin)
                return false;
        }
    }

    void work(int t)
    {
        uint64_t seen = 0;
        for (;;) {
            auto fresh = [&] { return generation_.load(std::memory_order_acquire) != seen; };
            if (!spinUntil(fresh)) {
                std::unique_lock<std::mutex> lock(mutex_);
                wake_.wait(lock, [&] { return stop_ || fresh(); });
                if (stop_)
                    return;
            }
            seen = generation_.load(std::memory_order_acquire);
            task_(context_, t);
            if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
                std::lock_guard<std::mutex> lock(mutex_);  // the caller may be about to sleep
                done_.notify_one();
            }
        }
    }

    std::mutex mutex_;
    std::condition_variable wake_, done_;
    void (*task_)(void*, int) = nullptr;  // the running pass and its context, published by generation_
    void* context_ = nullptr;
    std::atomic<uint64_t> generation_{0};
    std::atomic<int> pending_{0};
    std::atomic<size_t> next_{0};  // the next chunk of the running pass
    bool stop_ = false;  // under mutex_
    std::vector<std::thread> workers_;
};

/// Runs body over [0, n) on `threads` threads: on the calling thread alone
/// for one, else on `pool`, made (again) for that many threads when needed.
template <typename Body>
void runParallel(std::unique_ptr<WorkerPool>& pool, int threads, size_t n, const Body& body)
{
    if (threads <= 1) {
        body(size_t(0), n, 0);
        return;
    }
    if (!pool || pool->size() != threads)
        pool = std::make_unique<WorkerPool>(threads);
    pool->run(n, body);
}

}  // namespace detail
}  // namespace strata
