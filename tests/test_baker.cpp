// The baker (paper 2.1, 2.2, 3.2): the closed-form normal-volume solve,
// closed-form bakes (sphere over icosahedron, sine over a square), real
// pairs, determinism, and the command line's handling of bad input.
#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/baker/bake_rig.h"
#include "strata/baker/bake.h"
#include "strata/baker/distance.h"
#include "strata/baker/mesh_input.h"
#include "strata/baker/normal_volume.h"
#include "strata/io/exr.h"
#include "strata/io/rig_io.h"
#include "strata/normals.h"
#include "test_util.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <map>
#include <set>
#include <functional>
#include <fstream>
#include <random>

using namespace strata;
using namespace strata::baker;

namespace {

TriangleMesh icosphereMesh(int subdivisions, float radius)
{
    const ControlMesh m = examples::makeIcosphere(subdivisions);
    TriangleMesh t;
    for (const glm::vec3& p : m.positions)
        t.positions.push_back(radius * p);
    t.triangles = m.triangles;
    return t;
}

// The built-in head over a level-3 icosphere, without UVs: its relief
// breaks the surface into many charts.
ControlMesh headWithoutUVs()
{
    ControlMesh head = examples::makeIcosphere(3);
    for (glm::vec3& p : head.positions)
        p *= examples::headRadius(glm::normalize(p));
    head.uvs.clear();
    head.uvIndices.clear();
    return head;
}

// A chart atlas laid out for a size x size map with the bake's one-texel
// gutter, its UVs checked (inside the map, no two triangles overlapping).
// With `bakes`, the atlas a bake lays out (buildAtlas: charts, or one chart
// over the whole map), its UVs cleared first.
::testing::AssertionResult chartAtlas(ControlMesh* mesh, int size, ChartAtlasStats* stats, bool bakes = false)
{
    AtlasOptions options;
    options.mapSize = size;
    options.gutter = 1;
    if (bakes) {
        mesh->uvs.clear();
        mesh->uvIndices.clear();
    }
    Status s = bakes ? buildAtlas(mesh, options, stats) : buildChartAtlas(mesh, options, stats);
    if (s)
        s = checkUVs(*mesh, size);
    if (!s)
        return ::testing::AssertionFailure() << s.message();
    return ::testing::AssertionSuccess();
}


// The unit sphere baked through `control`'s atlas (a level-1 icosphere
// cage) at 256^2 comes back at level 4 within the per-triangle atlas's
// bound: chords of the sphere plus bilinear sampling, well under 1e-3 of
// the diagonal.
void expectSphereBakesBack(const ControlMesh& control)
{
    const TriangleMesh high = icosphereMesh(5, 1.0f);
    BakeOptions bakeOptions;
    bakeOptions.size = 256;
    DisplacementMap map;
    BakeReport report;
    ASSERT_TRUE(bake(&map, nullptr, &report, control, high, bakeOptions).isOk());
    std::vector<LevelError> errors;
    ASSERT_TRUE(closedLoopError(&errors, control, map, Scheme::Linear, high, 4, 4, 2).isOk());
    EXPECT_LT(errors[0].forwardRms / report.diagonal, 3e-4);
    EXPECT_LT(errors[0].backwardRms / report.diagonal, 3e-4);
    EXPECT_LT(errors[0].forwardMax / report.diagonal, 2e-3);
}
}  // namespace

TEST(NormalVolume, MapThenEquationTwoReturnsThePoint)
{
    std::mt19937 rng(1234);
    std::uniform_real_distribution<double> u(-1.0, 1.0), unit(0.0, 1.0);
    int checked = 0;
    for (int trial = 0; trial < 4000; ++trial) {
        NormalVolumeTriangle t;
        for (int k = 0; k < 3; ++k)
            t.v[k] = glm::dvec3(u(rng), u(rng), 0.2 * u(rng));
        const glm::dvec3 fn = glm::cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
        if (glm::length(fn) < 0.05)
            continue;  // keep triangles well shaped
        for (int k = 0; k < 3; ++k)
            t.n[k] = glm::normalize(glm::normalize(fn) + 0.4 * glm::dvec3(u(rng), u(rng), u(rng)));
        // Barycentrics anywhere inside, near edges, near and at vertices.
        double b1 = unit(rng), b2 = unit(rng);
        if (b1 + b2 > 1.0) {
            b1 = 1.0 - b1;
            b2 = 1.0 - b2;
        }
        switch (trial % 5) {
        case 1: b2 = 1e-9; break;                      // on an edge
        case 2: b1 = 1.0 - 1e-9; b2 = 0.0; break;      // at a vertex
        case 3: b1 = 0.5 * (1.0 - b2); break;          // interior
        default: break;
        }
        const double d = trial % 7 == 0 ? 0.0 : 0.3 * u(rng);
        const glm::dvec3 x = evaluateNormalVolume(t, b1, b2, d);
        NormalVolumeHit hit;
        ASSERT_TRUE(mapToNormalVolume(t, x, 1.0, 1e-7, &hit)) << "trial " << trial;
        const glm::dvec3 back = evaluateNormalVolume(t, hit.b1, hit.b2, hit.d);
        const double diag = 2.0 * std::sqrt(3.0);
        EXPECT_LE(glm::length(back - x), 1e-6 * diag) << "trial " << trial;
        if (d == 0.0) {
            EXPECT_NEAR(hit.d, 0.0, 1e-9) << "trial " << trial;  // on the surface, d = 0 is the smallest root
        }
        ++checked;
    }
    EXPECT_GT(checked, 2000);
}

TEST(NormalVolume, PointOutsideEveryVolumeIsReported)
{
    NormalVolumeTriangle t;
    t.v[0] = {0, 0, 0};
    t.v[1] = {1, 0, 0};
    t.v[2] = {0, 1, 0};
    t.n[0] = t.n[1] = t.n[2] = {0, 0, 1};  // a straight prism
    NormalVolumeHit hit;
    EXPECT_FALSE(mapToNormalVolume(t, {2.0, 2.0, 0.5}, 10.0, 1e-7, &hit));
    ASSERT_TRUE(mapToNormalVolume(t, {0.25, 0.25, 0.5}, 10.0, 1e-7, &hit));
    EXPECT_NEAR(hit.d, 0.5, 1e-12);
    // Negative barycentrics are allowed when re-mapping into a neighbour's plane.
    ASSERT_TRUE(mapToNormalVolumePlane(t, {2.0, 2.0, 0.5}, 0.4, 1.0, &hit));
    EXPECT_NEAR(hit.b1 + hit.b2, 4.0, 1e-9);
}

TEST(Bake, ClosedLoopInChunksMeasuresTheWholeSurface)
{
    // Streaming the closed loop in chunks of control faces measures the same
    // surface: the backward distance (each high-res sample to its nearest
    // chunk) equals the whole surface's; the forward RMS differs only by the
    // vertices chunk borders sample twice.
    ControlMesh control = examples::makeIcosphere(1);
    ASSERT_TRUE(buildTriangleAtlas(&control, {256, 2}).isOk());
    TriangleMesh high = icosphereMesh(4, 1.0f);
    for (glm::vec3& p : high.positions)
        p *= examples::headRadius(p);
    BakeOptions options;
    options.size = 256;
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        options.scheme = scheme;
        DisplacementMap map;
        ASSERT_TRUE(bake(&map, nullptr, nullptr, control, high, options).isOk());
        std::vector<LevelError> whole, chunked;
        ASSERT_TRUE(closedLoopError(&whole, control, map, scheme, high, 2, 3, 2).isOk());
        ASSERT_TRUE(closedLoopError(&chunked, control, map, scheme, high, 2, 3, 2, /*chunkTriangles=*/200).isOk());
        ASSERT_EQ(whole.size(), 2u);
        ASSERT_EQ(chunked.size(), 2u);
        for (size_t k = 0; k < 2; ++k) {
            SCOPED_TRACE(std::string(schemeName(scheme)) + " level " + std::to_string(whole[k].level));
            EXPECT_EQ(chunked[k].triangles, whole[k].triangles);
            EXPECT_NEAR(chunked[k].backwardRms, whole[k].backwardRms, 1e-6 * whole[k].backwardRms + 1e-9);
            EXPECT_NEAR(chunked[k].backwardMax, whole[k].backwardMax, 1e-6 * whole[k].backwardMax + 1e-9);
            EXPECT_NEAR(chunked[k].forwardRms, whole[k].forwardRms, 0.05 * whole[k].forwardRms);
            EXPECT_NEAR(chunked[k].forwardMax, whole[k].forwardMax, 1e-6 * whole[k].forwardMax + 1e-9);
        }
    }
}

TEST(Bake, SphereOntoIcosahedronReconstructsTheSphere)
{
    ControlMesh control = examples::makeIcosphere(0);
    ASSERT_TRUE(buildTriangleAtlas(&control, {512, 2}).isOk());
    const TriangleMesh high = icosphereMesh(5, 1.0f);  // 20480 triangles on the unit sphere
    BakeOptions options;
    options.size = 512;
    DisplacementMap map;
    BakeReport report;
    const Status st = bake(&map, nullptr, &report, control, high, options);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(report.fallbackVertices, 0u);
    EXPECT_EQ(report.raster.multiLayerTexels, 0u);  // a convex control mesh has no overfolds
    EXPECT_GT(report.coverage, 0.99);
    std::vector<LevelError> errors;
    ASSERT_TRUE(closedLoopError(&errors, control, map, Scheme::Linear, high, 0, 6, 2).isOk());
    // Both meshes are chords of the unit sphere: the input (edge 1.05 / 32)
    // sags by edge^2 / 8 = 1.3e-4, level 6 (edge 1.05 / 64) by 3.4e-5, and
    // bilinear sampling adds |d''| h^2 / 2 ~ 4e-5 (h = 1.05 / 120).  Their sum,
    // 2.1e-4, is 6e-5 of the diagonal 2 sqrt(3): the RMS must stay below 1e-4
    // and the maximum below 3e-4.
    const double diag = report.diagonal;
    EXPECT_LT(errors[6].forwardRms / diag, 1e-4);
    EXPECT_LT(errors[6].backwardRms / diag, 1e-4);
    EXPECT_LT(errors[6].forwardMax / diag, 3e-4);
    EXPECT_LT(errors[6].backwardMax / diag, 3e-4);
    // Coarser levels only add their own faceting.
    for (int level = 0; level < 6; ++level)
        EXPECT_GE(errors[size_t(level)].backwardRms, errors[6].backwardRms * 0.9) << level;
    // And every reconstructed vertex lies on the unit sphere up to that.
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, control, Scheme::Linear, 4).isOk());
    ASSERT_TRUE(plan->setDisplacement(map).isOk());
    std::vector<glm::vec3> n(control.positions.size()), x(plan->refinedVertexCount());
    computeControlNormals(n.data(), control.positions.data(), n.size(), control.triangles.data(), control.faceCount());
    ASSERT_TRUE(plan->evaluate(x.data(), nullptr, 0, x.size(), control.positions.data(), n.data(), n.size()).isOk());
    float worst = 0.0f;
    for (const glm::vec3& p : x)
        worst = std::max(worst, std::fabs(glm::length(p) - 1.0f));
    EXPECT_LT(worst, 1e-3f);  // level-4 chords sag by 5.4e-4 between vertices; the vertices themselves lie closer
}

