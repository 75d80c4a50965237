// strata::Surface: the one object every front end draws a rig through.
// Closed form where there is one (the icosahedron and its sphere), equality
// with the pieces it is made of elsewhere, and every input that would draw
// another surface refused.
#include "test_rigs.h"

#include "strata/normals.h"
#include "strata/surface.h"

#include <cstring>
#include <limits>
#include <random>

namespace strata {
namespace {

// The icosahedron with a map whose surface is the unit sphere (as
// Reconstruction.IcosahedronAndSphereMapGiveTheSphere), as a rig.
void sphereRig(Rig* rig, DisplacementMap* map, int size)
{
    rig->mesh = examples::makeIcosphere(0);
    ASSERT_TRUE(baker::buildTriangleAtlas(&rig->mesh, {size, 2}).isOk());
    ASSERT_TRUE(examples::bakeRadialSurface(map, rig->mesh, size, 2, [](const glm::vec3&) { return 1.0f; }).isOk());
    rig->hasDisplacement = true;
    rig->displacement.encoding = "exr";
    rig->displacement.width = rig->displacement.height = size;
    rig->displacement.scheme = Scheme::Linear;
    rig->displacement.recommendedLevel = 4;
}

std::vector<glm::vec3> evaluate(Surface& s, std::vector<glm::vec3>* normals = nullptr, int threads = 1)
{
    std::vector<glm::vec3> p(s.vertexCount());
    if (normals)
        normals->resize(s.vertexCount());
    EXPECT_TRUE(s.evaluate(p.data(), normals ? normals->data() : nullptr, p.size(), threads).isOk());
    return p;
}

bool sameBits(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b)
{
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(glm::vec3)) == 0;
}

}  // namespace

TEST(Surface, TheIcosahedronRigIsTheSphereAtItsRecommendedLevel)
{
    Rig rig;
    DisplacementMap map;
    const int size = 512;
    sphereRig(&rig, &map, size);
    std::unique_ptr<Surface> s;
    ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
    EXPECT_EQ(s->level(), 4);
    EXPECT_EQ(s->scheme(), Scheme::Linear);
    EXPECT_TRUE(s->displaced());
    // 20 * 4^4 triangles; 10 * 4^4 + 2 vertices on a closed genus-0 mesh.
    EXPECT_EQ(s->triangleCount(), 20u * 256u);
    EXPECT_EQ(s->vertexCount(), 10u * 256u + 2u);
    std::vector<glm::vec3> n;
    const std::vector<glm::vec3> p = evaluate(*s, &n);
    // The bilinear bound of the map (see IcosahedronAndSphereMapGiveTheSphere).
    const float edge = glm::length(rig.mesh.positions[rig.mesh.triangles[0]] - rig.mesh.positions[rig.mesh.triangles[1]]);
    const float h = edge / float(size / 4 - 4 * 2);
    float worst = 0.0f, worstNormal = 0.0f;
    for (size_t v = 0; v < p.size(); ++v) {
        worst = std::max(worst, std::fabs(glm::length(p[v]) - 1.0f));
        // On the unit sphere the shading normal is the radius, up to the
        // facets of level 4 (a few degrees).
        worstNormal = std::max(worstNormal, 1.0f - glm::dot(n[v], glm::normalize(p[v])));
    }
    EXPECT_LE(worst, 2.0f * h * h);
    EXPECT_LT(worstNormal, 0.01f);
    // Any thread count, the same bits.
    std::vector<glm::vec3> n2;
    EXPECT_TRUE(sameBits(evaluate(*s, &n2, 2), p));
    EXPECT_TRUE(sameBits(n2, n));
    // Without the displacement it is the flat icosahedron: every vertex on
    // a face, between the inradius (0.7947) and the circumradius (1) from
    // the centre, and near the face centres far inside the sphere.
    SurfaceOptions bare;
    bare.displace = false;
    bare.level = 4;
    ASSERT_TRUE(Surface::create(&s, rig, &map, bare).isOk());
    EXPECT_FALSE(s->displaced());
    float nearest = 1.0f;
    for (const glm::vec3& q : evaluate(*s)) {
        EXPECT_LE(glm::length(q), 1.0f + 1e-6f);
        EXPECT_GE(glm::length(q), 0.7946544f - 1e-6f);
        nearest = std::min(nearest, glm::length(q));
    }
    EXPECT_LT(nearest, 0.80f);
}

