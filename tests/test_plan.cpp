// Refinement plans and CPU reconstruction (paper 2.3, 3.1): counts, the
// linear scheme's flatness, the smooth scheme against OpenSubdiv's own limit,
// closed-form displaced surfaces, watertightness across UV seams.
#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/io/mesh_io.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "test_util.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

using namespace strata;

namespace {

std::unique_ptr<Plan> makePlan(const ControlMesh& m, Scheme scheme, int level)
{
    std::unique_ptr<Plan> plan;
    const Status st = Plan::create(&plan, m, scheme, level);
    EXPECT_TRUE(st.isOk()) << st.message();
    return plan;
}

std::vector<glm::vec3> normalsOf(const ControlMesh& m)
{
    std::vector<glm::vec3> n(m.positions.size());
    computeControlNormals(n.data(), m.positions.data(), n.size(), m.triangles.data(), m.faceCount());
    return n;
}

std::vector<glm::vec3> evaluateAll(const Plan& plan, const ControlMesh& m)
{
    const std::vector<glm::vec3> n = normalsOf(m);
    std::vector<glm::vec3> out(plan.refinedVertexCount());
    const Status st = plan.evaluate(out.data(), nullptr, 0, out.size(), m.positions.data(), n.data(), n.size());
    EXPECT_TRUE(st.isOk()) << st.message();
    return out;
}

ControlMesh spotOrSkip(const std::string& path)
{
    ControlMesh m;
    const Status st = io::readObj(path, &m);
    EXPECT_TRUE(st.isOk()) << st.message();
    return m;
}

void checkCounts(const ControlMesh& m)
{
    MeshTopologyStats s = computeTopologyStats(m.triangles.data(), m.faceCount());
    size_t V = s.vertices, E = s.edges, F = m.faceCount();
    size_t UV = m.uvs.size(), EUV = 0;
    if (m.hasUVs())
        EUV = computeTopologyStats(m.uvIndices.data(), m.faceCount()).edges;
    for (int level = 0; level <= 4; ++level) {
        auto plan = makePlan(m, Scheme::Linear, level);
        ASSERT_TRUE(plan);
        EXPECT_EQ(plan->refinedFaceCount(), m.faceCount() << (2 * level)) << "level " << level;
        EXPECT_EQ(plan->refinedVertexCount(), V) << "level " << level;
        std::vector<glm::vec2> uvs;
        std::vector<uint32_t> uvIndices;
        plan->refinedUVs(&uvs, &uvIndices);
        EXPECT_EQ(uvs.size(), UV) << "level " << level;
        EXPECT_EQ(uvIndices.size(), m.hasUVs() ? 3 * plan->refinedFaceCount() : 0u) << "level " << level;
        EXPECT_EQ(plan->refinedTriangles().size(), 3 * plan->refinedFaceCount());
        // One midpoint per edge, 3 new edges inside each face, 4 child faces.
        V += E;
        E = 2 * E + 3 * F;
        if (m.hasUVs()) {
            UV += EUV;
            EUV = 2 * EUV + 3 * F;
        }
        F *= 4;
    }
}

void checkLinearOnControlTriangles(const ControlMesh& m, int maxLevel)
{
    const float tol = 1e-6f * test::boundingBoxDiagonal(m);
    for (int level = 1; level <= maxLevel; ++level) {
        auto plan = makePlan(m, Scheme::Linear, level);
        ASSERT_TRUE(plan);
        const std::vector<glm::vec3> x = evaluateAll(*plan, m);  // zero displacement
        const auto& tri = plan->refinedTriangles();
        float worst = 0.0f;
        for (size_t f = 0; f < plan->refinedFaceCount(); ++f) {
            const size_t parent = f >> (2 * level);
            const glm::vec3 a = m.positions[m.triangles[3 * parent]], b = m.positions[m.triangles[3 * parent + 1]],
                            c = m.positions[m.triangles[3 * parent + 2]];
            for (int k = 0; k < 3; ++k)
                worst = std::max(worst, test::pointTriangleDistance(x[tri[3 * f + k]], a, b, c));
        }
        EXPECT_LE(worst, tol) << "level " << level;
    }
}

// OpenSubdiv's face-varying refinement of the UVs (linear, level by level):
// per refined corner, its value index and value.
void osdFaceVaryingUVs(const ControlMesh& m, int level, std::vector<uint32_t>* ids, std::vector<glm::vec2>* values)
{
    using namespace OpenSubdiv;
    std::vector<int> vpf(m.faceCount(), 3), fv(m.triangles.begin(), m.triangles.end()),
        uvi(m.uvIndices.begin(), m.uvIndices.end());
    Far::TopologyDescriptor desc;
    desc.numVertices = int(m.positions.size());
    desc.numFaces = int(m.faceCount());
    desc.numVertsPerFace = vpf.data();
    desc.vertIndicesPerFace = fv.data();
    Far::TopologyDescriptor::FVarChannel channel;
    channel.numValues = int(m.uvs.size());
    channel.valueIndices = uvi.data();
    desc.numFVarChannels = 1;
    desc.fvarChannels = &channel;
    Sdc::Options opts;
    opts.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    opts.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_ALL);
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    std::unique_ptr<Far::TopologyRefiner> r(Factory::Create(desc, Factory::Options(Sdc::SCHEME_LOOP, opts)));
    Far::TopologyRefiner::UniformOptions uniform(level);
    r->RefineUniform(uniform);
    struct V {
        glm::vec2 p;
        void Clear() { p = glm::vec2(0.0f); }
        void AddWithWeight(const V& s, float w) { p += w * s.p; }
    };
    std::vector<V> src(m.uvs.size());
    for (size_t i = 0; i < m.uvs.size(); ++i)
        src[i].p = m.uvs[i];
    Far::PrimvarRefiner pr(*r);
    for (int l = 1; l <= level; ++l) {
        std::vector<V> dst(size_t(r->GetLevel(l).GetNumFVarValues(0)));
        V* in = src.data();
        V* out = dst.data();
        pr.InterpolateFaceVarying(l, in, out, 0);
        src.swap(dst);
    }
    const Far::TopologyLevel& last = r->GetLevel(level);
    ids->clear();
    for (int f = 0; f < last.GetNumFaces(); ++f)
        for (int c : last.GetFaceFVarValues(f, 0))
            ids->push_back(uint32_t(c));
    values->resize(src.size());
    for (size_t i = 0; i < src.size(); ++i)
        (*values)[i] = src[i].p;
}

