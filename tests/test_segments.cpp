// The paper's own deformer (eq. 6, point-to-line mapping to skeleton
// segments), its joint file and its conversion to glTF skin weights.
#include "strata/io/joint_file.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "strata/segment_deformer.h"
#include "test_rigs.h"

using strata::test::maxDistance;

#include <glm/gtc/matrix_transform.hpp>

#include <cmath>

using namespace strata;

namespace {

const std::string kPenguinJoints = std::string(STRATA_SOURCE_DIR) + "/tests/data/penguin_joints.json";

// A straight three-joint arm along y (shoulder 0, elbow 1, wrist 2) and
// points on a tube of radius r around it.
struct Arm {
    std::vector<glm::vec3> joints{{0, 0, 0}, {0, 1, 0}, {0, 2, 0}};
    std::vector<int> parents{-1, 0, 1};
    std::vector<glm::vec3> points;
    float r = 0.25f;
};

Arm makeArm(float step = 0.05f)
{
    Arm arm;
    for (float y = 0.05f; y < 1.96f; y += step)
        for (int k = 0; k < 8; ++k) {
            const float a = float(k) * 0.785398f;
            arm.points.emplace_back(arm.r * std::cos(a), y, arm.r * std::sin(a));
        }
    return arm;
}

// Skin matrices that turn the elbow (and the wrist with it) by `degrees`
// about z.
std::vector<glm::mat4> bendElbow(float degrees)
{
    const glm::mat4 bend = glm::translate(glm::mat4(1.0f), glm::vec3(0, 1, 0)) *
                           glm::rotate(glm::mat4(1.0f), glm::radians(degrees), glm::vec3(0, 0, 1)) *
                           glm::translate(glm::mat4(1.0f), glm::vec3(0, -1, 0));
    return {glm::mat4(1.0f), bend, bend};
}

}  // namespace

TEST(Segments, BindPoseReproducesTheInputThroughEquation6)
{
    // A bent rest pose, so the joint planes are tilted bisectors.
    Arm arm = makeArm();
    arm.joints[2] = glm::vec3(0.7f, 1.7f, 0.0f);
    SegmentBinding binding;
    ASSERT_TRUE(bindSegments(&binding, arm.joints.data(), arm.parents.data(), 3, arm.points.data(), arm.points.size())
                    .isOk());
    ASSERT_EQ(binding.segments.size(), 2u);
    std::vector<glm::mat4> identity(3, glm::mat4(1.0f));
    std::vector<glm::vec3> out(arm.points.size());
    SegmentPose pose;
    deformSegments(out.data(), binding, identity.data(), &pose);
    EXPECT_LT(maxDistance(out, arm.points), 1e-6f * 2.0f);
}

TEST(Segments, RigidMotionOfTheWholeSkeletonIsRigid)
{
    Arm arm = makeArm();
    SegmentBinding binding;
    ASSERT_TRUE(bindSegments(&binding, arm.joints.data(), arm.parents.data(), 3, arm.points.data(), arm.points.size())
                    .isOk());
    const glm::mat4 m = glm::translate(glm::mat4(1.0f), glm::vec3(3, -1, 2)) *
                        glm::rotate(glm::mat4(1.0f), 1.1f, glm::normalize(glm::vec3(1, 2, 3)));
    std::vector<glm::mat4> skin(3, m);
    std::vector<glm::vec3> out(arm.points.size());
    SegmentPose pose;
    deformSegments(out.data(), binding, skin.data(), &pose);
    for (size_t i = 0; i < out.size(); ++i)
        ASSERT_LT(glm::length(out[i] - glm::vec3(m * glm::vec4(arm.points[i], 1.0f))), 1e-5f) << i;
}

