// The per-vertex displacement codec's arithmetic, in one place
// (strata/vertex_displacements.h): the subdivision hierarchy the values are
// predicted along, their quantisation, the prediction and its inverse, and
// the field the stored values define over the control mesh.  The baker
// quantises with it while it fits values; io's byte format
// (io/src/vertex_codec.cpp: zigzag residuals in zstd frames) codes what it
// predicts.
#include "strata/vertex_displacements.h"

#include "refiner.h"
#include "strata/displacement_math.h"

#include <opensubdiv/far/primvarRefiner.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {

using detail::checkLevel;
using detail::createUniformRefiner;
using detail::refineCorners;
namespace Far = OpenSubdiv::Far;

namespace {

// A primvar that records the two heaviest parent vertices a child is made
// from.  In the sharp refiner a vertex child weighs itself most (1, 3/4 on
// a crease, 1 - n beta in a face) and an edge child its edge's two ends
// most (1/2 each on a crease, 3/8 each inside a face), so those are the
// topological parents whatever rule OpenSubdiv applies.
struct ParentRecord {
    uint32_t self = 0;
    uint32_t parent[2] = {0, 0};
    float weight[2] = {0.0f, 0.0f};
    void Clear(void* = nullptr)
    {
        weight[0] = weight[1] = 0.0f;
    }
    void AddWithWeight(const ParentRecord& src, float w)
    {
        if (w > weight[0]) {
            parent[1] = parent[0];
            weight[1] = weight[0];
            parent[0] = src.self;
            weight[0] = w;
        } else if (w > weight[1]) {
            parent[1] = src.self;
            weight[1] = w;
        }
    }
};

}  // namespace

Status buildSubdivisionParents(SubdivisionParents* out, const ControlMesh& mesh, int level)
{
    if (!out)
        return Status(StatusCode::InvalidArgument, "buildSubdivisionParents: null argument");
    Status st = checkLevel(level);
    if (!st)
        return st;
    ControlMesh topo;  // topology only: no UVs to validate or refine
    topo.positions = mesh.positions;
    topo.triangles = mesh.triangles;
    st = validateControlMesh(topo);
    if (!st)
        return st;
    std::unique_ptr<Far::TopologyRefiner> refiner = createUniformRefiner(topo, level);
    if (!refiner)
        return Status(StatusCode::InvalidData, "OpenSubdiv rejected the control topology");
    SubdivisionParents h;
    h.levelCounts.push_back(uint32_t(refiner->GetLevel(0).GetNumVertices()));
    Far::PrimvarRefiner primvars(*refiner);
    std::vector<ParentRecord> src(h.levelCounts[0]), dst;
    for (size_t i = 0; i < src.size(); ++i)
        src[i].self = uint32_t(i);
    for (int l = 1; l <= level; ++l) {
        const size_t parentCount = src.size(), childCount = size_t(refiner->GetLevel(l).GetNumVertices());
        dst.assign(childCount, ParentRecord());
        ParentRecord* from = src.data();
        ParentRecord* to = dst.data();
        primvars.Interpolate(l, from, to);
        for (size_t c = 0; c < childCount; ++c) {
            const ParentRecord& r = dst[c];
            const bool ok = c < parentCount ? r.parent[0] == c && r.weight[0] > r.weight[1]
                                            : r.weight[1] > 0.0f && r.parent[0] < parentCount &&
                                                  r.parent[1] < parentCount && r.parent[0] != r.parent[1];
            if (!ok)
                return Status(StatusCode::InvalidData, "OpenSubdiv numbered level " + std::to_string(l) +
                                                           " in an unexpected order (vertex " + std::to_string(c) + ")");
            if (c >= parentCount) {
                h.parents.push_back(r.parent[0]);
                h.parents.push_back(r.parent[1]);
            }
        }
        h.levelCounts.push_back(uint32_t(childCount));
        src.swap(dst);
        for (size_t i = 0; i < src.size(); ++i)
            src[i].self = uint32_t(i);
    }
    *out = std::move(h);
    return Status::ok();
}

