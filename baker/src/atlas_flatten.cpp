// The chart atlas's flattening: a chart projected onto its plane, then
// least-squares conformal, then as rigid as possible, checked for folds,
// laps and distortion.
#include "atlas_parts.h"

#include "distortion.h"
#include "strata/plane.h"

#include <Eigen/Sparse>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

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
        const double area = orient2(u[0], u[1], u[2]);
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

}  // namespace

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

}  // namespace baker
}  // namespace strata
