// Strata runtime: adaptive, error-bounded level of detail, crack-free.
//
// A plan refines every control face to one level L.  An adaptive frame
// draws each control face f at its own level l_f <= L instead, out of the
// same plan: the refined grids are nested (grid point (i, j) of level l is
// grid point (i, j) * 2^(L - l) of level L, with the same displacement), so
// a coarser face is a subset of the plan's vertices and costs only those.
//
// Cracks.  The edge between faces f and g is drawn at level min(l_f, l_g)
// (min over every face of a non-manifold edge; a border edge at its face's
// level).  The finer face's grid points on that edge that the coarser level
// lacks are snapped along the edge to the nearest kept point (a tie to the
// one nearer the edge's first corner in the face's order), and its
// triangles that collapse are dropped: the strip along the edge becomes a
// fan onto the coarse edge's vertices, which both faces then share.  This
// is micromesh's edge decimation, for any difference of levels.  A closed
// manifold control mesh gives a closed manifold frame for every assignment
// of levels.
//
// Quarters.  A control face drawn at level l >= 1 is its four level-1
// children (quarters: at corners 0, 1, 2, then the middle one) each at l,
// and each quarter may take its own level (1 .. finest) instead: detail
// finer-grained than the control mesh, for cages whose faces span more of
// the model than a view resolves alike.  An edge between quarters (inside a
// face) is drawn at the lower of theirs, and each half of a control edge at
// the lowest level of what touches it; a face at level 0 (its quarters all
// 0) draws its edges at level 0, and a quarter's points on such an edge
// snap to the edge's corners, its midpoint to the first.  A face of unequal
// quarters beside a face at level 0 is drawn with all four at its finest
// (quarterLevels() says what is drawn).  The same snapping then closes
// every seam.
//
// Levels from a view.  FaceLevelErrors holds, per control face and level,
// how far the level's surface (the piecewise-linear interpolation of its
// displaced grid) strays from level L's: measured once, at load, in the
// rest pose.  LevelChooser projects it at each face's nearest distance to
// the eye (a sphere around the posed face that holds its displaced
// surface) and takes the smallest level within the pixel tolerance,
// counting an error in any direction (along the line of sight too); then it
// raises neighbours where a stitched tile strays.
//
//     strata::AdaptiveFrame frame(plan);
//     frame.setLevels(levels.data(), levels.size());       // when the levels change
//     // or frame.setQuarterLevels(quarters.data(), quarters.size()): 4 per face
//     frame.evaluate(positions, normals, displacements, cp, cn, n, threads);
//     // draw frame.triangles() over frame.vertexCount() vertices
#pragma once

#include "strata/control_mesh.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace strata {

namespace detail {
class WorkerPool;
}

/// A perspective view: the eye, the point it looks at, the vertical field
/// of view and the viewport's height in pixels.
struct ViewSpec {
    glm::vec3 eye{0.0f, 0.0f, 1.0f};
    glm::vec3 target{0.0f};
    float fovYDegrees = 45.0f;
    float heightPx = 1080.0f;
    /// Pixels per model unit at distance 1: heightPx / (2 tan(fovY / 2)).
    float pixelsPerUnitAtDistanceOne() const;
    /// Whether the numbers describe a view (finite, eye != target, fovY in
    /// (0, 180), height > 0).
    bool valid() const;
};

/// Per control face and level 0..finest: the largest distance, in model
/// units, between the displaced surface at that level and at `finest`,
/// measured at the finest level's vertices (each against the drawn triangle
/// it lies in).  Non-increasing in the level; 0 at `finest`.
struct FaceLevelErrors {
    int finest = 0;
    size_t faceCount = 0;
    std::vector<float> error;   ///< faceCount * (finest + 1): error[f * (finest + 1) + l]
    std::vector<float> reach;   ///< per face: the largest distance from its control corners' centroid to its displaced surface
    /// faceCount * 4 * (finest + 1): the same per quarter of a face (levels
    /// 1 .. finest; level 0 holds level 1's), over the quarter's own part.
    std::vector<float> quarterError;
    float at(size_t face, int level) const { return error[face * size_t(finest + 1) + size_t(level)]; }
    float quarterAt(size_t face, int quarter, int level) const
    {
        return quarterError[(4 * face + size_t(quarter)) * size_t(finest + 1) + size_t(level)];
    }
};

