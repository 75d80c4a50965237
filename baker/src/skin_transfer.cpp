// Skin weights onto an automatic cage.  Carried: the nearest point on the
// capture, its triangle's corner weights blended by barycentrics (a cage
// made by simplifying the capture lies on or near it everywhere, so the
// nearest point is the part of the body the cage vertex stands for).
// Fitted: least squares over the animations' poses, so that the layered
// surface moves as the capture around each cage vertex moves, not only as
// its one nearest point does.
#include "strata/baker/skin_transfer.h"

#include "parallel.h"
#include "strata/normals.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace strata {
namespace baker {

namespace {

using JointWeights = std::vector<std::pair<uint16_t, double>>;  // joint, weight

// Strongest first, ties by joint.
bool strongerFirst(const std::pair<uint16_t, double>& x, const std::pair<uint16_t, double>& y)
{
    return x.second != y.second ? x.second > y.second : x.first < y.first;
}

// The capture's weights at barycentrics (b1, b2) of its triangle `face`:
// its corners' joints blended, strongest first (ties by joint).
void captureWeightsAt(JointWeights* sum, const TriangleMesh& high, const VertexWeights& hw, uint32_t face, double b1,
                      double b2)
{
    const size_t k = size_t(hw.influences);
    const double bary[3] = {1.0 - b1 - b2, b1, b2};
    sum->clear();
    for (size_t c = 0; c < 3; ++c) {
        const size_t hv = high.triangles[3 * size_t(face) + c];
        for (size_t i = 0; i < k; ++i) {
            const float wi = hw.weights[hv * k + i];
            if (!(wi > 0.0f))
                continue;
            const uint16_t j = hw.joints[hv * k + i];
            auto it = std::find_if(sum->begin(), sum->end(), [&](const auto& e) { return e.first == j; });
            if (it == sum->end())
                sum->push_back({j, bary[c] * double(wi)});
            else
                it->second += bary[c] * double(wi);
        }
    }
    std::sort(sum->begin(), sum->end(), strongerFirst);
}

// Keeps the `most` strongest of `sum` and writes them, normalised to sum to
// 1, into one vertex's slots (strongest first, the rest 0); false, writing
// nothing, where they weigh nothing.
bool writeStrongest(JointWeights* sum, size_t most, uint16_t* joints, float* weights)
{
    std::sort(sum->begin(), sum->end(), strongerFirst);
    if (sum->size() > most)
        sum->resize(most);
    double total = 0.0;
    for (const auto& e : *sum)
        total += e.second;
    if (!(total > 0.0))
        return false;
    for (size_t i = 0; i < most; ++i) {
        const bool set = i < sum->size();
        joints[i] = set ? (*sum)[i].first : 0;
        weights[i] = set ? float((*sum)[i].second / total) : 0.0f;
    }
    return true;
}

}  // namespace

// The nearest capture point to x, of `piece` where the shells are given.
double nearestOfPiece(const TriangleIndex& index, const SkinShells& shells, uint32_t piece, const glm::dvec3& x,
                      uint32_t* face, double* b1, double* b2)
{
    return shells.highFace ? index.nearestLabelled(x, shells.highFace, piece, face, b1, b2)
                           : index.nearest(x, face, b1, b2);
}

Status transferSkinWeights(const ControlMesh& cage, const TriangleMesh& high, const TriangleIndex& index,
                           const VertexWeights& highWeights, VertexWeights* out, int threads, SkinShells shells)
{
    if (!shells.cageVertex)
        shells.highFace = nullptr;
    const int k = highWeights.influences;
    if (!out || k <= 0 || highWeights.joints.size() != high.positions.size() * size_t(k) ||
        highWeights.weights.size() != highWeights.joints.size())
        return Status(StatusCode::InvalidArgument, "transferSkinWeights: the capture's weights do not match it");
    const size_t n = cage.positions.size();
    VertexWeights w;
    w.influences = k;
    w.joints.assign(n * size_t(k), 0);
    w.weights.assign(n * size_t(k), 0.0f);
    std::vector<uint8_t> missed(n, 0);
    // One cage vertex: false when no weighted capture point is found.
    auto weigh = [&](size_t v) {
        uint32_t face = 0;
        double b1 = 0.0, b2 = 0.0;
        const uint32_t piece = shells.cageVertex ? shells.cageVertex[v] : 0;
        if (nearestOfPiece(index, shells, piece, glm::dvec3(cage.positions[v]), &face, &b1, &b2) < 0.0 ||
            face >= high.faceCount())
            return false;
        JointWeights sum;
        captureWeightsAt(&sum, high, highWeights, face, b1, b2);
        return writeStrongest(&sum, size_t(k), &w.joints[v * size_t(k)], &w.weights[v * size_t(k)]);
    };
    parallelFor(n, threads, [&](size_t begin, size_t end) {
        for (size_t v = begin; v < end; ++v)
            missed[v] = !weigh(v);
    });
    const size_t misses = size_t(std::count(missed.begin(), missed.end(), uint8_t(1)));
    if (misses)
        return Status(StatusCode::InvalidData, std::to_string(misses) +
                                                   " cage vertices found no weighted capture triangle to take skin "
                                                   "weights from");
    *out = std::move(w);
    return Status::ok();
}

namespace {

constexpr int kMaxCandidates = 8;        // joints a cage vertex's fit chooses from
constexpr size_t kMaxPoses = 48;
constexpr size_t kTimesPerAnimation = 12;
constexpr int kMaxSweeps = 12;
constexpr double kSettled = 0.99;        // a sweep keeping 99% of the sum or more ends the fit
constexpr double kPull = 1e-3;           // towards the given weights, against the data's spread

// Solves A x = b for an m x m symmetric positive definite A (row-major)
// by Cholesky; false when A is not positive definite.
bool choleskySolve(const double* A, int m, const double* b0, const double* b1, double* x0, double* x1)
{
    double L[kMaxCandidates * kMaxCandidates] = {};
    for (int i = 0; i < m; ++i)
        for (int j = 0; j <= i; ++j) {
            double v = A[i * m + j];
            for (int k = 0; k < j; ++k)
                v -= L[i * m + k] * L[j * m + k];
            if (i == j) {
                if (!(v > 0.0))
                    return false;
                L[i * m + i] = std::sqrt(v);
            } else {
                L[i * m + j] = v / L[j * m + j];
            }
        }
    for (int r = 0; r < 2; ++r) {
        const double* b = r ? b1 : b0;
        double* x = r ? x1 : x0;
        for (int i = 0; i < m; ++i) {
            double v = b[i];
            for (int k = 0; k < i; ++k)
                v -= L[i * m + k] * x[k];
            x[i] = v / L[i * m + i];
        }
        for (int i = m - 1; i >= 0; --i) {
            double v = x[i];
            for (int k = i + 1; k < m; ++k)
                v -= L[k * m + i] * x[k];
            x[i] = v / L[i * m + i];
        }
    }
    return true;
}

// w minimising w'Aw + 2 g'w with its entries summing to 1, non-negative,
// at most `most` of them non-zero (A m x m, positive definite): the
// equality-constrained minimum on a set of joints that drops the most
// negative weight, then the smallest, until both hold.  False when no
// set solves.
bool solveWeights(const double* A, const double* g, int m, int most, double* w)
{
    bool on[kMaxCandidates];
    std::fill(on, on + m, true);
    int count = m;
    while (count > 0) {
        int at[kMaxCandidates];
        int n = 0;
        for (int i = 0; i < m; ++i)
            if (on[i])
                at[n++] = i;
        double a[kMaxCandidates * kMaxCandidates], gs[kMaxCandidates], ones[kMaxCandidates], x[kMaxCandidates],
            z[kMaxCandidates];
        for (int i = 0; i < n; ++i) {
            for (int j = 0; j < n; ++j)
                a[i * n + j] = A[at[i] * m + at[j]];
            gs[i] = g[at[i]];
            ones[i] = 1.0;
        }
        if (!choleskySolve(a, n, gs, ones, x, z))
            return false;
        // w = -x - nu z, nu making the weights sum to 1.
        double sx = 0.0, sz = 0.0;
        for (int i = 0; i < n; ++i) {
            sx += x[i];
            sz += z[i];
        }
        if (!(sz > 0.0))
            return false;
        const double nu = -(1.0 + sx) / sz;
        std::fill(w, w + m, 0.0);
        int worst = -1, least = -1;
        for (int i = 0; i < n; ++i) {
            w[at[i]] = -x[i] - nu * z[i];
            if (w[at[i]] < 0.0 && (worst < 0 || w[at[i]] < w[worst]))
                worst = at[i];
            if (least < 0 || w[at[i]] < w[least])
                least = at[i];
        }
        if (worst < 0 && count <= most)
            return true;
        on[worst >= 0 ? worst : least] = false;
        --count;
    }
    return false;
}

// w'Aw + 2 g'w.
double objective(const double* A, const double* g, int m, const double* w)
{
    double f = 0.0;
    for (int i = 0; i < m; ++i) {
        double r = 2.0 * g[i];
        for (int j = 0; j < m; ++j)
            r += A[i * m + j] * w[j];
        f += r * w[i];
    }
    return f;
}

glm::vec3 transformPoint(const glm::mat4& m, const glm::vec3& p) { return glm::vec3(m * glm::vec4(p, 1.0f)); }

}  // namespace

void sampleSkinPoses(const Skeleton& skeleton, std::vector<glm::mat4>* skins,
                     std::vector<std::pair<size_t, float>>* poseTimes)
{
    skins->clear();
    if (poseTimes)
        poseTimes->clear();
    const size_t nj = skeleton.skin.joints.size();
    if (skeleton.animations.empty() || nj == 0 || skeleton.order.size() != skeleton.nodes.size())
        return;
    // Evenly spaced times of every animation, between its ends (the bake
    // measures at the ends and at ninths).
    std::vector<std::pair<size_t, float>> times;
    // At most 64 MB of skin matrices (a skin of 65,535 joints takes 16 poses).
    const size_t most = std::min(kMaxPoses, std::max<size_t>(1, (size_t(64) << 20) / (sizeof(glm::mat4) * nj)));
    const size_t perAnimation =
        std::max<size_t>(1, std::min(kTimesPerAnimation, most / skeleton.animations.size()));
    for (size_t a = 0; a < skeleton.animations.size(); ++a)
        for (size_t i = 0; i < perAnimation; ++i) {
            const Animation& an = skeleton.animations[a];
            times.push_back({a, an.start + (an.end - an.start) * (float(i) + 0.5f) / float(perAnimation)});
        }
    if (times.size() > most) {  // many animations: every one, fewer times
        std::vector<std::pair<size_t, float>> kept;
        for (size_t i = 0; i < most; ++i)
            kept.push_back(times[i * times.size() / most]);
        times.swap(kept);
    }
    skins->resize(times.size() * nj);
    std::vector<glm::mat4> world(skeleton.nodes.size());
    std::vector<NodeTransform> local(skeleton.nodes.size());
    for (size_t q = 0; q < times.size(); ++q) {
        sampleAnimation(local.data(), skeleton, &skeleton.animations[times[q].first], times[q].second);
        computeWorldMatrices(world.data(), skeleton, local.data());
        computeSkinMatrices(skins->data() + q * nj, skeleton, world.data());
    }
    if (poseTimes)
        *poseTimes = std::move(times);
}

void skinPositions(const glm::vec3* positions, size_t count, const VertexWeights& weights,
                   const std::vector<glm::mat4>& skins, size_t jointCount, std::vector<glm::vec3>* out, int threads)
{
    const size_t poses = jointCount ? skins.size() / jointCount : 0;
    out->assign(poses * count, glm::vec3(0.0f));
    parallelFor(poses, threads, [&](size_t begin, size_t end) {
        for (size_t q = begin; q < end; ++q)
            skinLinear(out->data() + q * count, positions, count, weights, skins.data() + q * jointCount);
    });
}

Status fitSkinWeights(const Plan& plan, const ControlMesh& cage, const TriangleMesh& high, const TriangleIndex& index,
                      const VertexWeights& highWeights, const Skeleton& skeleton, VertexWeights* weights,
                      SkinFitReport* report, int threads, SkinShells shells)
{
    if (!shells.cageVertex)
        shells.highFace = nullptr;
    const size_t nc = cage.positions.size(), nj = skeleton.skin.joints.size();
    const int most = weights ? weights->influences : 0;
    if (!weights || most <= 0 || weights->weights.size() != nc * size_t(most) ||
        weights->joints.size() != weights->weights.size() || plan.controlVertexCount() != nc ||
        highWeights.influences <= 0 ||
        highWeights.weights.size() != high.positions.size() * size_t(highWeights.influences) ||
        highWeights.joints.size() != highWeights.weights.size() || skeleton.skin.inverseBindMatrices.size() != nj ||
        skeleton.order.size() != skeleton.nodes.size())
        return Status(StatusCode::InvalidArgument,
                      "fitSkinWeights: the cage, its weights, the capture's or the skeleton do not match");
    SkinFitReport rep;
    if (report)
        *report = rep;
    if (skeleton.animations.empty() || nj == 0 || nc == 0)
        return Status::ok();
    for (size_t i = 0; i < weights->joints.size(); ++i)
        if (weights->joints[i] >= nj)
            return Status(StatusCode::InvalidArgument, "fitSkinWeights: a cage weight names joint " +
                                                           std::to_string(weights->joints[i]) + " of " +
                                                           std::to_string(nj));
    for (size_t i = 0; i < highWeights.joints.size(); ++i)
        if (highWeights.weights[i] > 0.0f && highWeights.joints[i] >= nj)
            return Status(StatusCode::InvalidArgument, "fitSkinWeights: a capture weight names joint " +
                                                           std::to_string(highWeights.joints[i]) + " of " +
                                                           std::to_string(nj));

    std::vector<glm::mat4> skins;
    sampleSkinPoses(skeleton, &skins);
    const size_t P = skins.size() / nj;

    // The points: the layered surface at rest (displaced, where the
    // capture's weights are read) and its base b = sum_k a_k c_k.
    const size_t np = plan.refinedVertexCount();
    std::vector<glm::vec3> normals(nc), displaced(np);
    computeControlNormals(normals.data(), cage.positions.data(), nc, cage.triangles.data(), cage.faceCount());
    if (Status st = plan.evaluate(displaced.data(), nullptr, 0, np, cage.positions.data(), normals.data(), nc); !st)
        return st;
    Plan::FlatStencils stencils;
    plan.flattenStencils(&stencils);
    const size_t wpe = size_t(stencils.weightsPerEntry);
    auto stencilWeight = [&](size_t e) { return stencils.weights[e * wpe]; };
    // The capture's weights at each point's nearest capture point (a point
    // without one is left out of the fit).
    const size_t hk = 3 * size_t(highWeights.influences);
    std::vector<uint16_t> pointJoint(np * hk, 0);
    std::vector<float> pointWeight(np * hk, 0.0f);
    std::vector<uint8_t> used(np, 0);
    // And where that point is: its triangle and barycentrics, and the
    // point's base from it (the capture moves its triangle's corners each
    // by its own blend of joints, and the point between them).
    std::vector<uint32_t> pointFace(np, 0);
    std::vector<glm::vec3> pointBary(np, glm::vec3(0.0f)), pointOffset(np, glm::vec3(0.0f));
    parallelFor(np, threads, [&](size_t begin, size_t end) {
        JointWeights sum;
        for (size_t p = begin; p < end; ++p) {
            uint32_t face = 0;
            double b1 = 0.0, b2 = 0.0;
            // A point's piece: its stencil's control vertices' (refinement
            // never joins two pieces).
            const uint32_t piece = shells.cageVertex && stencils.offsets[p] < stencils.offsets[p + 1]
                                       ? shells.cageVertex[stencils.indices[stencils.offsets[p]]]
                                       : 0;
            if (stencils.offsets[p] == stencils.offsets[p + 1] || !std::isfinite(displaced[p].x) ||
                nearestOfPiece(index, shells, piece, glm::dvec3(displaced[p]), &face, &b1, &b2) < 0.0 ||
                face >= high.faceCount())
                continue;
            captureWeightsAt(&sum, high, highWeights, face, b1, b2);
            double total = 0.0;
            for (const auto& e : sum)
                total += e.second;
            if (!(total > 0.0))
                continue;
            for (size_t i = 0; i < sum.size() && i < hk; ++i) {
                pointJoint[p * hk + i] = sum[i].first;
                pointWeight[p * hk + i] = float(sum[i].second / total);
            }
            used[p] = 1;
            pointFace[p] = face;
            pointBary[p] = glm::vec3(float(1.0 - b1 - b2), float(b1), float(b2));
            glm::vec3 base(0.0f), x(0.0f);
            for (uint32_t e = stencils.offsets[p]; e < stencils.offsets[p + 1]; ++e)
                base += stencilWeight(e) * cage.positions[stencils.indices[e]];
            for (int c = 0; c < 3; ++c)
                x += pointBary[p][c] * high.positions[high.triangles[3 * size_t(face) + size_t(c)]];
            pointOffset[p] = base - x;
        }
    });
    // Each cage vertex's points and stencil weights.
    std::vector<uint32_t> first(nc + 1, 0), vertexPoint;
    std::vector<float> vertexWeight;
    for (size_t p = 0; p < np; ++p)
        if (used[p])
            for (uint32_t e = stencils.offsets[p]; e < stencils.offsets[p + 1]; ++e)
                if (stencilWeight(e) != 0.0f)
                    ++first[stencils.indices[e] + 1];
    for (size_t k = 0; k < nc; ++k)
        first[k + 1] += first[k];
    vertexPoint.resize(first[nc]);
    vertexWeight.resize(first[nc]);
    {
        std::vector<uint32_t> fill(first.begin(), first.end() - 1);
        for (size_t p = 0; p < np; ++p)
            if (used[p])
                for (uint32_t e = stencils.offsets[p]; e < stencils.offsets[p + 1]; ++e)
                    if (stencilWeight(e) != 0.0f) {
                        const uint32_t at = fill[stencils.indices[e]]++;
                        vertexPoint[at] = uint32_t(p);
                        vertexWeight[at] = stencilWeight(e);
                    }
    }

    // The residuals, pose-major: where the cage moves each point less where
    // the capture moves it.  The capture's point moves as its triangle's
    // corners do, each by its own blend of joints (not by the blended
    // weights, which differ where a large triangle spans a joint); the
    // point's offset from it is carried by the blend at the point.
    const size_t hi = size_t(highWeights.influences);
    std::vector<glm::vec3> posedCage, residual(P * np, glm::vec3(0.0f));
    skinPositions(cage.positions.data(), nc, *weights, skins, nj, &posedCage, threads);
    parallelFor(np, threads, [&](size_t begin, size_t end) {
        for (size_t p = begin; p < end; ++p) {
            if (!used[p])
                continue;
            for (size_t q = 0; q < P; ++q) {
                glm::vec3 r(0.0f);
                for (uint32_t e = stencils.offsets[p]; e < stencils.offsets[p + 1]; ++e)
                    r += stencilWeight(e) * posedCage[q * nc + stencils.indices[e]];
                for (size_t c = 0; c < 3; ++c) {
                    const size_t hv = high.triangles[3 * size_t(pointFace[p]) + c];
                    const glm::vec3 at = high.positions[hv] + pointOffset[p];
                    float total = 0.0f;
                    glm::vec3 moved(0.0f);
                    for (size_t i = 0; i < hi; ++i) {
                        const float wi = highWeights.weights[hv * hi + i];
                        if (wi > 0.0f) {
                            moved += wi * transformPoint(skins[q * nj + highWeights.joints[hv * hi + i]], at);
                            total += wi;
                        }
                    }
                    // A corner that weighs nothing stays where it is.
                    r -= pointBary[p][int(c)] * (total > 0.0f ? moved / total : at);
                }
                residual[q * np + p] = r;
            }
        }
    });
    auto squaredSum = [&] {
        double s = 0.0;
        for (const glm::vec3& r : residual)
            s += double(glm::dot(r, r));
        return s;
    };
    const size_t points = size_t(std::count(used.begin(), used.end(), uint8_t(1)));
    rep.poses = P;
    rep.points = points;
    const double count = double(std::max<size_t>(1, P * points));
    double total = squaredSum();
    rep.before = rep.after = std::sqrt(total / count);

    // Each cage vertex's candidates: its own joints, then the joints its
    // points' capture weights name, by their weight summed over its points.
    std::vector<uint16_t> candidates(nc * kMaxCandidates, 0);
    std::vector<uint8_t> candidateCount(nc, 0);
    std::vector<double> given(nc * kMaxCandidates, 0.0), current(nc * kMaxCandidates, 0.0);
    parallelFor(nc, threads, [&](size_t begin, size_t end) {
        std::vector<double> mass(nj, 0.0);
        std::vector<uint16_t> named;
        for (size_t k = begin; k < end; ++k) {
            named.clear();
            for (uint32_t e = first[k]; e < first[k + 1]; ++e) {
                const size_t p = vertexPoint[e];
                for (size_t i = 0; i < hk && pointWeight[p * hk + i] > 0.0f; ++i) {
                    const uint16_t j = pointJoint[p * hk + i];
                    if (mass[j] == 0.0)
                        named.push_back(j);
                    mass[j] += double(vertexWeight[e]) * double(pointWeight[p * hk + i]);
                }
            }
            uint16_t* c = candidates.data() + k * kMaxCandidates;
            int n = 0;
            for (int i = 0; i < most; ++i) {
                const float w = weights->weights[k * size_t(most) + size_t(i)];
                if (w > 0.0f && n < kMaxCandidates) {
                    c[n] = weights->joints[k * size_t(most) + size_t(i)];
                    given[k * kMaxCandidates + size_t(n)] = double(w);
                    ++n;
                }
            }
            std::sort(named.begin(), named.end(), [&](uint16_t a, uint16_t b) {
                return mass[a] != mass[b] ? mass[a] > mass[b] : a < b;
            });
            for (uint16_t j : named)
                if (n < kMaxCandidates && std::find(c, c + n, j) == c + n)
                    c[n++] = j;
            for (uint16_t j : named)
                mass[j] = 0.0;
            candidateCount[k] = uint8_t(n);
        }
    });
    current = given;

    // Gauss-Seidel over the cage's vertices: each one's weights minimise
    // the sum with every other vertex's held.
    std::vector<glm::dvec3> U(P * kMaxCandidates), e(P);
    for (int sweep = 0; sweep < kMaxSweeps && total > 0.0; ++sweep) {
        for (size_t k = 0; k < nc; ++k) {
            const int m = candidateCount[k];
            if (m < 2 || first[k] == first[k + 1])
                continue;
            const uint16_t* c = candidates.data() + k * kMaxCandidates;
            double* w = current.data() + k * kMaxCandidates;
            const double* w0 = given.data() + k * kMaxCandidates;
            double alpha = 0.0;
            for (uint32_t x = first[k]; x < first[k + 1]; ++x)
                alpha += double(vertexWeight[x]) * double(vertexWeight[x]);
            // U: each candidate's motion of c_k; e: the residual its
            // points would have without c_k.
            double G[kMaxCandidates * kMaxCandidates] = {}, h[kMaxCandidates] = {}, spread = 0.0, scale = 0.0;
            for (size_t q = 0; q < P; ++q) {
                glm::dvec3 sum(0.0), mean(0.0), own(0.0);
                for (uint32_t x = first[k]; x < first[k + 1]; ++x)
                    sum += double(vertexWeight[x]) * glm::dvec3(residual[q * np + vertexPoint[x]]);
                for (int i = 0; i < m; ++i) {
                    U[q * kMaxCandidates + size_t(i)] =
                        glm::dvec3(transformPoint(skins[q * nj + c[i]], cage.positions[k]));
                    own += w[i] * U[q * kMaxCandidates + size_t(i)];
                    mean += U[q * kMaxCandidates + size_t(i)] / double(m);
                }
                e[q] = sum - alpha * own;
                for (int i = 0; i < m; ++i) {
                    const glm::dvec3& ui = U[q * kMaxCandidates + size_t(i)];
                    for (int j = 0; j < m; ++j)
                        G[i * m + j] += glm::dot(ui, U[q * kMaxCandidates + size_t(j)]);
                    h[i] += glm::dot(ui, e[q]);
                    spread += glm::dot(ui - mean, ui - mean);
                    scale += glm::dot(ui, ui);
                }
            }
            // Drawn towards the given weights by a thousandth of how far
            // the candidates' motions differ (the part the data decides).
            const double mu = alpha * (kPull * spread + 1e-12 * scale) / double(m);
            if (!(mu > 0.0))
                continue;
            double A[kMaxCandidates * kMaxCandidates], g[kMaxCandidates], next[kMaxCandidates];
            for (int i = 0; i < m; ++i) {
                for (int j = 0; j < m; ++j)
                    A[i * m + j] = alpha * G[i * m + j] + (i == j ? mu : 0.0);
                g[i] = h[i] - mu * w0[i];
            }
            if (!solveWeights(A, g, m, most, next) || !(objective(A, g, m, next) < objective(A, g, m, w)))
                continue;
            for (size_t q = 0; q < P; ++q) {
                glm::dvec3 d(0.0);
                for (int i = 0; i < m; ++i)
                    d += (next[i] - w[i]) * U[q * kMaxCandidates + size_t(i)];
                const glm::vec3 df(d);
                for (uint32_t x = first[k]; x < first[k + 1]; ++x)
                    residual[q * np + vertexPoint[x]] += vertexWeight[x] * df;
            }
            std::copy(next, next + m, w);
        }
        const double now = squaredSum();
        const bool settled = now > kSettled * total;
        total = now;
        if (settled)
            break;
    }
    rep.after = std::sqrt(total / count);

    // The weights, strongest first in each vertex's slots.
    JointWeights fitted;
    for (size_t k = 0; k < nc; ++k) {
        fitted.clear();
        for (int i = 0; i < candidateCount[k]; ++i)
            if (current[k * kMaxCandidates + size_t(i)] > 0.0)
                fitted.push_back({candidates[k * kMaxCandidates + size_t(i)], current[k * kMaxCandidates + size_t(i)]});
        writeStrongest(&fitted, size_t(most), &weights->joints[k * size_t(most)], &weights->weights[k * size_t(most)]);
    }
    if (report)
        *report = rep;
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
