// The chart atlas's packing: each chart's footprint (the texels its
// samples read, with gutters) placed lowest-top into a texel occupancy map
// at the largest common scale that fits, in several orders, then grown into
// the gaps; the UVs written from the placements.
#include "atlas_parts.h"

#include "cancel.h"
#include "parallel.h"
#include "strata/plane.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace strata {
namespace baker {

namespace {

// A chart's own scale: the common one, raised so that the chart spans at
// least kMinChartTexels along its length (a chart of a texel or two would
// be sampled from its gutter); and the stretch of its short side (charts
// lie with their long side along x) that brings that side to
// kMinChartTexels too.  Stretching only the short side keeps a sliver
// short: raising the whole scale made one sliver face of spot's cage a
// chart as long as a 128 map.
constexpr double kMinChartTexels = 6.0;
constexpr double kMaxStretch = 16.0;

void setChartScale(Chart* c, double scale)
{
    const double w = c->hi.x - c->lo.x, h = c->hi.y - c->lo.y;
    double s = scale;
    if (w > 0.0)
        s = std::min(std::max(s, kMinChartTexels / w), 64.0 * scale);
    c->scaleX = s;
    c->stretchY = h > 0.0 ? std::min(std::max(kMinChartTexels / (h * s), 1.0), kMaxStretch) : 1.0;
}

// Chart point in texels inside its footprint, in one of eight orientations:
// bit 2 mirrors it (a scalar map has no handedness), bits 0-1 turn it by
// quarters.
glm::dvec2 placed(const Chart& c, const glm::dvec2& p, double scale, int rotation, int gutter)
{
    glm::dvec2 q = (p - c.lo) * glm::dvec2(scale, scale * c.stretchY);
    const double w = (c.hi.x - c.lo.x) * scale, h = (c.hi.y - c.lo.y) * scale * c.stretchY;
    if (rotation & 4)
        q.x = w - q.x;
    const int turn = rotation & 3;
    const glm::dvec2 r = turn == 1 ? glm::dvec2(h - q.y, q.x)
                         : turn == 2 ? glm::dvec2(w - q.x, h - q.y)
                         : turn == 3 ? glm::dvec2(q.y, w - q.x)
                                     : q;
    return r + glm::dvec2(double(gutter) + 0.5);
}

// The chart's footprint at a scale and orientation: the texels a bilinear
// sample inside it can read, plus gutter - 1 rings (those whose closed
// square of half-side `gutter` about the centre meets one of its
// triangles), as runs of rows per column (the gaps between a hand's fingers
// stay free for other charts).  Footprints never overlap, so no texel a
// chart reads is another chart's.
struct Footprint {
    int width = 0, height = 0;
    std::vector<uint32_t> first;  // width + 1: each column's runs in [first[x], first[x + 1])
    std::vector<int> lo, hi;      // per run: lowest and highest row
};

// The rows y of the column of texel centres x = cx whose closed square of
// half-side r meets triangle t: the square meets it exactly when its centre's
// y lies within r of the triangle's y extent inside the vertical slab
// |x - cx| <= r, and that extent is reached at a corner inside the slab or
// where an edge crosses one of the slab's sides.  False when the slab misses
// the triangle.
bool slabRows(double cx, double r, const glm::dvec2 t[3], int* lo, int* hi)
{
    const double left = cx - r, right = cx + r;
    double a = 1e300, b = -1e300;
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 p = t[k], q = t[(k + 1) % 3];
        if (p.x >= left && p.x <= right) {
            a = std::min(a, p.y);
            b = std::max(b, p.y);
        }
        for (double side : {left, right})
            if ((p.x - side) * (q.x - side) < 0.0) {
                const double y = p.y + (q.y - p.y) * ((side - p.x) / (q.x - p.x));
                a = std::min(a, y);
                b = std::max(b, y);
            }
    }
    if (!(a <= b))
        return false;
    *lo = int(std::ceil(a - r - 0.5));
    *hi = int(std::floor(b + r - 0.5));
    return *lo <= *hi;
}

Footprint footprint(const Chart& c, const ControlMesh& mesh, const std::vector<int32_t>& local, double scale,
                    int rotation, int gutter, int size)
{
    const double w = (c.hi.x - c.lo.x) * scale, h = (c.hi.y - c.lo.y) * scale * c.stretchY;
    Footprint fp;
    // A chart wider or taller than the atlas fits nowhere: its size alone
    // says so, before a mask as large as the chart (a cage with one vertex
    // two billion units out makes a chart of billions of texels).
    const double fw = std::ceil(rotation & 1 ? h : w) + 2.0 * gutter + 1.0;
    const double fh = std::ceil(rotation & 1 ? w : h) + 2.0 * gutter + 1.0;
    if (!(fw <= double(size)) || !(fh <= double(size))) {
        fp.width = fp.height = size + 1;
        return fp;
    }
    fp.width = int(fw);
    fp.height = int(fh);
    std::vector<uint8_t> mask(size_t(fp.width) * size_t(fp.height), 0);  // column-major
    const double reach = double(gutter) + 0.5;
    for (uint32_t f : c.faces) {
        glm::dvec2 t[3];
        for (int k = 0; k < 3; ++k)
            t[k] = placed(c, c.points[size_t(local[mesh.triangles[3 * size_t(f) + size_t(k)]])], scale, rotation, gutter);
        const double minX = std::min({t[0].x, t[1].x, t[2].x}), maxX = std::max({t[0].x, t[1].x, t[2].x});
        const int x0 = std::max(0, int(std::floor(minX - reach)));
        const int x1 = std::min(fp.width - 1, int(std::ceil(maxX + reach)));
        const int y0 = std::max(0, int(std::floor(std::min({t[0].y, t[1].y, t[2].y}) - reach)));
        const int y1 = std::min(fp.height - 1, int(std::ceil(std::max({t[0].y, t[1].y, t[2].y}) + reach)));
        const double r = double(gutter);
        for (int x = x0; x <= x1; ++x) {
            int lo = 0, hi = -1;
            if (!slabRows(x + 0.5, r, t, &lo, &hi))
                continue;
            lo = std::max(lo, y0);
            hi = std::min(hi, y1);
            if (lo <= hi)
                std::memset(&mask[size_t(x) * size_t(fp.height) + size_t(lo)], 1, size_t(hi - lo + 1));
        }
    }
    fp.first.assign(size_t(fp.width) + 1, 0);
    for (int x = 0; x < fp.width; ++x) {
        fp.first[size_t(x)] = uint32_t(fp.lo.size());
        const uint8_t* col = &mask[size_t(x) * size_t(fp.height)];
        for (int y = 0; y < fp.height; ++y)
            if (col[y] && (y == 0 || !col[y - 1])) {
                int end = y;
                while (end + 1 < fp.height && col[end + 1])
                    ++end;
                fp.lo.push_back(y);
                fp.hi.push_back(end);
            }
    }
    fp.first[size_t(fp.width)] = uint32_t(fp.lo.size());
    return fp;
}

// Texel occupancy of the map, a bitset per column (bit y of column x: texel
// (x, y) is taken), so a chart can drop into a hole under an overhang that a
// skyline would have closed off.
class Occupancy {
public:
    explicit Occupancy(int size)
        : size_(size), words_(size_t(size + 63) / 64), bits_(size_t(size) * words_, 0),
          taken_(size_t(size) * size_t(size + 1), 0)
    {
    }