TEST(Segments, BentElbowMatchesTheJointPlaneConstruction)
{
    // Points at the elbow's joint plane (y = 1) on the upper arm's side,
    // and at the wrist end of the forearm, whose end plane is perpendicular.
    Arm arm;
    const float r = arm.r;
    arm.points = {{r, 1.0f, 0.0f}, {-r, 1.0f, 0.0f}, {0.0f, 1.0f, r}, {r, 2.0f, 0.0f}, {0.0f, 2.0f, -r}};
    SegmentBinding binding;
    ASSERT_TRUE(bindSegments(&binding, arm.joints.data(), arm.parents.data(), 3, arm.points.data(), arm.points.size())
                    .isOk());
    EXPECT_EQ(binding.segment[0], 0u);  // upper arm: the lower segment wins the tie at the plane
    EXPECT_NEAR(binding.alpha[0], 0.0f, 1e-6f);
    EXPECT_NEAR(binding.distance[0], r, 1e-6f);
    EXPECT_EQ(binding.segment[3], 1u);
    EXPECT_NEAR(binding.alpha[3], 0.0f, 1e-6f);

    // Bend 90 degrees about z: the forearm turns towards -x.
    const std::vector<glm::mat4> skin = bendElbow(90.0f);
    std::vector<glm::vec3> out(arm.points.size());
    SegmentPose pose;
    deformSegments(out.data(), binding, skin.data(), &pose);
    const glm::vec3 elbow(0, 1, 0);
    const glm::vec3 plane = glm::normalize(glm::vec3(0, 1, 0) + glm::vec3(-1, 0, 0));  // bisector
    // Inner side (-x): in the bisecting plane at distance r from the upper arm's line.
    EXPECT_NEAR(glm::dot(out[1] - elbow, plane), 0.0f, 1e-6f);
    EXPECT_NEAR(std::fabs(out[1].x), r, 1e-6f);
    // Outer side (+x): in the plane too, pulled back to distance r from the
    // elbow (the paper's scaling at acute joints) instead of r * sqrt(2).
    EXPECT_NEAR(glm::dot(out[0] - elbow, plane), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(out[0] - elbow), r, 1e-6f);
    EXPECT_GT(out[0].x, 0.0f);
    // On the bend axis (z) nothing leans: the point stays put.
    EXPECT_LT(glm::length(out[2] - arm.points[2]), 1e-6f);
    // The wrist end of the forearm: perpendicular end plane, so it moves
    // rigidly with the elbow's rotation.
    for (int i : {3, 4})
        EXPECT_LT(glm::length(out[size_t(i)] - glm::vec3(skin[1] * glm::vec4(arm.points[size_t(i)], 1.0f))), 1e-6f);

    // Without the scaling the outer point overshoots to r * sqrt(2).
    binding.keepDistance = false;
    deformSegments(out.data(), binding, skin.data(), &pose);
    EXPECT_NEAR(glm::length(out[0] - elbow), r * std::sqrt(2.0f), 1e-5f);
}

TEST(Segments, SurfaceStaysContinuousAcrossABentJoint)
{
    // A dense line of points along the arm on each side crosses the elbow's
    // plane; after a 120-degree bend, neighbours stay neighbours.
    for (float side : {1.0f, -1.0f}) {
        Arm arm;
        const float h = 0.002f;
        for (float y = 0.5f; y <= 1.5f; y += h)
            arm.points.emplace_back(side * arm.r, y, 0.0f);
        SegmentBinding binding;
        ASSERT_TRUE(bindSegments(&binding, arm.joints.data(), arm.parents.data(), 3, arm.points.data(),
                                 arm.points.size())
                        .isOk());
        const std::vector<glm::mat4> skin = bendElbow(120.0f);
        std::vector<glm::vec3> out(arm.points.size());
        SegmentPose pose;
        deformSegments(out.data(), binding, skin.data(), &pose);
        float maxStep = 0.0f;
        for (size_t i = 1; i < out.size(); ++i)
            maxStep = std::max(maxStep, glm::length(out[i] - out[i - 1]));
        EXPECT_LT(maxStep, 4.0f * h) << "side " << side;
    }
}

TEST(Segments, SkinWeightsFollowTheBindingAndBlendAtJoints)
{
    Arm arm = makeArm(0.01f);
    SegmentBinding binding;
    ASSERT_TRUE(bindSegments(&binding, arm.joints.data(), arm.parents.data(), 3, arm.points.data(), arm.points.size())
                    .isOk());
    VertexWeights w;
    segmentSkinWeights(&w, binding, arm.parents.data());
    ASSERT_EQ(w.influences, 4);
    float previous[8] = {};
    for (size_t v = 0; v < arm.points.size(); ++v) {
        float sum = 0.0f, toForearm = 0.0f;
        for (int k = 0; k < 4; ++k) {
            sum += w.weights[v * 4 + size_t(k)];
            if (w.joints[v * 4 + size_t(k)] == 1)
                toForearm += w.weights[v * 4 + size_t(k)];
        }
        EXPECT_NEAR(sum, 1.0f, 1e-6f);
        const float y = arm.points[v].y;
        // Half and half at the elbow's plane, none farther than r away, all
        // of it on the forearm beyond r.
        if (std::fabs(y - 1.0f) < 1e-4f) {
            EXPECT_NEAR(toForearm, 0.5f, 1e-3f) << y;
        } else if (y < 1.0f - arm.r - 1e-3f) {
            EXPECT_EQ(toForearm, 0.0f) << y;
        } else if (y > 1.0f + arm.r + 1e-3f) {
            EXPECT_EQ(toForearm, 1.0f) << y;
        } else if (std::fabs(std::fabs(y - 1.0f) - arm.r) > 1e-3f) {
            EXPECT_TRUE(toForearm > 0.0f && toForearm < 1.0f) << y;
        }
        // Monotone across the joint: more forearm the farther along.
        if (v >= 8 && std::fabs(arm.points[v - 8].y - y) > 1e-4f) {
            EXPECT_LE(previous[v % 8], toForearm + 1e-6f) << y;
        }
        previous[v % 8] = toForearm;
    }
}

