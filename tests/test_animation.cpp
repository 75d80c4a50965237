// Skeleton-driven deformation (paper 2.4, glTF skins): rest = bind pose,
// SimpleSkin against a hand computation, every Fox / CesiumMan animation
// finite and continuous, baked detail following watertight, bad input.
#include "procedural.h"
#include "strata/animation.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "test_rigs.h"

#include <glm/gtc/matrix_transform.hpp>

#include <cmath>

using namespace strata;

namespace {

using strata::test::readText;
using strata::test::writeText;

// A vertical column of control vertices bound to a two-joint chain: hip at
// y = 0, knee at y = 1; weights blend linearly between y = 0.5 and 1.5.
Rig columnRig()
{
    Rig rig;
    rig.mesh = examples::makeIcosphere(1);
    for (glm::vec3& p : rig.mesh.positions)
        p = glm::vec3(0.3f * p.x, 1.0f + p.y, 0.3f * p.z);
    Skeleton& s = rig.skeleton;
    test::twoJointSkin(&s, rig.mesh, "hip", "knee", glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f),
                       [](const glm::vec3& p) { return glm::clamp(p.y - 0.5f, 0.0f, 1.0f); });
    // "bend": the knee turns 60 degrees about z over one second; "still":
    // keys equal to the rest transform (identity joint motion).
    Animation bend;
    bend.name = "bend";
    const glm::quat q0(1.0f, 0.0f, 0.0f, 0.0f), q1 = glm::angleAxis(glm::radians(60.0f), glm::vec3(0, 0, 1));
    bend.channels.push_back(test::rotationKeys(1, {0.0f, 1.0f}, {q0, q1}));
    Animation still;
    still.name = "still";
    AnimationChannel t;
    t.node = 1;
    t.path = AnimationPath::Translation;
    t.times = {0.0f, 2.0f};
    t.values = {0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f};
    still.channels.push_back(t);
    s.animations = {bend, still};
    EXPECT_TRUE(finalizeSkeleton(&s, rig.mesh.positions.size()).isOk());
    return rig;
}

}  // namespace

TEST(Animation, RestPoseEqualsBindPose)
{
    const Rig rig = columnRig();
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    for (SkinningMethod method : {SkinningMethod::Linear, SkinningMethod::DualQuaternion})
        for (int anim : {-1, 1})
            for (float t : {0.0f, 0.7f, 2.0f, 9.0f}) {
                ASSERT_TRUE(animator.pose(anim, t, method).isOk());
                for (size_t v = 0; v < rig.mesh.positions.size(); ++v)
                    ASSERT_LE(glm::length(animator.positions()[v] - rig.mesh.positions[v]), 1e-6f) << v;
            }
}

TEST(Animation, BendMatchesHandComputation)
{
    const Rig rig = columnRig();
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    for (float t : {0.25f, 0.5f, 1.0f, 3.0f}) {
        ASSERT_TRUE(animator.pose(0, t).isOk());
        // Slerp between identity and 60 degrees is a rotation by 60 t (clamped).
        const float angle = glm::radians(60.0f) * std::min(t, 1.0f);
        const float c = std::cos(angle), s = std::sin(angle);
        for (size_t v = 0; v < rig.mesh.positions.size(); ++v) {
            const glm::vec3 p = rig.mesh.positions[v];
            const float w = glm::clamp(p.y - 0.5f, 0.0f, 1.0f);
            const glm::vec3 r = p - glm::vec3(0, 1, 0);
            const glm::vec3 bent = glm::vec3(c * r.x - s * r.y, s * r.x + c * r.y, r.z) + glm::vec3(0, 1, 0);
            ASSERT_LE(glm::length(animator.positions()[v] - ((1.0f - w) * p + w * bent)), 1e-5f) << v << " t " << t;
        }
    }
}