// The plan's refined UVs against OpenSubdiv's: the same bits at every corner,
// and the same values shared (a one-to-one map between the two numberings).
void checkUVsAgainstOpenSubdiv(const ControlMesh& m, int maxLevel)
{
    for (int level = 0; level <= maxLevel; ++level) {
        auto plan = makePlan(m, Scheme::Linear, level);
        ASSERT_TRUE(plan);
        std::vector<glm::vec2> uvs, refUVs;
        std::vector<uint32_t> ids, refIds;
        plan->refinedUVs(&uvs, &ids);
        osdFaceVaryingUVs(m, level, &refIds, &refUVs);
        ASSERT_EQ(ids.size(), refIds.size()) << "level " << level;
        ASSERT_EQ(uvs.size(), refUVs.size()) << "level " << level;
        std::vector<uint32_t> toRef(uvs.size(), ~0u), fromRef(refUVs.size(), ~0u);
        size_t differ = 0, unshared = 0;
        for (size_t c = 0; c < ids.size(); ++c) {
            differ += std::memcmp(&uvs[ids[c]], &refUVs[refIds[c]], sizeof(glm::vec2)) != 0;
            uint32_t& a = toRef[ids[c]];
            uint32_t& b = fromRef[refIds[c]];
            unshared += (a != ~0u && a != refIds[c]) || (b != ~0u && b != ids[c]);
            a = refIds[c];
            b = ids[c];
        }
        EXPECT_EQ(differ, 0u) << "level " << level;
        EXPECT_EQ(unshared, 0u) << "level " << level;
        // Each vertex's canonical UV is its first corner's.
        std::vector<uint8_t> seen(plan->refinedVertexCount(), 0);
        std::vector<glm::vec2> sampleUVs;
        plan->sampleUVs(&sampleUVs);
        size_t wrong = 0;
        for (size_t c = 0; c < ids.size(); ++c) {
            const uint32_t v = plan->refinedTriangles()[c];
            if (!seen[v]++)
                wrong += std::memcmp(&sampleUVs[v], &uvs[ids[c]], sizeof(glm::vec2)) != 0;
        }
        EXPECT_EQ(wrong, 0u) << "level " << level;
    }
}

}  // namespace

