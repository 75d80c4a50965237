// Adaptive level of detail out of one plan (adaptive.h).
#include "strata/adaptive.h"

#include "strata/control_mesh.h"
#include "strata/displacement_math.h"
#include "strata/plane.h"

#include "simd.h"
#include "worker_pool.h"

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace strata {

namespace {

constexpr uint32_t kNone = 0xffffffffu;

// The grid point of each slot of a tile of resolution R.
void slotPoints(std::vector<uint16_t>* is, std::vector<uint16_t>* js, uint32_t R)
{
    const size_t slots = size_t(R + 1) * (R + 2) / 2;
    is->resize(slots);
    js->resize(slots);
    for (uint32_t j = 0; j <= R; ++j)
        for (uint32_t i = 0; i + j <= R; ++i) {
            const size_t k = tileSlot(i, j, R);
            (*is)[k] = uint16_t(i);
            (*js)[k] = uint16_t(j);
        }
}

// Calls fn(i, j, w, area) for every grid point (i, j) of a tile of
// resolution R inside or on the counter-clockwise grid triangle (gi, gj):
// w are its barycentric weights times `area` (twice the triangle's area).
template <typename Fn>
void rasterGrid(const int gi[3], const int gj[3], int R, const Fn& fn)
{
    const glm::ivec2 g[3] = {{gi[0], gj[0]}, {gi[1], gj[1]}, {gi[2], gj[2]}};
    const int area = orient2(g[0], g[1], g[2]);
    if (area <= 0)
        return;
    const int i0 = std::min({gi[0], gi[1], gi[2]}), i1 = std::max({gi[0], gi[1], gi[2]});
    const int j0 = std::min({gj[0], gj[1], gj[2]}), j1 = std::max({gj[0], gj[1], gj[2]});
    for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1 && i + j <= R; ++i) {
            int w[3];
            bool inside = true;
            for (int k = 0; k < 3 && inside; ++k) {
                w[k] = orient2(g[(k + 1) % 3], g[(k + 2) % 3], glm::ivec2(i, j));
                inside = w[k] >= 0;
            }
            if (inside)
                fn(i, j, w, area);
        }
}

// The orthonormal camera frame of a view and its projection to pixels.
struct Camera {
    glm::vec3 eye, forward, right, up;
    float k;  // pixels per unit at distance 1
    explicit Camera(const ViewSpec& v) : eye(v.eye), k(v.pixelsPerUnitAtDistanceOne())
    {
        forward = glm::normalize(v.target - v.eye);
        const glm::vec3 worldUp = std::fabs(forward.y) > 0.999f ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
        right = glm::normalize(glm::cross(forward, worldUp));
        up = glm::cross(right, forward);
    }
    // Pixel coordinates of p, false behind the eye.
    bool project(glm::vec3 p, float* x, float* y) const
    {
        const glm::vec3 q = p - eye;
        const float z = glm::dot(q, forward);
        if (!(z > 0.0f))
            return false;
        *x = k * glm::dot(q, right) / z;
        *y = k * glm::dot(q, up) / z;
        return true;
    }
};

}  // namespace

float ViewSpec::pixelsPerUnitAtDistanceOne() const
{
    const float halfFov = 0.5f * fovYDegrees * 3.14159265358979f / 180.0f;
    return heightPx / (2.0f * std::tan(halfFov));
}

bool ViewSpec::valid() const
{
    auto finite = [](glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); };
    return finite(eye) && finite(target) && glm::length(target - eye) > 0.0f && std::isfinite(fovYDegrees) &&
           fovYDegrees > 0.0f && fovYDegrees < 180.0f && std::isfinite(heightPx) && heightPx > 0.0f;
}

namespace {

// Where grid point (i, j) of a tile at `level` is drawn when its edges are
// at edgeLevels: a point on an edge drawn coarser snaps along it to the
// nearest point that edge keeps (a tie to the one nearer the edge's first
// corner in the face's order); corners and inner points stay.
void snapPoint(uint32_t* i, uint32_t* j, int level, const int edgeLevels[3])
{
    const uint32_t R = 1u << level;
    auto snap = [&](uint32_t t, int edgeLevel) {
        const uint32_t m = 1u << (level - edgeLevel);
        return m == 1 ? t : (t + m / 2 - 1) / m * m;
    };
    if (*j == 0 && *i != 0 && *i != R) {  // edge 0: corner 0 -> 1, t = i
        *i = snap(*i, edgeLevels[0]);
    } else if (*i + *j == R && *i != 0 && *j != 0) {  // edge 1: corner 1 -> 2, t = j
        *j = snap(*j, edgeLevels[1]);
        *i = R - *j;
    } else if (*i == 0 && *j != 0 && *j != R) {  // edge 2: corner 2 -> 0, t = R - j
        *j = R - snap(R - *j, edgeLevels[2]);
    }
}

// The index of a (level, edge levels) template among (finest + 1)^4.
size_t templateKey(int finest, int level, const int e[3])
{
    const size_t n = size_t(finest + 1);
    return ((size_t(level) * n + size_t(e[0])) * n + size_t(e[1])) * n + size_t(e[2]);
}

// Per face corner (3 f + k, the edge from corner k to k + 1), its edge in `edges`.
std::vector<uint32_t> cornerEdges(const EdgeGroups& edges, size_t faceCount)
{
    std::vector<uint32_t> edgeOf(3 * faceCount, 0);
    for (size_t e = 0; e < edges.edgeCount(); ++e)
        for (uint32_t k = 0; k < edges.faceCountOf(e); ++k)
            edgeOf[edges.cornersOf(e)[k]] = uint32_t(e);
    return edgeOf;
}

// Each edge at the lowest level of the faces that share it.
void edgeLevelsFor(std::vector<uint8_t>* edgeLevels, const uint8_t* levels, const std::vector<uint32_t>& edgeOf,
                   int finest)
{
    std::fill(edgeLevels->begin(), edgeLevels->end(), uint8_t(finest));
    for (size_t c = 0; c < edgeOf.size(); ++c)
        (*edgeLevels)[edgeOf[c]] = std::min((*edgeLevels)[edgeOf[c]], levels[c / 3]);
}

}  // namespace

