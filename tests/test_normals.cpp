// Control vertex normals (paper eq. 1's n_j): closed-form cases.
#include "procedural.h"
#include "strata/frame.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "strata/plane.h"
#include "test_util.h"

#include <algorithm>
#include <cstring>
#include <memory>
#include <random>
#include <type_traits>

using namespace strata;

TEST(ControlNormals, IcosphereNormalsAreRadial)
{
    for (int s = 0; s <= 2; ++s) {
        const ControlMesh m = examples::makeIcosphere(s);
        std::vector<glm::vec3> n(m.positions.size());
        computeControlNormals(n.data(), m.positions.data(), m.positions.size(), m.triangles.data(), m.faceCount());
        for (size_t v = 0; v < n.size(); ++v) {
            EXPECT_NEAR(glm::length(n[v]), 1.0f, 1e-6f);
            // By symmetry of the regular icosahedron the normal is exactly radial;
            // subdivided spheres are near-radial.
            EXPECT_GT(glm::dot(n[v], glm::normalize(m.positions[v])), s == 0 ? 1.0f - 1e-6f : 0.999f) << v;
        }
    }
}

TEST(ControlNormals, AngleWeightingIgnoresTessellationDensity)
{
    // A roof ridge at the origin: the left plane z = x holds one triangle,
    // the right plane z = -x two larger triangles spanning the same angle at
    // the origin.  Angle weighting gives the exact bisector (0, 0, 1);
    // counting faces or weighting by area would tilt it to the right.
    ControlMesh m;
    m.positions = {{0, 0, 0}, {-1, 1, -1}, {-1, -1, -1}, {2, -2, -2}, {2, 0, -2}, {2, 2, -2}};
    m.triangles = {0, 1, 2, 0, 3, 4, 0, 4, 5};
    std::vector<glm::vec3> n(m.positions.size());
    computeControlNormals(n.data(), m.positions.data(), n.size(), m.triangles.data(), m.faceCount());
    EXPECT_NEAR(n[0].x, 0.0f, 1e-6f);
    EXPECT_NEAR(n[0].y, 0.0f, 1e-6f);
    EXPECT_NEAR(n[0].z, 1.0f, 1e-6f);
    // A vertex inside one plane takes that plane's normal.
    EXPECT_NEAR(glm::dot(n[4], glm::normalize(glm::vec3(1, 0, 1))), 1.0f, 1e-6f);
}

