// Adaptive level of detail (adaptive.h): stitched tiles, crack-free frames
// at random level mixes in both schemes and animated, the uniform surface
// as a special case, and levels chosen from a view within their tolerance.
#include "strata/adaptive.h"
#include "strata/baker/distance.h"
#include "strata/io/mesh_io.h"
#include "strata/normals.h"
#include "strata/plane.h"
#include "strata/surface.h"

#include "test_rigs.h"

#include <gtest/gtest.h>

#include <random>
#include <set>
#include <utility>

namespace strata {
namespace {

// Triangles (slots of a tile of 2^finest segments an edge) that tile their
// control face exactly: counter-clockwise, of positive area summing to the
// face, every edge inside the face shared by two triangles in opposite
// directions.  Returns the edges on the face's sides: side k (from corner k
// to corner k + 1) and the stretch t0 -> t1 along it from its first corner.
struct SideSegment {
    int side, t0, t1;
};
std::vector<SideSegment> expectTiling(const std::vector<uint16_t>& t, int finest, const std::string& label)
{
    const int R = 1 << finest;
    std::vector<std::pair<int, int>> at(size_t(R + 1) * size_t(R + 2) / 2);
    for (int j = 0; j <= R; ++j)
        for (int i = 0; i + j <= R; ++i)
            at[tileSlot(uint32_t(i), uint32_t(j), uint32_t(R))] = {i, j};
    std::vector<SideSegment> sides;
    long area = 0;
    std::map<std::pair<int, int>, int> directed;
    EXPECT_EQ(t.size() % 3, 0u) << label;
    for (size_t k = 0; k + 2 < t.size(); k += 3) {
        auto point = [&](uint16_t slot) { return glm::ivec2(at[slot].first, at[slot].second); };
        const long twice = orient2(point(t[k]), point(t[k + 1]), point(t[k + 2]));
        EXPECT_GT(twice, 0) << label;
        area += twice;
        for (int m = 0; m < 3; ++m)
            ++directed[{t[k + size_t(m)], t[k + size_t(m + 1) % 3]}];
    }
    EXPECT_EQ(area, long(R) * R) << label;  // twice the face's area in grid units
    auto side = [&](int slot) {
        const auto p = at[size_t(slot)];
        return std::array<bool, 3>{p.second == 0, p.first + p.second == R, p.first == 0};
    };
    for (const auto& [edge, count] : directed) {
        EXPECT_EQ(count, 1) << label;
        const bool twin = directed.count({edge.second, edge.first}) > 0;
        const auto sa = side(edge.first), sb = side(edge.second);
        int border = -1;
        for (int m = 0; m < 3; ++m)
            if (sa[size_t(m)] && sb[size_t(m)])
                border = m;
        EXPECT_EQ(twin, border < 0) << label;
        if (border < 0)
            continue;
        const auto pa = at[size_t(edge.first)], pb = at[size_t(edge.second)];
        auto along = [&](std::pair<int, int> p) { return border == 0 ? p.first : border == 1 ? p.second : R - p.second; };
        sides.push_back({border, along(pa), along(pb)});
    }
    return sides;
}

// Every (level, edge levels) template of a finest level tiles its control
// face exactly, each side cut into exactly its edge level's 2^e segments.
void expectTemplateTiles(int finest, int level, const int e[3])
{
    std::vector<uint16_t> t;
    adaptiveTileTriangles(&t, finest, level, e);
    const std::string label = "finest " + std::to_string(finest) + " level " + std::to_string(level) + " edges " +
                              std::to_string(e[0]) + std::to_string(e[1]) + std::to_string(e[2]);
    std::array<int, 3> segments{0, 0, 0};
    for (const SideSegment& g : expectTiling(t, finest, label)) {
        EXPECT_EQ(g.t1 - g.t0, 1 << (finest - e[g.side])) << label << " border " << g.side;
        ++segments[size_t(g.side)];
    }
    for (int m = 0; m < 3; ++m)
        EXPECT_EQ(segments[size_t(m)], 1 << e[m]) << label << " border " << m;
}

TEST(Adaptive, EveryTileTemplateTilesItsFace)
{
    for (int finest = 0; finest <= 4; ++finest)
        for (int level = 0; level <= finest; ++level)
            for (int a = 0; a <= level; ++a)
                for (int b = 0; b <= level; ++b)
                    for (int c = 0; c <= level; ++c) {
                        const int e[3] = {a, b, c};
                        expectTemplateTiles(finest, level, e);
                    }
    // The finest levels a plan takes, at their extreme mixes.
    for (int level : {5, 6}) {
        for (const std::array<int, 3>& e : std::vector<std::array<int, 3>>{{0, 0, 0}, {level, 0, 3}, {1, level, level}, {level, level, level}}) {
            expectTemplateTiles(6, level, e.data());
        }
    }
}

// A face drawn as four quarters (levels q, each half of its edges at h:
// h[k][0] at corner k, h[k][1] at corner k + 1) tiles the face exactly,
// as a whole face's template does: counter-clockwise triangles of positive
// area summing to the face, inner edges twice in opposite directions, and
// each half of each border edge cut into its level's segments.
void expectQuartersTile(int finest, const int q[4], const int h[3][2])
{
    const int R = 1 << finest;
    std::string label = "finest " + std::to_string(finest) + " quarters";
    for (int c = 0; c < 4; ++c)
        label += " " + std::to_string(q[c]);
    label += " halves";
    for (int k = 0; k < 3; ++k)
        label += " " + std::to_string(h[k][0]) + "/" + std::to_string(h[k][1]);
    std::vector<uint16_t> t, all;
    const int mid = q[3];
    for (int c = 0; c < 4; ++c) {
        // Each quarter's edges in its own order (adaptive.h).
        const int inner[3] = {std::min(q[0], mid), std::min(q[1], mid), std::min(q[2], mid)};
        int x[3], coarse = 0;
        if (c == 0) {
            x[0] = h[0][0], x[1] = inner[0], x[2] = h[2][1];
        } else if (c == 1) {
            x[0] = h[0][1], x[1] = h[1][0], x[2] = inner[1];
        } else if (c == 2) {
            x[0] = inner[2], x[1] = h[1][1], x[2] = h[2][0];
        } else {
            x[0] = inner[2], x[1] = inner[0], x[2] = inner[1];
            coarse = (h[0][0] == 0 ? 1 : 0) | (h[1][0] == 0 ? 2 : 0) | (h[2][0] == 0 ? 4 : 0);
        }
        adaptiveQuarterTriangles(&t, finest, c, q[c], x, coarse);
        all.insert(all.end(), t.begin(), t.end());
    }
    std::array<std::array<int, 2>, 3> segments{};
    for (const SideSegment& g : expectTiling(all, finest, label)) {
        const int half = g.t1 <= R / 2 ? 0 : 1;
        if (h[g.side][0] == 0) {
            EXPECT_EQ(g.t1 - g.t0, R) << label << " border " << g.side;
        } else {
            EXPECT_EQ(g.t1 - g.t0, 1 << (finest - h[g.side][half])) << label << " border " << g.side;
        }
        ++segments[size_t(g.side)][size_t(half)];
    }
    for (int k = 0; k < 3; ++k) {
        if (h[k][0] == 0) {
            EXPECT_EQ(segments[size_t(k)][0] + segments[size_t(k)][1], 1) << label << " border " << k;
        } else {
            EXPECT_EQ(segments[size_t(k)][0], 1 << (h[k][0] - 1)) << label << " border " << k;
            EXPECT_EQ(segments[size_t(k)][1], 1 << (h[k][1] - 1)) << label << " border " << k;
        }
    }
}

TEST(Adaptive, EveryMixOfQuartersTilesItsFace)
{
    // Every mix at finest 3, each edge's halves at any levels up to their
    // quarters' (both 0: a neighbour at level 0); random mixes at 5.
    for (int finest : {1, 2, 3}) {
        std::vector<int> q(4, 1);
        for (q[0] = 1; q[0] <= finest; ++q[0])
            for (q[1] = 1; q[1] <= finest; ++q[1])
                for (q[2] = 1; q[2] <= finest; ++q[2])
                    for (q[3] = 1; q[3] <= finest; ++q[3])
                        for (int code = 0; code < 729; ++code) {
                            // Per edge: 0 both halves at 0, else a level per half.
                            int h[3][2], rest = code;
                            bool valid = true;
                            for (int k = 0; k < 3; ++k) {
                                const int a = rest % 3, b = (rest / 3) % 3;
                                rest /= 9;
                                const int qa = q[size_t(k)], qb = q[size_t(k + 1) % 3];
                                // 0: zero; 1: the quarter's own; 2: one coarser (if >= 1)
                                // A face edge at level 0 only beside four equal quarters.
                                if (a == 0 || b == 0) {
                                    valid = valid && a == 0 && b == 0 && q[0] == q[1] && q[1] == q[2] && q[2] == q[3];
                                    h[k][0] = h[k][1] = 0;
                                } else {
                                    h[k][0] = a == 1 ? qa : qa - 1;
                                    h[k][1] = b == 1 ? qb : qb - 1;
                                    valid = valid && h[k][0] >= 1 && h[k][1] >= 1;
                                }
                            }
                            if (valid)
                                expectQuartersTile(finest, q.data(), h);
                        }
    }
    std::mt19937 rng(3);
    for (int trial = 0; trial < 400; ++trial) {
        const int finest = 5;
        std::uniform_int_distribution<int> level(1, finest);
        int q[4], h[3][2];
        for (int& l : q)
            l = level(rng);
        if (trial % 10 == 0)
            q[1] = q[2] = q[3] = q[0];
        for (int k = 0; k < 3; ++k) {
            const bool zero = trial % 5 == 0 && k == trial % 3 && q[0] == q[1] && q[1] == q[2] && q[2] == q[3];
            h[k][0] = zero ? 0 : std::uniform_int_distribution<int>(1, q[k])(rng);
            h[k][1] = zero ? 0 : std::uniform_int_distribution<int>(1, q[(k + 1) % 3])(rng);
        }
        expectQuartersTile(finest, q, h);
    }
}

// The bending example rig in either scheme.
// Random quarter levels, 4 per face: a quarter of the faces at level 0,
// a quarter at one level 1..finest, the rest mixed.
void randomQuarters(std::vector<uint8_t>* quarters, int finest, std::mt19937& rng)
{
    std::uniform_int_distribution<int> any(1, finest), pick(0, 3);
    for (size_t f = 0; f < quarters->size() / 4; ++f) {
        const int kind = pick(rng);
        const uint8_t one = uint8_t(any(rng));
        for (size_t k = 0; k < 4; ++k)
            (*quarters)[4 * f + k] = kind == 0 ? 0 : kind == 1 ? one : uint8_t(any(rng));
    }
}

// How many triangles use each undirected edge.
std::map<std::pair<uint32_t, uint32_t>, int> edgeUses(const std::vector<uint32_t>& triangles)
{
    std::map<std::pair<uint32_t, uint32_t>, int> uses;
    for (size_t k = 0; k < triangles.size(); k += 3)
        for (size_t e = 0; e < 3; ++e) {
            const uint32_t u = triangles[k + e], v = triangles[k + (e + 1) % 3];
            ++uses[{std::min(u, v), std::max(u, v)}];
        }
    return uses;
}

// The tests' camera: a 40-degree, 1080-pixel-tall view of the origin from
// `eye`.
ViewSpec viewFrom(glm::vec3 eye)
{
    ViewSpec view;
    view.eye = eye;
    view.target = glm::vec3(0.0f);
    view.fovYDegrees = 40.0f;
    view.heightPx = 1080.0f;
    return view;
}

// A choice made afresh: every quarter set to the finest level by hand
// first, so no levels are held from an earlier choice.
Status chooseAfresh(Surface& s, const ViewSpec& view, float tolerance)
{
    const std::vector<uint8_t> finest(4 * (s.plan().controlTriangles().size() / 3), uint8_t(s.level()));
    if (Status st = s.setQuarterLevels(finest.data(), finest.size()); !st)
        return st;
    return s.chooseFaceLevels(view, tolerance);
}

// The largest on-screen deviation (pixels) of s's adaptive frame from its
// finest surface, both in s's current pose.
float pixelDeviation(Surface& s, const ViewSpec& view)
{
    std::vector<glm::vec3> fine(s.vertexCount()), p(s.adaptiveFrame().vertexCount());
    if (!s.evaluate(fine.data(), nullptr, fine.size()).isOk() || !s.evaluateAdaptive(p.data(), nullptr, p.size()).isOk())
        return std::numeric_limits<float>::infinity();
    return s.adaptiveFrame().maxScreenDeviation(p.data(), fine.data(), view);
}

// The frame's triangles close up: no border edge, no non-manifold edge, the
// sphere's Euler characteristic, every vertex used, no triangle repeats a
// vertex, and each vertex where the uniform finest frame puts it.
void expectClosedFrame(Surface& s, const std::string& label)
{
    const AdaptiveFrame& frame = s.adaptiveFrame();
    const std::vector<uint32_t>& tri = frame.triangles();
    const MeshTopologyStats st = computeTopologyStats(tri.data(), frame.triangleCount());
    EXPECT_EQ(st.boundaryEdges, 0u) << label;
    EXPECT_EQ(st.nonManifoldEdges, 0u) << label;
    EXPECT_EQ(st.eulerCharacteristic, 2) << label;
    EXPECT_EQ(st.vertices, frame.vertexCount()) << label;
    for (size_t t = 0; t < tri.size(); t += 3)
        ASSERT_TRUE(tri[t] != tri[t + 1] && tri[t + 1] != tri[t + 2] && tri[t] != tri[t + 2]) << label;

    std::vector<glm::vec3> p(frame.vertexCount()), n(frame.vertexCount());
    ASSERT_TRUE(s.evaluateAdaptive(p.data(), n.data(), p.size(), 2).isOk());
    std::vector<glm::vec3> fine(s.vertexCount());
    ASSERT_TRUE(s.plan()
                    .evaluate(fine.data(), nullptr, 0, fine.size(), s.controlPositions().data(),
                              s.controlNormals().data(), s.controlVertexCount())
                    .isOk());
    // Each normal is the area-weighted sum over the drawn triangles at the
    // vertex (the tile pass inside large tiles, the gather pass elsewhere),
    // and one thread gives the same bits as two.
    std::vector<glm::vec3> expected(p.size(), glm::vec3(0.0f)), p1(p.size()), n1(p.size());
    for (size_t t = 0; t < tri.size(); t += 3) {
        const glm::vec3 area2 = glm::cross(p[tri[t + 1]] - p[tri[t]], p[tri[t + 2]] - p[tri[t]]);
        for (size_t k = t; k < t + 3; ++k)
            expected[tri[k]] += area2;
    }
    for (glm::vec3& e : expected)
        e = glm::normalize(e);
    ASSERT_TRUE(s.evaluateAdaptive(p1.data(), n1.data(), p1.size(), 1).isOk());
    for (size_t v = 0; v < p.size(); ++v) {
        ASSERT_EQ(p[v], fine[frame.vertices()[v]]) << label << " vertex " << v;
        ASSERT_NEAR(glm::length(n[v]), 1.0f, 1e-5f) << label;
        ASSERT_LT(glm::length(n[v] - expected[v]), 1e-4f) << label << " vertex " << v;
        ASSERT_EQ(p1[v], p[v]) << label;
        ASSERT_EQ(n1[v], n[v]) << label;
    }
    // Shading normals face out of the closed surface, like its triangles.
    glm::vec3 centre(0.0f);
    for (const glm::vec3& q : p)
        centre += q / float(p.size());
    size_t outward = 0;
    for (size_t v = 0; v < p.size(); ++v)
        outward += glm::dot(n[v], p[v] - centre) > 0.0f;
    EXPECT_GT(outward, p.size() * 99 / 100) << label;
}

TEST(Adaptive, RandomLevelMixesAreClosedInBothSchemesAnimated)
{
    std::mt19937 rng(7);
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        test::makeBendingExampleRig(&rig, &map, scheme);
        std::unique_ptr<Surface> s;
        ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
        ASSERT_EQ(s->level(), 4);
        const size_t nf = rig.mesh.faceCount();
        std::vector<uint8_t> levels(nf);
        for (int trial = 0; trial < 12; ++trial) {
            // Uniform draws, then mixes of two far-apart levels, the hardest stitching.
            std::uniform_int_distribution<int> any(0, 4), pick(0, 1);
            for (uint8_t& l : levels)
                l = uint8_t(trial < 6 ? any(rng) : (pick(rng) ? 4 : trial % 2));
            ASSERT_TRUE(s->setFaceLevels(levels.data(), nf).isOk());
            ASSERT_TRUE(s->setAnimationTime(0, 0.1f * float(trial)).isOk());
            expectClosedFrame(*s, std::string(schemeName(scheme)) + " trial " + std::to_string(trial));
        }
        // Quarters at random levels, faces at level 0 among them (a face
        // of unequal quarters beside one is drawn at its finest quarter).
        std::vector<uint8_t> quarters(4 * nf);
        for (int trial = 0; trial < 12; ++trial) {
            std::uniform_int_distribution<int> any(1, 4), pick(0, 3);
            for (size_t f = 0; f < nf; ++f) {
                const bool whole = pick(rng) == 0;
                for (int c = 0; c < 4; ++c)
                    quarters[4 * f + size_t(c)] = uint8_t(trial % 2 && whole ? 0 : any(rng));
            }
            ASSERT_TRUE(s->setQuarterLevels(quarters.data(), quarters.size()).isOk());
            const std::vector<uint8_t>& drawn = s->adaptiveFrame().quarterLevels();
            for (size_t k = 0; k < quarters.size(); ++k)
                ASSERT_GE(drawn[k], quarters[k]);
            ASSERT_TRUE(s->setAnimationTime(0, 0.1f * float(trial)).isOk());
            expectClosedFrame(*s, std::string(schemeName(scheme)) + " quarters trial " + std::to_string(trial));
        }
    }
}

// A control mesh with a hole (the bending head without its crown): random
// face and quarter levels keep the frame's topology that of the control
// mesh (Euler characteristic 1, one border), with no non-manifold edge and
// every vertex where the finest plan puts it.
TEST(Adaptive, RandomQuarterMixesOnAnOpenMeshKeepItsTopology)
{
    std::mt19937 rng(11);
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        test::makeBendingExampleRig(&rig, &map, scheme);
        ControlMesh& m = rig.mesh;
        std::vector<uint32_t> triangles, uvIndices;
        for (size_t f = 0; f < m.faceCount(); ++f) {
            const glm::vec3 c = (m.positions[m.triangles[3 * f]] + m.positions[m.triangles[3 * f + 1]] +
                                 m.positions[m.triangles[3 * f + 2]]) / 3.0f;
            if (c.y > 0.6f * glm::length(c))
                continue;  // the crown
            triangles.insert(triangles.end(), m.triangles.begin() + std::ptrdiff_t(3 * f), m.triangles.begin() + std::ptrdiff_t(3 * f + 3));
            if (m.hasUVs())
                uvIndices.insert(uvIndices.end(), m.uvIndices.begin() + std::ptrdiff_t(3 * f), m.uvIndices.begin() + std::ptrdiff_t(3 * f + 3));
        }
        ASSERT_LT(triangles.size(), m.triangles.size());
        m.triangles = triangles;
        m.uvIndices = uvIndices;
        const MeshTopologyStats control = computeTopologyStats(m.triangles.data(), m.faceCount());
        ASSERT_EQ(control.eulerCharacteristic, 1);
        ASSERT_GT(control.boundaryEdges, 0u);
        std::unique_ptr<Surface> s;
        const Status created = Surface::create(&s, rig, &map);
        ASSERT_TRUE(created.isOk()) << created.message();
        const size_t nf = m.faceCount();
        std::vector<uint8_t> quarters(4 * nf);
        std::vector<glm::vec3> fine(s->vertexCount());
        for (int trial = 0; trial < 10; ++trial) {
            randomQuarters(&quarters, s->level(), rng);
            ASSERT_TRUE(s->setQuarterLevels(quarters.data(), quarters.size()).isOk());
            ASSERT_TRUE(s->setAnimationTime(0, 0.15f * float(trial)).isOk());
            const std::string label = std::string(schemeName(scheme)) + " trial " + std::to_string(trial);
            const AdaptiveFrame& frame = s->adaptiveFrame();
            const MeshTopologyStats st = computeTopologyStats(frame.triangles().data(), frame.triangleCount());
            EXPECT_EQ(st.nonManifoldEdges, 0u) << label;
            EXPECT_EQ(st.eulerCharacteristic, 1) << label;
            EXPECT_GT(st.boundaryEdges, 0u) << label;
            // One rim and no slit: the open edges make one loop, each of its
            // vertices on two of them (a crack would open a second loop).
            std::map<uint32_t, std::vector<uint32_t>> rim;
            for (const auto& [edge, count] : edgeUses(frame.triangles()))
                if (count == 1) {
                    rim[edge.first].push_back(edge.second);
                    rim[edge.second].push_back(edge.first);
                }
            ASSERT_FALSE(rim.empty()) << label;
            size_t walked = 0;
            for (uint32_t prev = rim.begin()->first, at = rim.begin()->second[0];; ++walked) {
                ASSERT_EQ(rim[at].size(), 2u) << label;
                const uint32_t next = rim[at][0] == prev ? rim[at][1] : rim[at][0];
                prev = at;
                at = next;
                if (prev == rim.begin()->first)
                    break;
                ASSERT_LE(walked, rim.size()) << label;
            }
            EXPECT_EQ(walked + 1, rim.size()) << label << ": the open edges make more than one loop";
            std::vector<glm::vec3> p(frame.vertexCount()), n(p.size());
            ASSERT_TRUE(s->evaluateAdaptive(p.data(), n.data(), p.size(), 2).isOk());
            ASSERT_TRUE(s->plan()
                            .evaluate(fine.data(), nullptr, 0, fine.size(), s->controlPositions().data(),
                                      s->controlNormals().data(), s->controlVertexCount())
                            .isOk());
            for (size_t v = 0; v < p.size(); ++v) {
                ASSERT_EQ(p[v], fine[frame.vertices()[v]]) << label << " vertex " << v;
                ASSERT_NEAR(glm::length(n[v]), 1.0f, 1e-5f) << label;
            }
        }
    }
}