TEST(Bake, PlaneWithSineOntoTwoTrianglesReconstructsTheSine)
{
    const ControlMesh control = examples::makeSquare();
    const float amplitude = 0.03f, k = 2.0f * float(M_PI) * 2.0f;
    TriangleMesh high;
    const int n = 200;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const float x = float(i) / n, y = float(j) / n;
            high.positions.emplace_back(x, y, amplitude * std::sin(k * x));
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
            high.triangles.insert(high.triangles.end(), {a, b, d, a, d, c});
        }
    BakeOptions options;
    options.size = 256;
    DisplacementMap map;
    BakeReport report;
    ASSERT_TRUE(bake(&map, nullptr, &report, control, high, options).isOk());
    EXPECT_EQ(report.fallbackVertices, 0u);
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, control, Scheme::Linear, 6).isOk());
    ASSERT_TRUE(plan->setDisplacement(map).isOk());
    std::vector<glm::vec3> normals(4, glm::vec3(0, 0, 1)), x(plan->refinedVertexCount());
    ASSERT_TRUE(plan->evaluate(x.data(), nullptr, 0, x.size(), control.positions.data(), normals.data(), 4).isOk());
    // Error budget: the input's own piecewise-linear sampling (A k^2 h^2 / 8
    // for h = 1/200) plus bilinear reconstruction (same with h = 1/256).
    const float hi = 1.0f / n, hm = 1.0f / 256.0f;
    const float tol = amplitude * k * k * (hi * hi + hm * hm) / 8.0f * 1.5f + 1e-6f;
    float worst = 0.0f;
    for (const glm::vec3& p : x)
        if (p.x > hm && p.x < 1.0f - hm)
            worst = std::max(worst, std::fabs(p.z - amplitude * std::sin(k * p.x)));
    EXPECT_LT(worst, tol);
}

TEST(Bake, OutputDoesNotDependOnThreadCount)
{
    ControlMesh control = examples::makeIcosphere(1);
    ASSERT_TRUE(buildTriangleAtlas(&control, {512, 2}).isOk());
    TriangleMesh high = icosphereMesh(4, 1.0f);
    for (glm::vec3& p : high.positions)
        p *= examples::headRadius(glm::normalize(p));
    BakeOptions options;
    options.size = 512;
    DisplacementMap one, two;
    options.threads = 1;
    ASSERT_TRUE(bake(&one, nullptr, nullptr, control, high, options).isOk());
    options.threads = 2;
    ASSERT_TRUE(bake(&two, nullptr, nullptr, control, high, options).isOk());
    ASSERT_EQ(one.texels.size(), two.texels.size());
    EXPECT_EQ(0, std::memcmp(one.texels.data(), two.texels.data(), one.texels.size() * sizeof(float)));
}

// A triangle index built on threads (they share its Morton-code and box
// passes) answers exactly as the one built on one thread:
// the same face, distance and line hits for random queries, and on the
// sphere the distance is the gap to the radius.
TEST(Bake, TriangleIndexDoesNotDependOnThreadCount)
{
    const TriangleMesh sphere = icosphereMesh(6, 1.0f);  // 81920 triangles
    TriangleIndex one, three;
    one.build(sphere.positions.data(), sphere.triangles.data(), sphere.faceCount(), 1);
    three.build(sphere.positions.data(), sphere.triangles.data(), sphere.faceCount(), 3);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> uni(-1.5, 1.5);
    for (int q = 0; q < 2000; ++q) {
        const glm::dvec3 x(uni(rng), uni(rng), uni(rng));
        uint32_t f1 = 0, f3 = 0;
        const double d1 = one.nearest(x, &f1), d3 = three.nearest(x, &f3);
        ASSERT_EQ(f1, f3) << q;
        ASSERT_EQ(d1, d3) << q;
        EXPECT_NEAR(d1, std::abs(glm::length(x) - 1.0), 2e-3) << q;  // the flat facets lie within 1e-3 of it
        double t1 = 0.0, t3 = 0.0;
        const glm::dvec3 dir = glm::normalize(x);
        ASSERT_EQ(one.intersectLine(x, dir, 3.0, &t1), three.intersectLine(x, dir, 3.0, &t3));
        ASSERT_EQ(t1, t3) << q;
    }
}

// The four-wide tree's nearest point is the brute-force one: the same
// smallest distance, ties to the lowest face, on random triangle soup and
// random queries near and far, with and without a hint.  nearestWithin is
// that distance clamped to its bound.  A non-finite query has no answer, and
// a triangle with a NaN corner is never an answer, nor does it slow the
// other queries into a walk of the whole tree (they see the same faces).
TEST(Bake, TriangleIndexNearestIsTheBruteForceOne)
{
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> uni(-1.0f, 1.0f), small(-0.05f, 0.05f);
    TriangleMesh soup;
    for (int t = 0; t < 3000; ++t) {
        const glm::vec3 c(uni(rng), uni(rng), uni(rng));
        for (int k = 0; k < 3; ++k) {
            soup.triangles.push_back(uint32_t(soup.positions.size()));
            soup.positions.push_back(c + glm::vec3(small(rng), small(rng), small(rng)));
        }
    }
    TriangleIndex index;
    index.build(soup.positions.data(), soup.triangles.data(), soup.faceCount(), 2);
    // Independently of the index's routine: the plane when the projection
    // falls inside, else the nearest of the three edges.
    auto segment2 = [](const glm::dvec3& x, const glm::dvec3& a, const glm::dvec3& b) {
        const glm::dvec3 ab = b - a;
        const double t = std::clamp(glm::dot(x - a, ab) / glm::dot(ab, ab), 0.0, 1.0);
        const glm::dvec3 c = a + t * ab;
        return glm::dot(x - c, x - c);
    };
    auto triangle2 = [&](const glm::dvec3& x, uint32_t f) {
        const glm::dvec3 a(soup.positions[3 * f]), b(soup.positions[3 * f + 1]), c(soup.positions[3 * f + 2]);
        const glm::dvec3 n = glm::normalize(glm::cross(b - a, c - a));
        const glm::dvec3 p = x - glm::dot(x - a, n) * n;
        const bool inside = glm::dot(glm::cross(b - a, p - a), n) >= 0.0 && glm::dot(glm::cross(c - b, p - b), n) >= 0.0 &&
                            glm::dot(glm::cross(a - c, p - c), n) >= 0.0;
        if (inside)
            return glm::dot(x - p, x - p);
        return std::min({segment2(x, a, b), segment2(x, b, c), segment2(x, c, a)});
    };
    auto bruteForce = [&](const glm::dvec3& x, uint32_t* face) {
        double best = 1e300;
        for (uint32_t f = 0; f < soup.faceCount(); ++f)
            if (const double d2 = triangle2(x, f); d2 < best) {
                best = d2;
                *face = f;
            }
        return best;
    };
    std::uniform_real_distribution<double> far(-3.0, 3.0);
    int64_t hint = -1;
    for (int q = 0; q < 400; ++q) {
        const glm::dvec3 x(far(rng), far(rng), far(rng));
        uint32_t expected = 0, got = 0, hinted = 0;
        const double best2 = bruteForce(x, &expected);
        const double d = index.nearest(x, &got);
        ASSERT_NEAR(d * d, best2, 1e-6 * best2) << q;
        if (got != expected) {  // only a tie within the float the index compares in
            ASSERT_NEAR(triangle2(x, got), best2, 1e-6 * best2) << q;
        }
        index.nearest(x, &hinted, nullptr, nullptr, int64_t(q % soup.faceCount()));
        ASSERT_EQ(hinted, got) << q;
        const double bound = 0.5 * d;
        EXPECT_EQ(index.nearestWithin(x, bound, &hint), bound) << q;
        EXPECT_EQ(index.nearestWithin(x, 2.0 * d + 1e-3, &hint), d) << q;
        EXPECT_EQ(hint, int64_t(got)) << q;
    }
    EXPECT_LT(index.nearest(glm::dvec3(std::nan(""), 0.0, 0.0)), 0.0);
    EXPECT_LT(index.nearest(glm::dvec3(0.0, std::numeric_limits<double>::infinity(), 0.0)), 0.0);
    const baker::DistanceStats lost = baker::sampleDistance({glm::vec3(std::nanf(""))}, index, 1);
    EXPECT_TRUE(std::isinf(lost.rms));

    // One corner NaN: that triangle is never the answer.
    TriangleMesh poisoned = soup;
    poisoned.positions[3 * 17 + 1] = glm::vec3(std::nanf(""), 0.0f, 0.0f);
    TriangleIndex pi;
    pi.build(poisoned.positions.data(), poisoned.triangles.data(), poisoned.faceCount(), 1);
    for (int q = 0; q < 200; ++q) {
        const glm::dvec3 x(far(rng), far(rng), far(rng));
        uint32_t a = 0, b = 0;
        index.nearest(x, &a);
        const double d = pi.nearest(x, &b);
        ASSERT_TRUE(std::isfinite(d)) << q;
        ASSERT_NE(b, 17u) << q;
        if (a != 17u) {
            ASSERT_EQ(a, b) << q;
        }
    }
    // The bound counts the samples beyond it.
    const std::vector<glm::vec3> samples{glm::vec3(10.0f), glm::vec3(soup.positions[0])};
    const baker::DistanceStats bounded = baker::sampleDistance(samples, index, 1, 1.0);
    EXPECT_EQ(bounded.beyond, 1u);
    EXPECT_EQ(bounded.max, 1.0);
    EXPECT_NEAR(bounded.rms, std::sqrt(0.5), 1e-6);
}