void adaptiveTileTriangles(std::vector<uint16_t>* out, int finest, int level, const int edgeLevels[3])
{
    out->clear();
    const uint32_t R = 1u << level, fineR = 1u << finest, step = 1u << (finest - level);
    auto point = [&](uint32_t i, uint32_t j) {
        snapPoint(&i, &j, level, edgeLevels);
        return uint16_t(tileSlot(i * step, j * step, fineR));
    };
    auto emit = [&](uint16_t a, uint16_t b, uint16_t c) {
        if (a == b || b == c || c == a)
            return;  // collapsed onto a coarser edge
        out->push_back(a);
        out->push_back(b);
        out->push_back(c);
    };
    for (uint32_t j = 0; j < R; ++j)
        for (uint32_t i = 0; i + j < R; ++i) {
            emit(point(i, j), point(i + 1, j), point(i, j + 1));
            if (i + j + 1 < R)
                emit(point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
        }
}

LevelChooser::LevelChooser() = default;
LevelChooser::~LevelChooser() = default;

float LevelChooser::templateError(const std::vector<uint16_t>& t, size_t face) const
{
    const uint32_t R = 1u << errors_.finest;
    const uint32_t* tile = &tiles_[face * slots_];
    const glm::vec3* p = rest_.data();
    float worst = 0.0f;
    for (size_t k = 0; k < t.size(); k += 3) {
        const int gi[3] = {slotI_[t[k]], slotI_[t[k + 1]], slotI_[t[k + 2]]};
        const int gj[3] = {slotJ_[t[k]], slotJ_[t[k + 1]], slotJ_[t[k + 2]]};
        const glm::vec3 q[3] = {p[tile[t[k]]], p[tile[t[k + 1]]], p[tile[t[k + 2]]]};
        rasterGrid(gi, gj, int(R), [&](int i, int j, const int w[3], int area) {
            const glm::vec3 drawn = (float(w[0]) * q[0] + float(w[1]) * q[1] + float(w[2]) * q[2]) / float(area);
            worst = std::max(worst, glm::length(p[tile[tileSlot(uint32_t(i), uint32_t(j), R)]] - drawn));
        });
    }
    return worst;
}

const std::vector<uint16_t>& LevelChooser::tileTemplate(int level, const int e[3])
{
    std::vector<uint16_t>& t = templates_[templateKey(errors_.finest, level, e)];
    if (t.empty())
        adaptiveTileTriangles(&t, errors_.finest, level, e);
    return t;
}

Status LevelChooser::init(const Plan& plan, const float* displacements, const glm::vec3* controlPositions,
                          const glm::vec3* controlNormals, size_t controlCount, int threads)
{
    std::vector<uint32_t> tiles;
    if (Status st = plan.tileVertices(&tiles); !st)
        return st;
    const size_t nv = plan.refinedVertexCount();
    std::vector<glm::vec3> rest(nv);
    if (Status st = plan.evaluate(rest.data(), nullptr, 0, nv, displacements ? displacements : plan.displacements().data(),
                                  controlPositions, controlNormals, controlCount);
        !st)
        return st;
    const int L = plan.level();
    const uint32_t R = 1u << L;
    tiles_ = std::move(tiles);
    rest_ = std::move(rest);
    slots_ = size_t(R + 1) * (R + 2) / 2;
    controlTriangles_ = plan.controlTriangles();
    controlCount_ = plan.controlVertexCount();
    const size_t nf = controlTriangles_.size() / 3;
    slotPoints(&slotI_, &slotJ_, R);
    edges_ = groupEdges(controlTriangles_.data(), nf);
    edgeOf_ = cornerEdges(edges_, nf);
    edgeLevels_.assign(edges_.edgeCount(), 0);
    templates_.assign(size_t(L + 1) * size_t(L + 1) * size_t(L + 1) * size_t(L + 1), {});
    stitched_.clear();
    gains_.assign(nf, 0.0f);

    FaceLevelErrors& e = errors_;
    e.finest = L;
    e.faceCount = nf;
    e.error.assign(nf * size_t(L + 1), 0.0f);
    e.reach.assign(nf, 0.0f);
    for (int l = 0; l <= L; ++l) {
        const int same[3] = {l, l, l};
        tileTemplate(l, same);
    }
    auto faces = [&](size_t begin, size_t end, int) {
        for (size_t f = begin; f < end; ++f) {
            const uint32_t* tile = &tiles_[f * slots_];
            const uint32_t* c = &controlTriangles_[3 * f];
            const glm::vec3 centroid = (controlPositions[c[0]] + controlPositions[c[1]] + controlPositions[c[2]]) / 3.0f;
            float reach = 0.0f;
            for (size_t k = 0; k < slots_; ++k)
                reach = std::max(reach, glm::length(rest_[tile[k]] - centroid));
            e.reach[f] = reach;
            float* err = &e.error[f * size_t(L + 1)];
            for (int l = L - 1; l >= 0; --l) {
                const int same[3] = {l, l, l};  // built above
                err[l] = std::max(templateError(templates_[templateKey(L, l, same)], f), err[l + 1]);
            }
        }
    };
    if (threads > 1) {
        detail::WorkerPool pool(threads);
        pool.run(nf, faces);
    } else {
        faces(0, nf, 0);
    }
    return Status::ok();
}

float LevelChooser::stitchedError(size_t face, int level, const int e[3])
{
    if (e[0] >= level && e[1] >= level && e[2] >= level)
        return errors_.at(face, level);
    const uint64_t key = uint64_t(face) << 12 | uint64_t(level) << 9 | uint64_t(e[0]) << 6 | uint64_t(e[1]) << 3 |
                         uint64_t(e[2]);
    const auto found = stitched_.find(key);
    if (found != stitched_.end())
        return found->second;
    const float error = templateError(tileTemplate(level, e), face);
    stitched_.emplace(key, error);
    return error;
}

size_t LevelChooser::bytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    size_t t = 0;
    for (const std::vector<uint16_t>& v : templates_)
        t += bytes(v);
    return t + bytes(errors_.error) + bytes(errors_.reach) + bytes(rest_) + bytes(tiles_) + bytes(controlTriangles_) +
           bytes(slotI_) + bytes(slotJ_) + bytes(edges_.corners) + bytes(edges_.offsets) + bytes(edgeOf_) +
           bytes(edgeLevels_) + bytes(gains_) + stitched_.size() * (sizeof(uint64_t) + sizeof(float) + 2 * sizeof(void*));
}

