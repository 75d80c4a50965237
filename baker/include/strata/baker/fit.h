// Strata baker: fitting the control mesh to the capture (Lee, Moreton and
// Hoppe, Displaced Subdivision Surfaces, section 4.2).
//
// A cage drawn or decimated on the capture has its vertices on the surface,
// so its Loop limit surface shrinks inside convex parts and its flat
// triangles cut chords: the displacements must then carry the difference,
// and where the cage's normals cannot reach (an ear, a finger's side) they
// cannot.  Fitting moves the control vertices, keeping topology, UVs and
// anything per vertex, so that the scheme's base surface itself lies close
// to the capture in both directions.
#pragma once

#include "strata/baker/bake.h"
#include "strata/baker/distance.h"
#include "strata/control_mesh.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <cstddef>
#include <vector>

namespace strata {
namespace baker {

struct FitOptions {
    Scheme scheme = Scheme::Smooth;  ///< the base surface fitted: the limit surface or the flat cage
    int level = 3;                   ///< samples of the base surface: its refined vertices at this level
    int iterations = 4;              ///< correspondence rounds (nearest points found anew each round)
    /// Weight of keeping each control vertex's Laplacian (its offset from its
    /// neighbours' mean) as it was, against the two distance terms: holds the
    /// cage's shape where the capture says little and keeps it from folding.
    double smoothness = 0.05;
    /// A fit is a refinement, not a registration: a cage whose base surface
    /// lies farther than this fraction of the capture's bounding-box
    /// diagonal from it (RMS), or that the fit would move a vertex farther
    /// than that, is left as it is (the bake then reports what is wrong).
    double maxMove = 0.1;
    int threads = 2;
};

struct FitStats {
    double rmsBefore = 0.0;  ///< base surface to capture, both directions (larger RMS), model units
    double rmsAfter = 0.0;
    double maxMove = 0.0;    ///< largest control vertex displacement, model units
};

/// Moves control->positions so that the base surface of options.scheme
/// approximates `high` (indexed by highIndex) in the least-squares sense,
/// both directions: the base surface's samples to their nearest capture
/// points, and the capture's vertices to their nearest base-surface points.
/// Leaves the mesh untouched when the fit does not lower the error or the
/// cage is too far from the capture (options.maxMove).
Status fitControlMesh(ControlMesh* control, const TriangleMesh& high, const TriangleIndex& highIndex,
                      const FitOptions& options, FitStats* stats = nullptr);

/// Per-vertex displacements fitted to the capture: the values at `level`'s
/// refined vertices of `mesh` in `scheme` (as a rig stores them) that place
/// the displaced refined mesh closest to `high` in the least-squares sense,
/// both directions (each displaced vertex to its nearest capture point,
/// each capture vertex to its nearest point of the displaced mesh), from
/// `values` as the first guess, over `iterations` correspondence rounds.
/// Where a sample's nearest capture point lies along its direction this is
/// the sampled distance; between samples the capture's creases pull the
/// values so the triangles pass close to them.
Status fitVertexDisplacements(std::vector<float>* values, const ControlMesh& mesh, Scheme scheme, int level,
                              const TriangleMesh& high, const TriangleIndex& highIndex, int iterations, int threads);

}  // namespace baker
}  // namespace strata
