// The bake pipeline (paper 2.1-2.3, 3.2): map vertices, rasterise, dilate.
#include "strata/baker/bake.h"
#include "strata/uv_raster.h"
#include "plans.h"
#include "parallel.h"

#include "strata/baker/dilate.h"
#include "strata/baker/distance.h"
#include "strata/baker/fill.h"
#include "mapping.h"
#include "elapsed.h"
#include "rasterize.h"
#include "strata/baker/surface.h"
#include "strata/normals.h"
#include "strata/plane.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <atomic>
#include <limits>
#include <chrono>
#include <cmath>

namespace strata {
namespace baker {

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
        auv += 0.5 * std::fabs(double(cross2(u1 - u0, u2 - u0)));
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
        double area = orient2(t[0], t[1], t[2]);
        if (area < 0.0) {
            std::swap(t[1], t[2]);
            area = -area;
        }
        if (!(area > 0.0))
            continue;
        const TexelRect r = texelRect(t, size, size);
        for (int y = r.y0; y <= r.y1; ++y)
            for (int x = r.x0; x <= r.x1; ++x) {
                const glm::dvec2 c(x + 0.5, y + 0.5);
                // Strictly inside by more than a hundredth of a texel: shared
                // edges and vertices never count as overlap.
                bool in = true;
                for (int k = 0; k < 3 && in; ++k) {
                    const glm::dvec2 a = t[k], b = t[(k + 1) % 3];
                    const double e = orient2(a, b, c) / glm::length(b - a);
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
    std::vector<uint32_t> pointShells;
    if (const ShellLabels* shells = options.shells.get();
        shells && shells->highVertex.size() == high.positions.size() &&
        shells->controlFace.size() == control.faceCount()) {
        // Each surface face stands for its control face's piece (a smooth
        // surface's faces are 4^level per control face, in order); a point
        // whose piece has no face left (a piece the decimation lost) maps
        // onto any.
        const int shift = options.scheme == Scheme::Linear ? 0 : 2 * options.denseLevel;
        std::vector<uint32_t> faceShells(surface.faceCount());
        std::vector<uint8_t> present;
        for (size_t f = 0; f < faceShells.size(); ++f) {
            const uint32_t piece = shells->controlFace[f >> shift];
            faceShells[f] = piece;
            if (piece >= present.size())
                present.resize(size_t(piece) + 1, 0);
            present[piece] = 1;
        }
        pointShells = shells->highVertex;
        for (uint32_t& piece : pointShells)
            if (piece >= present.size() || !present[piece])
                piece = SurfaceIndex::kAnyShell;
        index.setShells(std::move(faceShells));
    }
    std::vector<VertexMapping> mapping;
    MappingStats ms;
    if (!(st = mapVertices(&mapping, &index, surface, high.positions.data(), high.positions.size(), options.threads,
                           &ms, 0.25, pointShells.empty() ? nullptr : pointShells.data())))
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
        highIndex.build(high.positions.data(), high.triangles.data(), high.faceCount(), options.threads);
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
    dilate(&raster.distance, &valid, rep.size, options.gutter, 0.5f * (dmin + dmax), options.threads);
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

namespace {

// Control faces in Morton order of their centroids, so consecutive chunks
// are compact in space (tight boxes for the backward pass).
std::vector<uint32_t> spatialFaceOrder(const ControlMesh& control)
{
    const size_t nf = control.faceCount();
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const glm::vec3& p : control.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const glm::vec3 extent = glm::max(hi - lo, glm::vec3(1e-30f));
    auto spread = [](uint32_t v) {  // 10 bits -> every third bit
        v &= 0x3ff;
        v = (v | (v << 16)) & 0x030000ff;
        v = (v | (v << 8)) & 0x0300f00f;
        v = (v | (v << 4)) & 0x030c30c3;
        v = (v | (v << 2)) & 0x09249249;
        return v;
    };
    std::vector<std::pair<uint32_t, uint32_t>> keyed(nf);
    for (size_t f = 0; f < nf; ++f) {
        const glm::vec3 c = (control.positions[control.triangles[3 * f]] + control.positions[control.triangles[3 * f + 1]] +
                             control.positions[control.triangles[3 * f + 2]]) /
                            3.0f;
        const glm::vec3 q = glm::clamp((c - lo) / extent, 0.0f, 1.0f) * 1023.0f;
        keyed[f] = {spread(uint32_t(q.x)) | (spread(uint32_t(q.y)) << 1) | (spread(uint32_t(q.z)) << 2), uint32_t(f)};
    }
    std::sort(keyed.begin(), keyed.end());
    std::vector<uint32_t> order(nf);
    for (size_t k = 0; k < nf; ++k)
        order[k] = keyed[k].second;
    return order;
}

double boxDistance(const glm::vec3& p, const glm::vec3& lo, const glm::vec3& hi)
{
    const glm::dvec3 d = glm::max(glm::max(glm::dvec3(lo) - glm::dvec3(p), glm::dvec3(p) - glm::dvec3(hi)), glm::dvec3(0.0));
    return glm::length(d);
}

}  // namespace

// Both directions sample by area (each sample of equal weight), as an
// independent tool measures: as many samples over the capture as it has
// vertices and faces, and over the reconstruction at one density.
std::vector<glm::vec3> loopSamples(const TriangleMesh& high)
{
    return areaSamples(high.positions.data(), high.triangles.data(), high.faceCount(),
                       high.positions.size() + high.faceCount());
}

Status closedLoopError(std::vector<LevelError>* out, const ControlMesh& control, const DisplacementMap& map,
                       Scheme scheme, const TriangleMesh& high, int minLevel, int maxLevel, int threads,
                       size_t chunkTriangles, const DisplacementField* field, const LoopCapture* capture)
{
    TriangleIndex ownIndex;
    std::vector<glm::vec3> ownSamples;
    if (!capture) {
        ownIndex.build(high.positions.data(), high.triangles.data(), high.faceCount());
        ownSamples = loopSamples(high);
    }
    const TriangleIndex& highIndex = capture ? *capture->index : ownIndex;
    const std::vector<glm::vec3>& highSamples = capture ? capture->samples : ownSamples;
    std::vector<glm::vec3> normals(control.positions.size());
    computeControlNormals(normals.data(), control.positions.data(), normals.size(), control.triangles.data(),
                          control.faceCount());
    const size_t nf = control.faceCount(), nv = control.positions.size();
    // Vertex -> faces, for the support ring the smooth scheme needs.
    std::vector<uint32_t> vfOffsets, vfFaces;
    buildVertexFaces(&vfOffsets, &vfFaces, control.triangles.data(), nf, nv);
    const std::vector<uint32_t> order = spatialFaceOrder(control);
    const double controlArea = surfaceArea(control.positions.data(), control.triangles.data(), nf);
    // Distances are measured up to a tenth of the capture's diagonal; one
    // that far counts as that far (the RMS is then a lower bound, and far
    // beyond any tolerance).  Without the bound a surface that has gone
    // wild costs a walk over much of the capture per sample: minutes.
    glm::vec3 captureLo(1e30f), captureHi(-1e30f);
    for (const glm::vec3& p : high.positions) {
        captureLo = glm::min(captureLo, p);
        captureHi = glm::max(captureHi, p);
    }
    const double reach =
        high.positions.empty() ? 1.0 : 0.1 * std::max(1e-30, double(glm::length(captureHi - captureLo)));
    out->clear();
    for (int level = std::max(0, minLevel); level <= maxLevel; ++level) {
        // Each chunk of control faces is refined, measured and freed before
        // the next: memory stays bounded by chunkTriangles whatever the level.
        const size_t per = size_t(1) << (2 * level);
        // Forward samples per unit area: about one and a half per refined
        // triangle (the vertices and centroids the measure took before), up
        // to as many as the capture gets (its vertices and faces): a level
        // finer than the capture holds no detail the capture's own sampling
        // would miss, and at level 4 of a 2k cage the samples would be
        // 770k where the capture has 150k.
        const double density =
            controlArea > 0.0 ? std::min(1.5 * double(nf * per), double(std::max<size_t>(highSamples.size(), 1))) / controlArea
                              : 0.0;
        const size_t facesPerChunk = std::max<size_t>(1, chunkTriangles / per);
        double forwardSq = 0.0, forwardMax = 0.0, forwardSamples = 0.0;
        size_t vertices = 0;
        std::vector<double> best(highSamples.size(), reach);
        std::vector<int32_t> subIndex(nv, -1);
        std::vector<uint8_t> inSub(nf, 0);
        for (size_t first = 0; first < nf; first += facesPerChunk) {
            const size_t count = std::min(facesPerChunk, nf - first);
            const bool whole = count == nf;
            // The chunk's faces plus support faces: one ring, so every refined
            // vertex of the chunk has the same first face (and so samples the
            // map at the same UV) as in the whole mesh; two for the smooth
            // scheme, whose limit surface depends on the neighbourhood.  In
            // the original face order, which fixes that first face.
            std::vector<uint32_t> faces(order.begin() + long(first), order.begin() + long(first + count));
            if (!whole) {
                for (uint32_t f : faces)
                    inSub[f] = 2;  // 2: measured, 1: support
                const int rings = scheme == Scheme::Smooth ? 2 : 1;
                for (int ring = 0; ring < rings; ++ring) {
                    const size_t n = faces.size();
                    for (size_t k = 0; k < n; ++k)
                        for (int c = 0; c < 3; ++c) {
                            const uint32_t v = control.triangles[3 * size_t(faces[k]) + size_t(c)];
                            for (uint32_t j = vfOffsets[v]; j < vfOffsets[v + 1]; ++j)
                                if (!inSub[vfFaces[j]]) {
                                    inSub[vfFaces[j]] = 1;
                                    faces.push_back(vfFaces[j]);
                                }
                        }
                }
                std::sort(faces.begin(), faces.end());
            }
            ControlMesh sub;
            std::vector<glm::vec3> subNormals;
            std::vector<uint32_t> used;
            if (whole) {
                sub = control;
                subNormals = normals;
            } else {
                for (uint32_t f : faces)
                    for (int c = 0; c < 3; ++c) {
                        const uint32_t v = control.triangles[3 * size_t(f) + size_t(c)];
                        if (subIndex[v] < 0) {
                            subIndex[v] = int32_t(sub.positions.size());
                            sub.positions.push_back(control.positions[v]);
                            subNormals.push_back(normals[v]);
                            used.push_back(v);
                        }
                        sub.triangles.push_back(uint32_t(subIndex[v]));
                        if (control.hasUVs())
                            sub.uvIndices.push_back(control.uvIndices[3 * size_t(f) + size_t(c)]);
                    }
                sub.uvs = control.uvs;
                for (uint32_t v : used)
                    subIndex[v] = -1;
            }
            std::unique_ptr<Plan> plan;
            // A whole mesh borrows the last smooth plan's stencils; a chunk's
            // topology is its own.
            Status st = whole ? createPlan(&plan, sub, scheme, level) : Plan::create(&plan, sub, scheme, level);
            if (st && field) {
                // The field is indexed by the whole mesh's faces.
                std::vector<float> d(plan->refinedVertexCount(), 0.0f);
                const std::vector<SampleLocation>& at = plan->sampleLocations();
                for (size_t v = 0; v < d.size(); ++v)
                    if (at[v].face != kNoControlFace)
                        d[v] = field->evaluate(whole ? at[v].face : faces[at[v].face], at[v].bary.x, at[v].bary.y);
                st = plan->setDisplacements(d.data(), d.size());
            } else if (st) {
                st = plan->setDisplacement(map);
            }
            if (!st)
                return st;
            std::vector<glm::vec3> rec(plan->refinedVertexCount());
            if (!(st = plan->evaluate(rec.data(), nullptr, 0, rec.size(), sub.positions.data(), subNormals.data(),
                                      subNormals.size())))
                return st;
            // Only the chunk's own refined faces.
            std::vector<uint32_t> measured;
            if (whole) {
                measured = plan->refinedTriangles();
            } else {
                measured.reserve(3 * count * per);
                const std::vector<uint32_t>& all = plan->refinedTriangles();
                for (size_t k = 0; k < faces.size(); ++k)
                    if (inSub[faces[k]] == 2)
                        measured.insert(measured.end(), all.begin() + long(3 * k * per), all.begin() + long(3 * (k + 1) * per));
                for (uint32_t f : faces)
                    inSub[f] = 0;
            }
            const size_t chunkFaces = measured.size() / 3;
            const uint32_t* tris = measured.data();
            vertices += whole ? rec.size() : 0;
            // Forward samples: the measured faces by area, at one density
            // over every chunk.
            // A surface that has gone wild (a cage too coarse for the capture,
            // a scheme that overshoots) can have many times its cage's area:
            // its samples are capped at four times the usual count per
            // triangle, each then weighted by the density it stands for.
            const double recArea = surfaceArea(rec.data(), tris, chunkFaces);
            const double chunkDensity =
                recArea * density > 6.0 * double(chunkFaces) ? 6.0 * double(chunkFaces) / recArea : density;
            const std::vector<glm::vec3> samples = areaSamplesAtDensity(rec.data(), tris, chunkFaces, chunkDensity);
            const DistanceStats fwd = sampleDistance(samples, highIndex, threads, reach);
            const double weight = density / chunkDensity;
            forwardSq += fwd.rms * fwd.rms * double(fwd.samples) * weight;
            forwardMax = std::max(forwardMax, fwd.max);
            forwardSamples += double(fwd.samples) * weight;
            TriangleIndex recIndex;
            recIndex.build(rec.data(), tris, chunkFaces);
            glm::vec3 lo(1e30f), hi(-1e30f);
            for (size_t i = 0; i < 3 * chunkFaces; ++i) {
                lo = glm::min(lo, rec[tris[i]]);
                hi = glm::max(hi, rec[tris[i]]);
            }
            parallelFor(highSamples.size(), threads, [&](size_t b, size_t e) {
                int64_t hint = -1;  // as in sampleDistance
                for (size_t i = b; i < e; ++i)
                    if (boxDistance(highSamples[i], lo, hi) < best[i])
                        best[i] = std::min(best[i], recIndex.nearestWithin(glm::dvec3(highSamples[i]), best[i], &hint));
            });
        }
        double backwardSq = 0.0, backwardMax = 0.0;
        for (double d : best) {
            backwardSq += d * d;
            backwardMax = std::max(backwardMax, d);
        }
        LevelError e;
        e.level = level;
        e.vertices = vertices;  // 0 when the level was measured in chunks
        e.triangles = nf * per;
        e.forwardRms = forwardSamples > 0.0 ? std::sqrt(forwardSq / forwardSamples) : 0.0;
        e.forwardMax = forwardMax;
        e.backwardRms = best.empty() ? 0.0 : std::sqrt(backwardSq / double(best.size()));
        e.backwardMax = backwardMax;
        out->push_back(e);
    }
    return Status::ok();
}

Status evaluateBareSurface(std::unique_ptr<Plan>* plan, std::vector<glm::vec3>* surface,
                           std::vector<glm::vec3>* direction, const ControlMesh& mesh, Scheme scheme, int level,
                           size_t valueCount, const char* what)
{
    Status st = createPlan(plan, mesh, scheme, level);
    if (!st)
        return st;
    const size_t n = (*plan)->refinedVertexCount();
    if (valueCount != n)
        return Status(StatusCode::InvalidArgument, std::string(what) + ": " + std::to_string(valueCount) +
                                                       " values for " + std::to_string(n) + " vertices");
    std::vector<glm::vec3> normals(mesh.positions.size());
    computeControlNormals(normals.data(), mesh.positions.data(), normals.size(), mesh.triangles.data(),
                          mesh.faceCount());
    surface->resize(n);
    direction->resize(n);
    (*plan)->clearDisplacement();
    return (*plan)->evaluate(surface->data(), direction->data(), 0, n, mesh.positions.data(), normals.data(),
                             normals.size());
}

Status measureVertexDisplacements(std::vector<float>* values, const ControlMesh& mesh, Scheme scheme, int level,
                                  const TriangleIndex& high, double window, int threads, size_t* replaced)
{
    std::unique_ptr<Plan> plan;
    std::vector<glm::vec3> surface, direction;
    if (Status st = evaluateBareSurface(&plan, &surface, &direction, mesh, scheme, level, values->size(),
                                        "measureVertexDisplacements");
        !st)
        return st;
    const size_t n = surface.size();
    const std::vector<SampleLocation>& at = plan->sampleLocations();
    std::atomic<size_t> changed{0};
    parallelFor(n, threads, [&](size_t b, size_t e) {
        size_t local = 0;
        for (size_t v = b; v < e; ++v) {
            const glm::dvec3 dir(direction[v]);
            const double len = glm::length(dir);
            if (at[v].face == kNoControlFace || !(len > 0.0))
                continue;
            // The line's parameter t is the displacement d itself (x = s + d n,
            // n unnormalised in the linear scheme), so the window is window / |n|.
            const double d = (*values)[v], w = window / len;
            double t = 0.0;
            if (high.intersectLine(glm::dvec3(surface[v]), dir, std::fabs(d) + w, &t, /*alongOnly=*/true) &&
                std::fabs(t - d) <= w) {
                (*values)[v] = float(t);
                ++local;
            }
        }
        changed += local;
    });
    if (replaced)
        *replaced = changed;
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
