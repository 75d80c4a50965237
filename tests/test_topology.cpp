// General control topology (issue 10): the cases a subdivision regression
// suite holds must refine in both schemes, not be refused.  An edge shared
// by many faces, a non-manifold vertex, inconsistent orientation, a face
// that repeats a vertex, unreferenced vertices and valence-2 interior
// vertices.  Each is checked for the things that hold in closed form:
// refined counts, linear vertices on their control faces, boundary and
// non-manifold edges multiplied by 2^level (watertight where the input is),
// and separate components staying separate.
#include "procedural.h"
#ifdef STRATA_HAVE_IO
#include "strata/io/mesh_io.h"
#endif
#include "strata/normals.h"
#include "strata/plan.h"
#include "test_util.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>

using namespace strata;

namespace {

// Connected components of the faces' vertex graph (union-find over faces).
size_t componentCount(const std::vector<uint32_t>& triangles, size_t vertexCount)
{
    std::vector<uint32_t> parent(vertexCount);
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](uint32_t v) {
        while (parent[v] != v)
            v = parent[v] = parent[parent[v]];
        return v;
    };
    std::vector<bool> used(vertexCount, false);
    for (size_t i = 0; i < triangles.size(); i += 3)
        for (int c = 0; c < 3; ++c) {
            used[triangles[i + size_t(c)]] = true;
            const uint32_t a = find(triangles[i + size_t(c)]), b = find(triangles[i + size_t((c + 1) % 3)]);
            if (a != b)
                parent[a] = b;
        }
    size_t n = 0;
    for (uint32_t v = 0; v < vertexCount; ++v)
        n += used[v] && find(v) == v;
    return n;
}

// Refines m in both schemes at levels 0..3 and checks what is known.
// Edge statistics key edges by their vertex pair, so they only apply when
// no two faces share all three vertices (the pillow below does).
void checkRefines(const ControlMesh& m, const char* what, bool edgeStats = true)
{
    const MeshTopologyStats s0 = computeTopologyStats(m.triangles.data(), m.faceCount());
    const size_t comps0 = componentCount(m.triangles, m.positions.size());
    std::vector<glm::vec3> n(m.positions.size());
    computeControlNormals(n.data(), m.positions.data(), n.size(), m.triangles.data(), m.faceCount());
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth})
        for (int level = 0; level <= 3; ++level) {
            SCOPED_TRACE(std::string(what) + " " + schemeName(scheme) + " level " + std::to_string(level));
            std::unique_ptr<Plan> plan;
            const Status st = Plan::create(&plan, m, scheme, level);
            ASSERT_TRUE(st.isOk()) << st.message();
            ASSERT_EQ(plan->refinedFaceCount(), m.faceCount() << (2 * level));
            const MeshTopologyStats s = computeTopologyStats(plan->refinedTriangles().data(), plan->refinedFaceCount());
            if (edgeStats) {
                EXPECT_EQ(s.boundaryEdges, s0.boundaryEdges << level);
                EXPECT_EQ(s.nonManifoldEdges, s0.nonManifoldEdges << level);
                EXPECT_EQ(s.eulerCharacteristic, s0.eulerCharacteristic);
            }
            EXPECT_EQ(componentCount(plan->refinedTriangles(), plan->refinedVertexCount()), comps0);
            std::vector<glm::vec3> out(plan->refinedVertexCount());
            ASSERT_TRUE(plan->evaluate(out.data(), nullptr, 0, out.size(), m.positions.data(), n.data(), n.size()).isOk());
            for (size_t v = 0; v < out.size(); ++v)
                ASSERT_TRUE(std::isfinite(out[v].x) && std::isfinite(out[v].y) && std::isfinite(out[v].z)) << v;
            if (scheme != Scheme::Linear)
                continue;
            // Linear: each refined vertex is the barycentric point of its sample.
            for (size_t v = 0; v < out.size(); ++v) {
                const SampleLocation& sl = plan->sampleLocations()[v];
                if (sl.face == kNoControlFace)
                    continue;
                const uint32_t* t = &m.triangles[3 * size_t(sl.face)];
                const glm::vec3 p = (1.0f - sl.bary.x - sl.bary.y) * m.positions[t[0]] +
                                    sl.bary.x * m.positions[t[1]] + sl.bary.y * m.positions[t[2]];
                ASSERT_LT(glm::length(out[v] - p), 1e-5f) << v;
            }
        }
}

// A "book": `pages` triangles all sharing the edge (0, 1), fanned around it.
ControlMesh makeBook(int pages)
{
    ControlMesh m;
    m.positions = {{0, 0, 0}, {0, 0, 1}};
    for (int p = 0; p < pages; ++p) {
        const float a = 6.2831853f * float(p) / float(pages);
        m.positions.push_back({std::cos(a), std::sin(a), 0.5f});
        m.triangles.insert(m.triangles.end(), {0u, 1u, uint32_t(2 + p)});
    }
    return m;
}

}  // namespace

TEST(Topology, EdgeSharedByHundredFaces)
{
    const ControlMesh m = makeBook(100);
    EXPECT_EQ(computeTopologyStats(m.triangles.data(), m.faceCount()).nonManifoldEdges, 1u);
    checkRefines(m, "book of 100");
}

TEST(Topology, FinOnAClosedSurface)
{
    ControlMesh m = examples::makeIcosphere(1);
    m.uvs.clear();
    m.uvIndices.clear();
    const uint32_t a = m.triangles[0], b = m.triangles[1];
    m.positions.push_back(2.0f * (m.positions[a] + m.positions[b]));
    m.triangles.insert(m.triangles.end(), {b, a, uint32_t(m.positions.size() - 1)});
    checkRefines(m, "fin");
}