TEST(Animation, DualQuaternionKeepsVolumeAtATwist)
{
    // Twist the knee by 180 degrees about the bone: linear blending collapses
    // half-weighted vertices onto the axis (candy wrapper), dual quaternions
    // keep them at their distance from it.
    Rig rig = columnRig();
    Animation twist;
    twist.name = "twist";
    AnimationChannel c;
    c.node = 1;
    c.path = AnimationPath::Rotation;
    const glm::quat q = glm::angleAxis(glm::radians(179.0f), glm::vec3(0, 1, 0));
    c.times = {0.0f};
    c.values = {q.x, q.y, q.z, q.w};
    twist.channels.push_back(c);
    rig.skeleton.animations.push_back(twist);
    ASSERT_TRUE(finalizeSkeleton(&rig.skeleton, rig.mesh.positions.size()).isOk());
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    float linearMin = 1e9f, dqMin = 1e9f;
    for (SkinningMethod m : {SkinningMethod::Linear, SkinningMethod::DualQuaternion}) {
        ASSERT_TRUE(animator.pose(2, 0.0f, m).isOk());
        for (size_t v = 0; v < rig.mesh.positions.size(); ++v) {
            const glm::vec3 p = rig.mesh.positions[v];
            if (std::fabs(p.y - 1.0f) > 0.05f)
                continue;  // the half-weighted ring
            const glm::vec3 x = animator.positions()[v];
            const float radius = std::sqrt(x.x * x.x + x.z * x.z) / std::sqrt(p.x * p.x + p.z * p.z);
            (m == SkinningMethod::Linear ? linearMin : dqMin) = std::min(m == SkinningMethod::Linear ? linearMin : dqMin, radius);
        }
    }
    EXPECT_LT(linearMin, 0.1f);
    EXPECT_GT(dqMin, 0.99f);
}

TEST(Animation, SimpleSkinMatchesHandComputation)
{
    STRATA_REQUIRE_DATA(path, "SimpleSkin.gltf");
    Rig rig;
    const Status st = io::loadRig(path, &rig);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(rig.skeleton.skin.joints.size(), 2u);
    ASSERT_EQ(rig.skeleton.animations.size(), 1u);
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    // By hand from the file: joint 1 sits at (0, 1, 0); both inverse bind
    // matrices translate by (-0.5, -1, 0); joint 2 is joint 1's child with
    // the animated rotation about z, keyed every 0.5 s:
    // 0, 45, 90, 90, 45, 0, 0, -45, -90, -90, -45, 0 degrees (the file's
    // quaternions are 0.383/0.924 and 0.707/0.707 to three digits).
    const float keys[12] = {0, 45, 90, 90, 45, 0, 0, -45, -90, -90, -45, 0};
    for (float t : {0.0f, 0.25f, 0.5f, 1.0f, 1.25f, 2.0f, 4.25f, 6.0f}) {
        ASSERT_TRUE(animator.pose(0, t).isOk());
        const int k = std::min(int(t / 0.5f), 11);
        const float s = std::min(t / 0.5f - float(k), 1.0f);
        const float deg = k == 11 ? keys[11] : keys[k] + (keys[k + 1] - keys[k]) * s;
        const float a = glm::radians(deg), c = std::cos(a), sn = std::sin(a);
        for (size_t v = 0; v < rig.mesh.positions.size(); ++v) {
            const glm::vec3 p = rig.mesh.positions[v];
            const float w = p.y / 2.0f;  // the file's weights: 1, 0.75, 0.5, 0.25, 0 for joint 1 by height
            const glm::vec3 r = p - glm::vec3(0.5f, 1.0f, 0.0f);
            const glm::vec3 a1 = p + glm::vec3(-0.5f, 0.0f, 0.0f);
            const glm::vec3 a2 = glm::vec3(c * r.x - sn * r.y, sn * r.x + c * r.y, r.z) + glm::vec3(0, 1, 0);
            const glm::vec3 expected = (1.0f - w) * a1 + w * a2;
            // 2e-3: the file's quaternions carry three significant digits.
            EXPECT_LE(glm::length(animator.positions()[v] - expected), 2e-3f) << "vertex " << v << " t " << t;
        }
    }
}

