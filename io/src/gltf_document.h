// Internal: the source glTF document a rig keeps so that saving it loses
// nothing, and the confined loader every glTF read goes through.
#pragma once

#include "strata/rig.h"
#include "strata/status.h"
#include "text.h"

#include <nlohmann/json_fwd.hpp>
#include <tiny_gltf.h>

#include <functional>
#include <string>
#include <vector>

namespace strata {

struct SourceDocument {
    tinygltf::Model model;
    /// Encoded bytes of every image that is not in a bufferView (external
    /// file or data URI), by image index; empty where none was readable.
    std::vector<std::vector<unsigned char>> imageBytes;
};

namespace io {

/// The glTF extension names the readers and writers of compressed meshes share.
constexpr const char* kDracoExtension = "KHR_draco_mesh_compression";
constexpr const char* kMeshoptExtension = "EXT_meshopt_compression";

/// Whether `path`, every symbolic link resolved, lies inside `folder` (also
/// resolved; "" is the working directory): confinement by file, not spelling.
bool resolvesInsideFolder(const std::string& path, const std::string& folder);

/// Parses a .glb/.gltf.  External buffers and images resolve only inside
/// the file's folder (no absolute paths, no "..", no URI schemes but data:,
/// regular files only).  Image pixels are not decoded; their encoded bytes
/// are kept in doc->imageBytes.
Status loadGltfDocument(const std::string& path, SourceDocument* doc, size_t maxBytes = size_t(2048) << 20);

/// The one-line refusal of work that needs `needBytes`, over `maxBytes`:
/// "<what> needs about N MB, over the M MB budget (raise it with --max-memory MB)".
Status overBudget(const std::string& what, double needBytes, size_t maxBytes);

/// loadGltfDocument from bytes: external files resolve inside `folder`
/// ("" denies them all when folder names no real directory).
Status parseGltfDocument(const unsigned char* data, size_t size, bool binary, const std::string& folder,
                         const std::string& path, SourceDocument* doc, size_t maxBytes = size_t(2048) << 20);


/// The bufferView of a primitive's KHR_draco_mesh_compression data (-1:
/// none), and its renumbering when buffers are packed.
int dracoView(const tinygltf::Primitive& p);
void setDracoView(tinygltf::Primitive* p, int view);
/// Decodes every KHR_draco_mesh_compression primitive of a .glb's JSON into
/// plain accessors (of the types they declare) whose data it appends to
/// `bin` (the BIN chunk, buffer 0), and drops the extension.  Counts are
/// checked against the accessors; errors name `path`.
Status decodeDracoJson(nlohmann::json& doc, std::vector<unsigned char>* bin, const std::string& path);
/// Lists extension `name` in the model's extensionsUsed and, where
/// `required`, its extensionsRequired, each at most once.
void useExtension(tinygltf::Model& model, const std::string& name, bool required);
/// Removes extension `name` from a document's extensionsUsed and
/// extensionsRequired (dropping a list it leaves empty).
void dropExtension(nlohmann::json& doc, const char* name);
/// Codes with KHR_draco_mesh_compression (Edgebreaker) every triangle
/// primitive that has only a float POSITION and TEXCOORD_n sets, no morph
/// targets and accessors no one else uses: positions quantised so that no
/// coordinate moves more than positionError (> 0), UVs to 16 bits (decoded
/// as floats).  The old bufferViews are left for packBuffers to drop.
Status encodeDracoPrimitives(tinygltf::Model& model, double positionError, size_t* coded);

/// The accessor a mesh's STRATA_layered_displacement layer stores its coded
/// per-vertex values in (-1: none), and its renumbering.
int layerAccessor(const tinygltf::Mesh& mesh);
void setLayerAccessor(tinygltf::Mesh* mesh, int accessor);

/// Removes every displacement layer (STRATA_layered_displacement, and the
/// format 1-4 block in extras) and its declaration; returns the index of the
/// map image a layer named (for the caller to remove), or -1.
int dropLayers(tinygltf::Model& model);

/// The bufferView a mesh's strata block stores per-vertex displacements in
/// (-1: none), and its renumbering when buffers are packed.
int strataVertexView(const tinygltf::Value& extras);
void setStrataVertexView(tinygltf::Value* extras, int view);

/// An image's MIME type from its first bytes ("image/png", "image/jpeg",
/// "image/webp", "image/ktx2" or "image/avif"), or "" for none of them.
std::string sniffMime(const std::vector<unsigned char>& bytes);

/// Removes image `index`, renumbering texture sources, those texture
/// extensions name too (EXT_texture_webp, EXT_texture_avif, KHR_texture_basisu),
/// and imageBytes.
void removeImage(tinygltf::Model& model, std::vector<std::vector<unsigned char>>* imageBytes, int index);

/// Moves every image that is not in a bufferView into one, from imageBytes
/// (external files and data URIs as loaded); notes name any left by URI.
Status embedImages(tinygltf::Model& model, std::vector<std::vector<unsigned char>>& imageBytes,
                   std::vector<std::string>* notes);

/// Copies accessor `index` in the order of `src` (source element per new
/// element) into a new packed accessor with 4-byte aligned elements.
Status gatherAccessor(tinygltf::Model& model, int index, const std::vector<uint32_t>& src, const std::string& what,
                      int* out);

/// Where an accessor index is referenced: vertex attributes, indices and
/// morph targets of primitives, and skins and animation samplers (Other).
enum class AccessorUse { Attribute, Indices, MorphTarget, Other };

/// Calls visit on every accessor reference in the model (by reference, so it
/// may renumber), with the primitive for Attribute, Indices and MorphTarget.
void forEachAccessorReference(tinygltf::Model& model,
                              const std::function<void(int&, AccessorUse, const tinygltf::Primitive*)>& visit);

/// Drops accessors and bufferViews nothing references (when only extensions
/// known not to reference them are used) and merges all buffers into one.
Status packBuffers(tinygltf::Model& model);

/// Moves childless skinned-mesh nodes to the scene root (they draw the same;
/// the glTF-Validator warns otherwise).
void rootSkinnedMeshNodes(tinygltf::Model& model, std::vector<std::string>* notes);

/// asset.generator of a rig: "Strata <version>".
#define STRATA_RIG_GENERATOR "Strata " STRATA_VERSION
/// asset.generator of what Strata writes that is not a rig (a reconstructed
/// surface or scene, a mesh): the rig's, then kSurfaceGeneratorSuffix, so a
/// reader tells a surface that never had a layer from a rig that lost it.
#define STRATA_SURFACE_SUFFIX " (a displaced surface, no layer)"
constexpr const char* kSurfaceGeneratorSuffix = STRATA_SURFACE_SUFFIX;
#define STRATA_SURFACE_GENERATOR STRATA_RIG_GENERATOR STRATA_SURFACE_SUFFIX

/// packBuffers and Strata as the generator (a rig's, or with `surface` a
/// surface's): what every writer does first.
Status prepareForWriting(const std::string& path, tinygltf::Model& model, bool surface = false);

/// prepareForWriting, then an atomic write (.glb/.gltf).
Status packAndWrite(const std::string& path, tinygltf::Model& model, bool surface = false);

/// As packAndWrite, for .glb, with vertex attributes and triangle indices
/// coded by EXT_meshopt_compression (no uncompressed fallback).
/// positionError > 0 (model units) stores float POSITIONs with meshopt's
/// EXPONENTIAL filter at the fewest mantissa bits that keep every
/// coordinate within it (the accessors' bounds follow the decoded values);
/// 0 keeps them exact.
/// draco: code eligible primitives with KHR_draco_mesh_compression instead
/// (encodeDracoPrimitives; needs positionError > 0).
Status writeCompressedGlb(const std::string& path, tinygltf::Model& model, double positionError = 0.0,
                          bool draco = false);
/// writeCompressedGlb into memory.  The index codec may rotate each
/// triangle's corners, which renumbers the refined vertices of the mesh a
/// loader rebuilds, so whoever must know that numbering reads these bytes.
/// `notes` (when not null) receives one line naming the bufferViews left
/// plain and why, beyond images and the layer's values (coded already).
Status encodeCompressedGlb(const std::string& path, tinygltf::Model& model, std::string* out,
                           double positionError = 0.0, bool draco = false, std::vector<std::string>* notes = nullptr);

/// A .glb that uses EXT_meshopt_compression or KHR_draco_mesh_compression,
/// decoded to a plain .glb in `plain` (left empty when the input uses
/// neither).  Errors name `path`.
Status decodeCompressedGlb(const unsigned char* data, size_t size, const std::string& path, std::string* plain);

}  // namespace io
}  // namespace strata
