// Internal: the per-format writers behind writeMesh (mesh_io.cpp).
#pragma once

#include "strata/io/mesh_io.h"

#include <string>

namespace strata {
namespace io {

Status writeObj(const std::string& path, const MeshView& mesh);  // obj.cpp
Status writePly(const std::string& path, const MeshView& mesh);  // ply.cpp

}  // namespace io
}  // namespace strata