// The vectorised corner angles against atan2, in float and in double
// precision, on random triangles of every shape (needles, obtuse, tiny) and
// more than one block of faces.
TEST(ControlNormals, VectorisedAnglesMatchAtan2)
{
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
    ControlMesh mesh;
    const size_t vertices = 400, faces = 1100;
    for (size_t v = 0; v < vertices; ++v)
        mesh.positions.push_back(glm::vec3(uni(rng), uni(rng), uni(rng)) * (v % 7 == 0 ? 1e-3f : 1.0f));
    for (size_t f = 0; f < faces; ++f) {
        const uint32_t a = uint32_t(rng() % vertices), b = uint32_t((a + 1 + rng() % (vertices - 2)) % vertices);
        uint32_t c = uint32_t(rng() % vertices);
        while (c == a || c == b)
            c = uint32_t(rng() % vertices);
        mesh.triangles.insert(mesh.triangles.end(), {a, b, c});
    }
    std::vector<glm::dvec3> ref(vertices, glm::dvec3(0.0));
    for (size_t f = 0; f < faces; ++f) {
        const uint32_t* t = &mesh.triangles[3 * f];
        for (int k = 0; k < 3; ++k) {
            const glm::dvec3 p = mesh.positions[t[k]], q = mesh.positions[t[(k + 1) % 3]],
                             r = mesh.positions[t[(k + 2) % 3]];
            const glm::dvec3 n = glm::cross(glm::dvec3(mesh.positions[t[1]]) - glm::dvec3(mesh.positions[t[0]]),
                                            glm::dvec3(mesh.positions[t[2]]) - glm::dvec3(mesh.positions[t[0]]));
            const double angle = std::atan2(glm::length(glm::cross(q - p, r - p)), glm::dot(q - p, r - p));
            ref[t[k]] += glm::normalize(n) * angle;
        }
    }
    std::vector<glm::vec3> normals(vertices);
    computeControlNormals(normals.data(), mesh.positions.data(), vertices, mesh.triangles.data(), faces);
    std::vector<glm::vec3> old(vertices, glm::vec3(0.0f));
    for (size_t f = 0; f < faces; ++f) {
        const uint32_t* t = &mesh.triangles[3 * f];
        const glm::vec3 p0 = mesh.positions[t[0]], p1 = mesh.positions[t[1]], p2 = mesh.positions[t[2]];
        const glm::vec3 e01 = p1 - p0, e12 = p2 - p1, e20 = p0 - p2;
        const glm::vec3 n = glm::cross(e01, -e20);
        const float len = glm::length(n);
        const glm::vec3 unit = n / len;
        old[t[0]] += unit * std::atan2(len, glm::dot(e01, -e20));
        old[t[1]] += unit * std::atan2(len, glm::dot(e12, -e01));
        old[t[2]] += unit * std::atan2(len, glm::dot(e20, -e12));
    }
    // Against double precision: as close as float atan2 gets (the mesh's
    // conditioning, not the angles, sets that).  Against float atan2: equal
    // to a few ulps.
    double worstNew = 0.0, worstOld = 0.0, worstDiff = 0.0;
    for (size_t v = 0; v < vertices; ++v) {
        if (glm::length(ref[v]) < 1e-3)
            continue;  // opposite faces cancel: the direction is ill-conditioned
        worstNew = std::max(worstNew, glm::length(glm::dvec3(normals[v]) - glm::normalize(ref[v])));
        worstOld = std::max(worstOld, glm::length(glm::dvec3(glm::normalize(old[v])) - glm::normalize(ref[v])));
        worstDiff = std::max(worstDiff, double(glm::length(normals[v] - glm::normalize(old[v]))));
    }
    EXPECT_LT(worstNew, 1.05 * worstOld + 1e-6);
    EXPECT_LT(worstDiff, 2e-6);
}

TEST(ControlNormals, DegenerateTrianglesContributeNothing)
{
    ControlMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {5, 5, 5}};
    // A proper triangle, plus a zero-area one (collinear 0,1,3).
    m.triangles = {0, 1, 2, 0, 1, 3};
    std::vector<glm::vec3> n(5);
    computeControlNormals(n.data(), m.positions.data(), 5, m.triangles.data(), 2);
    EXPECT_NEAR(n[0].z, 1.0f, 1e-6f);
    EXPECT_NEAR(n[1].z, 1.0f, 1e-6f);
    // Vertex 3 only touches the degenerate face; vertex 4 is isolated.
    EXPECT_EQ(n[3], glm::vec3(0.0f));
    EXPECT_EQ(n[4], glm::vec3(0.0f));
}