// A non-manifold control edge: a tetrahedron hung inside the closed head on
// one of its edges (four faces on that edge).  Every mix of quarter levels
// stitches all four faces to the same points along it: no output edge is
// open, each lies on two faces or (along the hinge) four, and the Euler
// characteristic stays the control mesh's.
TEST(Adaptive, RandomQuarterMixesStitchAcrossANonManifoldEdge)
{
    std::mt19937 rng(5);
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        test::makeBendingExampleRig(&rig, &map, scheme);
        ControlMesh& m = rig.mesh;
        const uint32_t a = m.triangles[0], b = m.triangles[1];
        const glm::vec3 mid = 0.5f * (m.positions[a] + m.positions[b]);
        const glm::vec3 side = 0.2f * glm::normalize(glm::cross(m.positions[b] - m.positions[a], mid));
        const uint32_t c = uint32_t(m.positions.size()), d = c + 1;
        m.positions.push_back(0.6f * mid + side);
        m.positions.push_back(0.6f * mid - side);
        m.triangles.insert(m.triangles.end(), {a, b, c, b, a, d, a, c, d, b, d, c});
        // The fins sample the map where the first face does, and move with
        // the hinge's first vertex.
        const uint32_t ua = m.uvIndices[0], ub = m.uvIndices[1], uc = m.uvIndices[2];
        m.uvIndices.insert(m.uvIndices.end(), {ua, ub, uc, ub, ua, uc, ua, uc, uc, ub, uc, uc});
        VertexWeights& w = rig.skeleton.weights;
        const size_t k = size_t(w.influences);
        for (int copy = 0; copy < 2; ++copy) {
            w.joints.insert(w.joints.end(), w.joints.begin() + long(a * k), w.joints.begin() + long((a + 1) * k));
            w.weights.insert(w.weights.end(), w.weights.begin() + long(a * k), w.weights.begin() + long((a + 1) * k));
        }
        const MeshTopologyStats control = computeTopologyStats(m.triangles.data(), m.faceCount());
        ASSERT_EQ(control.nonManifoldEdges, 1u);
        ASSERT_EQ(control.boundaryEdges, 0u);
        SurfaceOptions options;
        options.level = 4;
        std::unique_ptr<Surface> s;
        const Status created = Surface::create(&s, rig, &map, options);
        ASSERT_TRUE(created.isOk()) << created.message();
        ASSERT_EQ(s->level(), 4);
        const size_t nf = m.faceCount();
        std::vector<uint8_t> quarters(4 * nf);
        for (int trial = 0; trial < 40; ++trial) {
            randomQuarters(&quarters, s->level(), rng);
            ASSERT_TRUE(s->setQuarterLevels(quarters.data(), quarters.size()).isOk());
            const std::string label = std::string(schemeName(scheme)) + " trial " + std::to_string(trial);
            const AdaptiveFrame& frame = s->adaptiveFrame();
            const std::vector<uint32_t>& t = frame.triangles();
            size_t hinge = 0;
            for (const auto& [edge, count] : edgeUses(t)) {
                ASSERT_TRUE(count == 2 || count == 4) << label << ": an edge on " << count << " faces";
                hinge += count == 4;
            }
            EXPECT_GE(hinge, 1u) << label;
            const MeshTopologyStats st = computeTopologyStats(t.data(), frame.triangleCount());
            EXPECT_EQ(st.eulerCharacteristic, control.eulerCharacteristic) << label;
            std::vector<glm::vec3> p(frame.vertexCount());
            ASSERT_TRUE(s->evaluateAdaptive(p.data(), nullptr, p.size()).isOk()) << label;
        }
        // A view's choice over the hinge, bent (the bend's pass takes every
        // face around an edge there, not a pair): within the tolerance.
        ASSERT_TRUE(s->setAnimationTime(0, 0.8f).isOk());
        for (float distance : {2.5f, 8.0f}) {
            const std::string label = std::string(schemeName(scheme)) + " at " + std::to_string(distance);
            const ViewSpec view = viewFrom(glm::vec3(0.3f, 0.2f, distance));
            ASSERT_TRUE(chooseAfresh(*s, view, 1.0f).isOk()) << label;
            EXPECT_LE(pixelDeviation(*s, view), 1.0f) << label;
            std::set<int> levels(s->adaptiveFrame().quarterLevels().begin(), s->adaptiveFrame().quarterLevels().end());
            EXPECT_GE(levels.size(), 2u) << label << ": one level everywhere";
        }
    }
}

