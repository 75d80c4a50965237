// Applying a rig's displacement to a plan, whichever way the rig stores it.
#include "strata/rig.h"
#include "strata/uv_raster.h"

#include "strata/vertex_displacements.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace strata {

Status applyRigDisplacement(Plan* plan, const Rig& rig, const DisplacementMap* map, float scale)
{
    if (!plan)
        return Status(StatusCode::InvalidArgument, "applyRigDisplacement: no plan");
    const DisplacementInfo& info = rig.displacement;
    // The displacements belong to one surface: the rig's control mesh, in the
    // scheme it was baked against.  Any other plan would draw another surface.
    if (rig.hasDisplacement && plan->scheme() != info.scheme)
        return Status(StatusCode::InvalidArgument,
                      std::string("the plan uses the ") + schemeName(plan->scheme()) +
                          " scheme but the rig was baked against the " + schemeName(info.scheme) +
                          " scheme: build the plan with rig.displacement.scheme");
    if (plan->controlVertexCount() != rig.mesh.vertexCount() ||
        plan->controlTopologyHash() != controlTopologyHash(rig.mesh.triangles.data(), rig.mesh.faceCount(),
                                                           rig.mesh.vertexCount()))
        return Status(StatusCode::InvalidArgument, "the plan was built from another control mesh than the rig's "
                                                   "(other vertices or triangles): build it from rig.mesh");
    if (rig.hasDisplacement && info.vertexLevel >= 0) {
        DisplacementField field;
        Status st = DisplacementField::create(&field, rig.mesh, info.vertexLevel, info.vertexValues);
        if (!st)
            return st;
        return plan->setDisplacement(field, scale);
    }
    if (!map || map->texels.empty())
        return Status(StatusCode::InvalidArgument, "the rig stores a displacement map and none was given");
    return plan->setDisplacement(*map, scale);
}

Status rasterizeVertexDisplacements(DisplacementMap* map, const Plan& plan, const std::vector<float>& values)
{
    const int w = map->width, h = map->height;
    if (w < 1 || h < 1 || w > kMaxDisplacementMapSize || h > kMaxDisplacementMapSize)
        return Status(StatusCode::InvalidArgument, "map size " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " is invalid");
    if (values.size() != plan.refinedVertexCount() || !plan.hasUVs())
        return Status(StatusCode::InvalidArgument, "rasterizeVertexDisplacements: values or UVs do not match the plan");
    const size_t texels = size_t(w) * size_t(h);
    std::vector<float> value(texels, 0.0f);
    std::vector<uint8_t> covered(texels, 0);
    const std::vector<uint32_t>& tri = plan.refinedTriangles();
    std::vector<glm::vec2> uvs;
    std::vector<uint32_t> uvIndex;
    plan.refinedUVs(&uvs, &uvIndex);
    for (size_t f = 0; f < plan.refinedFaceCount(); ++f) {
        glm::vec2 uv[3];
        double d[3];
        for (int k = 0; k < 3; ++k) {
            uv[k] = uvs[uvIndex[3 * f + size_t(k)]];
            d[k] = values[tri[3 * f + size_t(k)]];
        }
        forEachTexelInUVTriangle(uv, w, h, [&](int x, int y, double b0, double b1, double b2) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            value[i] = float(b0 * d[0] + b1 * d[1] + b2 * d[2]);
            covered[i] = 1;
        });
    }
    // Gutters: two rings of texels around every chart take the mean of their
    // covered neighbours, so bilinear reads at a chart's edge stay inside it.
    for (int ring = 0; ring < 2; ++ring) {
        std::vector<uint8_t> next = covered;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const size_t i = size_t(y) * size_t(w) + size_t(x);
                if (covered[i])
                    continue;
                double sum = 0.0;
                int n = 0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                            continue;
                        const size_t j = size_t(yy) * size_t(w) + size_t(xx);
                        if (covered[j]) {
                            sum += value[j];
                            ++n;
                        }
                    }
                if (n) {
                    value[i] = float(sum / n);
                    next[i] = 1;
                }
            }
        covered.swap(next);
    }
    map->texels = std::move(value);
    map->factor = 1.0f;
    map->offset = 0.0f;
    return Status::ok();
}

}  // namespace strata
