// Internal: a capture's appearance (materials, vertex colours) carried onto
// an automatic cage as textures in its UVs.
#pragma once

#include "strata/baker/distance.h"
#include "strata/control_mesh.h"
#include "strata/displacement_map.h"
#include "strata/io/materials.h"
#include "strata/io/rig_io.h"
#include "strata/status.h"

#include <glm/vec4.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace strata {
namespace baker {

/// A capture as the re-bake reads its appearance.
struct CaptureAppearance {
    const io::SceneMaterials& materials;         ///< a glTF capture's (no materials: vertexColours alone)
    const std::vector<glm::vec4>& vertexColours;  ///< a PLY's or OBJ's, linear, per capture vertex (or empty)
    const std::vector<glm::vec3>& positions;      ///< the capture's vertices (its shading normals' geometry)
    const std::vector<uint32_t>& triangles;       ///< the capture's, 3 per face
    const std::vector<uint32_t>& fileCorners;     ///< per capture corner, its file vertex (materials' UVs, colours)
    const std::vector<int>& faceMaterial;         ///< per capture face, its material in `materials`
    size_t mainMaterial = 0;                      ///< the one most faces wear: its alpha mode and sidedness
    bool drawnFlat = false;                       ///< drawn faceted (and so its rig: the normal texture's frame)
};

/// The capture's colour, as glTF draws it (every material's base colour
/// factor and texture, its vertex colours), as one texture in `control`'s
/// UVs, at the resolution of its largest texture, or about a texel per
/// vertex where the vertices carry colours (256 to 2048 texels a side);
/// metallic-roughness (with occlusion in R) and emission as textures of
/// their own where the materials differ in them or have them as
/// textures; where a material has a normal texture, a normal texture that
/// gives the rig's surface (`control` displaced by `map` in `scheme` at
/// `level`) the capture's shading normals (transferNormals).  Each texel
/// reads the capture where the displaced cage (`control`, `map`) meets it,
/// found through `captureIndex`, on `threads`.  `out` gets
/// the rig's one material, `note` the summary's words for what was
/// carried.  Fails, before any work, where the textures would need more
/// than `maxMemoryMB`.
Status carryAppearance(const CaptureAppearance& capture, const ControlMesh& control, const DisplacementMap& map,
                       Scheme scheme, int level, const TriangleIndex& captureIndex, double maxMemoryMB, int threads,
                       io::BaseColourTexture* out, std::string* note);

}  // namespace baker
}  // namespace strata