TEST(Adaptive, OneLevelEverywhereIsTheUniformSurfaceOfThatLevel)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> fine = test::bendingSurfaceAt(0.7f, &rig, &map, scheme);
        ASSERT_TRUE(fine);
        for (int level = 0; level <= 4; ++level) {
            const std::string label = std::string(schemeName(scheme)) + " level " + std::to_string(level);
            SurfaceOptions o;
            o.level = level;
            std::unique_ptr<Surface> uniform;
            ASSERT_TRUE(Surface::create(&uniform, rig, &map, o).isOk());
            ASSERT_TRUE(uniform->setAnimationTime(0, 0.7f).isOk());
            std::vector<glm::vec3> up(uniform->vertexCount()), un(up.size());
            ASSERT_TRUE(uniform->evaluate(up.data(), un.data(), up.size()).isOk());

            std::vector<uint8_t> levels(rig.mesh.faceCount(), uint8_t(level));
            ASSERT_TRUE(fine->setFaceLevels(levels.data(), levels.size()).isOk());
            const AdaptiveFrame& frame = fine->adaptiveFrame();
            std::vector<glm::vec3> ap(frame.vertexCount()), an(ap.size());
            ASSERT_TRUE(fine->evaluateAdaptive(ap.data(), an.data(), ap.size()).isOk());
            EXPECT_EQ(frame.vertexCount(), uniform->vertexCount()) << label;
            EXPECT_EQ(frame.triangleCount(), uniform->triangleCount()) << label;

            // Same points: each adaptive vertex is a uniform vertex at the
            // same place on the same face, with the same position and, on a
            // closed mesh, the same normal (up to the order of the sums).
            std::map<std::tuple<uint32_t, float, float>, size_t> uniformAt;
            const auto& us = uniform->plan().sampleLocations();
            for (size_t v = 0; v < us.size(); ++v)
                uniformAt[{us[v].face, us[v].bary.x, us[v].bary.y}] = v;
            const auto& fs = fine->plan().sampleLocations();
            for (size_t v = 0; v < ap.size(); ++v) {
                const SampleLocation& loc = fs[frame.vertices()[v]];
                const auto it = uniformAt.find({loc.face, loc.bary.x, loc.bary.y});
                ASSERT_NE(it, uniformAt.end()) << label;
                if (scheme == Scheme::Linear) {
                    ASSERT_EQ(ap[v], up[it->second]) << label;
                } else {  // limit stencils of another level: the same point to rounding
                    ASSERT_LT(glm::length(ap[v] - up[it->second]), 2e-6f) << label;
                }
                ASSERT_LT(glm::length(an[v] - un[it->second]), 2e-5f) << label;
            }
        }
    }
}

