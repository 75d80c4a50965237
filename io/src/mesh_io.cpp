// Plain mesh output by extension: OBJ (obj.cpp), PLY (ply.cpp), glTF
// (gltf_mesh_writer.cpp).
#include "strata/io/mesh_io.h"

#include "gltf_mesh_writer.h"
#include "mesh_writers.h"
#include "strata/io/file.h"

namespace strata {
namespace io {

Status writeMesh(const std::filesystem::path& pathFile, const MeshView& mesh)
{
    const std::string path = pathFile.string();
    if (!mesh.positions || !mesh.triangles || mesh.vertexCount == 0 || mesh.faceCount == 0)
        return Status(StatusCode::InvalidArgument, path + ": nothing to write (empty mesh)");
    if (mesh.uvs && !mesh.uvIndices)
        return Status(StatusCode::InvalidArgument, path + ": UVs without UV indices");
    const std::string ext = extensionOf(path);
    if (ext == ".obj")
        return writeObj(path, mesh);
    if (ext == ".ply")
        return writePly(path, mesh);
    if (ext == ".glb" || ext == ".gltf")
        return writeGltfMesh(path, mesh, "strata_mesh", nullptr);
    return Status(StatusCode::InvalidArgument, path + ": unknown output format \"" + ext +
                                                   "\" (use .obj, .ply, .glb or .gltf)");
}

}  // namespace io
}  // namespace strata
