// Control-mesh and displacement fitting (Displaced Subdivision Surfaces 4.2),
// against closed forms: an icosahedron's base surfaces and the unit sphere,
// a flat square's refined vertices and a sine.
#include "procedural.h"
#include "strata/baker/bake_rig.h"
#include "strata/baker/distance.h"
#include "strata/baker/fit.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "test_util.h"

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>

using namespace strata;
using namespace strata::baker;

namespace {

TriangleMesh sphereCapture(int subdivisions)
{
    const ControlMesh m = examples::makeIcosphere(subdivisions);
    return TriangleMesh{m.positions, m.triangles, {}};
}

// RMS of |radius - 1| over a scheme's refined vertices at `level`.
double radialRms(const ControlMesh& cage, Scheme scheme, int level)
{
    std::unique_ptr<Plan> plan;
    EXPECT_TRUE(Plan::create(&plan, cage, scheme, level).isOk());
    std::vector<glm::vec3> normals(cage.positions.size()), x(plan->refinedVertexCount());
    computeControlNormals(normals.data(), cage.positions.data(), normals.size(), cage.triangles.data(),
                          cage.faceCount());
    plan->clearDisplacement();
    EXPECT_TRUE(plan->evaluate(x.data(), nullptr, 0, x.size(), cage.positions.data(), normals.data(), normals.size())
                    .isOk());
    double sum = 0.0;
    for (const glm::vec3& p : x)
        sum += (glm::length(glm::dvec3(p)) - 1.0) * (glm::length(glm::dvec3(p)) - 1.0);
    return std::sqrt(sum / double(x.size()));
}

// The unit sphere as a dense capture, indexed.
struct SphereCapture {
    TriangleMesh mesh = sphereCapture(5);
    TriangleIndex index;
    SphereCapture() { index.build(mesh.positions.data(), mesh.triangles.data(), mesh.faceCount()); }
};

// A once-split icosahedron inscribed in the unit sphere, fitted to it for
// `scheme`; the radial RMS of its base surface before and after.
struct FittedCage {
    ControlMesh cage = examples::makeIcosphere(1);
    double before = 0.0, after = 0.0;
    FitStats stats;
};

FittedCage fitIcosahedronToSphere(Scheme scheme)
{
    const SphereCapture sphere;
    FittedCage f;
    f.before = radialRms(f.cage, scheme, 3);
    FitOptions options;
    options.scheme = scheme;
    options.level = 3;
    EXPECT_TRUE(fitControlMesh(&f.cage, sphere.mesh, sphere.index, options, &f.stats).isOk());
    f.after = radialRms(f.cage, scheme, 3);
    return f;
}

// A default bake request of a real pair (shared data) into a fresh folder.
BakeRequest pairRequest(const std::string& high, const std::string& control, const std::string& folder,
                        const std::string& name)
{
    BakeRequest request;
    request.high = high;
    request.control = control;
    request.output = strata::test::tempDir(folder) + "/" + name;
    return request;
}

}  // namespace

// The Loop limit surface of a once-split icosahedron inscribed in the unit
// sphere lies inside it; fitted, the cage grows (the twelve valence-5
// vertices alike, the thirty others alike, by symmetry) until the limit
// surface straddles the sphere.
TEST(Fit, IcosahedronLimitSurfaceFitsTheSphere)
{
    const FittedCage f = fitIcosahedronToSphere(Scheme::Smooth);
    const ControlMesh& cage = f.cage;
    EXPECT_GT(f.before, 0.05);  // the limit surface sinks ~9% (RMS) inside the sphere
    EXPECT_LT(f.after, 0.05 * f.before);
    EXPECT_LT(f.stats.rmsAfter, 0.05 * f.stats.rmsBefore);
    EXPECT_GT(f.stats.maxMove, 0.05);
    // makeIcosphere lists the icosahedron's twelve vertices first.
    const float r5 = glm::length(cage.positions[0]), r6 = glm::length(cage.positions[12]);
    EXPECT_GT(r5, 1.05f);
    EXPECT_GT(r6, r5);  // the valence-6 vertices' masks pull less towards the inside
    for (size_t v = 0; v < cage.positions.size(); ++v)
        EXPECT_NEAR(glm::length(cage.positions[v]), v < 12 ? r5 : r6, 1e-4f) << v;
}

