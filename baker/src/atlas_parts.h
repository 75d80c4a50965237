// Internal to the baker: the chart atlas's three parts and what they
// share.  Charting (atlas_charts.cpp) grows disk-shaped charts over a
// control mesh; flattening (atlas_flatten.cpp) maps each into the plane
// within kChartMaxDistortion; packing (atlas_pack.cpp) places their
// footprints in the map and writes the UVs.  atlas.cpp holds the entry
// points (atlas.h) and the per-triangle atlas.
#pragma once

#include "strata/baker/atlas.h"
#include "strata/control_mesh.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

// The largest share of the surface's area a chart may grow to (border
// teeth may then add a face or two).  The distortion bound alone makes a
// sphere two large charts, which fill 52% of a square map (two discs fill at
// most 54%); grown to quarters it is seven, which fill 73%.  A cage that
// large charts cover well may pack best that way, so where the share binds
// the atlas is laid out both ways and the one with more texels inside
// charts is kept.
constexpr double kMaxChartShare = 0.25;

struct Chart {
    std::vector<uint32_t> faces;
    glm::dvec3 normal{0.0};          // area-weighted unit normal: the plane its flattening starts from
    std::vector<uint32_t> vertices;  // topological vertices, in first-use order
    std::vector<glm::dvec2> points;  // flattened, per entry of vertices
    glm::dvec2 lo{0.0}, hi{0.0};
    double scaleX = 0.0;      // texels per model unit, set by the packer (where it goes: its Placement)
    double stretchY = 1.0;    // and the factor on y (the short side), set with it
    double distortion = 1.0;  // chartDistortion of points
};

// A mesh's charts, grown under one share of the surface.
struct ChartSet {
    std::vector<Chart> charts;
    double maxDistortion = 1.0;
};

// What chart growth needs of a mesh, whichever share bounds it: per face
// its unit normal, area and neighbours (across manifold, consistently
// oriented edges only), and each vertex's faces.
struct ChartMesh {
    std::vector<glm::dvec3> faceNormal;
    std::vector<double> faceArea;
    double totalArea = 0.0;
    std::vector<std::array<uint32_t, 3>> neighbour;
    std::vector<uint32_t> vertexFaceOffsets, vertexFaces;

    explicit ChartMesh(const ControlMesh& mesh);
};

// Charting: grows, flattens, straightens and turns the charts of a mesh,
// each under maxShare of its area: everything of the atlas that does not
// depend on the map size (nor on `threads`).
void makeCharts(const ControlMesh& mesh, const ChartMesh& geometry, int threads, double maxShare,
                std::vector<Chart>* chartsOut, double* maxDistortionOut, bool* shareBoundOut);

// Flattening: a chart whose faces are set, projected on its normal's
// plane, then conformal, then as rigid as possible.  True, with points and
// distortion set, when the result is fold-free, does not lap over itself
// and stays within kChartMaxDistortion.  `local` (one entry per mesh
// vertex) must be all -1 and is left so.
bool flattenChart(Chart* c, const ControlMesh& mesh, std::vector<int32_t>* local);

// Packing: the charts into an options.mapSize map (the largest common
// scale that fits: bracket, then bisect; then, with options.growIntoGaps,
// each chart put back larger where it fits), and the UVs they give: one
// per (chart, vertex), which faces index.  `area`: the mesh's; `fill`: the
// fraction of the map inside charts.
Status layoutCharts(std::vector<Chart> charts, const ControlMesh& mesh, const AtlasOptions& options, double area,
                    std::vector<glm::vec2>* uvsOut, std::vector<uint32_t>* uvIndicesOut, double* fill);

}  // namespace baker
}  // namespace strata