float skinScale(const float* m, size_t count)
{
    float worst = 1.0f;
    for (size_t n = 0; n < count; ++n, m += 16) {
        // Largest eigenvalue of A^T A (A: the upper 3x3, column-major) by
        // the closed form for symmetric 3x3 matrices.
        double a[3][3];
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) {
                double s = 0.0;
                for (int k = 0; k < 3; ++k)
                    s += double(m[4 * r + k]) * double(m[4 * c + k]);
                a[r][c] = s;
            }
        const double p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        const double q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
        double top;
        if (p1 <= 1e-30 * (q * q + 1e-300)) {
            top = std::max(a[0][0], std::max(a[1][1], a[2][2]));
        } else {
            const double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) + (a[2][2] - q) * (a[2][2] - q) + 2.0 * p1;
            const double p = std::sqrt(p2 / 6.0);
            double b[3][3];
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c)
                    b[r][c] = (a[r][c] - (r == c ? q : 0.0)) / p;
            const double det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) -
                               b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0]) +
                               b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
            const double r = std::max(-1.0, std::min(1.0, det / 2.0));
            top = q + 2.0 * p * std::cos(std::acos(r) / 3.0);
        }
        const float sigma = float(std::sqrt(std::max(0.0, top)));
        if (std::isfinite(sigma))
            worst = std::max(worst, sigma);
    }
    return worst;
}

