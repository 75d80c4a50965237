// Strata runtime: displacements stored per refined vertex.
//
// A rig evaluated at level L reads its map once per refined vertex (one
// sample each, so seams cannot crack).  Those N_L numbers are all the map
// contributes at levels 0..L, and they are far fewer than the texels of a
// map that resolves them.  A rig may therefore store them directly, in
// subdivision order, each predicted from the edge it splits (docs/FORMAT.md,
// "vertex" encoding); io/ entropy-codes the residuals.
//
// OpenSubdiv numbers the vertices of level l + 1 so that the first N_l are
// the children of the level-l vertices, in order; the rest are the midpoints
// of the level-l edges; the coder relies on it (checked when the hierarchy
// is built).  DisplacementField evaluates the stored values anywhere.
#pragma once

#include "strata/control_mesh.h"
#include "strata/status.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace strata {

/// The subdivision hierarchy of mesh's uniform refinement to `level`, in
/// level-`level` vertex numbering.
struct SubdivisionParents {
    /// levelCounts[l]: vertices at level l (levelCounts[0] is the control
    /// vertex count); level + 1 entries.
    std::vector<uint32_t> levelCounts;
    /// Two per vertex past the control vertices: the ends of the edge it
    /// splits (vertex v >= levelCounts[0] uses entries 2 (v - levelCounts[0])
    /// and the next).  Both ends are vertices of an earlier level.
    std::vector<uint32_t> parents;
};

/// Builds the hierarchy with OpenSubdiv (the same refiner as Plan) and checks
/// the numbering described above.
Status buildSubdivisionParents(SubdivisionParents* out, const ControlMesh& mesh, int level);

/// The displacement that per-vertex values at level L define over the whole
/// control mesh: per control face, the values at its level-L grid points
/// (b1, b2) = (i, j) / 2^L, interpolated linearly inside each grid triangle
/// of the 1-to-4 split.  At levels up to L every refined vertex lands on a
/// grid point (its own value); past L this is the edge-midpoint rule.
class DisplacementField {
public:
    /// \param values  one per vertex of mesh's uniform refinement to `level`
    static Status create(DisplacementField* out, const ControlMesh& mesh, int level, const std::vector<float>& values);

    int level() const { return level_; }
    /// The distance at barycentrics (b1, b2) of control face `face`.
    float evaluate(uint32_t face, float b1, float b2) const;

private:
    int level_ = 0;
    uint32_t side_ = 1;        // 2^level
    size_t perFace_ = 3;       // (side + 1) (side + 2) / 2
    std::vector<float> grid_;  // perFace_ per control face, rows of constant j
};

/// The quantisation of stored values (docs/FORMAT.md): q_i = round((d_i -
/// dmin) / s), s = step (range / 65535 for step 0, at least range / (2^24 -
/// 1), so every q is exact in a float), clamped to the levels the range
/// spans; a value decodes as strata_decode_distance(q, factor, offset) with
/// factor = s, offset = dmin.  The coder and the baker (which measures the
/// quantised values before it settles a step) share it.  Fails on a value
/// that is not finite.
Status quantizeDisplacements(const std::vector<float>& values, double step, std::vector<int32_t>* q, float* factor,
                             float* offset);

/// Integer prediction in subdivision order, lossless: control vertex v is
/// predicted by control vertex v - 1 (0 for the first), every later vertex by
/// the floor of the mean of its two parents.  residuals[i] = q[i] - prediction.
void predictSubdivisionResiduals(const SubdivisionParents& h, const int32_t* q, int32_t* residuals);
/// The inverse of predictSubdivisionResiduals.
void reconstructSubdivisionValues(const SubdivisionParents& h, const int32_t* residuals, int32_t* q);

}  // namespace strata
