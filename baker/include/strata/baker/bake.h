// Strata baker: the whole bake of paper sections 2.1-2.3 and 3.2, from a
// high-resolution mesh and a control mesh with UVs to a displacement map.
#pragma once

#include "strata/baker/distance.h"
#include "strata/control_mesh.h"
#include "strata/displacement_map.h"
#include "strata/plan.h"
#include "strata/vertex_displacements.h"
#include "strata/status.h"

#include <glm/vec4.hpp>

#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace baker {

/// What a texel keeps when several layers of the high-resolution surface
/// map onto it (overfolds, paper 3.2.3).
enum class OverlapPolicy {
    Max,      ///< the paper's rule: the largest distance (the outer envelope)
    Nearest,  ///< the smallest |d|: the layer closest to the control surface
};

struct RasterStats {
    size_t triangles = 0;
    size_t degenerateTriangles = 0;  ///< zero-area high-res triangles, skipped
    size_t borderTriangles = 0;      ///< vertices mapped to different control triangles
    size_t pieces = 0;               ///< (high-res triangle, control triangle) pairs rasterised
    size_t coveredTexels = 0;
    size_t multiLayerTexels = 0;     ///< texels hit by more than one layer
};

/// A high-resolution mesh: positions and triangles only.
struct TriangleMesh {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    /// Per vertex, linear RGBA: a PLY's or OBJ's vertex colours (loadHighMesh),
    /// which --control auto re-bakes into the rig's texture; empty without.
    std::vector<glm::vec4> colours;
    size_t faceCount() const { return triangles.size() / 3; }
};

/// The connected pieces of a capture ("shells", its vertices welded by
/// position), and the piece each control face was built from.  A capture
/// of separate parts that pass through each other (a robot's rigid pieces
/// meeting at its joints) maps each part's vertices onto its own part's
/// cage, so that no part rides on a neighbour's cage when posed.
struct ShellLabels {
    std::vector<uint32_t> highVertex;   ///< per high-resolution vertex: its piece
    std::vector<uint32_t> controlFace;  ///< per control face: the piece it was built from
};

struct BakeOptions {
    Scheme scheme = Scheme::Linear;
    int size = 0;                       ///< map side; 0 = automatic (paper 2.3 rule)
    int maxSize = 8192;
    OverlapPolicy overlap = OverlapPolicy::Max;
    int threads = 2;
    int denseLevel = 3;                 ///< smooth scheme: limit-surface sampling level
    int gutter = 4;                     ///< dilation passes (texels)
    int lineRings = 0;                  ///< gutter rings measured by line intersection before dilation
    /// Each high-resolution vertex maps onto control faces of its own piece
    /// (null: onto any face; used where its counts match the meshes baked).
    std::shared_ptr<const ShellLabels> shells;
};

struct StageTimes {
    double mapping = 0, rasterize = 0, dilate = 0;  ///< ms (dilate includes hole filling)
};

struct BakeReport {
    size_t highVertices = 0, highTriangles = 0, controlTriangles = 0;
    size_t fallbackVertices = 0;
    double searchDistance = 0;
    RasterStats raster;
    int size = 0;
    std::string sizeReason;
    double typicalEdge = 0;             ///< median high-res edge length
    double coverage = 0;                ///< fraction of texels inside charts hit by forward mapping
    size_t lineFilledTexels = 0;        ///< holes and gutter rings measured by line intersection
    double overlapFraction = 0;         ///< covered texels hit by more than one layer
    float dmin = 0, dmax = 0;
    double diagonal = 0;                ///< high-res bounding-box diagonal
    StageTimes times;
};

/// Median edge length of a triangle mesh (the paper's "typical edge").
double medianEdgeLength(const TriangleMesh& mesh);

/// Paper 2.3: a texel about the high-resolution mesh's typical edge.  With
/// A3 the control mesh's 3D area and Auv its UV area (unit square), the side
/// N = sqrt(A3 / Auv) / typicalEdge, rounded up to a power of two and clamped
/// to [64, maxSize].  `reason` explains the choice.
int chooseMapSize(const ControlMesh& control, double typicalEdge, int maxSize, std::string* reason);