TEST(Segments, BadSkeletonsAreClearErrors)
{
    const glm::vec3 p(0.0f);
    SegmentBinding b;
    std::vector<glm::vec3> one{{0, 0, 0}};
    std::vector<int> root{-1};
    EXPECT_FALSE(bindSegments(&b, one.data(), root.data(), 1, &p, 1).isOk());  // no segment
    std::vector<glm::vec3> same{{0, 0, 0}, {0, 0, 0}};
    std::vector<int> chain{-1, 0};
    const Status st = bindSegments(&b, same.data(), chain.data(), 2, &p, 1);
    EXPECT_NE(st.message().find("no segment"), std::string::npos) << st.message();
    std::vector<glm::vec3> two{{0, 0, 0}, {0, 1, 0}};
    const glm::vec3 nan(std::nanf(""), 0.0f, 0.0f);
    EXPECT_FALSE(bindSegments(&b, two.data(), chain.data(), 2, &nan, 1).isOk());
}

TEST(JointFile, LoadsTheAuthoredPenguinSkeleton)
{
    Skeleton s;
    const Status st = io::loadJointFile(kPenguinJoints, &s);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(s.nodes.size(), 8u);
    ASSERT_EQ(s.skin.joints.size(), 8u);
    EXPECT_EQ(s.nodes[3].name, "head");
    EXPECT_EQ(s.nodes[3].parent, 2);
    EXPECT_EQ(s.nodes[3].rest.translation, glm::vec3(0.0f, 0.5f, 0.0f));
    // Bind positions come back from the inverse bind matrices.
    std::vector<glm::vec3> joints;
    std::vector<int> parents;
    skinJointHierarchy(&joints, &parents, s);
    EXPECT_EQ(joints[5], glm::vec3(0.875f, -0.5f, 0.0f));
    EXPECT_EQ(parents[5], 4);
    EXPECT_EQ(parents[0], -1);
    ASSERT_EQ(s.animations.size(), 2u);
    EXPECT_EQ(findAnimation(s, "flap"), 1);
    EXPECT_FLOAT_EQ(s.animations[1].end, 0.8f);
    // The root translation key is an offset from its rest place.
    NodeTransform local[8];
    sampleAnimation(local, s, &s.animations[1], 0.8f);
    EXPECT_EQ(local[0].translation, glm::vec3(0.0f, -0.75f, 0.0f));
    sampleAnimation(local, s, &s.animations[0], 0.5f);
    EXPECT_NEAR(glm::angle(local[2].rotation), glm::radians(40.0f), 1e-5f);
}

TEST(JointFile, BadFilesAreClearErrors)
{
    const std::string dir = test::tempDir("joint_files");
    const std::string good = R"("joints": [{"name": "a", "position": [0, 0, 0]}, {"name": "b", "parent": "a", "position": [0, 1, 0]}])";
    const struct {
        const char* what;
        std::string text;
        const char* expect;
    } cases[] = {
        {"empty", "", "is empty"},
        {"not json", "joints: a", "not a JSON joint file"},
        {"no joints", "{}", "\"joints\" is missing"},
        {"cycle", R"({"joints": [{"name": "a", "parent": "b", "position": [0,0,0]}, {"name": "b", "parent": "a", "position": [0,1,0]}]})", "cycle"},
        {"unknown parent", R"({"joints": [{"name": "a", "parent": "z", "position": [0,0,0]}]})", "unknown parent 'z'"},
        {"duplicate", R"({"joints": [{"name": "a", "position": [0,0,0]}, {"name": "a", "position": [0,1,0]}]})", "used twice"},
        {"coincident", R"({"joints": [{"name": "a", "position": [0,0,0]}, {"name": "b", "parent": "a", "position": [0,0,0]}]})", "coincides"},
        {"huge number", R"({"joints": [{"name": "a", "position": [0,1e999,0]}]})", "overflow"},
        {"short position", R"({"joints": [{"name": "a", "position": [0,1]}]})", "array of 3"},
        {"newer version", "{\"strataJoints\": 2, " + good + "}", "version 2"},
        {"decreasing keys", "{" + good + R"(, "animations": [{"name": "x", "keys": [{"time": 1, "rotate": {"b": [0,0,0,1]}}, {"time": 0, "rotate": {"b": [0,0,0,1]}}]}]})", "decrease"},
        {"unknown key joint", "{" + good + R"(, "animations": [{"keys": [{"time": 0, "rotate": {"q": [0,0,0,1]}}]}]})", "unknown joint 'q'"},
        {"zero axis", "{" + good + R"(, "animations": [{"keys": [{"time": 0, "rotate": {"b": {"axis": [0,0,0], "degrees": 3}}}]}]})", "zero axis"},
        {"no samplers", "{" + good + R"(, "animations": [{"name": "idle", "keys": [{"time": 0}]}]})", "keys no joint"},
    };
    for (const auto& c : cases) {
        const std::string path = dir + "/bad.json";
        test::writeText(path, c.text);
        Skeleton s;
        const Status st = io::loadJointFile(path, &s);
        EXPECT_FALSE(st.isOk()) << c.what;
        EXPECT_NE(st.message().find(c.expect), std::string::npos) << c.what << ": " << st.message();
        EXPECT_NE(st.message().find(path), std::string::npos) << c.what << ": " << st.message();
    }
    Skeleton s;
    EXPECT_FALSE(io::loadJointFile(dir + "/missing.json", &s).isOk());
}

