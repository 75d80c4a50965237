// Morton-order BVH (spatial index for normal volumes and nearest-point queries).
#include "bvh.h"

#include "parallel.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>

namespace strata {
namespace baker {

void Box::extend(const glm::vec3& p)
{
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
}

void Box::extend(const Box& b)
{
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
}

namespace {

// Spreads the low 10 bits of v three bits apart (bit i moves to bit 3i).
uint32_t spreadBits(uint32_t v)
{
    v &= 0x3ff;
    v = (v | v << 16) & 0x030000ff;
    v = (v | v << 8) & 0x0300f00f;
    v = (v | v << 4) & 0x030c30c3;
    v = (v | v << 2) & 0x09249249;
    return v;
}

}  // namespace

void Bvh::build(const std::vector<Box>& boxes, int threads)
{
    nodes_.clear();
    items_.resize(boxes.size());
    if (boxes.empty())
        return;
    // Morton codes of the box centres (10 bits an axis over the centres'
    // bounds) above each item's number, sorted on the code by a two-pass LSD
    // radix sort that keeps equal codes in item order: O(n), where a median
    // split re-partitions every level.
    const size_t n = boxes.size();
    Box all;
    for (const Box& b : boxes)
        all.extend(0.5f * (b.lo + b.hi));
    const glm::vec3 ext = all.hi - all.lo;
    const float extent = std::max({ext.x, ext.y, ext.z});
    const float scale = extent > 0.0f ? 1023.0f / extent : 0.0f;
    std::vector<uint64_t> key(n), keyTmp(n);
    parallelFor(n, threads, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) {
            const glm::vec3 c = (0.5f * (boxes[i].lo + boxes[i].hi) - all.lo) * scale;
            uint32_t q[3];
            for (int a = 0; a < 3; ++a)
                q[a] = uint32_t(std::min(1023.0f, std::max(0.0f, c[a])));
            const uint32_t code = spreadBits(q[0]) << 2 | spreadBits(q[1]) << 1 | spreadBits(q[2]);
            key[i] = uint64_t(code) << 32 | uint64_t(i);
        }
    });
    for (int shift = 32; shift < 62; shift += 15) {
        std::vector<uint32_t> count(32769, 0);
        for (size_t i = 0; i < n; ++i)
            ++count[((key[i] >> shift) & 0x7fff) + 1];
        for (int d = 0; d < 32768; ++d)
            count[size_t(d) + 1] += count[size_t(d)];
        for (size_t i = 0; i < n; ++i)
            keyTmp[count[(key[i] >> shift) & 0x7fff]++] = key[i];
        key.swap(keyTmp);
    }
    std::vector<uint64_t>().swap(keyTmp);
    for (size_t i = 0; i < n; ++i)
        items_[i] = uint32_t(key[i]);
    auto code = [&](uint32_t i) { return uint32_t(key[i] >> 32); };

    // Top down over the sorted codes: a range splits where its highest
    // differing bit turns on (a spatial midpoint, axes in turn), at its middle
    // when its codes are equal or the tree is already deep (the query stacks
    // hold 64 nodes); leaves hold at most four items.  Children follow their
    // parent in the node array.
    struct Range {
        uint32_t node, first, count, depth;
    };
    nodes_.reserve(n / 2 + 1);
    nodes_.push_back({});
    std::vector<Range> stack{{0, 0, uint32_t(n), 0}};
    while (!stack.empty()) {
        const Range r = stack.back();
        stack.pop_back();
        if (r.count <= 4) {
            nodes_[r.node].first = r.first;
            nodes_[r.node].count = r.count;
            continue;
        }
        const uint32_t last = r.first + r.count - 1;
        uint32_t mid = r.first + r.count / 2;
        const uint32_t diff = code(r.first) ^ code(last);
        if (diff != 0 && r.depth < 32) {
            int bit = 31;
            while (!((diff >> bit) & 1))
                --bit;
            // The first code of the range with that bit set.
            uint32_t lo = r.first + 1, hi = last;
            while (lo < hi) {
                const uint32_t m = lo + (hi - lo) / 2;
                if ((code(m) >> bit) & 1)
                    hi = m;
                else
                    lo = m + 1;
            }
            mid = lo;
        }
        const uint32_t l = uint32_t(nodes_.size()), rt = l + 1;
        nodes_.push_back({});
        nodes_.push_back({});
        nodes_[r.node].first = l;
        nodes_[r.node].right = rt;
        nodes_[r.node].count = 0;
        stack.push_back({rt, mid, last + 1 - mid, r.depth + 1});
        stack.push_back({l, r.first, mid - r.first, r.depth + 1});
    }
    itemBoxes_.resize(n);
    parallelFor(n, threads, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i)
            itemBoxes_[i] = boxes[items_[i]];
    });
    // Children always come after their parent: fill boxes in reverse order.
    for (size_t i = nodes_.size(); i-- > 0;) {
        Node& node = nodes_[i];
        node.box = Box();
        if (node.count > 0) {
            for (uint32_t k = 0; k < node.count; ++k)
                node.box.extend(itemBoxes_[node.first + k]);
        } else {
            node.box.extend(nodes_[node.first].box);
            node.box.extend(nodes_[node.right].box);
        }
    }
}

glm::dvec3 closestPointOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c,
                                  double* bary1, double* bary2)
{
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        *bary1 = *bary2 = 0.0;
        return a;
    }
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        *bary1 = 1.0;
        *bary2 = 0.0;
        return b;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        const double v = d1 / (d1 - d3);
        *bary1 = v;
        *bary2 = 0.0;
        return a + v * ab;
    }
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        *bary1 = 0.0;
        *bary2 = 1.0;
        return c;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        const double w = d2 / (d2 - d6);
        *bary1 = 0.0;
        *bary2 = w;
        return a + w * ac;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        *bary1 = 1.0 - w;
        *bary2 = w;
        return b + w * (c - b);
    }
    const double denom = 1.0 / (va + vb + vc);
    const double v = vb * denom, w = vc * denom;
    *bary1 = v;
    *bary2 = w;
    return a + ab * v + ac * w;
}

}  // namespace baker
}  // namespace strata