TEST(Surface, TileLayoutHoldsTheSameVerticesAsThePlanLayout)
{
    Rig rig;
    DisplacementMap map;
    sphereRig(&rig, &map, 256);
    SurfaceOptions tiles;
    tiles.layout = FrameLayout::Tiles;
    std::unique_ptr<Surface> a, b;
    ASSERT_TRUE(Surface::create(&a, rig, &map).isOk());
    ASSERT_TRUE(Surface::create(&b, rig, &map, tiles).isOk());
    const std::vector<glm::vec3> pa = evaluate(*a), pb = evaluate(*b);
    ASSERT_EQ(pa.size(), pb.size());
    const std::vector<uint32_t>& order = b->vertexOrder();
    for (size_t v = 0; v < pb.size(); ++v)
        ASSERT_EQ(pb[v], pa[order[v]]) << v;
    // Each layout's triangles index its own vertices: the same triangles.
    const std::vector<uint32_t>& ta = a->triangles();
    const std::vector<uint32_t>& tb = b->triangles();
    ASSERT_EQ(ta.size(), tb.size());
    double areaA = 0.0, areaB = 0.0;
    for (size_t t = 0; t < ta.size(); t += 3) {
        areaA += glm::length(glm::cross(pa[ta[t + 1]] - pa[ta[t]], pa[ta[t + 2]] - pa[ta[t]]));
        areaB += glm::length(glm::cross(pb[tb[t + 1]] - pb[tb[t]], pb[tb[t + 2]] - pb[tb[t]]));
    }
    EXPECT_NEAR(areaA, areaB, 1e-6 * areaA);
}

TEST(Surface, EveryWayToPoseGivesTheSameSurface)
{
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map);
    SurfaceOptions options;
    options.level = 3;
    std::unique_ptr<Surface> s;
    ASSERT_TRUE(Surface::create(&s, rig, &map, options).isOk());
    EXPECT_EQ(s->jointCount(), 2u);
    EXPECT_EQ(s->animationCount(), 1u);
    const std::vector<glm::vec3> rest = evaluate(*s);

    // By animation time, against the animator itself.
    ASSERT_TRUE(s->setAnimationTime(0, 0.5f).isOk());
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    ASSERT_TRUE(animator.pose(0, 0.5f).isOk());
    EXPECT_TRUE(sameBits(s->controlPositions(), animator.positions()));
    EXPECT_TRUE(sameBits(s->controlNormals(), animator.normals()));
    std::vector<glm::vec3> n1;
    const std::vector<glm::vec3> byTime = evaluate(*s, &n1);
    float moved = 0.0f;
    for (size_t v = 0; v < rest.size(); ++v)
        moved = std::max(moved, glm::length(rest[v] - byTime[v]));
    EXPECT_GT(moved, 0.1f);

    // By the skin matrices an engine computed, and by control positions it
    // deformed itself: the same bits.
    const std::vector<glm::mat4> skin = s->skinMatrices();
    ASSERT_EQ(skin.size(), 2u);
    ASSERT_TRUE(s->setRestPose().isOk());
    ASSERT_TRUE(s->setJointMatrices(skin.data(), skin.size()).isOk());
    std::vector<glm::vec3> n2;
    EXPECT_TRUE(sameBits(evaluate(*s, &n2), byTime));
    EXPECT_TRUE(sameBits(n2, n1));
    const std::vector<glm::vec3> control = animator.positions();
    ASSERT_TRUE(s->setRestPose().isOk());
    EXPECT_TRUE(sameBits(evaluate(*s), rest));
    ASSERT_TRUE(s->setControlPositions(control.data(), control.size()).isOk());
    std::vector<glm::vec3> n3;
    EXPECT_TRUE(sameBits(evaluate(*s, &n3), byTime));
    EXPECT_TRUE(sameBits(n3, n1));

    // The pieces by hand, in the order the header gives, are the same bits.
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, rig.mesh, rig.displacement.scheme, 3).isOk());
    ASSERT_TRUE(applyRigDisplacement(plan.get(), rig, &map).isOk());
    std::vector<glm::vec3> normals(control.size());
    computeControlNormals(normals.data(), control.data(), control.size(), rig.mesh.triangles.data(),
                          rig.mesh.faceCount());
    FrameEvaluator frame(*plan);
    std::vector<glm::vec3> p(plan->refinedVertexCount()), n(p.size());
    ASSERT_TRUE(frame.evaluate(p.data(), n.data(), nullptr, control.data(), normals.data(), control.size(), 1).isOk());
    EXPECT_TRUE(sameBits(p, byTime));
}