// A render-ready frame, per control face (tiles): the normals of
// Plan::computeShadingNormals up to the order of the additions; positions
// bit-identical to Plan::evaluate in the linear scheme and to rounding in the
// smooth one (dense per-tile stencils); everything bit-identical for 1, 2 and
// 3 threads, and in tile order the same values permuted.  On a sphere the normals of the bare refined
// (flat, linear) mesh point outwards to within the facets' angle.
TEST(ShadingNormals, FrameEvaluatorMatchesTheScatterForAnyThreadCount)
{
    ControlMesh mesh = examples::makeIcosphere(2);
    const size_t isolated = mesh.positions.size();  // an unreferenced control vertex refines to itself
    mesh.positions.push_back(glm::vec3(5.0f));
    std::vector<glm::vec3> control(mesh.positions.size());
    computeControlNormals(control.data(), mesh.positions.data(), control.size(), mesh.triangles.data(),
                          mesh.faceCount());
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        for (int level : {0, 1, 3, 4}) {
            std::unique_ptr<Plan> plan;
            ASSERT_TRUE(Plan::create(&plan, mesh, scheme, level).isOk());
            const size_t n = plan->refinedVertexCount();
            std::vector<float> d(n);
            for (size_t v = 0; v < n; ++v)
                d[v] = 0.01f * std::sin(float(v));
            std::vector<glm::vec3> ref(n), refNormals(n), first(n), firstPositions(n);
            ASSERT_TRUE(plan->evaluate(ref.data(), nullptr, 0, n, d.data(), mesh.positions.data(), control.data(),
                                       control.size()).isOk());
            plan->computeShadingNormals(refNormals.data(), ref.data());
            FrameEvaluator frame(*plan);
            for (int threads : {1, 2, 3}) {
                std::vector<glm::vec3> q(n), nq(n);
                ASSERT_TRUE(frame.evaluate(q.data(), nq.data(), d.data(), mesh.positions.data(), control.data(),
                                           control.size(), threads).isOk());
                EXPECT_EQ(frame.tiled(), level >= (scheme == Scheme::Linear ? 3 : 1));
                if (scheme == Scheme::Linear || !frame.tiled()) {
                    EXPECT_EQ(0, std::memcmp(q.data(), ref.data(), n * sizeof(glm::vec3))) << threads;
                } else {  // the same stencils, summed per tile in another order
                    for (size_t v = 0; v < n; ++v)
                        ASSERT_LT(glm::length(q[v] - ref[v]), 1e-5f) << v << " level " << level;
                }
                for (size_t v = 0; v < n; ++v)
                    ASSERT_LT(glm::length(nq[v] - refNormals[v]), 1e-4f) << v << " level " << level;
                if (!frame.tiled()) {
                    EXPECT_EQ(0, std::memcmp(nq.data(), refNormals.data(), n * sizeof(glm::vec3))) << threads;
                }
                if (threads == 1) {
                    first = nq;
                    firstPositions = q;
                }
                EXPECT_EQ(0, std::memcmp(nq.data(), first.data(), n * sizeof(glm::vec3))) << threads;
                EXPECT_EQ(0, std::memcmp(q.data(), firstPositions.data(), n * sizeof(glm::vec3))) << threads;
                EXPECT_EQ(nq[isolated], glm::vec3(0.0f));  // the unreferenced vertex has no faces
            }
            // The tile layout: the same vertices in another order, with the
            // triangles and the order to match.
            FrameEvaluator tiles(*plan, FrameLayout::Tiles);
            EXPECT_EQ(tiles.layout(), frame.tiled() ? FrameLayout::Tiles : FrameLayout::Plan);
            const std::vector<uint32_t> order = tiles.vertexOrder();
            const std::vector<uint32_t> triangles = tiles.triangles();
            ASSERT_EQ(order.size(), n);
            ASSERT_EQ(triangles.size(), plan->refinedTriangles().size());
            std::vector<uint8_t> hit(n, 0);
            for (uint32_t v : order)
                hit[v]++;
            EXPECT_EQ(std::count(hit.begin(), hit.end(), uint8_t(1)), std::ptrdiff_t(n));  // a permutation
            for (size_t i = 0; i < triangles.size(); ++i)
                ASSERT_EQ(order[triangles[i]], plan->refinedTriangles()[i]);
            for (int threads : {1, 2}) {
                std::vector<glm::vec3> q(n), nq(n), qOnly(n);
                ASSERT_TRUE(tiles.evaluate(q.data(), nq.data(), d.data(), mesh.positions.data(), control.data(),
                                           control.size(), threads).isOk());
                ASSERT_TRUE(tiles.evaluate(qOnly.data(), nullptr, d.data(), mesh.positions.data(), control.data(),
                                           control.size(), threads).isOk());
                for (size_t o = 0; o < n; ++o) {
                    ASSERT_EQ(q[o], firstPositions[order[o]]) << o;
                    ASSERT_EQ(qOnly[o], firstPositions[order[o]]) << o;
                    ASSERT_EQ(nq[o], first[order[o]]) << o;
                }
            }
        }
    }
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, mesh, Scheme::Linear, 4).isOk());
    FrameEvaluator frame(*plan);
    const size_t n = plan->refinedVertexCount();
    std::vector<float> zero(n, 0.0f);
    std::vector<glm::vec3> q(n), nq(n);
    ASSERT_TRUE(frame.evaluate(q.data(), nq.data(), zero.data(), mesh.positions.data(), control.data(),
                               control.size(), 2).isOk());
    for (size_t v = 0; v + 1 < n; ++v) {
        if (glm::length(q[v]) < 2.0f) {
            ASSERT_GT(glm::dot(nq[v], glm::normalize(q[v])), 0.98f) << v;  // the flat cage: within its facets' angle
        }
    }
    EXPECT_FALSE(frame.evaluate(q.data(), nq.data(), zero.data(), mesh.positions.data(), control.data(),
                                control.size() - 1, 2).isOk());
}

