// Strata baker: automatic UV atlas for control meshes without UVs
// (issue: "generate a texel-aligned atlas automatically ... so the user never
// has to unwrap").
#pragma once

#include "strata/control_mesh.h"
#include "strata/status.h"

namespace strata {
namespace baker {

struct AtlasOptions {
    int mapSize = 1024;   ///< texels per side of the square map the atlas is laid out for
    int gutter = 2;       ///< texels of gutter around every chart
};

/// Replaces mesh.uvs / mesh.uvIndices with a per-triangle atlas: triangles
/// are paired into square cells of a regular grid, each pair split along the
/// cell's diagonal with a gutter between them, corners on texel boundaries.
/// Every triangle is its own chart, so every edge is a UV seam; the runtime's
/// one-sample-per-vertex rule keeps the reconstruction watertight.
/// Fails when the map is too small to give every triangle at least a few texels.
Status buildTriangleAtlas(ControlMesh* mesh, const AtlasOptions& options);

}  // namespace baker
}  // namespace strata