TEST(Plan, RefinedUVsAreOpenSubdivsFaceVaryingRefinement)
{
    ControlMesh square = examples::makeSquare();  // open: boundary edges
    checkUVsAgainstOpenSubdiv(square, 4);
    ControlMesh atlased = examples::makeIcosphere(1);
    ASSERT_TRUE(baker::buildTriangleAtlas(&atlased, {512, 2}).isOk());
    checkUVsAgainstOpenSubdiv(atlased, 4);  // every edge a UV seam
    // A sphere cut along one meridian: continuous UVs except across the cut.
    ControlMesh sphere = examples::makeIcosphere(2);
    sphere.uvIndices.clear();
    sphere.uvs.clear();
    for (size_t f = 0; f < sphere.faceCount(); ++f) {
        glm::vec3 p[3];
        for (int k = 0; k < 3; ++k)
            p[k] = sphere.positions[sphere.triangles[3 * f + size_t(k)]];
        const bool wraps = (p[0].x < 0.0f || p[1].x < 0.0f || p[2].x < 0.0f) &&
                           (p[0].z * p[1].z < 0.0f || p[1].z * p[2].z < 0.0f || p[2].z * p[0].z < 0.0f);
        for (int k = 0; k < 3; ++k) {
            float u = std::atan2(p[k].z, p[k].x) / 6.2831853f + 0.5f;
            if (wraps && p[k].z < 0.0f)
                u += 1.0f;  // the far side of the cut, as its own UV
            sphere.uvIndices.push_back(uint32_t(sphere.uvs.size()));
            sphere.uvs.emplace_back(u, 0.5f + 0.5f * p[k].y);
        }
    }
    // Weld equal (vertex, UV) corners so the layout is continuous away from the cut.
    std::vector<std::pair<std::pair<uint32_t, std::pair<float, float>>, uint32_t>> keyed;
    for (size_t c = 0; c < sphere.uvIndices.size(); ++c)
        keyed.push_back({{sphere.triangles[c], {sphere.uvs[c].x, sphere.uvs[c].y}}, uint32_t(c)});
    std::sort(keyed.begin(), keyed.end());
    std::vector<glm::vec2> welded;
    for (size_t i = 0; i < keyed.size(); ++i) {
        if (i == 0 || keyed[i].first != keyed[i - 1].first)
            welded.emplace_back(keyed[i].first.second.first, keyed[i].first.second.second);
        sphere.uvIndices[keyed[i].second] = uint32_t(welded.size() - 1);
    }
    sphere.uvs = welded;
    checkUVsAgainstOpenSubdiv(sphere, 4);
}

TEST(Plan, RefinedUVsOnSpotAreOpenSubdivs)
{
    STRATA_REQUIRE_DATA(path, "spot_control_mesh.obj");
    checkUVsAgainstOpenSubdiv(spotOrSkip(path), 3);
}

TEST(Plan, CountsFollowTheSubdivisionFormulas)
{
    checkCounts(examples::makeIcosphere(0));
    ControlMesh square = examples::makeSquare();
    checkCounts(square);  // open mesh: boundary edges split too
    ControlMesh atlased = examples::makeIcosphere(1);
    ASSERT_TRUE(baker::buildTriangleAtlas(&atlased, {512, 2}).isOk());
    checkCounts(atlased);  // every edge a UV seam
}

TEST(Plan, CountsOnSpot)
{
    STRATA_REQUIRE_DATA(path, "spot_control_mesh.obj");
    checkCounts(spotOrSkip(path));
}

