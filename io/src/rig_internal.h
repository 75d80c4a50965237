// Internal to strata_io: what the rig reader (rig_read.cpp), the scene's
// geometry (rig_scene.cpp), its skeleton (rig_skeleton.cpp) and the rig
// writer (rig_write.cpp) share.  Not installed.
#pragma once

#include "gltf_document.h"
#include "strata/io/rig_io.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace io {
namespace rigfile {

// ---- The layer block (rig_read.cpp) ----

/// obj[name] when obj is an object that has it, else null.
const tinygltf::Value* member(const tinygltf::Value& obj, const char* name);
/// The mesh's layer: its STRATA_layered_displacement extension (*extension
/// true) or the extras.strata block of format versions 1-4; null if none.
const tinygltf::Value* layerBlock(const tinygltf::Mesh& mesh, bool* extension);

/// 64-bit FNV-1a of `size` bytes, continuing from `h` (start: kFnvOffset).
uint64_t fnvBytes(uint64_t h, const void* data, size_t size);
constexpr uint64_t kFnvOffset = 0xcbf29ce484222325ull;
uint64_t uvHash(const std::vector<glm::vec2>& uvs);
/// FNV-1a of the UVs of every face corner, in face order.
uint64_t cornerUVHash(const ControlMesh& mesh);
std::string hex64(uint64_t v);

/// The placeholders saveRig writes for the fingerprint's hashes and then
/// replaces, in the encoded file, by those of the control mesh that file
/// reads back as (the same length, so no offset moves).
const char* const kTopologyToken = "~strata~topolog~";
const char* const kPositionsToken = "~strata~position";
const char* const kShapeToken = "~strata~shape~~~";
const char* const kUVToken = "~strata~uvs~~~~~";

/// Refuses a control mesh other than the one the layer was baked on, naming
/// what changed (checkBinding false: only the record's fields are read).
Status checkLayerBinding(const tinygltf::Value& block, const std::string& path, const ControlMesh& mesh,
                         bool checkBinding);

/// What finishRig does with a layer that does not match its control mesh:
/// refuse the file (loadRig), skip the comparison (sealLayer, whose file has
/// placeholders yet), or drop the layer with a warning (a control mesh for a
/// new bake, whose layer the bake replaces).
enum class LayerCheck { Enforce, Seal, DropStale };

/// A loaded document as a Rig: its scene's geometry, skeleton and layer.
Status finishRig(const std::string& path, std::shared_ptr<SourceDocument> doc, Rig* out,
                 LayerCheck check = LayerCheck::Enforce, size_t maxBytes = size_t(2048) << 20);

// ---- The scene's geometry (rig_scene.cpp) ----

glm::mat4 localMatrix(const tinygltf::Node& n);
/// Each node's parent and world matrix at rest; refuses cycles and nodes
/// with two parents.
Status restWorldMatrices(const std::string& path, const tinygltf::Model& model, std::vector<int>* parentOut,
                         std::vector<glm::mat4>* world);
/// The part's node mirrors it (its transform's determinant is negative):
/// glTF draws its triangles with the winding reversed, and the control mesh
/// holds them so (readSceneGeometry), outward as drawn.  Never a skinned
/// part: its node's transform does not place it, and its skin's matrices
/// move its vertices where glTF draws them, mirror or not, in their file
/// order (a second skin's toScene may mirror: the order stays).
bool mirrors(const RigPart& part);
/// Turns every triangle of a triangle list the other way round (corners 1
/// and 2 swapped): a mirrored part's file order <-> its control-mesh order.
void reverseWinding(std::vector<uint32_t>* triangles);
/// The accessor of attribute `name`, or -1.
int attributeOf(const tinygltf::Primitive& prim, const std::string& name);
/// A triangle primitive's indices (or 0..n-1), checked against vertexCount.
Status primitiveTriangles(const tinygltf::Model& model, const tinygltf::Primitive& prim, size_t vertexCount,
                          const std::string& what, std::vector<uint32_t>* out);

/// The skins a scene's skinned parts use, as the one skin of a Strata rig:
/// the first part's skin's joints, then each other skin's joints it lacks.
/// Each skin binds its meshes in a bind space of its own; another skin's
/// meshes are read into the first's through toFirst, the matrix M with
/// first's inverse bind matrix times M equal to its own at every joint the
/// two share (the identity where they bind them alike; exporters that write
/// a skin per mesh do).  Where no one M fits (a mesh bound in another pose),
/// its vertices are rebound one by one (rebind: M per joint, blended by each
/// vertex's weights), which rig_scene accepts where a vertex's joints agree
/// on where it lies.
struct SkinUnion {
    std::vector<int> skins;                      // the glTF skins, in the order the parts first use them
    std::vector<int> joints;                     // per joint of the union: its node
    std::vector<glm::mat4> inverseBindMatrices;  // per joint of the union, in the first skin's bind space
    std::vector<std::vector<uint16_t>> jointOf;  // per skin in `skins`: its joint -> the union's
    std::vector<glm::mat4> toFirst;              // per skin in `skins`: its bind space -> the first's
    std::vector<std::vector<glm::mat4>> rebind;  // per skin: per its joint, its bind space -> the union's
                                                 // (empty: toFirst fits every joint)
    std::vector<int> apartJoint;                 // per skin: the first joint node toFirst did not fit, or -1