TEST(Surface, RefusesEveryInputThatWouldDrawAnotherSurface)
{
    Rig rig;
    DisplacementMap map;
    sphereRig(&rig, &map, 128);
    std::unique_ptr<Surface> s;
    auto refused = [&](const Rig& r, const DisplacementMap* m, const SurfaceOptions& o, const char* needle) {
        s.reset();
        const Status st = Surface::create(&s, r, m, o);
        EXPECT_FALSE(st.isOk()) << needle;
        EXPECT_NE(st.message().find(needle), std::string::npos) << st.message();
        EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
        EXPECT_FALSE(s) << needle;
    };
    // Another scheme with the displacement: another surface.
    SurfaceOptions smooth;
    smooth.scheme = Scheme::Smooth;
    smooth.schemeGiven = true;
    refused(rig, &map, smooth, "baked against the linear scheme");
    EXPECT_FALSE(Surface::check(rig, smooth).isOk());
    // Without it, the bare cage in any scheme.
    smooth.displace = false;
    smooth.level = 2;
    ASSERT_TRUE(Surface::create(&s, rig, &map, smooth).isOk());
    EXPECT_EQ(s->scheme(), Scheme::Smooth);
    // A map-coded rig without its map.
    refused(rig, nullptr, {}, "none was given");
    // Levels out of range, a scale that is not a number.
    SurfaceOptions deep;
    deep.level = kMaxLevel + 1;
    refused(rig, &map, deep, "out of range");
    SurfaceOptions nan;
    nan.scale = std::nanf("");
    refused(rig, &map, nan, "scale");
    // A file whose layer a tool dropped, unless the bare cage is asked for.
    Rig stripped = rig;
    stripped.hasDisplacement = false;
    stripped.layerMissing = "a tool dropped it";
    refused(stripped, &map, {}, "no displacement layer (a tool dropped it)");
    SurfaceOptions bare;
    bare.displace = false;
    EXPECT_TRUE(Surface::create(&s, stripped, &map, bare).isOk());
    // A control mesh of another topology than the rig's: applyRigDisplacement
    // refuses the plan (the displacements belong to one mesh).
    std::unique_ptr<Plan> other;
    ASSERT_TRUE(Plan::create(&other, examples::makeIcosphere(1), Scheme::Linear, 2).isOk());
    const Status st = applyRigDisplacement(other.get(), rig, &map);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("another control mesh"), std::string::npos) << st.message();

    // Poses and buffers of the wrong size.
    ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
    EXPECT_NE(s->setAnimationTime(0, 0.0f).message().find("no skin"), std::string::npos);
    glm::mat4 one(1.0f);
    EXPECT_NE(s->setJointMatrices(&one, 1).message().find("no skin"), std::string::npos);
    std::vector<glm::vec3> few(rig.mesh.vertexCount() - 1);
    Status pose = s->setControlPositions(few.data(), few.size());
    EXPECT_NE(pose.message().find("11 control positions for 12 control vertices"), std::string::npos)
        << pose.message();
    std::vector<glm::vec3> small(s->vertexCount() - 1);
    Status ev = s->evaluate(small.data(), nullptr, small.size());
    EXPECT_FALSE(ev.isOk());
    EXPECT_NE(ev.message().find("refined vertices"), std::string::npos) << ev.message();

    // A skin that weighs other vertices than the cage has (a vertex added to
    // a hand-built rig after its skeleton was finalised), or names a joint
    // past its own: refused, not read past its end.
    Rig skinned;
    DisplacementMap skinnedMap;
    test::makeBendingExampleRig(&skinned, &skinnedMap);
    ASSERT_TRUE(Surface::create(&s, skinned, &skinnedMap).isOk());
    Rig grown = skinned;
    grown.mesh.positions.push_back(glm::vec3(0.0f));
    refused(grown, &skinnedMap, {}, "the skin weighs 42 vertices and the control mesh has 43");
    Rig wild = skinned;
    wild.skeleton.weights.joints[4 * 3] = 40;
    wild.skeleton.weights.weights[4 * 3] = 1.0f;
    refused(wild, &skinnedMap, {}, "vertex 3 references joint 40 of a 2-joint skin");
}