Status LevelChooser::choose(uint8_t* levels, const ViewSpec& view, float pixelError, const glm::vec3* controlPositions,
                            size_t controlCount, float poseScale)
{
    const int L = errors_.finest;
    const size_t nf = errors_.faceCount;
    if (!levels || (nf > 0 && !controlPositions))
        return Status(StatusCode::InvalidArgument, "LevelChooser::choose: null buffer");
    if (controlCount != controlCount_)
        return Status(StatusCode::InvalidArgument, std::to_string(controlCount) + " control positions for " +
                                                       std::to_string(controlCount_) + " control vertices");
    if (!view.valid())
        return Status(StatusCode::InvalidArgument, "the view is not a view (eye and target must differ, the field of view "
                                                   "lie in (0, 180) degrees and the height be positive)");
    if (!(pixelError > 0.0f) || !std::isfinite(pixelError))
        return Status(StatusCode::InvalidArgument, "the pixel tolerance must be a positive number");
    if (!(poseScale >= 1.0f) || !std::isfinite(poseScale))
        poseScale = 1.0f;
    const Camera cam(view);
    // Pixels per model unit of error at each face: at the nearest point of
    // a sphere around it, and at the largest angle off the view axis within
    // the sphere (an error there moves up to 1 / cos^2 as many pixels as on
    // the axis).  Infinite when the eye is inside the sphere, 0 when the
    // sphere is wholly behind the eye.
    for (size_t f = 0; f < nf; ++f) {
        const uint32_t* c = &controlTriangles_[3 * f];
        const glm::vec3 centre = (controlPositions[c[0]] + controlPositions[c[1]] + controlPositions[c[2]]) / 3.0f;
        const float r = errors_.reach[f] * poseScale;
        const glm::vec3 q = centre - cam.eye;
        const float d = glm::length(q);
        float g;
        if (!(d > r)) {
            g = std::numeric_limits<float>::infinity();
        } else {
            const float axis = std::acos(std::max(-1.0f, std::min(1.0f, glm::dot(q, cam.forward) / d)));
            const float spread = std::asin(std::min(1.0f, r / d));
            if (axis - spread >= 1.5707f) {
                g = 0.0f;
            } else {
                const float cosine = std::cos(std::min(axis + spread, 1.0472f));  // past 60 degrees: off any screen
                g = cam.k * poseScale / ((d - r) * cosine * cosine);
            }
        }
        gains_[f] = g;
        int level = L;
        for (int l = 0; l < L; ++l)
            if (errors_.at(f, l) * g <= pixelError) {
                level = l;
                break;
            }
        levels[f] = uint8_t(level);
    }
    // Stitching: where a face meets coarser edges its strips (and corners,
    // where two coarse edges meet) may stray further than the face or its
    // neighbours alone.  While one does, the coarsest neighbour across its
    // coarsest edge goes up a level (levels only rise, so this ends).
    for (bool changed = true; changed;) {
        changed = false;
        edgeLevelsFor(&edgeLevels_, levels, edgeOf_, L);
        for (size_t f = 0; f < nf; ++f) {
            const int l = levels[f];
            const int e[3] = {edgeLevels_[edgeOf_[3 * f]], edgeLevels_[edgeOf_[3 * f + 1]], edgeLevels_[edgeOf_[3 * f + 2]]};
            if ((e[0] >= l && e[1] >= l && e[2] >= l) || stitchedError(f, l, e) * gains_[f] <= pixelError)
                continue;
            const int k = e[0] <= e[1] && e[0] <= e[2] ? 0 : e[1] <= e[2] ? 1 : 2;
            const uint32_t edge = edgeOf_[3 * f + size_t(k)];
            for (uint32_t m = 0; m < edges_.faceCountOf(edge); ++m) {
                uint8_t& other = levels[edges_.cornersOf(edge)[m] / 3];
                if (other == e[k])
                    other = uint8_t(e[k] + 1);
            }
            edgeLevels_[edge] = uint8_t(e[k] + 1);  // at least; recomputed next pass
            changed = true;
        }
    }
    return Status::ok();
}

// The tile pass's working arrays (structure of arrays): the grid's
// positions and sums, per slot; the up and down triangles' normals, per row
// with a zero before (never written) and one after (written per tile); row
// -1 is a zero row, never written.
void AdaptiveFrame::Scratch::resize(int finest)
{
    const size_t R = size_t(1) << finest, width = (R + 2 + 7) / 8 * 8 + 8;
    rowWidth = width;
    for (std::vector<float>* v : {&px, &py, &pz, &sx, &sy, &sz})
        v->assign((R + 1) * (R + 2) / 2 + 2 * width, 0.0f);  // every slot, and whole vectors past the last rows
    for (int a = 0; a < 3; ++a) {
        up[a].assign((R + 2) * width, 0.0f);
        down[a].assign((R + 2) * width, 0.0f);
    }
}

