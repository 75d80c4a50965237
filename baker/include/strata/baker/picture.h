// Strata baker: a character and its rig drawn side by side, on the CPU, to
// compare what they look like (the texture PSNR of a --control auto bake's
// per-frame table).  A small z-buffered rasteriser: perspective-correct UVs,
// the base colour factor times a bilinear, repeating texture, one light
// from the eye's side plus an ambient term, smooth or flat shading per part
// as glTF asks, the normal texture read in the frame a viewer derives for a
// mesh without TANGENT (normalTextureFrame).  No OpenGL: the baker runs on
// machines without a GPU.
#pragma once

#include "strata/io/materials.h"
#include "strata/io/render_mesh.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <cstdint>
#include <vector>

namespace strata {
namespace baker {

/// One run of triangles drawn with one material.
struct PicturePart {
    size_t firstTriangle = 0, triangleCount = 0;
    glm::vec4 colour{1.0f};                ///< base colour factor
    const io::ImageRGBA* image = nullptr;  ///< base colour texture, or null
    const float* uvs = nullptr;            ///< 2 per vertex (the texture's UV set), or null
    const io::MaterialInfo* material = nullptr;  ///< its texture's UV transform (null: none)
    const float* colours = nullptr;        ///< COLOR_0 per vertex (linear), or null
    int colourComponents = 0;              ///< 3 (RGB) or 4 (RGBA) per vertex in colours
    bool flat = false;                     ///< face normals (glTF's rule for a primitive without NORMAL)
    const io::ImageRGBA* normalImage = nullptr;       ///< normal texture (tangent space, linear), or null
    const float* normalUvs = nullptr;                 ///< 2 per vertex (the normal texture's UV set), or null
    const io::MaterialInfo* normalMaterial = nullptr;  ///< its scale, UV transform and wraps (io::normalAt)
};

/// A posed, textured triangle mesh as the picture sees it.
struct PictureMesh {
    std::vector<glm::vec3> positions;  ///< per vertex
    std::vector<glm::vec3> normals;    ///< per vertex, for smooth parts (need not be unit)
    std::vector<uint32_t> triangles;   ///< 3 per triangle
    std::vector<PicturePart> parts;
};

/// The picture's camera: square, `size` pixels a side.
struct PictureCamera {
    glm::vec3 eye{0.0f, 0.0f, 1.0f}, target{0.0f};
    glm::vec3 up{0.0f, 1.0f, 0.0f};
    float fovYDegrees = 35.0f;
    int size = 256;
};

/// A camera that frames the box [lo, hi] (glTF's +Y up), seen from the front
/// (+Z), a little from the side and above.
PictureCamera frameBox(const glm::vec3& lo, const glm::vec3& hi, int size = 256);

/// The mesh drawn through `camera`: RGB, 3 bytes a pixel, row 0 at the top,
/// black where nothing is drawn.
void renderPicture(const PictureMesh& mesh, const PictureCamera& camera, std::vector<uint8_t>* rgb);

/// PSNR (dB) of two pictures of the same size over the pixels either draws
/// (not black in both); 99 for two equal pictures, 0 when neither draws.
double picturePsnr(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b);

/// A rig's surface laid out for a picture: `layout` (buildRenderMesh of the
/// surface's plan), the surface's positions and normals in plan order, and
/// the rig's materials (loadSceneMaterials), each part with its material's
/// factor, texture and UV set, flat where RigPart::flat, and its normal
/// texture where `normalTextures`.
PictureMesh pictureOf(const io::RenderMesh& layout, const std::vector<glm::vec3>& positions,
                      const std::vector<glm::vec3>& normals, const io::SceneMaterials& materials,
                      bool normalTextures = true);

}  // namespace baker
}  // namespace strata
