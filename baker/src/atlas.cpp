// Per-triangle UV atlas, paired into square cells.
#include "strata/baker/atlas.h"

#include "strata/normals.h"

#include "distortion.h"
#include "cancel.h"
#include "parallel.h"
#include "strata/plane.h"

#include <Eigen/Sparse>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <tuple>
#include <vector>
#include <string>

namespace strata {
namespace baker {

Status buildTriangleAtlas(ControlMesh* mesh, const AtlasOptions& options)
{
    const size_t nf = mesh->faceCount();
    if (nf == 0)
        return Status(StatusCode::InvalidArgument, "cannot build an atlas for a mesh without faces");
    if (options.mapSize < 8 || options.gutter < 1)
        return Status(StatusCode::InvalidArgument, "atlas map size must be at least 8 and the gutter at least 1");
    const size_t cells = (nf + 1) / 2;
    const int grid = int(std::ceil(std::sqrt(double(cells))));
    const int cell = options.mapSize / grid;  // texels per cell side, integral so corners sit on texel edges
    const int g = options.gutter;
    // Each triangle needs room for gutters on all sides plus a usable interior.
    if (cell < 4 * g + 6)
        return Status(StatusCode::InvalidArgument,
                      "a " + std::to_string(options.mapSize) + " map is too small for " + std::to_string(nf) +
                          " per-triangle charts (" + std::to_string(cell) + " texels per cell); use a larger map");
    const float inv = 1.0f / float(options.mapSize);
    mesh->uvs.clear();
    mesh->uvIndices.resize(nf * 3);
    for (size_t f = 0; f < nf; ++f) {
        const int c = int(f / 2);
        const float x0 = float((c % grid) * cell), y0 = float((c / grid) * cell);
        const float lo = float(g), hi = float(cell - g);
        // Two right triangles per cell; the diagonal gap is 2g texels wide
        // along the axes, so each side keeps a full gutter.
        glm::vec2 corners[3];
        if (f % 2 == 0) {
            corners[0] = {lo, lo};
            corners[1] = {hi - 2.0f * float(g), lo};
            corners[2] = {lo, hi - 2.0f * float(g)};
        } else {
            corners[0] = {hi, hi};
            corners[1] = {lo + 2.0f * float(g), hi};
            corners[2] = {hi, lo + 2.0f * float(g)};
        }
        for (int k = 0; k < 3; ++k) {
            mesh->uvIndices[3 * f + size_t(k)] = uint32_t(mesh->uvs.size());
            mesh->uvs.emplace_back((x0 + corners[k].x) * inv, (y0 + corners[k].y) * inv);
        }
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata

// ---- Chart atlas ----

namespace strata {
namespace baker {
namespace {

// Charts flatten within kChartMaxDistortion (chartDistortion measures it).
// At 2 the real cages' charts stopped a few faces short of what packs well:
// 2.5 fills 70-72% of spot's, the penguin's and the hand's maps where 2 (and
// 2.25) filled 69.4-70.9%; spot's and the penguin's seams lose 6 and 13
// vertices (the hand's gain 18, 1.27 -> 1.30x), and their maps' closed loops
// stay within 5% (spot's 0.0325 -> 0.0311%).

// Local/global iterations of the as-rigid-as-possible refinement.
constexpr int kRigidIterations = 8;
// The largest share of the surface's area a chart may grow to (border
// teeth may then add a face or two).  The distortion bound alone makes a
// sphere two large charts, which fill 52% of a square map (two discs fill at
// most 54%); grown to quarters it is seven, which fill 73%.  A cage that
// large charts cover well may pack best that way, so where the share binds
// the atlas is laid out both ways and the one with more texels inside
// charts is kept.
constexpr double kMaxChartShare = 0.25;
// The most faces one chart may have, which bounds a try's sparse
// factorisations: a dense cage's flat regions are cut into charts this
// large.
constexpr size_t kMaxChartFaces = 65536;
// The largest charts a border face's move between them is retried alone
// for (after its batch failed to flatten).
constexpr size_t kMaxRetryFaces = 1024;

struct Chart {
    std::vector<uint32_t> faces;
    glm::dvec3 normal{0.0};          // area-weighted unit normal: the plane its flattening starts from
    std::vector<uint32_t> vertices;  // topological vertices, in first-use order
    std::vector<glm::dvec2> points;  // flattened, per entry of vertices
    glm::dvec2 lo{0.0}, hi{0.0};
    double scaleX = 0.0;      // texels per model unit, set by the packer (where it goes: its Placement)
    double stretchY = 1.0;    // and the factor on y (the short side), set with it
    double distortion = 1.0;  // chartDistortion of points
};

// Projects onto the plane orthogonal to n, in an orthonormal frame.
void frame(const glm::dvec3& n, glm::dvec3* u, glm::dvec3* v)
{
    const glm::dvec3 a = std::fabs(n.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    *u = glm::normalize(glm::cross(n, a));
    *v = glm::cross(n, *u);
}

// Least-squares conformal map (Levy et al. 2002) of one disk-shaped chart:
// the two vertices farthest apart in its projection `points` stay where
// the projection put them, the rest solve the normal equations (a sparse
// Cholesky factorisation).  Overwrites points; false when the map folds (a
// face turned clockwise) or cannot be solved.
bool flattenConformal(const Chart& c, const ControlMesh& mesh, const std::vector<int32_t>& local,
                      std::vector<glm::dvec2>* points)
{
    const size_t n = c.vertices.size();
    if (n < 3)
        return false;
    // Pins: the two vertices farthest apart in the projection.
    size_t p0 = 0, p1 = 0;
    {
        double best = -1.0;
        for (size_t i = 0; i < n; ++i)
            if (glm::length((*points)[i] - (*points)[0]) > best) {
                best = glm::length((*points)[i] - (*points)[0]);
                p0 = i;
            }
        best = -1.0;
        for (size_t i = 0; i < n; ++i)
            if (glm::length((*points)[i] - (*points)[p0]) > best) {
                best = glm::length((*points)[i] - (*points)[p0]);
                p1 = i;
            }
    }
    if (p0 == p1)
        return false;
    // Unknowns: u then v of every free vertex.
    std::vector<int> column(n, -1);
    int free = 0;
    for (size_t i = 0; i < n; ++i)
        if (i != p0 && i != p1)
            column[i] = free++;
    // Per face, the complex weights W_k = a_k + i b_k of its conformality
    // residual sum_k W_k (u_k + i v_k), over sqrt(twice its area): two
    // real rows of A.
    std::vector<Eigen::Triplet<double>> entries;
    std::vector<double> rhs;
    entries.reserve(12 * c.faces.size());
    int row = 0;
    for (uint32_t f : c.faces) {
        glm::dvec2 q[3];
        if (!isometric(mesh, f, q))
            continue;
        const double w = 1.0 / std::sqrt(q[1].x * q[2].y);
        double fixedRe = 0.0, fixedIm = 0.0;
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 d = (q[(k + 2) % 3] - q[(k + 1) % 3]) * w;
            const size_t v = size_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]]);
            if (column[v] < 0) {
                const glm::dvec2 x = (*points)[v];
                fixedRe += d.x * x.x - d.y * x.y;
                fixedIm += d.y * x.x + d.x * x.y;
                continue;
            }
            entries.emplace_back(row, column[v], d.x);
            entries.emplace_back(row, free + column[v], -d.y);
            entries.emplace_back(row + 1, column[v], d.y);
            entries.emplace_back(row + 1, free + column[v], d.x);
        }
        rhs.push_back(-fixedRe);
        rhs.push_back(-fixedIm);
        row += 2;
    }
    Eigen::SparseMatrix<double> a(row, 2 * free);
    a.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SparseMatrix<double> normal = Eigen::SparseMatrix<double>(a.transpose()) * a;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
    if (solver.info() != Eigen::Success)
        return false;
    const Eigen::VectorXd x = solver.solve(a.transpose() * Eigen::Map<const Eigen::VectorXd>(rhs.data(), row));
    if (solver.info() != Eigen::Success)
        return false;
    for (size_t i = 0; i < n; ++i)
        if (column[i] >= 0)
            (*points)[i] = glm::dvec2(x[column[i]], x[free + column[i]]);
    // A fold: a face turned clockwise.
    for (uint32_t f : c.faces) {
        glm::dvec2 u[3];
        for (int k = 0; k < 3; ++k)
            u[k] = (*points)[size_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]])];
        const double area = (u[1].x - u[0].x) * (u[2].y - u[0].y) - (u[1].y - u[0].y) * (u[2].x - u[0].x);
        if (!(area > 0.0) || !std::isfinite(area))
            return false;
    }
    return true;
}

// As-rigid-as-possible flattening (Liu et al. 2008) of a disk chart, from
// its conformal map: alternately the rotation closest to each face's
// Jacobian, and the cotangent-weighted least-squares positions given those
// rotations (one vertex pinned; the Laplacian factorised once).  A conformal
// map of a wide curved chart shrinks its rim; this one trades a little angle
// for area, so a chart can cover far more of the surface at the same
// sampling.  Returns false (points untouched) when the result folds.
bool flattenRigid(const Chart& c, const ControlMesh& mesh, const std::vector<int32_t>& local,
                  std::vector<glm::dvec2>* points, int iterations)
{
    const size_t n = c.vertices.size();
    struct Face {
        uint32_t v[3];
        glm::dvec2 q[3];
        double w[3];  // half the cotangent of the angle at corner k: the weight of the opposite edge
    };
    std::vector<Face> faces;
    faces.reserve(c.faces.size());
    for (uint32_t f : c.faces) {
        Face t;
        if (!isometric(mesh, f, t.q))
            continue;
        for (int k = 0; k < 3; ++k) {
            t.v[k] = uint32_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]]);
            const glm::dvec2 a = t.q[(k + 1) % 3] - t.q[k], b = t.q[(k + 2) % 3] - t.q[k];
            t.w[k] = 0.5 * glm::dot(a, b) / cross2(a, b);
        }
        faces.push_back(t);
    }
    if (n < 3 || faces.empty())
        return false;
    // The Laplacian over every vertex but the pinned one (vertex 0).
    const uint32_t pin = 0;
    auto column = [&](uint32_t v) { return int(v) - 1; };
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(12 * faces.size());
    for (const Face& t : faces)
        for (int k = 0; k < 3; ++k) {
            const uint32_t i = t.v[(k + 1) % 3], j = t.v[(k + 2) % 3];
            for (uint32_t x : {i, j})
                if (x != pin)
                    entries.emplace_back(column(x), column(x), t.w[k]);
            if (i != pin && j != pin) {
                entries.emplace_back(column(i), column(j), -t.w[k]);
                entries.emplace_back(column(j), column(i), -t.w[k]);
            }
        }
    Eigen::SparseMatrix<double> laplacian(int(n) - 1, int(n) - 1);
    laplacian.setFromTriplets(entries.begin(), entries.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(laplacian);
    if (solver.info() != Eigen::Success)
        return false;
    std::vector<glm::dvec2> u(*points);
    Eigen::MatrixXd b(int(n) - 1, 2);
    for (int it = 0; it < iterations; ++it) {
        b.setZero();
        for (const Face& t : faces) {
            // Local step: the rotation closest to the face's Jacobian, from
            // S = sum w (u_i - u_j)(q_i - q_j)^T.
            double s00 = 0.0, s01 = 0.0, s10 = 0.0, s11 = 0.0;
            for (int k = 0; k < 3; ++k) {
                const int i = (k + 1) % 3, j = (k + 2) % 3;
                const glm::dvec2 du = u[t.v[i]] - u[t.v[j]], dq = t.q[i] - t.q[j];
                s00 += t.w[k] * du.x * dq.x;
                s01 += t.w[k] * du.x * dq.y;
                s10 += t.w[k] * du.y * dq.x;
                s11 += t.w[k] * du.y * dq.y;
            }
            const double angle = std::atan2(s10 - s01, s00 + s11), cs = std::cos(angle), sn = std::sin(angle);
            // Global step's right-hand side: each edge's rotated rest vector.
            for (int k = 0; k < 3; ++k) {
                const uint32_t i = t.v[(k + 1) % 3], j = t.v[(k + 2) % 3];
                const glm::dvec2 dq = t.q[(k + 1) % 3] - t.q[(k + 2) % 3];
                const glm::dvec2 e = t.w[k] * glm::dvec2(cs * dq.x - sn * dq.y, sn * dq.x + cs * dq.y);
                for (const auto& [x, y, sign] : {std::make_tuple(i, j, 1.0), std::make_tuple(j, i, -1.0)}) {
                    if (x == pin)
                        continue;
                    b(column(x), 0) += sign * e.x;
                    b(column(x), 1) += sign * e.y;
                    if (y == pin) {  // the pinned neighbour's known position
                        b(column(x), 0) += t.w[k] * u[pin].x;
                        b(column(x), 1) += t.w[k] * u[pin].y;
                    }
                }
            }
        }
        const Eigen::MatrixXd x = solver.solve(b);
        if (solver.info() != Eigen::Success)
            return false;
        for (uint32_t v = 1; v < n; ++v)
            u[v] = glm::dvec2(x(column(v), 0), x(column(v), 1));
    }
    for (const Face& t : faces) {
        const glm::dvec2 a = u[t.v[1]] - u[t.v[0]], bb = u[t.v[2]] - u[t.v[0]];
        const double area = cross2(a, bb);
        if (!(area > 0.0) || !std::isfinite(area))
            return false;
    }
    *points = std::move(u);
    return true;
}

