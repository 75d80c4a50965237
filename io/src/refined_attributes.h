// Strata io (private): a glTF primitive's per-vertex attribute refined
// through the face-varying refinement of the rig's file corners, shared by
// the scene writer and the render mesh.
#pragma once

#include "strata/plan.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <tiny_gltf.h>

#include <string>
#include <vector>

namespace strata {
namespace io {

/// Whether an attribute of a source primitive is refined per corner (UVs,
/// colours, custom data), rather than rebuilt (positions, normals, skin) or
/// left out (tangents).
bool isRefinedAttribute(const std::string& name);

/// Attribute `name` (accessor `accessor` of `part`'s primitive) at each
/// output vertex, given the refined corner value of each
/// (cornerValue[i]): *components values per entry, written to `out` at
/// `stride` floats per vertex (`out` holds cornerValue.size() * stride
/// floats).  Control values from other parts contribute nothing.
Status refinePartAttribute(const tinygltf::Model& model, const RigPart& part, const FaceVaryingRefinement& fv,
                           const uint32_t* cornerValue, size_t count, int accessor, const std::string& name,
                           int components, float* out, size_t stride);

/// The number of components of an attribute accessor (0 when not a vector type).
int attributeComponents(const tinygltf::Model& model, int accessor);

}  // namespace io
}  // namespace strata
