// Strata io: control rigs as glTF 2.0 (.glb or .gltf), see docs/FORMAT.md.
#pragma once

#include <filesystem>

#include "strata/displacement_map.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace io {

/// The glTF extension that carries a rig's displacement layer (format
/// version 5, docs/STRATA_layered_displacement.md), on every mesh that takes part.
constexpr const char* kLayerExtension = "STRATA_layered_displacement";

/// One clause on why a glTF file loaded as `rig` has no displacement layer
/// (which tool wrote it, and what that tool does with the layer), for
/// tools that refuse to draw such a file as if it were displaced.
std::string missingLayerCause(const Rig& rig);

/// Bytes of what a rig loaded from glTF carries besides its meshes and its
/// displacement layer: images (textures, embedded or beside the file),
/// animation keys and skins' inverse bind matrices, which a plain glb of
/// the same character carries too; 0 for other rigs.
size_t characterBytes(const Rig& rig);

/// characterBytes by kind (an accessor two animations share counted once).
struct CharacterBytes {
    size_t images = 0, animations = 0, skins = 0;
};
CharacterBytes characterBytesOf(const Rig& rig);

/// What loading a file may cost.  Every count a file declares is checked
/// against the bytes that back it; what it would then take in memory
/// (decoded buffers, zeros a sparse or bufferView-less accessor stands for,
/// the subdivision hierarchy its per-vertex displacements need) is checked
/// against maxMemoryMB before it is allocated, and a file that needs more
/// is refused with the figure and the flag that raises it.
struct LoadOptions {
    double maxMemoryMB = 2048.0;  ///< fits a 4 GB machine with the work that follows
};

/// Loads a control rig, or any glTF scene with triangles (then
/// rig.hasDisplacement is false).  Every triangle primitive of every mesh is
/// read (strips and fans unrolled; points and lines kept in the document
/// only), in the scene's space at rest: unskinned mesh nodes are placed by
/// their node's world transform, skinned ones as glTF defines.  Vertices are
/// welded by exact position across all primitives into one control mesh;
/// rig.parts records which faces and file vertices came from which
/// primitive.  Quantized attributes (KHR_mesh_quantization) are read.  The
/// whole document is kept in rig.source, so saveRig() writes it back
/// complete.  External files resolve only inside the file's folder.  Every
/// accessor is bounds-checked; a newer format version, malformed metadata or
/// bad geometry is a clear error.  Rigs of every earlier format version load.
Status loadRig(const std::filesystem::path& path, Rig* out, const LoadOptions& options = LoadOptions());

/// loadRig for a control mesh that a new bake will displace: a layer that no
/// longer matches the mesh (a tool welded, reordered or quantised it, or
/// dropped what it refers to) is dropped with a warning instead of refusing
/// the file, since the bake replaces it.
Status loadControlForBake(const std::filesystem::path& path, Rig* out, const LoadOptions& options = LoadOptions());

/// A glTF scene places a mesh wherever a node names it, and loadRig reads
/// each placement as parts of its own.  A rig written as its source document
/// (a bake onto this control mesh) keeps its layer's UVs in each part's
/// primitive, so a mesh placed twice cannot be one: refused, naming the mesh
/// and two of its nodes.  OK for a rig not read from glTF.
Status checkEachMeshPlacedOnce(const std::string& path, const Rig& rig);

/// loadRig from bytes in memory (.glb when `binary`, else .gltf JSON); no
/// external file is read.  `name` is used in messages.
Status loadRigFromMemory(const unsigned char* data, size_t size, bool binary, const std::string& name, Rig* out,
                         const LoadOptions& options = LoadOptions());

/// Loads every triangle primitive of any glTF scene (as loadRig places them)
/// as one triangle soup welded by exact position, without the control-mesh checks (a captured
/// high-resolution mesh may be non-manifold; the baker tolerates that).
/// `flat`, when given, is set when no triangle primitive has NORMAL (glTF
/// then draws the scene with face normals).
Status loadGltfTriangles(const std::filesystem::path& path, std::vector<glm::vec3>* positions, std::vector<uint32_t>* triangles,
                         const LoadOptions& options = LoadOptions(), bool* flat = nullptr);

