// Control-mesh fitting (Displaced Subdivision Surfaces, section 4.2): a
// few rounds of nearest-point correspondences, each followed by one linear
// least-squares solve for the control positions.
//
// The base surface is sampled at its refined vertices X = S C, S being the
// runtime plan's own stencils (limit positions for the smooth scheme,
// barycentric weights for the linear one).  The energy of a round is
//
//   wF sum_i |X_i - p_i|^2                 refined vertex -> nearest capture point
// + wB sum_j |sum_c beta_jc X_c - h_j|^2   capture vertex -> nearest point of the refined mesh
// + mu sum_v |L C_v - L C0_v|^2            each control vertex's offset from its neighbours' mean kept
// + eps |C - C_prev|^2                     (keeps vertices no term reaches where they are)
//
// Both distance terms are quadratic in X, so they are gathered into one
// sparse form over the refined mesh's edges (Q) and the normal equations
// are applied as S^T (wF I + wB Q) S + mu L^T L + eps I without forming
// them; conjugate gradients with a Jacobi preconditioner solve the three
// coordinates together.  Every pass is a gather, so the result is the same
// for any thread count.
#include "strata/baker/fit.h"
#include "plans.h"

#include "parallel.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace strata {
namespace baker {

namespace {

// Compressed sparse rows with double weights.
struct Csr {
    std::vector<uint32_t> offsets, cols;
    std::vector<double> w;
    size_t rows() const { return offsets.empty() ? 0 : offsets.size() - 1; }
};

Csr transpose(const Csr& a, size_t colCount)
{
    Csr t;
    t.offsets.assign(colCount + 1, 0);
    for (uint32_t c : a.cols)
        ++t.offsets[c + 1];
    for (size_t c = 0; c < colCount; ++c)
        t.offsets[c + 1] += t.offsets[c];
    t.cols.resize(a.cols.size());
    t.w.resize(a.w.size());
    std::vector<uint32_t> fill(t.offsets.begin(), t.offsets.end() - 1);
    for (size_t r = 0; r < a.rows(); ++r)
        for (uint32_t e = a.offsets[r]; e < a.offsets[r + 1]; ++e) {
            const uint32_t at = fill[a.cols[e]]++;
            t.cols[at] = uint32_t(r);
            t.w[at] = a.w[e];
        }
    return t;
}

// y = A x (gather form).
void multiply(const Csr& a, const std::vector<glm::dvec3>& x, std::vector<glm::dvec3>* y, int threads)
{
    y->resize(a.rows());
    parallelFor(a.rows(), threads, [&](size_t begin, size_t end) {
        for (size_t r = begin; r < end; ++r) {
            glm::dvec3 s(0.0);
            for (uint32_t e = a.offsets[r]; e < a.offsets[r + 1]; ++e)
                s += a.w[e] * x[a.cols[e]];
            (*y)[r] = s;
        }
    });
}

// Each vertex's neighbours across the triangles' edges, sorted, each once
// (a vertex is not its own neighbour).
std::vector<std::vector<uint32_t>> neighbourLists(const std::vector<uint32_t>& triangles, size_t vertexCount)
{
    std::vector<std::vector<uint32_t>> lists(vertexCount);
    for (size_t f = 0; f < triangles.size() / 3; ++f)
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
                if (a != b)
                    lists[triangles[3 * f + size_t(a)]].push_back(triangles[3 * f + size_t(b)]);
    for (std::vector<uint32_t>& l : lists) {
        std::sort(l.begin(), l.end());
        l.erase(std::unique(l.begin(), l.end()), l.end());
    }
    return lists;
}

// Componentwise helpers, so one solver serves scalars and coordinates.
inline double times(double a, double b) { return a * b; }
inline glm::dvec3 times(const glm::dvec3& a, const glm::dvec3& b) { return a * b; }
inline double ratio(double a, double b) { return b > 0.0 ? a / b : 0.0; }
inline glm::dvec3 ratio(const glm::dvec3& a, const glm::dvec3& b)
{
    return glm::dvec3(ratio(a.x, b.x), ratio(a.y, b.y), ratio(a.z, b.z));
}
inline bool small(double rr, double r0) { return rr <= 1e-20 * std::max(r0, 1e-300); }
inline bool small(const glm::dvec3& rr, const glm::dvec3& r0)
{
    return small(rr.x, r0.x) && small(rr.y, r0.y) && small(rr.z, r0.z);
}

// Solves A x = rhs (A symmetric positive definite, applied by `apply`) by
// conjugate gradients with the Jacobi preconditioner diag, from x's
// current value; T is double or glm::dvec3 (three systems at once).
template <typename T, typename Apply>
void conjugateGradients(Apply&& apply, const std::vector<double>& diag, const std::vector<T>& rhs, std::vector<T>* x,
                        int maxIterations = 400)
{
    const size_t n = rhs.size();
    std::vector<T> r(n), z(n), p(n), ap;
    apply(*x, &ap);
    T rz(0.0), r0(0.0);
    for (size_t v = 0; v < n; ++v) {
        r[v] = rhs[v] - ap[v];
        z[v] = r[v] / diag[v];
        p[v] = z[v];
        rz += times(r[v], z[v]);
        r0 += times(rhs[v], rhs[v]);
    }
    for (int it = 0; it < maxIterations; ++it) {
        apply(p, &ap);
        T pap(0.0);
        for (size_t v = 0; v < n; ++v)
            pap += times(p[v], ap[v]);
        const T alpha = ratio(rz, pap);
        T rr(0.0), rzNext(0.0);
        for (size_t v = 0; v < n; ++v) {
            (*x)[v] += alpha * p[v];
            r[v] -= alpha * ap[v];
            z[v] = r[v] / diag[v];
            rr += times(r[v], r[v]);
            rzNext += times(r[v], z[v]);
        }
        if (small(rr, r0))
            break;
        const T beta = ratio(rzNext, rz);
        rz = rzNext;
        for (size_t v = 0; v < n; ++v)
            p[v] = z[v] + beta * p[v];
    }
}

// The two distance terms as one quadratic form over the refined vertices'
// positions y (the same for each coordinate):
//   wF sum_i |y_i - p_i|^2 + wB sum_j |sum_c beta_jc y_c - h_j|^2 = y^T Q y - 2 y^T g + const,
// Q living on the refined mesh's edges and diagonal.
struct PairForm {
    Csr q;
    std::vector<uint32_t> slots;     // per refined triangle, its nine (corner, corner) entries of q
    std::vector<uint32_t> diagonal;  // per refined vertex, its (v, v) entry of q