// Sampling distortion of a flattened chart (SamplingDistortion over its
// faces); 1e300 where a face folds.
double chartDistortion(const Chart& c, const ControlMesh& mesh, const std::vector<int32_t>& local)
{
    SamplingDistortion distortion;
    for (uint32_t f : c.faces) {
        glm::dvec2 q[3];
        if (!isometric(mesh, f, q))
            continue;
        glm::dvec2 w[3];
        for (int k = 0; k < 3; ++k)
            w[k] = c.points[size_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]])];
        if (!distortion.add(q, w))
            return 1e300;
    }
    return distortion.worst();
}

// Projects a chart's vertices onto the plane orthogonal to n (where its
// conformal map starts): fills c->vertices and c->points in first-use
// order, and each vertex's entry in local.
void projectChart(Chart* c, const ControlMesh& mesh, const glm::dvec3& n, std::vector<int32_t>* local)
{
    glm::dvec3 u, v;
    frame(n, &u, &v);
    for (uint32_t f : c->faces)
        for (int k = 0; k < 3; ++k) {
            const uint32_t p = mesh.triangles[3 * size_t(f) + size_t(k)];
            if ((*local)[p] < 0) {
                (*local)[p] = int32_t(c->vertices.size());
                c->vertices.push_back(p);
                const glm::dvec3 x(mesh.positions[p]);
                c->points.emplace_back(glm::dot(x, u), glm::dot(x, v));
            }
        }
}

// True when two border edges of a flattened chart that share no vertex
// meet: a conformal map can be fold-free and still lap over itself.
bool selfOverlaps(const Chart& c, const ControlMesh& mesh, const std::vector<int32_t>& local)
{
    std::vector<uint32_t> triangles;  // the chart's faces in its local vertex numbers
    triangles.reserve(3 * c.faces.size());
    for (uint32_t f : c.faces)
        for (int k = 0; k < 3; ++k)
            triangles.push_back(uint32_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]]));
    const EdgeGroups edges = groupEdges(triangles.data(), c.faces.size());
    std::vector<std::array<uint32_t, 2>> border;  // the edges of one face only
    for (size_t e = 0; e < edges.edgeCount(); ++e)
        if (edges.faceCountOf(e) == 1) {
            const uint32_t corner = edges.cornersOf(e)[0];
            border.push_back({triangles[corner], triangles[corner / 3 * 3 + (corner % 3 + 1) % 3]});
        }
    auto orient = [](const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& p) {
        const double d = orient2(a, b, p);
        return d > 0.0 ? 1 : d < 0.0 ? -1 : 0;
    };
    for (size_t i = 0; i < border.size(); ++i) {
        const glm::dvec2 a = c.points[border[i][0]], b = c.points[border[i][1]];
        const glm::dvec2 lo = glm::min(a, b), hi = glm::max(a, b);
        for (size_t j = i + 1; j < border.size(); ++j) {
            if (border[j][0] == border[i][0] || border[j][0] == border[i][1] || border[j][1] == border[i][0] ||
                border[j][1] == border[i][1])
                continue;
            const glm::dvec2 p = c.points[border[j][0]], q = c.points[border[j][1]];
            if (std::max(p.x, q.x) < lo.x || std::min(p.x, q.x) > hi.x || std::max(p.y, q.y) < lo.y ||
                std::min(p.y, q.y) > hi.y)
                continue;
            if (orient(a, b, p) * orient(a, b, q) <= 0 && orient(p, q, a) * orient(p, q, b) <= 0)
                return true;
        }
    }
    return false;
}

