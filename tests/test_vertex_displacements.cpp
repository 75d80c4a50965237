// Displacements stored per refined vertex (vertex_displacements.h): the
// subdivision hierarchy against the refined geometry, the lossless integer
// prediction, the field that carries the values to any level, and the map
// rasterised from them.  Closed forms: edge children are the midpoints of
// their parents on a flat refinement, and linear functions are reproduced
// exactly by linear interpolation.
#include "procedural.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/vertex_displacements.h"
#include "test_grid.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <random>

using namespace strata;

namespace {

std::vector<glm::vec3> flatPositions(const ControlMesh& m, int level)
{
    std::unique_ptr<Plan> plan;
    EXPECT_TRUE(Plan::create(&plan, m, Scheme::Linear, level).isOk());
    std::vector<glm::vec3> normals(m.positions.size()), out(plan->refinedVertexCount());
    computeControlNormals(normals.data(), m.positions.data(), normals.size(), m.triangles.data(), m.faceCount());
    EXPECT_TRUE(plan->evaluate(out.data(), nullptr, 0, out.size(), m.positions.data(), normals.data(), normals.size())
                    .isOk());
    return out;
}

}  // namespace

TEST(VertexDisplacements, EdgeChildrenAreMidpointsAndLevelsArePrefixes)
{
    const ControlMesh mesh = examples::makeIcosphere(1);
    const int L = 4;
    SubdivisionParents h;
    ASSERT_TRUE(buildSubdivisionParents(&h, mesh, L).isOk());
    ASSERT_EQ(h.levelCounts.size(), size_t(L + 1));
    EXPECT_EQ(h.levelCounts[0], mesh.positions.size());
    const std::vector<glm::vec3> fine = flatPositions(mesh, L);
    ASSERT_EQ(fine.size(), h.levelCounts[L]);
    EXPECT_EQ(h.parents.size(), 2 * (fine.size() - mesh.positions.size()));
    // Each level's vertices are the first ones of the finest level.
    for (int l = 0; l < L; ++l) {
        const std::vector<glm::vec3> coarse = flatPositions(mesh, l);
        ASSERT_EQ(coarse.size(), h.levelCounts[size_t(l)]);
        for (size_t v = 0; v < coarse.size(); ++v)
            ASSERT_LT(glm::length(coarse[v] - fine[v]), 1e-6f) << "level " << l << " vertex " << v;
    }
    // Every later vertex is the midpoint of its two parents, which come from
    // an earlier level.
    const size_t base = h.levelCounts[0];
    for (size_t v = base; v < fine.size(); ++v) {
        const uint32_t a = h.parents[2 * (v - base)], b = h.parents[2 * (v - base) + 1];
        size_t level = 0;
        while (v >= h.levelCounts[level])
            ++level;
        ASSERT_LT(a, h.levelCounts[level - 1]);
        ASSERT_LT(b, h.levelCounts[level - 1]);
        ASSERT_LT(glm::length(0.5f * (fine[a] + fine[b]) - fine[v]), 1e-6f) << v;
    }
}

TEST(VertexDisplacements, IntegerPredictionIsLossless)
{
    const ControlMesh mesh = examples::makeIcosphere(0);
    SubdivisionParents h;
    ASSERT_TRUE(buildSubdivisionParents(&h, mesh, 3).isOk());
    const size_t n = h.levelCounts.back();
    std::mt19937 rng(7);
    std::uniform_int_distribution<int32_t> any(0, (1 << 24) - 1);
    std::vector<int32_t> q(n), residuals(n), back(n);
    for (int32_t& x : q)
        x = any(rng);
    predictSubdivisionResiduals(h, q.data(), residuals.data());
    reconstructSubdivisionValues(h, residuals.data(), back.data());
    EXPECT_EQ(q, back);
    // A smooth field predicts well: residuals of a linear function are at
    // most one (the floor of the mean).
    const std::vector<glm::vec3> p = flatPositions(mesh, 3);
    for (size_t v = 0; v < n; ++v)
        q[v] = int32_t(std::lround(4096.0 * (p[v].x + 2.0 * p[v].y + 3.0)));
    predictSubdivisionResiduals(h, q.data(), residuals.data());
    for (size_t v = h.levelCounts[0]; v < n; ++v)
        ASSERT_LE(std::abs(residuals[v]), 1) << v;
}

