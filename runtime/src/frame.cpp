// A render-ready frame on one or several threads (frame.h).
#include "strata/frame.h"

#include "strata/displacement_math.h"
#include "strata/normals.h"

#include "simd.h"
#include "worker_pool.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <utility>

namespace strata {

namespace {

constexpr uint32_t kOwned = 0x80000000u;
// A tile's slot numbers fit the tile layout's 16-bit slot list.
static_assert((size_t(1) << kMaxLevel) + 2 < 362, "(R + 1)(R + 2) / 2 slots must stay below 2^16");
constexpr uint32_t kIndexMask = 0x7fffffffu;
constexpr uint32_t kUnset = 0xffffffffu;

inline glm::vec3 unitOrZero(glm::vec3 n)
{
    const float len = glm::length(n);
    return len > 0.0f ? n / len : glm::vec3(0.0f);
}

// The smooth scheme's tile: limit positions and tangents as the product of
// the tile's control points with its dense weights, then eq. 2 along the
// unit limit normal (strata_limit_normal), as structure of arrays.
STRATA_KERNEL_INLINE void limitGrid(size_t n, size_t points, const uint32_t* control, const float* weights,
                                    const glm::vec3* cp, const float* d, float* const* acc, float* const* p)
{
    // One vector of slots at a time, its nine sums held in registers over
    // all the tile's points (the weights stream; nothing else moves).
    for (size_t s0 = 0; s0 < n; s0 += detail::kLanes) {
        float a[9][detail::kLanes] = {};
        for (size_t k = 0; k < points; ++k) {
            const glm::vec3 c = cp[control[k]];
            const float* w = weights + 3 * (s0 * points + detail::kLanes * k);
            for (size_t l = 0; l < detail::kLanes; ++l) {
                const float w0 = w[l], w1 = w[detail::kLanes + l], w2 = w[2 * detail::kLanes + l];
                a[0][l] += w0 * c.x;
                a[1][l] += w0 * c.y;
                a[2][l] += w0 * c.z;
                a[3][l] += w1 * c.x;
                a[4][l] += w1 * c.y;
                a[5][l] += w1 * c.z;
                a[6][l] += w2 * c.x;
                a[7][l] += w2 * c.y;
                a[8][l] += w2 * c.z;
            }
        }
        for (int i = 0; i < 9; ++i)
            for (size_t l = 0; l < detail::kLanes; ++l)
                acc[i][s0 + l] = a[i][l];
    }
    const float *ux = acc[3], *uy = acc[4], *uz = acc[5], *vx = acc[6], *vy = acc[7], *vz = acc[8];
    float* __restrict px = p[0];
    float* __restrict py = p[1];
    float* __restrict pz = p[2];
    for (size_t s = 0; s < n; ++s) {
        const float nx = uy[s] * vz[s] - uz[s] * vy[s], ny = uz[s] * vx[s] - ux[s] * vz[s],
                    nz = ux[s] * vy[s] - uy[s] * vx[s];
        const float len = std::sqrt(nx * nx + ny * ny + nz * nz);
        const float scale = len > 0.0f ? d[s] / len : 0.0f;
        px[s] = acc[0][s] + nx * scale;
        py[s] = acc[1][s] + ny * scale;
        pz[s] = acc[2][s] + nz * scale;
    }
}

}  // namespace

// One tile's local arrays (detail::GridScratch) and the smooth scheme's
// nine sums per slot: limit position, d/ds, d/dt.
struct FrameEvaluator::Scratch : detail::GridScratch {
    std::vector<float> limit[9];
    void resize(size_t slots, size_t row, bool smooth)
    {
        GridScratch::resize(slots, row);
        for (std::vector<float>& v : limit)
            v.assign(smooth ? detail::wholeVectors(slots) : 0, 0.0f);
    }
    size_t bytes() const { return GridScratch::bytes() + 9 * limit[0].capacity() * 4; }
};

template <typename Body>
void FrameEvaluator::parallel(int threads, size_t n, const Body& body)
{
    detail::runParallel(pool_, threads, n, body);
}

FrameEvaluator::FrameEvaluator(const Plan& plan, FrameLayout layout) : plan_(plan), requested_(layout) {}
FrameEvaluator::~FrameEvaluator() = default;

void FrameEvaluator::buildTables()
{
    if (built_)
        return;
    built_ = true;
    tiled_ = buildTiles();
    if (tiled_ && requested_ == FrameLayout::Tiles)
        buildTileLayout();
    if (!tiled_) {
        slots_ = {};
        borderVertices_ = {};
        borderOffsets_ = {};
        borderEntries_ = {};
        const std::vector<uint32_t>& tri = plan_.refinedTriangles();
        const size_t nv = plan_.refinedVertexCount(), nf = plan_.refinedFaceCount();
        buildVertexFaces(&offsets_, &faces_, tri.data(), nf, nv);  // ascending: the scatter's order
        faceNormals_.resize(nf);
    }
}

// Finds every control face's grid in the refined topology.  A refined
// vertex's sample is in its owning control face; in a neighbouring face that
// shares it (it lies on their common edge or corner), its barycentrics are
// the same weights of the same control vertices.  Returns false, and the
// generic path runs, unless every refined face is a grid triangle of its
// control face with the grid's orientation.
bool FrameEvaluator::buildTiles()
{
    const int level = plan_.level();
    // Below these levels a tile is too small to pay for itself (measured:
    // bench_runtime): linear tiles of 15 slots lose to the plain passes,
    // smooth tiles of 3 slots to the per-vertex stencils.
    if (level < (plan_.scheme() == Scheme::Linear ? 3 : 1))
        return false;
    const uint32_t R = 1u << level;
    const std::vector<uint32_t>& control = plan_.controlTriangles();
    const std::vector<uint32_t>& refined = plan_.refinedTriangles();
    const std::vector<SampleLocation>& samples = plan_.sampleLocations();
    const size_t nf0 = control.size() / 3, nf = refined.size() / 3, nv = samples.size();
    const size_t perTile = size_t(1) << (2 * level);
    if (nf != nf0 * perTile || nv >= kIndexMask)
        return false;

    resolution_ = int(R);
    slotCount_ = size_t(R + 1) * (R + 2) / 2;
    detail::gridTables(R, &rowStart_, &slotW1_, &slotW2_);
    std::vector<uint16_t> slotI(slotCount_), slotJ(slotCount_);
    borderSlots_.clear();
    for (uint32_t i = 0; i <= R; ++i)
        for (uint32_t j = 0; i + j <= R; ++j) {
            const uint32_t k = rowStart_[i] + j;
            slotI[k] = uint16_t(i);
            slotJ[k] = uint16_t(j);
            if (i == 0 || j == 0 || i + j == R)
                borderSlots_.push_back(k);
        }
    auto slotOf = [&](uint32_t i, uint32_t j) { return rowStart_[i] + j; };

    slots_.assign(nf0 * slotCount_, kUnset);
    std::vector<uint8_t> owners(nv, 0), seen(perTile);
    for (size_t g = 0; g < nf0; ++g) {
        const uint32_t* cg = &control[3 * g];
        std::fill(seen.begin(), seen.end(), uint8_t(0));
        for (size_t r = g * perTile; r < (g + 1) * perTile; ++r) {
            uint32_t local[3];
            for (int c = 0; c < 3; ++c) {
                const uint32_t v = refined[3 * r + size_t(c)];
                const SampleLocation& s = samples[v];
                if (s.face == kNoControlFace || s.face >= nf0)
                    return false;
                const float w[3] = {1.0f - s.bary.x - s.bary.y, s.bary.x, s.bary.y};
                float wg[3] = {0.0f, 0.0f, 0.0f};
                const uint32_t* cf = &control[3 * size_t(s.face)];
                for (int m = 0; m < 3; ++m) {
                    if (w[m] == 0.0f)
                        continue;
                    const int k = cg[0] == cf[m] ? 0 : cg[1] == cf[m] ? 1 : cg[2] == cf[m] ? 2 : -1;
                    if (k < 0)
                        return false;  // not on this control face
                    wg[k] = w[m];
                }
                const float fi = wg[1] * float(R), fj = wg[2] * float(R);
                if (fi != std::floor(fi) || fj != std::floor(fj) || fi < 0.0f || fj < 0.0f || fi + fj > float(R))
                    return false;
                const uint32_t k = slotOf(uint32_t(fi), uint32_t(fj));
                uint32_t& slot = slots_[g * slotCount_ + k];
                const bool own = s.face == g;
                if (slot == kUnset) {
                    slot = v | (own ? kOwned : 0u);
                    owners[v] = uint8_t(owners[v] + (own ? 1 : 0));
                } else if ((slot & kIndexMask) != v) {
                    return false;
                }
                local[c] = k;
            }
            // Rotate the smallest slot first; it is the grid triangle's
            // (i, j) corner: up (i, j), (i + 1, j), (i, j + 1), or down
            // (i, j + 1), (i + 1, j), (i + 1, j + 1).
            const int first = local[0] < local[1] ? (local[0] < local[2] ? 0 : 2) : (local[1] < local[2] ? 1 : 2);
            const uint32_t a = local[first], b = local[(first + 1) % 3], c = local[(first + 2) % 3];
            const uint32_t i = slotI[a], j = slotJ[a];
            // Rows before i hold rowStart_[i] - i up and rowStart_[i] - 2i
            // down triangles; the R(R + 1)/2 up ones are numbered first.
            size_t index;
            if (i + j < R && b == slotOf(i + 1, j) && c == slotOf(i, j + 1))
                index = size_t(rowStart_[i]) - i + j;
            else if (j >= 1 && i + j < R && b == slotOf(i + 1, j - 1) && c == slotOf(i + 1, j))
                index = size_t(R) * (R + 1) / 2 + rowStart_[i] - 2 * i + j - 1;
            else
                return false;
            if (index >= perTile || seen[index])
                return false;
            seen[index] = 1;
        }
    }
    for (size_t v = 0; v < nv; ++v)
        if (owners[v] > 1 || (owners[v] == 0 && samples[v].face != kNoControlFace))
            return false;
    isolated_.clear();
    for (size_t v = 0; v < nv; ++v)
        if (samples[v].face == kNoControlFace)
            isolated_.push_back(uint32_t(v));

    // Each border vertex's partial sums, in tile order.
    const size_t ring = borderSlots_.size();
    std::vector<uint32_t> count(nv + 1, 0);
    for (size_t g = 0; g < nf0; ++g)
        for (size_t b = 0; b < ring; ++b)
            ++count[(slots_[g * slotCount_ + borderSlots_[b]] & kIndexMask) + 1];
    borderVertices_.clear();
    borderOffsets_.assign(1, 0);
    std::vector<uint32_t> start(nv, 0);
    uint32_t total = 0;
    for (size_t v = 0; v < nv; ++v) {
        start[v] = total;
        if (count[v + 1]) {
            borderVertices_.push_back(uint32_t(v));
            total += count[v + 1];
            borderOffsets_.push_back(total);
        }
    }
    borderEntries_.resize(total);
    for (size_t g = 0; g < nf0; ++g)
        for (size_t b = 0; b < ring; ++b)
            borderEntries_[start[slots_[g * slotCount_ + borderSlots_[b]] & kIndexMask]++] = uint32_t(g * ring + b);
    partials_.assign(nf0 * ring, glm::vec3(0.0f));
    if (plan_.scheme() == Scheme::Smooth)
        buildLimitTiles();
    return true;
}

// The smooth scheme per tile: the limit stencils of the tile's slots
// (OpenSubdiv's, as Plan::flattenStencils gives them) gathered into one
// dense matrix per tile over the control points they use, three weight rows
// (position, d/ds, d/dt) per point, padded to whole vectors and stored a
// vector of slots at a time: [chunk][point][position, d/ds, d/dt][lane].  A
// frame then streams each matrix once, where the per-vertex stencils gather
// the same control points again and again.
//
// Most tiles share their matrix: every regular patch evaluates the same box
// spline at the same slots.  A tile's points are put in a canonical order
// (by their weight columns) and its matrix is kept once for all the tiles
// whose canonical matrices agree within kShareTolerance (weights are at
// most 1; float rounding of the same evaluation in another face's patch
// differs by a few ulps).  The frame then reads each tile's control points
// and a matrix that stays in cache, instead of streaming ~200 bytes of
// weights per vertex.
void FrameEvaluator::buildLimitTiles()
{
    constexpr float kShareTolerance = 1e-6f;
    Plan::FlatStencils flat;
    plan_.flattenStencils(&flat);
    const size_t nf0 = plan_.controlTriangles().size() / 3, stride = detail::wholeVectors(slotCount_);
    std::vector<int32_t> local(plan_.controlVertexCount(), -1);
    limitOffsets_.assign(1, 0);
    limitControl_.clear();
    for (size_t g = 0; g < nf0; ++g) {
        const size_t first = limitControl_.size();
        for (size_t k = 0; k < slotCount_; ++k) {
            const uint32_t v = slots_[g * slotCount_ + k] & kIndexMask;
            for (uint32_t e = flat.offsets[v]; e < flat.offsets[v + 1]; ++e)
                if (local[flat.indices[e]] < 0) {
                    local[flat.indices[e]] = int32_t(limitControl_.size() - first);
                    limitControl_.push_back(flat.indices[e]);
                }
        }
        for (size_t i = first; i < limitControl_.size(); ++i)
            local[limitControl_[i]] = -1;
        limitOffsets_.push_back(uint32_t(limitControl_.size()));
    }
    limitWeights_.clear();
    limitMatrix_.assign(nf0, 0);
    std::vector<float> block, column, canonical;
    std::vector<uint32_t> order;
    // Shared matrices by a hash of their rounded weights; a hit is checked
    // against the tolerance (a near-tie that rounds apart only loses sharing).
    std::unordered_multimap<uint64_t, std::pair<size_t, size_t>> shared;  // hash -> (start, points)
    for (size_t g = 0; g < nf0; ++g) {
        const uint32_t first = limitOffsets_[g];
        const size_t points = limitOffsets_[g + 1] - first, rows = stride / detail::kLanes;
        for (uint32_t i = first; i < limitOffsets_[g + 1]; ++i)
            local[limitControl_[i]] = int32_t(i - first);
        block.assign(3 * stride * points, 0.0f);
        for (size_t k = 0; k < slotCount_; ++k) {
            const uint32_t v = slots_[g * slotCount_ + k] & kIndexMask;
            const size_t chunk = k / detail::kLanes, lane = k % detail::kLanes;
            for (uint32_t e = flat.offsets[v]; e < flat.offsets[v + 1]; ++e) {
                float* row = block.data() + 3 * detail::kLanes * (chunk * points + size_t(local[flat.indices[e]])) + lane;
                for (int c = 0; c < 3; ++c)
                    row[size_t(c) * detail::kLanes] += flat.weights[3 * size_t(e) + size_t(c)];
            }
        }
        for (uint32_t i = first; i < limitOffsets_[g + 1]; ++i)
            local[limitControl_[i]] = -1;
        // Canonical point order: by weight column, compared lexicographically.
        column.resize(points * rows * 3 * detail::kLanes);
        for (size_t pt = 0; pt < points; ++pt)
            for (size_t chunk = 0; chunk < rows; ++chunk)
                std::copy_n(block.data() + 3 * detail::kLanes * (chunk * points + pt), 3 * detail::kLanes,
                            column.data() + (pt * rows + chunk) * 3 * detail::kLanes);
        const size_t length = rows * 3 * detail::kLanes;
        order.resize(points);
        for (uint32_t pt = 0; pt < points; ++pt)
            order[pt] = pt;
        // Compared rounded (a strict order that a few ulps rarely change).
        auto rounded = [&](float w) { return std::lround(double(w) / (64.0 * double(kShareTolerance))); };
        std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
            const float *x = column.data() + size_t(a) * length, *y = column.data() + size_t(b) * length;
            for (size_t i = 0; i < length; ++i)
                if (rounded(x[i]) != rounded(y[i]))
                    return rounded(x[i]) < rounded(y[i]);
            return false;
        });
        canonical.resize(block.size());
        for (size_t chunk = 0; chunk < rows; ++chunk)
            for (size_t pt = 0; pt < points; ++pt)
                std::copy_n(column.data() + (size_t(order[pt]) * rows + chunk) * 3 * detail::kLanes, 3 * detail::kLanes,
                            canonical.data() + 3 * detail::kLanes * (chunk * points + pt));
        std::vector<uint32_t> control(limitControl_.begin() + first, limitControl_.begin() + first + long(points));
        for (size_t pt = 0; pt < points; ++pt)
            limitControl_[first + pt] = control[order[pt]];
        uint64_t hash = 1469598103934665603ull ^ points;
        for (float w : canonical)
            hash = (hash ^ uint64_t(int64_t(std::lround(double(w) / (256.0 * double(kShareTolerance)))))) *
                   1099511628211ull;
        size_t at = limitWeights_.size();
        for (auto [it, end] = shared.equal_range(hash); it != end; ++it) {
            if (it->second.second != points)
                continue;  // a collision between matrices of other sizes
            const float* w = limitWeights_.data() + it->second.first;
            bool same = true;
            for (size_t i = 0; i < canonical.size() && same; ++i)
                same = std::fabs(w[i] - canonical[i]) <= kShareTolerance;
            if (same) {
                at = it->second.first;
                break;
            }
        }
        if (at == limitWeights_.size()) {
            limitWeights_.insert(limitWeights_.end(), canonical.begin(), canonical.end());
            shared.emplace(hash, std::make_pair(at, points));
        }
        limitMatrix_[g] = at;
    }
    limitWeights_.shrink_to_fit();
}

