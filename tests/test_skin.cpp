// Skin weights on an automatic cage (skin_transfer.h): carried from the
// capture at each cage vertex's nearest point, then fitted over the
// animations so that the layered surface bends as the capture does.
#include "procedural.h"
#include "strata/baker/distance.h"
#include "strata/baker/mesh_input.h"
#include "strata/baker/skin_transfer.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "test_rigs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

using namespace strata;
using namespace strata::baker;

namespace {

// The skin matrices of `skeleton`'s first animation at `time`.
std::vector<glm::mat4> skinsAt(const Skeleton& skeleton, float time)
{
    Skeleton at = skeleton;
    at.animations.resize(1);
    at.animations[0].start = at.animations[0].end = time;
    std::vector<glm::mat4> skins;
    sampleSkinPoses(at, &skins);  // every pose at `time`: the first kept
    skins.resize(at.skin.joints.size());
    return skins;
}

// RMS distance from `points` to the triangles over `surface`.
double rmsDistance(const std::vector<glm::vec3>& points, const std::vector<glm::vec3>& surface,
                   const std::vector<uint32_t>& triangles)
{
    TriangleIndex index;
    index.build(surface.data(), triangles.data(), triangles.size() / 3);
    double sum = 0.0;
    for (const glm::vec3& p : points) {
        const double d = index.nearest(glm::dvec3(p));
        sum += d * d;
    }
    return std::sqrt(sum / double(points.size()));
}

// RMS distance from the layered surface's points, `cage` posed with
// `weights` at `time` and refined by `plan`, to `capture` posed with the
// skeleton's own weights.
double posedDistance(const Plan& plan, const ControlMesh& cage, const VertexWeights& weights,
                     const TriangleMesh& capture, const Skeleton& skeleton, float time)
{
    const std::vector<glm::mat4> skins = skinsAt(skeleton, time);
    std::vector<glm::vec3> cagePosed, capturePosed;
    skinPositions(cage.positions.data(), cage.vertexCount(), weights, skins, skins.size(), &cagePosed);
    skinPositions(capture.positions.data(), capture.positions.size(), skeleton.weights, skins, skins.size(),
                  &capturePosed);
    std::vector<glm::vec3> normals(cage.vertexCount()), points(plan.refinedVertexCount());
    computeControlNormals(normals.data(), cagePosed.data(), normals.size(), cage.triangles.data(), cage.faceCount());
    EXPECT_TRUE(
        plan.evaluate(points.data(), nullptr, 0, points.size(), cagePosed.data(), normals.data(), normals.size())
            .isOk());
    return rmsDistance(points, capturePosed, capture.triangles);
}

// "bend": joint 1 (the child) turns 0.8 rad about z over a second.
Animation bendAnimation()
{
    Animation bend;
    bend.name = "bend";
    bend.channels.push_back(test::rotationKeys(
        1, {0.0f, 1.0f}, {glm::quat(1, 0, 0, 0), glm::angleAxis(0.8f, glm::vec3(0.0f, 0.0f, 1.0f))}));
    bend.end = 1.0f;
    return bend;
}

// A helper joint that turns a narrow band of a sphere: the capture is a
// level-1 icosphere cage refined to level 3 (so the layered surface at
// rest is the capture exactly, and posed it differs only by its skin),
// skinned to two joints at the centre, the child's weight 1 on the
// equator and falling to 0 at |y| = 0.1; the animation turns the child
// 0.8 rad about z.
struct BendingSphere {
    ControlMesh cage = examples::makeIcosphere(1);
    std::unique_ptr<Plan> plan;
    TriangleMesh capture;
    Skeleton skeleton;  // the capture's weights
    TriangleIndex index;