TEST(SegmentsRealData, BakedPenguinWithAuthoredJointsStaysWatertight)
{
    STRATA_REQUIRE_DATA(highPath, "penguin_hr.obj");
    STRATA_REQUIRE_DATA(controlPath, "penguin_control_mesh.obj");
    Rig rig;
    DisplacementMap map;
    ASSERT_NO_FATAL_FAILURE(test::bakePenguin(highPath, controlPath, &rig, &map));
    ASSERT_TRUE(io::loadJointFile(kPenguinJoints, &rig.skeleton).isOk());
    const Status bound = bindSkeletonWeights(&rig.skeleton, rig.mesh);
    ASSERT_TRUE(bound.isOk()) << bound.message();

    // The general eq. 6 path (not the zero-motion shortcut) reproduces the
    // control mesh in the bind pose.
    {
        std::vector<glm::vec3> joints;
        std::vector<int> parents;
        skinJointHierarchy(&joints, &parents, rig.skeleton);
        SegmentBinding binding;
        ASSERT_TRUE(bindSegments(&binding, joints.data(), parents.data(), joints.size(), rig.mesh.positions.data(),
                                 rig.mesh.vertexCount())
                        .isOk());
        std::vector<glm::mat4> identity(joints.size(), glm::mat4(1.0f));
        std::vector<glm::vec3> out(rig.mesh.vertexCount());
        SegmentPose pose;
        deformSegments(out.data(), binding, identity.data(), &pose);
        EXPECT_LT(maxDistance(out, rig.mesh.positions), 1e-6f * 3.5f);
    }

    const MeshTopologyStats control = computeTopologyStats(rig.mesh.triangles.data(), rig.mesh.faceCount());
    const std::string dir = test::tempDir("segment_penguin");
    for (int level = 0; level <= 5; ++level) {
        io::Reconstruction still, rec;
        ASSERT_TRUE(io::reconstruct(&still, rig, &map, Scheme::Linear, level).isOk());
        for (int animation : {0, 1}) {
            io::Pose pose;
            pose.animation = animation;
            pose.method = SkinningMethod::Segments;
            Animator animator;
            ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
            ASSERT_TRUE(animator.segmentStatus().isOk()) << animator.segmentStatus().message();
            // t = 0 is zero joint motion (the joint file's coordinates are
            // exact in binary): exactly the static reconstruction.
            ASSERT_TRUE(io::reconstruct(&rec, rig, &map, Scheme::Linear, level, 1.0f, &pose).isOk());
            ASSERT_EQ(rec.positions.size(), still.positions.size());
            for (size_t v = 0; v < rec.positions.size(); ++v)
                ASSERT_EQ(rec.positions[v], still.positions[v]) << "level " << level;
            for (float t : {0.2f, 0.4f, 0.5f, 0.8f}) {
                pose.time = t;
                ASSERT_TRUE(io::reconstructPose(&rec, pose).isOk());
                float moved = 0.0f;
                for (size_t v = 0; v < rec.positions.size(); ++v) {
                    ASSERT_TRUE(std::isfinite(rec.positions[v].x) && std::isfinite(rec.positions[v].y) &&
                                std::isfinite(rec.positions[v].z));
                    moved = std::max(moved, glm::length(rec.positions[v] - still.positions[v]));
                }
                EXPECT_GT(moved, 0.05f) << "level " << level << " t " << t;
                EXPECT_LT(moved, 2.0f) << "level " << level << " t " << t;
                if (level > 3 && t != 0.4f)
                    continue;  // the file round trip below is the slow part
                test::expectWatertightRoundTrip(rec, control, dir + "/frame.glb",
                                                "level " + std::to_string(level) + " t " + std::to_string(t));
            }
        }
    }
}