// A chart's own scale: the common one, raised so that the chart spans at
// least kMinChartTexels along its length (a chart of a texel or two would
// be sampled from its gutter); and the stretch of its short side (charts
// lie with their long side along x) that brings that side to
// kMinChartTexels too.  Stretching only the short side keeps a sliver
// short: raising the whole scale made one sliver face of spot's cage a
// chart as long as a 128 map.
constexpr double kMinChartTexels = 6.0;
constexpr double kMaxStretch = 16.0;

void setChartScale(Chart* c, double scale)
{
    const double w = c->hi.x - c->lo.x, h = c->hi.y - c->lo.y;
    double s = scale;
    if (w > 0.0)
        s = std::min(std::max(s, kMinChartTexels / w), 64.0 * scale);
    c->scaleX = s;
    c->stretchY = h > 0.0 ? std::min(std::max(kMinChartTexels / (h * s), 1.0), kMaxStretch) : 1.0;
}

// Chart point in texels inside its footprint, in one of eight orientations:
// bit 2 mirrors it (a scalar map has no handedness), bits 0-1 turn it by
// quarters.
glm::dvec2 placed(const Chart& c, const glm::dvec2& p, double scale, int rotation, int gutter)
{
    glm::dvec2 q = (p - c.lo) * glm::dvec2(scale, scale * c.stretchY);
    const double w = (c.hi.x - c.lo.x) * scale, h = (c.hi.y - c.lo.y) * scale * c.stretchY;
    if (rotation & 4)
        q.x = w - q.x;
    const int turn = rotation & 3;
    const glm::dvec2 r = turn == 1 ? glm::dvec2(h - q.y, q.x)
                         : turn == 2 ? glm::dvec2(w - q.x, h - q.y)
                         : turn == 3 ? glm::dvec2(q.y, w - q.x)
                                     : q;
    return r + glm::dvec2(double(gutter) + 0.5);
}

// The chart's footprint at a scale and orientation: the texels a bilinear
// sample inside it can read, plus gutter - 1 rings (those whose closed
// square of half-side `gutter` about the centre meets one of its
// triangles), as runs of rows per column (the gaps between a hand's fingers
// stay free for other charts).  Footprints never overlap, so no texel a
// chart reads is another chart's.
struct Footprint {
    int width = 0, height = 0;
    std::vector<uint32_t> first;  // width + 1: each column's runs in [first[x], first[x + 1])
    std::vector<int> lo, hi;      // per run: lowest and highest row
};

// The rows y of the column of texel centres x = cx whose closed square of
// half-side r meets triangle t: the square meets it exactly when its centre's
// y lies within r of the triangle's y extent inside the vertical slab
// |x - cx| <= r, and that extent is reached at a corner inside the slab or
// where an edge crosses one of the slab's sides.  False when the slab misses
// the triangle.
bool slabRows(double cx, double r, const glm::dvec2 t[3], int* lo, int* hi)
{
    const double left = cx - r, right = cx + r;
    double a = 1e300, b = -1e300;
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 p = t[k], q = t[(k + 1) % 3];
        if (p.x >= left && p.x <= right) {
            a = std::min(a, p.y);
            b = std::max(b, p.y);
        }
        for (double side : {left, right})
            if ((p.x - side) * (q.x - side) < 0.0) {
                const double y = p.y + (q.y - p.y) * ((side - p.x) / (q.x - p.x));
                a = std::min(a, y);
                b = std::max(b, y);
            }
    }
    if (!(a <= b))
        return false;
    *lo = int(std::ceil(a - r - 0.5));
    *hi = int(std::floor(b + r - 0.5));
    return *lo <= *hi;
}

Footprint footprint(const Chart& c, const ControlMesh& mesh, const std::vector<int32_t>& local, double scale,
                    int rotation, int gutter, int size)
{
    const double w = (c.hi.x - c.lo.x) * scale, h = (c.hi.y - c.lo.y) * scale * c.stretchY;
    Footprint fp;
    // A chart wider or taller than the atlas fits nowhere: its size alone
    // says so, before a mask as large as the chart (a cage with one vertex
    // two billion units out makes a chart of billions of texels).
    const double fw = std::ceil(rotation & 1 ? h : w) + 2.0 * gutter + 1.0;
    const double fh = std::ceil(rotation & 1 ? w : h) + 2.0 * gutter + 1.0;
    if (!(fw <= double(size)) || !(fh <= double(size))) {
        fp.width = fp.height = size + 1;
        return fp;
    }
    fp.width = int(fw);
    fp.height = int(fh);
    std::vector<uint8_t> mask(size_t(fp.width) * size_t(fp.height), 0);  // column-major
    const double reach = double(gutter) + 0.5;
    for (uint32_t f : c.faces) {
        glm::dvec2 t[3];
        for (int k = 0; k < 3; ++k)
            t[k] = placed(c, c.points[size_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]])], scale, rotation, gutter);
        const double minX = std::min({t[0].x, t[1].x, t[2].x}), maxX = std::max({t[0].x, t[1].x, t[2].x});
        const int x0 = std::max(0, int(std::floor(minX - reach)));
        const int x1 = std::min(fp.width - 1, int(std::ceil(maxX + reach)));
        const int y0 = std::max(0, int(std::floor(std::min({t[0].y, t[1].y, t[2].y}) - reach)));
        const int y1 = std::min(fp.height - 1, int(std::ceil(std::max({t[0].y, t[1].y, t[2].y}) + reach)));
        const double r = double(gutter);
        for (int x = x0; x <= x1; ++x) {
            int lo = 0, hi = -1;
            if (!slabRows(x + 0.5, r, t, &lo, &hi))
                continue;
            lo = std::max(lo, y0);
            hi = std::min(hi, y1);
            if (lo <= hi)
                std::memset(&mask[size_t(x) * size_t(fp.height) + size_t(lo)], 1, size_t(hi - lo + 1));
        }
    }
    fp.first.assign(size_t(fp.width) + 1, 0);
    for (int x = 0; x < fp.width; ++x) {
        fp.first[size_t(x)] = uint32_t(fp.lo.size());
        const uint8_t* col = &mask[size_t(x) * size_t(fp.height)];
        for (int y = 0; y < fp.height; ++y)
            if (col[y] && (y == 0 || !col[y - 1])) {
                int end = y;
                while (end + 1 < fp.height && col[end + 1])
                    ++end;
                fp.lo.push_back(y);
                fp.hi.push_back(end);
            }
    }
    fp.first[size_t(fp.width)] = uint32_t(fp.lo.size());
    return fp;
}

// Texel occupancy of the map, a bitset per column (bit y of column x: texel
// (x, y) is taken), so a chart can drop into a hole under an overhang that a
// skyline would have closed off.
class Occupancy {
public:
    explicit Occupancy(int size)
        : size_(size), words_(size_t(size + 63) / 64), bits_(size_t(size) * words_, 0),
          taken_(size_t(size) * size_t(size + 1), 0)
    {
    }

    // True when rows [from, from + length) of column x are all free: one
    // difference of the column's running count of taken rows.
    bool free(int x, int from, int length) const
    {
        const uint16_t* count = &taken_[size_t(x) * size_t(size_ + 1)];
        return count[from + length] == count[from];
    }

    // The lowest y >= from with rows [y, y + length) of column x all free, or
    // size when there is none.
    int firstFree(int x, int from, int length) const
    {
        const uint64_t* col = &bits_[size_t(x) * words_];
        int y = from;
        while (y + length <= size_) {
            const int blocker = firstTaken(col, y, y + length);
            if (blocker < 0)
                return y;
            y = firstClear(col, blocker);  // past the whole taken run
        }
        return size_;
    }