    explicit BendingSphere(Scheme scheme = Scheme::Linear)
    {
        EXPECT_TRUE(Plan::create(&plan, cage, scheme, 3).isOk());
        plan->clearDisplacement();
        std::vector<glm::vec3> normals(cage.vertexCount());
        computeControlNormals(normals.data(), cage.positions.data(), normals.size(), cage.triangles.data(),
                              cage.faceCount());
        capture.positions.resize(plan->refinedVertexCount());
        EXPECT_TRUE(plan->evaluate(capture.positions.data(), nullptr, 0, capture.positions.size(),
                                   cage.positions.data(), normals.data(), normals.size())
                        .isOk());
        capture.triangles = plan->refinedTriangles();
        ControlMesh asMesh;
        asMesh.positions = capture.positions;
        test::twoJointSkin(&skeleton, asMesh, "root", "child", glm::vec3(0.0f), glm::vec3(0.0f),
                           [](const glm::vec3& p) { return 1.0f - glm::smoothstep(0.0f, 0.1f, std::abs(p.y)); });
        skeleton.animations.push_back(bendAnimation());
        EXPECT_TRUE(finalizeSkeleton(&skeleton, capture.positions.size()).isOk());
        index.build(capture.positions.data(), capture.triangles.data(), capture.faceCount());
    }

    double posedRms(const VertexWeights& weights, float time) const
    {
        return posedDistance(*plan, cage, weights, capture, skeleton, time);
    }
};

void expectValidWeights(const VertexWeights& w, size_t vertices, size_t joints)
{
    ASSERT_EQ(w.weights.size(), vertices * size_t(w.influences));
    ASSERT_EQ(w.joints.size(), w.weights.size());
    for (size_t v = 0; v < vertices; ++v) {
        double sum = 0.0;
        for (size_t i = 0; i < size_t(w.influences); ++i) {
            const float x = w.weights[v * size_t(w.influences) + i];
            EXPECT_GE(x, 0.0f) << "vertex " << v;
            EXPECT_LT(w.joints[v * size_t(w.influences) + i], joints) << "vertex " << v;
            if (i > 0) {  // strongest first
                EXPECT_LE(x, w.weights[v * size_t(w.influences) + i - 1]) << "vertex " << v;
            }
            sum += double(x);
        }
        EXPECT_NEAR(sum, 1.0, 1e-5) << "vertex " << v;
    }
}

}  // namespace

// The cage's vertices on the equator take the capture's weight there (all
// on the child), and their faces, reaching |y| = 0.5, then turn with the
// child where the capture turns only a band of 0.1.  Fitted over the
// animation, the weights bring the posed surface closer to the capture at a
// pose the fit did not sample (its last key: the fit samples between the
// ends): the RMS distance 0.029 -> 0.013.
TEST(SkinFit, FittedWeightsFollowTheCapturesBendAtAPoseNotFitted)
{
    // The smooth scheme's points are Loop limit points, each a blend of a
    // dozen or so cage vertices (its stencils): the fit reads them the same way.
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        SCOPED_TRACE(scheme == Scheme::Linear ? "linear" : "smooth");
        BendingSphere s(scheme);
        VertexWeights carried;
        ASSERT_TRUE(transferSkinWeights(s.cage, s.capture, s.index, s.skeleton.weights, &carried).isOk());
        VertexWeights fitted = carried;
        SkinFitReport report;
        ASSERT_TRUE(fitSkinWeights(*s.plan, s.cage, s.capture, s.index, s.skeleton.weights, s.skeleton, &fitted,
                                   &report, 2)
                        .isOk());
        expectValidWeights(fitted, s.cage.vertexCount(), 2);
        EXPECT_EQ(report.poses, 12u);
        EXPECT_EQ(report.points, s.plan->refinedVertexCount());
        EXPECT_LT(report.after, 0.8 * report.before);
        const double before = s.posedRms(carried, 1.0f), after = s.posedRms(fitted, 1.0f);
        EXPECT_GT(before, 1e-3);  // the bend shows
        EXPECT_LT(after, 0.6 * before) << before << " -> " << after;
        // At rest nothing moves, whatever the weights.
        EXPECT_LT(s.posedRms(fitted, 0.0f), 1e-5);
    }
}

