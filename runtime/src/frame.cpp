// A render-ready frame on several threads (frame.h).
#include "strata/frame.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <thread>

namespace strata {

namespace {

// Runs body(begin, end) over [0, n) split into `threads` contiguous ranges,
// the last on the calling thread.
template <typename Body>
void splitRange(size_t n, int threads, const Body& body)
{
    const size_t t = size_t(std::max(1, std::min(threads, 64)));
    if (t == 1 || n < 4096) {
        body(size_t(0), n);
        return;
    }
    std::vector<std::thread> pool;
    pool.reserve(t - 1);
    for (size_t i = 0; i + 1 < t; ++i)
        pool.emplace_back([&body, i, n, t] { body(n * i / t, n * (i + 1) / t); });
    body(n * (t - 1) / t, n);
    for (std::thread& th : pool)
        th.join();
}

}  // namespace

FrameEvaluator::FrameEvaluator(const Plan& plan) : plan_(plan)
{
    const std::vector<uint32_t>& tri = plan.refinedTriangles();
    const size_t nv = plan.refinedVertexCount(), nf = plan.refinedFaceCount();
    offsets_.assign(nv + 1, 0);
    for (uint32_t v : tri)
        ++offsets_[v + 1];
    for (size_t v = 0; v < nv; ++v)
        offsets_[v + 1] += offsets_[v];
    faces_.resize(tri.size());
    std::vector<uint32_t> fill(offsets_.begin(), offsets_.end() - 1);
    for (size_t f = 0; f < nf; ++f)  // ascending faces per vertex: the scatter's order
        for (int k = 0; k < 3; ++k)
            faces_[fill[tri[3 * f + size_t(k)]]++] = uint32_t(f);
    faceNormals_.resize(nf);
}

void FrameEvaluator::faceNormals(const glm::vec3* p, size_t begin, size_t end)
{
    const uint32_t* tri = plan_.refinedTriangles().data();
    for (size_t f = begin; f < end; ++f) {
        const uint32_t a = tri[3 * f], b = tri[3 * f + 1], c = tri[3 * f + 2];
        faceNormals_[f] = glm::cross(p[b] - p[a], p[c] - p[a]);  // |cross| is twice the area
    }
}

void FrameEvaluator::vertexNormals(glm::vec3* dst, size_t begin, size_t end) const
{
    for (size_t v = begin; v < end; ++v) {
        glm::vec3 n(0.0f);
        for (uint32_t i = offsets_[v]; i < offsets_[v + 1]; ++i)
            n += faceNormals_[faces_[i]];
        const float len = glm::length(n);
        dst[v] = len > 0.0f ? n / len : glm::vec3(0.0f);
    }
}

Status FrameEvaluator::evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                                const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                                int threads)
{
    const size_t nv = plan_.refinedVertexCount();
    const float* d = displacements ? displacements : plan_.displacements().data();
    Status first = plan_.evaluate(positions, nullptr, 0, 0, d, controlPositions, controlNormals, controlCount);
    if (!first || !positions)
        return first ? Status(StatusCode::InvalidArgument, "FrameEvaluator: null positions") : first;
    splitRange(nv, threads, [&](size_t b, size_t e) {
        plan_.evaluate(positions + b, nullptr, b, e, d, controlPositions, controlNormals, controlCount);
    });
    if (!normals)
        return Status::ok();
    splitRange(faceNormals_.size(), threads, [&](size_t b, size_t e) { faceNormals(positions, b, e); });
    splitRange(nv, threads, [&](size_t b, size_t e) { vertexNormals(normals, b, e); });
    return Status::ok();
}

size_t FrameEvaluator::bytes() const
{
    return offsets_.capacity() * 4 + faces_.capacity() * 4 + faceNormals_.capacity() * sizeof(glm::vec3);
}

}  // namespace strata