namespace {

// Slot (i, j) sums up(i, j), up(i - 1, j), up(i, j - 1), down(i - 1, j),
// down(i - 1, j - 1) and down(i, j - 1): in the padded rows (entry x of a
// row is triangle x - 1) entries i + 1 and i of rows j and j - 1.
STRATA_KERNEL_INLINE void sumRowSoA(size_t n, const float* __restrict u, const float* __restrict uBelow,
                                    const float* __restrict d, const float* __restrict dBelow, float* __restrict out)
{
    for (size_t i = 0; i < n; ++i)
        out[i] = u[i + 1] + u[i] + uBelow[i + 1] + d[i] + dBelow[i] + dBelow[i + 1];
}


// One tile at resolution R (kR: fixed at compile time, so a small tile's
// short rows unroll; 0: the general loop).
template <size_t kR, typename Scratch>
STRATA_KERNEL_INLINE void shadeGrid(size_t rRuntime, const uint32_t* source, const uint32_t* vertex,
                                    const uint32_t* partial, const uint16_t* snapped, size_t snappedCount,
                                    const uint16_t* snapTo, const glm::vec3* positions, glm::vec3* normals,
                                    glm::vec3* partials, Scratch& s)
{
    const size_t R = kR ? kR : rRuntime, W = s.rowWidth;
    const size_t slots = (R + 1) * (R + 2) / 2;
    // Loops run in whole vectors of 8 (no scalar remainders): the scratch
    // rows are padded, and what they write past a row's end is either
    // rewritten (the next row's sums), reset (the zero after each triangle
    // row) or never read.
    auto whole = [](size_t n) { return (n + 7) & ~size_t(7); };
    float* px = s.px.data();
    float* py = s.py.data();
    float* pz = s.pz.data();
    // Positions, by slot (row j starts at tileSlot(0, j, R)).
    for (size_t k = 0; k < slots; ++k) {
        const glm::vec3 p = positions[source[k]];
        px[k] = p.x;
        py[k] = p.y;
        pz[k] = p.z;
    }
    // Triangle normals row by row, into padded rows (entry i + 1: triangle i).
    // Row r of the buffers is grid row r - 1 (buffer row 0: the zero row -1).
    for (size_t j = 0; j < R; ++j) {
        const size_t r0 = tileSlot(0, uint32_t(j), uint32_t(R)), r1 = tileSlot(0, uint32_t(j + 1), uint32_t(R));
        const size_t nu = R - j, nd = R - j - 1, row = (j + 1) * W + 1;
        detail::crossRow(whole(nu), px + r0, py + r0, pz + r0, px + r0 + 1, py + r0 + 1, pz + r0 + 1, px + r1, py + r1, pz + r1,
                    s.up[0].data() + row, s.up[1].data() + row, s.up[2].data() + row);
        detail::crossRow(whole(nd), px + r0 + 1, py + r0 + 1, pz + r0 + 1, px + r1 + 1, py + r1 + 1, pz + r1 + 1, px + r1, py + r1,
                    pz + r1, s.down[0].data() + row, s.down[1].data() + row, s.down[2].data() + row);
        for (int a = 0; a < 3; ++a) {  // the one zero after each row the sums read (earlier tiles left values)
            s.up[a][row + nu] = 0.0f;
            s.down[a][row + nd] = 0.0f;
        }
    }
    for (int a = 0; a < 3; ++a) {  // grid row R has no triangles: the entry its one slot reads
        s.up[a][(R + 1) * W + 1] = 0.0f;
        s.down[a][(R + 1) * W + 1] = 0.0f;
    }
    float* sum[3] = {s.sx.data(), s.sy.data(), s.sz.data()};
    for (size_t j = 0; j <= R; ++j) {
        const size_t r0 = tileSlot(0, uint32_t(j), uint32_t(R)), row = (j + 1) * W, below = j * W;
        for (int a = 0; a < 3; ++a)
            sumRowSoA(whole(R - j + 1), s.up[a].data() + row, s.up[a].data() + below, s.down[a].data() + row,
                      s.down[a].data() + below, sum[a] + r0);
    }
    // A snapped point's triangles are its target's in the stitched tile.
    for (size_t k = 0; k < snappedCount; ++k) {
        const uint16_t from = snapped[k], to = snapTo[from];
        for (int a = 0; a < 3; ++a)
            sum[a][to] += sum[a][from];
    }
    // The border's partial sums (rows 0 and the two slanted sides), then
    // every slot normalised at once (vectorised), then the inner vertices.
    auto keep = [&](size_t k) {
        if (partial[k] != kNone)
            partials[partial[k]] = glm::vec3(sum[0][k], sum[1][k], sum[2][k]);
    };
    for (size_t i = 0; i <= R; ++i)
        keep(i);
    for (size_t j = 1; j <= R; ++j) {
        const size_t r0 = tileSlot(0, uint32_t(j), uint32_t(R));
        keep(r0);
        if (j < R)
            keep(r0 + R - j);
    }
    detail::normalizeGrid(whole(slots), sum[0], sum[1], sum[2]);
    for (size_t k = 0; k < slots; ++k)
        if (vertex[k] != kNone && partial[k] == kNone)
            normals[vertex[k]] = glm::vec3(sum[0][k], sum[1][k], sum[2][k]);
}

}  // namespace

