// UV atlases for a control mesh: the chart atlas (atlas_charts.cpp grows
// the charts, atlas_flatten.cpp flattens them, atlas_pack.cpp packs them),
// cached per cage, with the one-chart atlas where the charts miss the
// targets; and the per-triangle atlas, paired into square cells, where
// the charts do not fit the map.
#include "strata/baker/atlas.h"

#include "atlas_parts.h"
#include "cancel.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

Status buildTriangleAtlas(ControlMesh* mesh, const AtlasOptions& options)
{
    const size_t nf = mesh->faceCount();
    if (nf == 0)
        return Status(StatusCode::InvalidArgument, "cannot build an atlas for a mesh without faces");
    if (options.mapSize < 8 || options.gutter < 1)
        return Status(StatusCode::InvalidArgument, "atlas map size must be at least 8 and the gutter at least 1");
    const size_t cells = (nf + 1) / 2;
    const int grid = int(std::ceil(std::sqrt(double(cells))));
    const int cell = options.mapSize / grid;  // texels per cell side, integral so corners sit on texel edges
    const int g = options.gutter;
    // Each triangle needs room for gutters on all sides plus a usable interior.
    if (cell < 4 * g + 6)
        return Status(StatusCode::InvalidArgument,
                      "a " + std::to_string(options.mapSize) + " map is too small for " + std::to_string(nf) +
                          " per-triangle charts (" + std::to_string(cell) + " texels per cell); use a larger map");
    const float inv = 1.0f / float(options.mapSize);
    mesh->uvs.clear();
    mesh->uvIndices.resize(nf * 3);
    for (size_t f = 0; f < nf; ++f) {
        const int c = int(f / 2);
        const float x0 = float((c % grid) * cell), y0 = float((c / grid) * cell);
        const float lo = float(g), hi = float(cell - g);
        // Two right triangles per cell; the diagonal gap is 2g texels wide
        // along the axes, so each side keeps a full gutter.
        glm::vec2 corners[3];
        if (f % 2 == 0) {
            corners[0] = {lo, lo};
            corners[1] = {hi - 2.0f * float(g), lo};
            corners[2] = {lo, hi - 2.0f * float(g)};
        } else {
            corners[0] = {hi, hi};
            corners[1] = {lo + 2.0f * float(g), hi};
            corners[2] = {hi, lo + 2.0f * float(g)};
        }
        for (int k = 0; k < 3; ++k) {
            mesh->uvIndices[3 * f + size_t(k)] = uint32_t(mesh->uvs.size());
            mesh->uvs.emplace_back((x0 + corners[k].x) * inv, (y0 + corners[k].y) * inv);
        }
    }
    return Status::ok();
}

struct ChartCache::Impl {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    double area = 0.0;
    std::vector<ChartSet> sets;
    int chosen = -1;  // the set the first layout kept, or -1
    // The layouts made, for a bake that asks for a size again.
    struct Layout {
        int size = 0, gutter = 0;
        bool grow = false, orders = false;
        size_t set = 0;
        double fill = 0.0;
        std::vector<glm::vec2> uvs;
        std::vector<uint32_t> uvIndices;
    };
    std::vector<Layout> layouts;
    // The one-chart atlas (buildAtlas), over the unit square, once made.
    bool squareMade = false;
    Status square;
    std::vector<glm::vec2> squareUVs;
    std::vector<uint32_t> squareIndices;
    ChartAtlasStats squareStats;
};

ChartCache::ChartCache() = default;
ChartCache::~ChartCache() = default;
ChartCache::ChartCache(ChartCache&&) noexcept = default;
ChartCache& ChartCache::operator=(ChartCache&&) noexcept = default;

