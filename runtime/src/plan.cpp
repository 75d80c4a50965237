// Uniform refinement plans (paper 2.3, 3.1) built on OpenSubdiv Far.
//
// Both schemes share one topology: Loop refinement of the control triangles,
// with every edge and vertex tagged infinitely sharp for the paper's linear
// 1-to-4 split (sharpness changes weights, never topology).  The sharp
// refiner's stencils are the barycentric weights of each refined vertex in
// its control face; the smooth scheme additionally evaluates OpenSubdiv limit
// stencils at those same (face, s, t) locations.
#include "strata/plan.h"

#include "strata/displacement_math.h"
#include "strata/vertex_displacements.h"
#include "refiner.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/stencilTable.h>
#include <opensubdiv/far/stencilTableFactory.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefiner.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

namespace strata {

using namespace OpenSubdiv;

// The ...Real<float> factories directly: the Far::StencilTableFactory
// wrappers static_cast their result to a subclass it is not (UBSan reports it).
using StencilFactory = Far::StencilTableFactoryReal<float>;
using LimitFactory = Far::LimitStencilTableFactoryReal<float>;
using StencilTable = Far::StencilTableReal<float>;
using LimitStencilTable = Far::LimitStencilTableReal<float>;

const char* schemeName(Scheme scheme)
{
    return scheme == Scheme::Linear ? "linear" : "smooth";
}

bool parseScheme(const std::string& text, Scheme* out)
{
    if (text == "linear")
        *out = Scheme::Linear;
    else if (text == "smooth")
        *out = Scheme::Smooth;
    else
        return false;
    return true;
}

namespace {

// The Sdc options baker and runtime agree on (docs/FORMAT.md): boundary
// edges and corners sharp, face-varying data interpolated linearly.
Sdc::Options subdivisionOptions()
{
    Sdc::Options opts;
    opts.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    opts.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_ALL);
    return opts;
}

struct TopologyInput {
    std::vector<int> vertsPerFace;
    std::vector<int> faceVerts;
    std::vector<int> uvIndices;
    std::vector<int> creasePairs;
    std::vector<float> creaseWeights;
    std::vector<int> corners;
    std::vector<float> cornerWeights;
};

std::unique_ptr<Far::TopologyRefiner> createRefiner(const ControlMesh& mesh, bool allSharp, TopologyInput& in,
                                                    bool withUVs = true)
{
    const size_t nf = mesh.faceCount();
    in.vertsPerFace.assign(nf, 3);
    in.faceVerts.assign(mesh.triangles.begin(), mesh.triangles.end());
    if (withUVs)
        in.uvIndices.assign(mesh.uvIndices.begin(), mesh.uvIndices.end());
    else
        in.uvIndices.clear();

    Far::TopologyDescriptor desc;
    desc.numVertices = int(mesh.positions.size());
    desc.numFaces = int(nf);
    desc.numVertsPerFace = in.vertsPerFace.data();
    desc.vertIndicesPerFace = in.faceVerts.data();

    if (allSharp) {
        // Every directed edge of every face: interior edges are listed twice,
        // which OpenSubdiv resolves to the same edge with the same sharpness.
        in.creasePairs.clear();
        for (size_t f = 0; f < nf; ++f)
            for (int c = 0; c < 3; ++c) {
                in.creasePairs.push_back(int(mesh.triangles[3 * f + c]));
                in.creasePairs.push_back(int(mesh.triangles[3 * f + (c + 1) % 3]));
            }
        in.creaseWeights.assign(in.creasePairs.size() / 2, Sdc::Crease::SHARPNESS_INFINITE);
        desc.numCreases = int(in.creaseWeights.size());
        desc.creaseVertexIndexPairs = in.creasePairs.data();
        desc.creaseWeights = in.creaseWeights.data();
        in.corners.resize(mesh.positions.size());
        for (size_t v = 0; v < mesh.positions.size(); ++v)
            in.corners[v] = int(v);
        in.cornerWeights.assign(in.corners.size(), Sdc::Crease::SHARPNESS_INFINITE);
        desc.numCorners = int(in.corners.size());
        desc.cornerVertexIndices = in.corners.data();
        desc.cornerWeights = in.cornerWeights.data();
    }

    Far::TopologyDescriptor::FVarChannel channels[1];
    int count = 0;
    if (!in.uvIndices.empty()) {
        channels[count].numValues = int(mesh.uvs.size());
        channels[count++].valueIndices = in.uvIndices.data();
    }
    desc.numFVarChannels = count;
    desc.fvarChannels = count ? channels : nullptr;

    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    Factory::Options options(Sdc::SCHEME_LOOP, subdivisionOptions());
    options.validateFullTopology = false;
    return std::unique_ptr<Far::TopologyRefiner>(Factory::Create(desc, options));
}

}  // namespace

namespace detail {

// The sharp (linear) refiner of a control mesh, refined uniformly to level;
// null when OpenSubdiv rejects the topology.
std::unique_ptr<Far::TopologyRefiner> createUniformRefiner(const ControlMesh& mesh, int level)
{
    TopologyInput input;  // read by the factory only
    std::unique_ptr<Far::TopologyRefiner> refiner = createRefiner(mesh, /*allSharp=*/true, input);
    if (refiner && level > 0) {
        Far::TopologyRefiner::UniformOptions uniform(level);
        uniform.fullTopologyInLastLevel = false;
        refiner->RefineUniform(uniform);
    }
    return refiner;
}

}  // namespace detail

namespace {

// Face-varying stencils of channel 0 at the refiner's last level, or null.
std::unique_ptr<const StencilTable> createFaceVaryingTable(const Far::TopologyRefiner& refiner)
{
    StencilFactory::Options so;
    so.interpolationMode = StencilFactory::INTERPOLATE_FACE_VARYING;
    so.generateIntermediateLevels = false;
    so.generateOffsets = true;
    so.fvarChannel = 0;
    return std::unique_ptr<const StencilTable>(StencilFactory::Create(refiner, so));
}

}  // namespace