/// Chooses each control face's quarter levels for a view.
///
/// init() measures FaceLevelErrors once (in the rest pose, at load) and
/// keeps the finest surface's rest positions.  choose() first takes, per
/// face, the smallest level whose error, projected at the face's nearest
/// distance to the eye, is within the pixel tolerance (a face whose
/// bounding sphere holds the eye gets the finest level); a face at level 2
/// or finer then gives each quarter the smallest level within the tolerance
/// on its own part.  Then, while a quarter's stitched tile (its strips along
/// coarser edges, and the corners where two meet) strays past the
/// tolerance, the coarsest neighbour across its coarsest edge goes up a
/// level: that error is measured exactly for the tile as drawn (at the
/// finest vertices and where its fans' edges cross the finest edges), once
/// per quarter and combination, and remembered.
class LevelChooser {
public:
    LevelChooser();
    ~LevelChooser();
    LevelChooser(const LevelChooser&) = delete;
    LevelChooser& operator=(const LevelChooser&) = delete;

    /// For `plan` (its level is the finest) with these displacements (the
    /// plan's own when null), in the pose of controlPositions/Normals.
    Status init(const Plan& plan, const float* displacements, const glm::vec3* controlPositions,
                const glm::vec3* controlNormals, size_t controlCount, int threads = 1);
    const FaceLevelErrors& errors() const { return errors_; }

    /// quarters: 4 * errors().faceCount values (caller-owned; see
    /// AdaptiveFrame::setQuarterLevels).  controlPositions:
    /// the current pose; `poseScale` (>= 1 for a pose that stretches, the
    /// largest singular value of the skin matrices: skinScale()) multiplies
    /// errors and reaches.
    ///
    /// With the pose's control normals, a face whose corner normals turn
    /// apart (a bend: the displacement directions no longer turn as one)
    /// counts its errors (1 + twice that angle in radians, or its
    /// neighbours' where larger) times larger: a displacement error along a
    /// normal tilts with it, at the point and at the drawn corners, and a
    /// smooth surface's stencils reach across the face's edges.
    ///
    /// A face the pose stretches (the largest singular value of the map from
    /// its rest triangle to its posed one, or its neighbours' where larger,
    /// where it exceeds poseScale) counts its bounding sphere that many
    /// times larger and, in the smooth scheme, its errors too (the limit
    /// surface's curvature between grid points grows with it; a linear
    /// face is flat, its error the displacement's alone).  So a pose given
    /// as control positions, with no skin to bound it, is counted as well.
    ///
    /// `previous` (4 per face, or null): the levels chosen for the frame
    /// before.  Each face and quarter keeps its previous level while that
    /// level is within the tolerance and no finer than kHoldTolerance times
    /// the tolerance would choose; past that it takes the lowest level
    /// within kMotionTolerance of the tolerance.  A level that changes has
    /// to see its error move by the band between the two before it changes
    /// back, so a moving pose or camera does not flip levels (and rebuild
    /// the frame) every frame; every level still meets the tolerance.
    ///
    /// When `previous` are the levels this chooser chose last, for the same
    /// tolerance, they stand as they are (no picking, no stitching: a
    /// fraction of the cost) while everything they draw is still within the
    /// tolerance in this view and pose and at most one face in kRepairShare
    /// could fall: its pixels per unit of error fell below kHoldTolerance
    /// of what they were at the last choice made (in full or repaired).
    /// Detail no longer needed so waits for the next choice made for
    /// another reason, or for enough of it to gather: dropping it costs a
    /// rebuild of the frame.  A face stands while it is within the
    /// tolerance and cannot fall.  Where only a few faces (at most one in
    /// kRepairShare) no longer stand, every face is picked again but the
    /// stitching starts from the last levels and checks only those faces,
    /// the faces whose levels changed and their edge neighbours (a repair;
    /// on every repair of the tests, the levels a choice in full from
    /// `previous` gives); otherwise the choice is made in full.  A choice
    /// from `previous` levels (a view or pose that moves) picks and
    /// stitches for kMotionTolerance of the tolerance, while what stands is
    /// still checked against the tolerance itself: the faces near it rise
    /// together, in one rebuild, rather than one or two a frame as a moving
    /// camera or limb sweeps them across it.
    ///
    /// `poseStamp`: a number that changes whenever controlPositions or
    /// controlNormals do (Surface's pose version), or 0: the chooser then
    /// compares them with the last pose it measured bends for, and keeps a
    /// copy.  A moving pose then costs neither.
    Status choose(uint8_t* quarters, const ViewSpec& view, float pixelError, const glm::vec3* controlPositions,
                  size_t controlCount, float poseScale = 1.0f, const glm::vec3* controlNormals = nullptr,
                  const uint8_t* previous = nullptr, uint64_t poseStamp = 0);
    /// The share of the tolerance below which a held level gives way to a
    /// coarser one (see choose).
    static constexpr float kHoldTolerance = 0.85f;
    /// The share of the tolerance a choice from previous levels aims at
    /// (see choose).
    static constexpr float kMotionTolerance = 0.85f;
    /// Choices made in full, and choices that kept the last levels (see
    /// choose), since init.
    size_t fullChoices() const { return fullChoices_; }
    size_t keptChoices() const { return keptChoices_; }
    /// Choices stitched from the faces that no longer stand (see choose).
    size_t repairedChoices() const { return repairedChoices_; }
    /// A repair is tried while at most one face in kRepairShare no longer
    /// stands.
    static constexpr size_t kRepairShare = 8;