    void take(int x, int y0, int y1) { mark(x, y0, y1, true); }      // rows [y0, y1] of column x
    void release(int x, int y0, int y1) { mark(x, y0, y1, false); }  // the same rows, free again

private:
    void mark(int x, int y0, int y1, bool taken)
    {
        uint64_t* col = &bits_[size_t(x) * words_];
        for (int y = y0; y <= y1; ++y) {
            const uint64_t bit = uint64_t(1) << (y & 63);
            col[size_t(y) >> 6] = taken ? col[size_t(y) >> 6] | bit : col[size_t(y) >> 6] & ~bit;
        }
        uint16_t* count = &taken_[size_t(x) * size_t(size_ + 1)];
        for (int y = y0 + 1; y <= size_; ++y)
            count[y] = uint16_t(count[y - 1] + ((col[size_t(y - 1) >> 6] >> ((y - 1) & 63)) & 1));
    }

    // The first free row at or after y (size when none).
    int firstClear(const uint64_t* col, int y) const
    {
        while (y < size_) {
            const uint64_t free = ~col[size_t(y) >> 6] >> (y & 63);
            if (free)
                return std::min(size_, y + __builtin_ctzll(free));
            y = (y | 63) + 1;
        }
        return size_;
    }

    // The first taken row in [y0, y1), or -1.
    int firstTaken(const uint64_t* col, int y0, int y1) const
    {
        for (int y = y0; y < y1;) {
            const size_t w = size_t(y) >> 6;
            uint64_t bits = col[w] >> (y & 63);
            const int span = std::min(64 - (y & 63), y1 - y);
            if (span < 64)
                bits &= (uint64_t(1) << span) - 1;
            if (bits)
                return y + __builtin_ctzll(bits);
            y += span;
        }
        return -1;
    }

    int size_;
    size_t words_;
    std::vector<uint64_t> bits_;
    std::vector<uint16_t> taken_;  // per column, size + 1 running counts: rows [0, y) taken
};

// A chart's placement: its footprint, where it goes, and the row its top
// reaches (INT32_MAX when it fits nowhere).
struct Placement {
    int top = INT32_MAX, x = 0, y = 0, rotation = 0;
    Footprint fp;
};

// Finds where chart c (at its scaleX) goes into `occupied`, in whichever of
// its eight orientations its top ends lowest, at the lowest row every one
// of its columns is free (holes under earlier charts included); ties go to
// the lower orientation, then the lower column.  The orientations are tried
// on `threads` threads from a size of 256 up, each pruning against the best
// top any has found (ties allowed, so the lower orientation still wins
// them): the same placement for any thread count.  `local` must map the
// chart's vertices to their entries.
Placement place(const Chart& c, const Occupancy& occupied, const ControlMesh& mesh, const std::vector<int32_t>& local,
                int gutter, int size, int threads)
{
    Placement found[8];
    std::atomic<int> anyTop{INT32_MAX};
    auto tryOrientation = [&](int rotation) {
        Placement& own = found[rotation];
        own.rotation = rotation;
        own.fp = footprint(c, mesh, local, c.scaleX, rotation, gutter, size);
        const Footprint& fp = own.fp;
        if (fp.width > size || fp.height > size)
            return;
        for (int x = 0; x + fp.width <= size; ++x) {
            // Raise y until every column's span is free at once, giving
            // up once the top cannot beat the best placement so far.
            const int limit = std::min({size, own.top - 1, anyTop.load(std::memory_order_relaxed)});
            int y = 0;
            for (bool moved = true; moved && y + fp.height <= limit;) {
                moved = false;
                for (int col = 0; col < fp.width && y + fp.height <= limit; ++col)
                    for (uint32_t r = fp.first[size_t(col)]; r < fp.first[size_t(col) + 1]; ++r) {
                        const int lo = fp.lo[r];
                        if (occupied.free(x + col, y + lo, fp.hi[r] - lo + 1))
                            continue;
                        const int at = occupied.firstFree(x + col, y + lo, fp.hi[r] - lo + 1) - lo;
                        if (at > y) {
                            y = at;
                            moved = true;
                        }
                    }
            }
            const int top = y + fp.height;
            if (top <= limit) {  // limit < own.top: a strict improvement
                own.top = top;
                own.x = x;
                own.y = y;
                for (int seen = anyTop.load(); top < seen && !anyTop.compare_exchange_weak(seen, top);) {
                }
            }
        }
    };
    parallelChunks(8, size >= 256 ? threads : 1, [&](int, size_t begin, size_t end) {
        for (size_t rotation = begin; rotation < end; ++rotation)
            tryOrientation(int(rotation));
    });
    int best = 0;
    for (int rotation = 1; rotation < 8; ++rotation)
        if (found[rotation].top < found[best].top)
            best = rotation;
    return std::move(found[best]);
}

void take(Occupancy* occupied, const Placement& p, bool taken = true)
{
    for (int col = 0; col < p.fp.width; ++col)
        for (uint32_t r = p.fp.first[size_t(col)]; r < p.fp.first[size_t(col) + 1]; ++r)
            if (taken)
                occupied->take(p.x + col, p.y + p.fp.lo[r], p.y + p.fp.hi[r]);
            else
                occupied->release(p.x + col, p.y + p.fp.lo[r], p.y + p.fp.hi[r]);
}

void setLocal(const Chart& c, std::vector<int32_t>* local, bool on)
{
    for (size_t k = 0; k < c.vertices.size(); ++k)
        (*local)[c.vertices[k]] = on ? int32_t(k) : -1;
}

// Packs the charts' footprints into a texel occupancy map, largest first,
// each where place() puts it: sets each chart's scaleX and its entry of
// `placements`; false if they do not fit.
bool pack(std::vector<Chart>& charts, const std::vector<size_t>& order, const ControlMesh& mesh,
          std::vector<int32_t>& local, double scale, int gutter, int size, int threads,
          std::vector<Placement>* placements)
{
    Occupancy occupied(size);
    placements->assign(charts.size(), Placement());
    for (size_t i : order) {
        Chart& c = charts[i];
        setChartScale(&c, scale);
        setLocal(c, &local, true);
        Placement p = place(c, occupied, mesh, local, gutter, size, threads);
        setLocal(c, &local, false);
        if (p.top == INT32_MAX)
            return false;
        take(&occupied, p);
        (*placements)[i] = std::move(p);
    }
    return true;
}

// Packed at a common scale, charts leave gaps that none of them fits at
// that scale.  Each chart in turn, smallest first, is lifted out and put
// back, wherever place() finds room among the others, at the largest scale
// up to kMaxGrowth times its own that fits (tried whole, then bisected):
// the map's free texels become finer sampling of the charts that can use
// them.  A chart never shrinks (its old place is always there), so no part
// of the surface is sampled more coarsely than the common scale.  With
// --exr, two passes take the real pairs' fill from 50-67% to 60-70%; the
// hand, whose hand-shaped charts leave the space between the fingers to
// small ones, gains most (56 -> 66%).
constexpr double kMaxGrowth = 2.0;
constexpr int kGrowthPasses = 2;
constexpr int kGrowthSteps = 4;  // twice the scale, then three halvings of the interval

void growIntoGaps(std::vector<Chart>& charts, const std::vector<size_t>& order, std::vector<Placement>& placements,
                  const ControlMesh& mesh, std::vector<int32_t>& local, int gutter, int size, int threads)
{
    Occupancy occupied(size);
    for (const Placement& p : placements)
        take(&occupied, p);
    for (size_t n = order.size(); n-- > 0;) {
        const size_t i = order[n];
        Chart& c = charts[i];
        take(&occupied, placements[i], false);
        const double base = c.scaleX;
        setLocal(c, &local, true);
        double lo = 1.0, hi = kMaxGrowth;
        Placement best;
        for (int step = 0; step < kGrowthSteps; ++step) {
            const double mid = step == 0 ? hi : 0.5 * (lo + hi);
            c.scaleX = base * mid;
            Placement p = place(c, occupied, mesh, local, gutter, size, threads);
            if (p.top != INT32_MAX) {
                lo = mid;
                best = std::move(p);
                if (step == 0)
                    break;
            } else {
                hi = mid;
            }
        }
        setLocal(c, &local, false);
        if (best.top == INT32_MAX) {
            c.scaleX = base;  // stays where it was
        } else {
            c.scaleX = base * lo;
            placements[i] = std::move(best);
        }
        take(&occupied, placements[i]);
    }
}