namespace detail {

// Levels a plan and the helpers accept, with the one message for the rest.
Status checkLevel(int level)
{
    return level < 0 || level > kMaxLevel
               ? Status(StatusCode::InvalidArgument,
                        "subdivision level " + std::to_string(level) + " is outside 0.." + std::to_string(kMaxLevel))
               : Status::ok();
}

}  // namespace detail

using detail::checkLevel;
using detail::createUniformRefiner;

namespace detail {

// refineFaceVarying, also handing back what the same refinement knows of
// the refined vertices (when the pointers are not null): each refined
// face's three vertices and the level's vertex count.
Status refineCorners(FaceVaryingRefinement* out, std::vector<uint32_t>* faceVertices, size_t* vertexCount,
                     const ControlMesh& mesh, const uint32_t* cornerValues, size_t valueCount, int level)
{
    if (!out || !cornerValues)
        return Status(StatusCode::InvalidArgument, "refineFaceVarying: null argument");
    if (Status range = checkLevel(level); !range)
        return range;
    ControlMesh topo;
    topo.positions = mesh.positions;
    topo.triangles = mesh.triangles;
    topo.uvIndices.assign(cornerValues, cornerValues + mesh.triangles.size());
    topo.uvs.assign(valueCount, glm::vec2(0.0f));
    Status st = validateControlMesh(topo);
    if (!st)
        return st;
    std::unique_ptr<Far::TopologyRefiner> refiner = createUniformRefiner(topo, level);
    if (!refiner)
        return Status(StatusCode::InvalidData, "OpenSubdiv rejected the control topology");
    const Far::TopologyLevel& last = refiner->GetLevel(level);
    const size_t nf = size_t(last.GetNumFaces()), nvals = size_t(last.GetNumFVarValues(0));
    FaceVaryingRefinement r;
    r.corners.resize(nf * 3);
    for (size_t f = 0; f < nf; ++f) {
        Far::ConstIndexArray fvv = last.GetFaceFVarValues(Far::Index(f), 0);
        for (int c = 0; c < 3; ++c)
            r.corners[3 * f + size_t(c)] = uint32_t(fvv[c]);
    }
    if (faceVertices) {
        faceVertices->resize(nf * 3);
        for (size_t f = 0; f < nf; ++f) {
            Far::ConstIndexArray fv = last.GetFaceVertices(Far::Index(f));
            for (int c = 0; c < 3; ++c)
                (*faceVertices)[3 * f + size_t(c)] = uint32_t(fv[c]);
        }
    }
    if (vertexCount)
        *vertexCount = size_t(last.GetNumVertices());
    r.offsets.assign(nvals + 1, 0);
    if (level == 0) {
        for (size_t i = 0; i < nvals; ++i)
            r.offsets[i + 1] = uint32_t(i + 1);
        r.sources.resize(nvals);
        for (size_t i = 0; i < nvals; ++i)
            r.sources[i] = uint32_t(i);
        r.weights.assign(nvals, 1.0f);
    } else {
        std::unique_ptr<const StencilTable> table = createFaceVaryingTable(*refiner);
        if (!table || size_t(table->GetNumStencils()) != nvals)
            return Status(StatusCode::InvalidData, "OpenSubdiv produced an unexpected face-varying stencil table");
        for (size_t i = 0; i < nvals; ++i)
            r.offsets[i + 1] = r.offsets[i] + uint32_t(table->GetSizes()[i]);
        r.sources.assign(table->GetControlIndices().begin(), table->GetControlIndices().end());
        r.weights = table->GetWeights();
    }
    *out = std::move(r);
    return Status::ok();
}

}  // namespace detail

using detail::refineCorners;

Status refineFaceVarying(FaceVaryingRefinement* out, const ControlMesh& mesh, const uint32_t* cornerValues,
                         size_t valueCount, int level)
{
    return refineCorners(out, nullptr, nullptr, mesh, cornerValues, valueCount, level);
}

Plan::~Plan() = default;

Status Plan::create(std::unique_ptr<Plan>* out, const ControlMesh& mesh, Scheme scheme, int level)
{
    return create(out, mesh, scheme, level, nullptr);
}

Status Plan::create(std::unique_ptr<Plan>* out, const ControlMesh& mesh, Scheme scheme, int level,
                    const Plan* sameTopology)
{
    if (!out)
        return Status(StatusCode::InvalidArgument, "Plan::create: null output");
    if (level < 0 || level > kMaxLevel)
        return Status(StatusCode::InvalidArgument,
                      "subdivision level " + std::to_string(level) + " is outside 0.." + std::to_string(kMaxLevel));
    if (scheme != Scheme::Linear && scheme != Scheme::Smooth)
        return Status(StatusCode::InvalidArgument, "unknown subdivision scheme");
    Status st = validateControlMesh(mesh);
    if (!st)
        return st;
    std::unique_ptr<Plan> plan(new Plan());
    plan->scheme_ = scheme;
    plan->level_ = level;
    plan->controlVertexCount_ = mesh.positions.size();
    plan->controlTopology_ = strata::controlTopologyHash(mesh.triangles.data(), mesh.faceCount(), mesh.vertexCount());
    st = plan->build(mesh, sameTopology);
    if (!st)
        return st;
    *out = std::move(plan);
    return Status::ok();
}

struct Plan::Build {
    const Far::TopologyRefiner& refiner;
    const ControlMesh& mesh;
    std::vector<uint32_t> firstFace;  // per refined vertex: its first refined face (kNoControlFace: none)
    std::vector<uint8_t> firstCorner; // and its corner there
};