    /// Where `skin` is in `skins`, or -1.
    int indexOf(int skin) const;
};

/// Influence set `set` (JOINTS_n and WEIGHTS_n, 4 a vertex) of `part`'s
/// primitive: both empty where the primitive lacks the pair; refuses one
/// that is not one element per vertex.
Status readInfluenceSet(const std::string& path, const tinygltf::Model& model, const tinygltf::Primitive& prim,
                        const RigPart& part, int set, std::vector<uint32_t>* joints, std::vector<float>* weights);

/// The union of the skins `parts` use (none: an empty union).  Refuses a
/// missing or jointless skin, a joint that is no node, too few inverse bind
/// matrices, or one the union's cannot be inverted against; a skin no one
/// transform takes to the first's bind space gets `rebind` per joint.
Status uniteSkins(const std::string& path, const tinygltf::Model& model, const std::vector<RigPart>& parts,
                  SkinUnion* out);

/// The whole scene's triangle geometry, welded, with one part per primitive.
struct SceneGeometry {
    Rig rig;                 // mesh (not yet validated), sourceVertex, fileCorners, parts
    std::vector<const tinygltf::Primitive*> primitives;  // per part
    int blockMesh = -1;      // a mesh carrying a displacement layer, or -1
    bool blockIsExtension = false;  // the layer is STRATA_layered_displacement (else extras.strata)
    size_t passThrough = 0;  // point and line primitives, kept untouched
    size_t missingUV = 0;    // triangle parts without the displacement UV set
    std::string firstMissingUV;
    bool bindScaleWarned = false;  // a skin's joints disagree on the bind space's scale (said once)
    SkinUnion skins;               // the skinned parts' skins as one (their vertices read into its bind space)
    Status skinsUnited;            // why they could not be, for loadSkeleton to say (the geometry stands)
    std::vector<uint32_t> fileTriangles;      // every triangle in file vertices, degenerate ones included
    std::vector<uint32_t> fileTriangleParts;  // per file triangle: its part
    std::vector<glm::vec3> meshSpace;         // per file vertex: as its accessor holds it, before any transform
};

/// Welds file vertices (scene space) into rig->mesh: fills sourceVertex,
/// fileCorners, the parts' face ranges and, withUV, the mesh's UVs.
void weldFileVertices(const std::vector<float>& pos, std::vector<glm::vec2>&& uv, const std::vector<uint32_t>& tri,
                      const std::vector<uint32_t>& partOfTri, bool withUV, int texCoord, Rig* rig);

Status readSceneGeometry(const std::string& path, const SourceDocument& doc, SceneGeometry* out);

// ---- Carrying the layer through other tools (rig_carry.cpp) ----

/// The layer's `baked` control mesh, written by Strata's glTF Transform
/// extension when a command renumbered or moved the control mesh (reorder,
/// weld, quantize, meshopt, draco): rebuilds it, checks that the file's
/// tagged triangles (_STRATA_VERTEX) are still its triangles and its
/// vertices still near their places, and puts it in scene->rig in place of
/// the file's.  *bindFix maps the baked mesh's bind space to the skinned
/// parts' current one: each skin joint's inverse bind matrix is multiplied
/// by it on the right (a command that moved the vertices into another
/// space, as quantize does, changed the inverse bind matrices to match).
/// A rig placed elsewhere as a whole since the bake (its unskinned parts
/// moved, turned or scaled alike by their nodes): the control mesh the layer
/// was baked on, there, and the scale its displacements take with it.
struct Placement {
    bool placed = false;
    float scale = 1.0f;
    ControlMesh baked;  // the mesh to check the layer's record against
};

/// Why a rig its nodes mirror since the bake is refused.
inline constexpr const char* kMirrored =
    "its nodes mirror the rig since the bake (a negative scale), which turns its faces over and so renumbers the "
    "refinement its displacements follow: mirror the model before baking, or bake the mirrored one again";
/// Why a rig its nodes scale unevenly or shear since the bake is refused,
/// after the nodes that do it.
inline constexpr const char* kUnevenlyScaled =
    "scale the rig unevenly or shear it since the bake, which would bend the displaced surface out of its baked "
    "shape: scale it alike on every axis, or bake again";

/// The uniform scale s of a linear map that turns and scales alike in every
/// direction (its columns orthogonal and of one length, to a part in 1e-4),
/// or false.
bool similarityScale(const glm::dmat3& A, double* s);

/// *placement is filled where the carried mesh's unskinned parts sit moved
/// by one similarity from their baked places (a node moved the whole rig
/// after the tool): the baked mesh is then put there.
Status carryBakedControl(const std::string& path, const tinygltf::Model& model, const tinygltf::Value& block,
                         SceneGeometry* scene, glm::mat4* bindFix, Placement* placement);

// ---- The skeleton (rig_skeleton.cpp) ----

/// Nodes, the skinned parts' skins as one (scene.skins; rigid parts ride on
/// their node as an extra joint), per-vertex influences and animations.
Status loadSkeleton(const std::string& path, const tinygltf::Model& model, const SceneGeometry& scene, Rig* rig);

}  // namespace rigfile
}  // namespace io
}  // namespace strata
