// One-chart atlas: the surface cut open into a disk along a short cut
// graph and mapped onto the whole square (Gu, Gortler and Hoppe 2002,
// "Geometry images"), its interior placed by a stretch-minimising
// barycentric embedding (Yoshizawa, Belyaev and Seidel 2004).
#include "strata/baker/atlas.h"

#include "distortion.h"

#include <Eigen/Sparse>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <string>
#include <unordered_map>
#include <vector>

namespace strata {
namespace baker {
namespace {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
// Reweighting passes of the stretch-minimising embedding (it stops early
// once a pass no longer lowers the stretch).
constexpr int kStretchPasses = 12;
// Corner sets tried, best first: the first one that embeds.
constexpr size_t kCornerTries = 4;
// Weight of a corner's bend (its surface angle against a right angle, over
// pi, squared) against its sides' imbalance (a side's share of the
// border less a quarter, squared) when corners are chosen.
constexpr double kCornerBend = 0.01;
// The most cut augmentations (each one parameterisation).
constexpr int kMaxCuts = 64;
// Vertices a round tries to cut from, worst-stretched first.
constexpr size_t kAugmentTries = 8;
// The most vertices solved for (over every embedding) before the cut stops
// growing: five times what the penguin's 201-vertex cage takes (0.2M, 0.8
// s), so that a large cage costs seconds, not minutes.
constexpr size_t kMaxWork = 1000000;

// Half-edge connectivity of a triangle mesh: half-edge 3f + k runs from
// corner k of face f to corner k + 1.
struct Topology {
    size_t nv = 0, nf = 0;
    std::vector<uint32_t> twin;   // per half-edge, or kNone on a border
    std::vector<uint32_t> edge;   // per half-edge, its undirected edge
    std::vector<std::array<uint32_t, 2>> ends;  // per edge
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> around;  // per vertex: (neighbour, edge)
    std::vector<double> length;   // per edge
    std::vector<double> area;     // per face, on the surface
};

struct UnionFind {
    std::vector<uint32_t> parent;
    explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
    uint32_t find(uint32_t x)
    {
        while (parent[x] != x)
            x = parent[x] = parent[parent[x]];
        return x;
    }
    void unite(uint32_t a, uint32_t b) { parent[find(a)] = find(b); }
};

// The angle at corner c (3f + k) of the mesh's triangles, and the lengths
// of its two edges (to corners k + 1 and k + 2); -1 where one is empty.
double cornerAngle(const ControlMesh& mesh, size_t c, double* la = nullptr, double* lb = nullptr)
{
    const size_t f = c / 3, k = c % 3;
    const glm::dvec3 x(mesh.positions[mesh.triangles[c]]);
    const glm::dvec3 a = glm::dvec3(mesh.positions[mesh.triangles[3 * f + (k + 1) % 3]]) - x;
    const glm::dvec3 b = glm::dvec3(mesh.positions[mesh.triangles[3 * f + (k + 2) % 3]]) - x;
    const double lengthA = glm::length(a), lengthB = glm::length(b);
    if (la)
        *la = lengthA;
    if (lb)
        *lb = lengthB;
    if (!(lengthA > 0.0) || !(lengthB > 0.0))
        return -1.0;
    return std::acos(std::clamp(glm::dot(a, b) / (lengthA * lengthB), -1.0, 1.0));
}

// Fails on anything but one connected, consistently oriented, manifold
// surface of genus 0 (a sphere or a disk with holes).
Status buildTopology(const ControlMesh& mesh, Topology* t, size_t* borderLoops)
{
    const uint32_t* tri = mesh.triangles.data();
    t->nv = mesh.positions.size();
    t->nf = mesh.faceCount();
    const size_t nh = 3 * t->nf;
    std::unordered_map<uint64_t, uint32_t> directed;
    directed.reserve(nh);
    auto key = [](uint32_t a, uint32_t b) { return (uint64_t(a) << 32) | b; };
    for (uint32_t h = 0; h < nh; ++h) {
        const uint32_t a = tri[h], b = tri[h - h % 3 + (h % 3 + 1) % 3];
        if (!directed.emplace(key(a, b), h).second)
            return Status(StatusCode::InvalidArgument, "an edge is shared by more than two faces or the faces' orientations disagree");
    }
    t->area.resize(t->nf);
    for (size_t f = 0; f < t->nf; ++f) {
        const glm::dvec3 q0(mesh.positions[tri[3 * f]]), q1(mesh.positions[tri[3 * f + 1]]),
            q2(mesh.positions[tri[3 * f + 2]]);
        t->area[f] = 0.5 * glm::length(glm::cross(q1 - q0, q2 - q0));
    }
    t->twin.assign(nh, kNone);
    t->edge.assign(nh, kNone);
    t->around.assign(t->nv, {});
    for (uint32_t h = 0; h < nh; ++h) {
        if (t->edge[h] != kNone)
            continue;
        const uint32_t a = tri[h], b = tri[h - h % 3 + (h % 3 + 1) % 3];
        const auto it = directed.find(key(b, a));
        const uint32_t e = uint32_t(t->ends.size());
        t->ends.push_back({a, b});
        t->length.push_back(glm::length(glm::dvec3(mesh.positions[a]) - glm::dvec3(mesh.positions[b])));
        t->around[a].push_back({b, e});
        t->around[b].push_back({a, e});
        t->edge[h] = e;
        if (it != directed.end()) {
            t->twin[h] = it->second;
            t->twin[it->second] = h;
            t->edge[it->second] = e;
        }
    }
    // One fan per vertex (corners joined across their shared edges) and
    // one component.
    UnionFind corners(nh), faces(t->nf);
    for (uint32_t h = 0; h < nh; ++h)
        if (t->twin[h] != kNone) {
            const uint32_t o = t->twin[h];
            // Corner h (at the edge's start) meets the twin's corner at its end.
            corners.unite(h, o - o % 3 + (o % 3 + 1) % 3);
            faces.unite(h / 3, o / 3);
        }
    std::vector<uint32_t> fan(t->nv, kNone);
    size_t used = 0;
    for (uint32_t h = 0; h < nh; ++h) {
        const uint32_t v = tri[h], root = corners.find(h);
        if (fan[v] == kNone) {
            fan[v] = root;
            ++used;
        } else if (fan[v] != root) {
            return Status(StatusCode::InvalidArgument, "vertex " + std::to_string(v) + " joins separate fans");
        }
    }
    for (uint32_t f = 1; f < t->nf; ++f)
        if (faces.find(f) != faces.find(0))
            return Status(StatusCode::InvalidArgument, "the mesh has more than one connected part");
    // Border loops: each border vertex starts exactly one border half-edge.
    std::vector<uint32_t> next(t->nv, kNone);
    size_t borderEdges = 0;
    for (uint32_t h = 0; h < nh; ++h)
        if (t->twin[h] == kNone) {
            next[tri[h]] = tri[h - h % 3 + (h % 3 + 1) % 3];
            ++borderEdges;
        }
    std::vector<char> seen(t->nv, 0);
    size_t loops = 0;
    for (uint32_t v = 0; v < t->nv; ++v)
        if (next[v] != kNone && !seen[v]) {
            ++loops;
            for (uint32_t w = v; !seen[w]; w = next[w])
                seen[w] = 1;
        }
    const long chi = long(used) - long(t->ends.size()) + long(t->nf);
    if (2 - long(loops) - chi != 0)
        return Status(StatusCode::InvalidArgument, "the surface has handles (genus " +
                                                       std::to_string((2 - long(loops) - chi) / 2) + ")");
    *borderLoops = loops;
    return Status::ok();
}

// The surface cut along `cut` (and its border): one vertex per wedge of
// corners between cut edges, the border loop of the resulting disk.
struct Disk {
    std::vector<uint32_t> corner;   // per corner: its disk vertex
    std::vector<uint32_t> source;   // per disk vertex: its mesh vertex
    std::vector<uint32_t> border;   // the border loop, in order (counter-clockwise)
    std::vector<int> borderAt;      // per disk vertex: its place in border, or -1
};

bool cutOpen(const ControlMesh& mesh, const Topology& t, const std::vector<char>& cut, Disk* d)
{
    const size_t nh = 3 * t.nf;
    UnionFind corners(nh);
    for (uint32_t h = 0; h < nh; ++h)
        if (t.twin[h] != kNone && !cut[t.edge[h]]) {
            const uint32_t o = t.twin[h];
            corners.unite(h, o - o % 3 + (o % 3 + 1) % 3);
        }
    std::vector<uint32_t> id(nh, kNone);
    d->corner.assign(nh, kNone);
    d->source.clear();
    for (uint32_t h = 0; h < nh; ++h) {
        const uint32_t r = corners.find(h);
        if (id[r] == kNone) {
            id[r] = uint32_t(d->source.size());
            d->source.push_back(mesh.triangles[h]);
        }
        d->corner[h] = id[r];
    }
    // The disk's border half-edges: each border vertex starts one.
    std::vector<uint32_t> next(d->source.size(), kNone);
    size_t count = 0;
    for (uint32_t h = 0; h < nh; ++h)
        if (t.twin[h] == kNone || cut[t.edge[h]]) {
            const uint32_t a = d->corner[h], b = d->corner[h - h % 3 + (h % 3 + 1) % 3];
            if (next[a] != kNone)
                return false;  // a vertex the cut pinches: not a disk
            next[a] = b;
            ++count;
        }
    if (count < 3)
        return false;
    d->border.clear();
    d->borderAt.assign(d->source.size(), -1);
    uint32_t start = 0;
    while (next[start] == kNone)
        ++start;
    for (uint32_t v = start; d->borderAt[v] < 0; v = next[v]) {
        d->borderAt[v] = int(d->border.size());
        d->border.push_back(v);
    }
    // One loop, and a disk's Euler characteristic (V - E + F = 1).
    const long edges = (long(nh) + long(count)) / 2;
    return d->border.size() == count && long(d->source.size()) - edges + long(t.nf) == 1;
}

// L2 stretch (Sander et al. 2001) of the map from the square to the
// surface, per face, and the surface's total over its area (1 at best,
// the map's area scaled to the surface's).
struct Stretch {
    std::vector<double> face;  // squared, unnormalised
    double total = 0.0;
    bool valid = false;
};

Stretch measureStretch(const ControlMesh& mesh, const Topology& t, const Disk& d, const std::vector<glm::dvec2>& uv)
{
    Stretch s;
    s.face.assign(mesh.faceCount(), 0.0);
    double area2 = 0.0, area3 = 0.0, sum = 0.0;
    for (size_t f = 0; f < mesh.faceCount(); ++f) {
        const glm::dvec2 p0 = uv[d.corner[3 * f]], p1 = uv[d.corner[3 * f + 1]], p2 = uv[d.corner[3 * f + 2]];
        const glm::dvec3 q0(mesh.positions[mesh.triangles[3 * f]]), q1(mesh.positions[mesh.triangles[3 * f + 1]]),
            q2(mesh.positions[mesh.triangles[3 * f + 2]]);
        const double a = 0.5 * ((p1.x - p0.x) * (p2.y - p0.y) - (p2.x - p0.x) * (p1.y - p0.y));
        if (!(a > 0.0))
            return s;
        const glm::dvec3 ss = (q0 * (p1.y - p2.y) + q1 * (p2.y - p0.y) + q2 * (p0.y - p1.y)) / (2.0 * a);
        const glm::dvec3 st = (q0 * (p2.x - p1.x) + q1 * (p0.x - p2.x) + q2 * (p1.x - p0.x)) / (2.0 * a);
        s.face[f] = 0.5 * (glm::dot(ss, ss) + glm::dot(st, st));
        sum += t.area[f] * s.face[f];
        area2 += a;
        area3 += t.area[f];
    }
    if (!(area3 > 0.0))
        return s;
    s.total = std::sqrt(sum / area3 * area2 / area3);
    s.valid = std::isfinite(s.total);
    return s;
}

// Per vertex (numbered as `corner` numbers the faces' corners: a disk's
// vertices or the mesh's), the squared stretch of its faces over their
// area on the surface; -1 for a vertex without area.
std::vector<double> vertexStretch(const Topology& t, const std::vector<uint32_t>& corner, size_t count,
                                  const Stretch& s)
{
    std::vector<double> sum(count, 0.0), area(count, 0.0);
    for (size_t c = 0; c < 3 * t.nf; ++c) {
        sum[corner[c]] += t.area[c / 3] * s.face[c / 3];
        area[corner[c]] += t.area[c / 3];
    }
    for (size_t v = 0; v < count; ++v)
        sum[v] = area[v] > 0.0 ? sum[v] / area[v] : -1.0;
    return sum;
}

// Corners for the disk's border on the unit square.  An inner edge whose
// two ends lie on the border (a chord) must not lie along one side: each
// of the two border arcs it cuts off holds a corner strictly inside.  Of
// the corner sets that keep every chord off the sides, the ones whose
// sides are closest to a quarter of the border's length each, best first
// (at most `count`, from different first corners).
std::vector<std::array<size_t, 4>> chooseCorners(const ControlMesh& mesh, const Topology& t, const Disk& d,
                                                 size_t count)
{
    const size_t n = d.border.size();
    std::vector<std::array<size_t, 4>> found;
    if (n < 4)
        return found;
    std::vector<double> at(n + 1, 0.0);  // arc length along the border from its first vertex
    for (size_t i = 0; i < n; ++i)
        at[i + 1] = at[i] + glm::length(glm::dvec3(mesh.positions[d.source[d.border[i]]]) -
                                        glm::dvec3(mesh.positions[d.source[d.border[(i + 1) % n]]]));
    const double total = at[n];
    if (!(total > 0.0))
        return found;
    // Open arcs (first position, positions inside) that need a corner.
    std::vector<std::pair<size_t, size_t>> arcs;
    for (uint32_t h = 0; h < 3 * t.nf; ++h) {
        const uint32_t u = d.corner[h], v = d.corner[h - h % 3 + (h % 3 + 1) % 3];
        if (d.borderAt[u] < 0 || d.borderAt[v] < 0 || u > v)
            continue;
        const size_t pu = size_t(d.borderAt[u]), pv = size_t(d.borderAt[v]);
        if ((pu + 1) % n == pv || (pv + 1) % n == pu)
            continue;  // a border edge (or a chord beside one: caught as flat by the embedding)
        arcs.push_back({(pu + 1) % n, (pv + n - pu - 1) % n});
        arcs.push_back({(pv + 1) % n, (pu + n - pv - 1) % n});
    }
    auto inside = [&](size_t c, const std::pair<size_t, size_t>& arc) { return (c + n - arc.first) % n < arc.second; };
    auto length = [&](size_t from, size_t to) {  // along the border, from position `from` forwards to `to`
        return to >= from ? at[to] - at[from] : total - at[from] + at[to];
    };
    struct Scored {
        double score;
        std::array<size_t, 4> corners;
    };
    std::vector<Scored> all;
    // The surface's angle at each border vertex (a right angle maps onto
    // a corner without distortion, a straight border onto a side).
    std::vector<double> angle(d.source.size(), 0.0);
    for (size_t h = 0; h < 3 * t.nf; ++h)
        angle[d.corner[h]] += std::max(0.0, cornerAngle(mesh, h));
    // First corners: evenly spaced along the border, and its sharpest vertices.
    std::vector<size_t> firsts;
    const size_t spaced = std::min<size_t>(n, 48);
    for (size_t k = 0; k < spaced; ++k)
        firsts.push_back(k * n / spaced);
    std::vector<size_t> sharp(n);
    std::iota(sharp.begin(), sharp.end(), size_t(0));
    const size_t sharpest = std::min<size_t>(n, 8);
    std::partial_sort(sharp.begin(), sharp.begin() + long(sharpest), sharp.end(),
                      [&](size_t x, size_t y) { return angle[d.border[x]] < angle[d.border[y]]; });
    firsts.insert(firsts.end(), sharp.begin(), sharp.begin() + long(sharpest));
    for (const size_t c0 : firsts) {
        // Arcs without c0, as intervals [lo, hi] of offsets from c0.
        std::vector<std::pair<size_t, size_t>> open;
        bool impossible = false;
        for (const auto& arc : arcs) {
            if (arc.second == 0)
                impossible = true;
            if (!inside(c0, arc))
                open.push_back({(arc.first + n - c0) % n, (arc.first + n - c0) % n + arc.second - 1});
        }
        if (impossible)
            break;
        // Fewest corners that stab the intervals beyond offset `from`.
        auto needed = [&](size_t from) {
            std::vector<std::pair<size_t, size_t>> rest;
            for (const auto& iv : open)
                if (iv.first > from)
                    rest.push_back(iv);
            std::sort(rest.begin(), rest.end(), [](const auto& x, const auto& y) { return x.second < y.second; });
            size_t stabs = 0, last = 0;
            bool any = false;
            for (const auto& iv : rest)
                if (!any || iv.first > last) {
                    last = iv.second;
                    any = true;
                    ++stabs;
                }
            return stabs;
        };
        std::array<size_t, 4> c{c0, 0, 0, 0};
        size_t prev = 0;  // offset of the last corner
        bool ok = true;
        for (size_t j = 1; j < 4 && ok; ++j) {
            const double target = double(j) * 0.25 * total;
            // Offsets by their distance from the target, the nearest that
            // leaves no interval behind it unstabbed and the rest stabbable.
            std::vector<size_t> offsets;
            for (size_t o = prev + 1; o + (4 - j) <= n; ++o)
                offsets.push_back(o);
            std::sort(offsets.begin(), offsets.end(), [&](size_t x, size_t y) {
                return std::fabs(length(c0, (c0 + x) % n) - target) < std::fabs(length(c0, (c0 + y) % n) - target);
            });
            ok = false;
            for (size_t o : offsets) {
                bool skipped = false;
                for (const auto& iv : open)
                    if (iv.first > prev && iv.second < o)
                        skipped = true;
                if (skipped || needed(o) > 3 - j)
                    continue;
                c[j] = (c0 + o) % n;
                prev = o;
                ok = true;
                break;
            }
        }
        if (!ok || needed(prev) > 0)
            continue;
        double score = 0.0;
        for (size_t j = 0; j < 4; ++j) {
            const double side = length(c[j], c[(j + 1) % 4]) / total - 0.25;
            const double bend = (angle[d.border[c[j]]] - 0.5 * M_PI) / M_PI;
            score += side * side + kCornerBend * bend * bend;
        }
        all.push_back({score, c});
    }
    std::sort(all.begin(), all.end(), [](const Scored& x, const Scored& y) { return x.score < y.score; });
    for (size_t i = 0; i < all.size() && found.size() < count; ++i)
        found.push_back(all[i].corners);
    return found;
}

// Border placement on the unit square: the four corners' vertices on its
// corners, the rest spaced by length between them.
void placeBorder(const ControlMesh& mesh, const Disk& d, const std::array<size_t, 4>& corners,
                 std::vector<glm::dvec2>* uv)
{
    const size_t n = d.border.size();
    const glm::dvec2 square[5] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}};
    for (size_t c = 0; c < 4; ++c) {
        const size_t from = corners[c], count = (corners[(c + 1) % 4] + n - from) % n;
        std::vector<double> at(count + 1, 0.0);
        for (size_t i = 0; i < count; ++i)
            at[i + 1] = at[i] + glm::length(glm::dvec3(mesh.positions[d.source[d.border[(from + i) % n]]]) -
                                            glm::dvec3(mesh.positions[d.source[d.border[(from + i + 1) % n]]]));
        for (size_t i = 0; i < count; ++i) {
            const double s = at[count] > 0.0 ? at[i] / at[count] : double(i) / double(count);
            (*uv)[d.border[(from + i) % n]] = square[c] + s * (square[c + 1] - square[c]);
        }
    }
}

// The disk embedded in the unit square: border on the square's sides,
// inner vertices by a barycentric (Tutte) embedding with mean value
// weights (Floater 2003), then reweighted against stretch.  Fills uv
// (per disk vertex) and returns its stretch; invalid where no corner
// placement embeds.
Stretch embed(const ControlMesh& mesh, const Topology& t, const Disk& d, const std::array<size_t, 4>& corners,
              std::vector<glm::dvec2>* uvOut, size_t* work)
{
    const size_t n = d.source.size();
    std::vector<glm::dvec2> uv(n, glm::dvec2(0.0));
    placeBorder(mesh, d, corners, &uv);
    std::vector<int> column(n, -1);
    int inner = 0;
    for (size_t v = 0; v < n; ++v)
        if (d.borderAt[v] < 0)
            column[v] = inner++;
    // Mean value weights, per directed inner edge (i, j): from the corner
    // at i of each face on the edge.
    struct Weight {
        uint32_t i, j;
        double w;
    };
    std::vector<Weight> weights;
    weights.reserve(6 * t.nf);
    for (size_t f = 0; f < t.nf; ++f)
        for (int k = 0; k < 3; ++k) {
            const uint32_t i = d.corner[3 * f + size_t(k)];
            if (column[i] < 0)
                continue;
            double la = 0.0, lb = 0.0;
            const double angle = cornerAngle(mesh, 3 * f + size_t(k), &la, &lb);
            if (angle < 0.0)
                return Stretch();
            const double tanHalf = std::tan(0.5 * angle);
            if (!std::isfinite(tanHalf))
                return Stretch();  // a face flat as a line
            weights.push_back({i, d.corner[3 * f + size_t((k + 1) % 3)], tanHalf / la});
            weights.push_back({i, d.corner[3 * f + size_t((k + 2) % 3)], tanHalf / lb});
        }
    std::vector<double> scale(n, 1.0);  // per vertex j: its weights' divisor (its stretch)
    Stretch best;
    std::vector<glm::dvec2> bestUV;
    for (int pass = 0; pass <= kStretchPasses; ++pass) {
        if (inner > 0) {
            std::vector<Eigen::Triplet<double>> entries;
            entries.reserve(2 * weights.size());
            Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(inner, 2);
            for (const Weight& w : weights) {
                const double x = w.w / scale[w.j];
                entries.emplace_back(column[w.i], column[w.i], x);
                if (column[w.j] >= 0) {
                    entries.emplace_back(column[w.i], column[w.j], -x);
                } else {
                    rhs(column[w.i], 0) += x * uv[w.j].x;
                    rhs(column[w.i], 1) += x * uv[w.j].y;
                }
            }
            Eigen::SparseMatrix<double> a(inner, inner);
            a.setFromTriplets(entries.begin(), entries.end());
            Eigen::SparseLU<Eigen::SparseMatrix<double>> solver;
            solver.compute(a);
            *work += size_t(inner);
            if (solver.info() != Eigen::Success)
                break;
            const Eigen::MatrixXd x = solver.solve(rhs);
            if (solver.info() != Eigen::Success)
                break;
            for (size_t v = 0; v < n; ++v)
                if (column[v] >= 0)
                    uv[v] = glm::dvec2(x(column[v], 0), x(column[v], 1));
        }
        Stretch s = measureStretch(mesh, t, d, uv);
        if (!s.valid)
            break;
        if (best.valid && s.total >= best.total * 0.999) {
            if (s.total < best.total) {
                best = std::move(s);
                bestUV = uv;
            }
            break;
        }
        best = std::move(s);
        bestUV = uv;
        // Each vertex's stretch (over the area of its faces) divides the
        // weights towards it: stretched regions get more of the square.
        const std::vector<double> stretch = vertexStretch(t, d.corner, n, best);
        for (size_t v = 0; v < n; ++v)
            if (stretch[v] >= 0.0)
                scale[v] *= std::sqrt(std::sqrt(stretch[v]));
    }
    if (best.valid)
        *uvOut = std::move(bestUV);
    return best;
}

Stretch parameterize(const ControlMesh& mesh, const Topology& t, const Disk& d, std::vector<glm::dvec2>* uv,
                     size_t* work)
{
    for (const std::array<size_t, 4>& corners : chooseCorners(mesh, t, d, kCornerTries)) {
        Stretch s = embed(mesh, t, d, corners, uv, work);
        if (s.valid)
            return s;
    }
    return Stretch();
}

// Shortest path (by edge length) from v to the nearest vertex in `on`;
// marks its edges in cut.  False when none is reachable.
bool cutTowards(const Topology& t, uint32_t v, const std::vector<char>& on, std::vector<char>* cut)
{
    std::vector<double> dist(t.nv, std::numeric_limits<double>::infinity());
    std::vector<uint32_t> via(t.nv, kNone);  // the edge a vertex was reached by
    using Item = std::pair<double, uint32_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
    dist[v] = 0.0;
    queue.push({0.0, v});
    while (!queue.empty()) {
        const auto [dv, x] = queue.top();
        queue.pop();
        if (dv > dist[x])
            continue;
        if (on[x] && x != v) {
            for (uint32_t y = x; y != v;) {
                const uint32_t e = via[y];
                (*cut)[e] = 1;
                y = t.ends[e][0] == y ? t.ends[e][1] : t.ends[e][0];
            }
            return true;
        }
        for (const auto& [y, e] : t.around[x])
            if (dv + t.length[e] < dist[y]) {
                dist[y] = dv + t.length[e];
                via[y] = e;
                queue.push({dist[y], y});
            }
    }
    return false;
}

// Angle deficit per vertex (2 pi less its corners' angles): large at a
// surface's tips, where a cut opens it with the least stretch.
std::vector<double> angleDeficit(const ControlMesh& mesh)
{
    std::vector<double> deficit(mesh.positions.size(), 2.0 * M_PI);
    for (size_t c = 0; c < mesh.triangles.size(); ++c)
        deficit[mesh.triangles[c]] -= std::max(0.0, cornerAngle(mesh, c));
    return deficit;
}

// The largest sampling distortion over the faces, as chart atlases
// measure it; 0 where no face counts.
double worstDistortion(const ControlMesh& mesh, const Disk& d, const std::vector<glm::dvec2>& uv)
{
    SamplingDistortion distortion;
    bool any = false;
    for (size_t f = 0; f < mesh.faceCount(); ++f) {
        glm::dvec2 q[3];
        if (!isometric(mesh, uint32_t(f), q))
            continue;
        const glm::dvec2 w[3] = {uv[d.corner[3 * f]], uv[d.corner[3 * f + 1]], uv[d.corner[3 * f + 2]]};
        any = distortion.add(q, w) || any;
    }
    return any ? distortion.worst() : 0.0;
}

}  // namespace