// Flattens a chart whose faces are set: projected on its normal's plane,
// then conformal, then as rigid as possible.  True, with points and
// distortion set, when the result is fold-free, does not lap over itself
// and stays within kChartMaxDistortion.  `local` must be all -1 and is left so.
bool flattenChart(Chart* c, const ControlMesh& mesh, std::vector<int32_t>* local)
{
    c->vertices.clear();
    c->points.clear();
    projectChart(c, mesh, c->normal, local);
    bool ok = true;
    if (c->faces.size() == 1) {
        glm::dvec2 q[3];
        if (isometric(mesh, c->faces[0], q))  // a degenerate face keeps its projection
            c->points.assign(q, q + 3);
        c->distortion = 1.0;
    } else {
        const bool conformal = flattenConformal(*c, mesh, *local, &c->points);
        ok = flattenRigid(*c, mesh, *local, &c->points, kRigidIterations) || conformal;
        ok = ok && !selfOverlaps(*c, mesh, *local);
        c->distortion = ok ? chartDistortion(*c, mesh, *local) : 1e300;
        ok = ok && c->distortion <= kChartMaxDistortion;
    }
    for (uint32_t v : c->vertices)
        (*local)[v] = -1;
    return ok;
}

// What chart growth needs of a mesh, whichever share bounds it: per face
// its unit normal, area and neighbours (across manifold, consistently
// oriented edges only), and each vertex's faces.
struct ChartMesh {
    std::vector<glm::dvec3> faceNormal;
    std::vector<double> faceArea;
    double totalArea = 0.0;
    std::vector<std::array<uint32_t, 3>> neighbour;
    std::vector<uint32_t> vertexFaceOffsets, vertexFaces;

    explicit ChartMesh(const ControlMesh& mesh)
    {
        const size_t nf = mesh.faceCount();
        faceNormal.resize(nf);
        faceArea.resize(nf);
        for (size_t f = 0; f < nf; ++f) {
            const glm::dvec3 a(mesh.positions[mesh.triangles[3 * f]]), b(mesh.positions[mesh.triangles[3 * f + 1]]),
                c(mesh.positions[mesh.triangles[3 * f + 2]]);
            const glm::dvec3 n = glm::cross(b - a, c - a);
            faceArea[f] = 0.5 * glm::length(n);
            faceNormal[f] = faceArea[f] > 0.0 ? n / (2.0 * faceArea[f]) : glm::dvec3(0.0, 0.0, 1.0);
        }
        for (double a : faceArea)
            totalArea += a;
        neighbour.assign(nf, {UINT32_MAX, UINT32_MAX, UINT32_MAX});
        const EdgeGroups edges = groupEdges(mesh.triangles.data(), nf);
        for (size_t e = 0; e < edges.edgeCount(); ++e)
            if (edges.faceCountOf(e) == 2) {
                const uint32_t e0 = edges.cornersOf(e)[0], e1 = edges.cornersOf(e)[1];
                const uint32_t f0 = e0 / 3, f1 = e1 / 3;
                const bool opposite = mesh.triangles[e0] != mesh.triangles[e1];  // start vertices differ
                if (f0 != f1 && opposite) {
                    neighbour[f0][e0 % 3] = f1;
                    neighbour[f1][e1 % 3] = f0;
                }
            }
        buildVertexFaces(&vertexFaceOffsets, &vertexFaces, mesh.triangles.data(), nf, mesh.positions.size());
    }
};

