// A render-ready frame on several threads (frame.h).
#include "strata/frame.h"

#include "strata/normals.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <thread>

namespace strata {

FrameEvaluator::FrameEvaluator(const Plan& plan) : plan_(plan) {}

void FrameEvaluator::buildFaceTable()
{
    if (!offsets_.empty())
        return;
    const std::vector<uint32_t>& tri = plan_.refinedTriangles();
    const size_t nv = plan_.refinedVertexCount(), nf = plan_.refinedFaceCount();
    buildVertexFaces(&offsets_, &faces_, tri.data(), nf, nv);  // ascending: the scatter's order
    faceNormals_.resize(nf);
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
    Status st = plan_.evaluate(positions, nullptr, 0, 0, d, controlPositions, controlNormals, controlCount);
    if (!st)
        return st;
    if (!positions)
        return Status(StatusCode::InvalidArgument, "FrameEvaluator: null positions");
    threads = std::max(1, std::min(threads, 64));
    if (threads == 1 || nv < 4096) {
        st = plan_.evaluate(positions, nullptr, 0, nv, d, controlPositions, controlNormals, controlCount);
        if (st && normals)
            plan_.computeShadingNormals(normals, positions);
        return st;
    }
    if (normals)
        buildFaceTable();
    auto run = [threads](size_t n, const auto& body) {
        std::vector<std::thread> pool;
        pool.reserve(size_t(threads) - 1);
        for (int t = 1; t < threads; ++t)
            pool.emplace_back([&body, t, n, threads] {
                body(n * size_t(t) / size_t(threads), n * size_t(t + 1) / size_t(threads));
            });
        body(size_t(0), n / size_t(threads));
        for (std::thread& th : pool)
            th.join();
    };
    run(nv, [&](size_t b, size_t e) {
        plan_.evaluate(positions + b, nullptr, b, e, d, controlPositions, controlNormals, controlCount);
    });
    if (normals) {
        run(faceNormals_.size(), [&](size_t b, size_t e) { faceNormals(positions, b, e); });
        run(nv, [&](size_t b, size_t e) { vertexNormals(normals, b, e); });
    }
    return Status::ok();
}

size_t FrameEvaluator::bytes() const
{
    return offsets_.capacity() * 4 + faces_.capacity() * 4 + faceNormals_.capacity() * sizeof(glm::vec3);
}

}  // namespace strata