TEST(Plan, LinearSchemeStaysOnTheControlTriangles)
{
    checkLinearOnControlTriangles(examples::makeIcosphere(0), 5);
    checkLinearOnControlTriangles(examples::makeSquare(), 5);
}

TEST(Plan, LinearSchemeStaysOnTheControlTrianglesOfSpot)
{
    STRATA_REQUIRE_DATA(path, "spot_control_mesh.obj");
    checkLinearOnControlTriangles(spotOrSkip(path), 5);
}

TEST(Plan, LinearStencilsAreBarycentric)
{
    const ControlMesh m = examples::makeIcosphere(0);
    for (int level = 0; level <= 3; ++level) {
        auto plan = makePlan(m, Scheme::Linear, level);
        Plan::FlatStencils s;
        plan->flattenStencils(&s);
        ASSERT_EQ(s.weightsPerEntry, 1);
        for (size_t v = 0; v < plan->refinedVertexCount(); ++v) {
            ASSERT_EQ(s.offsets[v + 1] - s.offsets[v], 3u);
            float sum = 0.0f;
            for (uint32_t k = s.offsets[v]; k < s.offsets[v + 1]; ++k) {
                EXPECT_GE(s.weights[k], 0.0f);
                sum += s.weights[k];
            }
            EXPECT_NEAR(sum, 1.0f, 1e-6f);
            const SampleLocation loc = plan->sampleLocations()[v];
            EXPECT_GE(loc.bary.x, -1e-7f);
            EXPECT_GE(loc.bary.y, -1e-7f);
            EXPECT_LE(loc.bary.x + loc.bary.y, 1.0f + 1e-6f);
        }
    }
}

namespace {

// OpenSubdiv's own answer for the smooth scheme: refine uniformly with Loop,
// then project the last level's vertices to the limit.
void osdLimit(const ControlMesh& m, int level, std::vector<glm::vec3>* pos, std::vector<glm::vec3>* nrm)
{
    using namespace OpenSubdiv;
    std::vector<int> vpf(m.faceCount(), 3), fv(m.triangles.begin(), m.triangles.end());
    Far::TopologyDescriptor desc;
    desc.numVertices = int(m.positions.size());
    desc.numFaces = int(m.faceCount());
    desc.numVertsPerFace = vpf.data();
    desc.vertIndicesPerFace = fv.data();
    Sdc::Options opts;
    opts.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    std::unique_ptr<Far::TopologyRefiner> r(Factory::Create(desc, Factory::Options(Sdc::SCHEME_LOOP, opts)));
    Far::TopologyRefiner::UniformOptions uniform(level);
    uniform.fullTopologyInLastLevel = true;
    r->RefineUniform(uniform);
    struct V {
        glm::vec3 p;
        void Clear() { p = glm::vec3(0.0f); }
        void AddWithWeight(const V& s, float w) { p += w * s.p; }
    };
    std::vector<V> buf(size_t(r->GetNumVerticesTotal()));
    for (size_t i = 0; i < m.positions.size(); ++i)
        buf[i].p = m.positions[i];
    Far::PrimvarRefiner pr(*r);
    V* src = buf.data();
    for (int l = 1; l <= level; ++l) {
        V* dst = src + r->GetLevel(l - 1).GetNumVertices();
        pr.Interpolate(l, src, dst);
        src = dst;
    }
    const size_t n = size_t(r->GetLevel(level).GetNumVertices());
    std::vector<V> lp(n), du(n), dv(n);
    pr.Limit(src, lp, du, dv);
    pos->resize(n);
    nrm->resize(n);
    for (size_t i = 0; i < n; ++i) {
        (*pos)[i] = lp[i].p;
        (*nrm)[i] = glm::normalize(glm::cross(du[i].p, dv[i].p));
    }
}

void checkSmoothAgainstOpenSubdiv(const ControlMesh& m, int maxLevel, float tolerance)
{
    const float diag = test::boundingBoxDiagonal(m);
    for (int level = 0; level <= maxLevel; ++level) {
        auto plan = makePlan(m, Scheme::Smooth, level);
        ASSERT_TRUE(plan);
        std::vector<glm::vec3> x(plan->refinedVertexCount()), dir(x.size());
        ASSERT_TRUE(plan->evaluate(x.data(), dir.data(), 0, x.size(), m.positions.data(), nullptr, m.positions.size())
                        .isOk());
        std::vector<glm::vec3> ref, refN;
        osdLimit(m, level, &ref, &refN);
        ASSERT_EQ(ref.size(), x.size());
        float worst = 0.0f, worstAngle = 1.0f;
        for (size_t v = 0; v < x.size(); ++v) {
            worst = std::max(worst, glm::length(x[v] - ref[v]));
            worstAngle = std::min(worstAngle, glm::dot(dir[v], refN[v]));
        }
        EXPECT_LE(worst, tolerance * diag) << "level " << level;
        EXPECT_GT(worstAngle, 0.999f) << "level " << level;
    }
}

}  // namespace