TEST(Bake, DegenerateDuplicateAndNonManifoldInputIsTolerated)
{
    ControlMesh control = examples::makeIcosphere(0);
    ASSERT_TRUE(buildTriangleAtlas(&control, {256, 2}).isOk());
    TriangleMesh high = icosphereMesh(4, 1.0f);
    const size_t clean = high.faceCount();
    // A zero-area triangle, a duplicated vertex and a fin making an edge non-manifold.
    high.triangles.insert(high.triangles.end(), {0, 0, 1});
    high.positions.push_back(high.positions[5]);
    high.positions.push_back(1.02f * high.positions[7]);
    const uint32_t dup = uint32_t(high.positions.size() - 2), tip = dup + 1;
    high.triangles.insert(high.triangles.end(), {high.triangles[0], high.triangles[1], tip});
    high.triangles.insert(high.triangles.end(), {dup, high.triangles[4], high.triangles[5]});
    BakeOptions options;
    options.size = 256;
    DisplacementMap map;
    BakeReport report;
    ASSERT_TRUE(bake(&map, nullptr, &report, control, high, options).isOk());
    EXPECT_EQ(report.raster.degenerateTriangles, 1u);
    EXPECT_EQ(report.highTriangles, clean + 3);
}

namespace {

struct RealPair {
    const char* high;
    const char* control;
};

void checkRealPair(const RealPair& pair, const std::string& highPath, const std::string& controlPath)
{
    TriangleMesh high;
    ASSERT_TRUE(loadHighMesh(highPath, &high, nullptr).isOk());
    ControlMesh control;
    ASSERT_TRUE(loadControlMesh(controlPath, &control).isOk());
    AtlasOptions atlas;
    atlas.mapSize = 1024;
    atlas.gutter = 2;
    ASSERT_TRUE(buildTriangleAtlas(&control, atlas).isOk());
    BakeOptions options;
    options.scheme = Scheme::Smooth;
    options.size = 1024;
    DisplacementMap map;
    BakeReport report;
    const Status st = bake(&map, nullptr, &report, control, high, options);
    ASSERT_TRUE(st.isOk()) << st.message();
    int level = 0;
    while (level < kMaxLevel && (control.faceCount() << (2 * level)) <= high.faceCount())
        ++level;
    std::vector<LevelError> errors;
    ASSERT_TRUE(closedLoopError(&errors, control, map, Scheme::Smooth, high, 0, level, 2).isOk());
    const LevelError& e = errors.back();
    // Issue bar: RMS at most 0.1% of the bounding-box diagonal, both directions.
    EXPECT_LE(e.forwardRms / report.diagonal, 1e-3) << pair.high << " level " << level;
    EXPECT_LE(e.backwardRms / report.diagonal, 1e-3) << pair.high << " level " << level;
}

}  // namespace

TEST(BakeRealData, SpotSmoothWithinTheRmsBar)
{
    STRATA_REQUIRE_DATA(high, "spot_triangulated.obj");
    STRATA_REQUIRE_DATA(control, "spot_control_mesh.obj");
    checkRealPair({"spot", "spot"}, high, control);
}

// Penguin's raw map (no cage fit, values sampled from the map) misses the
// bar where its feet fold under the cage: measured by area, 1.4% of the
// surface there carries 99% of the squared error (0.146% RMS at level 4;
// sampled at vertices and centroids, which that sparse region has few of,
// it looked like 0.09%).  The default bake (a fitted cage, stored values
// fitted to the capture) is what ships: it reaches the bar with room.
TEST(BakeRealData, PenguinSmoothWithinTheRmsBar)
{
    STRATA_REQUIRE_DATA(high, "penguin_hr.obj");
    STRATA_REQUIRE_DATA(control, "penguin_control_mesh.obj");
    const std::string dir = test::tempDir("penguin_bar");
    BakeRequest request;
    request.high = high;
    request.control = control;
    request.output = dir + "/penguin.glb";
    request.options.scheme = Scheme::Smooth;
    request.schemeGiven = true;
    request.options.threads = 2;
    request.errorFrom = request.errorTo = 4;
    BakeResult result;
    const Status st = bakeRig(request, &result);
    ASSERT_TRUE(st.isOk()) << st.message();
    const nlohmann::json report = nlohmann::json::parse(result.report);
    ASSERT_FALSE(report["closedLoop"].empty()) << result.report;
    for (const nlohmann::json& e : report["closedLoop"]) {
        EXPECT_LE(e["forwardRms"].get<double>(), 1e-3) << "level " << e["level"];
        EXPECT_LE(e["backwardRms"].get<double>(), 1e-3) << "level " << e["level"];
    }
}

TEST(BakeRealData, SpotsShippedUVsAreRejectedAsOverlapping)
{
    STRATA_REQUIRE_DATA(controlPath, "spot_control_mesh.obj");
    ControlMesh control;
    ASSERT_TRUE(loadControlMesh(controlPath, &control).isOk());
    std::string note;
    EXPECT_TRUE(fitUVsToUnitSquare(&control, &note));  // spot's u reaches -0.052
    EXPECT_NE(note.find("rescaled"), std::string::npos);
    const Status st = checkUVs(control, 1024);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("overlap in UV space"), std::string::npos) << st.message();
}

// The evidence report's accuracy column rests on TriangleIndex /
// sampleDistance: cross-check them on a sphere against a scaled sphere.  For
// a polyhedron inscribed in the unit sphere, every vertex v is its own
// nearest point from s v (s > 1): v . w <= 1 = v . v for every w in it, so v
// lies in its normal cone.  So the one-sided distance from the scaled
// sphere's vertices is exactly s - 1, and the Hausdorff distance of the two
// spheres is s - 1 up to the tessellation's sagitta.
TEST(Distance, SphereAgainstScaledSphereIsExact)
{
    const ControlMesh a = examples::makeIcosphere(4);
    const float s = 1.25f;
    std::vector<glm::vec3> scaled = a.positions;
    for (glm::vec3& p : scaled)
        p *= s;
    baker::TriangleIndex ia, ib;
    ia.build(a.positions.data(), a.triangles.data(), a.faceCount());
    ib.build(scaled.data(), a.triangles.data(), a.faceCount());
    const baker::DistanceStats outward = baker::sampleDistance(scaled, ia, 2);
    EXPECT_NEAR(outward.max, s - 1.0f, 2e-6);
    EXPECT_NEAR(outward.rms, s - 1.0f, 2e-6);
    // Face centroids and the other direction: within the sagitta of a
    // level-4 icosphere edge (about 0.0012 of the radius).
    const std::vector<glm::vec3> samples =
        baker::surfaceSamples(a.positions.data(), a.positions.size(), a.triangles.data(), a.faceCount());
    const baker::DistanceStats inward = baker::sampleDistance(samples, ib, 2);
    EXPECT_NEAR(inward.max, s - 1.0f, 0.002 * s);
    EXPECT_NEAR(inward.rms, s - 1.0f, 0.002 * s);
    EXPECT_GT(inward.samples, a.positions.size());
}

TEST(Atlas, ChartAtlasIsCompactAndFoldFree)
{
    // A sphere of 1280 triangles: disk charts, each the largest breadth-first
    // growth whose rigid flattening keeps every direction's sampling within
    // kChartMaxDistortion of the chart's mean, flattened without flips,
    // packed without overlaps.
    ControlMesh sphere = examples::makeIcosphere(3);
    sphere.uvs.clear();
    sphere.uvIndices.clear();
    ChartAtlasStats stats;
    ASSERT_TRUE(chartAtlas(&sphere, 1024, &stats));
    EXPECT_GT(stats.charts, 1u);  // a closed surface is no disk
    EXPECT_LT(stats.charts, sphere.faceCount() / 8);
    EXPECT_GE(stats.maxDistortion, 1.0);
    EXPECT_LE(stats.maxDistortion, kChartMaxDistortion) << stats.maxDistortion;
    EXPECT_GT(stats.texelFill, 0.7);  // 75%: seven charts grown to at most a quarter of the sphere
    // No chart folds: no face is degenerate in UV space, and faces that
    // share a UV edge turn the same way (a chart may be placed mirrored,
    // as a whole).
    std::map<std::pair<uint32_t, uint32_t>, std::vector<bool>> edgeTurns;
    for (size_t f = 0; f < sphere.faceCount(); ++f) {
        const glm::vec2 a = sphere.uvs[sphere.uvIndices[3 * f]], b = sphere.uvs[sphere.uvIndices[3 * f + 1]],
                        c = sphere.uvs[sphere.uvIndices[3 * f + 2]];
        const float turn = (b - a).x * (c - a).y - (b - a).y * (c - a).x;
        EXPECT_NE(turn, 0.0f) << f;
        for (int k = 0; k < 3; ++k) {
            const uint32_t u = sphere.uvIndices[3 * f + size_t(k)], v = sphere.uvIndices[3 * f + size_t((k + 1) % 3)];
            edgeTurns[{std::min(u, v), std::max(u, v)}].push_back(turn > 0.0f);
        }
    }
    size_t sharedEdges = 0;
    for (const auto& [edge, turns] : edgeTurns)
        if (turns.size() == 2) {
            ++sharedEdges;
            EXPECT_EQ(turns[0], turns[1]) << edge.first << " " << edge.second;
        }
    EXPECT_GT(sharedEdges, sphere.faceCount());  // most of the 1920 edges lie inside charts
    // Vertices split only on chart borders: far fewer than a per-triangle atlas's three per face.
    std::set<std::pair<uint32_t, uint32_t>> fileVertices;
    for (size_t i = 0; i < sphere.triangles.size(); ++i)
        fileVertices.insert({sphere.triangles[i], sphere.uvIndices[i]});
    EXPECT_LE(double(fileVertices.size()), 1.3 * double(sphere.positions.size()));
}