    // True when rows [from, from + length) of column x are all free: one
    // difference of the column's running count of taken rows.
    bool free(int x, int from, int length) const
    {
        const uint16_t* count = &taken_[size_t(x) * size_t(size_ + 1)];
        return count[from + length] == count[from];
    }

    // The lowest y >= from with rows [y, y + length) of column x all free, or
    // size when there is none.
    int firstFree(int x, int from, int length) const
    {
        const uint64_t* col = &bits_[size_t(x) * words_];
        int y = from;
        while (y + length <= size_) {
            const int blocker = firstTaken(col, y, y + length);
            if (blocker < 0)
                return y;
            y = firstClear(col, blocker);  // past the whole taken run
        }
        return size_;
    }

    void take(int x, int y0, int y1) { mark(x, y0, y1, true); }      // rows [y0, y1] of column x
    void release(int x, int y0, int y1) { mark(x, y0, y1, false); }  // the same rows, free again

private:
    void mark(int x, int y0, int y1, bool taken)
    {
        uint64_t* col = &bits_[size_t(x) * words_];
        for (int y = y0; y <= y1; ++y) {
            const uint64_t bit = uint64_t(1) << (y & 63);
            col[size_t(y) >> 6] = taken ? col[size_t(y) >> 6] | bit : col[size_t(y) >> 6] & ~bit;
        }
        uint16_t* count = &taken_[size_t(x) * size_t(size_ + 1)];
        for (int y = y0 + 1; y <= size_; ++y)
            count[y] = uint16_t(count[y - 1] + ((col[size_t(y - 1) >> 6] >> ((y - 1) & 63)) & 1));
    }