// The refined topology: triangles, and each refined vertex's first face and
// corner (its canonical location).  Uniform refinement numbers child faces
// by parent face, so a refined face's control face is f >> 2 level;
// buildLinear checks the barycentrics against that.
Status Plan::buildTopology(Build& b)
{
    const size_t controlFaces = b.mesh.faceCount();
    std::vector<uint32_t>* firstFace = &b.firstFace;
    std::vector<uint8_t>* firstCorner = &b.firstCorner;
    const Far::TopologyLevel& last = b.refiner.GetLevel(level_);
    const size_t nv = size_t(last.GetNumVertices()), nf = size_t(last.GetNumFaces());
    if (nf != controlFaces << (2 * level_))
        return Status(StatusCode::InvalidData, "refinement produced " + std::to_string(nf) + " faces, expected " +
                                                   std::to_string(controlFaces << (2 * level_)));
    triangles_.resize(nf * 3);
    for (size_t f = 0; f < nf; ++f) {
        Far::ConstIndexArray fv = last.GetFaceVertices(Far::Index(f));
        if (fv.size() != 3)
            return Status(StatusCode::InvalidData, "refinement produced a non-triangular face");
        for (int c = 0; c < 3; ++c)
            triangles_[3 * f + c] = uint32_t(fv[c]);
    }
    firstFace->assign(nv, kNoControlFace);
    firstCorner->assign(nv, 0);
    for (size_t f = 0; f < nf; ++f)
        for (int c = 0; c < 3; ++c) {
            const uint32_t v = triangles_[3 * f + c];
            if ((*firstFace)[v] == kNoControlFace) {
                (*firstFace)[v] = uint32_t(f);
                (*firstCorner)[v] = uint8_t(c);
            }
        }
    return Status::ok();
}

// The linear scheme's stencils: every refined vertex is a barycentric
// combination of its control face's corners, so the plan keeps the control
// triangles and one (face, b1, b2) per refined vertex (b0 = 1 - b1 - b2,
// exact: the weights are dyadic).  Every face's children lie on its grid the
// same way, so the weights are followed through OpenSubdiv's uniform
// refinement of one triangle only (a vertex's child keeps its weights, an
// edge's child vertex takes the mean of its end points'), and that pattern
// places every refined vertex of the mesh.  Weights are kept per control
// vertex, at most three, so they need no face to be expressed in.
namespace {

struct ControlWeights {
    uint32_t id[3];
    float w[3];
    int n;
};

// The mean of two vertices' weights; false when they span more than three
// control vertices (the two do not share a control face).
bool midpoint(const ControlWeights& a, const ControlWeights& b, ControlWeights* out)
{
    *out = a;
    for (int i = 0; i < out->n; ++i)
        out->w[i] *= 0.5f;
    for (int j = 0; j < b.n; ++j) {
        int i = 0;
        while (i < out->n && out->id[i] != b.id[j])
            ++i;
        if (i == out->n) {
            if (out->n == 3)
                return false;
            out->id[i] = b.id[j];
            out->w[i] = 0.0f;
            ++out->n;
        }
        out->w[i] += 0.5f * b.w[j];
    }
    return true;
}

// Control weights of every refined vertex at `level` of a uniformly refined
// refiner, level by level from the control vertices' own.
Status refineWeights(const Far::TopologyRefiner& refiner, int level, size_t controlVertices,
                     std::vector<ControlWeights>* out)
{
    std::vector<ControlWeights>& weights = *out;
    std::vector<ControlWeights> next;
    weights.resize(controlVertices);
    for (size_t v = 0; v < weights.size(); ++v)
        weights[v] = {{uint32_t(v), 0, 0}, {1.0f, 0.0f, 0.0f}, 1};
    for (int l = 0; l < level; ++l) {
        const Far::TopologyLevel& parent = refiner.GetLevel(l);
        next.assign(size_t(refiner.GetLevel(l + 1).GetNumVertices()), ControlWeights{{0, 0, 0}, {0, 0, 0}, 0});
        for (Far::Index v = 0; v < parent.GetNumVertices(); ++v) {
            const Far::Index child = parent.GetVertexChildVertex(v);
            if (child >= 0)
                next[size_t(child)] = weights[size_t(v)];
        }
        for (Far::Index e = 0; e < parent.GetNumEdges(); ++e) {
            const Far::Index child = parent.GetEdgeChildVertex(e);
            const Far::ConstIndexArray ends = parent.GetEdgeVertices(e);
            if (child >= 0 && !midpoint(weights[size_t(ends[0])], weights[size_t(ends[1])], &next[size_t(child)]))
                return Status(StatusCode::InvalidData, "refined edge " + std::to_string(e) + " at level " +
                                                           std::to_string(l) + " spans two control faces");
        }
        weights.swap(next);
    }
    return Status::ok();
}

// The grid point (i, j) (barycentrics i / 2^level, j / 2^level) of each
// corner of a control face's 4^level refined faces, in their order, as
// i | j << 16.  It is the same for every face: uniform refinement numbers a
// face's children and their corners by the face's own corners and edges.
// Read off one triangle refined by OpenSubdiv, its vertices' weights
// followed level by level.
Status childCornerPattern(int level, std::vector<uint32_t>* out)
{
    ControlMesh one;
    one.positions = {glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f)};
    one.triangles = {0, 1, 2};
    std::unique_ptr<Far::TopologyRefiner> refiner = createUniformRefiner(one, level);
    if (!refiner)
        return Status(StatusCode::InvalidData, "OpenSubdiv rejected a single triangle");
    std::vector<ControlWeights> weights;
    if (Status st = refineWeights(*refiner, level, 3, &weights); !st)
        return st;
    const Far::TopologyLevel& last = refiner->GetLevel(level);
    const float R = float(1u << level);
    out->resize(3 * size_t(last.GetNumFaces()));
    for (Far::Index f = 0; f < last.GetNumFaces(); ++f) {
        Far::ConstIndexArray fv = last.GetFaceVertices(f);
        for (int c = 0; c < 3; ++c) {
            const ControlWeights& w = weights[size_t(fv[c])];
            float b[3] = {0.0f, 0.0f, 0.0f};
            for (int k = 0; k < w.n; ++k)
                b[w.id[k]] = w.w[k];
            (*out)[3 * size_t(f) + size_t(c)] = uint32_t(b[1] * R) | uint32_t(b[2] * R) << 16;
        }
    }
    return Status::ok();
}

}  // namespace