// The charts of an atlas: the components of faces joined by edges whose
// UVs they share (chartOfFace: a representative face per component), and
// each face's neighbour across each edge (-1 on borders and non-manifold
// edges).
struct AtlasCharts {
    std::vector<uint32_t> chartOfFace;
    std::vector<std::array<int64_t, 3>> across;
};

AtlasCharts atlasCharts(const ControlMesh& mesh)
{
    const size_t nf = mesh.faceCount();
    std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<uint32_t, int>>> edges;
    for (uint32_t f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = mesh.triangles[3 * f + k], b = mesh.triangles[3 * f + (k + 1) % 3];
            edges[{std::min(a, b), std::max(a, b)}].push_back({f, k});
        }
    std::vector<uint32_t> chart(nf);
    for (uint32_t f = 0; f < nf; ++f)
        chart[f] = f;
    std::function<uint32_t(uint32_t)> root = [&](uint32_t f) { return chart[f] == f ? f : chart[f] = root(chart[f]); };
    AtlasCharts out;
    out.across.assign(nf, {-1, -1, -1});
    for (const auto& [key, uses] : edges) {
        if (uses.size() != 2)
            continue;
        const auto [f, k] = uses[0];
        const auto [g, l] = uses[1];
        out.across[f][size_t(k)] = g;
        out.across[g][size_t(l)] = f;
        // Shared UVs: f's corners k, k + 1 are g's l + 1, l.
        if (mesh.uvIndices[3 * f + size_t(k)] == mesh.uvIndices[3 * g + size_t((l + 1) % 3)] &&
            mesh.uvIndices[3 * f + size_t((k + 1) % 3)] == mesh.uvIndices[3 * g + size_t(l)])
            chart[root(f)] = root(g);
    }
    out.chartOfFace.resize(nf);
    for (uint32_t f = 0; f < nf; ++f)
        out.chartOfFace[f] = root(f);
    return out;
}

// A developable surface (half of a prism's side, 16 rectangles around by 8
// along, each split in two) flattens without distortion: its conformal,
// then rigid, map is its unfolding, so each UV edge is its 3D edge times its
// chart's one scale.  (Whole, it would be one chart, a strip 1.57 times as
// long as wide; in quarters of its surface it packs better, 72%.)
TEST(Atlas, DevelopableSurfaceUnfoldsIsometrically)
{
    const int around = 16, along = 8;
    ControlMesh tube;
    for (int j = 0; j <= along; ++j)
        for (int i = 0; i <= around; ++i) {
            const double t = 3.14159265358979 * double(i) / double(around);
            tube.positions.emplace_back(float(std::cos(t)), float(std::sin(t)), float(0.25 * j));
        }
    auto at = [&](int i, int j) { return uint32_t(j * (around + 1) + i); };
    for (int j = 0; j < along; ++j)
        for (int i = 0; i < around; ++i) {
            for (uint32_t v : {at(i, j), at(i + 1, j), at(i + 1, j + 1)})
                tube.triangles.push_back(v);
            for (uint32_t v : {at(i, j), at(i + 1, j + 1), at(i, j + 1)})
                tube.triangles.push_back(v);
        }
    ChartAtlasStats stats;
    ASSERT_TRUE(chartAtlas(&tube, 512, &stats));
    EXPECT_LT(stats.maxDistortion, 1.0 + 1e-4);
    const size_t nf = tube.faceCount();
    const std::vector<uint32_t> chart = atlasCharts(tube).chartOfFace;
    std::map<uint32_t, std::pair<double, double>> ratio;  // per chart: smallest, largest UV / 3D edge
    for (uint32_t f = 0; f < nf; ++f) {
        glm::dvec3 p[3];
        for (int k = 0; k < 3; ++k)
            p[k] = glm::dvec3(tube.positions[tube.triangles[3 * f + size_t(k)]]);
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 u = glm::dvec2(tube.uvs[tube.uvIndices[3 * f + size_t(k)]]),
                             v = glm::dvec2(tube.uvs[tube.uvIndices[3 * f + size_t((k + 1) % 3)]]);
            const double r = glm::length(u - v) / glm::length(p[k] - p[(k + 1) % 3]);
            auto it = ratio.emplace(chart[f], std::make_pair(r, r)).first;
            it->second.first = std::min(it->second.first, r);
            it->second.second = std::max(it->second.second, r);
        }
    }
    EXPECT_EQ(ratio.size(), stats.charts);
    for (const auto& [c, r] : ratio)
        EXPECT_LT(r.second / r.first, 1.0 + 1e-3) << "chart " << c << ": " << r.first << " .. " << r.second;
    EXPECT_GT(stats.texelFill, 0.7);
}

// A chart only a texel or two across is stretched across its short side to
// six texels (bilinear samples inside it then read texels it covers), not
// scaled up whole: a sliver face beside a square keeps close to the
// square's texels per unit along its length.  Scaled up whole, this one
// would be about seven times as long as the square's scale makes it and
// would crowd the map.
TEST(Atlas, ThinChartIsStretchedAcrossOnly)
{
    ControlMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {3, 0, 0}, {4, 0, 0}, {3.5f, 0.005f, 0}};
    mesh.triangles = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    ChartAtlasStats stats;
    ASSERT_TRUE(chartAtlas(&mesh, 256, &stats));
    ASSERT_EQ(stats.charts, 2u);
    auto texels = [&](size_t f, int k) {  // UV length of face f's edge k, in texels
        const glm::dvec2 a = glm::dvec2(mesh.uvs[mesh.uvIndices[3 * f + size_t(k)]]),
                         b = glm::dvec2(mesh.uvs[mesh.uvIndices[3 * f + size_t((k + 1) % 3)]]);
        return 256.0 * glm::length(a - b);
    };
    const double square = texels(0, 0);  // edge (0,0,0)-(1,0,0): texels per unit
    const double along = texels(2, 0);   // the sliver's unit-long edge
    // Its height: twice its area over its long edge, in texels.
    const glm::dvec2 a = glm::dvec2(mesh.uvs[mesh.uvIndices[6]]), b = glm::dvec2(mesh.uvs[mesh.uvIndices[7]]),
                     c = glm::dvec2(mesh.uvs[mesh.uvIndices[8]]);
    const double across = 256.0 * std::fabs((b - a).x * (c - a).y - (b - a).y * (c - a).x) / glm::length(b - a);
    EXPECT_GT(square, 100.0);
    EXPECT_GE(across, 6.0 - 1e-3);
    // Packing may grow either chart into free space, up to twice its scale.
    EXPECT_LT(along, 2.0 * square + 1e-6) << across;
    EXPECT_GT(along, 0.5 * square - 1e-6) << across;
}

// Straight chart borders on the built-in head (its relief breaks the
// surface into many charts): few faces touch their own chart along one edge
// and one other chart along both others, the teeth breadth-first growth
// leaves.  Charts are the components of faces joined by edges whose UVs
// they share.
TEST(Atlas, ChartBordersHaveNoTeeth)
{
    ControlMesh sphere = headWithoutUVs();
    ChartAtlasStats stats;
    ASSERT_TRUE(chartAtlas(&sphere, 512, &stats));
    EXPECT_GT(stats.charts, 4u);
    const size_t nf = sphere.faceCount();
    const AtlasCharts charts = atlasCharts(sphere);
    const std::vector<std::array<int64_t, 3>>& across = charts.across;
    auto root = [&](uint32_t f) { return charts.chartOfFace[f]; };
    size_t teeth = 0;
    for (uint32_t f = 0; f < nf; ++f) {
        int own = 0;
        std::map<uint32_t, int> others;
        for (int k = 0; k < 3; ++k) {
            if (across[f][size_t(k)] < 0)
                continue;
            const uint32_t c = root(uint32_t(across[f][size_t(k)]));
            if (c == root(f))
                ++own;
            else
                ++others[c];
        }
        for (const auto& [c, count] : others)
            teeth += own == 1 && count == 2;
    }
    // A tooth stays only where its own chart's disk, or either chart's
    // flattening, forbids the move (none of 1280 here).
    EXPECT_LE(teeth, nf / 200);
}

TEST(Atlas, SphereBakedThroughAChartAtlasIsTheSphere)
{
    ControlMesh control = examples::makeIcosphere(1);
    AtlasOptions options;
    options.mapSize = 256;
    options.gutter = 1;
    ASSERT_TRUE(buildChartAtlas(&control, options).isOk());
    expectSphereBakesBack(control);
}

