// Strata baker: automatic UV atlas for control meshes without UVs
// (issue: "generate a texel-aligned atlas automatically ... so the user never
// has to unwrap").
#pragma once

#include "strata/control_mesh.h"
#include "strata/status.h"

#include <memory>

namespace strata {
namespace baker {

struct AtlasOptions {
    int mapSize = 1024;   ///< texels per side of the square map the atlas is laid out for
    int gutter = 2;       ///< texels of gutter around every chart
    int threads = 1;      ///< chart atlas: threads that pack (the same layout for any count)
    bool growIntoGaps = true;  ///< chart atlas: charts grow into the pack's gaps (finer sampling, more fill)
    /// Chart atlas: the packer tries eight chart orders and keeps the one
    /// that packs at the largest scale (more fill, at up to twice the
    /// packing time); false: the longest chart first only.
    bool tryOrders = true;
    /// buildAtlas: where the chart atlas misses its targets, one chart over
    /// the whole map instead (buildSquareAtlas); false: the chart atlas.
    bool wholeMap = true;
};

/// Replaces mesh.uvs / mesh.uvIndices with a per-triangle atlas: triangles
/// are paired into square cells of a regular grid, each pair split along the
/// cell's diagonal with a gutter between them, corners on texel boundaries.
/// Every triangle is its own chart, so every edge is a UV seam; the runtime's
/// one-sample-per-vertex rule keeps the reconstruction watertight.
/// Fails when the map is too small to give every triangle at least a few texels.
Status buildTriangleAtlas(ControlMesh* mesh, const AtlasOptions& options);

/// The most a chart's flattening may distort its sampling: no direction on
/// the surface is sampled more than this many times more finely or coarsely
/// (in texels per unit length) than the chart's mean.
constexpr double kChartMaxDistortion = 2.5;

struct ChartAtlasStats {
    size_t charts = 0;
    double texelFill = 0.0;  ///< fraction of the map's area inside charts
    /// The largest sampling distortion of a chart's flattening: over its
    /// faces, the most a direction on the surface is stretched or shrunk in
    /// the map against the chart's mean scale (at most kChartMaxDistortion).
    double maxDistortion = 0.0;
    /// buildSquareAtlas: one chart over the whole map; stretch is its L2
    /// stretch (Sander et al. 2001: the root mean square, over the surface,
    /// of how much a direction is stretched against the mean scale; 1 is an
    /// isometry), and maxDistortion is not bounded by kChartMaxDistortion.
    bool wholeMap = false;
    double stretch = 0.0;
};

/// Replaces mesh.uvs / mesh.uvIndices with a chart atlas.  Each chart grows
/// breadth first from the largest remaining face across manifold edges
/// while it stays a disk (Euler characteristic 1), and is the longest
/// prefix of that growth, up to a quarter of the surface and 65536 faces,
/// whose flattening stays within kChartMaxDistortion: its
/// least-squares conformal map (Levy et al. 2002) refined as rigid as
/// possible (Liu et al. 2008), both solved by sparse Cholesky (Eigen),
/// fold-free and not lapping over itself.  A border face then moves to a
/// neighbouring chart where that splits fewer vertices (it is its chart's
/// only face at more corners than the other chart is missing from, as a
/// saw tooth is) and both charts stay disks that flatten.  Where the quarter
/// bound a chart, the charts are grown again without it, both are laid out,
/// and the layout with more of the map inside charts is kept.  Each chart is turned to its smallest
/// bounding box, and the charts' footprints (`options.gutter` texels around
/// them) are packed into a texel occupancy map (a chart may drop into a hole
/// under another), in eight orientations (turned by quarters and mirrored),
/// at the largest common scale that fits `options.mapSize` (small charts get
/// at least 6 texels along, and are stretched to 6 across), in whichever
/// of eight chart orders packs at the largest scale (`options.tryOrders`).
/// A footprint may reach a gutter past the map's edge (the sampler clamps
/// to it; the chart itself stays inside).  With `options.growIntoGaps`,
/// each chart, smallest first, is then put back at the largest scale up to twice its
/// own that still fits among the others (two passes), so the pack's gaps
/// sample the surface more finely.  No chart is sampled more coarsely than
/// the common scale, and no texel a bilinear sample inside one chart reads
/// is read from inside another.
/// Vertices are split only on chart borders.  Fails (and leaves the mesh as
/// it was) when the charts do not fit the map; callers fall back to
/// buildTriangleAtlas.
/// The charts of a mesh (grown, flattened, turned) do not depend on the map
/// size: buildChartAtlas calls on the same mesh (the same positions and
/// triangles) at several sizes that share a cache make them once, and keep
/// the first call's choice between the two growths; a layout asked for
/// again (the same size and options) is the cache's copy.
class ChartCache {
public:
    ChartCache();
    ~ChartCache();
    ChartCache(ChartCache&&) noexcept;
    ChartCache& operator=(ChartCache&&) noexcept;
    struct Impl;  // atlas.cpp
    std::unique_ptr<Impl> impl;
};

Status buildChartAtlas(ControlMesh* mesh, const AtlasOptions& options, ChartAtlasStats* stats = nullptr,
                       ChartCache* cache = nullptr);

struct SquareAtlasOptions {
    int mapSize = 1024;           ///< texels per side of the square map; 0: UVs over the unit square
    double maxVertexRatio = 1.3;  ///< the most vertices the cut surface may have, per control vertex
};

/// Replaces mesh.uvs / mesh.uvIndices with one chart that covers the whole
/// map (Gu et al. 2002, "Geometry images"): the surface is cut open into a
/// disk, its border laid along the square's sides by length and its inside
/// placed by a barycentric embedding, mean value weights (Floater 2003)
/// reweighted against stretch (Yoshizawa et al. 2004), which cannot fold.
/// Four border vertices go on the corners, chosen so that no inner edge
/// between two border vertices lies along a side.  The cut starts from the
/// border loops joined up (on a closed surface: the shortest path between
/// its two sharpest tips) and grows by shortest paths, each round from
/// whichever of its most stretched vertices lowers the stretch most, while
/// the cut surface keeps within `options.maxVertexRatio` times the
/// vertices; the cut that stretches least is kept.  The chart's border
/// lies on the border texels' centres (see fitSquareAtlas).  Only for one
/// connected, consistently oriented manifold of genus 0 (a sphere, a disk,
/// a disk with holes); fails (the mesh left as it was) otherwise.  Its
/// cost grows with the cut's length: meant for cages of up to a few
/// thousand vertices, whose chart atlases split the most.
Status buildSquareAtlas(ControlMesh* mesh, const SquareAtlasOptions& options, ChartAtlasStats* stats = nullptr);

/// The least share of the map's texels an atlas should have inside charts.
constexpr double kAtlasMinFill = 0.70;

/// The atlas a bake lays out for `--uv auto`: the chart atlas or, with
/// `options.wholeMap`, where the charts split more than
/// SquareAtlasOptions::maxVertexRatio times the vertices (small cages: their
/// seams are long against their vertex count) or fill less than
/// kAtlasMinFill of the map and the cage allows it, the one-chart atlas,
/// which splits far fewer and fills the map.  A cache keeps both for the
/// cage's other sizes.  Fails where buildChartAtlas does.
Status buildAtlas(ControlMesh* mesh, const AtlasOptions& options, ChartAtlasStats* stats = nullptr,
                  ChartCache* cache = nullptr);

/// Moves UVs that span the unit square (buildSquareAtlas with mapSize 0)
/// onto a map of `mapSize` texels: the square's sides on the centres of the
/// map's border texels, so a bilinear sample inside never reads past them.
/// Returns the share of the map's texels inside the chart.
double fitSquareAtlas(std::vector<glm::vec2>* uvs, int mapSize);

}  // namespace baker
}  // namespace strata