// Tile layout: each tile's own vertices in slot order, tile after tile,
// then the isolated vertices.
void FrameEvaluator::buildTileLayout()
{
    const size_t nv = plan_.refinedVertexCount(), nf0 = plan_.controlTriangles().size() / 3;
    std::vector<uint32_t> out(nv, kUnset);
    order_.resize(nv);
    ownedSlots_.resize(nv);
    tileFirst_.resize(nf0 + 1);
    uint32_t next = 0;
    for (size_t g = 0; g < nf0; ++g) {
        tileFirst_[g] = next;
        for (size_t k = 0; k < slotCount_; ++k) {
            const uint32_t raw = slots_[g * slotCount_ + k];
            if (raw & kOwned) {
                order_[next] = raw & kIndexMask;
                ownedSlots_[next] = uint16_t(k);
                out[raw & kIndexMask] = next++;
            }
        }
    }
    tileFirst_[nf0] = next;
    for (uint32_t v : isolated_) {
        order_[next] = v;
        out[v] = next++;
    }
    // Border vertices in frame order, so their normals are written in order.
    const size_t nb = borderVertices_.size();
    std::vector<uint32_t> byOut(nb);
    for (size_t u = 0; u < nb; ++u)
        byOut[u] = uint32_t(u);
    std::sort(byOut.begin(), byOut.end(),
              [&](uint32_t a, uint32_t b) { return out[borderVertices_[a]] < out[borderVertices_[b]]; });
    std::vector<uint32_t> vertices(nb), offsets(nb + 1), entries(borderEntries_.size());
    offsets[0] = 0;
    for (size_t u = 0; u < nb; ++u) {
        const uint32_t src = byOut[u];
        vertices[u] = out[borderVertices_[src]];
        const uint32_t* b = borderEntries_.data() + borderOffsets_[src];
        const uint32_t count = borderOffsets_[src + 1] - borderOffsets_[src];
        std::copy(b, b + count, entries.begin() + offsets[u]);
        offsets[u + 1] = offsets[u] + count;
    }
    borderVertices_.swap(vertices);
    borderOffsets_.swap(offsets);
    borderEntries_.swap(entries);
    const std::vector<uint32_t>& tri = plan_.refinedTriangles();
    triangles_.resize(tri.size());
    for (size_t i = 0; i < tri.size(); ++i)
        triangles_[i] = out[tri[i]];
}