// Per-vertex values measured on the capture: an icosahedral cage inside a
// finely tessellated sphere of radius 1.1; every refined vertex, moved by
// its measured value along its direction, lands on that sphere (up to the
// capture's own chord error), whatever the map said within the window.
TEST(Measure, VertexDisplacementsLandOnTheCapture)
{
    const ControlMesh cage = examples::makeIcosphere(1);
    ControlMesh sphere = examples::makeIcosphere(5);
    for (glm::vec3& p : sphere.positions)
        p *= 1.1f;
    TriangleIndex index;
    index.build(sphere.positions.data(), sphere.triangles.data(), sphere.faceCount());
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        std::unique_ptr<Plan> plan;
        ASSERT_TRUE(Plan::create(&plan, cage, scheme, 3).isOk());
        std::vector<float> values(plan->refinedVertexCount(), 0.05f);  // a poor first guess, inside the window
        size_t replaced = 0;
        ASSERT_TRUE(measureVertexDisplacements(&values, cage, scheme, 3, index, 0.5, 2, &replaced).isOk());
        EXPECT_EQ(replaced, values.size());
        ASSERT_TRUE(plan->setDisplacements(values.data(), values.size()).isOk());
        std::vector<glm::vec3> normals(cage.positions.size()), out(values.size());
        computeControlNormals(normals.data(), cage.positions.data(), normals.size(), cage.triangles.data(),
                              cage.faceCount());
        ASSERT_TRUE(plan->evaluate(out.data(), nullptr, 0, out.size(), cage.positions.data(), normals.data(),
                                   normals.size())
                        .isOk());
        for (size_t v = 0; v < out.size(); ++v)
            ASSERT_NEAR(glm::length(out[v]), 1.1f, 2e-3f) << schemeName(scheme) << " vertex " << v;
    }
    // A window that excludes the capture keeps the given values.
    std::vector<float> values(642, 0.0f);
    size_t replaced = 1;
    ASSERT_TRUE(measureVertexDisplacements(&values, cage, Scheme::Linear, 2, index, 0.01, 2, &replaced).isOk());
    EXPECT_EQ(replaced, 0u);
    EXPECT_EQ(values, std::vector<float>(642, 0.0f));
}

// Holes of a control mesh closed where the capture is closed: an icosphere
// with one vertex's fan removed gets a five-triangle cap, consistently
// oriented, and is closed again (Euler characteristic 2).
TEST(ControlMeshHoles, BoundaryLoopsCloseWithConsistentFans)
{
    ControlMesh m = examples::makeIcosphere(1);
    const size_t faces = m.faceCount();
    std::vector<uint32_t> kept;
    for (size_t f = 0; f < faces; ++f) {
        const uint32_t* t = &m.triangles[3 * f];
        if (t[0] != 0 && t[1] != 0 && t[2] != 0)
            kept.insert(kept.end(), t, t + 3);
    }
    m.triangles = kept;
    EXPECT_EQ(countBoundaryEdges(m.triangles.data(), m.faceCount()), 5u);
    EXPECT_EQ(closeBoundaryLoops(&m), 1u);
    EXPECT_EQ(m.faceCount(), faces);  // five removed, five added
    EXPECT_EQ(countBoundaryEdges(m.triangles.data(), m.faceCount()), 0u);
    // Every directed edge once: the cap is oriented like its neighbours.
    std::vector<std::pair<uint32_t, uint32_t>> directed;
    for (size_t f = 0; f < m.faceCount(); ++f)
        for (int k = 0; k < 3; ++k)
            directed.push_back({m.triangles[3 * f + size_t(k)], m.triangles[3 * f + size_t((k + 1) % 3)]});
    std::sort(directed.begin(), directed.end());
    EXPECT_EQ(std::adjacent_find(directed.begin(), directed.end()), directed.end());
    // The new vertex sits at the hole's centroid, inside the sphere.
    EXPECT_LT(glm::length(m.positions.back()), 1.0f);
    // A closed mesh has nothing to close.
    ControlMesh closed = examples::makeIcosphere(1);
    EXPECT_EQ(closeBoundaryLoops(&closed), 0u);
}

// A boundary whose edges chain into a vertex that no boundary edge leaves
// (inconsistent orientation around non-manifold edges) is no closed loop:
// nothing is closed, and nothing is read past the boundary list (the
// chain's end was looked up beyond it: a heap overflow under ASan).
TEST(ControlMeshHoles, ABoundaryChainThatEndsOpenIsLeftAlone)
{
    ControlMesh m;
    for (int i = 0; i < 5; ++i)
        m.positions.push_back(glm::vec3(float(i), float(i * i % 3), float(i % 2)));
    m.triangles = {1, 0, 3, 4, 1, 3, 4, 2, 3, 2, 3, 1, 4, 0, 1, 4, 1, 2};
    const ControlMesh before = m;
    EXPECT_EQ(closeBoundaryLoops(&m), 0u);
    EXPECT_EQ(m.triangles, before.triangles);
    EXPECT_EQ(m.positions.size(), before.positions.size());
}

// A chart cache makes the same atlas at every size as a fresh layout, and is
// not fooled by a mesh whose positions changed.
TEST(Atlas, ChartCacheGivesTheSameAtlas)
{
    const ControlMesh head = headWithoutUVs();
    ChartCache cache;
    for (int size : {256, 512, 256}) {
        AtlasOptions options;
        options.mapSize = size;
        options.gutter = 1;
        ControlMesh fresh = head, reused = head;
        ASSERT_TRUE(buildChartAtlas(&fresh, options).isOk());
        ASSERT_TRUE(buildChartAtlas(&reused, options, nullptr, &cache).isOk());
        EXPECT_EQ(fresh.uvs, reused.uvs) << size;
        EXPECT_EQ(fresh.uvIndices, reused.uvIndices) << size;
    }
    ControlMesh moved = head;
    for (glm::vec3& p : moved.positions)
        p *= glm::vec3(1.0f, 0.5f, 1.0f);
    AtlasOptions options;
    options.mapSize = 512;
    options.gutter = 1;
    ControlMesh fresh = moved;
    ASSERT_TRUE(buildChartAtlas(&fresh, options).isOk());
    ASSERT_TRUE(buildChartAtlas(&moved, options, nullptr, &cache).isOk());
    EXPECT_EQ(fresh.uvs, moved.uvs);
}

// True when the closed square of half-side r about p meets triangle t
// (separating axes: the square's two, the triangle's three edge normals).
// The test's own check, independent of the packer's per-column extents.
bool squareMeetsTriangle(const glm::dvec2& p, double r, const glm::dvec2 t[3])
{
    const double minX = std::min({t[0].x, t[1].x, t[2].x}), maxX = std::max({t[0].x, t[1].x, t[2].x});
    const double minY = std::min({t[0].y, t[1].y, t[2].y}), maxY = std::max({t[0].y, t[1].y, t[2].y});
    if (maxX < p.x - r || minX > p.x + r || maxY < p.y - r || minY > p.y + r)
        return false;
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 a = t[k], b = t[(k + 1) % 3], o = t[(k + 2) % 3];
        const glm::dvec2 n(b.y - a.y, a.x - b.x);
        const double side = glm::dot(n, o - a);
        const double centre = glm::dot(n, p - a), extent = r * (std::fabs(n.x) + std::fabs(n.y));
        if (side > 0.0 ? centre + extent < 0.0 : side < 0.0 ? centre - extent > 0.0 : false)
            return false;
    }
    return true;
}

// Charts grown into the pack's gaps keep their gutters: no texel that a
// bilinear sample inside one chart reads (its centre within a texel of the
// chart, both axes) is read from inside another.  Charts are the components
// of faces joined by edges whose UVs they share.  And the growth fills the
// map: the head's 14 charts cover 73.0% of its texels at 256^2 and 74.6% at
// 512^2 (64.0% and 65.2% packed at one common scale).  Charts at the map's
// edge read its border texels: the sampler clamps to the edge.
TEST(Atlas, ChartsGrownIntoGapsReadOnlyTheirOwnTexels)
{
    for (int size : {256, 512}) {
        ControlMesh head = headWithoutUVs();
        ChartAtlasStats stats;
        ASSERT_TRUE(chartAtlas(&head, size, &stats));
        EXPECT_GT(stats.texelFill, size == 256 ? 0.70 : 0.72) << size;
        const size_t nf = head.faceCount();
        const std::vector<uint32_t> chart = atlasCharts(head).chartOfFace;
        std::vector<int64_t> reader(size_t(size) * size_t(size), -1);
        size_t shared = 0, read = 0;
        for (uint32_t f = 0; f < nf; ++f) {
            glm::dvec2 t[3];
            for (int k = 0; k < 3; ++k)
                t[k] = glm::dvec2(head.uvs[head.uvIndices[3 * f + size_t(k)]]) * double(size);
            const int x0 = int(std::floor(std::min({t[0].x, t[1].x, t[2].x}))) - 2;
            const int x1 = int(std::ceil(std::max({t[0].x, t[1].x, t[2].x}))) + 2;
            const int y0 = int(std::floor(std::min({t[0].y, t[1].y, t[2].y}))) - 2;
            const int y1 = int(std::ceil(std::max({t[0].y, t[1].y, t[2].y}))) + 2;
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x) {
                    // Bilinear weights vanish at a full texel: the open square.
                    if (!squareMeetsTriangle(glm::dvec2(x + 0.5, y + 0.5), 1.0 - 1e-6, t))
                        continue;
                    // Off the map, the sampler reads the edge texel (clamp to edge).
                    const int cx = std::clamp(x, 0, size - 1), cy = std::clamp(y, 0, size - 1);
                    int64_t& owner = reader[size_t(cy) * size_t(size) + size_t(cx)];
                    if (owner < 0) {
                        owner = chart[f];
                        ++read;
                    } else if (owner != int64_t(chart[f])) {
                        ++shared;
                    }
                }
        }
        EXPECT_EQ(shared, 0u) << size;
        EXPECT_GT(read, size_t(0.6 * size * size)) << size;
    }
}

// From 1024^2 up the orientations of each chart are tried on several
// threads; the layout is the one a single thread makes, and a valid one.
TEST(Atlas, PackingOnThreadsGivesTheSameLayout)
{
    const ControlMesh head = headWithoutUVs();
    AtlasOptions options;
    options.mapSize = 1024;
    options.gutter = 1;
    ControlMesh one = head;
    ASSERT_TRUE(buildChartAtlas(&one, options).isOk());
    for (int threads : {2, 3, 8}) {
        options.threads = threads;
        ControlMesh many = head;
        ASSERT_TRUE(buildChartAtlas(&many, options).isOk());
        EXPECT_EQ(one.uvs, many.uvs) << threads;
        EXPECT_EQ(one.uvIndices, many.uvIndices) << threads;
    }
    ASSERT_TRUE(checkUVs(one, 1024).isOk());
}

