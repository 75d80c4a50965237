// Strata examples: procedural control meshes and closed-form surfaces.
//
// The built-in example (the paper's demo: a detailed head-like surface over
// an icosahedron control mesh) and the closed-form test cases (sphere over
// icosahedron, sine over a square) are generated here, in code, so the
// project's own examples need no data files.
#pragma once

#include "strata/control_mesh.h"
#include "strata/displacement_map.h"
#include "strata/status.h"

#include <glm/vec3.hpp>

#include <functional>

namespace strata {
namespace examples {

/// A regular icosahedron inscribed in the unit sphere, each face split
/// 4^subdivisions times with new vertices projected onto the sphere.
/// Counter-clockwise seen from outside; no UVs.
ControlMesh makeIcosphere(int subdivisions);

/// A square [0,1] x [0,1] in the z = 0 plane as two triangles, normal +z,
/// with UV = (x, y).
ControlMesh makeSquare();

/// A star-shaped surface: the distance from the origin along each unit direction.
using RadiusFunction = std::function<float(const glm::vec3& unitDirection)>;

/// The built-in example: a head-like shape (cranium, brow, nose, cheeks,
/// ears, chin) with fine surface ripples, about unit size, facing +z, up +y.
float headRadius(const glm::vec3& unitDirection);

/// The built-in example's "capture": makeIcosphere(subdivisions) with every
/// vertex moved out to headRadius (20 * 4^subdivisions triangles).
ControlMesh makeHead(int subdivisions);

/// Closed-form displacement map of a star-shaped surface over a control mesh
/// with UVs: for each texel covered by a UV triangle (plus `gutter` texels
/// around it), the surface point p and direction n of paper eq. 2 are
/// evaluated with the runtime's normals, and d solves |p + d n| = R(...)
/// exactly (bisection to float precision).  Used by the built-in example and
/// by the closed-form tests; real meshes go through the baker.
Status bakeRadialSurface(DisplacementMap* out, const ControlMesh& mesh, int mapSize, int gutter,
                         const RadiusFunction& radius);

}  // namespace examples
}  // namespace strata