Status DisplacementField::create(DisplacementField* out, const ControlMesh& mesh, int level,
                                 const std::vector<float>& values)
{
    if (!out)
        return Status(StatusCode::InvalidArgument, "DisplacementField::create: null argument");
    const size_t nf = mesh.faceCount();
    std::vector<uint32_t> cornerIds(3 * nf);
    for (size_t c = 0; c < cornerIds.size(); ++c)
        cornerIds[c] = uint32_t(c);
    // Face-varying refinement of distinct corner ids: each refined corner's
    // weights are its barycentrics in its control face.
    // The same refinement numbers the refined vertices, as a plan does.
    FaceVaryingRefinement fv;
    std::vector<uint32_t> faceVertices;
    size_t vertexCount = 0;
    Status st = refineCorners(&fv, &faceVertices, &vertexCount, mesh, cornerIds.data(), cornerIds.size(), level);
    if (!st)
        return st;
    if (vertexCount != values.size())
        return Status(StatusCode::InvalidArgument, std::to_string(values.size()) + " displacements for " +
                                                       std::to_string(vertexCount) + " vertices at level " +
                                                       std::to_string(level));
    DisplacementField field;
    field.level_ = level;
    field.side_ = 1u << level;
    field.perFace_ = size_t(field.side_ + 1) * size_t(field.side_ + 2) / 2;
    field.grid_.assign(field.perFace_ * nf, 0.0f);
    const float n = float(field.side_);
    for (size_t rf = 0; rf < faceVertices.size() / 3; ++rf) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t value = fv.corners[3 * rf + size_t(k)];
            float b[3] = {0.0f, 0.0f, 0.0f};
            uint32_t face = 0;
            for (uint32_t e = fv.offsets[value]; e < fv.offsets[value + 1]; ++e) {
                face = fv.sources[e] / 3;
                b[fv.sources[e] % 3] += fv.weights[e];
            }
            const uint32_t i = uint32_t(std::lround(b[1] * n)), j = uint32_t(std::lround(b[2] * n));
            if (i + j > field.side_ || face >= nf)
                return Status(StatusCode::InvalidData, "unexpected face-varying weights at level " +
                                                           std::to_string(level));
            const size_t row = size_t(j) * (field.side_ + 1) - size_t(j) * (j - 1) / 2;
            field.grid_[face * field.perFace_ + row + i] = values[faceVertices[3 * rf + size_t(k)]];
        }
    }
    *out = std::move(field);
    return Status::ok();
}

float DisplacementField::evaluate(uint32_t face, float b1, float b2) const
{
    const float* g = grid_.data() + size_t(face) * perFace_;
    const uint32_t n = side_;
    auto at = [&](uint32_t i, uint32_t j) { return g[size_t(j) * (n + 1) - size_t(j) * (j - 1) / 2 + i]; };
    const float u = std::clamp(b1, 0.0f, 1.0f) * float(n), v = std::clamp(b2, 0.0f, 1.0f) * float(n);
    uint32_t i = std::min(uint32_t(u), n), j = std::min(uint32_t(v), n);
    if (i + j >= n) {  // on the far edge (a grid point, up to rounding)
        j = std::min(j, n);
        return at(n - j, j);
    }
    const float fu = u - float(i), fv = v - float(j);
    if (fu + fv <= 1.0f)
        return at(i, j) * (1.0f - fu - fv) + at(i + 1, j) * fu + at(i, j + 1) * fv;
    return at(i + 1, j) * (1.0f - fv) + at(i, j + 1) * (1.0f - fu) + at(i + 1, j + 1) * (fu + fv - 1.0f);
}

Status quantizeDisplacements(const std::vector<float>& values, double step, std::vector<int32_t>* q, float* factor,
                             float* offset)
{
    float dmin = std::numeric_limits<float>::max(), dmax = std::numeric_limits<float>::lowest();
    for (float v : values) {
        if (!std::isfinite(v))
            return Status(StatusCode::InvalidData, "vertex displacements: a value is not finite");
        dmin = std::min(dmin, v);
        dmax = std::max(dmax, v);
    }
    if (values.empty())
        dmin = dmax = 0.0f;
    const double range = double(dmax) - double(dmin);
    const double s = std::max(step > 0.0 ? step : range / 65535.0, range / 16777215.0);
    const double levels = s > 0.0 ? std::floor(range / s) + 1.0 : 1.0;
    q->resize(values.size());
    for (size_t i = 0; i < values.size(); ++i)
        (*q)[i] = s > 0.0 ? int32_t(std::min(std::llround((double(values[i]) - dmin) / s), (long long)(levels - 1)))
                          : 0;
    *factor = float(s);
    *offset = dmin;
    return Status::ok();
}

void predictSubdivisionResiduals(const SubdivisionParents& h, const int32_t* q, int32_t* residuals)
{
    const size_t base = h.levelCounts.front(), n = h.levelCounts.back();
    for (size_t v = 0; v < base; ++v)
        residuals[v] = int32_t(int64_t(q[v]) - (v > 0 ? int64_t(q[v - 1]) : 0));
    for (size_t v = base; v < n; ++v) {
        const int64_t a = q[h.parents[2 * (v - base)]], b = q[h.parents[2 * (v - base) + 1]];
        residuals[v] = int32_t(int64_t(q[v]) - ((a + b) >> 1));
    }
}

void reconstructSubdivisionValues(const SubdivisionParents& h, const int32_t* residuals, int32_t* q)
{
    const size_t base = h.levelCounts.front(), n = h.levelCounts.back();
    for (size_t v = 0; v < base; ++v)
        q[v] = int32_t(int64_t(residuals[v]) + (v > 0 ? int64_t(q[v - 1]) : 0));
    for (size_t v = base; v < n; ++v) {
        const int64_t a = q[h.parents[2 * (v - base)]], b = q[h.parents[2 * (v - base) + 1]];
        q[v] = int32_t(int64_t(residuals[v]) + ((a + b) >> 1));
    }
}

}  // namespace strata