// Issue 11's bars on real cages: at least 70% of the map inside charts and
// few split vertices, at the sizes their bakes choose (256^2).  Spot's and
// the penguin's cages filled 68.8% and 68.3% (340 and 364 vertices) before
// border faces moved wherever that splits fewer vertices (retried one at a
// time where a batch of moves failed to flatten) and charts could distort
// their sampling 2.5x: 70.7% each, 326 and 344 vertices.
// The one-chart atlas of a flat, irregular disk: no cut (it is a disk),
// its four sharpest border vertices (the square's corners) on the map's
// corners, and mean value coordinates reproduce linear maps, so the inside
// lands where the plane's own affine map puts it: every edge has the same
// length in the map over its length on the surface, and the stretch is 1.
TEST(Atlas, SquareAtlasOfAFlatSquareIsAnAffineMap)
{
    const int n = 9;
    ControlMesh disk;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> jitter(-0.3f, 0.3f);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const bool inner = i > 0 && j > 0 && i < n - 1 && j < n - 1;
            disk.positions.emplace_back(2.0f * (float(i) + (inner ? jitter(rng) : 0.0f)),
                                        2.0f * (float(j) + (inner ? jitter(rng) : 0.0f)), 0.0f);
        }
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            const uint32_t a = uint32_t(j * n + i), b = a + 1, c = a + uint32_t(n), d = c + 1;
            disk.triangles.insert(disk.triangles.end(), {a, b, d, a, d, c});
        }
    SquareAtlasOptions options;
    options.mapSize = 0;  // the unit square
    ChartAtlasStats stats;
    ASSERT_TRUE(buildSquareAtlas(&disk, options, &stats).isOk());
    EXPECT_TRUE(stats.wholeMap);
    EXPECT_EQ(disk.uvs.size(), disk.positions.size());  // nothing cut
    EXPECT_NEAR(stats.stretch, 1.0, 1e-6);
    EXPECT_NEAR(stats.maxDistortion, 1.0, 1e-6);
    for (size_t f = 0; f < disk.faceCount(); ++f)
        for (int k = 0; k < 3; ++k) {
            const size_t a = 3 * f + size_t(k), b = 3 * f + size_t((k + 1) % 3);
            const double uv = glm::length(glm::dvec2(disk.uvs[disk.uvIndices[a]] - disk.uvs[disk.uvIndices[b]]));
            const double xyz =
                glm::length(glm::dvec3(disk.positions[disk.triangles[a]] - disk.positions[disk.triangles[b]]));
            ASSERT_NEAR(uv / xyz, 1.0 / (2.0 * double(n - 1)), 1e-5) << "face " << f;
        }
    // On a map, the square's sides lie on the border texels' centres.
    ControlMesh placed = disk;
    fitSquareAtlas(&placed.uvs, 64);
    float lo = 1.0f, hi = 0.0f;
    for (const glm::vec2& uv : placed.uvs) {
        lo = std::min({lo, uv.x, uv.y});
        hi = std::max({hi, uv.x, uv.y});
    }
    EXPECT_FLOAT_EQ(lo, 0.5f / 64.0f);
    EXPECT_FLOAT_EQ(hi, 63.5f / 64.0f);
    EXPECT_TRUE(checkUVs(placed, 64).isOk());
}

// A closed genus-0 cage is cut open into one chart over the whole map
// within 1.3x its vertices, fold-free, and the sphere baked through it
// comes back as the chart atlas's does (the cut's seams stay closed: one
// sample per refined vertex).  buildAtlas takes it for the level-1
// icosphere, whose charts split far more than 1.3x its vertices.
TEST(Atlas, SquareAtlasCutsASphereOpen)
{
    for (int subdivisions : {1, 3}) {
        ControlMesh sphere = examples::makeIcosphere(subdivisions);
        sphere.uvs.clear();
        sphere.uvIndices.clear();
        SquareAtlasOptions options;
        options.mapSize = 256;
        ChartAtlasStats stats;
        ASSERT_TRUE(buildSquareAtlas(&sphere, options, &stats).isOk()) << subdivisions;
        EXPECT_LE(double(sphere.uvs.size()), 1.3 * double(sphere.positions.size())) << subdivisions;
        EXPECT_GT(sphere.uvs.size(), sphere.positions.size());  // a sphere must be cut
        EXPECT_GT(stats.texelFill, 0.99);
        EXPECT_LT(stats.stretch, 1.5) << subdivisions;
        EXPECT_TRUE(checkUVs(sphere, 256).isOk()) << subdivisions;
        for (size_t f = 0; f < sphere.faceCount(); ++f) {  // counter-clockwise, as the surface is
            const glm::dvec2 a(sphere.uvs[sphere.uvIndices[3 * f]]), b(sphere.uvs[sphere.uvIndices[3 * f + 1]]),
                c(sphere.uvs[sphere.uvIndices[3 * f + 2]]);
            ASSERT_GT((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x), 0.0) << "face " << f;
        }
    }
    ControlMesh control = examples::makeIcosphere(1);
    ChartAtlasStats stats;
    ASSERT_TRUE(chartAtlas(&control, 256, &stats, true));
    EXPECT_TRUE(stats.wholeMap);
    EXPECT_LE(double(control.uvs.size()), 1.3 * double(control.positions.size()));
    {
        ControlMesh charts = control;  // the same stats then describe the charts alone
        ASSERT_TRUE(chartAtlas(&charts, 256, &stats));
        EXPECT_FALSE(stats.wholeMap);
        EXPECT_EQ(stats.stretch, 0.0);
        EXPECT_GT(stats.charts, 1u);
    }
    expectSphereBakesBack(control);
}

// Only one connected genus-0 manifold opens into one square: a torus (a
// handle), two spheres and a fin on an edge are refused, the mesh left
// as it was; buildAtlas then keeps the chart atlas.
TEST(Atlas, SquareAtlasRefusesWhatCannotOpenIntoADisk)
{
    ControlMesh torus;
    const int around = 12, tube = 8;
    for (int i = 0; i < around; ++i)
        for (int j = 0; j < tube; ++j) {
            const double u = 2.0 * M_PI * i / around, v = 2.0 * M_PI * j / tube;
            torus.positions.emplace_back(float((2.0 + 0.6 * std::cos(v)) * std::cos(u)),
                                         float((2.0 + 0.6 * std::cos(v)) * std::sin(u)), float(0.6 * std::sin(v)));
        }
    for (int i = 0; i < around; ++i)
        for (int j = 0; j < tube; ++j) {
            const uint32_t a = uint32_t(i * tube + j), b = uint32_t(((i + 1) % around) * tube + j),
                           c = uint32_t(((i + 1) % around) * tube + (j + 1) % tube),
                           d = uint32_t(i * tube + (j + 1) % tube);
            torus.triangles.insert(torus.triangles.end(), {a, b, c, a, c, d});
        }
    ControlMesh two = examples::makeIcosphere(1);
    {
        const ControlMesh other = examples::makeIcosphere(1);
        const uint32_t base = uint32_t(two.positions.size());
        for (const glm::vec3& p : other.positions)
            two.positions.push_back(p + glm::vec3(3.0f, 0.0f, 0.0f));
        for (uint32_t v : other.triangles)
            two.triangles.push_back(base + v);
    }
    ControlMesh fin = examples::makeIcosphere(1);
    fin.positions.emplace_back(0.0f, 0.0f, 3.0f);
    fin.triangles.insert(fin.triangles.end(), {fin.triangles[0], fin.triangles[1], uint32_t(fin.positions.size() - 1)});
    for (ControlMesh* mesh : {&torus, &two, &fin}) {
        mesh->uvs.clear();
        mesh->uvIndices.clear();
        const ControlMesh before = *mesh;
        Status s = buildSquareAtlas(mesh, SquareAtlasOptions());
        EXPECT_FALSE(s.isOk());
        EXPECT_TRUE(mesh->uvIndices.empty()) << s.message();
        EXPECT_EQ(mesh->positions, before.positions);
    }
    EXPECT_NE(buildSquareAtlas(&torus, SquareAtlasOptions()).message().find("handles"), std::string::npos);
    AtlasOptions options;
    options.mapSize = 512;
    ChartAtlasStats stats;
    ASSERT_TRUE(buildAtlas(&torus, options, &stats).isOk());
    EXPECT_FALSE(stats.wholeMap);
    EXPECT_GT(stats.charts, 0u);
}

TEST(Atlas, RealCagesFillSeventyPercent)
{
    for (const char* name : {"spot_control_mesh.obj", "penguin_control_mesh.obj"}) {
        STRATA_REQUIRE_DATA(path, name);
        ControlMesh cage;
        ASSERT_TRUE(baker::loadControlMesh(path, &cage).isOk());
        cage.uvs.clear();
        cage.uvIndices.clear();
        ChartAtlasStats stats;
        ASSERT_TRUE(chartAtlas(&cage, 256, &stats)) << name;
        EXPECT_GE(stats.texelFill, 0.70) << name;
        EXPECT_LE(stats.maxDistortion, kChartMaxDistortion) << name;
        std::set<std::pair<uint32_t, uint32_t>> corners;  // a glb vertex per distinct (position, UV)
        for (size_t i = 0; i < cage.triangles.size(); ++i)
            corners.insert({cage.triangles[i], cage.uvIndices[i]});
        EXPECT_LE(double(corners.size()), 1.75 * double(cage.positions.size())) << name;
    }
}

// The atlas a bake lays out for the real cages meets the atlas targets:
// at least 70% of the map's texels inside charts and at most 1.3x as many
// vertices as the cage once split at its seams (their chart atlases split
// 1.7x: one chart over the whole map), fold-free and inside the map.
TEST(Atlas, RealCagesMeetTheAtlasTargets)
{
    for (const char* name : {"spot_control_mesh.obj", "penguin_control_mesh.obj", "hand_lowres.obj"}) {
        STRATA_REQUIRE_DATA(path, name);
        ControlMesh cage;
        ASSERT_TRUE(baker::loadControlMesh(path, &cage).isOk());
        ChartAtlasStats stats;
        ASSERT_TRUE(chartAtlas(&cage, 256, &stats, true)) << name;
        EXPECT_GE(stats.texelFill, 0.70) << name;
        std::set<std::pair<uint32_t, uint32_t>> corners;  // a glb vertex per distinct (position, UV)
        for (size_t i = 0; i < cage.triangles.size(); ++i)
            corners.insert({cage.triangles[i], cage.uvIndices[i]});
        EXPECT_LE(double(corners.size()), 1.3 * double(cage.positions.size())) << name;
    }
}