    /// The error (model units, rest pose) of quarter `quarter` of face
    /// `face` drawn at `level` >= 1 with its edges at edgeLevels and, for the
    /// middle quarter, `coarseSides` (as adaptiveQuarterTriangles), as
    /// stitched.  A whole face at level l >= 1 is its four quarters at l.
    float stitchedQuarterError(size_t face, int quarter, int level, const int edgeLevels[3], int coarseSides);

    size_t bytes() const;

private:
    void stitch(uint8_t* quarters, float pixelError, bool fromLast);
    float templateError(const std::vector<uint16_t>& t, size_t face) const;
    const std::vector<uint16_t>& quarterTemplate(int quarter, int level, const int edgeLevels[3], int coarseSides);

    FaceLevelErrors errors_;
    std::vector<glm::vec3> rest_;          // the finest surface, rest pose
    size_t restCount_ = 0;                 // control vertices of the rest pose given to init
    // Per face corner, its rest normal in its face's rest frame (first
    // edge, in-plane normal, face normal), in 9 rows of a value per face
    // (row 3 k + axis); per face 1 where that frame exists (not degenerate).
    std::vector<float> restLocal_, restFramed_;
    std::vector<uint32_t> tiles_, controlTriangles_;
    size_t slots_ = 0, controlCount_ = 0;
    std::vector<uint16_t> slotI_, slotJ_;
    EdgeGroups edges_;
    std::vector<uint32_t> faceNeighbours_;  // per face edge the face across it (empty: an edge has more than two)
    std::vector<uint32_t> edgeOf_;
    std::vector<uint8_t> halves_, zeroEdges_;  // per edge, its two halves' levels; scratch
    std::vector<std::vector<uint16_t>> levelTiles_;  // per level, the whole face's triangles at it
    std::unordered_map<uint32_t, std::vector<uint16_t>> quarterTemplates_;
    std::unordered_map<uint64_t, float> stitchedQuarters_;
    // Per face quarter, the last stitched error looked up (its key, ~0u:
    // none): a moving view asks for the same ones frame after frame.
    std::vector<std::pair<uint32_t, float>> lastStitched_;
    // Per face: pixels per unit of error in this view and pose; the cosine
    // of its bend's widest angle (its own or its neighbours'; see choose).
    // own_: each face's own bend or stretch, before its spread; edgeSpread_:
    // the spread's per-edge scratch where an edge has more than two faces.
    std::vector<float> gains_, cosines_, own_, edgeSpread_;
    // Per face: its rest edges' Gram matrix and inverse determinant (4 rows),
    // and the pose's stretch of it, spread to its neighbours (see choose).
    std::vector<float> restGram_, stretches_;
    bool smooth_ = false;  // the plan's scheme
    template <bool kLeast>
    void spread(const float* own, std::vector<float>* out);
    std::vector<glm::vec3> bentPositions_, bentNormals_;  // the pose cosines_ is for (no stamp)
    uint64_t bentStamp_ = 0;                              // or its stamp
    std::vector<float> corners_, cornerNormals_;          // the pose's, a row per corner axis
    // The last choice made (in full or repaired): its levels and tolerance,
    // and per face its gain and the largest error (rest pose, model units)
    // of what it draws.
    std::vector<uint8_t> lastQuarters_;
    std::vector<float> chosenGains_, drawnErrors_;
    float lastTolerance_ = 0.0f;
    size_t fullChoices_ = 0, keptChoices_ = 0, repairedChoices_ = 0;
    std::vector<uint8_t> seen_, recheck_, touched_;  // the stitching pass's scratch
    std::vector<uint32_t> moved_;                    // a repair's faces that no longer stood
};