// Grows, flattens, straightens and turns the charts of a mesh: everything
// of the atlas that does not depend on the map size (nor on `threads`).
void makeCharts(const ControlMesh& mesh, const ChartMesh& geometry, int threads, double maxShare,
                std::vector<Chart>* chartsOut, double* maxDistortionOut, bool* shareBoundOut)
{
    const size_t nf = mesh.faceCount(), nv = mesh.positions.size();
    std::vector<Chart>& charts = *chartsOut;
    *shareBoundOut = false;
    const std::vector<glm::dvec3>& faceNormal = geometry.faceNormal;
    const std::vector<double>& faceArea = geometry.faceArea;
    const double totalArea = geometry.totalArea;
    const std::vector<std::array<uint32_t, 3>>& neighbour = geometry.neighbour;
    const std::vector<uint32_t>& vertexFaceOffsets = geometry.vertexFaceOffsets;
    const std::vector<uint32_t>& vertexFaces = geometry.vertexFaces;
    std::vector<uint32_t> chartOf(nf, UINT32_MAX);
    std::vector<uint32_t> vertexChart(nv, UINT32_MAX);  // the chart a vertex was last added to
    // Chart `id` grown breadth first from `seed` over unassigned faces, up
    // to `limit` faces, while it stays a disk (Euler characteristic 1): a
    // face joins only if it adds as many vertices as edges less one, so it
    // neither pinches the border at a vertex nor closes a loop.  Every
    // prefix of its faces is a disk too.
    auto grow = [&](uint32_t seed, uint32_t id, size_t limit) {
        Chart c;
        std::vector<uint32_t>& queue = c.faces;
        queue.push_back(seed);
        chartOf[seed] = id;
        for (int k = 0; k < 3; ++k)
            vertexChart[mesh.triangles[3 * size_t(seed) + size_t(k)]] = id;
        for (size_t q = 0; q < queue.size() && queue.size() < limit; ++q) {
            const uint32_t f = queue[q];
            for (uint32_t g : neighbour[f]) {
                if (g == UINT32_MAX || chartOf[g] != UINT32_MAX || faceArea[g] <= 0.0 || queue.size() >= limit)
                    continue;
                int newVertices = 0, newEdges = 0;
                for (int k = 0; k < 3; ++k) {
                    newVertices += vertexChart[mesh.triangles[3 * size_t(g) + size_t(k)]] != id;
                    const uint32_t across = neighbour[g][size_t(k)];
                    newEdges += across == UINT32_MAX || chartOf[across] != id;
                }
                if (newVertices - newEdges + 1 != 0)
                    continue;
                chartOf[g] = id;
                for (int k = 0; k < 3; ++k)
                    vertexChart[mesh.triangles[3 * size_t(g) + size_t(k)]] = id;
                queue.push_back(g);
            }
        }
        return c;
    };
    auto release = [&](const Chart& c, size_t from) {
        for (size_t i = from; i < c.faces.size(); ++i)
            chartOf[c.faces[i]] = UINT32_MAX;
        if (from == 0)
            for (uint32_t f : c.faces)
                for (int k = 0; k < 3; ++k)
                    vertexChart[mesh.triangles[3 * size_t(f) + size_t(k)]] = UINT32_MAX;
    };
    std::vector<int32_t> local(nv, -1);
    auto normalOf = [&](const std::vector<uint32_t>& faces) {
        glm::dvec3 sum(0.0);
        for (uint32_t f : faces)
            sum += faceArea[f] * faceNormal[f];
        return glm::length(sum) > 0.0 ? glm::normalize(sum) : faceNormal[faces[0]];
    };
    // The first k faces of `grown` as a chart, if they flatten.
    auto prefix = [&](const Chart& grown, size_t k, Chart* out) {
        Chart c;
        c.faces.assign(grown.faces.begin(), grown.faces.begin() + std::ptrdiff_t(k));
        double area = 0.0;
        for (uint32_t f : c.faces)
            area += faceArea[f];
        if (k > 1 && maxShare < 1.0 && area > maxShare * totalArea) {
            *shareBoundOut = true;
            return false;
        }
        c.normal = normalOf(c.faces);
        if (!flattenChart(&c, mesh, &local))
            return false;
        *out = std::move(c);
        return true;
    };
    // Each chart, from the largest unassigned face, is the longest prefix of
    // its breadth-first growth that flattens within kChartMaxDistortion (and
    // kMaxChartShare): found by growing twice as large while it flattens (a
    // flat region becomes one chart without every face being tried), then
    // bisecting to within a sixteenth.  A single face always flattens.
    std::vector<uint32_t> seeds(nf);
    for (uint32_t f = 0; f < nf; ++f)
        seeds[f] = f;
    std::stable_sort(seeds.begin(), seeds.end(), [&](uint32_t a, uint32_t b) { return faceArea[a] > faceArea[b]; });
    for (uint32_t seed : seeds) {
        if (cancelRequested())  // a cancelled bake: the caller discards the charts
            return;
        if (chartOf[seed] != UINT32_MAX)
            continue;
        const uint32_t id = uint32_t(charts.size());
        Chart best, grown;
        size_t good = 0;  // the longest prefix known to flatten
        for (size_t limit = 16;; limit = std::min(2 * limit, kMaxChartFaces)) {
            grown = grow(seed, id, limit);
            if (prefix(grown, grown.faces.size(), &best)) {
                good = grown.faces.size();
                if (good < limit || limit == kMaxChartFaces)
                    break;  // nothing left to grow into, or as large as a chart may be
                release(grown, 0);
                continue;
            }
            size_t bad = grown.faces.size();
            while (bad - good > std::max<size_t>(1, good / 16)) {
                const size_t mid = good + (bad - good) / 2;
                (prefix(grown, mid, &best) ? good : bad) = mid;
            }
            if (good == 0) {
                good = 1;
                prefix(grown, 1, &best);
            } else if (best.faces.size() != good) {
                prefix(grown, good, &best);
            }
            break;
        }
        release(grown, good);
        charts.push_back(std::move(best));
    }
    // Breadth-first borders are saw-toothed, and every vertex on a border
    // is split once per chart around it.  A border face moves to a
    // neighbouring chart where that takes vertices off the seams: where it
    // is its own chart's only face at more of its corners than the other
    // chart is missing from (a tooth, touching its own chart along one edge
    // and the other along two, is the commonest).  Both charts must stay
    // disks: the face leaves its own as a growth step could have added it,
    // and joins the other as one would.  A few passes; the charts a pass
    // changed are flattened again, and the moves into or out of one that
    // no longer flattens are undone (and not tried again), until those
    // left all flatten.
    for (size_t i = 0; i < charts.size(); ++i)
        for (uint32_t f : charts[i].faces)
            chartOf[f] = uint32_t(i);
    auto touches = [&](uint32_t v, uint32_t chart, uint32_t except) {
        for (uint32_t e = vertexFaceOffsets[v]; e < vertexFaceOffsets[v + 1]; ++e)
            if (vertexFaces[e] != except && chartOf[vertexFaces[e]] == chart)
                return true;
        return false;
    };
    std::vector<uint8_t> refused(nf, 0);
    // The chart face f would move to, or UINT32_MAX.
    auto moveTarget = [&](uint32_t f) {
        const uint32_t a = chartOf[f];
        uint32_t other[3];
        int own = 0;
        for (int k = 0; k < 3; ++k) {
            const uint32_t g = neighbour[f][size_t(k)];
            other[k] = g == UINT32_MAX ? UINT32_MAX : chartOf[g];
            own += other[k] == a;
        }
        if (own == 0 || refused[f])
            return UINT32_MAX;
        int leaves = 0;  // corners where f is its chart's only face
        for (int k = 0; k < 3; ++k)
            leaves += !touches(mesh.triangles[3 * size_t(f) + size_t(k)], a, f);
        if (leaves - (3 - own) + 1 != 0)
            return UINT32_MAX;
        uint32_t best = UINT32_MAX;
        int bestGain = 0;
        for (int k = 0; k < 3; ++k) {
            const uint32_t b = other[k];
            if (b == UINT32_MAX || b == a || (k > 0 && b == other[0]) || (k > 1 && b == other[1]))
                continue;
            int arrives = 0, edges = 0;  // corners and edges f brings to b
            for (int l = 0; l < 3; ++l) {
                arrives += !touches(mesh.triangles[3 * size_t(f) + size_t(l)], b, UINT32_MAX);
                edges += other[l] != b;
            }
            if (arrives - edges + 1 == 0 && leaves - arrives > bestGain) {
                bestGain = leaves - arrives;
                best = b;
            }
        }
        return best;
    };
    // A chart (its faces those chartOf gives `id`) is still a disk: one
    // piece across its edges, with Euler characteristic 1.  Batched moves
    // that were each valid may not be together once some are undone.
    auto isDisk = [&](const Chart& c, uint32_t id, std::vector<int32_t>* mark) {
        long vertices = 0, twiceEdges = 0;
        for (uint32_t f : c.faces)
            for (int k = 0; k < 3; ++k) {
                int32_t& m = (*mark)[mesh.triangles[3 * size_t(f) + size_t(k)]];
                vertices += m == -1;
                m = 0;
                const uint32_t g = neighbour[f][size_t(k)];
                twiceEdges += g != UINT32_MAX && chartOf[g] == id ? 1 : 2;
            }
        for (uint32_t f : c.faces)
            for (int k = 0; k < 3; ++k)
                (*mark)[mesh.triangles[3 * size_t(f) + size_t(k)]] = -1;
        if (2 * (vertices + long(c.faces.size())) - twiceEdges != 2)
            return false;
        // One piece: a walk across its edges from its first face reaches
        // them all.
        std::vector<uint32_t> stack{c.faces[0]};
        std::vector<uint32_t> faces = c.faces;
        std::sort(faces.begin(), faces.end());
        std::vector<uint8_t> seen(faces.size(), 0);
        auto slot = [&](uint32_t f) { return size_t(std::lower_bound(faces.begin(), faces.end(), f) - faces.begin()); };
        seen[slot(c.faces[0])] = 1;
        size_t count = 1;
        while (!stack.empty()) {
            const uint32_t f = stack.back();
            stack.pop_back();
            for (uint32_t g : neighbour[f])
                if (g != UINT32_MAX && chartOf[g] == id && !seen[slot(g)]) {
                    seen[slot(g)] = 1;
                    ++count;
                    stack.push_back(g);
                }
        }
        return count == c.faces.size();
    };
    auto reflatten = [&](Chart* c, uint32_t id, std::vector<int32_t>* scratch) {
        c->normal = normalOf(c->faces);
        return isDisk(*c, id, scratch) && flattenChart(c, mesh, scratch);
    };
    struct Move {
        uint32_t face, from, to;
    };
    for (int pass = 0; pass < 8; ++pass) {
        if (cancelRequested())
            return;
        std::vector<Move> moves, undone;
        for (uint32_t f = 0; f < nf; ++f) {
            const uint32_t a = chartOf[f], b = moveTarget(f);
            if (b != UINT32_MAX) {
                chartOf[f] = b;
                moves.push_back({f, a, b});
            }
        }
        if (moves.empty())
            break;
        const std::vector<Chart> before = charts;
        std::vector<uint8_t> bad(charts.size(), 0);
        for (;;) {
            std::vector<uint8_t> changed(charts.size(), 0);
            for (const Move& m : moves)
                changed[m.from] = changed[m.to] = 1;
            for (size_t c = 0; c < charts.size(); ++c)
                if (changed[c])
                    charts[c].faces.clear();
            for (uint32_t f = 0; f < nf; ++f)
                if (changed[chartOf[f]])
                    charts[chartOf[f]].faces.push_back(f);
            // Each changed chart flattened on its own (charts are independent).
            std::vector<uint32_t> redo;
            for (size_t c = 0; c < charts.size(); ++c)
                if (changed[c])
                    redo.push_back(uint32_t(c));
            parallelChunks(redo.size(), threads, [&](int, size_t begin, size_t end) {
                std::vector<int32_t> scratch(begin < end ? nv : 0, -1);
                for (size_t i = begin; i < end; ++i)
                    if (!reflatten(&charts[redo[i]], redo[i], &scratch))
                        bad[redo[i]] = 1;
            });
            bool failed = false;
            for (uint32_t c : redo)
                failed = failed || bad[c];
            if (!failed)
                break;
            std::vector<Move> kept;
            for (const Move& m : moves)
                if (bad[m.from] || bad[m.to]) {
                    chartOf[m.face] = m.from;
                    undone.push_back(m);
                } else {
                    kept.push_back(m);
                }
            moves.swap(kept);
            for (size_t c = 0; c < charts.size(); ++c)
                if (changed[c])
                    charts[c] = before[c];  // flattened again if a kept move still changes it
        }
        // A batch fails as a whole where one of its moves does: those undone
        // are tried once more one at a time, and refused for good where
        // they still fail.  Only between charts of up to kMaxRetryFaces
        // faces: each try flattens both again, and on a dense cage (the
        // 100k scan's 10k remesh) its 95 tries between charts of 1,000-3,000
        // faces took 1.7 s to take 7 of 6,126 split vertices off.
        size_t single = 0;
        for (const Move& m : undone) {
            if (charts[m.from].faces.size() > kMaxRetryFaces || charts[m.to].faces.size() > kMaxRetryFaces) {
                refused[m.face] = 1;
                continue;
            }
            if (chartOf[m.face] != m.from || moveTarget(m.face) != m.to)
                continue;  // the next pass looks at it again
            Chart from = charts[m.from], to = charts[m.to];
            chartOf[m.face] = m.to;
            from.faces.erase(std::find(from.faces.begin(), from.faces.end(), m.face));
            to.faces.push_back(m.face);
            if (reflatten(&from, m.from, &local) && reflatten(&to, m.to, &local)) {
                charts[m.from] = std::move(from);
                charts[m.to] = std::move(to);
                ++single;
            } else {
                chartOf[m.face] = m.from;
                refused[m.face] = 1;
            }
        }
        if (moves.empty() && single == 0)
            break;
    }
    // Each chart turned to its smallest bounding box (5-degree steps), lying
    // down: shelves pack better.
    double maxDistortion = 1.0;
    for (Chart& c : charts) {
        maxDistortion = std::max(maxDistortion, c.distortion);
        double bestArea = 1e300, bestAngle = 0.0;
        for (int step = 0; step < 18; ++step) {
            const double t = double(step) * 3.14159265358979 / 36.0, cs = std::cos(t), sn = std::sin(t);
            glm::dvec2 lo(1e300), hi(-1e300);
            for (const glm::dvec2& p : c.points) {
                const glm::dvec2 r(cs * p.x - sn * p.y, sn * p.x + cs * p.y);
                lo = glm::min(lo, r);
                hi = glm::max(hi, r);
            }
            const double a = (hi.x - lo.x) * (hi.y - lo.y);
            if (a < bestArea) {
                bestArea = a;
                bestAngle = t;
            }
        }
        const double cs = std::cos(bestAngle), sn = std::sin(bestAngle);
        c.lo = glm::dvec2(1e300);
        c.hi = glm::dvec2(-1e300);
        for (glm::dvec2& p : c.points) {
            p = glm::dvec2(cs * p.x - sn * p.y, sn * p.x + cs * p.y);
            c.lo = glm::min(c.lo, p);
            c.hi = glm::max(c.hi, p);
        }
        if (c.hi.y - c.lo.y > c.hi.x - c.lo.x) {
            for (glm::dvec2& p : c.points)
                p = glm::dvec2(p.y, -p.x);
            c.lo = glm::dvec2(1e300);
            c.hi = glm::dvec2(-1e300);
            for (const glm::dvec2& p : c.points) {
                c.lo = glm::min(c.lo, p);
                c.hi = glm::max(c.hi, p);
            }
        }
    }
    *maxDistortionOut = maxDistortion;
}

}  // namespace