Status Plan::buildLinear(Build& build)
{
    const auto& [refiner, mesh, firstFace, firstCorner] = build;
    (void)refiner;
    const size_t nv = firstFace.size();
    controlTriangles_ = mesh.triangles;
    if (Status st = childCornerPattern(level_, &childCorners_); !st)
        return st;
    const uint32_t R = 1u << level_, childMask = (1u << (2 * level_)) - 1;
    const float step = 1.0f / float(R);
    samples_.resize(nv);
    isolated_.clear();
    for (size_t v = 0; v < nv; ++v) {
        if (firstFace[v] == kNoControlFace) {
            // An unreferenced control vertex refines to itself and nothing
            // else; the first levels' vertices keep their numbers.
            if (v >= controlVertexCount_)
                return Status(StatusCode::InvalidData, "isolated refined vertex " + std::to_string(v) +
                                                           " does not descend from a control vertex");
            samples_[v] = {kNoControlFace, glm::vec2(0.0f)};
            isolated_.push_back(uint32_t(v));
            continue;
        }
        const uint32_t face = firstFace[v] >> (2 * level_);
        const uint32_t p = childCorners_[3 * size_t(firstFace[v] & childMask) + firstCorner[v]];
        const uint32_t i = p & 0xffffu, j = p >> 16;
        // Control vertices keep their numbers and sit on their faces' corners.
        const int corner = i == 0 && j == 0 ? 0 : i == R && j == 0 ? 1 : i == 0 && j == R ? 2 : -1;
        if ((corner >= 0) != (v < controlVertexCount_) ||
            (corner >= 0 && controlTriangles_[3 * size_t(face) + size_t(corner)] != v))
            return Status(StatusCode::InvalidData, "refined vertex " + std::to_string(v) +
                                                       " does not follow uniform refinement in control face " +
                                                       std::to_string(face));
        samples_[v] = {face, glm::vec2(float(i) * step, float(j) * step)};
    }
    return Status::ok();
}

// Face-varying UVs, interpolated linearly (FVAR_LINEAR_ALL), and each
// vertex's canonical UV: the value of its first corner.
//
// Computed per control face rather than by OpenSubdiv's face-varying
// refinement, which cost more than the rest of the refinement: a face's
// refined UVs are a triangular grid of R = 2^level steps, and the linear
// rule makes each new grid point the mean of the two ends of the coarser
// edge it splits, exactly as OpenSubdiv's level-by-level interpolation
// (0.5 a + 0.5 b, rounded once), so the values are the same bits.  Values
// are shared as OpenSubdiv shares them on a manifold UV layout: a control
// face's corner keeps its control UV, a control edge's inner points are one
// run of values per (edge, UV pair at its ends), so UV seams split them, and
// a face's inner points are its own.  (OpenSubdiv also gives a UV separate
// values at a vertex whose faces using it are not joined across UV-continuous
// edges, and each face its own on a non-manifold edge; the bits agree.)
// Numbered: control values, edge runs, face interiors.
namespace {

// The grid of one face's linearly refined values from its corner values.
void refineGrid(std::vector<glm::vec2>* grid, const glm::vec2 corner[3], int level)
{
    const uint32_t R = 1u << level;
    glm::vec2* g = grid->data();
    g[tileSlot(0, 0, R)] = corner[0];
    g[tileSlot(R, 0, R)] = corner[1];
    g[tileSlot(0, R, R)] = corner[2];
    for (int k = 1; k <= level; ++k) {
        const uint32_t s = R >> k;  // this level's step; the parent grid's is 2 s
        for (uint32_t j = 0; j <= R; j += s)
            for (uint32_t i = 0; i + j <= R; i += s) {
                const bool oi = (i / s) & 1, oj = (j / s) & 1;
                if (!oi && !oj)
                    continue;  // a coarser point
                size_t a, b;
                if (oi && !oj) {
                    a = tileSlot(i - s, j, R);
                    b = tileSlot(i + s, j, R);
                } else if (!oi) {
                    a = tileSlot(i, j - s, R);
                    b = tileSlot(i, j + s, R);
                } else {
                    a = tileSlot(i - s, j + s, R);
                    b = tileSlot(i + s, j - s, R);
                }
                g[tileSlot(i, j, R)] = 0.5f * g[a] + 0.5f * g[b];
            }
    }
}

}  // namespace

// The plan keeps the control UVs; refinedUVs() and sampleUVs() make the rest.
Status Plan::buildUVs(Build& build)
{
    const ControlMesh& mesh = build.mesh;
    controlUVs_.clear();
    controlUVIndices_.clear();
    if (mesh.hasUVs()) {
        controlUVs_ = mesh.uvs;
        controlUVIndices_ = mesh.uvIndices;
    }
    return Status::ok();
}

