// Frames allocate nothing once warmed up: the uniform frame (FrameEvaluator)
// and the adaptive one (AdaptiveFrame), on one thread and on several.
// Counted by replacing the global operator new in this test program.
#include "strata/surface.h"

#include "test_rigs.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> gAllocations{0};
}

void* operator new(std::size_t n)
{
    gAllocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(n ? n : 1))
        return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace strata {
namespace {

TEST(FrameAllocation, WarmFramesAllocateNothing)
{
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map);
    std::unique_ptr<Surface> s;
    ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
    ViewSpec view;
    view.eye = glm::vec3(0.0f, 0.0f, 8.0f);
    ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk());
    std::vector<glm::vec3> p(s->vertexCount()), n(p.size());
    std::vector<glm::vec3> ap(s->adaptiveFrame().vertexCount()), an(ap.size());
    for (int threads : {1, 2}) {
        // Warm up: the first frame with normals and with this many threads.
        ASSERT_TRUE(s->evaluate(p.data(), n.data(), p.size(), threads).isOk());
        ASSERT_TRUE(s->evaluateAdaptive(ap.data(), an.data(), ap.size(), threads).isOk());
        for (int frame = 0; frame < 4; ++frame) {
            ASSERT_TRUE(s->setAnimationTime(0, 0.2f * float(frame)).isOk());
            const long before = gAllocations.load();
            const bool uniform = s->evaluate(p.data(), n.data(), p.size(), threads).isOk();
            const long afterUniform = gAllocations.load();
            const bool adaptive = s->evaluateAdaptive(ap.data(), an.data(), ap.size(), threads).isOk();
            const long afterAdaptive = gAllocations.load();
            ASSERT_TRUE(uniform && adaptive);
            EXPECT_EQ(afterUniform - before, 0) << threads << " threads, frame " << frame;
            EXPECT_EQ(afterAdaptive - afterUniform, 0) << threads << " threads, frame " << frame;
        }
    }
    // Posing, warm, by any setter: a pose is checked without making the
    // message it would need if refused.
    {
        ASSERT_TRUE(s->setAnimationTime(0, 0.3f).isOk());
        const std::vector<glm::mat4> skin = s->skinMatrices();
        const std::vector<glm::vec3> control = s->controlPositions();
        ASSERT_TRUE(s->setJointMatrices(skin.data(), skin.size()).isOk());
        ASSERT_TRUE(s->setControlPositions(control.data(), control.size()).isOk());
        const long before = gAllocations.load();
        const bool posed = s->setAnimationTime(0, 0.7f).isOk() && s->setJointMatrices(skin.data(), skin.size()).isOk() &&
                           s->setControlPositions(control.data(), control.size()).isOk() && s->setRestPose().isOk();
        const long after = gAllocations.load();
        ASSERT_TRUE(posed);
        EXPECT_EQ(after - before, 0);
    }
    // Choosing the same levels again reuses the frame's storage.
    ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk());
    const long before = gAllocations.load();
    ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk());
    EXPECT_EQ(gAllocations.load() - before, 0);
}

}  // namespace
}  // namespace strata