    void build(const std::vector<uint32_t>& triangles, size_t vertexCount)
    {
        const std::vector<std::vector<uint32_t>> adjacent = neighbourLists(triangles, vertexCount);
        q.offsets.assign(vertexCount + 1, 0);
        q.cols.clear();
        for (size_t v = 0; v < vertexCount; ++v) {
            // The row's columns: the vertex itself among its neighbours, sorted.
            const auto at = std::lower_bound(adjacent[v].begin(), adjacent[v].end(), uint32_t(v));
            q.cols.insert(q.cols.end(), adjacent[v].begin(), at);
            q.cols.push_back(uint32_t(v));
            q.cols.insert(q.cols.end(), at, adjacent[v].end());
            q.offsets[v + 1] = uint32_t(q.cols.size());
        }
        q.w.assign(q.cols.size(), 0.0);
        auto slot = [&](uint32_t r, uint32_t c) {
            const auto begin = q.cols.begin() + q.offsets[r], end = q.cols.begin() + q.offsets[r + 1];
            return uint32_t(std::lower_bound(begin, end, c) - q.cols.begin());
        };
        slots.resize(triangles.size() * 3);
        for (size_t f = 0; f < triangles.size() / 3; ++f)
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                    slots[9 * f + 3 * size_t(a) + size_t(b)] = slot(triangles[3 * f + a], triangles[3 * f + b]);
        diagonal.resize(vertexCount);
        for (size_t v = 0; v < vertexCount; ++v)
            diagonal[v] = slot(uint32_t(v), uint32_t(v));
        triangles_ = &triangles;
    }