// A pose that is not finite (a NaN or infinity an engine passed, a joint
// matrix that blew up, coordinates so large that the normals overflow) is
// refused by every pose setter with one line naming the vertex or joint,
// and the surface keeps its last pose: the same surface, the same choice
// of levels, never a NaN frame drawn with status OK.
TEST(Surface, PosesThatAreNotFiniteAreRefusedAndTheLastPoseKept)
{
    Rig rig;
    DisplacementMap map;
    std::unique_ptr<Surface> s = test::bendingSurfaceAt(0.5f, &rig, &map);
    ASSERT_TRUE(s);
    const std::vector<glm::vec3> posed = s->controlPositions(), normals = s->controlNormals();
    const std::vector<glm::mat4> skin = s->skinMatrices();
    ViewSpec view;
    view.eye = glm::vec3(0.3f, 0.2f, 5.0f);
    ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk());
    const std::vector<uint8_t> levels = s->adaptiveFrame().quarterLevels();
    const std::vector<glm::vec3> before = evaluate(*s);
    auto kept = [&](const Status& st, const std::string& needle, const std::string& label) {
        EXPECT_FALSE(st.isOk()) << label;
        EXPECT_NE(st.message().find(needle), std::string::npos) << label << ": " << st.message();
        EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
        EXPECT_TRUE(sameBits(s->controlPositions(), posed)) << label;
        EXPECT_TRUE(sameBits(s->controlNormals(), normals)) << label;
        EXPECT_TRUE(sameBits(evaluate(*s), before)) << label;
        ViewSpec nudged = view;
        nudged.eye.x += 1e-4f;
        ASSERT_TRUE(s->chooseFaceLevels(nudged, 1.0f).isOk()) << label;
        EXPECT_EQ(s->adaptiveFrame().quarterLevels(), levels) << label;
    };
    const float inf = std::numeric_limits<float>::infinity();
    for (const glm::vec3 bad : {glm::vec3(std::nanf(""), 0.0f, 0.0f), glm::vec3(0.0f, -inf, 0.0f)}) {
        std::vector<glm::vec3> p = posed;
        p[7] = bad;
        kept(s->setControlPositions(p.data(), p.size()), "control vertex 7 at (", "position " + std::to_string(bad.y));
    }
    // Finite, but so far out that the normals would overflow (the whole
    // pose moved there too), and just inside the bound: taken, and finite.
    std::vector<glm::vec3> far = posed;
    far[7] = glm::vec3(3e38f, -3e38f, 3e38f);
    kept(s->setControlPositions(far.data(), far.size()), "beyond +-1e9", "3e38");
    for (glm::vec3& p : far)
        p = p * 2e9f;
    kept(s->setControlPositions(far.data(), far.size()), "beyond +-1e9", "2e9");
    for (size_t v = 0; v < far.size(); ++v)
        far[v] = posed[v] * 1e9f / 1.5f;
    ASSERT_TRUE(s->setControlPositions(far.data(), far.size()).isOk());
    std::vector<glm::vec3> farNormals;
    const std::vector<glm::vec3> farFrame = evaluate(*s, &farNormals);
    for (size_t v = 0; v < farFrame.size(); ++v) {
        ASSERT_TRUE(std::isfinite(farFrame[v].x + farFrame[v].y + farFrame[v].z)) << v;
        ASSERT_NEAR(glm::length(farNormals[v]), 1.0f, 1e-3f) << v;
    }
    // Back to the skinned pose (as positions it would count its stretch).
    ASSERT_TRUE(s->setAnimationTime(0, 0.5f).isOk());
    // A joint matrix that is not finite, and finite ones whose skinning overflows.
    std::vector<glm::mat4> wild = skin;
    wild[1][3][0] = std::nanf("");
    kept(s->setJointMatrices(wild.data(), wild.size()), "joint 1", "NaN matrix");
    wild = skin;
    wild[0] = glm::mat4(3e38f);
    wild[0][3][3] = 1.0f;
    kept(s->setJointMatrices(wild.data(), wild.size()), "the joint matrices overflow it", "huge matrix");
    // An animation whose keys scale two nested joints by 1e20: the joint named.
    Rig grow = rig;
    grow.skeleton.animations.push_back(test::overflowingAnimation());
    std::unique_ptr<Surface> g;
    ASSERT_TRUE(Surface::create(&g, grow, &map).isOk());
    ASSERT_TRUE(g->setAnimationTime(0, 0.5f).isOk());
    const std::vector<glm::vec3> last = g->controlPositions();
    const Status st = g->setAnimationTime(1, 0.5f);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("the pose of animation 1 at 0.5"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("joint 1 (node 1"), std::string::npos) << st.message();
    EXPECT_TRUE(sameBits(g->controlPositions(), last));
    // And a good pose after a refused one is taken.
    ASSERT_TRUE(s->setControlPositions(posed.data(), posed.size()).isOk());
    ASSERT_TRUE(g->setAnimationTime(0, 0.25f).isOk());
}

