// Strata runtime: a render-ready frame (displaced positions and shading
// normals) on one or several threads.
//
// Shading normals are the area-weighted sum of the incident refined face
// normals, normalised (Plan::computeShadingNormals).  Computed as a scatter
// over the refined faces they cost four times the positions: each face reads
// its corners from far apart in OpenSubdiv's level-by-level vertex order.
//
// FrameEvaluator works per control face instead.  The refined vertices of
// a control face are a regular triangular grid of (2^level + 1)(2^level +
// 2)/2 vertices at known barycentrics.  One pass per control face ("tile")
// computes the grid's displaced positions into a small local array (the
// tile's own vertices are written out), the grid's face normals and their
// per-vertex sums.  A vertex inside the tile is then final; a vertex on the
// control face's border keeps its partial sum, and a second pass adds the
// partial sums of the tiles that share it, in tile order.  Normals equal
// computeShadingNormals up to the order of the additions (a few ulps), and
// every result is bit-identical for any thread count.
//
// Positions: in the linear scheme the same expression as Plan::evaluate,
// bit for bit.  In the smooth scheme each tile's limit stencils (the
// plan's, from OpenSubdiv) are gathered once into a dense matrix over the
// control points the tile uses, so a frame streams it in whole vectors;
// positions equal Plan::evaluate's up to the order of the additions.
//
// The frame's vertices come in one of two orders (FrameLayout).  In the
// plan's order a tile's vertices are written far apart (OpenSubdiv numbers
// refined vertices level by level); in tile order each tile writes its own
// vertices one after the other, about a third faster at level 5.  An engine
// that draws the frame takes triangles() as its index buffer and
// vertexOrder() to place per-vertex attributes (UVs) once.
//
// A plan whose refined faces are not such grids runs Plan::evaluate, a
// face-normal pass and a per-vertex gather instead (bit-identical to
// computeShadingNormals), always in the plan's order.
#pragma once

#include "strata/plan.h"
#include "strata/status.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace strata {

namespace detail {
class WorkerPool;
}

/// The order of a frame's vertices.
enum class FrameLayout {
    Plan,   ///< the plan's refined vertex order: Plan::refinedTriangles() indexes it
    Tiles,  ///< control face by control face, as the frame computes them
};

class FrameEvaluator {
public:
    /// For `plan`, which must outlive the evaluator.  A Tiles layout falls
    /// back to the plan's order where the frame cannot run per control face
    /// (layout() says which is used).
    explicit FrameEvaluator(const Plan& plan, FrameLayout layout = FrameLayout::Plan);
    ~FrameEvaluator();
    FrameEvaluator(const FrameEvaluator&) = delete;
    FrameEvaluator& operator=(const FrameEvaluator&) = delete;

    /// One frame: positions (and, when normals is not null, shading normals)
    /// of every refined vertex, on `threads` threads (1: the calling thread
    /// only).  displacements: the plan's own when null.  Arguments as
    /// Plan::evaluate.  Not re-entrant (it keeps scratch between frames);
    /// allocates only on its first frame with normals (and the first with
    /// more threads).
    Status evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                    const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                    int threads);

    /// Whether frames run per control face (the fast path).
    bool tiled();
    /// The layout frames are written in.
    FrameLayout layout();
    /// Per frame vertex, its refined vertex in the plan (the identity in
    /// the plan's layout): to place per-vertex attributes such as UVs.
    const std::vector<uint32_t>& vertexOrder();
    /// The refined triangles, indexing the frame's vertices (the plan's
    /// refinedTriangles() in its layout).
    const std::vector<uint32_t>& triangles();

    size_t bytes() const;

private:
    struct Scratch;
    template <typename Body>
    void parallel(int threads, size_t n, const Body& body);
    void buildTables();
    bool buildTiles();
    void buildTileLayout();
    void buildLimitTiles();
    void shadeTiles(Scratch& s, glm::vec3* positions, glm::vec3* normals, const float* d, const glm::vec3* cp,
                    const glm::vec3* cn, size_t faceBegin, size_t faceEnd);
    void finishBorders(glm::vec3* normals, size_t begin, size_t end) const;
    void faceNormals(const glm::vec3* positions, size_t begin, size_t end);
    void vertexNormals(glm::vec3* dst, size_t begin, size_t end) const;

    const Plan& plan_;
    FrameLayout requested_;
    bool built_ = false, tiled_ = false;

    // Tiles (linear scheme).  Slot (i, j) of a tile is the refined vertex at
    // barycentrics (1 - i/R - j/R, i/R, j/R) of its control face, R = 2^level;
    // slots are numbered row by row (i), j within a row.
    int resolution_ = 0;                 // R
    size_t slotCount_ = 0;               // (R + 1)(R + 2) / 2
    std::vector<uint32_t> rowStart_;     // R + 2: first slot of row i
    std::vector<float> slotW1_, slotW2_; // per slot: i / R, j / R
    std::vector<uint32_t> borderSlots_;  // the 3R slots on the tile's border, ascending
    std::vector<uint32_t> slots_;        // per tile and slot: refined vertex | kOwned when the tile writes it
    std::vector<glm::vec3> partials_;    // per tile and border slot: the tile's sum of face normals
    std::vector<uint32_t> borderVertices_, borderOffsets_, borderEntries_;  // each border vertex's partials, tile order
    std::vector<uint32_t> isolated_;     // refined vertices no face uses
    std::vector<uint32_t> limitOffsets_, limitControl_;  // smooth: each tile's control points
    std::vector<float> limitWeights_;    // smooth: the distinct tile matrices, per point 3 weight rows of whole-vector slots
    std::vector<size_t> limitMatrix_;    // smooth: per tile, where its matrix starts in limitWeights_
    std::vector<uint32_t> tileFirst_;    // tile layout: per tile (and one past), its first frame vertex
    std::vector<uint16_t> ownedSlots_;   // tile layout: per frame vertex, its slot in its tile
    std::vector<uint32_t> order_, triangles_;  // vertexOrder(), triangles() (tile layout, or built on request)
    std::vector<Scratch> scratch_;
    std::unique_ptr<detail::WorkerPool> pool_;  // worker threads, kept between frames

    // The generic path: each refined vertex's faces, ascending, and face normals.
    std::vector<uint32_t> offsets_, faces_;
    std::vector<glm::vec3> faceNormals_;
};

}  // namespace strata
