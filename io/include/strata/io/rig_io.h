// Strata io: control rigs as glTF 2.0 (.glb or .gltf), see docs/FORMAT.md.
#pragma once

#include "strata/displacement_map.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <string>

namespace strata {
namespace io {

/// Loads a control rig, or any glTF with a triangle mesh (then
/// rig.hasDisplacement is false).  The first mesh that carries a "strata"
/// extras block is used, else the first triangle primitive.  Vertices that
/// glTF splits (UV seams, hard edges) are welded by exact position into one
/// topological vertex.  Every accessor is bounds-checked; a newer format
/// version, malformed metadata or bad geometry is a clear error.
Status loadRig(const std::string& path, Rig* out);

/// Loads the first triangle primitive of any glTF as a triangle soup welded
/// by exact position, without the control-mesh checks (a captured
/// high-resolution mesh may be non-manifold; the baker tolerates that).
Status loadGltfTriangles(const std::string& path, std::vector<glm::vec3>* positions, std::vector<uint32_t>* triangles);

/// Loads the displacement map a rig names (the URI is relative to the rig),
/// checks its size against the rig, and sets factor/offset from the rig.
Status loadRigDisplacementMap(const std::string& rigPath, const Rig& rig, DisplacementMap* out);

/// Loads the rig's optional quantised PNG map (paper eq. 12) with factor and
/// offset set so texels decode to distances.
Status loadRigQuantizedMap(const std::string& rigPath, const Rig& rig, DisplacementMap* out);

/// Writes rig as .glb (binary) or .gltf (JSON with an embedded buffer) by
/// path extension, atomically.  Vertices are split where UVs differ; the
/// strata extras block is written when rig.hasDisplacement.
Status saveRig(const std::string& path, const Rig& rig);

}  // namespace io
}  // namespace strata