TEST(Adaptive, LevelErrorsShrinkToZeroAtTheFinestLevel)
{
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map, Scheme::Linear);
    std::unique_ptr<Surface> s;
    ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
    const FaceLevelErrors& e = s->faceLevelErrors();
    ASSERT_EQ(e.faceCount, rig.mesh.faceCount());
    ASSERT_EQ(e.finest, 4);
    float coarsest = 0.0f;
    for (size_t f = 0; f < e.faceCount; ++f) {
        EXPECT_EQ(e.at(f, 4), 0.0f);
        for (int l = 0; l < 4; ++l)
            EXPECT_GE(e.at(f, l), e.at(f, l + 1));
        coarsest = std::max(coarsest, e.at(f, 0));
        EXPECT_GT(e.reach[f], 0.0f);
    }
    // Quarters at level 1 with all three face edges at level 0 snap every
    // midpoint to a corner: the middle quarter becomes the level 0
    // triangle, with level 0's error, and the others collapse.  Quarters
    // at level 2 with their edges at 2 are the face at level 2.
    LevelChooser chooser;
    std::vector<glm::vec3> restNormals(rig.mesh.vertexCount());
    computeControlNormals(restNormals.data(), rig.mesh.positions.data(), rig.mesh.vertexCount(), rig.mesh.triangles.data(),
                          rig.mesh.faceCount());
    ASSERT_TRUE(chooser.init(s->plan(), nullptr, rig.mesh.positions.data(), restNormals.data(), rig.mesh.vertexCount()).isOk());
    const int corner[3][3] = {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}}, inner[3] = {1, 1, 1}, same[3] = {2, 2, 2};
    for (size_t f = 0; f < e.faceCount; ++f) {
        for (int c = 0; c < 3; ++c)
            EXPECT_EQ(chooser.stitchedQuarterError(f, c, 1, corner[c], 0), 0.0f);
        EXPECT_EQ(chooser.stitchedQuarterError(f, 3, 1, inner, 7), e.at(f, 0));
        float whole = 0.0f;
        for (int c = 0; c < 4; ++c)
            whole = std::max(whole, chooser.stitchedQuarterError(f, c, 2, same, 0));
        EXPECT_EQ(whole, e.at(f, 2));
    }
    // The head's bumps are a few percent of its unit radius: level 0 (the
    // flat icosphere face) misses them by that much.
    EXPECT_GT(coarsest, 0.01f);
    EXPECT_LT(coarsest, 0.5f);
}

TEST(Adaptive, ViewChosenLevelsMeetTheirPixelToleranceWithFewerVertices)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> s = test::bendingSurfaceAt(0.5f, &rig, &map, scheme);
        ASSERT_TRUE(s);
        size_t previous = ~size_t(0);
        for (float distance : {3.0f, 8.0f, 30.0f, 100.0f}) {
            ViewSpec view = viewFrom(glm::vec3(0.3f, 0.2f, distance));
            const std::string label = std::string(schemeName(scheme)) + " at " + std::to_string(distance);
            ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk()) << label;
            const AdaptiveFrame& frame = s->adaptiveFrame();
            EXPECT_LE(pixelDeviation(*s, view), 1.0f) << label;
            EXPECT_LE(frame.vertexCount(), previous) << label;
            previous = frame.vertexCount();
            expectClosedFrame(*s, label);
        }
        // Far away, far fewer vertices than the finest level.
        EXPECT_LT(previous, s->vertexCount() / 4) << schemeName(scheme);

        // Cameras anywhere, among the geometry too, through a 90-degree lens:
        // points near the eye's plane project arbitrarily far, and every
        // point in front of the eye stays within the tolerance all the same.
        // (Against the plan's own evaluation, which the frame's vertices
        // equal bit for bit: the uniform frame sums the smooth stencils in
        // another order, and a rounding step of a point a hair in front of
        // the eye is itself thousands of pixels.)  A bound that stopped at
        // 60 degrees off the axis failed 133 and 4 of 300 such views.
        std::vector<glm::vec3> exact(s->vertexCount());
        ASSERT_TRUE(s->plan()
                        .evaluate(exact.data(), nullptr, 0, exact.size(), s->controlPositions().data(),
                                  s->controlNormals().data(), s->controlVertexCount())
                        .isOk());
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (const glm::vec3& p : exact) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        std::mt19937 rng(3);
        std::uniform_real_distribution<float> u(0.0f, 1.0f);
        for (int trial = 0; trial < 100; ++trial) {
            ViewSpec view;
            view.eye = lo - 0.5f * (hi - lo) + 2.0f * (hi - lo) * glm::vec3(u(rng), u(rng), u(rng));
            view.target = view.eye + glm::vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
            view.fovYDegrees = 90.0f;
            view.heightPx = 1080.0f;
            const std::string label = std::string(schemeName(scheme)) + " random view " + std::to_string(trial);
            ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk()) << label;
            const AdaptiveFrame& frame = s->adaptiveFrame();
            std::vector<glm::vec3> p(frame.vertexCount());
            ASSERT_TRUE(s->evaluateAdaptive(p.data(), nullptr, p.size()).isOk());
            ASSERT_LE(frame.maxScreenDeviation(p.data(), exact.data(), view), 1.0f) << label;
        }
        expectClosedFrame(*s, std::string(schemeName(scheme)) + " the last random view");
    }
}

