// Strata runtime: the control rig as plain data (docs/FORMAT.md).
//
// The io layer fills this from a .glb/.gltf file; engines that have their own
// asset pipeline can fill it directly.  No file format code lives here.
#pragma once

#include "strata/animation.h"
#include "strata/control_mesh.h"
#include "strata/plan.h"

#include <string>
#include <vector>

namespace strata {

/// Version of the rig's "strata" extras block this build reads and writes.
constexpr int kRigFormatVersion = 1;

/// How the rig's displacement map is stored and applied.
struct DisplacementInfo {
    std::string uri;            ///< image beside the rig, relative URI (empty: no map)
    std::string encoding;       ///< "exr" (half or float texels), "png8" or "png16"
    int width = 0;              ///< map size the image must have
    int height = 0;
    float factor = 1.0f;        ///< displacementGeometryFactor: d = texel * factor + offset
    float offset = 0.0f;        ///< displacementGeometryOffset
    Scheme scheme = Scheme::Linear;
    int recommendedLevel = 3;
    /// Optional second copy of the map as an 8- or 16-bit PNG quantised with
    /// paper eq. 12: q = round((2^bits - 1) (d - dmin) / (dmax - dmin)).
    struct Quantized {
        std::string uri;  ///< empty: none
        int bits = 0;     ///< 8 or 16
        float dmin = 0.0f, dmax = 0.0f;
    } quantized;
};

struct Rig {
    ControlMesh mesh;                 ///< welded: one position per topological vertex
    std::vector<uint32_t> sourceVertex;  ///< per file vertex: its topological vertex in mesh
    bool hasDisplacement = false;     ///< false for a plain glTF without a strata block
    DisplacementInfo displacement;
    Skeleton skeleton;                ///< empty when the mesh is not skinned
    std::vector<std::string> warnings;  ///< tolerated problems found while loading
};

}  // namespace strata