// The flat icosahedron's chords cut inside the sphere; the least-squares
// cage pushes its vertices out so that the faces straddle it.
TEST(Fit, IcosahedronFacesStraddleTheSphereWhenFittedLinearly)
{
    const FittedCage f = fitIcosahedronToSphere(Scheme::Linear);
    EXPECT_LT(f.after, 0.6 * f.before);
    for (const glm::vec3& p : f.cage.positions)
        EXPECT_GT(glm::length(p), 1.0f);
}

// Fitting is not registration: a cage far from the capture stays where it is.
TEST(Fit, FarCageIsLeftAlone)
{
    const TriangleMesh sphere = sphereCapture(3);
    TriangleIndex index;
    index.build(sphere.positions.data(), sphere.triangles.data(), sphere.faceCount());
    ControlMesh cage = examples::makeIcosphere(1);
    for (glm::vec3& p : cage.positions)
        p.x += 50.0f;
    const ControlMesh original = cage;
    FitStats stats;
    ASSERT_TRUE(fitControlMesh(&cage, sphere, index, FitOptions(), &stats).isOk());
    EXPECT_EQ(cage.positions, original.positions);
    EXPECT_EQ(stats.maxMove, 0.0);
    EXPECT_EQ(stats.rmsAfter, stats.rmsBefore);
}

// A plane under z = a sin(2 pi x) sin(2 pi y): the fitted per-vertex values
// of a flat square's level-4 vertices follow the sine, and the displaced
// mesh lies at least as close to the capture as the sine sampled exactly
// at the vertices (the fit also pulls the chords between samples).
TEST(Fit, VertexDisplacementsFollowASine)
{
    const float a = 0.05f;
    auto height = [&](float x, float y) {
        return a * std::sin(2.0f * float(M_PI) * x) * std::sin(2.0f * float(M_PI) * y);
    };
    TriangleMesh capture;
    const int n = 160;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const float x = float(i) / n, y = float(j) / n;
            capture.positions.push_back({x, y, height(x, y)});
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t v = uint32_t(j * (n + 1) + i);
            capture.triangles.insert(capture.triangles.end(), {v, v + 1, v + uint32_t(n) + 2, v, v + uint32_t(n) + 2,
                                                               v + uint32_t(n) + 1});
        }
    TriangleIndex index;
    index.build(capture.positions.data(), capture.triangles.data(), capture.faceCount());
    const ControlMesh square = examples::makeSquare();
    const int level = 4;
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, square, Scheme::Linear, level).isOk());
    const size_t nr = plan->refinedVertexCount();
    std::vector<glm::vec3> normals(square.positions.size()), base(nr);
    computeControlNormals(normals.data(), square.positions.data(), normals.size(), square.triangles.data(),
                          square.faceCount());
    plan->clearDisplacement();
    ASSERT_TRUE(plan->evaluate(base.data(), nullptr, 0, nr, square.positions.data(), normals.data(), normals.size())
                    .isOk());
    std::vector<float> sampled(nr), fitted(nr, 0.0f);
    for (size_t v = 0; v < nr; ++v)
        sampled[v] = height(base[v].x, base[v].y);
    ASSERT_TRUE(fitVertexDisplacements(&fitted, square, Scheme::Linear, level, capture, index, 4, 1).isOk());
    // Distance of the displaced refined mesh to the capture, both ways.
    auto rms = [&](const std::vector<float>& d) {
        std::vector<glm::vec3> y(nr);
        for (size_t v = 0; v < nr; ++v)
            y[v] = base[v] + glm::vec3(0.0f, 0.0f, d[v]);
        TriangleIndex own;
        own.build(y.data(), plan->refinedTriangles().data(), plan->refinedFaceCount());
        const double forward =
            sampleDistance(surfaceSamples(y.data(), nr, plan->refinedTriangles().data(), plan->refinedFaceCount()),
                           index, 1)
                .rms;
        const double backward = sampleDistance(surfaceSamples(capture.positions.data(), capture.positions.size(),
                                                              capture.triangles.data(), capture.faceCount()),
                                               own, 1)
                                    .rms;
        return std::max(forward, backward);
    };
    double maxGap = 0.0;
    for (size_t v = 0; v < nr; ++v)
        maxGap = std::max(maxGap, double(std::fabs(fitted[v] - sampled[v])));
    EXPECT_LT(maxGap, 0.15 * a);
    EXPECT_LE(rms(fitted), rms(sampled));
    EXPECT_LT(rms(fitted), 0.02 * a);
    // The same for any thread count.
    std::vector<float> twoThreads(nr, 0.0f);
    ASSERT_TRUE(fitVertexDisplacements(&twoThreads, square, Scheme::Linear, level, capture, index, 4, 2).isOk());
    EXPECT_EQ(twoThreads, fitted);
}