namespace {

// Vertex v's fans from buildVertexFans as lists of ring vertices, with a
// closed fan's first vertex repeated at its end.
std::vector<std::vector<uint32_t>> fansOf(const std::vector<uint32_t>& offsets, const std::vector<uint32_t>& entries,
                                          uint32_t v)
{
    std::vector<std::vector<uint32_t>> fans;
    for (uint32_t k = offsets[v]; k < offsets[v + 1]; ++k) {
        const uint32_t e = entries[k];
        if (e & kFanStart)
            fans.emplace_back();
        EXPECT_FALSE(fans.empty()) << "an entry before any fan start";
        if (fans.empty())
            break;
        fans.back().push_back(e & kFanIndexMask);
        if (e & kFanClose)
            fans.back().push_back(fans.back().front());
    }
    return fans;
}

}  // namespace

TEST(VertexFans, ClosedRingsOpenFansAndPinchedVertices)
{
    // The icosahedron: every vertex one closed ring of its five neighbours,
    // counter-clockwise (each step's face is an input face, so the ring
    // turns the way the faces do).
    const ControlMesh ico = examples::makeIcosphere(0);
    std::vector<uint32_t> offsets, entries;
    buildVertexFans(&offsets, &entries, ico.triangles.data(), ico.faceCount(), ico.positions.size());
    EXPECT_EQ(entries.size(), 60u);  // one entry per face corner, the closing face free
    for (uint32_t v = 0; v < ico.positions.size(); ++v) {
        const auto fans = fansOf(offsets, entries, v);
        ASSERT_EQ(fans.size(), 1u) << v;
        ASSERT_EQ(fans[0].size(), 6u) << v;
        for (size_t s = 0; s + 1 < fans[0].size(); ++s) {
            bool isFace = false;
            for (size_t f = 0; f < ico.faceCount(); ++f)
                for (int k = 0; k < 3; ++k)
                    isFace |= ico.triangles[3 * f + size_t(k)] == v &&
                              ico.triangles[3 * f + size_t((k + 1) % 3)] == fans[0][s] &&
                              ico.triangles[3 * f + size_t((k + 2) % 3)] == fans[0][s + 1];
            EXPECT_TRUE(isFace) << v << " step " << s;
        }
    }
    // Two fans pinched at vertex 0 (a bow tie), the second of two faces, an
    // open strip; a face with two corners at vertex 0 (no area normal there)
    // and one whose other two corners coincide are left out.
    const std::vector<uint32_t> tris = {0, 1, 2, 0, 3, 4, 0, 2, 5, 0, 0, 6, 0, 6, 6};
    buildVertexFans(&offsets, &entries, tris.data(), tris.size() / 3, 7);
    const auto fans = fansOf(offsets, entries, 0);
    ASSERT_EQ(fans.size(), 2u);
    EXPECT_EQ(fans[0], (std::vector<uint32_t>{1, 2, 5}));
    EXPECT_EQ(fans[1], (std::vector<uint32_t>{3, 4}));
    EXPECT_EQ(fansOf(offsets, entries, 2), (std::vector<std::vector<uint32_t>>{{5, 0, 1}}));
    EXPECT_EQ(offsets[7] - offsets[6], 0u);  // vertex 6 is only in the two faces without area at it
}