// Each vertex's canonical UV: the value of its first corner, which is its
// first control face's grid point at its barycentrics there.  Vertices are
// grouped by that face (a counting sort) so each face's grid is made once.
void Plan::sampleUVs(std::vector<glm::vec2>* out) const
{
    out->clear();
    if (!hasUVs())
        return;
    const uint32_t R = 1u << level_;
    const size_t nfc = controlTriangles_.size() / 3, nv = samples_.size();
    std::vector<uint32_t> start(nfc + 1, 0), order(nv);
    for (const SampleLocation& at : samples_)
        if (at.face != kNoControlFace)
            ++start[size_t(at.face) + 1];
    for (size_t f = 0; f < nfc; ++f)
        start[f + 1] += start[f];
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t v = 0; v < nv; ++v)
        if (samples_[v].face != kNoControlFace)
            order[fill[samples_[v].face]++] = uint32_t(v);
    out->assign(nv, glm::vec2(0.0f));
    std::vector<glm::vec2> grid(size_t(R + 1) * (R + 2) / 2);
    for (size_t f = 0; f < nfc; ++f) {
        if (start[f] == start[f + 1])
            continue;
        const uint32_t* uv = &controlUVIndices_[3 * f];
        const glm::vec2 corner[3] = {controlUVs_[uv[0]], controlUVs_[uv[1]], controlUVs_[uv[2]]};
        refineGrid(&grid, corner, level_);
        for (uint32_t k = start[f]; k < start[f + 1]; ++k) {
            const glm::vec2 b = samples_[order[k]].bary * float(R);  // exact: dyadic
            (*out)[order[k]] = grid[tileSlot(uint32_t(b.x), uint32_t(b.y), R)];
        }
    }
}

void Plan::refinedUVs(std::vector<glm::vec2>* values, std::vector<uint32_t>* indices) const
{
    values->clear();
    indices->clear();
    if (!hasUVs())
        return;
    const uint32_t R = 1u << level_;
    const size_t nfc = controlTriangles_.size() / 3, childFaces = size_t(1) << (2 * level_);
    const size_t gridPoints = size_t(R + 1) * (R + 2) / 2;
    const size_t run = R - 1, inner = R >= 3 ? size_t(R - 1) * (R - 2) / 2 : 0;
    const std::vector<uint32_t>& tri = controlTriangles_;
    const std::vector<uint32_t>& uvi = controlUVIndices_;

    // Edge runs: one per (control edge, UV pair at its ends), numbered in
    // sorted key order; the run goes from the edge's lower vertex id.
    struct EdgeKey {
        uint32_t v0, v1, uv0, uv1, faceEdge;
    };
    std::vector<EdgeKey> keys(3 * nfc);
    for (size_t f = 0; f < nfc; ++f)
        for (int k = 0; k < 3; ++k) {
            const size_t a = 3 * f + size_t(k), b = 3 * f + size_t(k + 1) % 3;
            const bool up = tri[a] < tri[b];
            const size_t lo = up ? a : b, hi = up ? b : a;
            keys[a] = {tri[lo], tri[hi], uvi[lo], uvi[hi], uint32_t(a)};
        }
    std::sort(keys.begin(), keys.end(), [](const EdgeKey& x, const EdgeKey& y) {
        return std::tie(x.v0, x.v1, x.uv0, x.uv1, x.faceEdge) < std::tie(y.v0, y.v1, y.uv0, y.uv1, y.faceEdge);
    });
    std::vector<uint32_t> edgeRun(3 * nfc);
    uint32_t runs = 0;
    for (size_t i = 0; i < keys.size(); ++i) {
        const EdgeKey& k = keys[i];
        if (i > 0) {
            const EdgeKey& p = keys[i - 1];
            runs += !(p.v0 == k.v0 && p.v1 == k.v1 && p.uv0 == k.uv0 && p.uv1 == k.uv1);
        }
        edgeRun[k.faceEdge] = runs;
    }
    runs += keys.empty() ? 0 : 1;
    const size_t edgeBase = controlUVs_.size(), faceBase = edgeBase + size_t(runs) * run;
    values->resize(faceBase + nfc * inner);
    std::copy(controlUVs_.begin(), controlUVs_.end(), values->begin());

    // Each corner of a face's refined faces: its grid point (buildLinear's
    // pattern, the same for every face).
    std::vector<uint32_t> pattern(3 * childFaces);
    for (size_t c = 0; c < pattern.size(); ++c)
        pattern[c] = uint32_t(tileSlot(childCorners_[c] & 0xffffu, childCorners_[c] >> 16, R));

    std::vector<glm::vec2> grid(gridPoints);
    std::vector<uint32_t> ids(gridPoints);
    indices->resize(3 * nfc * childFaces);
    for (size_t f = 0; f < nfc; ++f) {
        const uint32_t* uv = &uvi[3 * f];
        const glm::vec2 corner[3] = {controlUVs_[uv[0]], controlUVs_[uv[1]], controlUVs_[uv[2]]};
        refineGrid(&grid, corner, level_);
        uint32_t next = uint32_t(faceBase + f * inner);
        for (uint32_t j = 0; j <= R; ++j)
            for (uint32_t i = 0; i + j <= R; ++i) {
                uint32_t id = 0;
                int edge = -1;
                uint32_t t = 0;  // steps from the edge's first corner in face order
                if ((i == 0 && j == 0) || (i == R && j == 0) || (i == 0 && j == R))
                    id = uv[i == R ? 1 : j == R ? 2 : 0];
                else if (j == 0)
                    edge = 0, t = i;
                else if (i + j == R)
                    edge = 1, t = j;
                else if (i == 0)
                    edge = 2, t = R - j;
                else
                    id = next++;
                if (edge >= 0) {
                    const uint32_t a = tri[3 * f + size_t(edge)], b = tri[3 * f + size_t(edge + 1) % 3];
                    const uint32_t step = a < b ? t : R - t;
                    id = uint32_t(edgeBase + size_t(edgeRun[3 * f + size_t(edge)]) * run + step - 1);
                }
                const size_t slot = tileSlot(i, j, R);
                ids[slot] = id;
                (*values)[id] = grid[slot];
            }
        uint32_t* dst = &(*indices)[3 * f * childFaces];
        for (size_t c = 0; c < pattern.size(); ++c)
            dst[c] = ids[pattern[c]];
    }
}