/// The largest singular value of the upper 3x3 of any of `count` matrices
/// (1 for none): how much a skinned pose can stretch a distance.
float skinScale(const float* matrices4x4, size_t count);

/// The triangles of a control face at level `level` whose three edges are
/// drawn at edgeLevels[k] <= level (edge k from corner k to corner k + 1), as
/// slots of the finest tile (tileSlot(i, j, 2^finest)), counter-clockwise.
/// What AdaptiveFrame draws per face, and a GPU's index template per
/// (level, edge levels).
void adaptiveTileTriangles(std::vector<uint16_t>* out, int finest, int level, const int edgeLevels[3]);

/// The triangles of quarter `quarter` (0, 1, 2 at the control face's corners
/// 0, 1, 2; 3 the middle one) drawn at control level `level` (1 .. finest),
/// as slots of the face's finest tile, counter-clockwise.  Its edges, in its
/// own corner order (quarter k: corner k, then the face's edge midpoints
/// going counter-clockwise; the middle: the midpoints of edges 1, 2, 0), are
/// drawn at edgeLevels[k] <= level (0 only on a control edge drawn at level
/// 0).  The middle quarter's corners lie on the face's edges: bit k of
/// `coarseSides` says edge k is drawn at level 0 (that corner then snaps to
/// the edge's first corner); 0 for the other quarters.
void adaptiveQuarterTriangles(std::vector<uint16_t>* out, int finest, int quarter, int level, const int edgeLevels[3],
                              int coarseSides);

class AdaptiveFrame {
public:
    /// For `plan` (its level is the finest; the plan must outlive the frame).
    explicit AdaptiveFrame(const Plan& plan);
    ~AdaptiveFrame();
    AdaptiveFrame(const AdaptiveFrame&) = delete;
    AdaptiveFrame& operator=(const AdaptiveFrame&) = delete;

    /// Sets each control face's level (count = control faces, each <= the
    /// plan's level) and builds the frame's vertices and triangles.  Costs
    /// time in the vertices drawn; allocates only to grow past the largest
    /// frame so far (and the first time a (level, edge levels) combination
    /// appears).
    Status setLevels(const uint8_t* levels, size_t count);
    /// Sets the level of each quarter of each control face (count = 4 per
    /// face: the quarters at corners 0, 1, 2, then the middle one): all four
    /// 0 (the face at level 0), or each in 1 .. the plan's level.  Four equal
    /// levels draw the face as setLevels does.
    Status setQuarterLevels(const uint8_t* quarters, size_t count);
    /// Per control face, its finest quarter's level.
    const std::vector<uint8_t>& levels() const { return levels_; }
    /// Per control face, its four quarters' levels (4 per face).
    const std::vector<uint8_t>& quarterLevels() const { return quarters_; }
    /// The level triangle `t` is drawn at (its quarter's).
    int triangleLevel(size_t t) const;
    /// How many control faces are drawn as quarters of mixed levels.
    size_t splitFaceCount() const;
    /// Per triangle corner (3 per triangle), face-varying UVs at its grid
    /// point, linear inside its control face as the plan refines UVs:
    /// control face f's corner k has uvs[uvIndices[3 f + k]].
    void cornerUVs(std::vector<glm::vec2>* out, const glm::vec2* uvs, const uint32_t* uvIndices) const;