// A vertex's steps are searched in place when few and through sorted lists
// when many (kFewSteps, 16): wheels of 5 .. 40 faces around vertex 0, given
// in a scrambled order, closed and with one face taken out, and two wheels
// pinched at vertex 0, give the ring in turn either way.
TEST(VertexFans, WheelsOfFewAndManyFaces)
{
    for (uint32_t k : {5u, 16u, 17u, 40u}) {
        for (bool open : {false, true}) {
            std::vector<uint32_t> tris;
            for (uint32_t i = 0; i < k; ++i) {
                const uint32_t s = (7 * i + 3) % k;  // scrambled (7 and k share no factor)
                if (open && s == k - 1)
                    continue;  // the face from ring vertex k to ring vertex 1
                tris.insert(tris.end(), {0, 1 + s, 1 + (s + 1) % k});
            }
            // A second wheel of k faces pinched to the first at vertex 0.
            for (uint32_t i = 0; i < k; ++i)
                tris.insert(tris.end(), {0, 1 + k + i, 1 + k + (i + 1) % k});
            std::vector<uint32_t> offsets, entries;
            buildVertexFans(&offsets, &entries, tris.data(), tris.size() / 3, 2 * k + 1);
            const auto fans = fansOf(offsets, entries, 0);
            ASSERT_EQ(fans.size(), 2u) << k;
            std::vector<uint32_t> first, second;
            for (uint32_t i = 0; i <= k; ++i) {
                if (!open || i < k)
                    first.push_back(1 + i % k);
                second.push_back(1 + k + i % k);
            }
            // The open fan starts at its border and comes first; a closed
            // ring starts at its first step in face order.
            if (!open) {
                std::rotate(first.begin(), first.begin() + 3, first.end() - 1);
                first.back() = first.front();
            }
            EXPECT_EQ(fans[0], first) << k << (open ? " open" : " closed");
            EXPECT_EQ(fans[1], second) << k;
        }
    }
}

TEST(VertexFans, FanNormalsEqualTheAreaWeightedScatter)
{
    // A displaced refined sphere with an open cut and a pinched vertex: the
    // GPU pass's CPU mirror against Plan::computeShadingNormals.
    ControlMesh mesh = examples::makeIcosphere(2);
    mesh.triangles.resize(mesh.triangles.size() - 3 * 6);  // a hole: open fans along its border
    std::vector<glm::vec3> control(mesh.positions.size());
    computeControlNormals(control.data(), mesh.positions.data(), control.size(), mesh.triangles.data(),
                          mesh.faceCount());
    for (int level : {0, 2, 3}) {
        std::unique_ptr<Plan> plan;
        ASSERT_TRUE(Plan::create(&plan, mesh, Scheme::Linear, level).isOk());
        const size_t n = plan->refinedVertexCount();
        std::vector<float> d(n);
        for (size_t v = 0; v < n; ++v)
            d[v] = 0.02f * std::sin(3.0f * float(v));
        std::vector<glm::vec3> p(n), ref(n), fan(n);
        ASSERT_TRUE(plan->evaluate(p.data(), nullptr, 0, n, d.data(), mesh.positions.data(), control.data(),
                                   control.size()).isOk());
        plan->computeShadingNormals(ref.data(), p.data());
        std::vector<uint32_t> offsets, entries;
        const std::vector<uint32_t>& tris = plan->refinedTriangles();
        buildVertexFans(&offsets, &entries, tris.data(), tris.size() / 3, n);
        // One entry per face corner, plus one where a fan stays open.
        size_t starts = 0, closes = 0;
        for (uint32_t e : entries) {
            starts += (e & kFanStart) != 0;
            closes += (e & kFanClose) != 0;
        }
        EXPECT_EQ(entries.size(), tris.size() + starts - closes);
        computeFanNormals(fan.data(), p.data(), n, offsets.data(), entries.data());
        size_t open = 0;
        for (size_t v = 0; v < n; ++v) {
            ASSERT_LT(glm::length(fan[v] - ref[v]), 1e-5f) << v << " level " << level;
            open += offsets[v + 1] > offsets[v] && !(entries[offsets[v + 1] - 1] & kFanClose);
        }
        EXPECT_GT(open, 0u) << "the hole's border has open fans";
    }
}