// The smooth scheme: Loop limit stencils (position, d/ds, d/dt) at every
// refined vertex's (face, s, t), from an adaptively refined, crease-free
// refiner, re-ordered into refined-vertex order so evaluate() streams.
Status Plan::buildLimit(const ControlMesh& mesh)
{
    const size_t nv = samples_.size();
    TopologyInput smoothInput;
    std::unique_ptr<Far::TopologyRefiner> smooth = createRefiner(mesh, /*allSharp=*/false, smoothInput);
    if (!smooth)
        return Status(StatusCode::InvalidData, "OpenSubdiv rejected the control topology");
    smooth->RefineAdaptive(Far::TopologyRefiner::AdaptiveOptions(4));

    // One location array per control face (its ptex face), listing the
    // refined vertices whose canonical face it is.  Isolated vertices
    // (kNoControlFace sorts last) have no ptex face: they keep their control
    // position through an identity stencil.
    std::vector<uint32_t> order(nv);
    for (size_t v = 0; v < nv; ++v)
        order[v] = uint32_t(v);
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t a, uint32_t b) { return samples_[a].face < samples_[b].face; });
    size_t located = nv;
    while (located > 0 && samples_[order[located - 1]].face == kNoControlFace)
        --located;
    std::vector<float> s(nv), t(nv);
    for (size_t k = 0; k < nv; ++k) {
        s[k] = samples_[order[k]].bary.x;
        t[k] = samples_[order[k]].bary.y;
    }
    LimitFactory::LocationArrayVec locations;
    for (size_t k = 0; k < located;) {
        size_t j = k;
        while (j < located && samples_[order[j]].face == samples_[order[k]].face)
            ++j;
        LimitFactory::LocationArray loc;
        loc.ptexIdx = int(samples_[order[k]].face);
        loc.numLocations = int(j - k);
        loc.s = &s[k];
        loc.t = &t[k];
        locations.push_back(loc);
        k = j;
    }
    LimitFactory::Options lo;
    lo.generate1stDerivatives = true;
    std::unique_ptr<const LimitStencilTable> limit(LimitFactory::Create(*smooth, locations, nullptr, nullptr, lo));
    if (!limit || size_t(limit->GetNumStencils()) != located)
        return Status(StatusCode::InvalidData, "OpenSubdiv produced an unexpected limit stencil table");

    const std::vector<int>& sizes = limit->GetSizes();
    const std::vector<Far::Index>& offsets = limit->GetOffsets();
    const std::vector<Far::Index>& idx = limit->GetControlIndices();
    const std::vector<float>& w = limit->GetWeights();
    const std::vector<float>& du = limit->GetDuWeights();
    const std::vector<float>& dv = limit->GetDvWeights();
    std::vector<uint32_t> stencilOf(nv);
    for (size_t k = 0; k < nv; ++k)
        stencilOf[order[k]] = uint32_t(k);
    limitOffsets_.assign(nv + 1, 0);
    for (size_t v = 0; v < nv; ++v)
        limitOffsets_[v + 1] = limitOffsets_[v] + (stencilOf[v] < located ? uint32_t(sizes[stencilOf[v]]) : 1u);
    limitIndices_.resize(limitOffsets_[nv]);
    limitWeights_.resize(size_t(limitOffsets_[nv]) * 3);
    for (size_t v = 0; v < nv; ++v) {
        if (stencilOf[v] >= located) {
            const size_t dst = limitOffsets_[v];
            limitIndices_[dst] = uint32_t(v);  // an isolated vertex keeps its control vertex's number
            limitWeights_[3 * dst + 0] = 1.0f;
            limitWeights_[3 * dst + 1] = limitWeights_[3 * dst + 2] = 0.0f;
            continue;
        }
        const size_t src = size_t(offsets[stencilOf[v]]);
        for (uint32_t k = 0, n = uint32_t(sizes[stencilOf[v]]); k < n; ++k) {
            const size_t dst = limitOffsets_[v] + k;
            limitIndices_[dst] = uint32_t(idx[src + k]);
            limitWeights_[3 * dst + 0] = w[src + k];
            limitWeights_[3 * dst + 1] = du[src + k];
            limitWeights_[3 * dst + 2] = dv[src + k];
        }
    }
    return Status::ok();
}

Status Plan::build(const ControlMesh& mesh, const Plan* sameTopology)
{
    // One sharp refiner for the topology alone (buildUVs refines the UVs).
    TopologyInput input;
    std::unique_ptr<Far::TopologyRefiner> refiner =
        createRefiner(mesh, /*allSharp=*/true, input, /*withUVs=*/false);
    if (!refiner)
        return Status(StatusCode::InvalidData, "OpenSubdiv rejected the control topology");
    if (level_ > 0) {
        Far::TopologyRefiner::UniformOptions uniform(level_);
        uniform.fullTopologyInLastLevel = false;
        refiner->RefineUniform(uniform);
    }
    Build b{*refiner, mesh, {}, {}};
    Status st = buildTopology(b);
    if (st)
        st = buildLinear(b);
    if (st)
        st = buildUVs(b);
    if (!st)
        return st;
    displacements_.assign(b.firstFace.size(), 0.0f);
    if (scheme_ != Scheme::Smooth)
        return Status::ok();
    // The limit stencils follow from the topology and level alone (the
    // refined vertices' locations are the topology's): a plan of the same
    // ones lends its own.
    if (sameTopology && sameRefinement(*sameTopology)) {
        limitOffsets_ = sameTopology->limitOffsets_;
        limitIndices_ = sameTopology->limitIndices_;
        limitWeights_ = sameTopology->limitWeights_;
        return Status::ok();
    }
    return buildLimit(mesh);
}

bool Plan::sameRefinement(const Plan& other) const
{
    return scheme_ == other.scheme_ && level_ == other.level_ && controlVertexCount_ == other.controlVertexCount_ &&
           controlTopology_ == other.controlTopology_ && controlTriangles_ == other.controlTriangles_;
}