// A capture coarse enough to be its own cage (a low-polygon character):
// its triangles across the joint have corners on either side, and it moves
// piecewise linearly between them, which no blend of weights at a point
// reproduces.  The layered surface on the capture's own cage and weights
// already moves exactly so: the fit measures nothing to mend and leaves it
// (fitted to the blended weights at each point instead, it moved the
// weights and the posed surface 0.4% of the radius off).
TEST(SkinFit, ACaptureAsItsOwnCageKeepsItsMotion)
{
    const ControlMesh cage = examples::makeIcosphere(1);
    TriangleMesh capture;
    capture.positions = cage.positions;
    capture.triangles = cage.triangles;
    Skeleton skeleton;
    test::twoJointSkin(&skeleton, cage, "root", "child", glm::vec3(0.0f), glm::vec3(0.0f),
                       [](const glm::vec3& p) { return p.y > 0.05f ? 1.0f : 0.0f; });
    skeleton.animations.push_back(bendAnimation());
    ASSERT_TRUE(finalizeSkeleton(&skeleton, capture.positions.size()).isOk());
    TriangleIndex index;
    index.build(capture.positions.data(), capture.triangles.data(), capture.faceCount());
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, cage, Scheme::Linear, 3).isOk());
    plan->clearDisplacement();

    VertexWeights carried;
    ASSERT_TRUE(transferSkinWeights(cage, capture, index, skeleton.weights, &carried).isOk());
    VertexWeights fitted = carried;
    SkinFitReport report;
    ASSERT_TRUE(fitSkinWeights(*plan, cage, capture, index, skeleton.weights, skeleton, &fitted, &report, 2).isOk());
    EXPECT_EQ(report.points, plan->refinedVertexCount());
    EXPECT_LT(report.before, 1e-6);
    EXPECT_LT(report.after, 1e-6);
    for (float t : {0.5f, 1.0f}) {
        EXPECT_LT(posedDistance(*plan, cage, carried, capture, skeleton, t), 1e-5) << "carried, at " << t;
        EXPECT_LT(posedDistance(*plan, cage, fitted, capture, skeleton, t), 1e-5) << "fitted, at " << t;
    }
}

// A capture that moves rigidly (every weight on one joint) leaves nothing
// to fit: the weights stay as carried, and so does a skeleton without
// animations.
TEST(SkinFit, NothingToFitLeavesTheWeights)
{
    BendingSphere s;
    for (size_t v = 0; v < s.capture.positions.size(); ++v) {
        s.skeleton.weights.weights[4 * v] = 0.0f;
        s.skeleton.weights.weights[4 * v + 1] = 1.0f;
    }
    VertexWeights carried;
    ASSERT_TRUE(transferSkinWeights(s.cage, s.capture, s.index, s.skeleton.weights, &carried).isOk());
    VertexWeights fitted = carried;
    SkinFitReport report;
    ASSERT_TRUE(
        fitSkinWeights(*s.plan, s.cage, s.capture, s.index, s.skeleton.weights, s.skeleton, &fitted, &report).isOk());
    EXPECT_EQ(fitted.joints, carried.joints);
    EXPECT_EQ(fitted.weights, carried.weights);
    EXPECT_LT(report.after, 1e-6);

    s.skeleton.animations.clear();
    ASSERT_TRUE(
        fitSkinWeights(*s.plan, s.cage, s.capture, s.index, s.skeleton.weights, s.skeleton, &fitted, &report).isOk());
    EXPECT_EQ(report.poses, 0u);
    EXPECT_EQ(fitted.weights, carried.weights);
}