bool FrameEvaluator::tiled()
{
    buildTables();
    return tiled_;
}

FrameLayout FrameEvaluator::layout()
{
    buildTables();
    return tiled_ ? requested_ : FrameLayout::Plan;
}

const std::vector<uint32_t>& FrameEvaluator::vertexOrder()
{
    if (layout() == FrameLayout::Plan && order_.size() != plan_.refinedVertexCount()) {
        order_.resize(plan_.refinedVertexCount());
        for (size_t v = 0; v < order_.size(); ++v)
            order_[v] = uint32_t(v);
    }
    return order_;
}

const std::vector<uint32_t>& FrameEvaluator::triangles()
{
    return layout() == FrameLayout::Tiles ? triangles_ : plan_.refinedTriangles();
}

namespace {
// Everything one range of tiles reads and writes (FrameEvaluator::shadeTiles).
struct TileJob {
    size_t R, S, ring;
    const uint32_t *control, *rows, *slots, *borderSlots;
    const float *w1, *w2, *d;
    const glm::vec3 *cp, *cn;
    glm::vec3 *positions, *normals, *partials;  // normals null: positions only
    const uint32_t* tileFirst;  // tile layout: each tile's first frame vertex (null: the plan's order)
    const uint16_t* ownedSlots; // tile layout: per frame vertex, its slot in its tile
    float* dl;               // S: each slot's displacement
    float* p[3];             // S: displaced positions
    float* sum[3];           // S: sums of face normals
    float* face[3][2][3];    // [pair % 3][up, down][x, y, z]: face normals one slot right, zero pads
    const float* zero;       // zeros, as long as a pair buffer
    // Smooth scheme: per tile, its control points (limitOffsets[f] ..
    // limitOffsets[f + 1] of limitControl) and their weights from
    // limitWeights + limitMatrix[f] (shared between tiles), [chunk of detail::kLanes
    // slots][point][position, d/ds, d/dt][lane]; limit: 9 sums per slot.
    const uint32_t *limitOffsets, *limitControl;
    const float* limitWeights;
    const size_t* limitMatrix;  // per tile: where its matrix starts in limitWeights
    float* limit[9];
};

// Writes tile f's own vertices: positions p and, with Normals, unit normals
// n (structure of arrays, by slot).  In the tile layout they are the tile's
// run of frame vertices, their slots listed; in the plan's order each owned
// slot names its vertex.
template <bool Normals>
STRATA_KERNEL_INLINE void writeOwned(const TileJob& job, size_t f, float* const* p, float* const* n)
{
    if (job.tileFirst) {
        for (size_t out = job.tileFirst[f]; out < job.tileFirst[f + 1]; ++out) {
            const size_t k = job.ownedSlots[out];
            job.positions[out] = glm::vec3(p[0][k], p[1][k], p[2][k]);
            if (Normals)
                job.normals[out] = glm::vec3(n[0][k], n[1][k], n[2][k]);
        }
        return;
    }
    const uint32_t* slot = job.slots + f * job.S;
    for (size_t k = 0; k < job.S; ++k) {
        const uint32_t raw = slot[k];
        if (raw & kOwned) {
            const size_t v = raw & kIndexMask;
            job.positions[v] = glm::vec3(p[0][k], p[1][k], p[2][k]);
            if (Normals)
                job.normals[v] = glm::vec3(n[0][k], n[1][k], n[2][k]);
        }
    }
}

// The tiles of faces [faceBegin, faceEnd).  kR: the grid's resolution when
// fixed at compile time (0: job.R); at levels 3 and 4 (rows of at most 9
// and 17 slots) the rows then unroll into constant-size vector loops,
// 6-15% faster than the general loop (bench_animation and bench_runtime).
template <size_t kR>
STRATA_KERNEL_INLINE void shadeTileGrid(const TileJob& job, size_t faceBegin, size_t faceEnd)
{
    const size_t R = kR ? kR : job.R, S = kR ? (kR + 1) * (kR + 2) / 2 : job.S, ring = job.ring;
    const uint32_t* rows = job.rows;
    float* dl = job.dl;
    float* const* p = job.p;
    float* const* sum = job.sum;
    for (size_t f = faceBegin; f < faceEnd; ++f) {
        const uint32_t* c = job.control + 3 * f;
        const uint32_t* slot = job.slots + f * S;
        const glm::vec3* cp = job.cp;
        const glm::vec3* cn = job.cn;
        for (size_t k = 0; k < S; ++k)
            dl[k] = job.d[slot[k] & kIndexMask];
        if (job.limitWeights) {
            const size_t stride = detail::wholeVectors(S);
            const uint32_t first = job.limitOffsets[f], count = job.limitOffsets[f + 1] - first;
            limitGrid(stride, count, job.limitControl + first, job.limitWeights + job.limitMatrix[f], cp, dl,
                      job.limit, p);
        } else {
            // The same expression as Plan::evaluate, so bit-identical.
            detail::displaceGrid(detail::wholeVectors(S), job.w1, job.w2, dl, cp[c[0]], cp[c[1]], cp[c[2]], cn[c[0]], cn[c[1]],
                         cn[c[2]], p[0], p[1], p[2]);
        }
        if (!job.normals) {
            writeOwned<false>(job, f, p, nullptr);
            continue;
        }
        detail::gridNormalSums<kR>(R, rows, p, job.face, job.zero, sum);
        // Border slots keep the tile's share (partials, in borderSlots
        // order); inside the tile the sums are complete.
        glm::vec3* partial = job.partials + f * ring;
        for (size_t b = 0; b < ring; ++b) {
            const uint32_t k = job.borderSlots[b];
            partial[b] = glm::vec3(sum[0][k], sum[1][k], sum[2][k]);
        }
        detail::normalizeGrid(detail::wholeVectors(S), sum[0], sum[1], sum[2]);
        // The tile's own vertices.  A border vertex's normal written here is
        // the tile's share only; the border pass, which runs after every
        // tile, overwrites it with the whole sum.
        writeOwned<true>(job, f, p, sum);
    }
}

STRATA_KERNEL_CLONES void shadeTileRange(const TileJob& job, size_t faceBegin, size_t faceEnd)
{
    if (job.R == 8)
        shadeTileGrid<8>(job, faceBegin, faceEnd);
    else if (job.R == 16)
        shadeTileGrid<16>(job, faceBegin, faceEnd);
    else
        shadeTileGrid<0>(job, faceBegin, faceEnd);
}

}  // namespace

