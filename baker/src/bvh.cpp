// Median-split BVH (spatial index for normal volumes and nearest-point queries).
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

bool Box::contains(const glm::vec3& p) const
{
    return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
}

float Box::distance2(const glm::vec3& p) const
{
    const glm::vec3 d = glm::max(glm::max(lo - p, p - hi), glm::vec3(0.0f));
    return glm::dot(d, d);
}

struct Bvh::SplitTask {
    uint32_t node, first, count;
    Box centres;
};

// Splits one task: a leaf at or below four items (or when the centres
// coincide), else two children at the median centre along the longest axis
// of the node's centre bounds.  Children's centre bounds are the parent's
// cut at the median, so nothing is rescanned.  The tree depends only on the
// items, never on the order tasks run in or on which array holds a node.
void Bvh::split(std::vector<Node>* nodes, const SplitTask& t, const std::vector<glm::vec3>& centre,
                std::vector<SplitTask>* out)
{
    const glm::vec3 ext = t.centres.hi - t.centres.lo;
    if (t.count <= 4 || (ext.x <= 0.0f && ext.y <= 0.0f && ext.z <= 0.0f)) {
        (*nodes)[t.node].first = t.first;
        (*nodes)[t.node].count = t.count;
        return;
    }
    const int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
    const uint32_t mid = t.first + t.count / 2;
    std::nth_element(items_.begin() + t.first, items_.begin() + mid, items_.begin() + t.first + t.count,
                     [&](uint32_t a, uint32_t b) { return centre[a][axis] < centre[b][axis]; });
    const float cut = centre[items_[mid]][axis];
    Box left = t.centres, right = t.centres;
    left.hi[axis] = cut;
    right.lo[axis] = cut;
    const uint32_t l = uint32_t(nodes->size()), r = l + 1;
    nodes->push_back({});
    nodes->push_back({});
    (*nodes)[t.node].first = l;
    (*nodes)[t.node].right = r;
    (*nodes)[t.node].count = 0;
    out->push_back({l, t.first, mid - t.first, left});
    out->push_back({r, mid, t.first + t.count - mid, right});
}

void Bvh::build(const std::vector<Box>& boxes, int threads)
{
    nodes_.clear();
    items_.resize(boxes.size());
    if (boxes.empty())
        return;
    std::vector<glm::vec3> centre(boxes.size());
    Box all;
    for (size_t i = 0; i < boxes.size(); ++i) {
        items_[i] = uint32_t(i);
        centre[i] = 0.5f * (boxes[i].lo + boxes[i].hi);
        all.extend(centre[i]);
    }
    nodes_.reserve(boxes.size() / 2 + 1);
    nodes_.push_back({});
    // The top levels breadth first on this thread, until there is a subtree
    // per thread and more; then each subtree in its own node array, on the
    // threads, appended in task order (child numbers offset).
    std::vector<SplitTask> tasks{{0, 0, uint32_t(boxes.size()), all}}, next;
    const size_t subtrees = threads > 1 && boxes.size() >= 65536 ? size_t(4 * threads) : 0;
    while (!tasks.empty() && tasks.size() < subtrees) {
        next.clear();
        for (const SplitTask& t : tasks)
            split(&nodes_, t, centre, &next);
        tasks.swap(next);
    }
    if (!subtrees) {  // one thread: depth first, in place
        while (!tasks.empty()) {
            const SplitTask t = tasks.back();
            tasks.pop_back();
            split(&nodes_, t, centre, &tasks);
        }
    }
    std::vector<std::vector<Node>> local(tasks.size());
    parallelChunks(tasks.size(), subtrees ? threads : 1, [&](int, size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            std::vector<Node>& nodes = local[i];
            nodes.push_back({});  // the subtree's root, stands for tasks[i].node
            std::vector<SplitTask> stack{{0, tasks[i].first, tasks[i].count, tasks[i].centres}};
            while (!stack.empty()) {
                const SplitTask t = stack.back();
                stack.pop_back();
                split(&nodes, t, centre, &stack);
            }
        }
    });
    for (size_t i = 0; i < tasks.size(); ++i) {
        const uint32_t base = uint32_t(nodes_.size()) - 1;  // local node j > 0 lands at base + j
        for (size_t j = 0; j < local[i].size(); ++j) {
            Node n = local[i][j];
            if (n.count == 0) {
                n.first += base;
                n.right += base;
            }
            if (j == 0)
                nodes_[tasks[i].node] = n;
            else
                nodes_.push_back(n);
        }
        std::vector<Node>().swap(local[i]);  // into the reserved nodes_: peak memory stays one tree
    }
    // Children always come after their parent: fill boxes in reverse order.
    for (size_t i = nodes_.size(); i-- > 0;) {
        Node& n = nodes_[i];
        n.box = Box();
        if (n.count > 0) {
            for (uint32_t k = 0; k < n.count; ++k)
                n.box.extend(boxes[items_[n.first + k]]);
        } else {
            n.box.extend(nodes_[n.first].box);
            n.box.extend(nodes_[n.right].box);
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