// Weights that do not match the cage, or name a joint the skin lacks (the
// cage's or the capture's), are refused by name.
TEST(SkinFit, MismatchedInputsAreRefused)
{
    BendingSphere s;
    VertexWeights carried;
    ASSERT_TRUE(transferSkinWeights(s.cage, s.capture, s.index, s.skeleton.weights, &carried).isOk());
    VertexWeights shortWeights = carried;
    shortWeights.weights.pop_back();
    Status st = fitSkinWeights(*s.plan, s.cage, s.capture, s.index, s.skeleton.weights, s.skeleton, &shortWeights);
    EXPECT_EQ(st.code(), StatusCode::InvalidArgument);
    VertexWeights badJoint = carried;
    badJoint.joints[0] = 7;
    st = fitSkinWeights(*s.plan, s.cage, s.capture, s.index, s.skeleton.weights, s.skeleton, &badJoint);
    EXPECT_EQ(st.code(), StatusCode::InvalidArgument);
    EXPECT_NE(st.message().find("joint 7"), std::string::npos) << st.message();
    // A capture weight that names a joint the skin lacks, where it weighs something.
    VertexWeights badCapture = s.skeleton.weights;
    badCapture.joints[0] = 9;
    badCapture.weights[0] = std::max(badCapture.weights[0], 0.5f);
    VertexWeights fitted = carried;
    st = fitSkinWeights(*s.plan, s.cage, s.capture, s.index, badCapture, s.skeleton, &fitted);
    EXPECT_EQ(st.code(), StatusCode::InvalidArgument);
    EXPECT_NE(st.message().find("capture weight names joint 9"), std::string::npos) << st.message();
}

namespace {

// A capsule along y (radius 0.2, from -1 to 1), closed by a fan at each
// end, skinned to two joints at the centre: the child's weight steps from
// 0 to 1 across |y| < 0.05, and "bend" turns it 1.2 rad about z.
struct BendingTube {
    TriangleMesh capture;
    Skeleton skeleton;

    BendingTube()
    {
        const int around = 48, along = 80;
        const float pi = 3.14159265f;
        for (int i = 0; i <= along; ++i)
            for (int j = 0; j < around; ++j) {
                const float a = 2.0f * pi * float(j) / float(around);
                capture.positions.emplace_back(0.2f * std::cos(a), -1.0f + 2.0f * float(i) / float(along),
                                               0.2f * std::sin(a));
            }
        const uint32_t bottom = uint32_t(capture.positions.size()), top = bottom + 1;
        capture.positions.emplace_back(0.0f, -1.0f, 0.0f);
        capture.positions.emplace_back(0.0f, 1.0f, 0.0f);
        auto at = [&](int i, int j) { return uint32_t(i * around + (j % around)); };
        for (int i = 0; i < along; ++i)
            for (int j = 0; j < around; ++j)
                capture.triangles.insert(capture.triangles.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j),
                                                                   at(i + 1, j + 1), at(i, j + 1)});
        for (int j = 0; j < around; ++j) {
            capture.triangles.insert(capture.triangles.end(), {bottom, at(0, j), at(0, j + 1)});
            capture.triangles.insert(capture.triangles.end(), {top, at(along, j + 1), at(along, j)});
        }
        ControlMesh asMesh;
        asMesh.positions = capture.positions;
        test::twoJointSkin(&skeleton, asMesh, "root", "child", glm::vec3(0.0f), glm::vec3(0.0f),
                           [](const glm::vec3& p) { return glm::smoothstep(-0.05f, 0.05f, p.y); });
        Animation bend;
        bend.name = "bend";
        bend.channels.push_back(test::rotationKeys(
            1, {0.0f, 1.0f}, {glm::quat(1, 0, 0, 0), glm::angleAxis(1.2f, glm::vec3(0.0f, 0.0f, 1.0f))}));
        bend.end = 1.0f;
        skeleton.animations.push_back(bend);
        EXPECT_TRUE(finalizeSkeleton(&skeleton, capture.positions.size()).isOk());
    }

    // RMS distance from the capture's vertices, posed at the end of "bend",
    // to a cage posed with the weights carried to it.
    double posedRms(const ControlMesh& cage) const
    {
        TriangleIndex index;
        index.build(capture.positions.data(), capture.triangles.data(), capture.faceCount());
        VertexWeights weights;
        EXPECT_TRUE(transferSkinWeights(cage, capture, index, skeleton.weights, &weights).isOk());
        const std::vector<glm::mat4> skins = skinsAt(skeleton, 1.0f);
        std::vector<glm::vec3> cagePosed, capturePosed;
        skinPositions(cage.positions.data(), cage.vertexCount(), weights, skins, 2, &cagePosed);
        skinPositions(capture.positions.data(), capture.positions.size(), skeleton.weights, skins, 2, &capturePosed);
        return rmsDistance(capturePosed, cagePosed, cage.triangles);
    }
};

}  // namespace