// RMS distance from points (a capture's vertices) to a mesh (a cage).
static double rmsFromPointsToMesh(const std::vector<glm::vec3>& points, const ControlMesh& mesh)
{
    strata::baker::TriangleIndex index;
    index.build(mesh.positions.data(), mesh.triangles.data(), mesh.faceCount());
    double sum = 0.0;
    for (const glm::vec3& p : points) {
        const double d = index.nearest(glm::dvec3(p));
        sum += d * d;
    }
    return std::sqrt(sum / double(points.size()));
}

// A capture cut along a seam (each vertex on one side of x = 0 duplicated
// for the triangles there, as UV seams come from a scanner or an
// exporter) decimates as the whole surface does: the seam's coincident
// vertices are one, so the cage is closed (no boundary, Euler
// characteristic 2) instead of keeping the seam as a crack.  The capture
// is large enough (81,920 triangles) that meshoptimizer takes it most of
// the way and OpenMesh the last collapses; the cage lies as close to the
// capture as that of the uncut sphere.
TEST(Simplifier, ASeamOfCoincidentVerticesIsNoBoundary)
{
    const ControlMesh sphere = strata::examples::makeHead(6);
    strata::baker::TriangleMesh whole, cut;
    whole.positions = sphere.positions;
    whole.triangles = sphere.triangles;
    cut = whole;
    std::vector<int64_t> copy(whole.positions.size(), -1);
    for (size_t f = 0; f < cut.faceCount(); ++f) {
        const glm::vec3 c = (whole.positions[whole.triangles[3 * f]] + whole.positions[whole.triangles[3 * f + 1]] +
                             whole.positions[whole.triangles[3 * f + 2]]) /
                            3.0f;
        if (c.x <= 0.0f)
            continue;
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = whole.triangles[3 * f + size_t(k)];
            if (copy[v] < 0) {
                copy[v] = int64_t(cut.positions.size());
                cut.positions.push_back(whole.positions[v]);
            }
            cut.triangles[3 * f + size_t(k)] = uint32_t(copy[v]);
        }
    }
    ASSERT_GT(strata::baker::countBoundaryEdges(cut.triangles.data(), cut.faceCount()), 0u);
    auto rmsToCage = [&](const ControlMesh& cage) { return rmsFromPointsToMesh(whole.positions, cage); };
    ControlMesh fromCut, fromWhole;
    ASSERT_TRUE(strata::baker::decimateToControlMesh(cut, 500, &fromCut).isOk());
    ASSERT_TRUE(strata::baker::decimateToControlMesh(whole, 500, &fromWhole).isOk());
    EXPECT_EQ(strata::baker::countBoundaryEdges(fromCut.triangles.data(), fromCut.faceCount()), 0u);
    EXPECT_EQ(fromCut.faceCount(), 500u);
    // Closed and 2-manifold: V - E + F = 2 with E = 3F / 2.
    EXPECT_EQ(int64_t(fromCut.positions.size()) - int64_t(3 * fromCut.faceCount() / 2) + int64_t(fromCut.faceCount()), 2);
    EXPECT_LE(rmsToCage(fromCut), 1.2 * rmsToCage(fromWhole));
}

// An open capture (a scan with holes) keeps its rims in the cage: each
// boundary edge holds the plane through it square to its face.  A sphere
// (radius 1) with its cap above z = 0.8 cut away, a rim of radius 0.6:
// decimated with plain quadrics the rim's chords cut across the hole and
// the cage's faces there lie over no capture at all.  Decimated to 300
// faces, the cage lies no farther from the cut sphere than the whole
// sphere's cage of as many faces per area lies from it.
TEST(Simplifier, AnOpenCapturesRimIsKept)
{
    const ControlMesh sphere = strata::examples::makeIcosphere(5);
    strata::baker::TriangleMesh cut;
    cut.positions = sphere.positions;
    for (size_t f = 0; f < sphere.faceCount(); ++f) {
        bool cap = true;
        for (int k = 0; k < 3; ++k)
            cap = cap && sphere.positions[sphere.triangles[3 * f + size_t(k)]].z > 0.8f;
        if (!cap)
            cut.triangles.insert(cut.triangles.end(), &sphere.triangles[3 * f], &sphere.triangles[3 * f] + 3);
    }
    ASSERT_GT(strata::baker::countBoundaryEdges(cut.triangles.data(), cut.faceCount()), 0u);
    ControlMesh cage;
    ASSERT_TRUE(strata::baker::decimateToControlMesh(cut, 300, &cage).isOk());
    std::set<uint32_t> rim;
    const strata::EdgeGroups edges = strata::groupEdges(cage.triangles.data(), cage.faceCount());
    for (size_t e = 0; e < edges.edgeCount(); ++e)
        if (edges.faceCountOf(e) == 1) {
            const uint32_t c = edges.corners[edges.offsets[e]];
            rim.insert({cage.triangles[c], cage.triangles[c / 3 * 3 + (c % 3 + 1) % 3]});
        }
    auto farthest = [](const ControlMesh& from, const strata::baker::TriangleMesh& to) {
        strata::baker::TriangleIndex index;
        index.build(to.positions.data(), to.triangles.data(), to.faceCount());
        return strata::baker::sampleDistance(
                   strata::baker::areaSamples(from.positions.data(), from.triangles.data(), from.faceCount(), 20000),
                   index, 1, 1.0)
            .max;
    };
    strata::baker::TriangleMesh whole;
    whole.positions = sphere.positions;
    whole.triangles = sphere.triangles;
    ControlMesh wholeCage;  // the cut keeps 90% of the sphere's area
    ASSERT_TRUE(strata::baker::decimateToControlMesh(whole, 333, &wholeCage).isOk());
    EXPECT_LE(farthest(cage, cut), 1.25 * farthest(wholeCage, whole)) << rim.size() << " rim vertices";
}

// A capture with a patch of faces turned against the rest (as some
// exporters write them) decimates to a closed cage, every face the same way
// round as its neighbours.  OpenMesh refuses a face that meets its
// neighbour the wrong way round, so the patch's rim was cut open: even the
// capture itself as its cage had holes.
TEST(Simplifier, AFlippedPatchIsTurnedBack)
{
    const ControlMesh head = strata::examples::makeHead(4);
    strata::baker::TriangleMesh high;
    high.positions = head.positions;
    high.triangles = head.triangles;
    size_t flipped = 0;
    for (size_t f = 0; f < high.faceCount(); ++f)
        if (glm::length(high.positions[high.triangles[3 * f]] - high.positions[0]) < 0.5f) {
            std::swap(high.triangles[3 * f + 1], high.triangles[3 * f + 2]);
            ++flipped;
        }
    ASSERT_GT(flipped, 50u);
    ASSERT_LT(2 * flipped, high.faceCount());
    for (size_t faces : {size_t(400), high.faceCount()}) {
        ControlMesh cage;
        ASSERT_TRUE(strata::baker::decimateToControlMesh(high, faces, &cage).isOk());
        EXPECT_EQ(cage.faceCount(), faces);
        const strata::EdgeGroups edges = strata::groupEdges(cage.triangles.data(), cage.faceCount());
        size_t open = 0, sameWay = 0;
        for (size_t e = 0; e < edges.edgeCount(); ++e) {
            open += edges.faceCountOf(e) != 2;
            if (edges.faceCountOf(e) == 2)
                sameWay += cage.triangles[edges.cornersOf(e)[0]] == cage.triangles[edges.cornersOf(e)[1]];
        }
        EXPECT_EQ(open, 0u) << faces;
        EXPECT_EQ(sameWay, 0u) << faces;
        // Turned as most of the capture was: outward, a positive volume.
        double volume = 0.0;
        for (size_t f = 0; f < cage.faceCount(); ++f)
            volume += double(glm::dot(cage.positions[cage.triangles[3 * f]],
                                      glm::cross(cage.positions[cage.triangles[3 * f + 1]],
                                                 cage.positions[cage.triangles[3 * f + 2]])));
        EXPECT_GT(volume, 0.0) << faces;
    }
}

// Faces OpenMesh cannot join (fins on an edge two faces already share) are
// kept aside and join every cage as they are, their corners kept through
// the collapses; a face repeated on the same corners, either way round, is
// no more surface and is left out.
TEST(Simplifier, FinsAreCountedAndRepeatsAreNot)
{
    const ControlMesh head = strata::examples::makeHead(3);
    strata::baker::TriangleMesh high;
    high.positions = head.positions;
    high.triangles = head.triangles;
    const size_t nf = high.faceCount();
    for (size_t f = 0; f < 20; ++f) {
        const uint32_t a = head.triangles[3 * f * 7], b = head.triangles[3 * f * 7 + 1];
        high.positions.push_back(0.5f * (head.positions[a] + head.positions[b]) * 1.3f);
        high.triangles.insert(high.triangles.end(), {a, b, uint32_t(high.positions.size() - 1)});
    }
    for (size_t f = 0; f < 30; ++f) {
        const uint32_t* t = &head.triangles[3 * (f * 11 + 3)];
        if (f % 2)
            high.triangles.insert(high.triangles.end(), {t[0], t[1], t[2]});
        else
            high.triangles.insert(high.triangles.end(), {t[0], t[2], t[1]});
    }
    strata::baker::Simplifier simplifier(high);
    for (size_t faces : {nf + 20, size_t(300)}) {
        ControlMesh cage;
        ASSERT_TRUE(simplifier.simplify(faces, &cage).isOk());
        EXPECT_EQ(simplifier.refusedFaces(), 20u);
        EXPECT_EQ(cage.faceCount(), faces);
        // Every fin is in the cage, on its corners' places.
        std::set<std::array<float, 9>> faceSet;
        for (size_t f = 0; f < cage.faceCount(); ++f) {
            std::array<float, 9> c;
            for (size_t k = 0; k < 3; ++k)
                for (int i = 0; i < 3; ++i)
                    c[3 * k + size_t(i)] = cage.positions[cage.triangles[3 * f + k]][i];
            faceSet.insert(c);
        }
        for (size_t f = nf; f < nf + 20; ++f) {
            std::array<float, 9> c;
            for (size_t k = 0; k < 3; ++k)
                for (int i = 0; i < 3; ++i)
                    c[3 * k + size_t(i)] = high.positions[high.triangles[3 * f + k]][i];
            EXPECT_EQ(faceSet.count(c), 1u) << "fin " << f - nf << " with " << faces << " faces";
        }
    }
}

