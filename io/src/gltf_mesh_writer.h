// Internal: one glTF writer for rigs and reconstructed meshes.
#pragma once

#include "strata/io/mesh_io.h"

#include <tiny_gltf.h>

namespace strata {
namespace io {

/// Writes a single-mesh glTF (.glb or .gltf by extension), splitting
/// vertices where UVs differ.  `meshExtras` goes on the mesh (may be null).
/// Normals are written only when every one is unit length.
Status writeGltfMesh(const std::string& path, const MeshView& mesh, const char* name,
                     const tinygltf::Value* meshExtras);

}  // namespace io
}  // namespace strata