namespace {

void checkAllAnimations(const std::string& path, SkinningMethod method)
{
    Rig rig;
    const Status st = io::loadRig(path, &rig);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_FALSE(rig.skeleton.animations.empty());
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    if (method == SkinningMethod::Segments) {
        ASSERT_TRUE(animator.segmentStatus().isOk()) << animator.segmentStatus().message();
    }
    glm::vec3 lo(1e30f), hi(-1e30f);
    ASSERT_TRUE(animator.pose(-1, 0.0f).isOk());
    for (const glm::vec3& p : animator.positions()) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const glm::vec3 centre = 0.5f * (lo + hi);
    const float diag = glm::length(hi - lo);
    std::vector<glm::vec3> a, b;
    for (size_t i = 0; i < rig.skeleton.animations.size(); ++i) {
        const Animation& anim = rig.skeleton.animations[i];
        for (float t = anim.start; t <= anim.end + 1e-6f; t += 1.0f / 30.0f) {
            ASSERT_TRUE(animator.pose(int(i), t, method).isOk());
            a = animator.positions();
            for (const glm::vec3& p : a) {
                ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << anim.name << " " << t;
                // A walking character stays within a few rest sizes of its rest box.
                ASSERT_LE(glm::length(p - centre), 3.0f * diag) << anim.name << " t " << t;
            }
            // Continuity: 0.1 ms later nothing may have jumped.
            ASSERT_TRUE(animator.pose(int(i), t + 1e-4f, method).isOk());
            b = animator.positions();
            float jump = 0.0f;
            for (size_t v = 0; v < a.size(); ++v)
                jump = std::max(jump, glm::length(a[v] - b[v]));
            ASSERT_LE(jump, 1e-3f * diag) << anim.name << " t " << t;
        }
    }
}

}  // namespace

TEST(AnimationRealData, FoxEveryAnimationFiniteBoundedContinuous)
{
    STRATA_REQUIRE_DATA(path, "Fox.glb");
    checkAllAnimations(path, SkinningMethod::Linear);
    checkAllAnimations(path, SkinningMethod::DualQuaternion);
    // The paper's deformer from Fox's joints alone, ignoring its weights.
    checkAllAnimations(path, SkinningMethod::Segments);
}

TEST(AnimationRealData, CesiumManEveryAnimationFiniteBoundedContinuous)
{
    STRATA_REQUIRE_DATA(path, "CesiumMan.glb");
    checkAllAnimations(path, SkinningMethod::Linear);
    checkAllAnimations(path, SkinningMethod::Segments);
}

TEST(AnimationRealData, BakedPenguinStaysWatertightWhileAnimated)
{
    STRATA_REQUIRE_DATA(highPath, "penguin_hr.obj");
    STRATA_REQUIRE_DATA(controlPath, "penguin_control_mesh.obj");
    Rig rig;
    DisplacementMap map;
    ASSERT_NO_FATAL_FAILURE(test::bakePenguin(highPath, controlPath, &rig, &map));
    // A skeleton authored for the penguin (standing along y): pelvis at
    // y = -0.5, neck at y = 0.5 (exact in binary, so the bind pose is exactly
    // the identity); the upper body bends forward about x.
    Skeleton& s = rig.skeleton;
    test::twoJointSkin(&s, rig.mesh, "pelvis", "neck", glm::vec3(0.0f, -0.5f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f),
                       [](const glm::vec3& p) { return glm::clamp((p.y - 0.1f) / 0.8f, 0.0f, 1.0f); });
    Animation nod;
    nod.name = "nod";
    const glm::quat q0(1, 0, 0, 0), q1 = glm::angleAxis(glm::radians(35.0f), glm::vec3(1, 0, 0));
    nod.channels.push_back(test::rotationKeys(1, {0.0f, 0.5f, 1.0f}, {q0, q1, q0}));
    s.animations.push_back(nod);
    ASSERT_TRUE(finalizeSkeleton(&s, rig.mesh.positions.size()).isOk());
    const MeshTopologyStats control = computeTopologyStats(rig.mesh.triangles.data(), rig.mesh.faceCount());
    const std::string dir = test::tempDir("animated_penguin");
    for (int level = 0; level <= 5; ++level) {
        io::Reconstruction still, rec;
        ASSERT_TRUE(io::reconstruct(&still, rig, &map, Scheme::Linear, level).isOk());
        io::Pose pose;
        pose.animation = 0;
        Animator animator;
        ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
        ASSERT_TRUE(io::reconstruct(&rec, rig, &map, Scheme::Linear, level, 1.0f, &pose).isOk());
        // t = 0 is zero joint motion: exactly the static reconstruction.
        ASSERT_EQ(rec.positions.size(), still.positions.size());
        for (size_t v = 0; v < rec.positions.size(); ++v)
            ASSERT_EQ(rec.positions[v], still.positions[v]) << "level " << level;
        for (float t : {0.25f, 0.5f, 0.8f}) {
            pose.time = t;
            ASSERT_TRUE(io::reconstructPose(&rec, pose).isOk());
            if (level > 3 && t != 0.5f)
                continue;  // the file round trip below is the slow part
            test::expectWatertightRoundTrip(rec, control, dir + "/frame.glb",
                                            "level " + std::to_string(level) + " t " + std::to_string(t));
        }
    }
}

