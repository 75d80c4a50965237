// Internal: cancelling a bake (BakeRequest::cancel).  The bake's thread
// holds the request's flag in a thread-local; parallelChunks hands it to
// its workers, which skip their work once it is set; the next stage
// boundary (Progress) or the commit of the outputs then unwinds the bake
// with BakeCancelled, and the staged outputs are removed.  Nothing a
// cancelled bake computed is ever written.
#pragma once

#include <atomic>

namespace strata {
namespace baker {

struct BakeCancelled {};

inline const std::atomic<bool>*& cancelFlag()
{
    thread_local const std::atomic<bool>* flag = nullptr;
    return flag;
}

inline bool cancelRequested()
{
    const std::atomic<bool>* flag = cancelFlag();
    return flag && flag->load(std::memory_order_relaxed);
}

/// Sets this thread's flag for a scope.
class CancelScope {
public:
    explicit CancelScope(const std::atomic<bool>* flag) : previous_(cancelFlag()) { cancelFlag() = flag; }
    ~CancelScope() { cancelFlag() = previous_; }
    CancelScope(const CancelScope&) = delete;
    CancelScope& operator=(const CancelScope&) = delete;

private:
    const std::atomic<bool>* previous_;
};

}  // namespace baker
}  // namespace strata