TEST(Plan, SmoothSchemeMatchesOpenSubdivLimit)
{
    checkSmoothAgainstOpenSubdiv(examples::makeIcosphere(0), 4, 1e-5f);
    checkSmoothAgainstOpenSubdiv(examples::makeSquare(), 3, 1e-5f);
}

TEST(Plan, SmoothSchemeMatchesOpenSubdivLimitOnSpot)
{
    STRATA_REQUIRE_DATA(path, "spot_control_mesh.obj");
    checkSmoothAgainstOpenSubdiv(spotOrSkip(path), 3, 1e-5f);
}

TEST(Reconstruction, IcosahedronAndSphereMapGiveTheSphere)
{
    ControlMesh m = examples::makeIcosphere(0);
    const int size = 512, gutter = 2;
    ASSERT_TRUE(baker::buildTriangleAtlas(&m, {size, gutter}).isOk());
    DisplacementMap map;
    ASSERT_TRUE(examples::bakeRadialSurface(&map, m, size, gutter, [](const glm::vec3&) { return 1.0f; }).isOk());
    // Bilinear interpolation of a function with second derivatives bounded
    // by K on a grid of spacing h errs by at most h^2 (|fxx| + |fyy| + 2|fxy|) / 8
    // <= K h^2 / 2.  Here h is the largest model-space texel: a chart cell is
    // size/4 texels for 10 cells and each right-triangle chart has legs of
    // cell - 4 * gutter texels for an icosahedron edge.  d(p) solves
    // |p + d n| = 1 with |n| >= 0.79 on the inscribed faces, which bounds its
    // second derivatives by K = 4.
    const float edge = glm::length(m.positions[m.triangles[0]] - m.positions[m.triangles[1]]);
    const float h = edge / float(size / 4 - 4 * gutter);
    const float bound = 4.0f * h * h / 2.0f;
    for (int level = 0; level <= 5; ++level) {
        auto plan = makePlan(m, Scheme::Linear, level);
        ASSERT_TRUE(plan->setDisplacement(map).isOk());
        const std::vector<glm::vec3> x = evaluateAll(*plan, m);
        float worst = 0.0f;
        for (const glm::vec3& p : x)
            worst = std::max(worst, std::fabs(glm::length(p) - 1.0f));
        EXPECT_LE(worst, bound) << "level " << level;
    }
}

TEST(Reconstruction, FlatSquareWithSineMapGivesTheSine)
{
    const ControlMesh m = examples::makeSquare();
    const int size = 256;
    const float amplitude = 0.05f, twoPiK = 2.0f * float(M_PI) * 3.0f;
    DisplacementMap map;
    map.width = map.height = size;
    map.texels.resize(size_t(size) * size);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x)
            map.texels[size_t(y) * size + size_t(x)] = amplitude * std::sin(twoPiK * (float(x) + 0.5f) / float(size));
    const float h = 1.0f / float(size);
    const float interior = amplitude * twoPiK * twoPiK * h * h / 8.0f + 1e-6f;  // bilinear bound
    const float border = amplitude * twoPiK * h / 2.0f + 1e-6f;                 // clamp-to-edge half texel
    for (int level = 0; level <= 6; ++level) {
        auto plan = makePlan(m, Scheme::Linear, level);
        ASSERT_TRUE(plan->setDisplacement(map).isOk());
        const std::vector<glm::vec3> x = evaluateAll(*plan, m);
        for (const glm::vec3& p : x) {
            const float expected = amplitude * std::sin(twoPiK * p.x);
            const bool nearBorder = p.x < 0.5f * h || p.x > 1.0f - 0.5f * h;
            ASSERT_LE(std::fabs(p.z - expected), nearBorder ? border : interior) << "level " << level << " x " << p.x;
        }
    }
}