Status buildSquareAtlas(ControlMesh* mesh, const SquareAtlasOptions& options, ChartAtlasStats* stats)
{
    const size_t nf = mesh->faceCount();
    if (nf == 0)
        return Status(StatusCode::InvalidArgument, "cannot build an atlas for a mesh without faces");
    if (options.mapSize != 0 && options.mapSize < 8)
        return Status(StatusCode::InvalidArgument, "atlas map size must be 0 (the unit square) or at least 8");
    Topology t;
    size_t loops = 0;
    if (Status s = buildTopology(*mesh, &t, &loops); !s)
        return s;
    const size_t used = [&] {
        std::vector<char> u(t.nv, 0);
        for (uint32_t v : mesh->triangles)
            u[v] = 1;
        return size_t(std::count(u.begin(), u.end(), 1));
    }();
    const size_t budget = size_t(std::floor(options.maxVertexRatio * double(used)));
    // The first cut: the border loops joined up, or on a closed surface
    // the shortest path between its two sharpest tips.
    std::vector<char> cut(t.ends.size(), 0), on(t.nv, 0);
    auto mark = [&] {
        std::fill(on.begin(), on.end(), 0);
        for (size_t e = 0; e < t.ends.size(); ++e)
            if (cut[e])
                on[t.ends[e][0]] = on[t.ends[e][1]] = 1;
    };
    for (uint32_t h = 0; h < 3 * nf; ++h)
        if (t.twin[h] == kNone)
            cut[t.edge[h]] = 1;
    const std::vector<double> deficit = angleDeficit(*mesh);
    if (loops == 0) {
        std::vector<uint32_t> order(t.nv);
        std::iota(order.begin(), order.end(), 0u);
        std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return deficit[a] > deficit[b]; });
        std::fill(on.begin(), on.end(), 0);
        on[order[0]] = 1;
        if (!cutTowards(t, order[1], on, &cut))
            return Status(StatusCode::InvalidArgument, "the mesh is too small to cut open");
    } else {
        // Every other border loop joined to the first's tree.
        for (;;) {
            mark();
            UnionFind parts(t.nv);
            for (size_t e = 0; e < t.ends.size(); ++e)
                if (cut[e])
                    parts.unite(t.ends[e][0], t.ends[e][1]);
            uint32_t first = kNone, other = kNone;
            for (uint32_t v = 0; v < t.nv && other == kNone; ++v)
                if (on[v]) {
                    if (first == kNone)
                        first = v;
                    else if (parts.find(v) != parts.find(first))
                        other = v;
                }
            if (other == kNone)
                break;
            std::vector<char> target(t.nv, 0);
            for (uint32_t v = 0; v < t.nv; ++v)
                target[v] = on[v] && parts.find(v) == parts.find(first);
            if (!cutTowards(t, other, target, &cut))
                return Status(StatusCode::InvalidArgument, "the border loops are not connected");
        }
    }
    // Augmented from the worst-stretched vertex off it (or, where that cut
    // does not embed or passes the vertex budget, the next worst, up to
    // kAugmentTries) while the budget allows; the cut that stretches least
    // is kept.
    Disk disk, bestDisk;
    std::vector<glm::dvec2> uv, bestUV;
    Stretch best, current;
    size_t work = 0;  // vertices solved for
    if (cutOpen(*mesh, t, cut, &disk) && disk.source.size() <= budget)
        current = parameterize(*mesh, t, disk, &uv, &work);
    if (current.valid) {
        best = current;
        bestDisk = disk;
        bestUV = uv;
    }
    for (int round = 0; round < kMaxCuts && current.valid && work < kMaxWork; ++round) {
        mark();
        const std::vector<double> stretch = vertexStretch(t, mesh->triangles, t.nv, current);
        std::vector<std::pair<double, uint32_t>> worst;
        for (uint32_t v = 0; v < t.nv; ++v)
            if (!on[v] && stretch[v] >= 0.0)
                worst.push_back({stretch[v], v});
        const size_t tries = std::min(worst.size(), kAugmentTries);
        std::partial_sort(worst.begin(), worst.begin() + long(tries), worst.end(), std::greater<>());
        bool grown = false;
        std::vector<char> chosenCut;
        Stretch chosen;
        Disk chosenDisk;
        std::vector<glm::dvec2> chosenUV;
        for (size_t i = 0; i < tries; ++i) {
            std::vector<char> trial = cut;
            if (!cutTowards(t, worst[i].second, on, &trial) || !cutOpen(*mesh, t, trial, &disk) ||
                disk.source.size() > budget)
                continue;
            Stretch s = parameterize(*mesh, t, disk, &uv, &work);
            if (!s.valid || (grown && s.total >= chosen.total))
                continue;
            chosenCut.swap(trial);
            chosen = std::move(s);
            chosenDisk = disk;
            chosenUV = uv;
            grown = true;
        }
        if (!grown)
            break;
        cut.swap(chosenCut);
        current = std::move(chosen);
        if (current.total < best.total) {
            best = current;
            bestDisk = std::move(chosenDisk);
            bestUV = std::move(chosenUV);
        }
    }
    if (!best.valid)
        return Status(StatusCode::InvalidArgument, "no cut within " + std::to_string(options.maxVertexRatio) +
                                                       "x the vertices opens the mesh into a square");
    mesh->uvs.resize(bestDisk.source.size());
    for (size_t v = 0; v < bestDisk.source.size(); ++v)
        mesh->uvs[v] = glm::vec2(bestUV[v]);
    mesh->uvIndices = bestDisk.corner;
    const double fill = options.mapSize > 0 ? fitSquareAtlas(&mesh->uvs, options.mapSize) : 1.0;
    if (stats) {
        *stats = ChartAtlasStats();
        stats->charts = 1;
        stats->texelFill = fill;
        stats->maxDistortion = worstDistortion(*mesh, bestDisk, bestUV);
        stats->wholeMap = true;
        stats->stretch = best.total;
    }
    return Status::ok();
}

double fitSquareAtlas(std::vector<glm::vec2>* uvs, int mapSize)
{
    // The border texels' centres hold the chart's border: a bilinear sample
    // inside it reads no texel past the map (nor clamps).
    const double size = double(std::max(mapSize, 2));
    for (glm::vec2& uv : *uvs)
        uv = glm::vec2(float((0.5 + double(uv.x) * (size - 1.0)) / size),
                       float((0.5 + double(uv.y) * (size - 1.0)) / size));
    return (size - 1.0) * (size - 1.0) / (size * size);
}

}  // namespace baker
}  // namespace strata