// The largest distance, in pixels of `view` at the point's depth, from
// points on mesh A (n + 1 per edge of each triangle) to mesh B: an
// independent tool's measure, by nearest points, not by grid places.
float nearestPixels(const ViewSpec& view, const std::vector<glm::vec3>& a, const std::vector<uint32_t>& ta,
                    const std::vector<glm::vec3>& b, const std::vector<uint32_t>& tb, int n)
{
    baker::TriangleIndex index;
    index.build(b.data(), tb.data(), tb.size() / 3);
    const glm::dvec3 eye(view.eye), forward = glm::normalize(glm::dvec3(view.target - view.eye));
    double worst = 0.0;
    int64_t hint = -1;
    for (size_t t = 0; t + 2 < ta.size(); t += 3) {
        const glm::dvec3 p0(a[ta[t]]), p1(a[ta[t + 1]]), p2(a[ta[t + 2]]);
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) {
                const glm::dvec3 x = p0 + (p1 - p0) * (double(i) / n) + (p2 - p0) * (double(j) / n);
                const double depth = glm::dot(x - eye, forward);
                if (depth > 0.0)
                    worst = std::max(worst, index.nearest(x, &hint) * view.pixelsPerUnitAtDistanceOne() / depth);
            }
    }
    return float(worst);
}

// A face drawn finer than its neighbour fans its strip along their edge
// onto the coarser edge's vertices, and a fan triangle's edges cut across
// the finest triangles between their vertices.  On a rough surface the
// finest surface there can stand far off the fan (nefertiti at 100%: 9.2 px
// between the vertices, 3.3 px by nearest points, where the vertices
// measured 0.98; here 2.4 px, 2.2 by nearest points, at 6 units): the
// choice counts those crossings, and the measure does too (a 4x finer
// lattice finds no more), so an independent tool's nearest-point distance,
// both ways, is within the tolerance as well.
TEST(Adaptive, StitchedTrianglesStayWithinTheToleranceBetweenTheFinestVertices)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        test::makeBendingExampleRig(&rig, &map, scheme);
        // A third of the atlas rough (a texel-sized ripple of 1% of the
        // head's radius), the rest smooth: faces drawn at the finest level
        // beside faces drawn coarse, their long fans across rough ground.
        std::mt19937 rng(11);
        std::uniform_real_distribution<float> ripple(-0.01f, 0.01f);
        for (size_t k = 0; k < map.texels.size(); ++k)
            if (int(k % size_t(map.width)) < map.width / 3)
                map.texels[k] += ripple(rng);
        std::unique_ptr<Surface> s;
        ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
        ASSERT_TRUE(s->setAnimationTime(0, 0.5f).isOk());
        std::vector<glm::vec3> fine(s->vertexCount());
        ASSERT_TRUE(s->evaluate(fine.data(), nullptr, fine.size()).isOk());
        const std::vector<uint32_t>& fineTriangles = s->plan().refinedTriangles();
        for (float distance : {6.0f, 12.0f, 24.0f}) {
            const ViewSpec view = viewFrom(glm::vec3(0.4f, 0.3f, distance));
            const std::string label = std::string(schemeName(scheme)) + " at " + std::to_string(distance);
            ASSERT_TRUE(chooseAfresh(*s, view, 1.0f).isOk()) << label;
            const AdaptiveFrame& frame = s->adaptiveFrame();
            std::vector<glm::vec3> p(frame.vertexCount());
            ASSERT_TRUE(s->evaluateAdaptive(p.data(), nullptr, p.size()).isOk());
            const float measured = frame.maxScreenDeviation(p.data(), fine.data(), view);
            EXPECT_LE(measured, 1.0f) << label;
            EXPECT_LE(frame.maxScreenDeviation(p.data(), fine.data(), view, 4), measured * 1.001f) << label;
            EXPECT_LE(nearestPixels(view, p, frame.triangles(), fine, fineTriangles, 6), 1.0f) << label;
            EXPECT_LE(nearestPixels(view, fine, fineTriangles, p, frame.triangles(), 3), 1.0f) << label;
            EXPECT_LT(frame.vertexCount(), s->vertexCount()) << label;
        }
        // Any mix of levels: the crossings find what a lattice 4x finer does.
        std::mt19937 mix(5);
        std::vector<uint8_t> quarters(4 * rig.mesh.faceCount());
        for (int trial = 0; trial < 5; ++trial) {
            randomQuarters(&quarters, s->level(), mix);
            ASSERT_TRUE(s->setQuarterLevels(quarters.data(), quarters.size()).isOk());
            const AdaptiveFrame& frame = s->adaptiveFrame();
            std::vector<glm::vec3> p(frame.vertexCount());
            ASSERT_TRUE(s->evaluateAdaptive(p.data(), nullptr, p.size()).isOk());
            const ViewSpec view = viewFrom(glm::vec3(0.4f, 0.3f, 3.0f));
            const float exact = frame.maxScreenDeviation(p.data(), fine.data(), view);
            EXPECT_LE(frame.maxScreenDeviation(p.data(), fine.data(), view, 4), exact * 1.001f)
                << schemeName(scheme) << " mix " << trial;
        }
    }
}

// A pose swinging back and forth under a still camera: chosen afresh each
// frame, levels
// flip where a face's error sits at the tolerance; chosen
// from the frame before, each level holds until it is clearly too fine.
// Both stay within the tolerance every frame.
TEST(Adaptive, LevelsHoldAcrossFramesOfAMovingPose)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> held = test::bendingSurfaceAt(0.0f, &rig, &map, scheme), fresh;
        ASSERT_TRUE(held);
        ASSERT_TRUE(Surface::create(&fresh, rig, &map).isOk());
        ViewSpec view = viewFrom(glm::vec3(0.3f, 0.2f, 6.0f));
        std::vector<uint8_t> heldBefore, freshBefore;
        int heldChanges = 0, freshChanges = 0;
        size_t heldVertices = 0, freshVertices = 0;
        for (int frame = 0; frame <= 60; ++frame) {
            const float t = 0.5f + 0.1f * std::sin(0.6f * float(frame));  // back and forth
            const std::string label = std::string(schemeName(scheme)) + " frame " + std::to_string(frame);
            ASSERT_TRUE(held->setAnimationTime(0, t).isOk());
            ASSERT_TRUE(fresh->setAnimationTime(0, t).isOk());
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk()) << label;
            ASSERT_TRUE(chooseAfresh(*fresh, view, 1.0f).isOk()) << label;
            for (Surface* s : {held.get(), fresh.get()})
                ASSERT_LE(pixelDeviation(*s, view), 1.0f) << label;
            const std::vector<uint8_t>& h = held->adaptiveFrame().quarterLevels();
            const std::vector<uint8_t>& r = fresh->adaptiveFrame().quarterLevels();
            heldChanges += frame > 0 && h != heldBefore;
            freshChanges += frame > 0 && r != freshBefore;
            heldBefore = h;
            freshBefore = r;
            heldVertices += held->adaptiveFrame().vertexCount();
            freshVertices += fresh->adaptiveFrame().vertexCount();
        }
        std::printf("%s: levels changed in %d of 60 frames held, %d chosen afresh; vertices %.3f of fresh\n",
                    schemeName(scheme), heldChanges, freshChanges, double(heldVertices) / double(freshVertices));
        EXPECT_LT(heldChanges, freshChanges / 2) << schemeName(scheme);
        EXPECT_LT(double(heldVertices), 1.25 * double(freshVertices)) << schemeName(scheme);
        // A still pose and camera settle: the choice after the first keeps
        // the frame.
        for (float distance : {2.5f, 6.0f, 20.0f}) {
            view.eye = glm::vec3(0.3f, 0.2f, distance);
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk());
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk());
            const uint64_t settled = held->adaptiveFrame().topologyVersion();
            for (int again = 0; again < 3; ++again) {
                ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk());
                EXPECT_EQ(held->adaptiveFrame().topologyVersion(), settled) << schemeName(scheme) << " at " << distance;
            }
        }
    }
}