    // The first free row at or after y (size when none).
    int firstClear(const uint64_t* col, int y) const
    {
        while (y < size_) {
            const uint64_t free = ~col[size_t(y) >> 6] >> (y & 63);
            if (free)
                return std::min(size_, y + __builtin_ctzll(free));
            y = (y | 63) + 1;
        }
        return size_;
    }

    // The first taken row in [y0, y1), or -1.
    int firstTaken(const uint64_t* col, int y0, int y1) const
    {
        for (int y = y0; y < y1;) {
            const size_t w = size_t(y) >> 6;
            uint64_t bits = col[w] >> (y & 63);
            const int span = std::min(64 - (y & 63), y1 - y);
            if (span < 64)
                bits &= (uint64_t(1) << span) - 1;
            if (bits)
                return y + __builtin_ctzll(bits);
            y += span;
        }
        return -1;
    }

    int size_;
    size_t words_;
    std::vector<uint64_t> bits_;
    std::vector<uint16_t> taken_;  // per column, size + 1 running counts: rows [0, y) taken
};

// A chart's placement: its footprint, where it goes, and the row its top
// reaches (INT32_MAX when it fits nowhere).
struct Placement {
    int top = INT32_MAX, x = 0, y = 0, rotation = 0;
    Footprint fp;
};

// Finds where chart c (at its scaleX) goes into `occupied`, in whichever of
// its eight orientations its top ends lowest, at the lowest row every one
// of its columns is free (holes under earlier charts included); ties go to
// the lower orientation, then the lower column.  The orientations are tried
// on `threads` threads from a size of 256 up, each pruning against the best
// top any has found (ties allowed, so the lower orientation still wins
// them): the same placement for any thread count.  `local` must map the
// chart's vertices to their entries.
Placement place(const Chart& c, const Occupancy& occupied, const ControlMesh& mesh, const std::vector<int32_t>& local,
                int gutter, int size, int threads)
{
    Placement found[8];
    std::atomic<int> anyTop{INT32_MAX};
    auto tryOrientation = [&](int rotation) {
        Placement& own = found[rotation];
        own.rotation = rotation;
        own.fp = footprint(c, mesh, local, c.scaleX, rotation, gutter, size);
        const Footprint& fp = own.fp;
        if (fp.width > size || fp.height > size)
            return;
        for (int x = 0; x + fp.width <= size; ++x) {
            // Raise y until every column's span is free at once, giving
            // up once the top cannot beat the best placement so far.
            const int limit = std::min({size, own.top - 1, anyTop.load(std::memory_order_relaxed)});
            int y = 0;
            for (bool moved = true; moved && y + fp.height <= limit;) {
                moved = false;
                for (int col = 0; col < fp.width && y + fp.height <= limit; ++col)
                    for (uint32_t r = fp.first[size_t(col)]; r < fp.first[size_t(col) + 1]; ++r) {
                        const int lo = fp.lo[r];
                        if (occupied.free(x + col, y + lo, fp.hi[r] - lo + 1))
                            continue;
                        const int at = occupied.firstFree(x + col, y + lo, fp.hi[r] - lo + 1) - lo;
                        if (at > y) {
                            y = at;
                            moved = true;
                        }
                    }
            }
            const int top = y + fp.height;
            if (top <= limit) {  // limit < own.top: a strict improvement
                own.top = top;
                own.x = x;
                own.y = y;
                for (int seen = anyTop.load(); top < seen && !anyTop.compare_exchange_weak(seen, top);) {
                }
            }
        }
    };
    parallelChunks(8, size >= 256 ? threads : 1, [&](int, size_t begin, size_t end) {
        for (size_t rotation = begin; rotation < end; ++rotation)
            tryOrientation(int(rotation));
    });
    int best = 0;
    for (int rotation = 1; rotation < 8; ++rotation)
        if (found[rotation].top < found[best].top)
            best = rotation;
    return std::move(found[best]);
}

void take(Occupancy* occupied, const Placement& p, bool taken = true)
{
    for (int col = 0; col < p.fp.width; ++col)
        for (uint32_t r = p.fp.first[size_t(col)]; r < p.fp.first[size_t(col) + 1]; ++r)
            if (taken)
                occupied->take(p.x + col, p.y + p.fp.lo[r], p.y + p.fp.hi[r]);
            else
                occupied->release(p.x + col, p.y + p.fp.lo[r], p.y + p.fp.hi[r]);
}

void setLocal(const Chart& c, std::vector<int32_t>* local, bool on)
{
    for (size_t k = 0; k < c.vertices.size(); ++k)
        (*local)[c.vertices[k]] = on ? int32_t(k) : -1;
}

// Packs the charts' footprints into a texel occupancy map, largest first,
// each where place() puts it: sets each chart's scaleX and its entry of
// `placements`; false if they do not fit.
bool pack(std::vector<Chart>& charts, const std::vector<size_t>& order, const ControlMesh& mesh,
          std::vector<int32_t>& local, double scale, int gutter, int size, int threads,
          std::vector<Placement>* placements)
{
    Occupancy occupied(size);
    placements->assign(charts.size(), Placement());
    for (size_t i : order) {
        Chart& c = charts[i];
        setChartScale(&c, scale);
        setLocal(c, &local, true);
        Placement p = place(c, occupied, mesh, local, gutter, size, threads);
        setLocal(c, &local, false);
        if (p.top == INT32_MAX)
            return false;
        take(&occupied, p);
        (*placements)[i] = std::move(p);
    }
    return true;
}

// Packed at a common scale, charts leave gaps that none of them fits at
// that scale.  Each chart in turn, smallest first, is lifted out and put
// back, wherever place() finds room among the others, at the largest scale
// up to kMaxGrowth times its own that fits (tried whole, then bisected):
// the map's free texels become finer sampling of the charts that can use
// them.  A chart never shrinks (its old place is always there), so no part
// of the surface is sampled more coarsely than the common scale.  With
// --exr, two passes take the real pairs' fill from 50-67% to 60-70%; the
// hand, whose hand-shaped charts leave the space between the fingers to
// small ones, gains most (56 -> 66%).
constexpr double kMaxGrowth = 2.0;
constexpr int kGrowthPasses = 2;
constexpr int kGrowthSteps = 4;  // twice the scale, then three halvings of the interval

void growIntoGaps(std::vector<Chart>& charts, const std::vector<size_t>& order, std::vector<Placement>& placements,
                  const ControlMesh& mesh, std::vector<int32_t>& local, int gutter, int size, int threads)
{
    Occupancy occupied(size);
    for (const Placement& p : placements)
        take(&occupied, p);
    for (size_t n = order.size(); n-- > 0;) {
        const size_t i = order[n];
        Chart& c = charts[i];
        take(&occupied, placements[i], false);
        const double base = c.scaleX;
        setLocal(c, &local, true);
        double lo = 1.0, hi = kMaxGrowth;
        Placement best;
        for (int step = 0; step < kGrowthSteps; ++step) {
            const double mid = step == 0 ? hi : 0.5 * (lo + hi);
            c.scaleX = base * mid;
            Placement p = place(c, occupied, mesh, local, gutter, size, threads);
            if (p.top != INT32_MAX) {
                lo = mid;
                best = std::move(p);
                if (step == 0)
                    break;
            } else {
                hi = mid;
            }
        }
        setLocal(c, &local, false);
        if (best.top == INT32_MAX) {
            c.scaleX = base;  // stays where it was
        } else {
            c.scaleX = base * lo;
            placements[i] = std::move(best);
        }
        take(&occupied, placements[i]);
    }
}

// Orders the packer tries the charts in.  Lowest-top placement of
// irregular charts is sensitive to order, and no one order wins: on the
// real pairs each of these packed best at some map size, by 1-5% of scale.
// First the longest first; then the largest box first, the tallest first;
// then the first with neighbours swapped at random (a fixed seed, so bakes
// repeat).
constexpr int kPackingOrders = 8;
constexpr double kOrderGain = 0.005;  // scale an order must beat the first by
constexpr int kScaleSteps = 6;

std::vector<std::vector<size_t>> packingOrders(const std::vector<Chart>& charts)
{
    std::vector<size_t> order(charts.size());
    for (size_t i = 0; i < order.size(); ++i)
        order[i] = i;
    auto extent = [&](size_t i) { return charts[i].hi - charts[i].lo; };
    auto by = [&](auto key) {
        std::vector<size_t> o = order;
        std::stable_sort(o.begin(), o.end(), [&](size_t a, size_t b) { return key(extent(a)) > key(extent(b)); });
        return o;
    };
    std::vector<std::vector<size_t>> orders;
    orders.push_back(by([](const glm::dvec2& e) { return std::max(e.x, e.y); }));
    orders.push_back(by([](const glm::dvec2& e) { return e.x * e.y; }));
    orders.push_back(by([](const glm::dvec2& e) { return e.y; }));
    uint32_t seed = 12345;
    while (orders.size() < size_t(kPackingOrders)) {
        std::vector<size_t> o = orders[0];
        for (size_t i = 1; i < o.size(); ++i) {
            seed = seed * 1664525u + 1013904223u;
            if ((seed >> 16) % 3 == 0)
                std::swap(o[i], o[i - 1]);
        }
        orders.push_back(std::move(o));
    }
    return orders;
}

// Packs the charts into an options.mapSize map (the largest common scale
// that fits: bracket, then bisect; then, with options.growIntoGaps, each
// chart put back larger where it fits) and writes the UVs they give: one
// per (chart, vertex), which faces index.  `fill`: the fraction of the map
// inside charts.

}  // namespace