TEST(VertexDisplacements, FieldReproducesLinearFunctionsAtEveryLevel)
{
    // Values of f(p) = a.p + c at the level-3 vertices of a flat refinement:
    // the field must return f at the refined vertices of every level, the
    // stored ones exactly and the finer ones by linear interpolation.
    const ControlMesh mesh = examples::makeIcosphere(1);
    const glm::vec3 a(0.3f, -0.7f, 0.2f);
    const float c = 0.05f;
    const int stored = 3;
    const std::vector<glm::vec3> at = flatPositions(mesh, stored);
    std::vector<float> values(at.size());
    for (size_t v = 0; v < at.size(); ++v)
        values[v] = glm::dot(a, at[v]) + c;
    DisplacementField field;
    ASSERT_TRUE(DisplacementField::create(&field, mesh, stored, values).isOk());
    for (int level = 0; level <= 5; ++level) {
        std::unique_ptr<Plan> plan;
        ASSERT_TRUE(Plan::create(&plan, mesh, Scheme::Linear, level).isOk());
        ASSERT_TRUE(plan->setDisplacement(field).isOk());
        const std::vector<glm::vec3> p = flatPositions(mesh, level);
        for (size_t v = 0; v < p.size(); ++v) {
            const float expect = level <= stored ? values[v] : glm::dot(a, p[v]) + c;
            ASSERT_NEAR(plan->displacements()[v], expect, 2e-6f) << "level " << level << " vertex " << v;
        }
    }
    // Wrong sizes are refused.
    values.pop_back();
    EXPECT_FALSE(DisplacementField::create(&field, mesh, stored, values).isOk());
}

TEST(VertexDisplacements, RasterisedMapMatchesTheValuesInsideCharts)
{
    // A linear function of UV, stored at level 2 on a grid whose UVs are its
    // positions: every texel centre inside the square holds f(uv) exactly
    // (interpolating a linear function), and the gutter repeats the border.
    const ControlMesh mesh = test::makeGrid(3);
    const int level = 2;
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, mesh, Scheme::Linear, level).isOk());
    auto f = [](glm::vec2 uv) { return 0.25f * uv.x - 0.5f * uv.y + 0.125f; };
    std::vector<float> values(plan->refinedVertexCount());
    std::vector<glm::vec2> sampleUVs;
    plan->sampleUVs(&sampleUVs);
    for (size_t v = 0; v < values.size(); ++v)
        values[v] = f(sampleUVs[v]);
    DisplacementMap map;
    map.width = 37;
    map.height = 29;
    ASSERT_TRUE(rasterizeVertexDisplacements(&map, *plan, values).isOk());
    ASSERT_EQ(map.texels.size(), size_t(37 * 29));
    for (int y = 0; y < map.height; ++y)
        for (int x = 0; x < map.width; ++x) {
            const glm::vec2 uv((float(x) + 0.5f) / float(map.width), (float(y) + 0.5f) / float(map.height));
            ASSERT_NEAR(map.texel(x, y), f(uv), 1e-6f) << x << ", " << y;
        }
    // Sampling it at the vertices gives the values back (bilinear of a
    // linear function), wherever the clamp to the border texels does not reach.
    size_t inside = 0;
    for (size_t v = 0; v < values.size(); ++v) {
        const glm::vec2 uv = sampleUVs[v];
        if (uv.x * 37.0f < 0.5f || uv.x * 37.0f > 36.5f || uv.y * 29.0f < 0.5f || uv.y * 29.0f > 28.5f)
            continue;
        ++inside;
        ASSERT_NEAR(sampleDisplacement(map, uv), values[v], 1e-5f) << v;
    }
    EXPECT_GT(inside, values.size() / 2);
    // A map that does not match the plan is refused.
    values.pop_back();
    EXPECT_FALSE(rasterizeVertexDisplacements(&map, *plan, values).isOk());
}

TEST(VertexDisplacements, RigAppliesItsValuesAtAnyLevel)
{
    Rig rig;
    rig.mesh = test::makeGrid(2);
    rig.hasDisplacement = true;
    rig.displacement.vertexLevel = 1;
    std::unique_ptr<Plan> stored;
    ASSERT_TRUE(Plan::create(&stored, rig.mesh, Scheme::Linear, 1).isOk());
    std::vector<glm::vec2> storedUVs;
    stored->sampleUVs(&storedUVs);
    for (const glm::vec2& uv : storedUVs)
        rig.displacement.vertexValues.push_back(uv.x * uv.y);  // bilinear: not linear inside a cell
    for (int level = 0; level <= 3; ++level) {
        std::unique_ptr<Plan> plan;
        ASSERT_TRUE(Plan::create(&plan, rig.mesh, Scheme::Linear, level).isOk());
        ASSERT_TRUE(applyRigDisplacement(plan.get(), rig, nullptr, 2.0f).isOk());
        std::vector<glm::vec2> uvs;
        plan->sampleUVs(&uvs);
        for (size_t v = 0; v < plan->refinedVertexCount(); ++v) {
            const glm::vec2 uv = uvs[v];
            if (level <= 1)  // the stored vertices: their own value
                ASSERT_NEAR(plan->displacements()[v], 2.0f * uv.x * uv.y, 1e-6f) << level << " " << v;
            else  // between them: within the bilinear's deviation from its interpolant
                ASSERT_NEAR(plan->displacements()[v], 2.0f * uv.x * uv.y, 2.0f * 0.25f * 0.25f) << level << " " << v;
        }
    }
    // A rig that stores a map needs one.
    rig.displacement.vertexLevel = -1;
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, rig.mesh, Scheme::Linear, 1).isOk());
    EXPECT_FALSE(applyRigDisplacement(plan.get(), rig, nullptr).isOk());
}
