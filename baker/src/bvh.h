// Strata baker: a bounding-volume hierarchy over axis-aligned boxes, used as
// the spatial index of normal volumes (point containment) and of triangle
// meshes (nearest point).  Morton-order build, flat node array, iterative
// queries; const queries are thread-safe.
#pragma once

#include <glm/vec3.hpp>

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
    /// Squared distance from p to the box (0 inside).  Inline: the nearest-
    /// point walk calls it for every node and item box it meets (a quarter
    /// of a default scan bake's time when it was a call into bvh.cpp).
    float distance2(const glm::vec3& p) const
    {
        const float dx = std::max(std::max(lo.x - p.x, p.x - hi.x), 0.0f);
        const float dy = std::max(std::max(lo.y - p.y, p.y - hi.y), 0.0f);
        const float dz = std::max(std::max(lo.z - p.z, p.z - hi.z), 0.0f);
        return dx * dx + dy * dy + dz * dz;
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

    struct Node {
        Box box;
        uint32_t first;  // leaf: first index into items_; inner: left child
        uint32_t count;  // leaf: item count; inner: 0
        uint32_t right;  // inner: right child
    };
    std::vector<Node> nodes_;
    std::vector<uint32_t> items_;
    std::vector<Box> itemBoxes_;  // items_[i]'s box: leaves test their items before visiting them
};

/// Closest point on triangle (a, b, c) to p (Ericson 5.1.5), in double.
glm::dvec3 closestPointOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c,
                                  double* bary1, double* bary2);

// ---- implementation of the templates ----

template <typename Enter, typename Visit>
void Bvh::walk(Enter&& enter, Visit&& visit) const
{
    if (nodes_.empty())
        return;
    uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& n = nodes_[stack[--top]];
        if (!enter(n.box))
            continue;
        if (n.count > 0) {
            for (uint32_t i = 0; i < n.count; ++i)
                if (enter(itemBoxes_[n.first + i]))
                    visit(items_[n.first + i]);
        } else {
            stack[top++] = n.first;
            stack[top++] = n.right;
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
    if (hint >= 0 && size_t(hint) < items_.size()) {
        const float d2 = distance2(uint32_t(hint));
        if (d2 <= bestD2) {
            bestD2 = d2;
            best = hint;
        }
    }
    if (!nodes_.empty()) {
        // Each node goes on the stack with its box's distance, measured
        // once (when its parent ordered its children).
        struct Entry {
            uint32_t node;
            float d2;
        } stack[64];
        int top = 0;
        stack[top++] = {0, nodes_[0].box.distance2(p)};
        while (top > 0) {
            const Entry e = stack[--top];
            if (e.d2 > bestD2)
                continue;
            const Node& n = nodes_[e.node];
            if (n.count > 0) {
                for (uint32_t i = 0; i < n.count; ++i) {
                    const uint32_t item = items_[n.first + i];
                    if (int64_t(item) == hint || itemBoxes_[n.first + i].distance2(p) > bestD2)
                        continue;
                    const float d2 = distance2(item);
                    if (d2 < bestD2 || (d2 == bestD2 && (best < 0 || item < best))) {
                        bestD2 = d2;
                        best = item;
                    }
                }
            } else {
                // Visit the nearer child first.
                const float dl = nodes_[n.first].box.distance2(p), dr = nodes_[n.right].box.distance2(p);
                if (dl < dr) {
                    stack[top++] = {n.right, dr};
                    stack[top++] = {n.first, dl};
                } else {
                    stack[top++] = {n.first, dl};
                    stack[top++] = {n.right, dr};
                }
            }
        }
    }
    *bestDistance2 = bestD2;
    return best;
}

}  // namespace baker
}  // namespace strata
