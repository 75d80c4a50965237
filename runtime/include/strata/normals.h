// Strata runtime: control vertex normals, the n_j of paper equation 1.
//
// The one function that both the baker (normal-volume mapping) and the
// runtime (every animated frame) call, so the normal volumes the map was
// baked in are exactly the ones it is displaced along.
//
// Weighting: each triangle adds its unit face normal times its interior
// angle at the vertex (Thurmer & Wuthrich 1998).  Angle weighting makes the
// result independent of how a polygon was split into triangles, which matters
// because glTF and OBJ control meshes arrive triangulated in arbitrary ways.
// Degenerate triangles (zero area) add nothing.  A vertex whose sum is zero
// (isolated, or only degenerate faces) gets the normal (0, 0, 0): it then
// carries no displacement, which is the only safe choice.
#pragma once

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace strata {

/// Writes one unit normal per vertex into dst.
/// \param dst        vertexCount normals (caller-owned, overwritten)
/// \param positions  vertexCount positions
/// \param triangles  3 * faceCount vertex indices, each < vertexCount
/// \pre indices are in range (validateControlMesh guarantees it).  Allocates nothing.
void computeControlNormals(glm::vec3* dst, const glm::vec3* positions, size_t vertexCount, const uint32_t* triangles,
                           size_t faceCount);

/// Each vertex's faces, ascending (the order a scatter over faces adds in):
/// vertex v's are faces[offsets[v] .. offsets[v + 1]).  A face appears once
/// per corner it has at v.
void buildVertexFaces(std::vector<uint32_t>* offsets, std::vector<uint32_t>* faces, const uint32_t* triangles,
                      size_t faceCount, size_t vertexCount);

}  // namespace strata