STRATA_KERNEL_CLONES void AdaptiveFrame::shadeAdaptiveTile(int level, const uint32_t* source, const uint32_t* vertex,
                                                           const uint32_t* partial, const uint16_t* snapped,
                                                           size_t snappedCount, const uint16_t* snapTo,
                                                           const glm::vec3* positions, glm::vec3* normals,
                                                           glm::vec3* partials, Scratch& s)
{
    if (level == 0) {
        // The control triangle itself: three corners, all shared, one normal.
        const glm::vec3 a = positions[source[0]];
        const glm::vec3 n = glm::cross(positions[source[1]] - a, positions[source[2]] - a);
        for (int k = 0; k < 3; ++k)
            partials[partial[k]] = n;
        return;
    }
    // Called directly (a lambda here would be compiled for the baseline
    // target, outside this clone).
    const size_t R = size_t(1) << level;
    if (R == 2)
        shadeGrid<2, Scratch>(R, source, vertex, partial, snapped, snappedCount, snapTo, positions, normals, partials, s);
    else if (R == 4)
        shadeGrid<4, Scratch>(R, source, vertex, partial, snapped, snappedCount, snapTo, positions, normals, partials, s);
    else if (R == 8)
        shadeGrid<8, Scratch>(R, source, vertex, partial, snapped, snappedCount, snapTo, positions, normals, partials, s);
    else
        shadeGrid<0, Scratch>(R, source, vertex, partial, snapped, snappedCount, snapTo, positions, normals, partials, s);
}

AdaptiveFrame::AdaptiveFrame(const Plan& plan) : plan_(plan), finest_(plan.level())
{
    const uint32_t R = 1u << finest_;
    slots_ = size_t(R + 1) * (R + 2) / 2;
    if (!plan.tileVertices(&tiles_))
        tiles_.clear();
    slotPoints(&slotI_, &slotJ_, R);
    const std::vector<uint32_t>& control = plan.controlTriangles();
    const size_t nf = control.size() / 3;
    const EdgeGroups edges = groupEdges(control.data(), nf);
    edgeOf_ = cornerEdges(edges, nf);
    edgeLevels_.assign(edges.edgeCount(), 0);
    const size_t combos = size_t(finest_ + 1) * size_t(finest_ + 1) * size_t(finest_ + 1) * size_t(finest_ + 1);
    templates_.resize(combos);
    remap_.assign(plan.refinedVertexCount(), kNone);
}

AdaptiveFrame::~AdaptiveFrame() = default;

size_t AdaptiveFrame::templateFor(int level, const int e[3])
{
    const size_t key = templateKey(finest_, level, e);
    TileTemplate& t = templates_[key];
    if (t.fine.empty()) {
        adaptiveTileTriangles(&t.fine, finest_, level, e);
        // The same triangles in the level's own slots, for the tile pass.
        const uint32_t step = 1u << (finest_ - level), R = 1u << level;
        const size_t slots = size_t(R + 1) * (R + 2) / 2;
        t.local.resize(t.fine.size());
        for (size_t k = 0; k < t.fine.size(); ++k)
            t.local[k] = uint16_t(tileSlot(slotI_[t.fine[k]] / step, slotJ_[t.fine[k]] / step, R));
        // The points snapped onto another (the tile pass reads their
        // target's position and adds their sums into the target's).
        t.snapTo.resize(slots);
        t.snapped.clear();
        for (uint32_t j = 0; j <= R; ++j)
            for (uint32_t i = 0; i + j <= R; ++i) {
                uint32_t si = i, sj = j;
                snapPoint(&si, &sj, level, e);
                const uint16_t from = uint16_t(tileSlot(i, j, R)), to = uint16_t(tileSlot(si, sj, R));
                t.snapTo[from] = to;
                if (from != to)
                    t.snapped.push_back(from);
            }
    }
    return key;
}

