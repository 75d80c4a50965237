// Strata io: plain mesh files (OBJ in; OBJ, PLY, glTF out).
#pragma once

#include <filesystem>

#include "strata/control_mesh.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <string>
#include <vector>

namespace strata {
namespace io {

struct ObjReadInfo {
    size_t polygons = 0;      ///< faces in the file
    size_t triangulated = 0;  ///< of which had more than 3 corners (fan-triangulated)
    size_t degenerate = 0;    ///< triangles dropped because they repeat a vertex (zero area)
    /// Per vertex: its colour (`v x y z r g b`, as MeshLab and scanners
    /// write it: sRGB-coded 0..1, or 0..255 where any value passes 1),
    /// linear RGBA; white for a vertex without.  Empty when none has one.
    std::vector<glm::vec4> colours;
};

/// Reads an OBJ as a control mesh: `v` positions, `vt` UVs (flipped to
/// glTF's v-down convention), `f` faces with optional /vt (negative indices
/// allowed), polygons fan-triangulated; triangles that repeat a vertex are
/// dropped and counted in info.  Other statements and `#` comments are ignored.
/// Errors name the file and line.
Status readObj(const std::filesystem::path& path, ControlMesh* out, ObjReadInfo* info = nullptr);

/// readObj from bytes in memory; `name` is used in messages.
Status parseObj(const unsigned char* data, size_t size, const std::string& name, ControlMesh* out,
                ObjReadInfo* info = nullptr);

/// A polygon soup read from PLY, OFF or STL, fan-triangulated.
struct PolygonMesh {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    /// Per vertex: a PLY vertex's red, green, blue (and alpha), sRGB-coded
    /// as scanners write them (integers over their range, floats 0..1), as
    /// linear RGBA.  Empty without (and for OFF and STL).
    std::vector<glm::vec4> colours;
    size_t polygonsTriangulated = 0;  ///< faces with more than 3 corners
};

/// Reads .ply (ascii, binary little and big endian; any property order and
/// types, list faces named vertex_indices or vertex_index), .off (plain OFF)
/// or .stl (binary or ascii; duplicate vertices welded).  Built for
/// untrusted files: declared counts are checked against the file's size
/// before anything is reserved, and the work is linear in the file size.
/// Errors name the file and the problem; nothing is printed.
Status readPolygonMesh(const std::filesystem::path& path, PolygonMesh* out);

/// readPolygonMesh from bytes in memory; `format` is ".ply", ".off" or
/// ".stl" and `name` is used in messages.
Status parsePolygonMesh(const unsigned char* data, size_t size, const std::string& format, const std::string& name,
                        PolygonMesh* out);

/// A mesh to write: arrays owned by the caller.
struct MeshView {
    const glm::vec3* positions = nullptr;  ///< vertexCount
    const glm::vec3* normals = nullptr;    ///< vertexCount, or nullptr
    size_t vertexCount = 0;
    const uint32_t* triangles = nullptr;   ///< 3 * faceCount
    size_t faceCount = 0;
    const glm::vec2* uvs = nullptr;        ///< face-varying values (glTF convention), or nullptr
    size_t uvCount = 0;
    const uint32_t* uvIndices = nullptr;   ///< 3 * faceCount, with uvs
    /// glTF only: UVs that all lie in [0, 1] are written as normalised
    /// 16-bit integers (core glTF 2.0), half the bytes of floats.
    bool compactUVs = false;
};

/// Writes the mesh by extension: .obj (v/vt/vn), .ply (binary, per-vertex
/// position and normal), .glb/.gltf (split where UVs differ).  Atomic.
Status writeMesh(const std::filesystem::path& path, const MeshView& mesh);

}  // namespace io
}  // namespace strata