// A choice keeps the last pose's bends while the pose stays (a view that
// moves over a still character); a pose that moves, by as little as a
// frame, is measured again: a surface that chose at other poses before
// chooses what a new one chooses.
TEST(Adaptive, AChoiceAfterAPoseChangeIsTheNewPosesChoice)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> reused = test::bendingSurfaceAt(0.0f, &rig, &map, scheme);
        std::unique_ptr<Surface> driven = test::bendingSurfaceAt(0.0f, &rig, &map, scheme);
        ASSERT_TRUE(reused && driven);
        ViewSpec view = viewFrom(glm::vec3(0.3f, 0.2f, 3.0f));
        size_t differ = 0;
        std::vector<uint8_t> rest;
        for (float t : {0.0f, 0.5f, 0.501f, 0.501f, 1.0f, 0.0f}) {
            const std::string label = std::string(schemeName(scheme)) + " at " + std::to_string(t);
            std::unique_ptr<Surface> fresh = test::bendingSurfaceAt(t, &rig, &map, scheme);
            ASSERT_TRUE(fresh);
            ASSERT_TRUE(fresh->chooseFaceLevels(view, 1.0f).isOk());
            ASSERT_TRUE(reused->setAnimationTime(0, t).isOk());
            for (int move = 0; move < 2; ++move) {
                view.eye.x += 0.01f * float(move);  // the view moves, the pose stays
                ASSERT_TRUE(chooseAfresh(*fresh, view, 1.0f).isOk());
                ASSERT_TRUE(chooseAfresh(*reused, view, 1.0f).isOk());
                EXPECT_EQ(reused->adaptiveFrame().quarterLevels(), fresh->adaptiveFrame().quarterLevels()) << label;
            }
            view.eye.x = 0.3f;
            // The same poses given as control positions, to a surface that
            // keeps choosing and to one made for each.
            std::unique_ptr<Surface> given = test::bendingSurfaceAt(0.0f, &rig, &map, scheme);
            ASSERT_TRUE(given);
            ASSERT_TRUE(given->setControlPositions(fresh->controlPositions().data(), fresh->controlVertexCount()).isOk());
            ASSERT_TRUE(driven->setControlPositions(fresh->controlPositions().data(), fresh->controlVertexCount()).isOk());
            ASSERT_TRUE(chooseAfresh(*given, view, 1.0f).isOk());
            ASSERT_TRUE(chooseAfresh(*driven, view, 1.0f).isOk());
            EXPECT_EQ(driven->adaptiveFrame().quarterLevels(), given->adaptiveFrame().quarterLevels()) << label;
            if (t == 0.0f)
                rest = fresh->adaptiveFrame().quarterLevels();
            else
                differ += fresh->adaptiveFrame().quarterLevels() != rest;
        }
        EXPECT_GT(differ, 0u) << schemeName(scheme) << ": the poses should choose differently";
    }
}

// A camera that dollies in and out a little each frame over a moving pose:
// most choices keep the last levels without being made again, and every
// frame still meets the tolerance (the kept ones too) and keeps no more
// detail than a fresh choice within kHoldTolerance of it, or about that.
// The levels a chooser of the test's own, made as `posed` makes its own
// (from `rest`, its rest pose), chooses in full in `posed`'s pose from
// `previous` (for a 1-pixel tolerance).
std::vector<uint8_t> choiceInFull(const Surface& rest, const Surface& posed, const ViewSpec& view,
                                  const std::vector<uint8_t>& previous)
{
    LevelChooser full;
    std::vector<uint8_t> levels(previous.size());
    EXPECT_TRUE(full.init(rest.plan(), nullptr, rest.controlPositions().data(), rest.controlNormals().data(),
                          rest.controlVertexCount())
                    .isOk());
    const std::vector<glm::mat4>& skin = posed.skinMatrices();
    EXPECT_TRUE(full.choose(levels.data(), view, 1.0f, posed.controlPositions().data(), posed.controlVertexCount(),
                            skin.empty() ? 1.0f : skinScale(&skin[0][0][0], skin.size()),
                            posed.controlNormals().data(), previous.data())
                    .isOk());
    return levels;
}

TEST(Adaptive, AKeptChoiceStillMeetsItsTolerance)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> held = test::bendingSurfaceAt(0.5f, &rig, &map, scheme),
                                 fresh = test::bendingSurfaceAt(0.5f, &rig, &map, scheme);
        ASSERT_TRUE(held && fresh);
        ViewSpec view = viewFrom(glm::vec3(0.0f, 0.0f, 1.0f));  // the eye set below
        size_t heldVertices = 0, bandVertices = 0, repairs = 0;
        // A chooser of the test's own, made as the Surface makes its own;
        // asked afresh each frame, it makes every choice in full.
        std::unique_ptr<Surface> rest = test::bendingSurfaceAt(0.0f, &rig, &map, scheme);
        ASSERT_TRUE(rest && rest->setRestPose().isOk());
        const int frames = 120;
        for (int frame = 0; frame < frames; ++frame) {
            // In from 6 to 2.5 and out again, the pose bending meanwhile.
            const float s = 0.5f - 0.5f * std::cos(6.2831853f * float(frame) / float(frames));
            view.eye = glm::vec3(0.3f, 0.2f, 6.0f - 3.5f * s);
            const float t = 0.5f + 0.05f * std::sin(0.1f * float(frame));
            const std::string label = std::string(schemeName(scheme)) + " frame " + std::to_string(frame);
            ASSERT_TRUE(held->setAnimationTime(0, t).isOk());
            ASSERT_TRUE(fresh->setAnimationTime(0, t).isOk());
            const std::vector<uint8_t> before = held->adaptiveFrame().quarterLevels();
            const size_t repairedBefore = held->levelChooser() ? held->levelChooser()->repairedChoices() : 0;
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk()) << label;
            ASSERT_LE(pixelDeviation(*held, view), 1.0f) << label;
            if (held->levelChooser()->repairedChoices() != repairedBefore) {
                // A repair (stitched from the faces that moved) is the
                // choice made in full from the same levels.
                ++repairs;
                EXPECT_EQ(choiceInFull(*rest, *held, view, before), held->adaptiveFrame().quarterLevels()) << label;
            }
            heldVertices += held->adaptiveFrame().vertexCount();
            ASSERT_TRUE(chooseAfresh(*fresh, view, LevelChooser::kHoldTolerance).isOk());
            bandVertices += fresh->adaptiveFrame().vertexCount();
        }
        const LevelChooser* chooser = held->levelChooser();
        ASSERT_TRUE(chooser);
        std::printf("%s: %zu choices made in full, %zu kept, %zu repaired; vertices %.3f of a fresh choice within the band\n",
                    schemeName(scheme), chooser->fullChoices(), chooser->keptChoices(), chooser->repairedChoices(),
                    double(heldVertices) / double(bandVertices));
        EXPECT_EQ(chooser->fullChoices() + chooser->keptChoices() + chooser->repairedChoices(), size_t(frames))
            << schemeName(scheme);
        EXPECT_GE(chooser->repairedChoices(), 5u) << schemeName(scheme);  // each checked above
        EXPECT_EQ(repairs, chooser->repairedChoices()) << schemeName(scheme);
        EXPECT_GT(chooser->keptChoices(), size_t(frames) / 2) << schemeName(scheme);
        EXPECT_GT(chooser->fullChoices(), 1u) << schemeName(scheme);
        EXPECT_LT(double(heldVertices), 1.1 * double(bandVertices)) << schemeName(scheme);
    }
}