Status sampleDisplacements(float* dst, const Plan& plan, const DisplacementMap& map, float scale)
{
    if (!dst)
        return Status(StatusCode::InvalidArgument, "sampleDisplacements: null buffer");
    std::vector<glm::vec2> uvs;
    plan.sampleUVs(&uvs);
    const std::vector<SampleLocation>& at = plan.sampleLocations();
    if (uvs.empty())
        return Status(StatusCode::InvalidArgument, "the control mesh has no UVs, so no displacement map can be applied");
    if (!std::isfinite(scale))
        return Status(StatusCode::InvalidArgument, "displacement scale is not finite");
    Status st = validateDisplacementMap(map);
    if (!st)
        return st;
    for (size_t v = 0; v < uvs.size(); ++v)
        dst[v] = at[v].face == kNoControlFace ? 0.0f : scale * sampleDisplacement(map, uvs[v]);
    return Status::ok();
}

Status sampleDisplacements(float* dst, const Plan& plan, const DisplacementField& field, float scale)
{
    if (!dst)
        return Status(StatusCode::InvalidArgument, "sampleDisplacements: null buffer");
    if (!std::isfinite(scale))
        return Status(StatusCode::InvalidArgument, "displacement scale is not finite");
    const std::vector<SampleLocation>& at = plan.sampleLocations();
    for (size_t v = 0; v < at.size(); ++v)
        dst[v] = at[v].face == kNoControlFace ? 0.0f : scale * field.evaluate(at[v].face, at[v].bary.x, at[v].bary.y);
    return Status::ok();
}

Status Plan::setDisplacement(const DisplacementMap& map, float scale)
{
    return sampleDisplacements(displacements_.data(), *this, map, scale);
}

Status Plan::setDisplacement(const DisplacementField& field, float scale)
{
    return sampleDisplacements(displacements_.data(), *this, field, scale);
}

Status Plan::setDisplacements(const float* values, size_t count, float scale)
{
    if (count != displacements_.size())
        return Status(StatusCode::InvalidArgument, std::to_string(count) + " displacements given for " +
                                                       std::to_string(displacements_.size()) + " refined vertices");
    if (!std::isfinite(scale))
        return Status(StatusCode::InvalidArgument, "displacement scale is not finite");
    for (size_t v = 0; v < count; ++v) {
        if (!std::isfinite(values[v]))
            return Status(StatusCode::InvalidArgument, "displacement " + std::to_string(v) + " is not finite");
        displacements_[v] = samples_[v].face == kNoControlFace ? 0.0f : scale * values[v];
    }
    return Status::ok();
}

void Plan::clearDisplacement()
{
    std::fill(displacements_.begin(), displacements_.end(), 0.0f);
}

Status Plan::evaluate(glm::vec3* dstPositions, glm::vec3* dstDirections, size_t begin, size_t end,
                      const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount) const
{
    return evaluate(dstPositions, dstDirections, begin, end, displacements_.data(), controlPositions, controlNormals,
                    controlCount);
}

Status Plan::checkEvaluate(const glm::vec3* dstPositions, const float* displacements, const glm::vec3* controlPositions,
                           const glm::vec3* controlNormals, size_t controlCount) const
{
    if (controlCount != controlVertexCount_)
        return Status(StatusCode::InvalidArgument, "evaluate: got " + std::to_string(controlCount) +
                                                       " control vertices, the plan was built for " +
                                                       std::to_string(controlVertexCount_));
    if (!dstPositions || !controlPositions || !displacements || (scheme_ == Scheme::Linear && !controlNormals))
        return Status(StatusCode::InvalidArgument, "evaluate: null buffer");
    return Status::ok();
}

// The one expression of eq. 2 for both entry points: refined vertex
// vertexAt(k) into slot k, for k in [0, count).
template <typename VertexAt>
void Plan::evaluateEach(glm::vec3* dstPositions, glm::vec3* dstDirections, size_t count, const VertexAt& vertexAt,
                        const float* d, const glm::vec3* controlPositions, const glm::vec3* controlNormals) const
{
    if (scheme_ == Scheme::Linear) {
        const SampleLocation* at = samples_.data();
        const uint32_t* tri = controlTriangles_.data();
        for (size_t k = 0; k < count; ++k) {
            const size_t v = vertexAt(k);
            const SampleLocation& s = at[v];
            glm::vec3 p, n;
            if (s.face != kNoControlFace) {
                const uint32_t* c = tri + 3 * size_t(s.face);
                const float w1 = s.bary.x, w2 = s.bary.y, w0 = 1.0f - w1 - w2;
                p = w0 * controlPositions[c[0]] + w1 * controlPositions[c[1]] + w2 * controlPositions[c[2]];
                n = w0 * controlNormals[c[0]] + w1 * controlNormals[c[1]] + w2 * controlNormals[c[2]];
            } else {  // an isolated vertex keeps its control vertex's number
                p = controlPositions[v];
                n = controlNormals[v];
            }
            dstPositions[k] = shared::strata_displace(p, n, d[v]);
            if (dstDirections)
                dstDirections[k] = n;
        }
        return;
    }
    for (size_t k = 0; k < count; ++k) {
        const size_t v = vertexAt(k);
        glm::vec3 p(0.0f), du(0.0f), dv(0.0f);
        for (uint32_t e = limitOffsets_[v], end = limitOffsets_[v + 1]; e < end; ++e) {
            const glm::vec3 c = controlPositions[limitIndices_[e]];
            p += limitWeights_[3 * e + 0] * c;
            du += limitWeights_[3 * e + 1] * c;
            dv += limitWeights_[3 * e + 2] * c;
        }
        const glm::vec3 n = shared::strata_limit_normal(du, dv);
        dstPositions[k] = shared::strata_displace(p, n, d[v]);
        if (dstDirections)
            dstDirections[k] = n;
    }
}

