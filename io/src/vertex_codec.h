// Strata io (private): per-refined-vertex displacements, entropy-coded
// (docs/FORMAT.md, encoding "vertex").
#pragma once

#include "strata/status.h"
#include "strata/vertex_displacements.h"

#include <string>
#include <vector>

namespace strata {
namespace io {

/// Quantises `values` (one per vertex of mesh's uniform refinement to
/// `level`) to multiples of `step` above their minimum, predicts them in
/// subdivision order and codes the residuals with zstd.  factor/offset
/// receive the dequantisation d = q * factor + offset.  The arithmetic is
/// the runtime's (strata/vertex_displacements.h); this is the byte format.
Status encodeVertexDisplacements(const ControlMesh& mesh, int level, const std::vector<float>& values, double step,
                                 std::string* bytes, float* factor, float* offset);

/// The inverse; every length is checked against the hierarchy before
/// anything is allocated past the input's size.  `what` names the data in
/// messages.
Status decodeVertexDisplacements(const ControlMesh& mesh, int level, const unsigned char* data, size_t size,
                                 float factor, float offset, const std::string& what, std::vector<float>* values);

}  // namespace io
}  // namespace strata
