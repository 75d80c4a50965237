// Adaptive level of detail out of one plan (adaptive.h).
#include "strata/adaptive.h"

#include "strata/control_mesh.h"
#include "strata/displacement_math.h"
#include "strata/plane.h"

#include "simd.h"
#include "worker_pool.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace strata {

namespace {

constexpr uint32_t kNone = 0xffffffffu;

// Faces drawn at this level or finer (8 segments an edge) go through the
// tile pass; coarser tiles are mostly border, and their few triangles cost
// less summed per vertex (as the uniform frame's plain passes below level
// 3; measured with bench_runtime).
constexpr int kGridLevel = 3;

// Slot of grid point (i, j) in the tile pass's layout (detail::GridScratch:
// row i, j within it); tileSlot(j, i, R).
inline size_t gridSlot(uint32_t i, uint32_t j, uint32_t R) { return tileSlot(j, i, R); }

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

// floor(n / d) for d > 0.
inline int floorDiv(int n, int d) { return n >= 0 ? n / d : -((-n + d - 1) / d); }

// Calls fn(t, i0, j0, i1, j1, s) at every point where the grid segment from
// (ai, aj) to (bi, bj) crosses an edge of the finest lattice between its
// points: t along the segment, on the lattice edge from (i0, j0) to
// (i1, j1), s along that edge (0 < s < 1).  A segment along a lattice line
// (a nested level's edge) crosses none.  A stitched triangle's edge cuts
// the finest triangles it passes over; the drawn surface and the finest one
// are both linear on each piece of a finest triangle that a drawn triangle
// covers, so their largest distance there is at the piece's corners: the
// finest vertices inside the drawn triangle, its own corners and these
// crossings.
template <typename Fn>
void forEachCrossing(int ai, int aj, int bi, int bj, const Fn& fn)
{
    const int di = bi - ai, dj = bj - aj;
    if (di == 0 || dj == 0 || di + dj == 0)
        return;
    // Lines i = c (j = aj + (c - ai) dj / di), j = c, and i + j = c.
    auto lines = [&](int from, int along, int otherFrom, int otherAlong, auto edge) {
        const int sign = along > 0 ? 1 : -1, d = sign * along;
        for (int k = 1; k < d; ++k) {
            const int c = from + sign * k;
            const int n = otherFrom * d + k * otherAlong;  // the other coordinate times d (t = k / d)
            const int o = floorDiv(n, d), r = n - o * d;
            if (r != 0)
                edge(double(k) / double(d), c, o, double(r) / double(d));
        }
    };
    lines(ai, di, aj, dj, [&](double t, int c, int o, double f) { fn(t, c, o, c, o + 1, f); });
    lines(aj, dj, ai, di, [&](double t, int c, int o, double f) { fn(t, o, c, o + 1, c, f); });
    lines(ai + aj, di + dj, ai, di, [&](double t, int c, int o, double f) { fn(t, o, c - o, o + 1, c - o - 1, f); });
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
    // Pixel coordinates of p and its depth, false behind the eye.  In
    // double: a point near the eye's plane projects its rounding far off
    // screen.
    bool project(const glm::dvec3& p, double* x, double* y, double* depth) const
    {
        const glm::dvec3 q = p - glm::dvec3(eye);
        const double z = glm::dot(q, glm::dvec3(forward));
        if (!(z > 0.0))
            return false;
        *x = double(k) * glm::dot(q, glm::dvec3(right)) / z;
        *y = double(k) * glm::dot(q, glm::dvec3(up)) / z;
        *depth = z;
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

// Lowers an edge's two halves (half[0] at its lower-numbered vertex) to
// the levels of the quarters of face corners c (control indices) and q
// that touch it, the edge being the face's edge k (corner k to k + 1).
inline void lowerHalves(uint8_t* half, const uint32_t* c, const uint8_t* q, size_t k)
{
    const size_t next = k == 2 ? 0 : k + 1;
    const int forward = c[k] < c[next] ? 0 : 1;  // the half at corner k
    half[forward] = std::min(half[forward], q[k]);
    half[1 - forward] = std::min(half[1 - forward], q[next]);
}

// Each half of each edge at the lowest level of the quarters that touch it
// (a face at level 0 touches both halves at 0): halves[2 e] is the half at
// the edge's lower-numbered vertex.  The quarter at corner k of a face
// touches the halves of edges k and k + 2 at that corner.
void halfLevelsFor(std::vector<uint8_t>* halves, const uint8_t* quarters, const uint32_t* control,
                   const std::vector<uint32_t>& edgeOf, int finest)
{
    std::fill(halves->begin(), halves->end(), uint8_t(finest));
    uint8_t* h = halves->data();
    const size_t nf = edgeOf.size() / 3;
    for (size_t f = 0; f < nf; ++f)
        for (size_t k = 0; k < 3; ++k)
            lowerHalves(h + 2 * size_t(edgeOf[3 * f + k]), control + 3 * f, quarters + 4 * f, k);
}

// Edge e's two halves again (as halfLevelsFor), from the quarters of the
// faces around it: after some of those faces' quarters changed.
void edgeHalves(uint8_t* halves, size_t e, const uint8_t* quarters, const uint32_t* control, const EdgeGroups& edges,
                int finest)
{
    uint8_t* half = halves + 2 * e;
    half[0] = half[1] = uint8_t(finest);
    for (uint32_t m = 0; m < edges.faceCountOf(e); ++m) {
        const size_t corner = edges.cornersOf(e)[m], f = corner / 3;
        lowerHalves(half, control + 3 * f, quarters + 4 * f, corner % 3);
    }
}

// Whether a face's four quarters are at one level (the face drawn as one
// tile, unless its edges' halves differ).
bool alike(const uint8_t* q) { return q[0] == q[1] && q[1] == q[2] && q[2] == q[3]; }

// A face of unequal quarters beside a face at level 0 is drawn with every
// quarter at its finest: the midpoint of the edge between them is gone, and
// an inner edge drawn coarser would have to snap onto it.  `zero` (per edge)
// is scratch.  Levels only rise.
void settleQuarters(uint8_t* quarters, const std::vector<uint32_t>& edgeOf, size_t edgeCount,
                    std::vector<uint8_t>* zero)
{
    const size_t nf = edgeOf.size() / 3;
    zero->assign(edgeCount, 0);
    for (size_t f = 0; f < nf; ++f)
        if (quarters[4 * f] == 0)
            for (size_t k = 0; k < 3; ++k)
                (*zero)[edgeOf[3 * f + k]] = 1;
    for (size_t f = 0; f < nf; ++f) {
        uint8_t* q = quarters + 4 * f;
        if (alike(q))
            continue;
        if ((*zero)[edgeOf[3 * f]] || (*zero)[edgeOf[3 * f + 1]] || (*zero)[edgeOf[3 * f + 2]])
            std::fill(q, q + 4, std::max({q[0], q[1], q[2], q[3]}));
    }
}

// Face f's halves: h[k][0] the half of its edge k at corner k, h[k][1] at
// corner k + 1.
void faceHalves(int h[3][2], const std::vector<uint8_t>& halves, const uint32_t* control,
                const std::vector<uint32_t>& edgeOf, size_t f)
{
    for (size_t k = 0; k < 3; ++k) {
        const bool forward = control[3 * f + k] < control[3 * f + (k + 1) % 3];
        const size_t e = 2 * size_t(edgeOf[3 * f + k]);
        h[k][0] = halves[e + (forward ? 0 : 1)];
        h[k][1] = halves[e + (forward ? 1 : 0)];
    }
}

// Whether every half of a face's edges (h, as faceHalves) is at `level` or finer.
bool noCoarser(const int h[3][2], int level)
{
    return std::min({h[0][0], h[0][1], h[1][0], h[1][1], h[2][0], h[2][1]}) >= level;
}

// Whether face f (its quarters q, its halves h) is drawn whole: four equal
// quarters and each edge at one level (then e[k], else the lower half).
bool drawnWhole(const uint8_t* q, const int h[3][2], int e[3])
{
    bool whole = alike(q);
    for (int k = 0; k < 3; ++k) {
        whole = whole && h[k][0] == h[k][1];
        e[k] = std::min(h[k][0], h[k][1]);
    }
    return whole;
}

// Quarter c's edge levels in its own corner order (adaptiveQuarterTriangles)
// and, for the middle one, the face's edges at level 0 (coarseSides).
void quarterEdges(int c, const uint8_t* q, const int h[3][2], int x[3], int* coarseSides)
{
    const int mid = q[3];
    const int inner[3] = {std::min<int>(q[0], mid), std::min<int>(q[1], mid), std::min<int>(q[2], mid)};
    *coarseSides = 0;
    switch (c) {
    case 0: x[0] = h[0][0], x[1] = inner[0], x[2] = h[2][1]; break;
    case 1: x[0] = h[0][1], x[1] = h[1][0], x[2] = inner[1]; break;
    case 2: x[0] = inner[2], x[1] = h[1][1], x[2] = h[2][0]; break;
    default:
        x[0] = inner[2], x[1] = inner[0], x[2] = inner[1];
        *coarseSides = (h[0][0] == 0 ? 1 : 0) | (h[1][0] == 0 ? 2 : 0) | (h[2][0] == 0 ? 4 : 0);
    }
}

// A quarter template's key (levels up to 7: kMaxLevel is 6).
uint32_t quarterKey(int c, int level, const int x[3], int coarseSides)
{
    return uint32_t(c) | uint32_t(level) << 2 | uint32_t(x[0]) << 5 | uint32_t(x[1]) << 8 | uint32_t(x[2]) << 11 |
           uint32_t(coarseSides) << 14;
}

// Quarters at this level and finer go through the tile pass (a quarter's
// grid there has kGridLevel's 8 segments an edge, or more).
constexpr int kQuarterGridLevel = kGridLevel + 1;

// The index of quarter q's grid at `level` among AdaptiveFrame's grids.
size_t quarterGrid(int finest, int q, int level)
{
    return size_t(finest + 1) * size_t(q + 1) + size_t(level);
}

// The quarter whose part holds the grid point (i, j) of a tile of resolution R.
int quarterAt(uint32_t i, uint32_t j, uint32_t R)
{
    return 2 * (i + j) <= R ? 0 : 2 * i >= R ? 1 : 2 * j >= R ? 2 : 3;
}

// The triangles of a lattice of R segments an edge, counter-clockwise in
// (i, j), each corner drawn at point(i, j) (a slot); a triangle collapsed
// by its points (onto a coarser edge) is left out.
template <typename Point>
void emitLattice(std::vector<uint16_t>* out, uint32_t R, const Point& point)
{
    auto emit = [&](uint16_t a, uint16_t b, uint16_t c) {
        if (a == b || b == c || c == a)
            return;
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

}  // namespace

void adaptiveTileTriangles(std::vector<uint16_t>* out, int finest, int level, const int edgeLevels[3])
{
    out->clear();
    const uint32_t R = 1u << level, fineR = 1u << finest, step = 1u << (finest - level);
    emitLattice(out, R, [&](uint32_t i, uint32_t j) {
        snapPoint(&i, &j, level, edgeLevels);
        return uint16_t(tileSlot(i * step, j * step, fineR));
    });
}

namespace {

// Quarter `quarter` of a face's finest grid (N = 2^finest), drawn at
// `level`: its own grid of r = 2^(level - 1) segments an edge, point (u, v)
// of which is the face's grid point at(u, v), and where that point is drawn.
struct QuarterLattice {
    int finest;
    uint32_t N, h, step, r, oi, oj;
    bool turned;
    int side[3], inner[3];

    QuarterLattice(int finestLevel, int quarter, int level, const int x[3], int coarseSides)
        : finest(finestLevel), N(1u << finestLevel), h(N / 2), step(1u << (finestLevel - level)),
          r(1u << (level - 1)), oi(quarter == 1 || quarter == 3 ? h : 0), oj(quarter >= 2 ? h : 0),
          turned(quarter == 3), side{finestLevel, finestLevel, finestLevel}, inner{finestLevel, finestLevel, finestLevel}
    {
        // The quarter's origin and direction in the face's grid: the middle
        // one is the corner ones turned half a turn (counter-clockwise
        // still).  The level each of the face's edges (0, 1, 2) and inner
        // edges (A: i + j = h, B: i = h, C: j = h) is drawn at where this
        // quarter meets it.
        switch (quarter) {
        case 0: side[0] = x[0], inner[0] = x[1], side[2] = x[2]; break;
        case 1: side[0] = x[0], side[1] = x[1], inner[1] = x[2]; break;
        case 2: inner[2] = x[0], side[1] = x[1], side[2] = x[2]; break;
        default:
            inner[2] = x[0], inner[0] = x[1], inner[1] = x[2];
            for (int k = 0; k < 3; ++k)
                side[k] = coarseSides >> k & 1 ? 0 : finest;
        }
    }
    void at(uint32_t u, uint32_t v, uint32_t* i, uint32_t* j) const
    {
        *i = turned ? oi - u * step : oi + u * step;
        *j = turned ? oj - v * step : oj + v * step;
    }
    // Where point (u, v) is drawn, in the face's grid.  A tie goes to the
    // start of the quarter's own edge (as on a whole face), so the two
    // quarters of an inner edge break ties apart: both keep the same
    // points, which is what closes the seam.
    void drawnAt(uint32_t u, uint32_t v, uint32_t* pi, uint32_t* pj) const
    {
        uint32_t i, j;
        at(u, v, &i, &j);
        // To the nearest kept point, a tie to the lower t (or, `up`, the higher).
        auto snap = [&](uint32_t t, int edgeLevel, bool up = false) {
            const uint32_t m = 1u << (finest - edgeLevel);
            return m == 1 ? t : (t + m / 2 - (up ? 0 : 1)) / m * m;
        };
        const bool corner = (j == 0 && (i == 0 || i == N)) || (i == 0 && j == N);
        if (corner) {
        } else if (j == 0) {  // edge 0, t = i
            i = snap(i, side[0]);
        } else if (i + j == N) {  // edge 1, t = j
            j = snap(j, side[1]);
            i = N - j;
        } else if (i == 0) {  // edge 2, t = N - j
            j = N - snap(N - j, side[2]);
        } else if (i + j == h) {  // A, t = j
            j = snap(j, inner[0], turned);
            i = h - j;
        } else if (i == h && j < h) {  // B, t = j
            j = snap(j, inner[1], !turned);
        } else if (j == h && i < h) {  // C, t = i
            i = snap(i, inner[2], turned);
        }
        *pi = i;
        *pj = j;
    }
    // The quarter's own point at face grid point (i, j), false if none.
    bool local(uint32_t i, uint32_t j, uint32_t* u, uint32_t* v) const
    {
        const int64_t du = turned ? int64_t(oi) - int64_t(i) : int64_t(i) - int64_t(oi);
        const int64_t dv = turned ? int64_t(oj) - int64_t(j) : int64_t(j) - int64_t(oj);
        if (du < 0 || dv < 0 || du % step != 0 || dv % step != 0 || (du + dv) / step > int64_t(r))
            return false;
        *u = uint32_t(du / step);
        *v = uint32_t(dv / step);
        return true;
    }
};

}  // namespace

void adaptiveQuarterTriangles(std::vector<uint16_t>* out, int finest, int quarter, int level, const int x[3],
                              int coarseSides)
{
    out->clear();
    if (finest < 1 || level < 1 || level > finest || quarter < 0 || quarter > 3)
        return;
    const QuarterLattice q(finest, quarter, level, x, coarseSides);
    emitLattice(out, q.r, [&](uint32_t u, uint32_t v) {
        uint32_t i, j;
        q.drawnAt(u, v, &i, &j);
        return uint16_t(tileSlot(i, j, q.N));
    });
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
        // From its lowest slot on (a turn keeps it counter-clockwise): the
        // same triangle gives the same sums in whatever template it stands.
        const size_t r = t[k] <= t[k + 1] && t[k] <= t[k + 2] ? 0 : t[k + 1] <= t[k + 2] ? 1 : 2;
        const uint16_t c[3] = {t[k + r], t[k + (r + 1) % 3], t[k + (r + 2) % 3]};
        const int gi[3] = {slotI_[c[0]], slotI_[c[1]], slotI_[c[2]]};
        const int gj[3] = {slotJ_[c[0]], slotJ_[c[1]], slotJ_[c[2]]};
        const glm::vec3 q[3] = {p[tile[c[0]]], p[tile[c[1]]], p[tile[c[2]]]};
        rasterGrid(gi, gj, int(R), [&](int i, int j, const int w[3], int area) {
            const glm::vec3 drawn = (float(w[0]) * q[0] + float(w[1]) * q[1] + float(w[2]) * q[2]) / float(area);
            worst = std::max(worst, glm::length(p[tile[tileSlot(uint32_t(i), uint32_t(j), R)]] - drawn));
        });
        for (int e = 0; e < 3; ++e) {
            const int b = (e + 1) % 3;
            forEachCrossing(gi[e], gj[e], gi[b], gj[b], [&](double along, int i0, int j0, int i1, int j1, double f) {
                const glm::vec3 drawn = q[e] + float(along) * (q[b] - q[e]);
                const glm::vec3 a = p[tile[tileSlot(uint32_t(i0), uint32_t(j0), R)]];
                const glm::vec3 fine = a + float(f) * (p[tile[tileSlot(uint32_t(i1), uint32_t(j1), R)]] - a);
                worst = std::max(worst, glm::length(fine - drawn));
            });
        }
    }
    return worst;
}

const std::vector<uint16_t>& LevelChooser::quarterTemplate(int quarter, int level, const int x[3], int coarseSides)
{
    std::vector<uint16_t>& t = quarterTemplates_[quarterKey(quarter, level, x, coarseSides)];
    if (t.empty())
        adaptiveQuarterTriangles(&t, errors_.finest, quarter, level, x, coarseSides);
    return t;
}

namespace {

// An orthonormal frame of triangle (a, b, c): its first edge, the in-plane
// normal to it, the triangle's normal (columns); false when degenerate.
bool triangleFrame(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::mat3* frame)
{
    const glm::vec3 u = b - a, n = glm::cross(u, c - a);
    const float lu = glm::length(u), ln = glm::length(n);
    if (!(lu > 0.0f) || !(ln > 0.0f))
        return false;
    const glm::vec3 e1 = u / lu, e3 = n / ln;
    *frame = glm::mat3(e1, glm::cross(e3, e1), e3);
    return true;
}

}  // namespace

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
    restCount_ = controlCount;
    slots_ = size_t(R + 1) * (R + 2) / 2;
    controlTriangles_ = plan.controlTriangles();
    smooth_ = plan.scheme() == Scheme::Smooth;
    controlCount_ = plan.controlVertexCount();
    const size_t nf = controlTriangles_.size() / 3;
    restLocal_.assign(9 * nf, 0.0f);
    restFramed_.assign(nf, 0.0f);
    restGram_.assign(4 * nf, 0.0f);
    for (size_t f = 0; f < nf; ++f) {
        const uint32_t* c = &controlTriangles_[3 * f];
        // The Gram matrix of the rest triangle's two edges from corner 0
        // and its inverse determinant (0: degenerate, nothing to stretch).
        const glm::dvec3 e1 = glm::dvec3(controlPositions[c[1]]) - glm::dvec3(controlPositions[c[0]]),
                         e2 = glm::dvec3(controlPositions[c[2]]) - glm::dvec3(controlPositions[c[0]]);
        const double g11 = glm::dot(e1, e1), g12 = glm::dot(e1, e2), g22 = glm::dot(e2, e2);
        const double det = g11 * g22 - g12 * g12;
        if (det > 1e-12 * (g11 + g22) * (g11 + g22)) {
            restGram_[f] = float(g11);
            restGram_[nf + f] = float(g12);
            restGram_[2 * nf + f] = float(g22);
            restGram_[3 * nf + f] = float(1.0 / det);
        }
        glm::mat3 frame;
        if (!triangleFrame(controlPositions[c[0]], controlPositions[c[1]], controlPositions[c[2]], &frame))
            continue;
        restFramed_[f] = 1.0f;
        for (size_t k = 0; k < 3; ++k) {
            const glm::vec3 local = glm::transpose(frame) * controlNormals[c[k]];
            for (int a = 0; a < 3; ++a)
                restLocal_[(3 * k + size_t(a)) * nf + f] = local[a];
        }
    }
    lastStitched_.assign(4 * nf, {~0u, 0.0f});
    slotPoints(&slotI_, &slotJ_, R);
    edges_ = groupEdges(controlTriangles_.data(), nf);
    edgeOf_ = cornerEdges(edges_, nf);
    // Where no edge has more than two faces: each face's neighbour across
    // each of its edges (itself across a border edge), so the bend's spread
    // reads three faces per face and no pass over edges.
    faceNeighbours_.clear();
    bool pairs = true;
    for (size_t e = 0; e < edges_.edgeCount() && pairs; ++e)
        pairs = edges_.faceCountOf(e) <= 2;
    if (pairs) {
        faceNeighbours_.resize(3 * nf);
        for (size_t f = 0; f < nf; ++f)
            for (size_t k = 0; k < 3; ++k) {
                const uint32_t e = edgeOf_[3 * f + k];
                const uint32_t* c = edges_.cornersOf(e);
                const uint32_t a = c[0] / 3, b = c[edges_.faceCountOf(e) - 1] / 3;
                faceNeighbours_[3 * f + k] = a == f ? b : a;
            }
    }
    halves_.assign(2 * edges_.edgeCount(), 0);
    levelTiles_.assign(size_t(L + 1), {});
    quarterTemplates_.clear();
    stitchedQuarters_.clear();
    gains_.assign(nf, 0.0f);
    bentPositions_.clear();  // no bends measured for this plan yet
    bentNormals_.clear();
    bentStamp_ = 0;
    lastQuarters_.clear();  // nor a choice made
    fullChoices_ = keptChoices_ = repairedChoices_ = 0;

    FaceLevelErrors& e = errors_;
    e.finest = L;
    e.faceCount = nf;
    e.error.assign(nf * size_t(L + 1), 0.0f);
    e.reach.assign(nf, 0.0f);
    e.quarterError.assign(4 * nf * size_t(L + 1), 0.0f);
    std::vector<const std::vector<uint16_t>*> quarterTiles(4 * size_t(L + 1), nullptr);
    for (int l = 0; l <= L; ++l) {
        const int same[3] = {l, l, l};
        adaptiveTileTriangles(&levelTiles_[size_t(l)], L, l, same);
        for (int c = 0; c < 4 && l >= 1; ++c)
            quarterTiles[size_t(c) * size_t(L + 1) + size_t(l)] = &quarterTemplate(c, l, same, 0);
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
                err[l] = std::max(templateError(levelTiles_[size_t(l)], f), err[l + 1]);
            }
            for (int q = 0; q < 4; ++q) {
                float* qe = &e.quarterError[(4 * f + size_t(q)) * size_t(L + 1)];
                for (int l = L - 1; l >= 1; --l)
                    qe[l] = std::max(templateError(*quarterTiles[size_t(q) * size_t(L + 1) + size_t(l)], f), qe[l + 1]);
                qe[0] = L >= 1 ? qe[1] : 0.0f;
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

float LevelChooser::stitchedQuarterError(size_t face, int quarter, int level, const int x[3], int coarseSides)
{
    if (x[0] >= level && x[1] >= level && x[2] >= level && coarseSides == 0)
        return errors_.quarterAt(face, quarter, level);
    const uint32_t small = quarterKey(quarter, level, x, coarseSides);
    std::pair<uint32_t, float>& last = lastStitched_[4 * face + size_t(quarter)];
    if (last.first == small)
        return last.second;
    const uint64_t key = uint64_t(face) << 17 | small;
    const auto found = stitchedQuarters_.find(key);
    float error;
    if (found != stitchedQuarters_.end()) {
        error = found->second;
    } else {
        error = templateError(quarterTemplate(quarter, level, x, coarseSides), face);
        stitchedQuarters_.emplace(key, error);
    }
    last = {small, error};
    return error;
}

size_t LevelChooser::bytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    const size_t node = sizeof(uint64_t) + sizeof(float) + 2 * sizeof(void*);
    size_t t = 0;
    for (const std::vector<uint16_t>& v : levelTiles_)
        t += bytes(v);
    for (const auto& v : quarterTemplates_)
        t += bytes(v.second) + node;
    return t + bytes(errors_.error) + bytes(errors_.reach) + bytes(errors_.quarterError) + bytes(rest_) + bytes(restLocal_) + bytes(restFramed_) + bytes(lastStitched_) + bytes(seen_) + bytes(recheck_) + bytes(touched_) + bytes(moved_) + bytes(cosines_) + bytes(stretches_) + bytes(restGram_) + bytes(own_) + bytes(edgeSpread_) + bytes(faceNeighbours_) + bytes(bentPositions_) + bytes(bentNormals_) + bytes(corners_) + bytes(cornerNormals_) + bytes(lastQuarters_) + bytes(chosenGains_) + bytes(drawnErrors_) + bytes(tiles_) +
           bytes(controlTriangles_) + bytes(slotI_) + bytes(slotJ_) + bytes(edges_.corners) + bytes(edges_.offsets) +
           bytes(edgeOf_) + bytes(halves_) + bytes(gains_) + stitchedQuarters_.size() * node;
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

namespace {

// arccos to within 2e-8 rad on [-1, 1] (Abramowitz and Stegun 4.4.46: a
// polynomial times sqrt(1 - x) on [0, 1], reflected below 0): a few
// multiplies that vectorise, where the library's call was the choice's
// dearest step.
STRATA_KERNEL_INLINE float arccos(float x)
{
    const float t = std::fabs(x);
    const float p = 1.5707963050f + t * (-0.2145988016f + t * (0.0889789874f + t * (-0.0501743046f + t * (0.0308918810f +
                    t * (-0.0170881256f + t * (0.0066700901f + t * -0.0012624911f))))));
    const float r = std::sqrt(std::max(0.0f, 1.0f - t)) * p;
    return x < 0.0f ? 3.14159265f - r : r;
}

// Gathers one value per face corner into 9 rows of n (row 3 k + axis):
// the choice's passes then run over faces as whole vectors.
void gatherCorners(float* rows, const glm::vec3* values, const uint32_t* triangles, size_t n)
{
    for (size_t f = 0; f < n; ++f)
        for (size_t k = 0; k < 3; ++k) {
            const glm::vec3 v = values[triangles[3 * f + k]];
            rows[(3 * k) * n + f] = v.x;
            rows[(3 * k + 1) * n + f] = v.y;
            rows[(3 * k + 2) * n + f] = v.z;
        }
}

// Per face, the smallest cosine between a corner normal in the pose and
// its rest normal turned as the face's triangle turned: the posed frame
// (first edge, in-plane normal, face normal) applied to the rest frame's
// coordinates `local`.  1 where either frame is degenerate (`framed` 0).
// Corners p, normals nr and local are gatherCorners rows.
STRATA_KERNEL_CLONES void leastCosines(size_t n, const float* __restrict p, const float* __restrict nr,
                                       const float* __restrict local, const float* __restrict framed,
                                       float* __restrict out)
{
    for (size_t f = 0; f < n; ++f) {
        const float ux = p[3 * n + f] - p[f], uy = p[4 * n + f] - p[n + f], uz = p[5 * n + f] - p[2 * n + f];
        const float vx = p[6 * n + f] - p[f], vy = p[7 * n + f] - p[n + f], vz = p[8 * n + f] - p[2 * n + f];
        const float nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
        const float lu = ux * ux + uy * uy + uz * uz, ln = nx * nx + ny * ny + nz * nz;
        const bool ok = framed[f] > 0.0f && lu > 0.0f && ln > 0.0f;
        const float iu = ok ? 1.0f / std::sqrt(lu) : 0.0f, in = ok ? 1.0f / std::sqrt(ln) : 0.0f;
        const float e1x = ux * iu, e1y = uy * iu, e1z = uz * iu, e3x = nx * in, e3y = ny * in, e3z = nz * in;
        const float e2x = e3y * e1z - e3z * e1y, e2y = e3z * e1x - e3x * e1z, e2z = e3x * e1y - e3y * e1x;
        float least = 1.0f;
        for (size_t k = 0; k < 3; ++k) {
            const float lx = local[3 * k * n + f], ly = local[(3 * k + 1) * n + f], lz = local[(3 * k + 2) * n + f];
            const float c = nr[3 * k * n + f] * (e1x * lx + e2x * ly + e3x * lz) +
                            nr[(3 * k + 1) * n + f] * (e1y * lx + e2y * ly + e3y * lz) +
                            nr[(3 * k + 2) * n + f] * (e1z * lx + e2z * ly + e3z * lz);
            least = c < least ? c : least;  // a NaN normal bends nothing
        }
        out[f] = ok ? least : 1.0f;
    }
}

// Per face, how far the pose stretches its triangle: the largest singular
// value (at least 1) of the map from its rest edges to its posed ones, in
// its plane, from the rest Gram matrix and inverse determinant `gram` (4
// rows; a 0 determinant stretches nothing).  Corners p: gatherCorners rows.
STRATA_KERNEL_CLONES void faceStretches(size_t n, const float* __restrict p, const float* __restrict gram,
                                        float* __restrict out)
{
    for (size_t f = 0; f < n; ++f) {
        const float ux = p[3 * n + f] - p[f], uy = p[4 * n + f] - p[n + f], uz = p[5 * n + f] - p[2 * n + f];
        const float vx = p[6 * n + f] - p[f], vy = p[7 * n + f] - p[n + f], vz = p[8 * n + f] - p[2 * n + f];
        const float pa = ux * ux + uy * uy + uz * uz, pb = ux * vx + uy * vy + uz * vz, pc = vx * vx + vy * vy + vz * vz;
        const float a = gram[f], b = gram[n + f], c = gram[2 * n + f], inverse = gram[3 * n + f];
        // M^T M has the eigenvalues of R^-1 P (R, P: the Gram matrices).
        const float trace = (c * pa - 2.0f * b * pb + a * pc) * inverse, det = (pa * pc - pb * pb) * inverse;
        const float top = 0.5f * (trace + std::sqrt(std::max(0.0f, trace * trace - 4.0f * det)));
        out[f] = std::sqrt(std::max(1.0f, top));  // NaN: max keeps 1
    }
}

// The choice's angular bounds (see choose) as cosines: a sphere wholly
// behind the eye (its nearest direction 1.5707 rad off the axis or more),
// and one reaching the eye's plane (its farthest 1.5697 rad or more);
// cosf(1.5707f) and cosf(1.5697f).
constexpr float kBehindCosine = 9.6277392e-05f, kEyePlaneCosine = 0.00109632395f;

// Pixels per model unit of error at each face: at the nearest point of a
// sphere around it, and at the largest angle off the view axis within the
// sphere (an error there moves up to 1 / cos^2 as many pixels as on the
// axis).  Infinite when the eye is inside the sphere or the sphere reaches
// the eye's plane (a point there projects arbitrarily far: the view has no
// width, so every point in front of the eye is held to the tolerance, as
// maxScreenDeviation measures), 0 when the sphere is wholly behind the
// eye.  A bent face (cosines, when not null: its smallest) counts its errors
// 1 + twice its angle larger.  A stretched one (its stretch, where larger
// than the pose's scale) counts its sphere that much larger and, in the
// smooth scheme, its errors: a level's error there is the limit surface's
// curvature between its grid points, which the stretch scales; in the
// linear scheme the base surface is flat on a face and the error is the
// displacement's alone, along the posed normals (the bend's part).
// Every case is computed and one selected, so the loop vectorises.  p: the
// corners' gatherCorners rows.
struct GainView {
    glm::vec3 eye, forward;
    float k, poseScale;
    float stretchErrors;  // 1 in the smooth scheme (a stretch scales the errors too), else 0
};
STRATA_KERNEL_CLONES void gainsFor(size_t n, const float* __restrict p, const float* __restrict reach,
                                   const float* __restrict cosines, const float* __restrict stretches, GainView v,
                                   float* __restrict out)
{
    const float infinity = std::numeric_limits<float>::infinity();
    for (size_t f = 0; f < n; ++f) {
        const float qx = (p[f] + p[3 * n + f] + p[6 * n + f]) / 3.0f - v.eye.x;
        const float qy = (p[n + f] + p[4 * n + f] + p[7 * n + f]) / 3.0f - v.eye.y;
        const float qz = (p[2 * n + f] + p[5 * n + f] + p[8 * n + f]) / 3.0f - v.eye.z;
        const float scale = std::max(v.poseScale, stretches[f]);
        const float r = reach[f] * scale;
        const float errorScale = v.poseScale + v.stretchErrors * (scale - v.poseScale);  // no branch: it vectorises
        const float d = std::sqrt(qx * qx + qy * qy + qz * qz);
        // The cosines of axis - spread and axis + spread, from the axis's
        // cosine and the spread's sine (r / d).  An angle in [0, 3pi/2] is
        // past a bound below pi/2 exactly where its cosine is below the
        // bound's; axis - spread is in it where the axis is no nearer than
        // the spread (cosines the other way).
        const float ca = std::max(-1.0f, std::min(1.0f, (qx * v.forward.x + qy * v.forward.y + qz * v.forward.z) / d));
        const float sa = std::sqrt(std::max(0.0f, 1.0f - ca * ca));
        const float ss = std::min(1.0f, r / d), cs = std::sqrt(std::max(0.0f, 1.0f - ss * ss));
        const float inner = ca * cs + sa * ss, outer = ca * cs - sa * ss;
        float g = v.k * errorScale / ((d - r) * outer * outer);
        g = outer <= kEyePlaneCosine ? infinity : g;
        g = ca <= cs && inner <= kBehindCosine ? 0.0f : g;
        g = d > r ? g : infinity;
        if (cosines) {
            // The widest angle is the smallest cosine's; one within
            // rounding of 1 (under 0.1 degree) is no bend, so the rest pose
            // has none.
            const float least = cosines[f];
            g *= least < 1.0f - 1e-6f ? 1.0f + 2.0f * arccos(std::max(-1.0f, least)) : 1.0f;
        }
        out[f] = g;
    }
}

}  // namespace

void LevelChooser::stitch(uint8_t* quarters, float pixelError, bool fromLast)
{
    const int L = errors_.finest;
    const size_t nf = errors_.faceCount;
    // Stitching: where a quarter meets coarser edges its strips (and
    // corners, where two coarse edges meet) may stray further than it or
    // its neighbours alone.  While one does, the coarsest neighbour across
    // its coarsest edge goes up a level (levels only rise, so this ends).
    // A face's check reads its own quarters and its edges' halves (from
    // its edge neighbours' quarters) and nothing else, so after the first
    // pass only faces where those changed (settled or raised) are checked
    // again, and faces raised during a pass later in it: the others pass
    // as they did.  From the last levels (fromLast), their halves stand,
    // and the first pass checks the faces that no longer stood (moved_), the
    // faces whose quarters changed and their edge neighbours; `touched_`
    // gathers every face checked, whose drawn errors are measured again.
    const uint32_t* control = controlTriangles_.data();
    recheck_.assign(nf, 1);
    touched_.assign(nf, fromLast ? 0 : 1);
    if (fromLast)
        seen_.assign(lastQuarters_.begin(), lastQuarters_.end());
    else
        seen_.resize(4 * nf);
    for (bool changed = true, first = !fromLast, start = true; changed; first = false, start = false) {
        changed = false;
        settleQuarters(quarters, edgeOf_, edges_.edgeCount(), &zeroEdges_);
        if (first) {
            halfLevelsFor(&halves_, quarters, control, edgeOf_, L);
        } else {
            // Only the edges of faces whose quarters changed have new halves.
            std::fill(recheck_.begin(), recheck_.end(), uint8_t(0));
            if (start)
                for (uint32_t f : moved_)
                    recheck_[f] = 1;
            for (size_t f = 0; f < nf; ++f) {
                if (std::memcmp(quarters + 4 * f, &seen_[4 * f], 4) == 0)
                    continue;
                recheck_[f] = 1;
                for (size_t k = 0; k < 3; ++k) {
                    const uint32_t edge = edgeOf_[3 * f + k];
                    edgeHalves(halves_.data(), edge, quarters, control, edges_, L);
                    for (uint32_t m = 0; m < edges_.faceCountOf(edge); ++m)
                        recheck_[edges_.cornersOf(edge)[m] / 3] = 1;
                }
            }
        }
        std::memcpy(seen_.data(), quarters, 4 * nf);
        for (size_t f = 0; f < nf; ++f)
            touched_[f] |= recheck_[f];
        for (size_t f = 0; f < nf; ++f) {
            uint8_t* fq = quarters + 4 * f;
            if (!recheck_[f] || fq[0] == 0)
                continue;  // as it passed; or a level-0 face (no point to snap)
            int h[3][2];
            faceHalves(h, halves_, control, edgeOf_, f);
            if (alike(fq) && noCoarser(h, fq[0]))
                continue;  // every quarter meets edges at its level or finer
            for (int c = 0; c < 4; ++c) {
                int x[3], coarseSides;
                quarterEdges(c, fq, h, x, &coarseSides);
                const int l = fq[c];
                if ((x[0] >= l && x[1] >= l && x[2] >= l && coarseSides == 0) ||
                    stitchedQuarterError(f, c, l, x, coarseSides) * gains_[f] <= pixelError)
                    continue;
                // The coarsest of its edges; the middle quarter's corners on
                // a face edge at level 0 count as that edge.
                int k = x[0] <= x[1] && x[0] <= x[2] ? 0 : x[1] <= x[2] ? 1 : 2, lowest = x[k];
                int faceEdge = -1, end = 0;  // the face edge (and its half) across edge k, if any
                if (coarseSides != 0) {
                    faceEdge = (coarseSides & 1) ? 0 : (coarseSides & 2) ? 1 : 2;
                    lowest = 0;
                } else if (c < 3 && k != (c == 0 ? 1 : c == 1 ? 2 : 0)) {
                    // Quarter c's edges on the face: c's edge c (half at its
                    // start) and edge c + 2 (half at its end).
                    faceEdge = c == 0 ? (k == 0 ? 0 : 2) : c == 1 ? (k == 0 ? 0 : 1) : (k == 1 ? 1 : 2);
                    end = (c == 0 && k == 2) || (c == 1 && k == 0) || (c == 2 && k == 1) ? 1 : 0;
                }
                if (faceEdge < 0) {  // a sibling across an inner edge
                    uint8_t& sibling = fq[c < 3 ? 3 : (k == 0 ? 2 : k == 1 ? 0 : 1)];
                    if (sibling == lowest) {
                        sibling = uint8_t(lowest + 1);
                        changed = true;
                    }
                    continue;
                }
                const uint32_t edge = edgeOf_[3 * f + size_t(faceEdge)];
                const uint32_t at = control[3 * f + (size_t(faceEdge) + size_t(end)) % 3];
                for (uint32_t m = 0; m < edges_.faceCountOf(edge); ++m) {
                    const size_t g = edges_.cornersOf(edge)[m] / 3;
                    uint8_t* gq = quarters + 4 * g;
                    if (gq[0] == 0 && lowest == 0) {
                        std::fill(gq, gq + 4, uint8_t(1));
                        changed = true;
                        recheck_[g] = 1;
                        continue;
                    }
                    for (int kk = 0; kk < 3; ++kk)
                        if (control[3 * g + size_t(kk)] == at && gq[kk] == lowest) {
                            gq[kk] = uint8_t(lowest + 1);
                            changed = true;
                            recheck_[g] = 1;
                        }
                }
            }
        }
    }
    // What the next choice needs to keep these levels: per face the largest
    // error of what it draws (as the stitching measures it).
    drawnErrors_.resize(nf);
    for (size_t f = 0; f < nf; ++f) {
        if (!touched_[f])
            continue;  // as the last choice drew it
        const uint8_t* fq = quarters + 4 * f;
        float e = alike(fq) ? errors_.at(f, fq[0]) : 0.0f;  // a split face: its quarters' own
        if (fq[0] != 0) {
            int h[3][2];
            faceHalves(h, halves_, control, edgeOf_, f);
            if (alike(fq) && noCoarser(h, fq[0])) {  // unstitched: the quarters' own errors
                for (int c = 0; c < 4; ++c)
                    e = std::max(e, errors_.quarterAt(f, c, fq[0]));
                drawnErrors_[f] = e;
                continue;
            }
            for (int c = 0; c < 4; ++c) {
                int x[3], coarseSides;
                quarterEdges(c, fq, h, x, &coarseSides);
                e = std::max(e, stitchedQuarterError(f, c, fq[c], x, coarseSides));
            }
        }
        drawnErrors_[f] = e;
    }
}

// Per face the smallest (kLeast) or largest of its own value and its edge
// neighbours' (every face around a non-manifold edge): a bend or stretch
// reaches across edges (a smooth surface's stencils do).
template <bool kLeast>
void LevelChooser::spread(const float* own, std::vector<float>* out)
{
    auto pick = [](std::initializer_list<float> v) { return kLeast ? std::min(v) : std::max(v); };
    const size_t nf = errors_.faceCount;
    out->resize(nf);
    float* o = out->data();
    if (!faceNeighbours_.empty()) {
        const uint32_t* nb = faceNeighbours_.data();
        for (size_t f = 0; f < nf; ++f)
            o[f] = pick({own[f], own[nb[3 * f]], own[nb[3 * f + 1]], own[nb[3 * f + 2]]});
        return;
    }
    const float none = kLeast ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
    edgeSpread_.assign(edges_.edgeCount(), none);
    for (size_t e = 0; e < edges_.edgeCount(); ++e)
        for (uint32_t m = 0; m < edges_.faceCountOf(e); ++m)
            edgeSpread_[e] = pick({edgeSpread_[e], own[edges_.cornersOf(e)[m] / 3]});
    for (size_t f = 0; f < nf; ++f) {
        const uint32_t* e = &edgeOf_[3 * f];
        o[f] = pick({own[f], edgeSpread_[e[0]], edgeSpread_[e[1]], edgeSpread_[e[2]]});
    }
}

Status LevelChooser::choose(uint8_t* quarters, const ViewSpec& view, float pixelError, const glm::vec3* controlPositions,
                            size_t controlCount, float poseScale, const glm::vec3* controlNormals,
                            const uint8_t* previous, uint64_t poseStamp)
{
    const int L = errors_.finest;
    const size_t nf = errors_.faceCount;
    if (!quarters || (nf > 0 && !controlPositions))
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
    // The pose's bend at each face: its own, or its neighbours' where
    // larger (a smooth surface's stencils reach across its edges): the
    // smallest cosine of the face and the faces across its edges.
    const bool bent = controlNormals && restCount_ == controlCount;
    // A view that moves over a pose that does not (a still character, a
    // scan) keeps the bends of the last choice: the same stamp, or (none
    // given) the same positions and normals.
    const bool samePose = bent && (poseStamp != 0 ? poseStamp == bentStamp_
                                                  : bentStamp_ == 0 && bentPositions_.size() == controlCount &&
                                                        std::equal(bentPositions_.begin(), bentPositions_.end(),
                                                                   controlPositions) &&
                                                        std::equal(bentNormals_.begin(), bentNormals_.end(), controlNormals));
    corners_.resize(9 * nf);
    gatherCorners(corners_.data(), controlPositions, controlTriangles_.data(), nf);
    if (bent && !samePose) {
        bentStamp_ = poseStamp;
        if (poseStamp == 0) {
            bentPositions_.assign(controlPositions, controlPositions + controlCount);
            bentNormals_.assign(controlNormals, controlNormals + controlCount);
        } else {
            bentPositions_.clear();
            bentNormals_.clear();
        }
        cornerNormals_.resize(9 * nf);
        gatherCorners(cornerNormals_.data(), controlNormals, controlTriangles_.data(), nf);
        own_.resize(nf);
        leastCosines(nf, corners_.data(), cornerNormals_.data(), restLocal_.data(), restFramed_.data(), own_.data());
        spread<true>(own_.data(), &cosines_);
        faceStretches(nf, corners_.data(), restGram_.data(), own_.data());
        spread<false>(own_.data(), &stretches_);
    }
    if (!bent) {
        // No normals to tell a new pose by: the stretch, measured again and
        // spread as with them; the bends and stretches kept for the last
        // pose with normals no longer stand (stretches_ is this pose's).
        bentStamp_ = 0;
        bentPositions_.clear();
        bentNormals_.clear();
        own_.resize(nf);
        faceStretches(nf, corners_.data(), restGram_.data(), own_.data());
        spread<false>(own_.data(), &stretches_);
    }
    gainsFor(nf, corners_.data(), errors_.reach.data(), bent ? cosines_.data() : nullptr, stretches_.data(),
             GainView{cam.eye, cam.forward, cam.k, poseScale, smooth_ ? 1.0f : 0.0f}, gains_.data());
    // What the picking and stitching aim at: the tolerance, or, where this
    // choice follows levels chosen before (a view or pose that moves),
    // kMotionTolerance of it (see choose).
    const float target = previous ? kMotionTolerance * pixelError : pixelError;
    // Face f's levels from its gain: the lowest level within the target
    // and, from level 2, each quarter's.
    auto pickFace = [&](size_t f) {
        const float g = gains_[f];
        // The lowest level in [from, to] within the target; a previous
        // level `was` above it is kept while no finer than the lowest
        // within kHoldTolerance of the tolerance (past that, the lowest
        // within the target: a camera that jumps away does not keep the
        // band's extra detail).
        auto pick = [&](int from, int to, int was, auto&& error) {
            auto lowest = [&](float tolerance) {
                for (int l = from; l < to; ++l)
                    if (error(l) * g <= tolerance)
                        return l;
                return to;
            };
            const int need = lowest(target);
            return was <= need || was > lowest(kHoldTolerance * pixelError) ? need : was;
        };
        const uint8_t* pq = previous ? previous + 4 * f : nullptr;
        const int level = pick(0, L, pq ? std::max({pq[0], pq[1], pq[2], pq[3]}) : 0,
                               [&](int l) { return errors_.at(f, l); });
        // Below level 2 a quarter has nothing coarser to take.
        uint8_t* fq = quarters + 4 * f;
        for (int k = 0; k < 4; ++k)
            fq[k] = uint8_t(level < 2 ? level
                                      : pick(1, level, pq ? pq[k] : 0, [&](int l) { return errors_.quarterAt(f, k, l); }));
        // A split whose quarters' grids hold more points than the face's
        // (their shared borders counted twice, as the frame's passes work
        // them) saves too few vertices to pay for its smaller tiles.
        if (level >= 2) {
            auto points = [](int l) { const uint32_t n = 1u << l; return (n + 1) * (n + 2) / 2; };
            uint32_t split = 0;
            for (int k = 0; k < 4; ++k)
                split += points(fq[k] - 1);
            if (split > points(level))
                std::fill(fq, fq + 4, uint8_t(level));
        }
    };
    // The last choice's levels stand, without picking or stitching, while
    // everything it draws is still within the tolerance and at most one face
    // in kRepairShare could fall (its gain fell below kHoldTolerance of its
    // gain then; see choose).  Where only a few faces no longer stand, the
    // choice is repaired: stitched from those faces and the ones whose
    // levels the picking changed.
    auto within = [&](size_t f, float tolerance) {
        const float g = gains_[f], e = drawnErrors_[f];
        return int((e == 0.0f) | (e * g <= tolerance));
    };
    auto holds = [&](size_t f) { return int(gains_[f] >= kHoldTolerance * chosenGains_[f]); };
    // What a repair checks again: the faces past the target (the tolerance
    // itself, or kMotionTolerance of it) or able to fall.
    auto settled = [&](size_t f) { return within(f, target) & holds(f); };
    bool repair = false;
    if (previous && pixelError == lastTolerance_ && lastQuarters_.size() == 4 * nf &&
        std::equal(lastQuarters_.begin(), lastQuarters_.end(), previous)) {
        // Every face checked, without a branch: the loop vectorises.
        size_t moved = 0, rising = 0;
        for (size_t f = 0; f < nf; ++f) {
            const int w = within(f, pixelError);
            rising += size_t(1 - w);
            moved += size_t(1 - (w & holds(f)));
        }
        // Detail no longer needed waits: it still meets the tolerance, and
        // dropping it costs a rebuild.
        if (rising == 0 && moved * kRepairShare <= nf) {
            std::copy(previous, previous + 4 * nf, quarters);
            ++keptChoices_;
            return Status::ok();
        }
        repair = moved * kRepairShare <= nf;
    }
    moved_.clear();
    if (repair)
        for (size_t f = 0; f < nf; ++f)
            if (!settled(f))
                moved_.push_back(uint32_t(f));
    for (size_t f = 0; f < nf; ++f)
        pickFace(f);
    stitch(quarters, target, repair);
    // A repair stands where every face it checked draws within the target
    // (the others passed above); otherwise the choice is made in full.
    if (repair) {
        bool checked = true;
        for (size_t f = 0; f < nf && checked; ++f)
            checked = !touched_[f] || within(f, target);
        if (!checked) {
            repair = false;
            for (size_t f = 0; f < nf; ++f)
                pickFace(f);
            stitch(quarters, target, false);
        }
    }
    ++(repair ? repairedChoices_ : fullChoices_);
    chosenGains_ = gains_;
    lastQuarters_.assign(quarters, quarters + 4 * nf);
    lastTolerance_ = pixelError;
    return Status::ok();
}

namespace {

// Unnormalised normals of triangles list[b .. e) of a frame's triangles.
STRATA_KERNEL_CLONES void triangleNormalsRange(const uint32_t* triangles, const uint32_t* list, const glm::vec3* p,
                                               glm::vec3* out, size_t b, size_t e)
{
    for (size_t k = b; k < e; ++k) {
        const uint32_t* t = triangles + 3 * size_t(list[k]);
        const glm::vec3 a = p[t[0]];
        out[k] = glm::cross(p[t[1]] - a, p[t[2]] - a);
    }
}


}  // namespace

// The tile pass's scratch (one per thread) and its arguments.
struct AdaptiveFrame::Scratch : detail::GridScratch {};

struct AdaptiveFrame::TileJob {
    const uint32_t* control;
    const LevelGrid* grids;
    const uint32_t* gridOf;
    const uint32_t *faces, *first, *slots, *writeFirst, *snapFirst;
    const GridWrite* writes;
    const uint16_t* snaps;
    const uint32_t* partialFirst;
    const uint16_t* partialSlots;
    glm::vec3* partials;
    const float* d;
    const glm::vec3 *cp, *cn;  // linear: the control mesh (null: smooth, positions read)
    glm::vec3 *positions, *normals;
};

// Grid tiles [begin, end): linear, displaced positions as the uniform
// frame's tiles compute them (bit-identical to Plan::evaluate), each
// snapped point then at its target; smooth, the positions already
// evaluated, snapped points reading their target's.  Then the grid's sums
// of face normals (a collapsed triangle has zero area); the tile writes its
// own vertices' positions and its inner vertices' normals.
STRATA_KERNEL_CLONES void AdaptiveFrame::shadeTiles(const TileJob& job, Scratch& s, size_t begin, size_t end)
{
    float* p[3] = {s.px.data(), s.py.data(), s.pz.data()};
    float* sum[3] = {s.sum[0].data(), s.sum[1].data(), s.sum[2].data()};
    float* face[3][2][3];
    for (int pair = 0; pair < 3; ++pair)
        for (int kind = 0; kind < 2; ++kind)
            for (int a = 0; a < 3; ++a)
                face[pair][kind][a] = s.face[pair][kind][a].data();
    for (size_t g = begin; g < end; ++g) {
        const uint32_t f = job.faces[g];
        const LevelGrid& grid = job.grids[job.gridOf[g]];
        const size_t R = grid.res, S = (R + 1) * (R + 2) / 2;
        const uint32_t* slot = job.slots + job.first[g];
        if (job.cp) {
            float* dl = s.d.data();
            for (size_t k = 0; k < S; ++k)
                dl[k] = job.d[slot[k]];
            const uint32_t* c = job.control + 3 * size_t(f);
            detail::displaceGrid(detail::wholeVectors(S), grid.w1.data(), grid.w2.data(), dl, job.cp[c[0]],
                                 job.cp[c[1]], job.cp[c[2]], job.cn[c[0]], job.cn[c[1]], job.cn[c[2]], p[0], p[1],
                                 p[2]);
            for (uint32_t k = job.snapFirst[g]; k < job.snapFirst[g + 1]; k += 2)
                for (int a = 0; a < 3; ++a)
                    p[a][job.snaps[k]] = p[a][job.snaps[k + 1]];
        } else {
            for (size_t k = 0; k < S; ++k) {
                const glm::vec3 q = job.positions[slot[k]];
                p[0][k] = q.x;
                p[1][k] = q.y;
                p[2][k] = q.z;
            }
        }
        if (job.normals) {
            if (R == 8)
                detail::gridNormalSums<8>(R, grid.rows.data(), p, face, s.zero.data(), sum);
            else if (R == 16)
                detail::gridNormalSums<16>(R, grid.rows.data(), p, face, s.zero.data(), sum);
            else
                detail::gridNormalSums<0>(R, grid.rows.data(), p, face, s.zero.data(), sum);
            // A snapped point's triangles are its target's; a border
            // slot's sum is the tile's share of its vertex's normal.
            for (uint32_t k = job.snapFirst[g]; k < job.snapFirst[g + 1]; k += 2)
                for (int a = 0; a < 3; ++a)
                    sum[a][job.snaps[k + 1]] += sum[a][job.snaps[k]];
            for (uint32_t k = job.partialFirst[g]; k < job.partialFirst[g + 1]; ++k) {
                const size_t at = job.partialSlots[k];
                job.partials[k] = glm::vec3(sum[0][at], sum[1][at], sum[2][at]);
            }
            detail::normalizeGrid(detail::wholeVectors(S), sum[0], sum[1], sum[2]);
        }
        for (uint32_t w = job.writeFirst[g]; w < job.writeFirst[g + 1]; ++w) {
            const GridWrite& out = job.writes[w];
            const size_t k = out.slot;
            if (job.cp)
                job.positions[out.vertex] = glm::vec3(p[0][k], p[1][k], p[2][k]);
            if (job.normals && out.inner)
                job.normals[out.vertex] = glm::vec3(sum[0][k], sum[1][k], sum[2][k]);
        }
    }
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
    halves_.assign(2 * edges.edgeCount(), 0);
    const size_t combos = size_t(finest_ + 1) * size_t(finest_ + 1) * size_t(finest_ + 1) * size_t(finest_ + 1);
    templates_.resize(combos);
    remap_.assign(plan.refinedVertexCount(), kNone);
    // The tile pass's grids, level kGridLevel and finer.
    levelGrids_.resize(size_t(finest_) + 1);
    for (int level = kGridLevel; level <= finest_; ++level) {
        LevelGrid& grid = levelGrids_[size_t(level)];
        const uint32_t r = 1u << level, step = 1u << (finest_ - level);
        grid.res = r;
        detail::gridTables(r, &grid.rows, &grid.w1, &grid.w2);
        grid.fine.resize(size_t(r + 1) * (r + 2) / 2);
        grid.border.resize(grid.fine.size());
        for (uint32_t i = 0; i <= r; ++i)
            for (uint32_t j = 0; i + j <= r; ++j) {
                grid.fine[gridSlot(i, j, r)] = uint16_t(tileSlot(i * step, j * step, R));
                grid.border[gridSlot(i, j, r)] = uint8_t(i == 0 || j == 0 || i + j == r);
            }
    }
    // Each quarter's grids, level kGridLevel + 1 and finer: the same rows,
    // the face's barycentrics at the quarter's points.
    levelGrids_.resize(size_t(finest_ + 1) * 5);
    for (int quarter = 0; quarter < 4; ++quarter)
        for (int level = kQuarterGridLevel; level <= finest_; ++level) {
            const int none[3] = {finest_, finest_, finest_};
            const QuarterLattice q(finest_, quarter, level, none, 0);
            LevelGrid& grid = levelGrids_[quarterGrid(finest_, quarter, level)];
            grid.res = q.r;
            detail::gridTables(q.r, &grid.rows, &grid.w1, &grid.w2);
            grid.fine.resize(size_t(q.r + 1) * (q.r + 2) / 2);
            grid.border.resize(grid.fine.size());
            for (uint32_t u = 0; u <= q.r; ++u)
                for (uint32_t v = 0; u + v <= q.r; ++v) {
                    uint32_t i, j;
                    q.at(u, v, &i, &j);
                    const size_t k = gridSlot(u, v, q.r);
                    grid.border[k] = uint8_t(u == 0 || v == 0 || u + v == q.r);
                    grid.w1[k] = float(i) / float(R);
                    grid.w2[k] = float(j) / float(R);
                    grid.fine[k] = uint16_t(tileSlot(i, j, R));
                }
        }
}

AdaptiveFrame::~AdaptiveFrame() = default;

void AdaptiveFrame::TileTemplate::indexCorners(size_t tileSlots)
{
    std::vector<int32_t> at(tileSlots, -1);
    used.clear();
    corner.resize(fine.size());
    for (size_t k = 0; k < fine.size(); ++k) {
        int32_t& u = at[fine[k]];
        if (u < 0) {
            u = int32_t(used.size());
            used.push_back(fine[k]);
        }
        corner[k] = uint16_t(u);
    }
}

void AdaptiveFrame::TileTemplate::indexLocal()
{
    usedLocal.resize(used.size());
    for (size_t k = 0; k < fine.size(); ++k)
        usedLocal[corner[k]] = local[k];
}

size_t AdaptiveFrame::templateFor(int level, const int e[3])
{
    const size_t key = templateKey(finest_, level, e);
    TileTemplate& t = templates_[key];
    if (t.fine.empty()) {
        adaptiveTileTriangles(&t.fine, finest_, level, e);
        t.indexCorners(slots_);
        if (level < kGridLevel)
            return key;
        // The same triangles in the level's grid slots, and where each grid
        // point is drawn (a point snapped onto another takes its position).
        const uint32_t step = 1u << (finest_ - level), R = 1u << level;
        const size_t slots = size_t(R + 1) * (R + 2) / 2;
        t.local.resize(t.fine.size());
        for (size_t k = 0; k < t.fine.size(); ++k)
            t.local[k] = uint16_t(gridSlot(slotI_[t.fine[k]] / step, slotJ_[t.fine[k]] / step, R));
        t.snapTo.resize(slots);
        t.snaps.clear();
        for (uint32_t i = 0; i <= R; ++i)
            for (uint32_t j = 0; i + j <= R; ++j) {
                uint32_t si = i, sj = j;
                snapPoint(&si, &sj, level, e);
                const uint16_t from = uint16_t(gridSlot(i, j, R)), to = uint16_t(gridSlot(si, sj, R));
                t.snapTo[from] = to;
                if (from != to)
                    t.snaps.insert(t.snaps.end(), {from, to});
            }
        t.indexLocal();
    }
    return key;
}

const AdaptiveFrame::TileTemplate& AdaptiveFrame::quarterTemplateFor(int quarter, int level, const int x[3],
                                                                      int coarseSides)
{
    TileTemplate& t = quarterTemplates_[quarterKey(quarter, level, x, coarseSides)];
    if (!t.fine.empty() || level < 1)
        return t;
    adaptiveQuarterTriangles(&t.fine, finest_, quarter, level, x, coarseSides);
    t.indexCorners(slots_);
    if (level < kQuarterGridLevel)
        return t;
    // The same triangles in the quarter's grid slots, and where each of its
    // points is drawn; a point drawn off the quarter's grid (beside a face
    // at level 0) leaves the quarter to the small tiles' passes.
    const QuarterLattice q(finest_, quarter, level, x, coarseSides);
    const size_t slots = size_t(q.r + 1) * (q.r + 2) / 2;
    t.local.resize(t.fine.size());
    t.snapTo.resize(slots);
    t.snaps.clear();
    for (size_t k = 0; k < t.fine.size(); ++k) {
        uint32_t u, v;
        if (!q.local(slotI_[t.fine[k]], slotJ_[t.fine[k]], &u, &v))
            return t;
        t.local[k] = uint16_t(gridSlot(u, v, q.r));
    }
    for (uint32_t u = 0; u <= q.r; ++u)
        for (uint32_t v = 0; u + v <= q.r; ++v) {
            uint32_t i, j, su, sv;
            q.drawnAt(u, v, &i, &j);
            if (!q.local(i, j, &su, &sv))
                return t;
            const uint16_t from = uint16_t(gridSlot(u, v, q.r)), to = uint16_t(gridSlot(su, sv, q.r));
            t.snapTo[from] = to;
            if (from != to)
                t.snaps.insert(t.snaps.end(), {from, to});
        }
    t.indexLocal();
    t.grid = true;
    return t;
}

Status AdaptiveFrame::setLevels(const uint8_t* levels, size_t count)
{
    const size_t nf = plan_.controlTriangles().size() / 3;
    if (count != nf || (nf > 0 && !levels))
        return Status(StatusCode::InvalidArgument, std::to_string(levels ? count : 0) + " face levels for " +
                                                       std::to_string(nf) + " control faces");
    for (size_t f = 0; f < nf; ++f)
        if (levels[f] > finest_)
            return Status(StatusCode::InvalidArgument, "control face " + std::to_string(f) + " asks for level " +
                                                           std::to_string(levels[f]) + ", past the plan's level " +
                                                           std::to_string(finest_));
    quarterScratch_.resize(4 * nf);
    for (size_t f = 0; f < nf; ++f)
        std::fill(&quarterScratch_[4 * f], &quarterScratch_[4 * f] + 4, levels[f]);
    return setQuarterLevels(quarterScratch_.data(), quarterScratch_.size());
}

int AdaptiveFrame::triangleLevel(size_t t) const
{
    const uint8_t* q = &quarters_[4 * size_t(triangleFaces_[t])];
    if (alike(q))
        return q[0];
    const uint16_t* cs = &cornerSlots_[3 * t];
    const uint32_t i = uint32_t(slotI_[cs[0]]) + slotI_[cs[1]] + slotI_[cs[2]];
    const uint32_t j = uint32_t(slotJ_[cs[0]]) + slotJ_[cs[1]] + slotJ_[cs[2]];
    return q[quarterAt(i, j, 3u << finest_)];  // the centroid's quarter (three times its grid point)
}

size_t AdaptiveFrame::splitFaceCount() const
{
    size_t n = 0;
    for (size_t k = 0; k < quarters_.size(); k += 4)
        n += alike(&quarters_[k]) ? 0 : 1;
    return n;
}

void AdaptiveFrame::cornerUVs(std::vector<glm::vec2>* out, const glm::vec2* uvs, const uint32_t* uvIndices) const
{
    const float R = float(1u << finest_);
    out->resize(cornerSlots_.size());
    for (size_t c = 0; c < cornerSlots_.size(); ++c) {
        const uint32_t* uv = &uvIndices[3 * size_t(triangleFaces_[c / 3])];
        const float b1 = float(slotI_[cornerSlots_[c]]) / R, b2 = float(slotJ_[cornerSlots_[c]]) / R;
        (*out)[c] = (1.0f - b1 - b2) * uvs[uv[0]] + b1 * uvs[uv[1]] + b2 * uvs[uv[2]];
    }
}

Status AdaptiveFrame::setQuarterLevels(const uint8_t* quarters, size_t count)
{
    const std::vector<uint32_t>& control = plan_.controlTriangles();
    const size_t nf = control.size() / 3;
    if (tiles_.size() != nf * slots_)
        return Status(StatusCode::InvalidData, "the plan's refined faces are not a grid per control face");
    if (count != 4 * nf || (nf > 0 && !quarters))
        return Status(StatusCode::InvalidArgument, std::to_string(quarters ? count : 0) + " quarter levels for " +
                                                       std::to_string(nf) + " control faces (4 each)");
    for (size_t f = 0; f < nf; ++f) {
        const uint8_t* q = quarters + 4 * f;
        const uint8_t top = std::max({q[0], q[1], q[2], q[3]}), low = std::min({q[0], q[1], q[2], q[3]});
        if (top > finest_)
            return Status(StatusCode::InvalidArgument, "control face " + std::to_string(f) + " asks for level " +
                                                           std::to_string(top) + ", past the plan's level " +
                                                           std::to_string(finest_));
        if (low == 0 && top != 0)
            return Status(StatusCode::InvalidArgument, "control face " + std::to_string(f) +
                                                           " mixes level 0 with finer quarters (a quarter's levels "
                                                           "are 1 and up; level 0 is the whole face)");
    }
    ++topologyVersion_;
    quarters_.assign(quarters, quarters + 4 * nf);
    settleQuarters(quarters_.data(), edgeOf_, halves_.size() / 2, &zeroEdges_);
    quarters = quarters_.data();
    levels_.resize(nf);
    for (size_t f = 0; f < nf; ++f)
        levels_[f] = std::max({quarters[4 * f], quarters[4 * f + 1], quarters[4 * f + 2], quarters[4 * f + 3]});
    halfLevelsFor(&halves_, quarters, control.data(), edgeOf_, finest_);

    const bool linear = plan_.scheme() == Scheme::Linear;
    const std::vector<SampleLocation>& samples = plan_.sampleLocations();

    // The drawn units, chosen first: a whole face, or a quarter of one.
    // `grid`: its tile pass runs on levelGrids_[gridIndex]; a whole face's
    // tile writes the positions of the border points its face owns too (a
    // quarter's are streamed, or evaluated, with the small tiles').  Their
    // sizes then size every record once.
    units_.resize(4 * nf);
    size_t unitCount = 0, cornerTotal = 0, slotTotal = 0;
    auto unit = [&](size_t f, const TileTemplate& tt, bool grid, size_t gridIndex, bool whole) {
        units_[unitCount++] = Unit{&tt, uint32_t(f), uint32_t(gridIndex), grid, whole};
        cornerTotal += tt.fine.size();
        if (grid)
            slotTotal += levelGrids_[gridIndex].fine.size();
    };
    for (size_t f = 0; f < nf; ++f) {
        const uint8_t* q = quarters + 4 * f;
        int h[3][2], e[3];
        faceHalves(h, halves_, control.data(), edgeOf_, f);
        if (!drawnWhole(q, h, e)) {
            for (int c = 0; c < 4; ++c) {
                int x[3], coarseSides;
                quarterEdges(c, q, h, x, &coarseSides);
                const TileTemplate& tt = quarterTemplateFor(c, q[c], x, coarseSides);
                unit(f, tt, tt.grid, quarterGrid(finest_, c, q[c]), false);
            }
            continue;
        }
        const int l = q[0];
        unit(f, templates_[templateFor(l, e)], l >= kGridLevel, size_t(l), true);
    }
    units_.resize(unitCount);

    // Per frame vertex (at most the plan's): its refined vertex, whether it
    // gathers its normal from shares and how many, whether the tile pass
    // writes its position.  Per triangle: its corners, their finest-tile
    // slots, its face.
    const size_t most = plan_.refinedVertexCount();
    if (frameVertex_.size() < most) {
        frameVertex_.resize(most);
        gathered_.resize(most);
        written_.resize(most);
        shareCount_.resize(most);
    }
    uint32_t* const vertex = frameVertex_.data();
    uint32_t* const shareCount = shareCount_.data();
    uint8_t *const gathered = gathered_.data(), *const written = written_.data();
    triangles_.resize(cornerTotal);
    cornerSlots_.resize(cornerTotal);
    triangleFaces_.resize(cornerTotal / 3);
    gatherTriangles_.resize(cornerTotal / 3);
    size_t smallTriangles = 0;
    gridFaces_.clear();
    gridOf_.clear();
    gridFirst_.assign(1, 0);
    gridWriteFirst_.assign(1, 0);
    gridSnapFirst_.assign(1, 0);
    gridSnaps_.clear();
    gridPartialFirst_.assign(1, 0);
    // Room for every slot (trimmed after): records written in place, where
    // one built aside and copied in stalls on its own stores.
    gridSlots_.resize(slotTotal);
    gridWrites_.resize(slotTotal);
    gridPartialSlots_.resize(slotTotal);
    partialVertex_.resize(slotTotal);
    if (slotVertex_.empty())
        slotVertex_.assign(slots_, kNone);
    if (unitVertex_.size() < slots_)
        unitVertex_.resize(slots_);
    size_t n = 0, corner = 0, slotAt = 0, writes = 0, partials = 0;
    for (const Unit& un : units_) {
        const TileTemplate& tt = *un.tt;
        const std::vector<uint16_t>& t = tt.fine;
        const uint32_t* tile = &tiles_[size_t(un.face) * slots_];
        const LevelGrid* lg = un.grid ? &levelGrids_[un.gridIndex] : nullptr;
        // Its vertices, numbered as its corners first use them; a small
        // tile's, or one a grid shares with another unit (its border),
        // sums its normal from shares.
        for (size_t u = 0; u < tt.used.size(); ++u) {
            const uint32_t v = tile[tt.used[u]];
            const uint8_t shared = uint8_t(!lg || lg->border[tt.usedLocal[u]]);
            uint32_t& m = remap_[v];
            if (m == kNone) {
                m = uint32_t(n++);
                vertex[m] = v;
                gathered[m] = shared;
                written[m] = 0;
                shareCount[m] = 0;
            } else if (shared) {
                gathered[m] = 1;
            }
            unitVertex_[u] = m;
            if (lg)
                slotVertex_[tt.usedLocal[u]] = m;
        }
        uint32_t* corners = triangles_.data() + corner;
        for (size_t k = 0; k < t.size(); ++k)
            corners[k] = unitVertex_[tt.corner[k]];
        std::copy(t.begin(), t.end(), cornerSlots_.begin() + long(corner));
        std::fill_n(triangleFaces_.begin() + long(corner / 3), t.size() / 3, un.face);
        if (!lg) {
            // A small tile's triangles: each a share of its corners' normals.
            for (size_t k = 0; k < t.size(); ++k)
                ++shareCount[corners[k]];
            for (size_t k = corner / 3; k < (corner + t.size()) / 3; ++k)
                gatherTriangles_[smallTriangles++] = uint32_t(k);
            corner += t.size();
            continue;
        }
        corner += t.size();
        // The tile pass: per grid slot its displacement's refined vertex
        // (linear) or the frame vertex whose position it takes (smooth);
        // the vertices it writes; its snapped points (linear).
        const size_t S = lg->fine.size();
        const uint32_t R = lg->res;
        gridFaces_.push_back(un.face);
        gridOf_.push_back(un.gridIndex);
        uint32_t* gridSlot0 = gridSlots_.data() + slotAt;
        for (size_t k = 0; k < S; ++k)
            gridSlot0[k] = linear ? tile[lg->fine[k]] : slotVertex_[tt.snapTo[k]];
        slotAt += S;
        gridFirst_.push_back(uint32_t(slotAt));
        for (uint32_t i = 0; i <= R; ++i)
            for (uint32_t j = 0; i + j <= R; ++j) {
                const size_t k = gridSlot(i, j, R);
                const uint32_t v = slotVertex_[k];
                if (v == kNone)
                    continue;
                const bool inner = !lg->border[k];
                // A border point's position is written by the face that owns it.
                if (inner || (un.whole && linear && samples[vertex[v]].face == un.face)) {
                    GridWrite& w = gridWrites_[writes++];
                    w.vertex = v;
                    w.slot = uint16_t(k);
                    w.inner = uint16_t(inner);
                    written[v] = 1;
                }
                if (!inner) {  // the tile's share of a border vertex's normal
                    gridPartialSlots_[partials] = uint16_t(k);
                    partialVertex_[partials++] = v;
                    ++shareCount[v];
                }
                slotVertex_[k] = kNone;
            }
        gridWriteFirst_.push_back(uint32_t(writes));
        gridPartialFirst_.push_back(uint32_t(partials));
        gridSnaps_.insert(gridSnaps_.end(), tt.snaps.begin(), tt.snaps.end());
        gridSnapFirst_.push_back(uint32_t(gridSnaps_.size()));
    }
    gatherTriangles_.resize(smallTriangles);
    gridWrites_.resize(writes);
    gridPartialSlots_.resize(partials);
    partialVertex_.resize(partials);
    vertices_.assign(vertex, vertex + n);
    for (uint32_t v : vertices_)
        remap_[v] = kNone;

    // The gather pass: per gathered vertex its shares, first the grid
    // tiles' partial sums (in tile order), then the normals of the small
    // tiles' triangles (in frame order).  A gathered vertex's share count
    // becomes its cursor into gatherEntries_.
    gatherVertices_.resize(n);
    gatherOffsets_.resize(n + 1);
    gatherOffsets_[0] = 0;
    size_t g = 0;
    uint32_t total = 0;
    for (size_t v = 0; v < n; ++v)
        if (gathered[v]) {
            gatherVertices_[g] = uint32_t(v);
            const uint32_t shares = shareCount[v];
            shareCount[v] = total;
            total += shares;
            gatherOffsets_[++g] = total;
        }
    gatherVertices_.resize(g);
    gatherOffsets_.resize(g + 1);
    gatherEntries_.resize(total);
    for (size_t k = 0; k < partials; ++k)
        gatherEntries_[shareCount[partialVertex_[k]]++] = uint32_t(k);
    for (size_t k = 0; k < gatherTriangles_.size(); ++k) {
        const uint32_t* c = &triangles_[3 * size_t(gatherTriangles_[k])];
        for (int i = 0; i < 3; ++i)
            gatherEntries_[shareCount[c[i]]++] = uint32_t(partials + k);
    }
    shares_.resize(partials + gatherTriangles_.size());

    // Linear scheme: the vertices of faces drawn below kGridLevel, each
    // with its control corners, weights and displacement side by side, so
    // a frame streams them.
    linear_.clear();
    if (linear) {
        // Written in place (room for all, trimmed after), as the tile records.
        const std::vector<float>& d = plan_.displacements();
        linear_.resize(n);
        size_t streamed = 0;
        for (size_t k = 0; k < n; ++k) {
            if (written_[k])
                continue;  // the tile pass writes it
            const SampleLocation& at = samples[vertices_[k]];
            const uint32_t* c = &control[3 * size_t(at.face)];
            LinearVertex& v = linear_[streamed++];
            v.c[0] = c[0];
            v.c[1] = c[1];
            v.c[2] = c[2];
            v.target = uint32_t(k);
            v.w1 = at.bary.x;
            v.w2 = at.bary.y;
            v.d = d[vertices_[k]];
        }
        linear_.resize(streamed);
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
    const bool linear = plan_.scheme() == Scheme::Linear;
    if (!linear)
        parallel(threads, vertices_.size(), [&](size_t b, size_t e, int) {
            (void)plan_.evaluateVertices(positions + b, nullptr, vertices_.data() + b, e - b, d, controlPositions,
                                         controlNormals, controlCount);
        });
    // The tile pass: linear, the positions of faces at kGridLevel or finer;
    // either scheme, their inner vertices' normals.
    if (!gridFaces_.empty() && (linear || normals)) {
        const int pool = threads <= 1 ? 1 : threads;
        if (scratch_.size() < size_t(pool)) {
            scratch_.resize(size_t(pool));
            for (Scratch& s : scratch_)
                s.resize(slots_, (size_t(1) << finest_) + 1);
        }
        TileJob job{};
        job.control = plan_.controlTriangles().data();
        job.grids = levelGrids_.data();
        job.gridOf = gridOf_.data();
        job.faces = gridFaces_.data();
        job.first = gridFirst_.data();
        job.slots = gridSlots_.data();
        job.writeFirst = gridWriteFirst_.data();
        job.writes = gridWrites_.data();
        job.snapFirst = gridSnapFirst_.data();
        job.snaps = gridSnaps_.data();
        job.partialFirst = gridPartialFirst_.data();
        job.partialSlots = gridPartialSlots_.data();
        job.partials = shares_.data();
        job.d = d;
        job.cp = linear ? controlPositions : nullptr;
        job.cn = linear ? controlNormals : nullptr;
        job.positions = positions;
        job.normals = normals;
        parallel(threads, gridFaces_.size(), [&](size_t b, size_t e, int t) { shadeTiles(job, scratch_[size_t(t)], b, e); });
    }
    if (linear) {
        // The other faces' vertices: Plan::evaluate's expression, bit for
        // bit, over the streamed corners.
        const bool own = d == plan_.displacements().data();
        parallel(threads, linear_.size(), [&](size_t b, size_t e, int) {
            for (size_t k = b; k < e; ++k) {
                const LinearVertex& v = linear_[k];
                const float w1 = v.w1, w2 = v.w2, w0 = 1.0f - w1 - w2;
                const glm::vec3 p = w0 * controlPositions[v.c[0]] + w1 * controlPositions[v.c[1]] +
                                    w2 * controlPositions[v.c[2]];
                const glm::vec3 n = w0 * controlNormals[v.c[0]] + w1 * controlNormals[v.c[1]] + w2 * controlNormals[v.c[2]];
                positions[v.target] = shared::strata_displace(p, n, own ? v.d : d[vertices_[v.target]]);
            }
        });
    }
    if (!normals)
        return Status::ok();

    // Every vertex the tile pass leaves (on a control edge, or in a face
    // below kGridLevel) sums its shares: grid tiles' partial sums and the
    // small tiles' triangle normals.
    glm::vec3* triangleShares = shares_.data() + partialVertex_.size();
    parallel(threads, gatherTriangles_.size(), [&](size_t b, size_t e, int) {
        triangleNormalsRange(triangles_.data(), gatherTriangles_.data(), positions, triangleShares, b, e);
    });
    parallel(threads, gatherVertices_.size(), [&](size_t b, size_t e, int) {
        detail::finishBorders(normals, gatherVertices_.data(), gatherOffsets_.data(), gatherEntries_.data(),
                              shares_.data(), b, e);
    });
    return Status::ok();
}

float AdaptiveFrame::maxScreenDeviation(const glm::vec3* framePositions, const glm::vec3* finePositions,
                                        const ViewSpec& view, int subdivision) const
{
    if (!view.valid() || !framePositions || !finePositions || subdivision < 1)
        return 0.0f;
    const Camera cam(view);
    const int R = 1 << finest_, m = std::min(subdivision, 64);
    float worst = 0.0f;
    const size_t nt = triangles_.size() / 3;
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t* tile = &tiles_[size_t(triangleFaces_[t]) * slots_];
        const uint16_t* cs = &cornerSlots_[3 * t];
        const int gi[3] = {slotI_[cs[0]], slotI_[cs[1]], slotI_[cs[2]]}, gj[3] = {slotJ_[cs[0]], slotJ_[cs[1]], slotJ_[cs[2]]};
        const uint32_t* v = &triangles_[3 * t];
        const glm::dvec3 p[3] = {framePositions[v[0]], framePositions[v[1]], framePositions[v[2]]};
        const int si[3] = {m * gi[0], m * gi[1], m * gi[2]}, sj[3] = {m * gj[0], m * gj[1], m * gj[2]};
        // The finest surface at lattice point (I, J) / m: its triangle's
        // interpolation there (the cell's lower triangle below the cell's
        // diagonal i + j = const, else the upper one).
        auto fineAt = [&](int I, int J) {
            auto at = [&](int i, int j) {
                return glm::dvec3(finePositions[tile[tileSlot(uint32_t(i), uint32_t(j), uint32_t(R))]]);
            };
            const int i = I / m, j = J / m, a = I - m * i, b = J - m * j;
            if (a == 0 && b == 0)
                return at(i, j);
            const double da = double(a) / m, db = double(b) / m;
            if (a + b <= m)
                return (1.0 - da - db) * at(i, j) + da * at(i + 1, j) + db * at(i, j + 1);
            return (da + db - 1.0) * at(i + 1, j + 1) + (1.0 - da) * at(i, j + 1) + (1.0 - db) * at(i + 1, j);
        };
        auto measure = [&](const glm::dvec3& drawn, const glm::dvec3& fine) {
            // Points a few float steps apart are one point: two evaluation
            // orders of the same vertex differ so (the smooth scheme's tile
            // pass against its stencils, 1e-7 at 0.75), and a point
            // 0.000005 units in front of the eye turned that into 2.7
            // million pixels.
            const glm::dvec3 magnitude = glm::max(glm::abs(fine), glm::abs(drawn));
            const double ulps = 8.0 * double(std::numeric_limits<float>::epsilon()) *
                                std::max({magnitude.x, magnitude.y, magnitude.z});
            const double apart = glm::length(fine - drawn);
            double xa, ya, xb, yb, da, depth;
            if (apart > ulps && cam.project(drawn, &xa, &ya, &da) && cam.project(fine, &xb, &yb, &depth))
                worst = std::max(worst, float(std::max(std::hypot(xa - xb, ya - yb), apart * double(cam.k) / depth)));
        };
        rasterGrid(si, sj, m * R, [&](int i, int j, const int w[3], int area) {
            measure((double(w[0]) * p[0] + double(w[1]) * p[1] + double(w[2]) * p[2]) / double(area), fineAt(i, j));
        });
        for (int e = 0; e < 3; ++e) {
            const int b = (e + 1) % 3;
            forEachCrossing(gi[e], gj[e], gi[b], gj[b], [&](double along, int i0, int j0, int i1, int j1, double f) {
                const glm::dvec3 a(finePositions[tile[tileSlot(uint32_t(i0), uint32_t(j0), uint32_t(R))]]);
                const glm::dvec3 c(finePositions[tile[tileSlot(uint32_t(i1), uint32_t(j1), uint32_t(R))]]);
                measure(p[e] + along * (p[b] - p[e]), a + f * (c - a));
            });
        }
    }
    return worst;
}

size_t AdaptiveFrame::bytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    size_t t = 0;
    for (const TileTemplate& v : templates_)
        t += bytes(v.fine) + bytes(v.local) + bytes(v.snapTo) + bytes(v.snaps);
    for (const LevelGrid& v : levelGrids_)
        t += bytes(v.rows) + bytes(v.w1) + bytes(v.w2) + bytes(v.fine) + bytes(v.border);
    for (const Scratch& v : scratch_)
        t += v.bytes();
    for (const auto& v : quarterTemplates_)
        t += bytes(v.second.fine) + bytes(v.second.local) + bytes(v.second.snapTo) + bytes(v.second.snaps) +
             sizeof(v) + 2 * sizeof(void*);
    return t + bytes(tiles_) + bytes(slotI_) + bytes(slotJ_) + bytes(edgeOf_) + bytes(halves_) + bytes(levels_) +
           bytes(quarters_) + bytes(quarterScratch_) + bytes(units_) + bytes(frameVertex_) + bytes(shareCount_) + bytes(written_) + bytes(gridOf_) +
           bytes(remap_) + bytes(vertices_) + bytes(triangles_) + bytes(triangleFaces_) + bytes(cornerSlots_) +
           bytes(gridFaces_) + bytes(gridFirst_) + bytes(gridSlots_) + bytes(gridWriteFirst_) + bytes(gridWrites_) +
           bytes(gridSnapFirst_) + bytes(gridSnaps_) + bytes(slotVertex_) + bytes(gathered_) + bytes(gatherVertices_) + bytes(gatherOffsets_) + bytes(gatherEntries_) +
           bytes(gatherTriangles_) + bytes(shares_) + bytes(gridPartialFirst_) + bytes(gridPartialSlots_) + bytes(partialVertex_) + bytes(linear_);
}

}  // namespace strata
