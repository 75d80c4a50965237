// Strata baker: a captured character's colour carried into the automatic
// cage's own UVs (--control auto on a textured glTF), so one texture maps
// the layered surface as the source's textures mapped the capture.
#pragma once

#include "strata/baker/distance.h"
#include "strata/control_mesh.h"
#include "strata/displacement_map.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <glm/vec4.hpp>

#include <cstdint>
#include <functional>
#include <vector>

namespace strata {
namespace baker {

struct ColorImage {
    int width = 0, height = 0;
    std::vector<uint8_t> rgba;  ///< 4 bytes per texel, row 0 first (v = 0)
};

/// The capture's colour at a point of its triangle `face` (barycentrics b1,
/// b2 of corners 1 and 2), linear RGBA in [0, 1] (glTF's base colour:
/// factor, decoded texture and vertex colour multiplied).
using CaptureColour = std::function<glm::vec4(uint32_t face, double b1, double b2)>;

/// A size x size image of the capture's colour in the cage's UVs.  Each
/// texel centre inside a cage triangle's UVs stands for the point of the
/// layered surface there: the cage point moved by the map's displacement
/// along the blended vertex normals (paper eq. 2), whose nearest capture
/// point (`capture`, the capture's index) gives the colour.  Texels outside
/// every triangle take their nearest chart's colour (dilated), so filtering
/// at chart borders never reads another colour.  The image is written as
/// a glTF base colour texture is read: RGB sRGB-coded, alpha linear.  Deterministic for any
/// thread count.
Status transferColour(const ControlMesh& cage, const DisplacementMap& map, const TriangleIndex& capture,
                      const CaptureColour& colour, int size, ColorImage* out, int threads = 1);

/// One image transferColours makes: its values at a capture point, and how
/// they are coded.
struct ColourLayer {
    CaptureColour colour;
    bool srgb = true;  ///< RGB sRGB-coded (base colour, emissive); false: as they are (metallic-roughness)
};

/// transferColour for several images at once, one nearest-point query per
/// texel for all of them: `out` gets one image per layer, in order.
Status transferColours(const ControlMesh& cage, const DisplacementMap& map, const TriangleIndex& capture,
                       const std::vector<ColourLayer>& layers, int size, std::vector<ColorImage>* out,
                       int threads = 1);

/// The capture's shading normal at a point of its triangle `face`
/// (barycentrics b1, b2 of corners 1 and 2): a unit vector in the capture's
/// space, its normal texture applied where it has one; zero where it has
/// no direction (the texel then takes its neighbours').
using CaptureNormal = std::function<glm::vec3(uint32_t face, double b1, double b2)>;

/// A size x size tangent-space normal texture in the cage's UVs that gives
/// the surface Strata draws the capture's shading normals: `cage` refined
/// in `scheme` to `level` and displaced by `map` (the rig's recommended
/// level: what strata-view and the browser draw), shaded by its refined
/// vertices' normals (Plan::computeShadingNormals), or by its triangles'
/// own where `flat` (a rig drawn faceted, DisplacementInfo::flatShading).  Each texel centre
/// inside a refined triangle's UVs is its point there; the nearest capture
/// point (`capture`) gives the normal, written in the frame a viewer
/// derives per pixel for a glTF mesh without TANGENT, as three.js (and
/// strata-view) do: X and Y the surface gradients of u and -v across the
/// blended normal, both over the longer of the two, Z the blended normal;
/// the texel holds the unit (x, y, z) with x X + y Y + z Z along the
/// capture's normal, coded (x, y, z) / 2 + 1/2, alpha 255.  (Where the UVs
/// are conformal this is MikkTSpace's frame too.)  Texels outside every
/// triangle take their chart's (dilated).
Status transferNormals(const ControlMesh& cage, const DisplacementMap& map, Scheme scheme, int level, bool flat,
                       const TriangleIndex& capture, const CaptureNormal& normal, int size, ColorImage* out,
                       int threads = 1);

}  // namespace baker
}  // namespace strata