namespace {

// A mesh's charts, grown under one share of the surface.
struct ChartSet {
    std::vector<Chart> charts;
    double maxDistortion = 1.0;
};

// Orders the packer tries the charts in.  Lowest-top placement of
// irregular charts is sensitive to order, and no one order wins: on the
// real pairs each of these packed best at some map size, by 1-5% of scale.
// First the longest first; then the largest box first, the tallest first;
// then the first with neighbours swapped at random (a fixed seed, so bakes
// repeat).
constexpr int kPackingOrders = 8;
constexpr double kOrderGain = 0.005;  // scale an order must beat the first by
constexpr int kScaleSteps = 6;

std::vector<std::vector<size_t>> packingOrders(const std::vector<Chart>& charts)
{
    std::vector<size_t> order(charts.size());
    for (size_t i = 0; i < order.size(); ++i)
        order[i] = i;
    auto extent = [&](size_t i) { return charts[i].hi - charts[i].lo; };
    auto by = [&](auto key) {
        std::vector<size_t> o = order;
        std::stable_sort(o.begin(), o.end(), [&](size_t a, size_t b) { return key(extent(a)) > key(extent(b)); });
        return o;
    };
    std::vector<std::vector<size_t>> orders;
    orders.push_back(by([](const glm::dvec2& e) { return std::max(e.x, e.y); }));
    orders.push_back(by([](const glm::dvec2& e) { return e.x * e.y; }));
    orders.push_back(by([](const glm::dvec2& e) { return e.y; }));
    uint32_t seed = 12345;
    while (orders.size() < size_t(kPackingOrders)) {
        std::vector<size_t> o = orders[0];
        for (size_t i = 1; i < o.size(); ++i) {
            seed = seed * 1664525u + 1013904223u;
            if ((seed >> 16) % 3 == 0)
                std::swap(o[i], o[i - 1]);
        }
        orders.push_back(std::move(o));
    }
    return orders;
}

// Packs the charts into an options.mapSize map (the largest common scale
// that fits: bracket, then bisect; then, with options.growIntoGaps, each
// chart put back larger where it fits) and writes the UVs they give: one
// per (chart, vertex), which faces index.  `fill`: the fraction of the map
// inside charts.
Status layoutCharts(std::vector<Chart> charts, const ControlMesh& mesh, const AtlasOptions& options, double area,
                    std::vector<glm::vec2>* uvsOut, std::vector<uint32_t>* uvIndicesOut, double* fill)
{
    const size_t nf = mesh.faceCount();
    std::vector<int32_t> local(mesh.positions.size(), -1);
    const int size = options.mapSize, g = options.gutter;
    // Charts are packed into the map with a gutter's margin around it: a
    // footprint may reach into the margin, the chart itself never (it lies
    // g + 1/2 texels inside its footprint).  The sampler clamps to the edge,
    // so no sample reads a texel there; the map's own border texels are not
    // spent on gutters.
    const int span = size + 2 * g;
    const std::vector<std::vector<size_t>> orders = packingOrders(charts);
    std::vector<Placement> placements, trial;
    size_t used = 0;
    // Packs orders[k] at `scale`; on success keeps the placement.
    auto packs = [&](size_t k, double scale) {
        if (cancelRequested())  // a cancelled bake: every pack fails at once
            return false;
        if (!pack(charts, orders[k], mesh, local, scale, g, span, options.threads, &trial))
            return false;
        placements.swap(trial);
        used = k;
        return true;
    };
    // The first order's largest scale: bracketed, then bisected (the last
    // success is the largest).
    double lo = 0.0, hi = area > 0.0 ? std::sqrt(double(size) * double(size) / area) : 1.0;
    while (packs(0, hi)) {
        lo = hi;
        hi *= 1.25;
    }
    if (lo == 0.0) {
        lo = hi;
        for (int tries = 0; !packs(0, lo); ++tries) {
            if (cancelRequested())
                return Status(StatusCode::Cancelled, "cancelled");
            if (tries == 40)
                return Status(StatusCode::InvalidArgument, "a " + std::to_string(size) + " map is too small for " +
                                                               std::to_string(charts.size()) +
                                                               " charts; use a larger map");
            lo *= 0.8;
        }
        hi = lo / 0.8;
    }
    for (int step = 0; step < kScaleSteps; ++step) {
        const double mid = 0.5 * (lo + hi);
        (packs(0, mid) ? lo : hi) = mid;
    }
    if (cancelRequested())
        return Status(StatusCode::Cancelled, "cancelled");
    // The other orders only where they beat it by kOrderGain: most cost one
    // pack that fails.  Where one succeeds, its own largest scale below the
    // first order's failure bound, hi, or 1.25 times that beyond.
    for (size_t k = 1; k < (options.tryOrders ? orders.size() : 1); ++k) {
        double a = lo * (1.0 + kOrderGain);
        if (!packs(k, a))
            continue;
        double b = std::max(hi, a * 1.25);
        for (int step = 0; step < kScaleSteps; ++step) {
            const double mid = 0.5 * (a + b);
            (packs(k, mid) ? a : b) = mid;
        }
        lo = a;
        hi = b;
    }
    for (Chart& c : charts)
        setChartScale(&c, lo);  // as the kept placement packed them
    for (int pass = 0; pass < (options.growIntoGaps ? kGrowthPasses : 0); ++pass)
        growIntoGaps(charts, orders[used], placements, mesh, local, g, span, options.threads);
    std::vector<glm::vec2>& uvs = *uvsOut;
    std::vector<uint32_t>& uvIndices = *uvIndicesOut;
    uvs.clear();
    uvIndices.assign(3 * nf, 0);
    const double inv = 1.0 / double(size);
    for (size_t i = 0; i < charts.size(); ++i) {
        const Chart& c = charts[i];
        const Placement& at = placements[i];
        const uint32_t base = uint32_t(uvs.size());
        for (const glm::dvec2& p : c.points) {
            const glm::dvec2 t = placed(c, p, c.scaleX, at.rotation, g) + glm::dvec2(double(at.x - g), double(at.y - g));
            uvs.emplace_back(float(t.x * inv), float(t.y * inv));
        }
        setLocal(c, &local, true);
        for (uint32_t f : c.faces)
            for (size_t k = 0; k < 3; ++k)
                uvIndices[3 * size_t(f) + k] = base + uint32_t(local[mesh.triangles[3 * size_t(f) + k]]);
        setLocal(c, &local, false);
    }
    // Area inside charts in texels (projected area <= true area).
    *fill = 0.0;
    for (size_t f = 0; f < nf; ++f) {
        const glm::vec2 a = uvs[uvIndices[3 * f]], b = uvs[uvIndices[3 * f + 1]], c = uvs[uvIndices[3 * f + 2]];
        *fill += 0.5 * std::fabs(double(cross2(b - a, c - a)));
    }
    return Status::ok();
}

}  // namespace

