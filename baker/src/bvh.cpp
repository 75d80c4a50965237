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
    itemCount_ = boxes.size();
    if (boxes.empty())
        return;
    std::vector<uint32_t> items(boxes.size());
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
        items[i] = uint32_t(key[i]);
    auto code = [&](uint32_t i) { return uint32_t(key[i] >> 32); };

    // Top down over the sorted codes: a range splits where its highest
    // differing bit turns on (a spatial midpoint, axes in turn), at its middle
    // when its codes are equal or the tree is already deep (the query stacks
    // hold 64 nodes); leaves hold at most four items.  Children follow their
    // parent in the node array.
    struct Range {
        uint32_t node, first, count, depth;
    };
    struct BinaryNode {
        Box box;
        uint32_t first;  // leaf: first index into items; inner: left child
        uint32_t count;  // leaf: item count; inner: 0
        uint32_t right;  // inner: right child
    };
    std::vector<BinaryNode> bin;
    bin.reserve(n / 2 + 1);
    bin.push_back({});
    std::vector<Range> stack{{0, 0, uint32_t(n), 0}};
    while (!stack.empty()) {
        const Range r = stack.back();
        stack.pop_back();
        if (r.count <= 4) {
            bin[r.node].first = r.first;
            bin[r.node].count = r.count;
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
        const uint32_t l = uint32_t(bin.size()), rt = l + 1;
        bin.push_back({});
        bin.push_back({});
        bin[r.node].first = l;
        bin[r.node].right = rt;
        bin[r.node].count = 0;
        stack.push_back({rt, mid, last + 1 - mid, r.depth + 1});
        stack.push_back({l, r.first, mid - r.first, r.depth + 1});
    }
    // Children always come after their parent: fill boxes in reverse order.
    for (size_t i = bin.size(); i-- > 0;) {
        BinaryNode& node = bin[i];
        node.box = Box();
        if (node.count > 0) {
            for (uint32_t k = 0; k < node.count; ++k)
                node.box.extend(boxes[items[node.first + k]]);
        } else {
            node.box.extend(bin[node.first].box);
            node.box.extend(bin[node.right].box);
        }
    }

    // Four-wide: each node takes its binary node's children, then opens the
    // slot with the largest box (an inner node into its two children, a leaf
    // into its items) while the result fits in four slots.  What is left
    // closed becomes a child node.  A slot is a binary inner node, a binary
    // leaf or an item; each wide node is built from one binary node.
    struct Slot {
        uint32_t index;  // binary node, or item when isItem
        bool isItem;
        Box box;
    };
    auto area = [](const Box& b) {
        const glm::vec3 e = glm::max(b.hi - b.lo, glm::vec3(0.0f));
        return e.x * e.y + e.y * e.z + e.z * e.x;
    };
    auto opensTo = [&](const Slot& s) { return s.isItem ? 1u : bin[s.index].count > 0 ? bin[s.index].count : 2u; };
    nodes_.reserve(n / 2 + 1);
    nodes_.push_back({});
    struct Pending {
        uint32_t wide, binary;
    };
    std::vector<Pending> todo{{0, 0}};
    while (!todo.empty()) {
        const Pending job = todo.back();
        todo.pop_back();
        Slot slots[4];
        int count = 1;
        slots[0] = {job.binary, false, bin[job.binary].box};
        for (;;) {
            int open = -1;
            float bestArea = -1.0f;
            for (int k = 0; k < count; ++k)
                if (!slots[k].isItem && uint32_t(count) - 1 + opensTo(slots[k]) <= 4 && area(slots[k].box) > bestArea) {
                    bestArea = area(slots[k].box);
                    open = k;
                }
            if (open < 0)
                break;
            const BinaryNode& b = bin[slots[open].index];
            Slot opened[4];
            int m = 0;
            if (b.count > 0) {
                for (uint32_t k = 0; k < b.count; ++k)
                    opened[m++] = {items[b.first + k], true, boxes[items[b.first + k]]};
            } else {
                opened[m++] = {b.first, false, bin[b.first].box};
                opened[m++] = {b.right, false, bin[b.right].box};
            }
            // In place, keeping the order of the slots (and so of the items).
            Slot merged[4];
            int c = 0;
            for (int k = 0; k < count; ++k) {
                if (k != open) {
                    merged[c++] = slots[k];
                    continue;
                }
                for (int i = 0; i < m; ++i)
                    merged[c++] = opened[i];
            }
            count = c;
            std::copy(merged, merged + c, slots);
        }
        Node node;
        for (int k = 0; k < 4; ++k) {
            const Box b = k < count ? slots[k].box : Box();
            for (int a = 0; a < 3; ++a) {
                node.lo[a][k] = b.lo[a];
                node.hi[a][k] = b.hi[a];
            }
            if (k >= count) {
                node.slot[k] = kEmpty;
            } else if (slots[k].isItem) {
                node.slot[k] = kItem | slots[k].index;
            } else {
                node.slot[k] = uint32_t(nodes_.size());
                nodes_.push_back({});
                todo.push_back({node.slot[k], slots[k].index});
            }
        }
        nodes_[job.wide] = node;
    }
}

}  // namespace baker
}  // namespace strata