// Smooth tiles share their weight matrix where their patches are alike: an
// icosphere has twelve irregular vertices, and its other faces' limit
// patches are one box spline.  Without sharing, the matrices of its 1,280
// tiles at level 4 alone (12 points each, three rows of 160 padded slots)
// would take 29.5 MB; the frame keeps under a quarter of that, and its
// frames still match the plan's per-vertex stencils.
TEST(ShadingNormals, SmoothTilesShareTheirWeights)
{
    const ControlMesh mesh = examples::makeIcosphere(3);
    std::vector<glm::vec3> control(mesh.positions.size());
    computeControlNormals(control.data(), mesh.positions.data(), control.size(), mesh.triangles.data(),
                          mesh.faceCount());
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, mesh, Scheme::Smooth, 4).isOk());
    const size_t n = plan->refinedVertexCount();
    std::vector<glm::vec3> ref(n), q(n), nq(n);
    ASSERT_TRUE(plan->evaluate(ref.data(), nullptr, 0, n, mesh.positions.data(), nullptr, control.size()).isOk());
    FrameEvaluator frame(*plan);
    ASSERT_TRUE(frame.evaluate(q.data(), nq.data(), nullptr, mesh.positions.data(), control.data(), control.size(), 1)
                    .isOk());
    ASSERT_TRUE(frame.tiled());
    const double unshared = 1280.0 * 3 * 160 * 12 * 4;
    EXPECT_LT(double(frame.bytes()), 0.25 * unshared);
    for (size_t v = 0; v < n; ++v)
        ASSERT_LT(glm::length(q[v] - ref[v]), 1e-5f) << v;
}

// strata/plane.h, the one edge function: twice the signed area, the sign
// of the turn, exact antisymmetry, and the arguments' own scalar type.
TEST(Plane, OrientationIsTwiceTheSignedArea)
{
    const glm::dvec2 a(0.0, 0.0), b(4.0, 0.0), c(0.0, 3.0);
    EXPECT_EQ(strata::orient2(a, b, c), 12.0);   // the 3-4-5 right triangle: area 6, counter-clockwise
    EXPECT_EQ(strata::orient2(a, c, b), -12.0);  // clockwise
    EXPECT_EQ(strata::orient2(a, b, glm::dvec2(2.0, 0.0)), 0.0);  // on the line
    EXPECT_EQ(strata::cross2(b - a, c - a), strata::orient2(a, b, c));
    const glm::dvec2 p(0.1, 0.7), q(0.3, -0.2), r(-0.6, 0.25);
    EXPECT_EQ(strata::cross2(p, q), -strata::cross2(q, p));
    // Translating all three points changes nothing but rounding.
    const glm::dvec2 t(1e3, -2e3);
    EXPECT_NEAR(strata::orient2(p + t, q + t, r + t), strata::orient2(p, q, r), 1e-9);
    static_assert(std::is_same<decltype(strata::cross2(glm::vec2(), glm::vec2())), float>::value,
                  "float in, float out: callers keep the bits they computed inline");
    EXPECT_EQ(strata::orient2(glm::ivec2(0, 0), glm::ivec2(2, 0), glm::ivec2(0, 2)), 4);  // integers exact
}