    /// The frame's vertices and triangles (3 per triangle, counter-clockwise,
    /// indexing the frame's vertices) for the current levels.
    size_t vertexCount() const { return vertices_.size(); }
    size_t triangleCount() const { return triangles_.size() / 3; }
    const std::vector<uint32_t>& triangles() const { return triangles_; }
    /// Per frame vertex, its refined vertex in the plan (to place per-vertex
    /// attributes, and what the frame evaluates).
    const std::vector<uint32_t>& vertices() const { return vertices_; }
    /// Per triangle, its control face (to place face-varying UVs: the
    /// corner's grid point is cornerSlots()).
    const std::vector<uint32_t>& triangleFaces() const { return triangleFaces_; }
    /// Per triangle corner, its slot in its control face's finest tile.
    const std::vector<uint16_t>& cornerSlots() const { return cornerSlots_; }
    /// Counts the topologies set (every setLevels or setQuarterLevels that
    /// succeeds): what was laid out for the frame's vertices and triangles
    /// holds while it stays the same.
    uint64_t topologyVersion() const { return topologyVersion_; }

    /// Displaced positions (and shading normals when normals is not null:
    /// the area-weighted sum of the incident frame triangles' normals,
    /// normalised) of vertexCount() vertices.  displacements: the plan's own
    /// when null.  Arguments as Plan::evaluate.  Bit-identical for any thread
    /// count; allocates nothing once warmed up (the first frame, or the
    /// first with more threads).
    Status evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                    const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                    int threads = 1);

    /// The largest deviation, in pixels of `view`, of this frame from the
    /// finest surface.  At every finest-level vertex of a control face, and
    /// wherever a frame triangle's edge crosses a finest edge (a stitched
    /// triangle's do, between the finest vertices; both surfaces are linear
    /// on each piece between, so these are where their distance peaks), the
    /// frame triangle's point at the same grid place (the surface as drawn
    /// there) against the finest surface's: the larger of the distance between their
    /// projections and their distance in space seen at the vertex's depth
    /// (a deviation along the line of sight moves no pixel but changes
    /// depth and shading).  Points behind the eye are skipped, and points a
    /// few float steps apart (8 of their largest coordinate) count as one:
    /// two evaluation orders of a vertex differ so, and a point a hair in
    /// front of the eye's plane projects that to millions of pixels.
    /// Computed in double.
    /// \param framePositions  vertexCount() positions from evaluate()
    /// \param finePositions   the plan's refinedVertexCount() positions in the same pose
    /// \param subdivision     also samples on a lattice this many times
    ///                        finer than the finest level's (1..64; the
    ///                        finest surface interpolated there): a check
    ///                        of the crossings, which find no less (tests,
    ///                        bench_runtime)
    float maxScreenDeviation(const glm::vec3* framePositions, const glm::vec3* finePositions, const ViewSpec& view,
                             int subdivision = 1) const;

    size_t bytes() const;

