// Internal: one glTF writer for rigs and reconstructed meshes.
#pragma once

#include "strata/animation.h"
#include "strata/io/mesh_io.h"

#include <tiny_gltf.h>

namespace strata {
namespace io {

/// Writes a single-mesh glTF (.glb or .gltf by extension), splitting
/// vertices where UVs differ.  `meshExtras` goes on the mesh (may be null).
/// Normals are written only when every one is unit length.
/// With a non-empty skeleton, its nodes, skin (JOINTS/WEIGHTS per vertex)
/// and animations are written too; node indices are kept and the mesh node
/// comes last.
Status writeGltfMesh(const std::string& path, const MeshView& mesh, const char* name,
                     const tinygltf::Value* meshExtras, const Skeleton* skeleton = nullptr);

/// The model writeGltfMesh writes, for callers that add to it first.
void buildGltfMesh(tinygltf::Model* out, const MeshView& mesh, const char* name, const tinygltf::Value* meshExtras,
                   const Skeleton* skeleton = nullptr);

/// Serialises a model (.glb or .gltf by extension), atomically.
Status writeGltfModel(const std::string& path, const tinygltf::Model& model);

/// Appends bytes to buffer 0 (4-byte aligned) as a new bufferView; returns its index.
int appendBufferView(tinygltf::Model& model, const void* data, size_t bytes, int target);
/// Appends an accessor over a whole bufferView; returns its index.
int appendAccessor(tinygltf::Model& model, int view, int componentType, int type, size_t count);

}  // namespace io
}  // namespace strata