Status AdaptiveFrame::setLevels(const uint8_t* levels, size_t count)
{
    const std::vector<uint32_t>& control = plan_.controlTriangles();
    const size_t nf = control.size() / 3;
    if (tiles_.size() != nf * slots_)
        return Status(StatusCode::InvalidData, "the plan's refined faces are not a grid per control face");
    if (count != nf || (nf > 0 && !levels))
        return Status(StatusCode::InvalidArgument, std::to_string(levels ? count : 0) + " face levels for " +
                                                       std::to_string(nf) + " control faces");
    for (size_t f = 0; f < nf; ++f)
        if (levels[f] > finest_)
            return Status(StatusCode::InvalidArgument, "control face " + std::to_string(f) + " asks for level " +
                                                           std::to_string(levels[f]) + ", past the plan's level " +
                                                           std::to_string(finest_));
    levels_.assign(levels, levels + nf);
    edgeLevelsFor(&edgeLevels_, levels, edgeOf_, finest_);

    vertices_.clear();
    triangles_.clear();
    triangleFaces_.clear();
    cornerSlots_.clear();
    tileTemplate_.resize(nf);
    tileFirst_.resize(nf + 1);
    tileVertex_.clear();
    tilePartial_.clear();
    tileSource_.clear();
    partialVertex_.clear();
    size_t partials = 0;
    for (size_t f = 0; f < nf; ++f) {
        const int l = levels[f];
        const int e[3] = {edgeLevels_[edgeOf_[3 * f]], edgeLevels_[edgeOf_[3 * f + 1]], edgeLevels_[edgeOf_[3 * f + 2]]};
        const size_t key = templateFor(l, e);
        const std::vector<uint16_t>& t = templates_[key].fine;
        const std::vector<uint16_t>& local = templates_[key].local;
        tileTemplate_[f] = uint32_t(key);
        const uint32_t R = 1u << l, step = 1u << (finest_ - l);
        const size_t levelSlots = size_t(R + 1) * (R + 2) / 2, base = tileVertex_.size();
        tileFirst_[f] = uint32_t(base);
        tileVertex_.resize(base + levelSlots, kNone);
        tilePartial_.resize(base + levelSlots, kNone);
        tileSource_.resize(base + levelSlots, kNone);
        const uint32_t* tile = &tiles_[f * slots_];
        for (size_t k = 0; k < t.size(); ++k) {
            const uint32_t v = tile[t[k]];
            if (remap_[v] == kNone) {
                remap_[v] = uint32_t(vertices_.size());
                vertices_.push_back(v);
            }
            triangles_.push_back(remap_[v]);
            cornerSlots_.push_back(t[k]);
            uint32_t& slot = tileVertex_[base + local[k]];
            if (slot == kNone) {
                slot = remap_[v];
                const uint32_t i = slotI_[t[k]] / step, j = slotJ_[t[k]] / step;
                if (i == 0 || j == 0 || i + j == R) {  // on the control face's border: shared
                    tilePartial_[base + local[k]] = uint32_t(partials++);
                    partialVertex_.push_back(remap_[v]);
                }
            }
        }
        triangleFaces_.insert(triangleFaces_.end(), t.size() / 3, uint32_t(f));
        // Every slot's position source: its own vertex, or its snap target's.
        const std::vector<uint16_t>& snapTo = templates_[key].snapTo;
        for (size_t k = 0; k < levelSlots; ++k)
            tileSource_[base + k] = tileVertex_[base + snapTo[k]];
    }
    tileFirst_[nf] = uint32_t(tileVertex_.size());
    for (uint32_t v : vertices_)
        remap_[v] = kNone;

    // Each border vertex's partial sums, in tile order (a stable counting
    // sort), laid out per border vertex as the uniform frame's border pass
    // reads them.  remap_, all ~0 again, lends its first n entries for the
    // frame vertices' border numbers, and is cleared after.
    const size_t n = vertices_.size();
    borderVertices_.clear();
    borderOffsets_.assign(1, 0);
    for (uint32_t v : partialVertex_)
        if (remap_[v] == kNone) {
            remap_[v] = uint32_t(borderVertices_.size());
            borderVertices_.push_back(v);
            borderOffsets_.push_back(0);
        }
    for (uint32_t v : partialVertex_)
        ++borderOffsets_[remap_[v] + 1];
    for (size_t u = 0; u < borderVertices_.size(); ++u)
        borderOffsets_[u + 1] += borderOffsets_[u];
    borderEntries_.resize(partials);
    for (size_t k = 0; k < partials; ++k)  // each vertex's end as its cursor, shifted back below
        borderEntries_[borderOffsets_[remap_[partialVertex_[k]]]++] = uint32_t(k);
    for (size_t u = borderVertices_.size(); u > 0; --u)
        borderOffsets_[u] = borderOffsets_[u - 1];
    borderOffsets_[0] = 0;
    for (uint32_t v : borderVertices_)
        remap_[v] = kNone;
    partials_.resize(partials);

    // Linear scheme: each frame vertex's control corners, weights and
    // displacement side by side, so a frame streams them.
    linear_.clear();
    if (plan_.scheme() == Scheme::Linear) {
        const std::vector<SampleLocation>& samples = plan_.sampleLocations();
        const std::vector<float>& d = plan_.displacements();
        linear_.resize(n);
        for (size_t k = 0; k < n; ++k) {
            const SampleLocation& at = samples[vertices_[k]];
            LinearVertex& lv = linear_[k];
            const uint32_t* c = &control[3 * size_t(at.face)];
            lv = {{c[0], c[1], c[2]}, at.bary.x, at.bary.y, d[vertices_[k]]};
        }
    }
    return Status::ok();
}

template <typename Body>
void AdaptiveFrame::parallel(int threads, size_t n, const Body& body)
{
    detail::runParallel(pool_, threads, n, body);
}