// A camera that moves away from a held choice keeps no more detail than a
// fresh choice within kHoldTolerance of the tolerance would take, and no
// less than one within the tolerance.
TEST(Adaptive, MovingAwayDropsLevelsToTheTolerance)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> held = test::bendingSurfaceAt(0.5f, &rig, &map, scheme),
                                 fresh = test::bendingSurfaceAt(0.5f, &rig, &map, scheme);
        ASSERT_TRUE(held && fresh);
        ViewSpec view = viewFrom(glm::vec3(0.0f, 0.0f, 1.0f));  // the eye set below
        auto freshAt = [&](float tolerance) {
            EXPECT_TRUE(chooseAfresh(*fresh, view, tolerance).isOk());
            return fresh->adaptiveFrame().vertexCount();
        };
        const glm::vec3 near(0.3f, 0.2f, 2.5f);
        for (float distance : {6.0f, 12.0f, 20.0f}) {
            view.eye = near;
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk());
            view.eye = glm::vec3(0.3f, 0.2f, distance);
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk());
            const size_t kept = held->adaptiveFrame().vertexCount(), need = freshAt(1.0f),
                         band = freshAt(LevelChooser::kHoldTolerance);
            std::printf("%s, 2.5 -> %.0f: %zu vertices held, %zu fresh, %zu fresh within the band\n",
                        schemeName(scheme), double(distance), kept, need, band);
            EXPECT_GE(kept, need);
            EXPECT_LE(double(kept), 1.02 * double(band)) << schemeName(scheme) << " at " << distance;
        }
    }
}

// A camera drifting away keeps the detail it no longer needs while it still
// meets the tolerance and at most one face in kRepairShare could fall:
// dropping it costs a rebuild.  Past that share the choice is made again
// and the levels fall to what a choice in full from them takes.
TEST(Adaptive, FallsWaitUntilEnoughCouldFall)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> held = test::bendingSurfaceAt(0.5f, &rig, &map, scheme);
        std::unique_ptr<Surface> full = test::bendingSurfaceAt(0.5f, &rig, &map, scheme);
        std::unique_ptr<Surface> rest = test::bendingSurfaceAt(0.0f, &rig, &map, scheme);
        ASSERT_TRUE(held && full && rest && rest->setRestPose().isOk());
        ViewSpec view = viewFrom(glm::vec3(0.3f, 0.2f, 2.5f));
        ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk());
        size_t waited = 0, fell = 0;
        double most = 0.0;  // the largest share of extra vertices kept
        for (int frame = 1; frame <= 60; ++frame) {
            // Away from 2.5 to 2.5 * 1.01^60 = 4.5, one percent a frame.
            view.eye = glm::vec3(0.3f, 0.2f, 2.5f * std::pow(1.01f, float(frame)));
            const std::string label = std::string(schemeName(scheme)) + " frame " + std::to_string(frame);
            const std::vector<uint8_t> before = held->adaptiveFrame().quarterLevels();
            ASSERT_TRUE(held->chooseFaceLevels(view, 1.0f).isOk()) << label;
            ASSERT_LE(pixelDeviation(*held, view), 1.0f) << label;
            const std::vector<uint8_t>& now = held->adaptiveFrame().quarterLevels();
            const std::vector<uint8_t> levels = choiceInFull(*rest, *held, view, before);
            if (now == before) {
                ASSERT_TRUE(full->setQuarterLevels(levels.data(), levels.size()).isOk());
                const double extra = double(held->adaptiveFrame().vertexCount()) /
                                         double(full->adaptiveFrame().vertexCount()) -
                                     1.0;
                waited += extra > 0.0;
                most = std::max(most, extra);
            } else {
                EXPECT_EQ(now, levels) << label;  // chosen again: the choice in full
                ++fell;
            }
        }
        std::printf("%s: %zu frames kept detail a choice in full would drop (at most %.1f%% more vertices), %zu "
                    "frames chose again\n",
                    schemeName(scheme), waited, 100.0 * most, fell);
        EXPECT_GT(waited, 0u) << schemeName(scheme);
        EXPECT_GT(fell, 0u) << schemeName(scheme);
        EXPECT_LT(most, 0.1) << schemeName(scheme);
    }
}

// The finest level everywhere draws the finest surface: no pixel off, even
// where a vertex lies a hair in front of the eye's plane, which projects a
// float step between two evaluation orders of the same vertex (the smooth
// tile pass against its stencils) to millions of pixels; and a choice made
// for such a view stays within its tolerance.
TEST(Adaptive, APointAtTheEyesPlaneIsNoPixelsOffAtTheFinestLevel)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> s = test::bendingSurfaceAt(0.5f, &rig, &map, scheme);
        ASSERT_TRUE(s);
        std::vector<glm::vec3> fine(s->vertexCount());
        ASSERT_TRUE(s->evaluate(fine.data(), nullptr, fine.size()).isOk());
        const std::vector<uint8_t> finest(rig.mesh.faceCount(), uint8_t(s->level()));
        size_t views = 0;
        for (size_t v = 0; v < fine.size(); v += fine.size() / 7) {
            // Vertex v 1e-6 in front of the eye, 0.4 to its side, looking
            // along +z or -z past it.
            for (float dir : {1.0f, -1.0f}) {
                ViewSpec view;
                view.eye = fine[v] + glm::vec3(0.4f, 0.0f, -dir * 1e-6f);
                view.target = view.eye + glm::vec3(0.0f, 0.0f, dir);
                view.fovYDegrees = 60.0f;
                view.heightPx = 1080.0f;
                const std::string label = std::string(schemeName(scheme)) + " vertex " + std::to_string(v);
                ASSERT_TRUE(s->setFaceLevels(finest.data(), finest.size()).isOk());
                EXPECT_EQ(pixelDeviation(*s, view), 0.0f) << label;
                ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk()) << label;
                EXPECT_LE(pixelDeviation(*s, view), 1.0f) << label;
                ++views;
            }
        }
        EXPECT_GE(views, 14u);
    }
}

TEST(Adaptive, BadLevelsAndViewsAreRefused)
{
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map, Scheme::Linear);
    std::unique_ptr<Surface> s;
    ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
    std::vector<uint8_t> levels(rig.mesh.faceCount(), 2);
    EXPECT_FALSE(s->setFaceLevels(levels.data(), levels.size() - 1).isOk());
    levels[3] = 5;
    const Status st = s->setFaceLevels(levels.data(), levels.size());
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("past the plan's level 4"), std::string::npos) << st.message();
    // Quarters: four per face, all 0 or each 1 and up.
    std::vector<uint8_t> quarters(4 * rig.mesh.faceCount(), 2);
    EXPECT_FALSE(s->setQuarterLevels(quarters.data(), quarters.size() - 4).isOk());
    quarters[5] = 0;
    const Status mixed = s->setQuarterLevels(quarters.data(), quarters.size());
    EXPECT_FALSE(mixed.isOk());
    EXPECT_NE(mixed.message().find("control face 1 mixes level 0"), std::string::npos) << mixed.message();
    quarters[5] = 5;
    EXPECT_FALSE(s->setQuarterLevels(quarters.data(), quarters.size()).isOk());
    ViewSpec view;
    view.eye = view.target = glm::vec3(1.0f);
    EXPECT_FALSE(s->chooseFaceLevels(view, 1.0f).isOk());
    view.eye = glm::vec3(0.0f, 0.0f, 5.0f);
    EXPECT_FALSE(s->chooseFaceLevels(view, 0.0f).isOk());
    EXPECT_FALSE(s->chooseFaceLevels(view, std::nanf("")).isOk());
    view.fovYDegrees = 180.0f;
    EXPECT_FALSE(s->chooseFaceLevels(view, 1.0f).isOk());
    std::vector<glm::vec3> p(3);
    EXPECT_FALSE(s->evaluateAdaptive(p.data(), nullptr, p.size()).isOk());
}