void FrameEvaluator::shadeTiles(Scratch& s, glm::vec3* positions, glm::vec3* normals, const float* d,
                                const glm::vec3* cp, const glm::vec3* cn, size_t faceBegin, size_t faceEnd)
{
    TileJob job{};
    job.R = size_t(resolution_);
    job.S = slotCount_;
    job.ring = borderSlots_.size();
    job.control = plan_.controlTriangles().data();
    job.rows = rowStart_.data();
    job.slots = slots_.data();
    job.borderSlots = borderSlots_.data();
    job.w1 = slotW1_.data();
    job.w2 = slotW2_.data();
    job.d = d;
    job.cp = cp;
    job.cn = cn;
    job.positions = positions;
    job.normals = normals;
    job.partials = partials_.data();
    job.zero = s.zero.data();
    if (!limitWeights_.empty()) {
        job.limitOffsets = limitOffsets_.data();
        job.limitControl = limitControl_.data();
        job.limitWeights = limitWeights_.data();
        job.limitMatrix = limitMatrix_.data();
        for (int a = 0; a < 9; ++a)
            job.limit[a] = s.limit[a].data();
    }
    job.tileFirst = requested_ == FrameLayout::Tiles ? tileFirst_.data() : nullptr;
    job.ownedSlots = ownedSlots_.data();
    job.dl = s.d.data();
    job.p[0] = s.px.data();
    job.p[1] = s.py.data();
    job.p[2] = s.pz.data();
    for (int a = 0; a < 3; ++a) {
        job.sum[a] = s.sum[a].data();
        for (int pair = 0; pair < 3; ++pair)
            for (int kind = 0; kind < 2; ++kind)
                job.face[pair][kind][a] = s.face[pair][kind][a].data();
    }
    shadeTileRange(job, faceBegin, faceEnd);
}