Status AdaptiveFrame::evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                               const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                               int threads)
{
    if (!positions && !vertices_.empty())
        return Status(StatusCode::InvalidArgument, "AdaptiveFrame::evaluate: no position buffer");
    const float* d = displacements ? displacements : plan_.displacements().data();
    // The arguments once; every chunk below then passes the same checks.
    glm::vec3 unused;
    if (Status st = plan_.evaluateVertices(positions ? positions : &unused, nullptr, nullptr, 0, d, controlPositions,
                                           controlNormals, controlCount);
        !st)
        return st;
    if (!linear_.empty()) {
        // Plan::evaluate's expression, bit for bit, over the streamed corners.
        const bool own = d == plan_.displacements().data();
        parallel(threads, linear_.size(), [&](size_t b, size_t e, int) {
            for (size_t k = b; k < e; ++k) {
                const LinearVertex& v = linear_[k];
                const float w1 = v.w1, w2 = v.w2, w0 = 1.0f - w1 - w2;
                const glm::vec3 p = w0 * controlPositions[v.c[0]] + w1 * controlPositions[v.c[1]] +
                                    w2 * controlPositions[v.c[2]];
                const glm::vec3 n = w0 * controlNormals[v.c[0]] + w1 * controlNormals[v.c[1]] + w2 * controlNormals[v.c[2]];
                positions[k] = shared::strata_displace(p, n, own ? v.d : d[vertices_[k]]);
            }
        });
    } else {
        parallel(threads, vertices_.size(), [&](size_t b, size_t e, int) {
            (void)plan_.evaluateVertices(positions + b, nullptr, vertices_.data() + b, e - b, d, controlPositions,
                                         controlNormals, controlCount);
        });
    }
    if (!normals)
        return Status::ok();

    // Normals per tile, on the tile's whole regular grid at its level:
    // a snapped point takes its target's position, so the grid's triangles
    // are the stitched tile's (a collapsed one has zero area), and its sum
    // goes to the target.  A slot inside the control face is then final;
    // one on its border leaves a partial sum that the border pass adds up
    // in tile order.
    const size_t nf = levels_.size();
    const int pool = threads <= 1 ? 1 : threads;
    if (scratch_.size() < size_t(pool)) {
        scratch_.resize(size_t(pool));
        for (Scratch& s : scratch_)
            s.resize(finest_);
    }
    parallel(threads, nf, [&](size_t b, size_t e, int t) {
        Scratch& s = scratch_[size_t(t)];
        for (size_t f = b; f < e; ++f) {
            const uint32_t base = tileFirst_[f];
            const TileTemplate& tt = templates_[tileTemplate_[f]];
            shadeAdaptiveTile(levels_[f], &tileSource_[base], &tileVertex_[base], &tilePartial_[base], tt.snapped.data(),
                              tt.snapped.size(), tt.snapTo.data(), positions, normals, partials_.data(), s);
        }
    });
    parallel(threads, borderVertices_.size(), [&](size_t b, size_t e, int) {
        detail::finishBorders(normals, borderVertices_.data(), borderOffsets_.data(), borderEntries_.data(),
                              partials_.data(), b, e);
    });
    return Status::ok();
}

float AdaptiveFrame::maxScreenDeviation(const glm::vec3* framePositions, const glm::vec3* finePositions,
                                        const ViewSpec& view) const
{
    if (!view.valid() || !framePositions || !finePositions)
        return 0.0f;
    const Camera cam(view);
    const int R = 1 << finest_;
    float worst = 0.0f;
    const size_t nt = triangles_.size() / 3;
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t* tile = &tiles_[size_t(triangleFaces_[t]) * slots_];
        const uint16_t* cs = &cornerSlots_[3 * t];
        const int gi[3] = {slotI_[cs[0]], slotI_[cs[1]], slotI_[cs[2]]}, gj[3] = {slotJ_[cs[0]], slotJ_[cs[1]], slotJ_[cs[2]]};
        const uint32_t* v = &triangles_[3 * t];
        const glm::vec3 p[3] = {framePositions[v[0]], framePositions[v[1]], framePositions[v[2]]};
        rasterGrid(gi, gj, R, [&](int i, int j, const int w[3], int area) {
            const glm::vec3 drawn = (float(w[0]) * p[0] + float(w[1]) * p[1] + float(w[2]) * p[2]) / float(area);
            const glm::vec3 fine = finePositions[tile[tileSlot(uint32_t(i), uint32_t(j), uint32_t(R))]];
            float xa, ya, xb, yb;
            if (cam.project(drawn, &xa, &ya) && cam.project(fine, &xb, &yb)) {
                const float depth = glm::dot(fine - cam.eye, cam.forward);
                worst = std::max({worst, std::hypot(xa - xb, ya - yb), glm::length(fine - drawn) * cam.k / depth});
            }
        });
    }
    return worst;
}

size_t AdaptiveFrame::bytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    size_t t = 0;
    for (const TileTemplate& v : templates_)
        t += bytes(v.fine) + bytes(v.local) + bytes(v.snapTo) + bytes(v.snapped);
    for (const Scratch& v : scratch_)
        t += 6 * bytes(v.px) + 6 * bytes(v.up[0]);
    return t + bytes(tiles_) + bytes(slotI_) + bytes(slotJ_) + bytes(edgeOf_) + bytes(edgeLevels_) + bytes(levels_) +
           bytes(remap_) + bytes(vertices_) + bytes(triangles_) + bytes(triangleFaces_) + bytes(cornerSlots_) +
           bytes(tileTemplate_) + bytes(tileFirst_) + bytes(tileVertex_) + bytes(tilePartial_) + bytes(tileSource_) + bytes(partialVertex_) +
           bytes(borderVertices_) + bytes(borderOffsets_) + bytes(borderEntries_) + bytes(partials_) + bytes(linear_);
}

}  // namespace strata