Status buildChartAtlas(ControlMesh* mesh, const AtlasOptions& options, ChartAtlasStats* stats, ChartCache* cache)
{
    const size_t nf = mesh->faceCount();
    if (nf == 0)
        return Status(StatusCode::InvalidArgument, "cannot build an atlas for a mesh without faces");
    if (options.mapSize < 8 || options.gutter < 1)
        return Status(StatusCode::InvalidArgument, "atlas map size must be at least 8 and the gutter at least 1");
    const bool cached = cache && cache->impl && cache->impl->positions == mesh->positions &&
                        cache->impl->triangles == mesh->triangles;
    ChartCache scratch;  // holds the charts when no cache is given
    ChartCache& store = cache ? *cache : scratch;
    if (!cached) {
        // Under kMaxChartShare; whole charts as well where the share bound.
        const ChartMesh geometry(*mesh);
        store.impl = std::make_unique<ChartCache::Impl>();
        ChartCache::Impl& made = *store.impl;
        made.positions = mesh->positions;
        made.triangles = mesh->triangles;
        for (size_t f = 0; f < nf; ++f) {  // the packer's area: from the float edge vectors
            const uint32_t* t = &mesh->triangles[3 * f];
            const glm::vec3 a = mesh->positions[t[0]], b = mesh->positions[t[1]], c = mesh->positions[t[2]];
            made.area += 0.5 * glm::length(glm::cross(glm::dvec3(b - a), glm::dvec3(c - a)));
        }
        made.sets.emplace_back();
        bool bound = false;
        makeCharts(*mesh, geometry, options.threads, kMaxChartShare, &made.sets[0].charts, &made.sets[0].maxDistortion,
                   &bound);
        if (bound && !cancelRequested()) {
            made.sets.emplace_back();
            makeCharts(*mesh, geometry, options.threads, 1.0, &made.sets[1].charts, &made.sets[1].maxDistortion,
                       &bound);
        }
        if (cancelRequested()) {  // makeCharts stopped part way: nothing of it is kept
            store.impl.reset();
            return Status(StatusCode::Cancelled, "cancelled");
        }
    }
    ChartCache::Impl& charts = *store.impl;
    const std::vector<ChartSet>& sets = charts.sets;
    const int chosen = charts.chosen;
    const double area = charts.area;
    auto report = [&](size_t set, double fill) {
        if (stats) {
            *stats = ChartAtlasStats();
            stats->charts = sets[set].charts.size();
            stats->texelFill = fill;
            stats->maxDistortion = sets[set].maxDistortion;
        }
    };
    for (const ChartCache::Impl::Layout& l : charts.layouts)
        if (l.size == options.mapSize && l.gutter == options.gutter && l.grow == options.growIntoGaps &&
            l.orders == options.tryOrders) {
            mesh->uvs = l.uvs;
            mesh->uvIndices = l.uvIndices;
            report(l.set, l.fill);
            return Status::ok();
        }
    // Each set laid out; the one with the most texels inside charts kept
    // (the first on a tie).  A cache remembers the choice for the cage's
    // other sizes: how well charts pack hardly depends on the size.
    Status first;
    bool tried = false;
    double bestFill = -1.0;
    size_t best = 0;
    std::vector<glm::vec2> uvs, bestUVs;
    std::vector<uint32_t> uvIndices, bestIndices;
    for (size_t i = 0; i < sets.size(); ++i) {
        if (chosen >= 0 && i != size_t(chosen))
            continue;
        double fill = 0.0;
        Status st = layoutCharts(sets[i].charts, *mesh, options, area, &uvs, &uvIndices, &fill);
        if (!tried)
            first = st;
        tried = true;
        if (st && fill > bestFill) {
            bestFill = fill;
            best = i;
            bestUVs.swap(uvs);
            bestIndices.swap(uvIndices);
        }
    }
    if (bestFill < 0.0)
        return first;
    if (chosen < 0 && sets.size() > 1)
        charts.chosen = int(best);
    if (cache)
        charts.layouts.push_back(
            {options.mapSize, options.gutter, options.growIntoGaps, options.tryOrders, best, bestFill, bestUVs, bestIndices});
    mesh->uvs = std::move(bestUVs);
    mesh->uvIndices = std::move(bestIndices);
    report(best, bestFill);
    return Status::ok();
}

Status buildAtlas(ControlMesh* mesh, const AtlasOptions& options, ChartAtlasStats* stats, ChartCache* cache)
{
    ChartCache scratch;  // holds the charts when no cache is given
    ChartCache& store = cache ? *cache : scratch;
    ChartAtlasStats own;
    if (!stats)
        stats = &own;
    Status s = buildChartAtlas(mesh, options, stats, &store);
    const SquareAtlasOptions whole;
    const double fill = stats->texelFill;
    const bool splitsFew = double(mesh->uvs.size()) <= whole.maxVertexRatio * double(mesh->positions.size());
    if (!s || !options.wholeMap || (splitsFew && fill >= kAtlasMinFill))
        return s;
    ChartCache::Impl& made = *store.impl;  // the charts' cache: this cage's
    if (!made.squareMade) {
        ControlMesh cut;
        cut.positions = mesh->positions;
        cut.triangles = mesh->triangles;
        SquareAtlasOptions unit = whole;
        unit.mapSize = 0;
        made.square = buildSquareAtlas(&cut, unit, &made.squareStats);
        made.squareUVs = std::move(cut.uvs);
        made.squareIndices = std::move(cut.uvIndices);
        made.squareMade = true;
    }
    if (!made.square)
        return s;  // not genus 0, or no cut within the vertex budget: the charts
    mesh->uvs = made.squareUVs;
    mesh->uvIndices = made.squareIndices;
    *stats = made.squareStats;
    stats->texelFill = fitSquareAtlas(&mesh->uvs, options.mapSize);
    return s;
}

}  // namespace baker
}  // namespace strata

