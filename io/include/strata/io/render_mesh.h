// Strata io: the refined surface laid out as a renderer draws it.
//
// A rig's refined vertices carry one position each, but the glTF parts it
// came from carry per-corner attributes (material UVs, colours) that differ
// across seams and between parts.  A renderer needs one vertex per
// (refined vertex, refined corner value): RenderMesh is that layout, made
// once per surface, and gather() places each frame's positions and normals
// into it.  Its first refinedVertexCount vertices are the refined vertices
// themselves, in the plan's order (what strata-reconstruct writes to .obj
// and .ply), each with the corner value of its first triangle; the copies a
// seam needs follow.  The indices keep the plan's triangle order, so each
// part's triangles are one contiguous range.  The WebAssembly runtime's
// three.js plugin draws through it; scene_writer refines the same
// attributes per part.
#pragma once

#include "strata/adaptive.h"
#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <glm/vec3.hpp>

#include <string>
#include <vector>

namespace strata {
namespace io {

struct RenderPart {
    uint32_t firstIndex = 0, indexCount = 0;  ///< its range of RenderMesh::indices
    int mesh = -1, primitive = -1;            ///< glTF mesh and primitive (-1: not from glTF)
    int material = -1;                        ///< glTF material, -1 for the default one
    bool flat = false;                        ///< drawn with face normals (RigPart::flat)
};

/// A per-corner attribute of the source primitives (TEXCOORD_n, COLOR_n,
/// custom _NAME), refined linearly inside each control face; zero on
/// parts that do not have it (a COLOR_n: white, as glTF draws them).
struct RenderAttribute {
    std::string name;
    int components = 0;
    std::vector<float> values;  ///< components per render vertex
};

struct RenderMesh {
    size_t refinedVertexCount = 0;
    /// Per render vertex: its refined vertex (an adaptive layout: its
    /// adaptive frame vertex).
    std::vector<uint32_t> refinedVertex;
    std::vector<uint32_t> indices;        ///< 3 per refined triangle, into the render vertices
    std::vector<RenderPart> parts;
    std::vector<RenderAttribute> attributes;
    /// Per refined vertex with seam copies (an empty table: none), the
    /// render vertex each control face around it uses, faces ascending:
    /// entries offsets[v] .. offsets[v + 1] of faces and vertices.  What
    /// buildAdaptiveRenderMesh reads a grid point's values by, made once.
    struct Seams {
        std::vector<uint32_t> offsets, faces, vertices;
    } seams;

    size_t vertexCount() const { return refinedVertex.size(); }
    /// Copies per-refined-vertex values (plan order) to the render vertices.
    void gather(const glm::vec3* refined, glm::vec3* out) const;
};

/// The layout of `plan` (a refinement of rig.mesh, as Surface::plan()).  A
/// rig not loaded from glTF is one part without attributes.
Status buildRenderMesh(const Rig& rig, const Plan& plan, RenderMesh* out);

/// The same for `frame`'s current levels (an AdaptiveFrame of `plan`, laid
/// out by `uniform` = buildRenderMesh(rig, plan)): one vertex per (frame
/// vertex, corner value), the frame's vertices first in frame order, seam
/// copies after; refinedVertexCount is the frame's vertex count and
/// refinedVertex names frame vertices, so gather() takes
/// AdaptiveFrame::evaluate's output.  The parts and attributes are
/// uniform's, each vertex with the value its grid point has at the finest
/// level, so textures map as they do there.  Holds until the frame's
/// topologyVersion() changes.
Status buildAdaptiveRenderMesh(const RenderMesh& uniform, const Plan& plan, const AdaptiveFrame& frame,
                               RenderMesh* out);

}  // namespace io
}  // namespace strata