// The box Surface::bounds gives holds every vertex of every frame, uniform
// and adaptive, in both schemes, as the pose moves, and is not much larger
// than the surface itself (the control box grown by the displacement).
TEST(Surface, BoundsHoldEveryPosedFrameAtEveryLevel)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        test::makeBendingExampleRig(&rig, &map);
        rig.displacement.scheme = scheme;
        SurfaceOptions options;
        options.level = 3;
        std::unique_ptr<Surface> s;
        ASSERT_TRUE(Surface::create(&s, rig, &map, options).isOk());
        float largest = 0.0f;
        for (float d : s->plan().displacements())
            largest = std::max(largest, std::fabs(d));
        ASSERT_GT(largest, 0.01f);  // a displaced surface: the growth is tested
        std::mt19937 random(7);
        std::vector<uint8_t> levels(rig.mesh.faceCount());
        for (float time : {0.0f, 0.3f, 0.7f, 1.0f}) {
            ASSERT_TRUE(s->setAnimationTime(0, time).isOk());
            glm::vec3 lo, hi;
            s->bounds(&lo, &hi);
            const std::vector<glm::vec3> p = evaluate(*s);
            glm::vec3 a = p[0], b = p[0];
            for (const glm::vec3& q : p) {
                a = glm::min(a, q);
                b = glm::max(b, q);
            }
            for (int k = 0; k < 3; ++k) {
                EXPECT_LE(lo[k], a[k]) << schemeName(scheme) << " t " << time;
                EXPECT_GE(hi[k], b[k]) << schemeName(scheme) << " t " << time;
                // No looser than the displacement twice over on each side.
                EXPECT_GE(lo[k], a[k] - 2.0f * largest - 0.05f * (b[k] - a[k]));
                EXPECT_LE(hi[k], b[k] + 2.0f * largest + 0.05f * (b[k] - a[k]));
            }
            // Random levels per face: the adaptive frame is inside too.
            for (uint8_t& l : levels)
                l = uint8_t(std::uniform_int_distribution<int>(0, 3)(random));
            ASSERT_TRUE(s->setFaceLevels(levels.data(), levels.size()).isOk());
            std::vector<glm::vec3> q(s->adaptiveFrame().vertexCount());
            ASSERT_TRUE(s->evaluateAdaptive(q.data(), nullptr, q.size()).isOk());
            for (const glm::vec3& v : q)
                ASSERT_TRUE(glm::all(glm::lessThanEqual(lo, v)) && glm::all(glm::lessThanEqual(v, hi)))
                    << schemeName(scheme) << " t " << time;
        }
    }
}

}  // namespace strata