struct ChartCache::Impl {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    double area = 0.0;
    std::vector<ChartSet> sets;
    int chosen = -1;  // the set the first layout kept, or -1
    // The layouts made, for a bake that asks for a size again.
    struct Layout {
        int size = 0, gutter = 0;
        bool grow = false, orders = false;
        size_t set = 0;
        double fill = 0.0;
        std::vector<glm::vec2> uvs;
        std::vector<uint32_t> uvIndices;
    };
    std::vector<Layout> layouts;
    // The one-chart atlas (buildAtlas), over the unit square, once made.
    bool squareMade = false;
    Status square;
    std::vector<glm::vec2> squareUVs;
    std::vector<uint32_t> squareIndices;
    ChartAtlasStats squareStats;
};

ChartCache::ChartCache() = default;
ChartCache::~ChartCache() = default;
ChartCache::ChartCache(ChartCache&&) noexcept = default;
ChartCache& ChartCache::operator=(ChartCache&&) noexcept = default;

Status buildChartAtlas(ControlMesh* mesh, const AtlasOptions& options, ChartAtlasStats* stats, ChartCache* cache)
{
    const size_t nf = mesh->faceCount();
    if (nf == 0)
        return Status(StatusCode::InvalidArgument, "cannot build an atlas for a mesh without faces");
    if (options.mapSize < 8 || options.gutter < 1)
        return Status(StatusCode::InvalidArgument, "atlas map size must be at least 8 and the gutter at least 1");
    const bool cached = cache && cache->impl && cache->impl->positions == mesh->positions &&
                        cache->impl->triangles == mesh->triangles;
    ChartCache scratch;  // holds the charts when no cache is given
    ChartCache& store = cache ? *cache : scratch;
    if (!cached) {
        // Under kMaxChartShare; whole charts as well where the share bound.
        const ChartMesh geometry(*mesh);
        store.impl = std::make_unique<ChartCache::Impl>();
        ChartCache::Impl& made = *store.impl;
        made.positions = mesh->positions;
        made.triangles = mesh->triangles;
        for (size_t f = 0; f < nf; ++f) {  // the packer's area: from the float edge vectors
            const uint32_t* t = &mesh->triangles[3 * f];
            const glm::vec3 a = mesh->positions[t[0]], b = mesh->positions[t[1]], c = mesh->positions[t[2]];
            made.area += 0.5 * glm::length(glm::cross(glm::dvec3(b - a), glm::dvec3(c - a)));
        }
        made.sets.emplace_back();
        bool bound = false;
        makeCharts(*mesh, geometry, options.threads, kMaxChartShare, &made.sets[0].charts, &made.sets[0].maxDistortion,
                   &bound);
        if (bound && !cancelRequested()) {
            made.sets.emplace_back();
            makeCharts(*mesh, geometry, options.threads, 1.0, &made.sets[1].charts, &made.sets[1].maxDistortion,
                       &bound);
        }
        if (cancelRequested()) {  // makeCharts stopped part way: nothing of it is kept
            store.impl.reset();
            return Status(StatusCode::Cancelled, "cancelled");
        }
    }
    ChartCache::Impl& charts = *store.impl;
    const std::vector<ChartSet>& sets = charts.sets;
    const int chosen = charts.chosen;
    const double area = charts.area;
    auto report = [&](size_t set, double fill) {
        if (stats) {
            *stats = ChartAtlasStats();
            stats->charts = sets[set].charts.size();
            stats->texelFill = fill;
            stats->maxDistortion = sets[set].maxDistortion;
        }
    };
    for (const ChartCache::Impl::Layout& l : charts.layouts)
        if (l.size == options.mapSize && l.gutter == options.gutter && l.grow == options.growIntoGaps &&
            l.orders == options.tryOrders) {
            mesh->uvs = l.uvs;
            mesh->uvIndices = l.uvIndices;
            report(l.set, l.fill);
            return Status::ok();
        }
    // Each set laid out; the one with the most texels inside charts kept
    // (the first on a tie).  A cache remembers the choice for the cage's
    // other sizes: how well charts pack hardly depends on the size.
    Status first;
    bool tried = false;
    double bestFill = -1.0;
    size_t best = 0;
    std::vector<glm::vec2> uvs, bestUVs;
    std::vector<uint32_t> uvIndices, bestIndices;
    for (size_t i = 0; i < sets.size(); ++i) {
        if (chosen >= 0 && i != size_t(chosen))
            continue;
        double fill = 0.0;
        Status st = layoutCharts(sets[i].charts, *mesh, options, area, &uvs, &uvIndices, &fill);
        if (!tried)
            first = st;
        tried = true;
        if (st && fill > bestFill) {
            bestFill = fill;
            best = i;
            bestUVs.swap(uvs);
            bestIndices.swap(uvIndices);
        }
    }
    if (bestFill < 0.0)
        return first;
    if (chosen < 0 && sets.size() > 1)
        charts.chosen = int(best);
    if (cache)
        charts.layouts.push_back(
            {options.mapSize, options.gutter, options.growIntoGaps, options.tryOrders, best, bestFill, bestUVs, bestIndices});
    mesh->uvs = std::move(bestUVs);
    mesh->uvIndices = std::move(bestIndices);
    report(best, bestFill);
    return Status::ok();
}

Status buildAtlas(ControlMesh* mesh, const AtlasOptions& options, ChartAtlasStats* stats, ChartCache* cache)
{
    ChartCache scratch;  // holds the charts when no cache is given
    ChartCache& store = cache ? *cache : scratch;
    ChartAtlasStats own;
    if (!stats)
        stats = &own;
    Status s = buildChartAtlas(mesh, options, stats, &store);
    const SquareAtlasOptions whole;
    const double fill = stats->texelFill;
    const bool splitsFew = double(mesh->uvs.size()) <= whole.maxVertexRatio * double(mesh->positions.size());
    if (!s || !options.wholeMap || (splitsFew && fill >= kAtlasMinFill))
        return s;
    ChartCache::Impl& made = *store.impl;  // the charts' cache: this cage's
    if (!made.squareMade) {
        ControlMesh cut;
        cut.positions = mesh->positions;
        cut.triangles = mesh->triangles;
        SquareAtlasOptions unit = whole;
        unit.mapSize = 0;
        made.square = buildSquareAtlas(&cut, unit, &made.squareStats);
        made.squareUVs = std::move(cut.uvs);
        made.squareIndices = std::move(cut.uvIndices);
        made.squareMade = true;
    }
    if (!made.square)
        return s;  // not genus 0, or no cut within the vertex budget: the charts
    mesh->uvs = made.squareUVs;
    mesh->uvIndices = made.squareIndices;
    *stats = made.squareStats;
    stats->texelFill = fitSquareAtlas(&mesh->uvs, options.mapSize);
    return s;
}

}  // namespace baker
}  // namespace strata
