// Strata runtime: the control mesh M^L (paper section 2).
//
// Positions are stored once per *topological* vertex; UVs are face-varying
// (one index per triangle corner), so a UV seam never splits a vertex.  This
// is the representation the refiner, the normal function and the baker share.
#pragma once

#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace strata {

struct ControlMesh {
    std::vector<glm::vec3> positions;   ///< one per topological vertex
    std::vector<uint32_t> triangles;    ///< 3 vertex indices per face, counter-clockwise seen from outside
    std::vector<glm::vec2> uvs;         ///< face-varying UV values, glTF convention (v = 0 is the image's first row)
    std::vector<uint32_t> uvIndices;    ///< 3 indices into uvs per face; empty when the mesh has no UVs

    size_t vertexCount() const { return positions.size(); }
    size_t faceCount() const { return triangles.size() / 3; }
    bool hasUVs() const { return !uvIndices.empty(); }
};

/// Checks that a control mesh can be refined: at least one face, indices in
/// range, no repeated vertex inside a face (zero area: loaders drop such
/// faces), finite positions and UVs, UV indices matching the faces.  Any
/// topology is accepted beyond that: edges shared by any number of faces,
/// non-manifold vertices, inconsistent orientation and unreferenced
/// vertices all refine (OpenSubdiv treats non-manifold features as sharp).
/// The message names the first offending face, vertex or UV.
Status validateControlMesh(const ControlMesh& mesh);

/// What a displacement layer was baked against, so that a control mesh that
/// changed after the bake is refused rather than displaced wrongly (the
/// per-vertex values are numbered by the refinement of exactly this mesh).
/// `topology` and `positions` are order-sensitive FNV-1a hashes (vertex count
/// and triangle indices; position bit patterns with -0 read as +0); `shape`
/// is order-insensitive (the sum over faces of a hash of the corners'
/// positions from the corner whose hash is smallest, winding kept), so a
/// mesh that was only renumbered keeps its shape and loses its topology.
struct ControlMeshFingerprint {
    size_t vertices = 0, faces = 0;
    uint64_t topology = 0, positions = 0, shape = 0;
};

ControlMeshFingerprint fingerprintControlMesh(const ControlMesh& mesh);

/// The order-sensitive topology hash alone (ControlMeshFingerprint::topology).
uint64_t controlTopologyHash(const uint32_t* triangles, size_t faceCount, size_t vertexCount);

/// The undirected edges of an indexed triangle list with the corners whose
/// edge each is: the one home of edge adjacency (boundary and non-manifold
/// edges, face neighbours, border loops).  Corner c = 3 * face + k stands
/// for the edge from the face's k-th vertex to its (k+1)-th.  Every corner
/// is listed once, grouped by edge; edges come in order of their lower
/// vertex, then their higher one, and corners ascend within an edge.
struct EdgeGroups {
    std::vector<uint32_t> corners;  ///< 3 per face, grouped by edge
    std::vector<uint32_t> offsets;  ///< edgeCount() + 1: edge e is corners [offsets[e], offsets[e + 1])
    size_t edgeCount() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    /// The corners of edge e, and how many faces use it (1: a boundary edge,
    /// 2: an interior one, more: non-manifold).
    const uint32_t* cornersOf(size_t e) const { return corners.data() + offsets[e]; }
    uint32_t faceCountOf(size_t e) const { return offsets[e + 1] - offsets[e]; }
};

/// Groups the corners of faceCount triangles by undirected edge, in time
/// linear in the corners (a counting sort on each edge's lower vertex; the
/// handful of edges at a vertex sorted in place).
EdgeGroups groupEdges(const uint32_t* triangles, size_t faceCount);

/// Counts used by tests and tools: edges, boundary edges, non-manifold edges.
struct MeshTopologyStats {
    size_t vertices = 0;          ///< vertices referenced by at least one face
    size_t edges = 0;
    size_t boundaryEdges = 0;     ///< edges with exactly one face
    size_t nonManifoldEdges = 0;  ///< edges with more than two faces
    long eulerCharacteristic = 0; ///< V - E + F over referenced vertices
};

/// Topology statistics of an indexed triangle list (3 indices per face).
MeshTopologyStats computeTopologyStats(const uint32_t* triangles, size_t faceCount);

}  // namespace strata
