// PLY: writing (binary little-endian; reading is polygon_reader.cpp's).
#include "mesh_writers.h"

#include "strata/io/file.h"

#include <cstring>
#include <sstream>
#include <string>

namespace strata {
namespace io {

Status writePly(const std::string& path, const MeshView& m)
{
    std::ostringstream header;
    header << "ply\nformat binary_little_endian 1.0\ncomment written by Strata\nelement vertex " << m.vertexCount
           << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (m.normals)
        header << "property float nx\nproperty float ny\nproperty float nz\n";
    header << "element face " << m.faceCount << "\nproperty list uchar uint vertex_indices\nend_header\n";
    std::string out = header.str();
    const size_t vbytes = m.normals ? 24 : 12;
    out.reserve(out.size() + m.vertexCount * vbytes + m.faceCount * 13);
    for (size_t i = 0; i < m.vertexCount; ++i) {
        out.append(reinterpret_cast<const char*>(&m.positions[i]), 12);
        if (m.normals)
            out.append(reinterpret_cast<const char*>(&m.normals[i]), 12);
    }
    for (size_t f = 0; f < m.faceCount; ++f) {
        out += char(3);
        out.append(reinterpret_cast<const char*>(&m.triangles[3 * f]), 12);
    }
    return writeFileAtomic(path, out.data(), out.size());
}

}  // namespace io
}  // namespace strata
