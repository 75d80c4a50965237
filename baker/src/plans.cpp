// The baker's refinement plans: the last smooth plan lends its limit stencils.
#include "plans.h"

#include <mutex>

namespace strata {
namespace baker {

namespace {

std::mutex lastMutex;
std::shared_ptr<const Plan> lastSmooth;  // a plan of the last smooth topology and level made here

}  // namespace

Status createPlan(std::unique_ptr<Plan>* out, const ControlMesh& mesh, Scheme scheme, int level)
{
    if (scheme != Scheme::Smooth)
        return Plan::create(out, mesh, scheme, level);
    std::shared_ptr<const Plan> lender;
    {
        std::lock_guard<std::mutex> lock(lastMutex);
        lender = lastSmooth;
    }
    Status st = Plan::create(out, mesh, scheme, level, lender.get());
    if (!st)
        return st;
    const Plan& made = **out;
    if (!lender || !lender->sameRefinement(made)) {
        // Kept as its own plan (the caller's may change its displacements);
        // it borrows the stencils just made.
        std::unique_ptr<Plan> kept;
        if (Plan::create(&kept, mesh, scheme, level, &made)) {
            std::lock_guard<std::mutex> lock(lastMutex);
            lastSmooth = std::move(kept);
        }
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