// On a real pair the fitted cage takes the default bake below the error of
// the cage as drawn (spot: the drawn cage's limit surface misses the ears
// and horns), and the summary and report say what moved.
TEST(Fit, SpotIsCloserWhenFitted)
{
    STRATA_REQUIRE_DATA(high, "spot_triangulated.obj");
    STRATA_REQUIRE_DATA(control, "spot_control_mesh.obj");
    BakeRequest request = pairRequest(high, control, "fit_spot", "fitted.glb");
    BakeResult fitted, drawn;
    ASSERT_TRUE(bakeRig(request, &fitted).isOk());
    request.fitCage = false;
    request.output.replace(request.output.rfind('/') + 1, std::string::npos, "drawn.glb");
    ASSERT_TRUE(bakeRig(request, &drawn).isOk());
    EXPECT_GT(fitted.rms, 0.0);
    EXPECT_LT(fitted.rms, drawn.rms);
    // The base surface itself (the Loop limit spot's bake measures on)
    // comes more than twice as close.
    const nlohmann::json report = nlohmann::json::parse(fitted.report);
    ASSERT_TRUE(report.contains("fit")) << fitted.report;
    EXPECT_TRUE(report["fit"]["moved"].get<bool>());
    EXPECT_LT(report["fit"]["baseRmsAfter"].get<double>(), 0.5 * report["fit"]["baseRmsBefore"].get<double>());
    EXPECT_NE(fitted.summary.find("cage vertices moved by up to"), std::string::npos) << fitted.summary;
    EXPECT_EQ(drawn.summary.find("cage vertices moved"), std::string::npos) << drawn.summary;
}

// The bar on the hand: the default bake reconstructs to 0.02% of
// the diagonal at its recommended level.
TEST(Fit, HandDefaultBakeReachesTheBar)
{
    STRATA_REQUIRE_DATA(high, "hand_closed.obj");
    STRATA_REQUIRE_DATA(control, "hand_lowres.obj");
    const BakeRequest request = pairRequest(high, control, "fit_hand", "hand.glb");
    BakeResult result;
    ASSERT_TRUE(bakeRig(request, &result).isOk());
    EXPECT_GT(result.rms, 0.0);
    EXPECT_LE(result.rms, 2e-4) << result.summary;
}

// A cage file whose map is asked for as an image keeps its vertices: a
// pipeline applies that map to the cage it has.
TEST(Fit, MapImagesKeepTheCageAsDrawn)
{
    STRATA_REQUIRE_DATA(high, "spot_triangulated.obj");
    STRATA_REQUIRE_DATA(control, "spot_control_mesh.obj");
    BakeRequest request = pairRequest(high, control, "fit_exr", "spot.glb");
    request.exr = true;
    request.options.size = test::kFixedMapSize;  // the size search is not what this asks about
    BakeResult result;
    ASSERT_TRUE(bakeRig(request, &result).isOk());
    EXPECT_NE(result.summary.find("cage kept as drawn"), std::string::npos) << result.summary;
    EXPECT_FALSE(nlohmann::json::parse(result.report).contains("fit"));
}
