// Strata baker: the surface high-resolution vertices are mapped onto.
//
// Linear scheme: the control mesh itself with the runtime's control normals
// (paper 2.1).  Smooth scheme: the Loop limit surface sampled densely by the
// runtime's own smooth Plan, with unit limit normals; its face-varying UVs
// are the control UVs interpolated linearly, exactly as the runtime samples.
#pragma once

#include "strata/control_mesh.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <vector>

namespace strata {
namespace baker {

struct BakeSurface {
    std::vector<glm::vec3> positions;  ///< per vertex
    std::vector<glm::vec3> normals;    ///< per vertex: the eq. 1 n_k
    std::vector<uint32_t> triangles;   ///< 3 per face
    std::vector<glm::vec2> uvs;        ///< face-varying values, glTF convention
    std::vector<uint32_t> uvIndices;   ///< 3 per face
    // Vertex -> incident faces (CSR), for stepping across border triangles.
    std::vector<uint32_t> ringOffsets, ringFaces;

    size_t faceCount() const { return triangles.size() / 3; }
    /// True when faces a and b share an edge.
    bool edgeAdjacent(uint32_t a, uint32_t b) const;
};

/// Builds the bake surface for `scheme` from a control mesh with UVs.
/// Smooth surfaces are sampled at `denseLevel` (4^level triangles per control face).
Status buildBakeSurface(BakeSurface* out, const ControlMesh& control, Scheme scheme, int denseLevel = 3);

}  // namespace baker
}  // namespace strata