Status Plan::evaluate(glm::vec3* dstPositions, glm::vec3* dstDirections, size_t begin, size_t end,
                      const float* displacements, const glm::vec3* controlPositions, const glm::vec3* controlNormals,
                      size_t controlCount) const
{
    if (begin > end || end > samples_.size())
        return Status(StatusCode::InvalidArgument, "evaluate: range [" + std::to_string(begin) + ", " +
                                                       std::to_string(end) + ") exceeds the " +
                                                       std::to_string(samples_.size()) + " refined vertices");
    if (Status st = checkEvaluate(dstPositions, displacements, controlPositions, controlNormals, controlCount); !st)
        return st;
    evaluateEach(dstPositions, dstDirections, end - begin, [begin](size_t k) { return begin + k; }, displacements,
                 controlPositions, controlNormals);
    return Status::ok();
}

Status Plan::evaluateVertices(glm::vec3* dstPositions, glm::vec3* dstDirections, const uint32_t* vertices, size_t count,
                              const float* displacements, const glm::vec3* controlPositions,
                              const glm::vec3* controlNormals, size_t controlCount) const
{
    if (count > 0 && !vertices)
        return Status(StatusCode::InvalidArgument, "evaluate: null vertex list");
    if (Status st = checkEvaluate(dstPositions, displacements, controlPositions, controlNormals, controlCount); !st)
        return st;
    const size_t nv = samples_.size();
    for (size_t k = 0; k < count; ++k)
        if (vertices[k] >= nv)
            return Status(StatusCode::InvalidArgument, "evaluate: vertex " + std::to_string(vertices[k]) +
                                                           " exceeds the " + std::to_string(nv) + " refined vertices");
    evaluateEach(dstPositions, dstDirections, count, [vertices](size_t k) { return size_t(vertices[k]); },
                 displacements, controlPositions, controlNormals);
    return Status::ok();
}

Status Plan::tileVertices(std::vector<uint32_t>* out) const
{
    const uint32_t R = 1u << level_;
    const size_t nf0 = controlTriangles_.size() / 3, childFaces = size_t(1) << (2 * level_);
    const size_t slots = size_t(R + 1) * (R + 2) / 2;
    if (triangles_.size() != 3 * nf0 * childFaces || childCorners_.size() != 3 * childFaces)
        return Status(StatusCode::InvalidData, "the refined faces are not a grid per control face");
    out->assign(nf0 * slots, kNoControlFace);
    for (size_t f = 0; f < nf0; ++f) {
        uint32_t* tile = out->data() + f * slots;
        const uint32_t* children = &triangles_[3 * f * childFaces];
        for (size_t c = 0; c < 3 * childFaces; ++c) {
            const uint32_t p = childCorners_[c];
            uint32_t& slot = tile[tileSlot(p & 0xffffu, p >> 16, R)];
            if (slot != kNoControlFace && slot != children[c])
                return Status(StatusCode::InvalidData, "control face " + std::to_string(f) +
                                                           " has two refined vertices at one grid point");
            slot = children[c];
        }
        for (size_t k = 0; k < slots; ++k)
            if (tile[k] == kNoControlFace)
                return Status(StatusCode::InvalidData, "control face " + std::to_string(f) + " misses a grid point");
    }
    return Status::ok();
}

void Plan::flattenStencils(FlatStencils* out) const
{
    const size_t nv = samples_.size();
    if (scheme_ == Scheme::Linear) {
        out->weightsPerEntry = 1;
        out->offsets.resize(nv + 1);
        out->indices.resize(3 * nv);
        out->weights.resize(3 * nv);
        for (size_t v = 0; v < nv; ++v) {
            out->offsets[v] = uint32_t(3 * v);
            const SampleLocation& s = samples_[v];
            const float w[3] = {1.0f - s.bary.x - s.bary.y, s.bary.x, s.bary.y};
            for (int k = 0; k < 3; ++k) {
                const bool isolated = s.face == kNoControlFace;
                out->indices[3 * v + size_t(k)] = isolated ? uint32_t(v) : controlTriangles_[3 * size_t(s.face) + size_t(k)];
                out->weights[3 * v + size_t(k)] = isolated ? (k == 0 ? 1.0f : 0.0f) : w[k];
            }
        }
        out->offsets[nv] = uint32_t(3 * nv);
        return;
    }
    out->weightsPerEntry = 3;
    out->offsets = limitOffsets_;
    out->indices = limitIndices_;
    out->weights = limitWeights_;
}

void Plan::computeShadingNormals(glm::vec3* dst, const glm::vec3* positions) const
{
    const size_t nv = samples_.size();
    for (size_t v = 0; v < nv; ++v)
        dst[v] = glm::vec3(0.0f);
    const size_t nf = triangles_.size() / 3;
    const uint32_t* tri = triangles_.data();
    for (size_t f = 0; f < nf; ++f) {
        const uint32_t a = tri[3 * f], b = tri[3 * f + 1], c = tri[3 * f + 2];
        // |cross| is twice the area: area weighting for free.
        const glm::vec3 n = glm::cross(positions[b] - positions[a], positions[c] - positions[a]);
        dst[a] += n;
        dst[b] += n;
        dst[c] += n;
    }
    for (size_t v = 0; v < nv; ++v) {
        const float len = glm::length(dst[v]);
        dst[v] = len > 0.0f ? dst[v] / len : glm::vec3(0.0f);
    }
}

size_t Plan::memoryBytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    return bytes(triangles_) + bytes(controlUVs_) + bytes(controlUVIndices_) + bytes(samples_) +
           bytes(displacements_) + bytes(controlTriangles_) + bytes(isolated_) + bytes(childCorners_) + bytes(limitOffsets_) +
           bytes(limitIndices_) +
           bytes(limitWeights_);
}

size_t Plan::stencilWeightCount() const
{
    if (scheme_ != Scheme::Linear)
        return limitIndices_.size();
    size_t n = 0;
    for (const SampleLocation& s : samples_)
        n += s.face == kNoControlFace ? 1
                                      : size_t(1.0f - s.bary.x - s.bary.y != 0.0f) + size_t(s.bary.x != 0.0f) +
                                            size_t(s.bary.y != 0.0f);
    return n;
}

}  // namespace strata