/// Checks UVs for baking: inside [0, 1] and no two triangles overlapping in
/// UV space (tested by rasterising at `size`); the message names the triangles.
Status checkUVs(const ControlMesh& control, int size);

/// When the UV layout leaves the unit square (real assets overshoot: spot's
/// reaches u = -0.052), fits it back with one uniform scale and offset, which
/// keeps every chart's shape and the layout free of overlaps.  Returns true
/// and describes the change in `note` when it had to.
bool fitUVsToUnitSquare(ControlMesh* control, std::string* note);

/// Checks a high-resolution mesh: finite positions, indices in range, at
/// least one non-degenerate triangle.
Status checkHighMesh(const TriangleMesh& high);

/// Runs mapping, rasterisation and dilation.  The control mesh must have UVs.
/// layersOut (optional) receives the per-texel layer counts (paper Fig. 6f).
Status bake(DisplacementMap* out, std::vector<uint16_t>* layersOut, BakeReport* report, const ControlMesh& control,
            const TriangleMesh& high, const BakeOptions& options);

/// Closed-loop error of one level: RMS and max distance, both directions,
/// between the runtime's reconstruction and the high-res surface.
struct LevelError {
    int level = 0;
    size_t vertices = 0, triangles = 0;
    double forwardRms = 0, forwardMax = 0;    ///< reconstructed -> high-res
    double backwardRms = 0, backwardMax = 0;  ///< high-res -> reconstructed
    /// The larger RMS of the two directions: what a tolerance is held to.
    double rms() const { return forwardRms > backwardRms ? forwardRms : backwardRms; }
};
/// Levels minLevel..maxLevel, streamed: each level is refined in chunks of
/// control faces (spatially ordered) of at most chunkTriangles refined
/// triangles, each measured and freed before the next, so memory is bounded
/// at any level.  Forward samples are each chunk's vertices and face
/// centroids; the backward distance keeps, per high-res sample, the nearest
/// chunk.  The smooth scheme refines each chunk with two rings of support
/// faces, so its limit surface is the whole mesh's.
/// With `field`, the displacements come from it (a rig that stores them per
/// vertex) instead of from sampling `map`.  With `capture`, the capture's
/// index and samples are those (built once where many closed loops measure
/// one capture; the same answers as without).
struct LoopCapture;
Status closedLoopError(std::vector<LevelError>* out, const ControlMesh& control, const DisplacementMap& map,
                       Scheme scheme, const TriangleMesh& high, int minLevel, int maxLevel, int threads,
                       size_t chunkTriangles = size_t(1) << 20, const DisplacementField* field = nullptr,
                       const LoopCapture* capture = nullptr);

/// The capture's side of the closed loop: its index (over high's positions
/// and triangles) and the samples the backward distance measures from (by
/// area, as many as it has vertices and faces: loopSamples()).
struct LoopCapture {
    const TriangleIndex* index = nullptr;
    std::vector<glm::vec3> samples;
};
std::vector<glm::vec3> loopSamples(const TriangleMesh& high);

/// Per-vertex displacements measured against the capture (Displaced
/// Subdivision Surfaces' sampling): for each refined vertex of `mesh` at
/// `level` in `scheme`, the signed distance along its displacement
/// direction to the nearest intersection with the capture, replacing the
/// map's sample in `values` when the two agree within `window` (a larger
/// gap means another layer of a fold: the map's forward-mapped value
/// stays).  Vertices no ray reaches keep the map's value.  Returns how many
/// values changed through `replaced` when it is not null.
Status measureVertexDisplacements(std::vector<float>* values, const ControlMesh& mesh, Scheme scheme, int level,
                                  const TriangleIndex& high, double window, int threads, size_t* replaced = nullptr);

/// The refined vertices of `mesh` at `level` in `scheme` before displacement
/// (eq. 2 with d = 0): each one's surface point and displacement direction,
/// through the runtime's own plan, which `plan` receives.  Fails, naming
/// `what`, when valueCount is not the refined vertex count.
Status evaluateBareSurface(std::unique_ptr<Plan>* plan, std::vector<glm::vec3>* surface,
                           std::vector<glm::vec3>* direction, const ControlMesh& mesh, Scheme scheme, int level,
                           size_t valueCount, const char* what);

}  // namespace baker
}  // namespace strata
