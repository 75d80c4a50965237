// The bake pipeline (paper 2.1-2.3, 3.2): map vertices, rasterise, dilate.
#include "strata/baker/bake.h"

#include "strata/baker/dilate.h"
#include "strata/baker/distance.h"
#include "strata/baker/fill.h"
#include "strata/baker/mapping.h"
#include "strata/baker/surface.h"
#include "strata/normals.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace strata {
namespace baker {
namespace {

double msSince(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

double medianEdgeLength(const TriangleMesh& mesh)
{
    std::vector<float> len;
    len.reserve(mesh.triangles.size());
    for (size_t f = 0; f < mesh.faceCount(); ++f)
        for (int k = 0; k < 3; ++k) {
            const float l = glm::length(mesh.positions[mesh.triangles[3 * f + k]] -
                                        mesh.positions[mesh.triangles[3 * f + (k + 1) % 3]]);
            if (l > 0.0f)
                len.push_back(l);
        }
    if (len.empty())
        return 0.0;
    std::nth_element(len.begin(), len.begin() + long(len.size() / 2), len.end());
    return double(len[len.size() / 2]);
}

int chooseMapSize(const ControlMesh& control, double typicalEdge, int maxSize, std::string* reason)
{
    double a3 = 0.0, auv = 0.0;
    for (size_t f = 0; f < control.faceCount(); ++f) {
        const glm::vec3 p0 = control.positions[control.triangles[3 * f]], p1 = control.positions[control.triangles[3 * f + 1]],
                        p2 = control.positions[control.triangles[3 * f + 2]];
        a3 += 0.5 * double(glm::length(glm::cross(p1 - p0, p2 - p0)));
        const glm::vec2 u0 = control.uvs[control.uvIndices[3 * f]], u1 = control.uvs[control.uvIndices[3 * f + 1]],
                        u2 = control.uvs[control.uvIndices[3 * f + 2]];
        auv += 0.5 * std::fabs(double((u1 - u0).x * (u2 - u0).y - (u1 - u0).y * (u2 - u0).x));
    }
    int size = 64;
    if (typicalEdge > 0.0 && auv > 0.0) {
        const double ideal = std::sqrt(a3 / auv) / typicalEdge;
        while (size < maxSize && double(size) < ideal)
            size *= 2;
        if (reason) {
            char buf[256];
            std::snprintf(buf, sizeof(buf),
                          "texel ~ typical high-res edge %.3g: ideal side %.0f texels -> %d (power of two, cap %d)",
                          typicalEdge, ideal, size, maxSize);
            *reason = buf;
        }
    }
    return std::min(size, maxSize);
}

Status checkUVs(const ControlMesh& control, int size)
{
    if (!control.hasUVs())
        return Status(StatusCode::InvalidArgument, "the control mesh has no UVs");
    for (size_t i = 0; i < control.uvIndices.size(); ++i) {
        const glm::vec2 uv = control.uvs[control.uvIndices[i]];
        if (uv.x < 0.0f || uv.y < 0.0f || uv.x > 1.0f || uv.y > 1.0f)
            return Status(StatusCode::InvalidData, "control triangle " + std::to_string(i / 3) + " has a UV (" +
                                                       std::to_string(uv.x) + ", " + std::to_string(uv.y) +
                                                       ") outside [0, 1]");
    }
    // Rasterise every UV triangle with a fill rule; a texel claimed twice is
    // an overlap.  Using the rasteriser's own edge rule via a one-layer bake
    // surface keeps the two consistent.
    std::vector<int32_t> owner(size_t(size) * size_t(size), -1);
    for (size_t f = 0; f < control.faceCount(); ++f) {
        glm::dvec2 t[3];
        for (int k = 0; k < 3; ++k)
            t[k] = glm::dvec2(control.uvs[control.uvIndices[3 * f + k]]) * double(size);
        double area = (t[1].x - t[0].x) * (t[2].y - t[0].y) - (t[1].y - t[0].y) * (t[2].x - t[0].x);
        if (area < 0.0) {
            std::swap(t[1], t[2]);
            area = -area;
        }
        if (!(area > 0.0))
            continue;
        const TexelRect r = texelRect(t, size);
        for (int y = r.y0; y <= r.y1; ++y)
            for (int x = r.x0; x <= r.x1; ++x) {
                const glm::dvec2 c(x + 0.5, y + 0.5);
                // Strictly inside by more than a hundredth of a texel: shared
                // edges and vertices never count as overlap.
                bool in = true;
                for (int k = 0; k < 3 && in; ++k) {
                    const glm::dvec2 a = t[k], b = t[(k + 1) % 3];
                    const double e = ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)) / glm::length(b - a);
                    in = e > 0.01;
                }
                if (!in)
                    continue;
                int32_t& o = owner[size_t(y) * size_t(size) + size_t(x)];
                if (o >= 0)
                    return Status(StatusCode::InvalidData, "control triangles " + std::to_string(o) + " and " +
                                                               std::to_string(f) +
                                                               " overlap in UV space (fix the UVs, or bake with --uv auto)");
                o = int32_t(f);
            }
    }
    return Status::ok();
}

bool fitUVsToUnitSquare(ControlMesh* control, std::string* note)
{
    glm::vec2 lo(1e30f), hi(-1e30f);
    for (uint32_t i : control->uvIndices) {
        lo = glm::min(lo, control->uvs[i]);
        hi = glm::max(hi, control->uvs[i]);
    }
    if (lo.x >= 0.0f && lo.y >= 0.0f && hi.x <= 1.0f && hi.y <= 1.0f)
        return false;
    const float extent = std::max(hi.x - lo.x, hi.y - lo.y);
    const float scale = extent > 0.0f ? 1.0f / extent : 1.0f;
    for (glm::vec2& uv : control->uvs)
        uv = glm::clamp((uv - lo) * scale, glm::vec2(0.0f), glm::vec2(1.0f));
    if (note) {
        char buf[200];
        std::snprintf(buf, sizeof(buf), "UVs spanned [%.4g, %.4g] x [%.4g, %.4g]; rescaled by %.4g to fit [0, 1]",
                      double(lo.x), double(hi.x), double(lo.y), double(hi.y), double(scale));
        *note = buf;
    }
    return true;
}

Status checkHighMesh(const TriangleMesh& high)
{
    if (high.positions.empty() || high.triangles.empty())
        return Status(StatusCode::InvalidData, "the high-resolution mesh has no triangles");
    for (size_t i = 0; i < high.positions.size(); ++i) {
        const glm::vec3& p = high.positions[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            return Status(StatusCode::InvalidData, "high-resolution vertex " + std::to_string(i) + " is not finite");
    }
    bool anyArea = false;
    for (size_t f = 0; f < high.faceCount(); ++f) {
        const uint32_t a = high.triangles[3 * f], b = high.triangles[3 * f + 1], c = high.triangles[3 * f + 2];
        if (a >= high.positions.size() || b >= high.positions.size() || c >= high.positions.size())
            return Status(StatusCode::InvalidData, "high-resolution triangle " + std::to_string(f) +
                                                       " references a missing vertex");
        const glm::vec3 n = glm::cross(high.positions[b] - high.positions[a], high.positions[c] - high.positions[a]);
        anyArea = anyArea || glm::dot(n, n) > 0.0f;
    }
    if (!anyArea)
        return Status(StatusCode::InvalidData, "every high-resolution triangle is degenerate");
    return Status::ok();
}

Status bake(DisplacementMap* out, std::vector<uint16_t>* layersOut, BakeReport* report, const ControlMesh& control,
            const TriangleMesh& high, const BakeOptions& options)
{
    Status st = checkHighMesh(high);
    if (!st)
        return st;
    BakeReport rep;
    rep.highVertices = high.positions.size();
    rep.highTriangles = high.faceCount();
    rep.controlTriangles = control.faceCount();
    rep.typicalEdge = medianEdgeLength(high);
    Box hb, cb;
    for (const glm::vec3& p : high.positions)
        hb.extend(p);
    for (const glm::vec3& p : control.positions)
        cb.extend(p);
    rep.diagonal = glm::length(glm::dvec3(hb.hi - hb.lo));
    // Far apart: the boxes do not even overlap (allowing 10% slack).
    const glm::vec3 slack = 0.1f * (hb.hi - hb.lo);
    if (hb.hi.x + slack.x < cb.lo.x || cb.hi.x + slack.x < hb.lo.x || hb.hi.y + slack.y < cb.lo.y ||
        cb.hi.y + slack.y < hb.lo.y || hb.hi.z + slack.z < cb.lo.z || cb.hi.z + slack.z < hb.lo.z)
        return Status(StatusCode::InvalidData, "the control mesh does not overlap the high-resolution mesh");

    rep.size = options.size > 0 ? options.size
                                : chooseMapSize(control, rep.typicalEdge, options.maxSize, &rep.sizeReason);
    if (options.size > 0)
        rep.sizeReason = "forced by --size";
    if (rep.size < 8 || rep.size > kMaxDisplacementMapSize)
        return Status(StatusCode::InvalidArgument, "map size " + std::to_string(rep.size) + " is out of range");

    auto t0 = std::chrono::steady_clock::now();
    BakeSurface surface;
    if (!(st = buildBakeSurface(&surface, control, options.scheme, options.denseLevel)))
        return st;
    SurfaceIndex index;
    std::vector<VertexMapping> mapping;
    MappingStats ms;
    if (!(st = mapVertices(&mapping, &index, surface, high.positions.data(), high.positions.size(), options.threads,
                           &ms)))
        return st;
    rep.fallbackVertices = ms.fallbacks;
    rep.searchDistance = ms.searchDistance;
    if (ms.fallbacks * 2 > ms.vertices)
        return Status(StatusCode::InvalidData,
                      "the control mesh is far from the high-resolution mesh: " + std::to_string(ms.fallbacks) +
                          " of " + std::to_string(ms.vertices) + " vertices lie in no normal volume");
    rep.times.mapping = msSince(t0);

    t0 = std::chrono::steady_clock::now();
    RasterResult raster;
    rasterize(&raster, index, high.positions.data(), high.triangles.data(), high.faceCount(), mapping, rep.size,
              options.overlap, options.threads);
    rep.raster = raster.stats;
    rep.times.rasterize = msSince(t0);

    t0 = std::chrono::steady_clock::now();
    std::vector<uint8_t> valid(raster.layers.size());
    float dmin = 1e30f, dmax = -1e30f;
    size_t hit = 0;
    for (size_t i = 0; i < valid.size(); ++i)
        valid[i] = raster.layers[i] > 0;
    size_t chartTexels = 0;
    const std::vector<int32_t> owners = chartOwners(surface, rep.size, options.lineRings, &chartTexels);
    for (size_t i = 0; i < valid.size(); ++i)
        hit += valid[i] && owners[i] >= 0;
    rep.coverage = chartTexels ? double(hit) / double(chartTexels) : 0.0;
    // The high-res index is only worth building when there is something to fill.
    bool holes = false;
    for (size_t i = 0; i < owners.size() && !holes; ++i)
        holes = owners[i] >= 0 && !valid[i];
    if (holes) {
        TriangleIndex highIndex;
        highIndex.build(high.positions.data(), high.triangles.data(), high.faceCount());
        rep.lineFilledTexels = fillByLineIntersection(&raster.distance, &valid, owners, surface, highIndex, rep.size,
                                                      4.0 * ms.searchDistance, options.threads);
    }
    for (size_t i = 0; i < valid.size(); ++i)
        if (valid[i]) {
            dmin = std::min(dmin, raster.distance[i]);
            dmax = std::max(dmax, raster.distance[i]);
        }
    if (dmin > dmax)
        return Status(StatusCode::InvalidData, "no texel was covered: the high-resolution mesh maps outside the UVs");
    dilate(&raster.distance, &valid, rep.size, options.gutter, 0.5f * (dmin + dmax));
    rep.times.dilate = msSince(t0);

    rep.overlapFraction = rep.raster.coveredTexels ? double(rep.raster.multiLayerTexels) / double(rep.raster.coveredTexels)
                                                   : 0.0;
    rep.dmin = dmin;
    rep.dmax = dmax;

    DisplacementMap map;
    map.width = map.height = rep.size;
    map.texels = std::move(raster.distance);
    if (layersOut)
        *layersOut = std::move(raster.layers);
    *out = std::move(map);
    if (report)
        *report = rep;
    return Status::ok();
}

Status closedLoopError(std::vector<LevelError>* out, const ControlMesh& control, const DisplacementMap& map,
                       Scheme scheme, const TriangleMesh& high, int minLevel, int maxLevel, int threads)
{
    TriangleIndex highIndex;
    highIndex.build(high.positions.data(), high.triangles.data(), high.faceCount());
    const std::vector<glm::vec3> highSamples =
        surfaceSamples(high.positions.data(), high.positions.size(), high.triangles.data(), high.faceCount());
    std::vector<glm::vec3> normals(control.positions.size());
    computeControlNormals(normals.data(), control.positions.data(), normals.size(), control.triangles.data(),
                          control.faceCount());
    out->clear();
    for (int level = std::max(0, minLevel); level <= maxLevel; ++level) {
        std::unique_ptr<Plan> plan;
        Status st = Plan::create(&plan, control, scheme, level);
        if (st)
            st = plan->setDisplacement(map);
        if (!st)
            return st;
        std::vector<glm::vec3> rec(plan->refinedVertexCount());
        if (!(st = plan->evaluate(rec.data(), nullptr, 0, rec.size(), control.positions.data(), normals.data(),
                                  normals.size())))
            return st;
        const auto& tris = plan->refinedTriangles();
        TriangleIndex recIndex;
        recIndex.build(rec.data(), tris.data(), tris.size() / 3);
        const DistanceStats fwd = sampleDistance(surfaceSamples(rec.data(), rec.size(), tris.data(), tris.size() / 3),
                                                 highIndex, threads);
        const DistanceStats bwd = sampleDistance(highSamples, recIndex, threads);
        LevelError e;
        e.level = level;
        e.vertices = rec.size();
        e.triangles = tris.size() / 3;
        e.forwardRms = fwd.rms;
        e.forwardMax = fwd.max;
        e.backwardRms = bwd.rms;
        e.backwardMax = bwd.max;
        out->push_back(e);
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