Status layoutCharts(std::vector<Chart> charts, const ControlMesh& mesh, const AtlasOptions& options, double area,
                    std::vector<glm::vec2>* uvsOut, std::vector<uint32_t>* uvIndicesOut, double* fill)
{
    const size_t nf = mesh.faceCount();
    std::vector<int32_t> local(mesh.positions.size(), -1);
    const int size = options.mapSize, g = options.gutter;
    // Charts are packed into the map with a gutter's margin around it: a
    // footprint may reach into the margin, the chart itself never (it lies
    // g + 1/2 texels inside its footprint).  The sampler clamps to the edge,
    // so no sample reads a texel there; the map's own border texels are not
    // spent on gutters.
    const int span = size + 2 * g;
    const std::vector<std::vector<size_t>> orders = packingOrders(charts);
    std::vector<Placement> placements, trial;
    size_t used = 0;
    // Packs orders[k] at `scale`; on success keeps the placement.
    auto packs = [&](size_t k, double scale) {
        if (cancelRequested())  // a cancelled bake: every pack fails at once
            return false;
        if (!pack(charts, orders[k], mesh, local, scale, g, span, options.threads, &trial))
            return false;
        placements.swap(trial);
        used = k;
        return true;
    };
    // The first order's largest scale: bracketed, then bisected (the last
    // success is the largest).
    double lo = 0.0, hi = area > 0.0 ? std::sqrt(double(size) * double(size) / area) : 1.0;
    while (packs(0, hi)) {
        lo = hi;
        hi *= 1.25;
    }
    if (lo == 0.0) {
        lo = hi;
        for (int tries = 0; !packs(0, lo); ++tries) {
            if (cancelRequested())
                return Status(StatusCode::Cancelled, "cancelled");
            if (tries == 40)
                return Status(StatusCode::InvalidArgument, "a " + std::to_string(size) + " map is too small for " +
                                                               std::to_string(charts.size()) +
                                                               " charts; use a larger map");
            lo *= 0.8;
        }
        hi = lo / 0.8;
    }
    for (int step = 0; step < kScaleSteps; ++step) {
        const double mid = 0.5 * (lo + hi);
        (packs(0, mid) ? lo : hi) = mid;
    }
    if (cancelRequested())
        return Status(StatusCode::Cancelled, "cancelled");
    // The other orders only where they beat it by kOrderGain: most cost one
    // pack that fails.  Where one succeeds, its own largest scale below the
    // first order's failure bound, hi, or 1.25 times that beyond.
    for (size_t k = 1; k < (options.tryOrders ? orders.size() : 1); ++k) {
        double a = lo * (1.0 + kOrderGain);
        if (!packs(k, a))
            continue;
        double b = std::max(hi, a * 1.25);
        for (int step = 0; step < kScaleSteps; ++step) {
            const double mid = 0.5 * (a + b);
            (packs(k, mid) ? a : b) = mid;
        }
        lo = a;
        hi = b;
    }
    for (Chart& c : charts)
        setChartScale(&c, lo);  // as the kept placement packed them
    for (int pass = 0; pass < (options.growIntoGaps ? kGrowthPasses : 0); ++pass)
        growIntoGaps(charts, orders[used], placements, mesh, local, g, span, options.threads);
    std::vector<glm::vec2>& uvs = *uvsOut;
    std::vector<uint32_t>& uvIndices = *uvIndicesOut;
    uvs.clear();
    uvIndices.assign(3 * nf, 0);
    const double inv = 1.0 / double(size);
    for (size_t i = 0; i < charts.size(); ++i) {
        const Chart& c = charts[i];
        const Placement& at = placements[i];
        const uint32_t base = uint32_t(uvs.size());
        for (const glm::dvec2& p : c.points) {
            const glm::dvec2 t = placed(c, p, c.scaleX, at.rotation, g) + glm::dvec2(double(at.x - g), double(at.y - g));
            uvs.emplace_back(float(t.x * inv), float(t.y * inv));
        }
        setLocal(c, &local, true);
        for (uint32_t f : c.faces)
            for (size_t k = 0; k < 3; ++k)
                uvIndices[3 * size_t(f) + k] = base + uint32_t(local[mesh.triangles[3 * size_t(f) + k]]);
        setLocal(c, &local, false);
    }
    // Area inside charts in texels (projected area <= true area).
    *fill = 0.0;
    for (size_t f = 0; f < nf; ++f) {
        const glm::vec2 a = uvs[uvIndices[3 * f]], b = uvs[uvIndices[3 * f + 1]], c = uvs[uvIndices[3 * f + 2]];
        *fill += 0.5 * std::fabs(double(cross2(b - a, c - a)));
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
