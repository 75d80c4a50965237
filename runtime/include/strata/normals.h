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

/// Each vertex's incident faces as fans of its one-ring, the layout the GPU
/// normal pass reads (shaders/normals.comp.glsl): a face (v, a, b), corners
/// counter-clockwise, is the ring step a -> b, and consecutive faces share a
/// ring vertex, so an interior vertex of valence k reads k neighbours instead
/// of the 2k corners of its faces.  Vertex v's entries are
/// entries[offsets[v] .. offsets[v + 1]), each a vertex index (kFanIndexMask)
/// with flags: kFanStart begins a fan (its first ring vertex), kFanClose on a
/// fan's last entry adds the face back to the fan's first (a closed ring).
/// Every face with exactly one corner at v appears once; a face with two
/// corners at v (area normal zero at v) is left out.  Non-manifold and
/// boundary vertices get several or open fans.  Sizes are linear; the
/// vertex count must stay below kFanIndexMask.
void buildVertexFans(std::vector<uint32_t>* offsets, std::vector<uint32_t>* entries, const uint32_t* triangles,
                     size_t faceCount, size_t vertexCount);
constexpr uint32_t kFanStart = 0x80000000u, kFanClose = 0x40000000u, kFanIndexMask = 0x3fffffffu;

/// Unit area-weighted vertex normals from buildVertexFans's layout: the sum
/// of cross(a - p, b - p) over each fan's ring steps, normalised ((0, 0, 0)
/// where it vanishes).  The CPU mirror of the GPU normal pass, operation
/// for operation.
void computeFanNormals(glm::vec3* dst, const glm::vec3* positions, size_t vertexCount, const uint32_t* offsets,
                       const uint32_t* entries);

}  // namespace strata
