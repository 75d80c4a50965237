// Strata io: bounds-checked reading of glTF accessors from untrusted files.
#pragma once

#include "strata/status.h"

#include <string>
#include <vector>

namespace tinygltf {
class Model;
}

namespace strata {
namespace io {

/// Reads accessor `index` as floats, `components` per element (2, 3, 4 or
/// 16).  FLOAT data is copied; normalized UNSIGNED_BYTE / UNSIGNED_SHORT
/// data is converted to [0, 1].  Every offset, stride and count is checked
/// against the buffers; sparse accessors and non-finite values are rejected.
/// `what` names the data in error messages ("POSITION").
Status readFloatAccessor(const tinygltf::Model& model, int index, int components, const std::string& what,
                         std::vector<float>* out);

/// Reads an accessor of unsigned integers (UNSIGNED_BYTE/SHORT/INT) with
/// `components` per element (1 for indices, 4 for JOINTS_n).
Status readUintAccessor(const tinygltf::Model& model, int index, int components, const std::string& what,
                        std::vector<uint32_t>* out);

/// The float `v` as the double with the fewest significant digits that
/// still rounds to it (glTF reads JSON numbers of float data as single
/// precision), so a writer prints "0.57565022", not "0.5756502151489258".
double jsonFloat(float v);
/// jsonFloat of each value: an accessor's min/max of float data.
void jsonFloats(std::vector<double>* values);

}  // namespace io
}  // namespace strata