/// Loads the rig's displacement map: the embedded image (format version 2)
/// or the EXR its URI names beside the rig; checks its size against the rig
/// and sets factor/offset so texels decode to distances.
Status loadRigDisplacementMap(const std::filesystem::path& rigPath, const Rig& rig, DisplacementMap* out);

/// Loads the rig's optional quantised PNG map (paper eq. 12) with factor and
/// offset set so texels decode to distances.
Status loadRigQuantizedMap(const std::filesystem::path& rigPath, const Rig& rig, DisplacementMap* out);

/// Writes rig as .glb (binary) or .gltf (JSON with an embedded buffer) by
/// path extension, atomically.  A rig loaded from glTF (rig.source) is
/// written as its source document plus the displacement block: materials,
/// textures (external images are embedded), names, extras, skins,
/// animations and untouched primitives all stay; UVs that differ from the
/// source's go into a new TEXCOORD set.  Other rigs are written as one mesh,
/// split where UVs differ.  With `map`, the map is embedded as a grey PNG
/// (paper eq. 12 over its range, 16 bits or what `options` allow) and the
/// block refers to it; without, the
/// block keeps rig.displacement's URI.  `notes` receives what could not be
/// carried over, if anything.
/// A bare control mesh's material: one base colour texture sampled through
/// the control mesh's UVs (TEXCOORD_0, then always written), as the baker
/// makes for an automatic cage of a textured character.
struct BaseColourTexture {
    std::string name;
    int width = 0, height = 0;
    std::vector<uint8_t> rgba;  ///< 4 bytes per texel, row 0 first (v = 0); JPEG or PNG, whichever is smaller, when opaque
    bool doubleSided = false;
    float metallic = 0.0f, roughness = 0.6f;  ///< the material's factors
    std::string alphaMode = "OPAQUE";          ///< glTF's OPAQUE, MASK or BLEND
    float alphaCutoff = 0.5f;                  ///< MASK's cutoff
    /// Optional, width x height RGBA like rgba: a metallic-roughness
    /// texture (G roughness, B metallic, linear), written with the factors
    /// above (and as the occlusion texture, its R, where `occlusion`), and
    /// an emissive texture (sRGB-coded RGB), written with `emissive` as its
    /// factor; empty: none.
    std::vector<uint8_t> metallicRoughness, emissiveRGBA;
    /// Optional, normalWidth x normalHeight RGBA (0: width x height): a
    /// tangent-space normal texture (glTF's: RGB = (X, Y, Z) / 2 + 1/2, X
    /// along +u, Y along -v), written as PNG; empty: none.
    std::vector<uint8_t> normalRGBA;
    int normalWidth = 0, normalHeight = 0;
    bool occlusion = false;
    float emissive[3] = {0.0f, 0.0f, 0.0f};  ///< emissiveFactor
    float emissiveStrength = 1.0f;            ///< past 1: written as KHR_materials_emissive_strength
};