// At rest the tube is straight: a quadric decimation spends its faces on
// the ends and spans the middle with long faces, which a bend then cuts
// through.  Decimated in the capture's poses too, the cage keeps rings at
// the bend, and posed it lies much closer to the posed capture (RMS 0.23
// -> 0.005 at 120 faces).
TEST(SkinFit, DecimatingInThePosesKeepsTheBend)
{
    BendingTube tube;
    std::vector<glm::mat4> skins;
    sampleSkinPoses(tube.skeleton, &skins);
    ASSERT_EQ(skins.size(), 12u * 2u);
    std::vector<glm::vec3> posed;
    skinPositions(tube.capture.positions.data(), tube.capture.positions.size(), tube.skeleton.weights, skins, 2,
                  &posed);
    ASSERT_EQ(posed.size(), 12 * tube.capture.positions.size());
    ControlMesh atRest, inPoses;
    ASSERT_TRUE(decimateToControlMesh(tube.capture, 120, &atRest).isOk());
    ASSERT_TRUE(decimateToControlMesh(tube.capture, 120, &inPoses, posed).isOk());
    EXPECT_LE(inPoses.faceCount(), 120u);
    const double rest = tube.posedRms(atRest), poses = tube.posedRms(inPoses);
    EXPECT_LT(poses, 0.1 * rest) << rest << " -> " << poses;
}

// The poses' skin matrices stay within 64 MB: a skin of 65,535 joints (the
// most a rig may have) has room for 16 poses, shared by its animations,
// where a small one takes 12 times an animation up to 48.
TEST(SkinFit, PosesOfAHugeSkinStayWithinTheirBudget)
{
    Skeleton huge;
    const size_t joints = 65535;
    huge.nodes.resize(joints);
    for (size_t j = 0; j < joints; ++j) {
        huge.skin.joints.push_back(int(j));
        huge.skin.inverseBindMatrices.emplace_back(1.0f);
    }
    Animation turn;
    turn.channels.push_back(test::rotationKeys(
        0, {0.0f, 1.0f}, {glm::quat(1, 0, 0, 0), glm::angleAxis(1.0f, glm::vec3(0.0f, 0.0f, 1.0f))}));
    turn.end = 1.0f;
    for (int a = 0; a < 5; ++a)
        huge.animations.push_back(turn);
    huge.weights.influences = 4;
    ASSERT_TRUE(finalizeSkeleton(&huge, 0).isOk());
    std::vector<glm::mat4> skins;
    std::vector<std::pair<size_t, float>> times;
    sampleSkinPoses(huge, &skins, &times);
    EXPECT_EQ(times.size(), 15u);  // room for 16: 3 times for each of the 5 animations
    EXPECT_EQ(skins.size(), 15u * joints);
    EXPECT_LE(skins.size() * sizeof(glm::mat4), size_t(64) << 20);
    EXPECT_EQ(times.front().first, 0u);  // every animation has its share
    EXPECT_EQ(times.back().first, 4u);

    huge.skin.joints.resize(2);
    huge.skin.inverseBindMatrices.resize(2);
    sampleSkinPoses(huge, &skins, &times);
    EXPECT_EQ(times.size(), 45u);  // 9 times for each of the 5 animations (48 / 5)
}