    // Fills q.w and g from the current positions y: each used refined vertex
    // to its nearest capture point, each capture vertex to its nearest point
    // on the refined mesh.  Returns the larger RMS of those two distances.
    double gather(std::vector<glm::dvec3>* g, const std::vector<glm::vec3>& y, const std::vector<uint8_t>& used,
                  const TriangleMesh& high, const TriangleIndex& highIndex, double wF, double wB, int threads)
    {
        const std::vector<uint32_t>& triangles = *triangles_;
        const size_t nr = y.size();
        g->assign(nr, glm::dvec3(0.0));
        std::fill(q.w.begin(), q.w.end(), 0.0);
        // Each query starts from the face the last round found (or, in the
        // first, the previous vertex's): the points move little, so the
        // search prunes at once.  Hints change only the speed.
        forwardHint_.resize(nr, -1);
        backwardHint_.resize(high.positions.size(), -1);
        std::vector<double> forward(nr, 0.0), backward(high.positions.size(), 0.0);
        parallelFor(nr, threads, [&](size_t begin, size_t end) {
            int64_t previous = -1;
            for (size_t v = begin; v < end; ++v) {
                uint32_t f;
                double b1, b2;
                if (!used[v] ||
                    highIndex.nearest(glm::dvec3(y[v]), &f, &b1, &b2, forwardHint_[v] >= 0 ? forwardHint_[v] : previous) <
                        0.0)
                    continue;
                forwardHint_[v] = previous = int64_t(f);
                const uint32_t* t = &high.triangles[3 * size_t(f)];
                const glm::dvec3 p = (1.0 - b1 - b2) * glm::dvec3(high.positions[t[0]]) +
                                     b1 * glm::dvec3(high.positions[t[1]]) + b2 * glm::dvec3(high.positions[t[2]]);
                (*g)[v] = wF * p;
                forward[v] = glm::dot(p - glm::dvec3(y[v]), p - glm::dvec3(y[v]));
                q.w[diagonal[v]] = wF;
            }
        });
        TriangleIndex index;
        index.build(y.data(), triangles.data(), triangles.size() / 3, threads);
        struct Hit {
            uint32_t face;
            double b[3];
        };
        std::vector<Hit> hits(high.positions.size());
        parallelFor(hits.size(), threads, [&](size_t begin, size_t end) {
            int64_t previous = -1;
            for (size_t j = begin; j < end; ++j) {
                double b1 = 0.0, b2 = 0.0;
                uint32_t f = 0;
                const double distance = index.nearest(glm::dvec3(high.positions[j]), &f, &b1, &b2,
                                                      backwardHint_[j] >= 0 ? backwardHint_[j] : previous);
                if (distance < 0.0)
                    f = 0xffffffffu;
                else
                    backwardHint_[j] = previous = int64_t(f);
                backward[j] = distance > 0.0 ? distance * distance : 0.0;
                hits[j] = {f, {1.0 - b1 - b2, b1, b2}};
            }
        });
        // In capture order, one thread: the same sums for any thread count.
        for (size_t j = 0; j < hits.size(); ++j) {
            const Hit& h = hits[j];
            if (h.face == 0xffffffffu)
                continue;
            for (int a = 0; a < 3; ++a) {
                (*g)[triangles[3 * size_t(h.face) + a]] += wB * h.b[a] * glm::dvec3(high.positions[j]);
                for (int b = 0; b < 3; ++b)
                    q.w[slots[9 * size_t(h.face) + 3 * size_t(a) + size_t(b)]] += wB * h.b[a] * h.b[b];
            }
        }
        double sumF = 0.0, sumB = 0.0;
        size_t countF = 0;
        for (size_t v = 0; v < nr; ++v)
            if (used[v]) {
                sumF += forward[v];
                ++countF;
            }
        for (double d2 : backward)
            sumB += d2;
        return std::max(std::sqrt(sumF / double(std::max<size_t>(countF, 1))),
                        std::sqrt(sumB / double(std::max<size_t>(backward.size(), 1))));
    }

private:
    const std::vector<uint32_t>* triangles_ = nullptr;
    std::vector<int64_t> forwardHint_, backwardHint_;  // per query, the face its last search found
};

}  // namespace

Status fitControlMesh(ControlMesh* control, const TriangleMesh& high, const TriangleIndex& highIndex,
                      const FitOptions& options, FitStats* stats)
{
    if (!control)
        return Status(StatusCode::InvalidArgument, "fitControlMesh: no control mesh");
    if (high.faceCount() == 0)
        return Status(StatusCode::InvalidArgument, "fitControlMesh: the capture has no triangles");
    if (options.level < 0 || options.level > kMaxLevel || options.iterations < 0 || !(options.smoothness >= 0.0))
        return Status(StatusCode::InvalidArgument, "fitControlMesh: level, iterations or smoothness out of range");
    std::unique_ptr<Plan> plan;
    if (Status st = createPlan(&plan, *control, options.scheme, options.level); !st)
        return st;
    const int threads = std::max(1, options.threads);
    const size_t n = control->positions.size();
    const std::vector<uint32_t>& refinedTriangles = plan->refinedTriangles();
    const std::vector<SampleLocation>& samples = plan->sampleLocations();
    const size_t nr = plan->refinedVertexCount();

    // S: refined vertex <- control vertices (position weights only).
    Csr s;
    {
        Plan::FlatStencils flat;
        plan->flattenStencils(&flat);
        const int stride = flat.weightsPerEntry;
        s.offsets.assign(nr + 1, 0);
        for (size_t v = 0; v < nr; ++v) {
            for (uint32_t e = flat.offsets[v]; e < flat.offsets[v + 1]; ++e)
                if (flat.weights[size_t(e) * size_t(stride)] != 0.0f) {
                    s.cols.push_back(flat.indices[e]);
                    s.w.push_back(flat.weights[size_t(e) * size_t(stride)]);
                }
            s.offsets[v + 1] = uint32_t(s.cols.size());
        }
    }
    const Csr st = transpose(s, n);

    // The control mesh's neighbours, for the Laplacian term.
    const std::vector<std::vector<uint32_t>> ring = neighbourLists(control->triangles, n);
    auto laplacian = [&](const std::vector<glm::dvec3>& x, std::vector<glm::dvec3>* y) {
        y->resize(n);
        for (size_t v = 0; v < n; ++v) {
            glm::dvec3 mean(0.0);
            for (uint32_t u : ring[v])
                mean += x[u];
            (*y)[v] = ring[v].empty() ? glm::dvec3(0.0) : x[v] - mean / double(ring[v].size());
        }
    };
    auto laplacianT = [&](const std::vector<glm::dvec3>& y, std::vector<glm::dvec3>* x) {
        x->resize(n);
        for (size_t u = 0; u < n; ++u) {
            glm::dvec3 sum = ring[u].empty() ? glm::dvec3(0.0) : y[u];
            for (uint32_t v : ring[u])
                sum -= y[v] / double(ring[v].size());
            (*x)[u] = sum;
        }
    };

    std::vector<glm::dvec3> c(n), c0(n);
    for (size_t v = 0; v < n; ++v)
        c[v] = c0[v] = glm::dvec3(control->positions[v]);
    std::vector<glm::dvec3> delta0;
    laplacian(c0, &delta0);

    auto refine = [&](const std::vector<glm::dvec3>& cp, std::vector<glm::vec3>* x) {
        std::vector<glm::dvec3> xd;
        multiply(s, cp, &xd, threads);
        x->resize(nr);
        for (size_t v = 0; v < nr; ++v)
            (*x)[v] = glm::vec3(xd[v]);
    };
    // Only vertices on a face are samples (an isolated one stays where it is).
    std::vector<uint8_t> onFace(nr, 0);
    size_t forwardCount = 0;
    for (size_t v = 0; v < nr; ++v)
        if (samples[v].face != kNoControlFace) {
            onFace[v] = 1;
            ++forwardCount;
        }
    const double wF = forwardCount ? 1.0 / double(forwardCount) : 0.0;
    const double wB = 1.0 / double(high.positions.size());
    std::vector<glm::vec3> x;
    refine(c, &x);
    // The error is measured where the fit looks: the refined vertices and
    // the capture's vertices, each to the other surface.
    PairForm form;
    form.build(refinedTriangles, nr);
    std::vector<glm::dvec3> g;
    const double before = form.gather(&g, x, onFace, high, highIndex, wF, wB, threads);
    glm::vec3 lo(high.positions[0]), hi(high.positions[0]);
    for (const glm::vec3& p : high.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const double moveLimit = options.maxMove * glm::length(glm::dvec3(hi - lo));
    if (stats) {
        stats->rmsBefore = stats->rmsAfter = before;
        stats->maxMove = 0.0;
    }
    if (!(before <= moveLimit))
        return Status::ok();

    const double mu = options.smoothness / double(std::max<size_t>(n, 1));
    const double eps = 1e-6 / double(std::max<size_t>(n, 1));

    for (int round = 0; round < options.iterations; ++round) {
        // Correspondences, both directions (the first round's were found
        // with the error before the fit).
        if (round > 0)
            form.gather(&g, x, onFace, high, highIndex, wF, wB, threads);
        const Csr& q = form.q;

        // Right-hand side and the operator.
        std::vector<glm::dvec3> rhs, tmp, lap;
        multiply(st, g, &rhs, threads);
        laplacianT(delta0, &lap);
        for (size_t v = 0; v < n; ++v)
            rhs[v] += mu * lap[v] + eps * c[v];
        std::vector<glm::dvec3> sx, qsx;
        auto apply = [&](const std::vector<glm::dvec3>& in, std::vector<glm::dvec3>* out) {
            multiply(s, in, &sx, threads);
            multiply(q, sx, &qsx, threads);
            multiply(st, qsx, out, threads);
            laplacian(in, &tmp);
            laplacianT(tmp, &lap);
            for (size_t v = 0; v < n; ++v)
                (*out)[v] += mu * lap[v] + eps * in[v];
        };
        // Jacobi preconditioner: diag(S^T Q S) from Q's diagonal only, plus
        // the Laplacian's and eps's diagonals.
        std::vector<double> diag(n, eps);
        for (size_t u = 0; u < n; ++u) {
            for (uint32_t e = st.offsets[u]; e < st.offsets[u + 1]; ++e) {
                const uint32_t r = st.cols[e];
                diag[u] += st.w[e] * st.w[e] * q.w[form.diagonal[r]];
            }
            if (!ring[u].empty()) {
                double d = 1.0;
                for (uint32_t v : ring[u])
                    d += 1.0 / (double(ring[v].size()) * double(ring[v].size()));
                diag[u] += mu * d;
            }
        }
        conjugateGradients(apply, diag, rhs, &c);
        refine(c, &x);
    }

    const double after = form.gather(&g, x, onFace, high, highIndex, wF, wB, threads);
    double maxMove = 0.0;
    for (size_t v = 0; v < n; ++v)
        maxMove = std::max(maxMove, glm::length(c[v] - c0[v]));
    if (!(after < before) || !(maxMove <= moveLimit))
        return Status::ok();
    if (stats) {
        stats->rmsAfter = after;
        stats->maxMove = maxMove;
    }
    for (size_t v = 0; v < n; ++v)
        control->positions[v] = glm::vec3(c[v]);
    return Status::ok();
}

Status fitVertexDisplacements(std::vector<float>* values, const ControlMesh& mesh, Scheme scheme, int level,
                              const TriangleMesh& high, const TriangleIndex& highIndex, int iterations, int threads)
{
    if (!values)
        return Status(StatusCode::InvalidArgument, "fitVertexDisplacements: no values");
    std::unique_ptr<Plan> plan;
    std::vector<glm::vec3> surface, direction;
    if (Status st = evaluateBareSurface(&plan, &surface, &direction, mesh, scheme, level, values->size(),
                                        "fitVertexDisplacements");
        !st)
        return st;
    const size_t nr = surface.size();
    threads = std::max(1, threads);
    const std::vector<uint32_t>& triangles = plan->refinedTriangles();
    const std::vector<SampleLocation>& samples = plan->sampleLocations();
    std::vector<uint8_t> used(nr, 0);
    size_t usedCount = 0;
    for (size_t v = 0; v < nr; ++v)
        if (samples[v].face != kNoControlFace && glm::length(direction[v]) > 0.0f) {
            used[v] = 1;
            ++usedCount;
        }
    if (!usedCount || high.positions.empty())
        return Status::ok();
    PairForm form;
    form.build(triangles, nr);
    const double wF = 1.0 / double(usedCount), wB = 1.0 / double(high.positions.size());
    // A weak pull to the round's starting values keeps the system definite.
    const double eps = 1e-4 * wF;
    std::vector<double> d(values->begin(), values->end());
    std::vector<glm::vec3> y(nr);
    auto place = [&]() {
        for (size_t v = 0; v < nr; ++v)
            y[v] = used[v] ? glm::vec3(glm::dvec3(surface[v]) + d[v] * glm::dvec3(direction[v])) : surface[v];
    };
    place();
    for (int round = 0; round < iterations; ++round) {
        std::vector<glm::dvec3> g;
        form.gather(&g, y, used, high, highIndex, wF, wB, threads);
        const Csr& q = form.q;
        // (N^T Q N) d = N^T (g - Q s), N the directions, s the bare surface;
        // unused vertices keep their value (their rows reduce to eps).
        std::vector<double> rhs(nr), diag(nr);
        parallelFor(nr, threads, [&](size_t begin, size_t end) {
            for (size_t a = begin; a < end; ++a) {
                const glm::dvec3 na(direction[a]);
                glm::dvec3 qs(0.0);
                for (uint32_t e = q.offsets[a]; e < q.offsets[a + 1]; ++e)
                    qs += q.w[e] * glm::dvec3(surface[q.cols[e]]);
                rhs[a] = used[a] ? glm::dot(na, g[a] - qs) + eps * d[a] : eps * d[a];
                diag[a] = (used[a] ? q.w[form.diagonal[a]] * glm::dot(na, na) : 0.0) + eps;
            }
        });
        auto apply = [&](const std::vector<double>& in, std::vector<double>* out) {
            out->resize(nr);
            parallelFor(nr, threads, [&](size_t begin, size_t end) {
                for (size_t a = begin; a < end; ++a) {
                    double sum = eps * in[a];
                    if (used[a]) {
                        const glm::dvec3 na(direction[a]);
                        for (uint32_t e = q.offsets[a]; e < q.offsets[a + 1]; ++e) {
                            const uint32_t b = q.cols[e];
                            if (used[b])
                                sum += q.w[e] * glm::dot(na, glm::dvec3(direction[b])) * in[b];
                        }
                    }
                    (*out)[a] = sum;
                }
            });
        };
        conjugateGradients(apply, diag, rhs, &d);
        place();
    }
    for (size_t v = 0; v < nr; ++v)
        if (used[v])
            (*values)[v] = float(d[v]);
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