TEST(Reconstruction, WatertightAcrossUVSeamsOnSpot)
{
    STRATA_REQUIRE_DATA(path, "spot_control_mesh.obj");
    Rig rig;
    rig.mesh = spotOrSkip(path);
    ASSERT_TRUE(rig.mesh.hasUVs());
    const MeshTopologyStats control = computeTopologyStats(rig.mesh.triangles.data(), rig.mesh.faceCount());
    // Noise in the map: both sides of every seam read unrelated texels, so
    // any per-corner sampling would open cracks.
    DisplacementMap map;
    map.width = map.height = 256;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> noise(-0.02f, 0.02f);
    map.texels.resize(256 * 256);
    for (float& t : map.texels)
        t = noise(rng);
    const std::string dir = test::tempDir("watertight");
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        for (int level = 0; level <= (scheme == Scheme::Linear ? 5 : 3); ++level) {
            io::Reconstruction rec;
            ASSERT_TRUE(io::reconstruct(&rec, rig, &map, scheme, level).isOk());
            // Through a file with split vertices, as any consumer sees it, then
            // welded again by exact position.
            const std::string out = dir + "/spot.glb";
            ASSERT_TRUE(io::writeReconstruction(out, rec).isOk());
            Rig back;
            const Status st = io::loadRig(out, &back);
            ASSERT_TRUE(st.isOk()) << st.message();
            EXPECT_EQ(back.mesh.positions.size(), rec.positions.size()) << "level " << level;
            const MeshTopologyStats s = computeTopologyStats(back.mesh.triangles.data(), back.mesh.faceCount());
            EXPECT_EQ(s.eulerCharacteristic, control.eulerCharacteristic) << "level " << level;
            EXPECT_EQ(s.boundaryEdges, control.boundaryEdges << level) << "level " << level;
            EXPECT_EQ(s.nonManifoldEdges, 0u);
        }
    }
}

TEST(Reconstruction, OpenBoundaryKeepsItsBoundary)
{
    // The square is open: 4 boundary edges, Euler characteristic 1.
    Rig rig;
    rig.mesh = examples::makeSquare();
    for (int level = 0; level <= 4; ++level) {
        io::Reconstruction rec;
        ASSERT_TRUE(io::reconstruct(&rec, rig, nullptr, Scheme::Linear, level).isOk());
        const auto& t = rec.plan().refinedTriangles();
        const MeshTopologyStats s = computeTopologyStats(t.data(), t.size() / 3);
        EXPECT_EQ(s.boundaryEdges, 4u << level);
        EXPECT_EQ(s.eulerCharacteristic, 1);
    }
}

