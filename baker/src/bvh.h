// Strata baker: a bounding-volume hierarchy over axis-aligned boxes, used as
// the spatial index of normal volumes (point containment) and of triangle
// meshes (nearest point).  Morton-order binary build collapsed into a
// four-wide tree (a node's four boxes tested as one vector), flat node
// array, iterative queries; const queries are thread-safe.
#pragma once

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace strata {
namespace baker {

struct Box {
    glm::vec3 lo{1e30f}, hi{-1e30f};
    void extend(const glm::vec3& p);
    void extend(const Box& b);
    bool contains(const glm::vec3& p) const
    {
        return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
    }
};

class Bvh {
public:
    /// Builds over items 0..boxes.size()-1 in Morton order of the box
    /// centres; `threads` share the code pass (the same tree for any count).
    void build(const std::vector<Box>& boxes, int threads = 1);

    /// Calls visit(item) for every item whose box contains p.
    template <typename Visit>
    void forEachContaining(const glm::vec3& p, Visit&& visit) const;

    /// Best-first search: distance2(item) returns the item's squared distance
    /// to the query; boxes farther than the best so far are pruned.  Returns
    /// the item with the smallest distance, ties going to the lowest index, so
    /// the answer does not depend on traversal order or on `hint` (an item to
    /// evaluate first, e.g. the previous query's answer, or -1).
    template <typename Distance2>
    int64_t nearest(const glm::vec3& p, float maxDistance2, Distance2&& distance2, float* bestDistance2,
                    int64_t hint = -1) const;

    /// Calls visit(item) for every item whose box meets the segment
    /// origin + t * dir, t in [t0, t1].
    template <typename Visit>
    void forEachOnSegment(const glm::vec3& origin, const glm::vec3& dir, float t0, float t1, Visit&& visit) const;

    bool empty() const { return nodes_.empty(); }

private:
    // Depth-first walk: visits the items whose box, and every ancestor's
    // box, passes `enter`.
    template <typename Enter, typename Visit>
    void walk(Enter&& enter, Visit&& visit) const;

    // The tree is four-wide: a node holds the boxes of its four slots as
    // structure of arrays, so one node (two cache lines) answers what two
    // levels of a binary tree did in four scattered loads, and the four box
    // distances are one vector computation.  A slot holds a child node, an
    // item (kItem set) or nothing (kEmpty, an inverted box no query meets).
    static constexpr uint32_t kItem = 0x80000000u, kEmpty = 0xffffffffu;
    struct Node {
        float lo[3][4], hi[3][4];
        uint32_t slot[4];
        Box box(int k) const
        {
            Box b;
            for (int a = 0; a < 3; ++a) {
                b.lo[a] = lo[a][k];
                b.hi[a] = hi[a][k];
            }
            return b;
        }
        /// Squared distance from p to each slot's box (0 inside).  The vector
        /// form rounds as the scalar one does without fused multiply-adds.
        void distance2(const glm::vec3& p, float out[4]) const
        {
#if defined(__SSE__)
            const __m128 zero = _mm_setzero_ps();
            __m128 sum = zero;
            for (int a = 0; a < 3; ++a) {
                const __m128 q = _mm_set1_ps(p[a]);
                const __m128 d = _mm_max_ps(_mm_max_ps(_mm_sub_ps(_mm_loadu_ps(lo[a]), q), _mm_sub_ps(q, _mm_loadu_ps(hi[a]))), zero);
                sum = a == 0 ? _mm_mul_ps(d, d) : _mm_add_ps(sum, _mm_mul_ps(d, d));
            }
            _mm_storeu_ps(out, sum);
#else
            for (int k = 0; k < 4; ++k) {
                float s = 0.0f;
                for (int a = 0; a < 3; ++a) {
                    const float d = std::max(std::max(lo[a][k] - p[a], p[a] - hi[a][k]), 0.0f);
                    s = a == 0 ? d * d : s + d * d;
                }
                out[k] = s;
            }
#endif
        }
    };
    std::vector<Node> nodes_;
    size_t itemCount_ = 0;
};

/// Closest point on triangle (a, b, c) to p (Ericson 5.1.5), in double.
/// Inline: the nearest-point walk calls it for every triangle it measures.
inline glm::dvec3 closestPointOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                         const glm::dvec3& c, double* bary1, double* bary2);

// ---- implementation of the templates ----

template <typename Enter, typename Visit>
void Bvh::walk(Enter&& enter, Visit&& visit) const
{
    if (nodes_.empty())
        return;
    uint32_t stack[256];  // up to three siblings wait per level: 3 x 64 levels + 1
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& n = nodes_[stack[--top]];
        for (int k = 0; k < 4; ++k) {
            const uint32_t s = n.slot[k];
            if (s == kEmpty || !enter(n.box(k)))
                continue;
            if (s & kItem)
                visit(s & ~kItem);
            else
                stack[top++] = s;
        }
    }
}

