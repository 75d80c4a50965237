// Skin weights onto an automatic cage: the nearest point on the capture,
// its triangle's corner weights blended by barycentrics.  A cage made by
// simplifying the capture lies on or near it everywhere, so the nearest
// point is the part of the body the cage vertex stands for.
#include "strata/baker/skin_transfer.h"

#include "parallel.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace strata {
namespace baker {

Status transferSkinWeights(const ControlMesh& cage, const TriangleMesh& high, const TriangleIndex& index,
                           const VertexWeights& highWeights, VertexWeights* out, int threads)
{
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
        if (index.nearest(glm::dvec3(cage.positions[v]), &face, &b1, &b2) < 0.0 || face >= high.faceCount())
            return false;
        const double bary[3] = {1.0 - b1 - b2, b1, b2};
        std::vector<std::pair<uint16_t, double>> sum;  // joint, weight
        for (int c = 0; c < 3; ++c) {
            const size_t hv = high.triangles[3 * size_t(face) + size_t(c)];
            for (int i = 0; i < k; ++i) {
                const float wi = highWeights.weights[hv * size_t(k) + size_t(i)];
                if (!(wi > 0.0f))
                    continue;
                const uint16_t j = highWeights.joints[hv * size_t(k) + size_t(i)];
                auto it = std::find_if(sum.begin(), sum.end(), [&](const auto& e) { return e.first == j; });
                if (it == sum.end())
                    sum.push_back({j, bary[c] * double(wi)});
                else
                    it->second += bary[c] * double(wi);
            }
        }
        std::sort(sum.begin(), sum.end(), [](const auto& x, const auto& y) {
            return x.second != y.second ? x.second > y.second : x.first < y.first;
        });
        if (sum.size() > size_t(k))
            sum.resize(size_t(k));
        double total = 0.0;
        for (const auto& e : sum)
            total += e.second;
        if (!(total > 0.0))
            return false;
        for (size_t i = 0; i < sum.size(); ++i) {
            w.joints[v * size_t(k) + i] = sum[i].first;
            w.weights[v * size_t(k) + i] = float(sum[i].second / total);
        }
        return true;
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

}  // namespace baker
}  // namespace strata
