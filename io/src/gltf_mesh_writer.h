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

}  // namespace io
}  // namespace strata