template <typename Visit>
void Bvh::forEachContaining(const glm::vec3& p, Visit&& visit) const
{
    walk([&](const Box& b) { return b.contains(p); }, visit);
}

template <typename Visit>
void Bvh::forEachOnSegment(const glm::vec3& origin, const glm::vec3& dir, float t0, float t1, Visit&& visit) const
{
    glm::vec3 inv;
    for (int a = 0; a < 3; ++a)
        inv[a] = dir[a] != 0.0f ? 1.0f / dir[a] : 3.0e38f;
    auto hits = [&](const Box& b) {
        float lo = t0, hi = t1;
        for (int a = 0; a < 3; ++a) {
            float ta = (b.lo[a] - origin[a]) * inv[a], tb = (b.hi[a] - origin[a]) * inv[a];
            if (dir[a] == 0.0f) {
                if (origin[a] < b.lo[a] || origin[a] > b.hi[a])
                    return false;
                continue;
            }
            if (ta > tb)
                std::swap(ta, tb);
            lo = ta > lo ? ta : lo;
            hi = tb < hi ? tb : hi;
            if (lo > hi)
                return false;
        }
        return true;
    };
    walk(hits, visit);
}

template <typename Distance2>
int64_t Bvh::nearest(const glm::vec3& p, float maxDistance2, Distance2&& distance2, float* bestDistance2,
                     int64_t hint) const
{
    int64_t best = -1;
    float bestD2 = maxDistance2;
    if (hint >= 0 && size_t(hint) < itemCount_) {
        const float d2 = distance2(uint32_t(hint));
        if (d2 <= bestD2) {
            bestD2 = d2;
            best = hint;
        }
    }
    if (!nodes_.empty()) {
        // Each node goes on the stack with its box's distance, measured
        // once (when its parent measured its slots); items are measured as
        // their node is, child nodes pushed farthest first.
        struct Entry {
            uint32_t node;
            float d2;
        } stack[256];  // as in walk()
        int top = 0;
        stack[top++] = {0, 0.0f};
        while (top > 0) {
            const Entry e = stack[--top];
            if (e.d2 > bestD2)
                continue;
            const Node& n = nodes_[e.node];
            float d[4];
            n.distance2(p, d);
            Entry children[4];
            int count = 0;
            for (int k = 0; k < 4; ++k) {
                const uint32_t s = n.slot[k];
                if (s == kEmpty || d[k] > bestD2)
                    continue;
                if (s & kItem) {
                    const uint32_t item = s & ~kItem;
                    if (int64_t(item) == hint)
                        continue;
                    const float d2 = distance2(item);
                    if (d2 < bestD2 || (d2 == bestD2 && (best < 0 || item < best))) {
                        bestD2 = d2;
                        best = item;
                    }
                } else {
                    // Insertion by distance, farthest first.
                    int i = count++;
                    for (; i > 0 && children[i - 1].d2 < d[k]; --i)
                        children[i] = children[i - 1];
                    children[i] = {s, d[k]};
                }
            }
            for (int i = 0; i < count; ++i)
                stack[top++] = children[i];
        }
    }
    *bestDistance2 = bestD2;
    return best;
}

inline glm::dvec3 closestPointOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                         const glm::dvec3& c, double* bary1, double* bary2)
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