struct RigWriteOptions {
    /// Largest quantisation step of the embedded map, in model units (0:
    /// 16 bits over the map's range).  The baker passes its tolerance (the
    /// error reached, where larger), so the map takes only the bits the
    /// tolerance needs (8-bit PNG when 256 levels suffice); per-vertex values
    /// may take another (RigWriter::setVertexValues).
    double maxQuantizationStep = 0.0;
    /// .glb only: code vertex attributes and triangle indices with
    /// EXT_meshopt_compression (three.js, Babylon.js, gltfpack and Strata
    /// read it; the glTF-Validator accepts it).  strata-bake turns it on.
    bool compress = false;
    /// With compress: the largest error allowed in each vertex position
    /// coordinate, in model units (0: exact).  Positions are then stored with
    /// meshopt's EXPONENTIAL filter at the bits that error allows (a float
    /// that decodes as a float, so skinning and node transforms are
    /// untouched); per-vertex displacements are measured on the positions
    /// as stored.  Only a bare control mesh: a rig written from a glTF
    /// document keeps its vertex data exact.  Where the cage does not read
    /// back face for face at that error (an edge shorter than it collapses),
    /// a quarter and then a sixteenth of it are tried.  strata-bake passes
    /// four times its tolerance.
    double maxPositionError = 0.0;
    /// With compress and maxPositionError: code a bare, unskinned control
    /// mesh with KHR_draco_mesh_compression (Edgebreaker connectivity,
    /// positions quantised to that error) instead of meshopt: about half the
    /// bytes.  Viewers with a Draco decoder (three.js, Babylon.js, Blender,
    /// Strata) read it.  When the cage does not read back face for face
    /// (Draco may weld or drop faces), meshopt is used.  strata-bake turns
    /// it on.
    bool draco = false;
    /// Store the map as its samples at the refined vertices of
    /// rig.displacement.recommendedLevel, predicted in subdivision order and
    /// zstd-coded (encoding "vertex", format versions 3 and 4), instead of as an
    /// image: a fraction of the bytes, exact at levels up to that one,
    /// interpolated past it.  strata-bake turns it on.
    bool vertexDisplacements = false;
    /// With vertexDisplacements: leave out the UVs the map was baked
    /// through when nothing else uses them (an atlas the baker made).  The
    /// per-vertex values are then the map's only form: seams no longer split
    /// vertices (fewer, better-coded vertices), and loadRigDisplacementMap
    /// refuses the rig.  A character's own texture UVs are always kept.
    bool omitDisplacementUVs = false;
    /// A rig written as a bare control mesh (not from a source document):
    /// its material, or null for none.
    const BaseColourTexture* baseColour = nullptr;
};

/// The bytes of a .glb with any EXT_meshopt_compression decoded: a plain
/// .glb that tools without meshopt support (tinygltf) read.
Status readPlainGlb(const std::filesystem::path& path, std::string* bytes);

Status saveRig(const std::filesystem::path& path, const Rig& rig, const DisplacementMap* map = nullptr,
               std::vector<std::string>* notes = nullptr, const RigWriteOptions* options = nullptr);

/// saveRig in steps, for a caller that fits the per-vertex displacements
/// itself (the baker measures each against the capture):
///   begin: everything but those values is encoded (with
///          vertexDisplacements, the mesh coding is chosen where the cage
///          reads back face for face);
///   setVertexValues: the values, over fileMesh() (the control mesh as a
///          loader rebuilds it from this file, in its numbering) at
///          vertexLevel(), only when needsVertexValues();
///   commit: the layer's record sealed from the encoded bytes, the file
///          written atomically (or its bytes returned).
/// saveRig is begin, setVertexValues(sampledValues(), quantizationStep())
/// and commit.  The writer holds copies: the rig and map may go after begin;
/// `notes` (lines for the user) is written to until commit.
class RigWriter {
public:
    RigWriter();
    ~RigWriter();
    RigWriter(const RigWriter&) = delete;
    RigWriter& operator=(const RigWriter&) = delete;

    Status begin(const std::filesystem::path& path, const Rig& rig, const DisplacementMap* map,
                 const RigWriteOptions& options, std::vector<std::string>* notes = nullptr);
    bool needsVertexValues() const;
    /// The control mesh as this file numbers it (valid while needsVertexValues).
    const ControlMesh& fileMesh() const;
    int vertexLevel() const;
    /// The map's samples at fileMesh's refined vertices (a seam vertex takes
    /// the median of its charts' samples).
    const std::vector<float>& sampledValues() const;
    /// RigWriteOptions::maxQuantizationStep.
    double quantizationStep() const;
    /// Codes `values` (one per refined vertex of fileMesh at vertexLevel)
    /// to multiples of `step` (0: 16 bits over their range).
    Status setVertexValues(const std::vector<float>& values, double step);
    Status commit();
    /// commit() into `bytes` (the file's whole content) instead of the file:
    /// nothing is written.  The path given to begin still names the file
    /// in messages and chooses .glb or .gltf.
    Status commit(std::string* bytes);

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace io
}  // namespace strata