// The face-count search's simplifier: a smaller count continues the last
// one's collapses (the same greedy order, with the quadrics accumulated so
// far) and gives the mesh a decimation of the whole capture to that count
// gives, but for collapses of equal cost taken in another order (this
// sphere's relief is symmetric); a larger count starts over and gives the
// same mesh exactly.
// A character of separate pieces (a robot's bolts on its body: six balls of
// radius 0.02, 1,280 triangles each, half sunk into a unit sphere of
// 5,120) decimated to 300 faces: the quadrics see each bolt as a speck of
// error and took it to a tetrahedron (4 faces, its face centres a third
// of its radius from its centre; the bolt's points 0.47-0.64 of its
// radius from it, RMS), which no displacement draws back as a ball.  Every
// piece keeps 12 faces or more, the body gives up the faces, and each
// bolt's cage lies within 0.35 of its radius of it (0.29-0.32 measured).
TEST(Simplifier, ASmallPieceKeepsEnoughFacesToBeDrawnBack)
{
    TriangleMesh high = icosphereMesh(4, 1.0f);
    const TriangleMesh bolt = icosphereMesh(3, 0.02f);
    const glm::vec3 at[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0.6f, 0.8f, 0}, {0, 0.6f, -0.8f}};
    for (const glm::vec3& c : at) {
        const uint32_t first = uint32_t(high.positions.size());
        for (const glm::vec3& p : bolt.positions)
            high.positions.push_back(c + p);
        for (uint32_t v : bolt.triangles)
            high.triangles.push_back(first + v);
    }
    size_t pieces = 0;
    const std::vector<uint32_t> shell = strata::baker::captureShells(high, &pieces);
    ASSERT_EQ(pieces, 7u);
    strata::baker::Simplifier simplifier(high, high.positions);  // a character, in one pose
    ControlMesh cage;
    std::vector<uint32_t> originals;
    ASSERT_TRUE(simplifier.simplify(300, &cage, &originals).isOk());
    EXPECT_EQ(cage.faceCount(), 300u);
    std::vector<size_t> faces(pieces, 0);
    for (size_t f = 0; f < cage.faceCount(); ++f)
        ++faces[shell[originals[cage.triangles[3 * f]]]];
    for (size_t p = 0; p < pieces; ++p)
        EXPECT_GE(faces[p], 12u) << "piece " << p;
    for (size_t b = 0; b < 6; ++b) {
        const size_t first = high.positions.size() - bolt.positions.size() * (6 - b);  // the bolt's first vertex
        std::vector<glm::vec3> points;
        ControlMesh piece;
        piece.positions = cage.positions;
        for (size_t f = 0; f < cage.faceCount(); ++f)
            if (shell[originals[cage.triangles[3 * f]]] == shell[first])
                piece.triangles.insert(piece.triangles.end(), &cage.triangles[3 * f], &cage.triangles[3 * f] + 3);
        for (size_t v = 0; v < bolt.positions.size(); ++v)
            points.push_back(high.positions[first + v]);
        ASSERT_FALSE(piece.triangles.empty()) << "bolt " << b;
        EXPECT_LT(rmsFromPointsToMesh(points, piece), 0.35 * 0.02) << "bolt " << b;
    }
}

// Sixty small boxes (a robot's hands and feet, a 6x6 grid on each side)
// and a large one on a largeGrid x largeGrid grid, each closed and turned
// outwards.
static TriangleMesh boxesCapture(int largeGrid)
{
    TriangleMesh high;
    const auto box = [&](glm::vec3 centre, glm::vec3 half, int n) {
        for (int axis = 0; axis < 3; ++axis)
            for (int side : {-1, 1}) {
                const uint32_t base = uint32_t(high.positions.size());
                const int u = (axis + 1) % 3, v = (axis + 2) % 3;
                for (int i = 0; i <= n; ++i)
                    for (int j = 0; j <= n; ++j) {
                        glm::vec3 p(0.0f);
                        p[axis] = float(side) * half[axis];
                        p[u] = half[u] * (2.0f * float(i) / float(n) - 1.0f);
                        p[v] = half[v] * (2.0f * float(j) / float(n) - 1.0f);
                        high.positions.push_back(centre + p);
                    }
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < n; ++j) {
                        const uint32_t a = base + uint32_t(i * (n + 1) + j), b = a + 1, c = a + uint32_t(n + 1);
                        const uint32_t outwards[6] = {a, c, b, b, c, c + 1}, inwards[6] = {a, b, c, b, c + 1, c};
                        const uint32_t* t = side > 0 ? outwards : inwards;
                        high.triangles.insert(high.triangles.end(), t, t + 6);
                    }
            }
    };
    for (int k = 0; k < 60; ++k)
        box(glm::vec3(0.04f * float(k), 0.0f, 0.0f), glm::vec3(0.012f + 0.0003f * float(k), 0.007f, 0.01f), 6);
    box(glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(0.5f), largeGrid);
    return high;
}

// `high` decimated to each of `targets` in turn (each continuing from the
// last) is closed: no face kept aside, every edge used once each way.
static void expectClosedCages(const TriangleMesh& high, const std::vector<size_t>& targets)
{
    strata::baker::Simplifier simplifier(high, high.positions);
    for (size_t target : targets) {
        SCOPED_TRACE(target);
        ControlMesh cage;
        ASSERT_TRUE(simplifier.simplify(target, &cage).isOk());
        EXPECT_EQ(simplifier.refusedFaces(), 0u);
        EXPECT_EQ(cage.faceCount(), target);
        std::map<std::pair<uint32_t, uint32_t>, int> uses;
        for (size_t f = 0; f < cage.faceCount(); ++f)
            for (int k = 0; k < 3; ++k)
                ++uses[{cage.triangles[3 * f + size_t(k)], cage.triangles[3 * f + size_t(k + 1) % 3]}];
        size_t unmatched = 0;
        for (const auto& e : uses)
            unmatched += e.second != 1 || uses.count({e.first.second, e.first.first}) == 0;
        EXPECT_EQ(unmatched, 0u);
    }
}

// A closed capture gives a closed cage.  Small boxes and a large one on a
// 40x40 grid, 45,120 triangles: meshoptimizer's collapses, which take a
// capture this large most of the way, left slivers along the boxes' edges
// (three faces on an edge), which OpenMesh cannot join, so the cage kept
// them aside and was not closed (an adaptive frame of it then had holes):
// 3 of them and 9 unmatched edges at 1,500 and 800 faces.  Its 20,000-face
// start is past a quarter of the capture, so the whole capture is now
// decimated, and every edge of the cage is matched.
TEST(Simplifier, AClosedCaptureOfSmallBoxesGivesAClosedCage)
{
    const TriangleMesh high = boxesCapture(40);
    ASSERT_EQ(high.faceCount(), 45120u);
    expectClosedCages(high, {1500, 800});
}

// The same with the large box on an 80x80 grid, 102,720 triangles: 72
// faces kept aside and 212 unmatched edges at 1,500 faces.  meshoptimizer
// is now held to 80,000 faces, where it leaves none, rather than the whole
// capture going to OpenMesh.  (Under the sanitizers it repeats the test
// above at twice the size: left out there.)
TEST(Simplifier, ALargerCaptureHoldsMeshoptimizerToMoreFaces)
{
    const TriangleMesh high = boxesCapture(80);
    ASSERT_EQ(high.faceCount(), 102720u);
    expectClosedCages(high, {1500});
}

TEST(Simplifier, ContinuingGivesTheDirectDecimation)
{
    const ControlMesh sphere = strata::examples::makeHead(4);
    strata::baker::TriangleMesh high;
    high.positions = sphere.positions;
    high.triangles = sphere.triangles;
    auto rmsToCage = [&](const ControlMesh& cage) { return rmsFromPointsToMesh(high.positions, cage); };
    strata::baker::Simplifier simplifier(high);
    size_t last = ~size_t(0);
    for (size_t faces : {1500u, 900u, 500u, 1200u, 250u}) {
        SCOPED_TRACE(faces);
        ControlMesh continued, direct;
        ASSERT_TRUE(simplifier.simplify(faces, &continued).isOk());
        ASSERT_TRUE(strata::baker::decimateToControlMesh(high, faces, &direct).isOk());
        EXPECT_EQ(direct.faceCount(), faces);
        EXPECT_EQ(continued.faceCount(), direct.faceCount());
        EXPECT_EQ(continued.positions.size(), direct.positions.size());
        if (faces > last) {  // started over
            EXPECT_EQ(continued.triangles, direct.triangles);
            EXPECT_EQ(continued.positions, direct.positions);
        } else {
            // Half-edge collapses keep capture vertices: most are the same ones.
            std::set<std::array<float, 3>> kept;
            for (const glm::vec3& p : direct.positions)
                kept.insert({p.x, p.y, p.z});
            size_t common = 0;
            for (const glm::vec3& p : continued.positions)
                common += kept.count({p.x, p.y, p.z});
            EXPECT_GE(double(common), 0.85 * double(direct.positions.size()));
            EXPECT_LE(rmsToCage(continued), 1.1 * rmsToCage(direct));
        }
        last = faces;
    }
}