void FrameEvaluator::finishBorders(glm::vec3* normals, size_t begin, size_t end) const
{
    detail::finishBorders(normals, borderVertices_.data(), borderOffsets_.data(), borderEntries_.data(),
                          partials_.data(), begin, end);
}

void FrameEvaluator::faceNormals(const glm::vec3* p, size_t begin, size_t end)
{
    const uint32_t* tri = plan_.refinedTriangles().data();
    for (size_t f = begin; f < end; ++f) {
        const uint32_t* c = tri + 3 * f;
        faceNormals_[f] = glm::cross(p[c[1]] - p[c[0]], p[c[2]] - p[c[0]]);  // |cross| is twice the area
    }
}

void FrameEvaluator::vertexNormals(glm::vec3* dst, size_t begin, size_t end) const
{
    for (size_t v = begin; v < end; ++v) {
        glm::vec3 n(0.0f);
        for (uint32_t i = offsets_[v]; i < offsets_[v + 1]; ++i)
            n += faceNormals_[faces_[i]];
        dst[v] = unitOrZero(n);
    }
}

Status FrameEvaluator::evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                                const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                                int threads)
{
    const size_t nv = plan_.refinedVertexCount();
    const float* d = displacements ? displacements : plan_.displacements().data();
    // An empty range validates the arguments.
    Status st = plan_.evaluate(positions, nullptr, 0, 0, d, controlPositions, controlNormals, controlCount);
    if (!st)
        return st;
    if (!positions)
        return Status(StatusCode::InvalidArgument, "FrameEvaluator: null positions");
    threads = std::max(1, std::min(threads, 64));
    if (nv < 4096)
        threads = 1;
    auto positionsOnly = [&] {
        parallel(threads, nv, [&](size_t b, size_t e, int) {
            plan_.evaluate(positions + b, nullptr, b, e, d, controlPositions, controlNormals, controlCount);
        });
    };
    // The tile layout needs the tiles even for positions alone; the plan's
    // order streams them from Plan::evaluate.
    if (!normals && requested_ == FrameLayout::Plan && plan_.scheme() == Scheme::Linear) {
        positionsOnly();
        return Status::ok();
    }
    buildTables();
    if (tiled_) {
        if (scratch_.size() < size_t(threads)) {
            scratch_.resize(size_t(threads));
            for (Scratch& s : scratch_)
                s.resize(slotCount_, size_t(resolution_) + 1, plan_.scheme() == Scheme::Smooth);
        }
        const size_t nf0 = plan_.controlTriangles().size() / 3;
        parallel(threads, nf0, [&](size_t b, size_t e, int t) {
            shadeTiles(scratch_[size_t(t)], positions, normals, d, controlPositions, controlNormals, b, e);
        });
        if (normals)
            parallel(threads, borderVertices_.size(), [&](size_t b, size_t e, int) { finishBorders(normals, b, e); });
        const bool tiles = requested_ == FrameLayout::Tiles;
        for (size_t r = 0; r < isolated_.size(); ++r) {
            const uint32_t v = isolated_[r];
            const size_t out = tiles ? tileFirst_.back() + r : v;
            plan_.evaluate(positions + out, nullptr, v, v + 1, d, controlPositions, controlNormals, controlCount);
            if (normals)
                normals[out] = glm::vec3(0.0f);
        }
        return Status::ok();
    }
    positionsOnly();
    if (!normals)
        return Status::ok();
    parallel(threads, faceNormals_.size(), [&](size_t b, size_t e, int) { faceNormals(positions, b, e); });
    parallel(threads, nv, [&](size_t b, size_t e, int) { vertexNormals(normals, b, e); });
    return Status::ok();
}

size_t FrameEvaluator::bytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    size_t scratch = 0;
    for (const Scratch& s : scratch_)
        scratch += s.bytes();
    return bytes(limitOffsets_) + bytes(limitControl_) + bytes(limitWeights_) + bytes(limitMatrix_) + bytes(tileFirst_) + bytes(ownedSlots_) + bytes(order_) + bytes(triangles_) + bytes(rowStart_) + bytes(slotW1_) + bytes(slotW2_) + bytes(borderSlots_) + bytes(slots_) +
           bytes(partials_) + bytes(borderVertices_) + bytes(borderOffsets_) + bytes(borderEntries_) +
           bytes(isolated_) + bytes(offsets_) + bytes(faces_) + bytes(faceNormals_) + scratch;
}

}  // namespace strata