TEST(Plan, RejectsBadArgumentsWithStatus)
{
    const ControlMesh m = examples::makeIcosphere(0);
    std::unique_ptr<Plan> plan;
    EXPECT_FALSE(Plan::create(&plan, m, Scheme::Linear, -1).isOk());
    EXPECT_FALSE(Plan::create(&plan, m, Scheme::Linear, kMaxLevel + 1).isOk());
    EXPECT_FALSE(plan);
    ASSERT_TRUE(Plan::create(&plan, m, Scheme::Linear, 2).isOk());
    const std::vector<glm::vec3> n = normalsOf(m);
    std::vector<glm::vec3> out(plan->refinedVertexCount());
    Status st = plan->evaluate(out.data(), nullptr, 0, out.size(), m.positions.data(), n.data(), 5);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("control vertices"), std::string::npos) << st.message();
    EXPECT_FALSE(plan->evaluate(out.data(), nullptr, 0, out.size() + 1, m.positions.data(), n.data(), 12).isOk());
    EXPECT_FALSE(plan->evaluate(out.data(), nullptr, 0, out.size(), m.positions.data(), nullptr, 12).isOk());
    // A range evaluation equals the matching slice of a full one.
    std::vector<glm::vec3> part(10);
    ASSERT_TRUE(plan->evaluate(part.data(), nullptr, 20, 30, m.positions.data(), n.data(), 12).isOk());
    ASSERT_TRUE(plan->evaluate(out.data(), nullptr, 0, out.size(), m.positions.data(), n.data(), 12).isOk());
    for (int i = 0; i < 10; ++i)
        EXPECT_EQ(part[size_t(i)], out[size_t(20 + i)]);
    // No UVs: no map can be applied.
    DisplacementMap map;
    map.width = map.height = 2;
    map.texels.assign(4, 0.0f);
    EXPECT_FALSE(plan->setDisplacement(map).isOk());
}

TEST(Plan, RejectsBadControlMeshes)
{
    std::unique_ptr<Plan> plan;
    ControlMesh empty;
    EXPECT_FALSE(Plan::create(&plan, empty, Scheme::Linear, 1).isOk());

    ControlMesh nan = examples::makeIcosphere(0);
    nan.positions[3].y = std::nanf("");
    Status st = Plan::create(&plan, nan, Scheme::Linear, 1);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("vertex 3"), std::string::npos) << st.message();

    ControlMesh repeated = examples::makeSquare();
    repeated.triangles[1] = repeated.triangles[0];
    EXPECT_FALSE(Plan::create(&plan, repeated, Scheme::Linear, 1).isOk());

    ControlMesh range = examples::makeSquare();
    range.triangles[2] = 99;
    EXPECT_FALSE(Plan::create(&plan, range, Scheme::Smooth, 1).isOk());

    EXPECT_FALSE(plan);
}

// One plan shared by two characters with the same control topology: each
// keeps only its own displacements, and evaluating through the shared,
// untouched plan gives what a plan of its own gives.
TEST(Plan, OneSharedPlanServesTwoCharacters)
{
    ControlMesh m = examples::makeIcosphere(1);
    ASSERT_TRUE(baker::buildTriangleAtlas(&m, {256, 2}).isOk());
    DisplacementMap a, b;
    a.width = a.height = b.width = b.height = 64;
    for (int i = 0; i < 64 * 64; ++i) {
        a.texels.push_back(0.05f * std::sin(0.1f * float(i)));
        b.texels.push_back(-0.02f * std::cos(0.07f * float(i)));
    }
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        const auto shared = makePlan(m, scheme, 3);
        const size_t n = shared->refinedVertexCount();
        std::vector<float> da(n), db(n);
        ASSERT_TRUE(sampleDisplacements(da.data(), *shared, a).isOk());
        ASSERT_TRUE(sampleDisplacements(db.data(), *shared, b, 2.0f).isOk());
        const std::vector<glm::vec3> normals = normalsOf(m);
        for (int which = 0; which < 2; ++which) {
            auto own = makePlan(m, scheme, 3);
            ASSERT_TRUE(own->setDisplacement(which ? b : a, which ? 2.0f : 1.0f).isOk());
            std::vector<glm::vec3> viaShared(n), viaOwn(n);
            ASSERT_TRUE(shared->evaluate(viaShared.data(), nullptr, 0, n, which ? db.data() : da.data(),
                                         m.positions.data(), normals.data(), normals.size())
                            .isOk());
            ASSERT_TRUE(own->evaluate(viaOwn.data(), nullptr, 0, n, m.positions.data(), normals.data(), normals.size())
                            .isOk());
            EXPECT_EQ(viaShared, viaOwn) << schemeName(scheme) << " character " << which;
        }
        // The shared plan's own displacements were never touched.
        EXPECT_EQ(shared->displacements(), std::vector<float>(n, 0.0f));
    }
}