TEST(Animation, RigWithSkeletonRoundTripsAndValidates)
{
    const std::string dir = test::tempDir("skinned_rig");
    const Rig rig = columnRig();
    ASSERT_TRUE(io::saveRig(dir + "/column.glb", rig).isOk());
    Rig back;
    const Status st = io::loadRig(dir + "/column.glb", &back);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(back.skeleton.animations.size(), 2u);
    EXPECT_EQ(back.skeleton.animations[0].name, "bend");
    Animator a, b;
    ASSERT_TRUE(a.init(rig.skeleton, rig.mesh).isOk());
    ASSERT_TRUE(b.init(back.skeleton, back.mesh).isOk());
    ASSERT_TRUE(a.pose(0, 0.6f).isOk());
    ASSERT_TRUE(b.pose(0, 0.6f).isOk());
    for (size_t v = 0; v < rig.mesh.positions.size(); ++v)
        EXPECT_LE(glm::length(a.positions()[v] - b.positions()[v]), 1e-6f);
}

TEST(Animation, BadInputIsAClearError)
{
    STRATA_REQUIRE_DATA(path, "SimpleSkin.gltf");
    const std::string dir = test::tempDir("anim_bad");
    const std::string json = readText(path);
    auto expectError = [&](const std::string& name, std::string text, const std::string& from, const std::string& to,
                           const std::string& needle) {
        const size_t at = text.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        text.replace(at, from.size(), to);
        writeText(dir + "/" + name, text);
        Rig rig;
        const Status st = io::loadRig(dir + "/" + name, &rig);
        EXPECT_FALSE(st.isOk()) << name;
        EXPECT_NE(st.message().find(name), std::string::npos) << st.message();
        EXPECT_NE(st.message().find(needle), std::string::npos) << name << ": " << st.message();
    };
    // The inverse bind matrices accessor (index 4) cut to one matrix.
    expectError("short_ibm.gltf", json, "\"componentType\":5126,\"count\":2,\"type\":\"MAT4\"",
                "\"componentType\":5126,\"count\":1,\"type\":\"MAT4\"", "1 matrices for 2 joints");
    // A one-joint skin while vertices are bound to joint 1.
    expectError("joints.gltf", json, "\"joints\":[1,2]", "\"joints\":[1]", "joint 1 of a 1-joint skin");
    expectError("nosamplers.gltf", json, "\"samplers\":[{\"input\":5,\"interpolation\":\"LINEAR\",\"output\":6}]",
                "\"samplers\":[]", "no samplers");
    // Node 2 lists node 0 as its child: 0 -> 1 -> 2 -> 0.
    expectError("cycle.gltf", json, "{\"rotation\":[0,0,0,1]}", "{\"rotation\":[0,0,0,1],\"children\":[0]}", "cycle");
    // NaN key values, written through the project's own writer.
    Rig rig = columnRig();
    rig.skeleton.animations[0].channels[0].values[5] = std::nanf("");
    ASSERT_TRUE(io::saveRig(dir + "/nan.glb", rig).isOk());
    Rig back;
    const Status st = io::loadRig(dir + "/nan.glb", &back);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("not finite"), std::string::npos) << st.message();
}