TEST(Topology, NonManifoldVertexJoiningTwoCones)
{
    // Two closed tetrahedra touching at one vertex (0).
    ControlMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3f, 0.3f, 1}, {-1, 0, 0}, {0, -1, 0}, {-0.3f, -0.3f, -1}};
    m.triangles = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3, 0, 4, 5, 0, 6, 4, 4, 6, 5, 5, 6, 0};
    checkRefines(m, "bowtie");
}

TEST(Topology, InconsistentOrientation)
{
    ControlMesh m = examples::makeSquare();
    std::swap(m.triangles[4], m.triangles[5]);
    checkRefines(m, "flipped face");
}

TEST(Topology, UnreferencedVerticesAndValenceTwo)
{
    // A square of two triangles plus two vertices no face uses.
    ControlMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {9, 9, 9}, {-9, 9, 9}};
    m.triangles = {0, 1, 2, 0, 2, 3};
    checkRefines(m, "unreferenced");
    // Valence-2 interior vertices: two triangles glued along all three
    // edges (a "pillow"), every vertex interior with two faces.
    ControlMesh pillow;
    pillow.positions = {{0, 0, 0}, {1, 0, 0}, {0.5f, 1, 0}};
    pillow.triangles = {0, 1, 2, 0, 2, 1};
    checkRefines(pillow, "pillow", /*edgeStats=*/false);
}

TEST(Topology, UnreferencedVertexHasNoDisplacement)
{
    ControlMesh m = examples::makeSquare();
    m.positions.push_back({5, 5, 5});
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, m, Scheme::Linear, 2).isOk());
    DisplacementMap map;
    map.width = map.height = 2;
    map.texels.assign(4, 1.0f);
    ASSERT_TRUE(plan->setDisplacement(map).isOk());
    size_t isolated = 0;
    for (size_t v = 0; v < plan->refinedVertexCount(); ++v)
        if (plan->sampleLocations()[v].face == kNoControlFace) {
            ++isolated;
            EXPECT_EQ(plan->displacements()[v], 0.0f);
        }
    EXPECT_EQ(isolated, 1u);
}

#ifdef STRATA_HAVE_IO
TEST(Topology, ObjFaceRepeatingAVertexIsDroppedAndCounted)
{
    const std::string path = std::string(STRATA_TEST_TMP) + "/repeat.obj";
    {
        std::ofstream f(path);
        f << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\nf 1 1 2\nf 2 3 3 # comment\n";
    }
    ControlMesh m;
    io::ObjReadInfo info;
    const Status st = io::readObj(path, &m, &info);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(m.faceCount(), 2u);
    EXPECT_EQ(info.degenerate, 2u);
    checkRefines(m, "repeated vertex");
}
#endif  // STRATA_HAVE_IO

// groupEdges, the one home of edge adjacency: a tetrahedron's six edges
// each with two opposite corners; a fin's edge with three; an open
// triangle's three edges with one; edges in (lower, higher) order and
// every corner once; sparse vertex numbers grouped the same way.
TEST(Topology, EdgeGroupsOfClosedOpenAndNonManifoldMeshes)
{
    const std::vector<uint32_t> tet = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
    const EdgeGroups g = groupEdges(tet.data(), 4);
    ASSERT_EQ(g.edgeCount(), 6u);
    std::vector<uint32_t> seen;
    std::pair<uint32_t, uint32_t> previous(0, 0);
    for (size_t e = 0; e < g.edgeCount(); ++e) {
        ASSERT_EQ(g.faceCountOf(e), 2u);
        const uint32_t c0 = g.cornersOf(e)[0], c1 = g.cornersOf(e)[1];
        EXPECT_LT(c0, c1);
        // The two corners run the edge in opposite directions.
        EXPECT_EQ(tet[c0], tet[c1 / 3 * 3 + (c1 % 3 + 1) % 3]);
        EXPECT_EQ(tet[c1], tet[c0 / 3 * 3 + (c0 % 3 + 1) % 3]);
        const std::pair<uint32_t, uint32_t> key(std::min(tet[c0], tet[c1]), std::max(tet[c0], tet[c1]));
        if (e > 0) {
            EXPECT_LT(previous, key);
        }
        previous = key;
        seen.insert(seen.end(), {c0, c1});
    }
    std::sort(seen.begin(), seen.end());
    std::vector<uint32_t> all(12);
    std::iota(all.begin(), all.end(), 0u);
    EXPECT_EQ(seen, all);

    const std::vector<uint32_t> fin = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    const EdgeGroups f = groupEdges(fin.data(), 3);
    size_t three = 0, one = 0;
    for (size_t e = 0; e < f.edgeCount(); ++e) {
        three += f.faceCountOf(e) == 3;
        one += f.faceCountOf(e) == 1;
    }
    EXPECT_EQ(three, 1u);
    EXPECT_EQ(one, 6u);
    EXPECT_EQ(f.edgeCount(), 7u);

    const std::vector<uint32_t> sparse = {7, 4000000000u, 123456789u};
    const EdgeGroups s = groupEdges(sparse.data(), 1);
    ASSERT_EQ(s.edgeCount(), 3u);
    for (size_t e = 0; e < 3; ++e)
        EXPECT_EQ(s.faceCountOf(e), 1u);
    const MeshTopologyStats stats = computeTopologyStats(sparse.data(), 1);
    EXPECT_EQ(stats.vertices, 3u);
    EXPECT_EQ(stats.boundaryEdges, 3u);
    EXPECT_EQ(groupEdges(nullptr, 0).edgeCount(), 0u);
}
