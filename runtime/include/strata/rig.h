// Strata runtime: the control rig as plain data (docs/FORMAT.md).
//
// The io layer fills this from a .glb/.gltf file; engines that have their own
// asset pipeline can fill it directly.  No file format code lives here.
#pragma once

#include "strata/animation.h"
#include "strata/control_mesh.h"
#include "strata/plan.h"

#include <glm/mat4x4.hpp>

#include <memory>
#include <string>
#include <vector>

namespace strata {

/// Version of the rig format this build writes: 5 is the declared glTF
/// extension STRATA_layered_displacement (docs/STRATA_layered_displacement.md);
/// versions 1 to 4, the "strata" block in mesh extras, are still read.
constexpr int kRigFormatVersion = 5;

/// The glTF document a rig was loaded from, kept whole so that writing the
/// rig back loses nothing (materials, textures, names, extras, primitives
/// Strata does not refine).  Opaque here: only strata_io reads it.
struct SourceDocument;

/// How the rig's displacement map is stored and applied.
struct DisplacementInfo {
    std::string uri;            ///< EXR beside the rig, relative URI (empty: the map is embedded)
    int image = -1;             ///< glTF image holding the embedded map (format version 2), or -1
    std::vector<unsigned char> embedded;  ///< the embedded image's (or vertex data's) encoded bytes, filled by the loader
    int texCoord = 0;           ///< TEXCOORD_n set the map is sampled through
    std::string encoding;       ///< "exr" (half or float texels), "png8", "png16" or "vertex"
    int width = 0;              ///< map size the image must have
    int height = 0;
    float factor = 1.0f;        ///< displacementGeometryFactor: d = texel * factor + offset
    float offset = 0.0f;        ///< displacementGeometryOffset
    Scheme scheme = Scheme::Linear;
    int recommendedLevel = 3;
    /// The layer's "shading": "flat": the capture was drawn with face normals
    /// (a glTF capture without NORMAL), so the rig's primitives without
    /// NORMAL are drawn so too.  False: the displaced surface is drawn smooth.
    bool flatShading = false;
    /// Encoding "vertex" (format versions 3 and 4): the map's samples at the refined
    /// vertices of `vertexLevel`, decoded by the loader (d, in model units;
    /// vertex_displacements.h).  width/height then give the size of the map
    /// rasterised from them for texture consumers (0 in a version 4 rig
    /// without UVs, which has no map).
    int vertexLevel = -1;
    int vertexView = -1;  ///< the glTF bufferView holding them coded (loader, versions 3 and 4), or -1
    int vertexAccessor = -1;  ///< the glTF accessor holding them coded (loader, version 5), or -1
    std::vector<float> vertexValues;
    /// Optional second copy of the map as an 8- or 16-bit PNG quantised with
    /// paper eq. 12: q = round((2^bits - 1) (d - dmin) / (dmax - dmin)).
    struct Quantized {
        std::string uri;  ///< empty: none
        int bits = 0;     ///< 8 or 16
        float dmin = 0.0f, dmax = 0.0f;
    } quantized;
};

/// One triangle primitive of the source scene: a range of the control
/// mesh's faces and of the file vertices.
struct RigPart {
    int mesh = -1, primitive = -1;  ///< glTF mesh and primitive index
    int node = -1;                  ///< the node that instances it (its first), or -1
    int instance = -1;              ///< its EXT_mesh_gpu_instancing instance on that node, or -1
    glm::mat4 instanceTransform{1.0f};  ///< that instance's transform in its node's space (in toScene)
    int material = -1;              ///< glTF material, -1 for the default one
    bool skinned = false;           ///< the node has a skin (else rigid on its node)
    /// Drawn with face normals: a glTF primitive without NORMAL, which glTF
    /// shades flat, in a plain file or in a rig whose layer says its capture
    /// was drawn so (DisplacementInfo::flatShading).  Runtime normals stay
    /// smooth; this is the renderer's choice of which to shade with.
    bool flat = false;
    glm::mat4 toScene{1.0f};        ///< mesh space -> the control mesh's space at rest
    uint32_t firstFace = 0, faceCount = 0;      ///< its faces in mesh.triangles
    uint32_t firstVertex = 0, vertexCount = 0;  ///< its file vertices (sourceVertex)
    std::string name;               ///< "mesh name/primitive index", for messages
};

struct Rig {
    ControlMesh mesh;                 ///< welded: one position per topological vertex
    std::vector<uint32_t> sourceVertex;  ///< per file vertex: its topological vertex in mesh
    std::vector<uint32_t> fileCorners;   ///< per face corner of mesh: the file vertex it came from
    std::vector<RigPart> parts;       ///< the triangle primitives, in face order (one part for OBJ input)
    /// The UV set mesh.uvs was loaded from (TEXCOORD_n of every part), or -1,
    /// and a hash of the values loaded: a writer keeps the file's UVs only
    /// while mesh.uvs still holds them.
    int fileTexCoord = -1;
    uint64_t fileUVHash = 0;
    std::shared_ptr<const SourceDocument> source;  ///< null unless loaded from glTF
    bool hasDisplacement = false;     ///< false for a plain glTF without a strata block
    /// Loaded from glTF without the layer: why (a tool dropped it, or the
    /// file was never baked).  Surface refuses such a rig unless asked for
    /// the bare cage, so a stripped file is never drawn as the baked surface.
    std::string layerMissing;
    DisplacementInfo displacement;
    Skeleton skeleton;                ///< empty when the mesh is not skinned
    std::vector<std::string> warnings;  ///< tolerated problems found while loading
};

/// How many of the rig's parts are drawn with face normals (RigPart::flat).
inline size_t flatPartCount(const Rig& rig)
{
    size_t n = 0;
    for (const RigPart& part : rig.parts)
        n += part.flat ? 1 : 0;
    return n;
}

/// Whether the rig is drawn with face normals throughout: it has parts, and
/// every one is flat.
inline bool allPartsFlat(const Rig& rig)
{
    return !rig.parts.empty() && flatPartCount(rig) == rig.parts.size();
}

/// True when the rig's displacement is sampled from a map that must be
/// loaded first (io::loadRigDisplacementMap); false when it has none or
/// stores its values per vertex (which applyRigDisplacement reads alone; such
/// a rig may have no UVs, and then no map at all).
inline bool rigNeedsMap(const Rig& rig)
{
    return rig.hasDisplacement && rig.displacement.vertexLevel < 0;
}

/// Sets plan's displacements from the rig: from its per-vertex values when
/// it stores them (exact at levels up to vertexLevel, interpolated past it),
/// else by sampling `map` (which must then be given).  plan must have been
/// built from rig.mesh.
Status applyRigDisplacement(Plan* plan, const Rig& rig, const DisplacementMap* map, float scale = 1.0f);

/// The map a vertex-coded rig stands for, for consumers that sample a
/// texture (Strata's own CPU and GPU paths take the values directly:
/// applyRigDisplacement, GpuSurface::setDisplacements): the values at
/// vertexLevel interpolated linearly
/// over the refined triangles in UV space, texel centres inside a triangle
/// exact, two texels of gutter around every chart.  map->width/height must
/// be set; plan is the rig's plan at vertexLevel.
Status rasterizeVertexDisplacements(DisplacementMap* map, const Plan& plan, const std::vector<float>& values);

}  // namespace strata