// strata-reconstruct --view, checked from its files alone: the adaptive
// mesh is closed and manifold, and every vertex of the finest surface in
// the same pose lies within the pixel tolerance of it (nearest distance,
// seen at the vertex's depth), with fewer vertices than the finest level.
TEST(Adaptive, ReconstructViewWritesAClosedMeshWithinItsTolerance)
{
    const std::string dir = test::tempDir("adaptive_view");
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map, Scheme::Linear);
    rig.displacement.uri = "bend.exr";
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/bend.exr", map).isOk());
    ASSERT_TRUE(io::saveRig(dir + "/bend.glb", rig).isOk());
    const std::string exe = STRATA_RECONSTRUCT_EXE, in = "'" + dir + "/bend.glb' --anim bend --time 0.5 ";
    test::CommandResult r = test::runCommand(exe + " " + in + "-o '" + dir + "/fine.obj'");
    ASSERT_EQ(r.code, 0) << r.output;
    ControlMesh fine;
    ASSERT_TRUE(io::readObj(dir + "/fine.obj", &fine).isOk());

    for (float distance : {2.5f, 12.0f}) {
        for (float tolerance : {1.0f, 4.0f}) {
            const std::string label = "distance " + std::to_string(distance) + ", " + std::to_string(tolerance) + " px";
            const glm::vec3 eye(0.5f, 0.4f, distance);
            char viewArg[128];
            std::snprintf(viewArg, sizeof(viewArg), "%g,%g,%g:0,0.2,0:40:1080", double(eye.x), double(eye.y), double(eye.z));
            const std::string out = dir + "/view.obj";
            r = test::runCommand(exe + " " + in + "--view " + viewArg + " --pixel-error " + std::to_string(tolerance) +
                                 " -o '" + out + "'");
            ASSERT_EQ(r.code, 0) << r.output;
            EXPECT_NE(r.output.find("largest deviation from level 4 in front of the eye"), std::string::npos) << r.output;
            ControlMesh adaptive;
            ASSERT_TRUE(io::readObj(out, &adaptive).isOk());
            const MeshTopologyStats st = computeTopologyStats(adaptive.triangles.data(), adaptive.faceCount());
            EXPECT_EQ(st.boundaryEdges, 0u) << label;
            EXPECT_EQ(st.nonManifoldEdges, 0u) << label;
            EXPECT_EQ(st.eulerCharacteristic, 2) << label;
            EXPECT_LT(adaptive.vertexCount(), fine.vertexCount()) << label;

            baker::TriangleIndex index;
            index.build(adaptive.positions.data(), adaptive.triangles.data(), adaptive.faceCount());
            ViewSpec view;
            view.eye = eye;
            view.target = glm::vec3(0.0f, 0.2f, 0.0f);
            view.fovYDegrees = 40.0f;
            const glm::vec3 forward = glm::normalize(view.target - view.eye);
            float worst = 0.0f;
            for (const glm::vec3& p : fine.positions) {
                const double d = index.nearest(glm::dvec3(p));
                worst = std::max(worst, float(d) * view.pixelsPerUnitAtDistanceOne() / glm::dot(p - eye, forward));
            }
            EXPECT_LE(worst, tolerance) << label;
        }
    }

    struct Case {
        std::string args, needle;
    };
    for (const Case& c : {Case{"--view 0,0,3:0,0,0:40", "--view expects"}, Case{"--view 0,0,3:0,0,3:40:1080", "must differ"},
                          Case{"--view 0,0,3:0,0,0:200:1080", "field of view"}, Case{"--pixel-error 1", "needs --view"},
                          Case{"--view 0,0,3:0,0,0:40:1080 --pixel-error 0", "--pixel-error"},
                          Case{"--view 0,0,3:0,0,0:40:1080 --frames 0:1:2", "--time instead"}}) {
        r = test::runCommand(exe + " '" + dir + "/bend.glb' " + c.args + " -o '" + dir + "/bad.obj'");
        EXPECT_EQ(r.code, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find(c.needle), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_FALSE(test::fileExists(dir + "/bad.obj")) << c.args;
    }
}

// A pose that stretches the cage counts its stretch, face by face, however
// it is given: control positions an engine deformed itself choose what the
// same pose as joint matrices does where the skin is rigid, and a cage
// stretched 2-4x (positions, no skin to tell it) stays within the
// tolerance in both schemes.
TEST(Adaptive, StretchedPosesStayWithinTheTolerance)
{
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        std::unique_ptr<Surface> bySkin = test::bendingSurfaceAt(0.6f, &rig, &map, scheme), byPositions;
        ASSERT_TRUE(bySkin);
        ASSERT_TRUE(Surface::create(&byPositions, rig, &map).isOk());
        const std::vector<glm::vec3>& posed = bySkin->controlPositions();
        ASSERT_TRUE(byPositions->setControlPositions(posed.data(), posed.size()).isOk());
        for (float distance : {3.0f, 8.0f}) {
            const std::string label = std::string(schemeName(scheme)) + " bent, at " + std::to_string(distance);
            const ViewSpec view = viewFrom(glm::vec3(0.5f, 0.3f, distance));
            ASSERT_TRUE(chooseAfresh(*bySkin, view, 1.0f).isOk()) << label;
            ASSERT_TRUE(chooseAfresh(*byPositions, view, 1.0f).isOk()) << label;
            EXPECT_EQ(byPositions->adaptiveFrame().quarterLevels(), bySkin->adaptiveFrame().quarterLevels()) << label;
        }
        size_t views = 0;
        for (const glm::vec3 stretch : {glm::vec3(2.0f, 1.0f, 1.0f), glm::vec3(4.0f, 1.0f, 1.0f), glm::vec3(1.0f, 3.0f, 0.5f)}) {
            std::vector<glm::vec3> p = rig.mesh.positions;
            for (glm::vec3& v : p)
                v *= stretch;
            ASSERT_TRUE(byPositions->setControlPositions(p.data(), p.size()).isOk());
            for (float distance : {2.5f, 5.0f, 10.0f, 20.0f}) {
                const std::string label = std::string(schemeName(scheme)) + " stretched " + std::to_string(stretch.x) + ", " +
                                          std::to_string(stretch.y) + " at " + std::to_string(distance);
                const ViewSpec view = viewFrom(glm::vec3(0.4f, 0.2f, distance));
                ASSERT_TRUE(chooseAfresh(*byPositions, view, 1.0f).isOk()) << label;
                EXPECT_LE(pixelDeviation(*byPositions, view), 1.0f) << label;
                ++views;
            }
        }
        EXPECT_EQ(views, 12u);
    }
}

// A pose given without its control normals still counts each face's
// stretch as the larger of its own and its neighbours' (a smooth
// surface's stencils reach across its edges): where nothing bends (a flat
// grid, one vertex slid along it), the choice is the one made with the
// normals.  And a chooser asked about other poses in between measures the
// pose again: the stretches of a pose given without normals once stood
// for the bends and stretches kept for the last pose given with them.
TEST(Adaptive, APoseWithoutNormalsSpreadsItsStretchAsWithThem)
{
    // A flat 8 x 8 grid in z = 0 about the origin, UV = (x, y), displaced by a sine.
    const int n = 8;
    ControlMesh grid = test::makeGrid(n);
    for (glm::vec3& p : grid.positions)
        p -= glm::vec3(0.5f, 0.5f, 0.0f);
    DisplacementMap map;
    map.width = map.height = 256;
    for (int y = 0; y < map.height; ++y)
        for (int x = 0; x < map.width; ++x)
            map.texels.push_back(0.01f * std::sin(0.2f * float(x)) * std::sin(0.2f * float(y)));
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, grid, Scheme::Smooth, 4).isOk());
    ASSERT_TRUE(plan->setDisplacement(map).isOk());
    const std::vector<glm::vec3> up(grid.positions.size(), glm::vec3(0.0f, 0.0f, 1.0f));
    auto chooser = [&] {
        auto c = std::make_unique<LevelChooser>();
        EXPECT_TRUE(c->init(*plan, nullptr, grid.positions.data(), up.data(), up.size()).isOk());
        return c;
    };
    // An interior vertex slid most of a cell along the grid: its six faces
    // stretch, nothing turns.
    std::vector<glm::vec3> posed = grid.positions;
    posed[size_t(4 * (n + 1) + 4)] += glm::vec3(0.9f / n, 0.6f / n, 0.0f);
    const size_t count = posed.size(), quarters = 4 * grid.faceCount();
    const std::unique_ptr<LevelChooser> asked = chooser();  // every pose in turn
    for (float distance : {3.0f, 6.0f}) {
        const ViewSpec view = viewFrom(glm::vec3(0.2f, 0.3f, distance));
        std::vector<uint8_t> with(quarters), without(quarters), rest(quarters), again(quarters);
        ASSERT_TRUE(chooser()->choose(with.data(), view, 1.0f, posed.data(), count, 1.0f, up.data()).isOk());
        ASSERT_TRUE(chooser()->choose(without.data(), view, 1.0f, posed.data(), count, 1.0f, nullptr).isOk());
        ASSERT_TRUE(chooser()->choose(rest.data(), view, 1.0f, grid.positions.data(), count, 1.0f, up.data()).isOk());
        EXPECT_NE(with, rest) << "eye at " << distance << ": the stretch should change the levels";
        EXPECT_EQ(with, without) << "eye at " << distance;
        ASSERT_TRUE(asked->choose(again.data(), view, 1.0f, posed.data(), count, 1.0f, up.data()).isOk());
        EXPECT_EQ(again, with) << "eye at " << distance;
        ASSERT_TRUE(asked->choose(again.data(), view, 1.0f, grid.positions.data(), count, 1.0f, nullptr).isOk());
        EXPECT_EQ(again, rest) << "eye at " << distance;
    }
}

}  // namespace
}  // namespace strata
