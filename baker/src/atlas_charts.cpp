// The chart atlas's charting: charts grown breadth first over a control
// mesh while they stay disks and flatten within kChartMaxDistortion, their
// borders straightened by moving faces between them, each turned to its
// smallest bounding box.
#include "atlas_parts.h"

#include "cancel.h"
#include "parallel.h"
#include "strata/normals.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

ChartMesh::ChartMesh(const ControlMesh& mesh)
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

// The most faces one chart may have, which bounds a try's sparse
// factorisations: a dense cage's flat regions are cut into charts this
// large.
constexpr size_t kMaxChartFaces = 65536;
// The largest charts a border face's move between them is retried alone
// for (after its batch failed to flatten).
constexpr size_t kMaxRetryFaces = 1024;

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

}  // namespace baker
}  // namespace strata