private:
    template <typename Body>
    void parallel(int threads, size_t n, const Body& body);
    size_t templateFor(int level, const int edgeLevels[3]);

    const Plan& plan_;
    int finest_ = 0;
    uint64_t topologyVersion_ = 0;
    size_t slots_ = 0;
    std::vector<uint32_t> tiles_;         // per control face, its finest tile's refined vertices
    std::vector<uint16_t> slotI_, slotJ_; // the finest tile's grid point per slot
    std::vector<uint32_t> edgeOf_;        // per face corner (3 f + k): its undirected edge
    std::vector<uint8_t> halves_;         // per edge: its two halves' levels for the current quarters
    std::vector<uint8_t> zeroEdges_;      // setQuarterLevels' scratch
    // By (level, e0, e1, e2), built on first use: the triangles in the
    // finest tile's slots; at kGridLevel and finer, also in the level's grid
    // slots, where each grid point is drawn, and the points drawn elsewhere
    // (pairs: slot, the slot it is drawn at).
    // Quarters the same (at kGridLevel + 1 and finer, `local` in the
    // quarter's own grid, when every point snaps to a point of it: `grid`).
    struct TileTemplate {
        std::vector<uint16_t> fine, local, snapTo, snaps;
        // The distinct finest-tile slots of `fine` in the order its corners
        // first use them, each corner's index among them, and (a template
        // with a grid) each distinct slot's grid slot: a frame numbers a
        // unit's vertices once per slot, not once per corner.
        std::vector<uint16_t> used, corner, usedLocal;
        bool grid = false;
        void indexCorners(size_t tileSlots);
        void indexLocal();
    };
    std::vector<TileTemplate> templates_;
    std::unordered_map<uint32_t, TileTemplate> quarterTemplates_;
    const TileTemplate& quarterTemplateFor(int quarter, int level, const int edgeLevels[3], int coarseSides);
    std::vector<uint8_t> levels_, quarters_, quarterScratch_;
    // setQuarterLevels' drawn units (a whole face or a quarter of one) and,
    // per frame vertex (room for the plan's), its refined vertex and its
    // count of normal shares (then its cursor among them).
    struct Unit {
        const TileTemplate* tt;
        uint32_t face, gridIndex;
        bool grid, whole;
    };
    std::vector<Unit> units_;
    std::vector<uint32_t> frameVertex_, shareCount_;
    std::vector<uint8_t> written_;        // per frame vertex: its position written by the tile pass
    std::vector<uint32_t> remap_;         // per refined vertex: its frame vertex, or ~0
    std::vector<uint32_t> vertices_, triangles_, triangleFaces_;
    std::vector<uint16_t> cornerSlots_;

    // The tile pass, over the faces drawn whole at kGridLevel or finer and
    // the quarters at kGridLevel + 1 or finer (gridFaces_, each with its grid
    // in gridOf_).  Per level (and per quarter and level, past the levels),
    // its grid (detail::GridScratch's layout): row
    // starts, barycentrics per slot (padded to whole vectors), and each
    // slot's slot in the finest tile.  Per grid face: per slot, its
    // displacement's refined vertex (linear) or the frame vertex whose
    // position it takes (smooth); the frame vertices it writes (its own
    // positions, linear; its inner normals); its snapped points (linear).
    struct LevelGrid {
        uint32_t res = 0;  // segments an edge
        std::vector<uint32_t> rows;
        std::vector<float> w1, w2;
        std::vector<uint16_t> fine;
        std::vector<uint8_t> border;  // per slot: on the grid's border
    };
    struct GridWrite {
        uint32_t vertex;
        uint16_t slot, inner;
    };
    std::vector<LevelGrid> levelGrids_;
    std::vector<uint32_t> gridFaces_, gridOf_, gridFirst_, gridSlots_, gridWriteFirst_, gridSnapFirst_, gridPartialFirst_;
    std::vector<GridWrite> gridWrites_;
    std::vector<uint16_t> gridSnaps_;
    std::vector<uint16_t> gridPartialSlots_;  // per partial sum: its grid slot
    std::vector<uint32_t> partialVertex_;     // per partial sum: its frame vertex
    std::vector<uint32_t> slotVertex_;  // setLevels' scratch: per grid slot, its frame vertex
    std::vector<uint32_t> unitVertex_;  // setLevels' scratch: per distinct slot of a unit, its frame vertex
    struct Scratch;
    struct TileJob;
    std::vector<Scratch> scratch_;  // per thread
    static void shadeTiles(const TileJob& job, Scratch& s, size_t begin, size_t end);
    // The gather pass, for every other vertex (gathered_): its shares of
    // shares_, which holds the grid tiles' partial sums and then the normals
    // of the small tiles' triangles (gatherTriangles_).
    std::vector<uint8_t> gathered_;
    std::vector<uint32_t> gatherVertices_, gatherOffsets_, gatherEntries_, gatherTriangles_;
    std::vector<glm::vec3> shares_;
    // Linear scheme: the vertices of faces below kGridLevel.
    struct LinearVertex {
        uint32_t c[3], target;
        float w1, w2, d;
    };
    std::vector<LinearVertex> linear_;
    std::unique_ptr<detail::WorkerPool> pool_;
};

}  // namespace strata
