// Strata io: the materials of a rig loaded from glTF, as plain data for a
// viewer or an engine (base colour factor and texture, alpha mode), with
// the UVs each primitive's base colour texture is sampled through.
#pragma once

#include "strata/rig.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec4.hpp>
#include <glm/ext/vector_double2.hpp>
#include <glm/ext/vector_double4.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace strata {
namespace io {

enum class AlphaMode { Opaque = 0, Mask = 1, Blend = 2 };

/// How a texture's sampler reads past [0, 1] (glTF's wrapS and wrapT, whose
/// codes these are).
enum class TextureWrap { Repeat = 10497, ClampToEdge = 33071, MirroredRepeat = 33648 };

/// Where a texture is read: its UV set, KHR_texture_transform and sampler.
struct TextureCoords {
    int texCoord = 0;  ///< the TEXCOORD_n set the texture uses (KHR_texture_transform's when it names one)
    /// KHR_texture_transform (identity without):
    /// uv' = uvOffset + R(uvRotation) (uvScale * uv), R turning counter-clockwise.
    glm::vec2 uvOffset{0.0f}, uvScale{1.0f};
    float uvRotation = 0.0f;
    /// The texture's sampler, along u and v (glTF's default: repeat).
    TextureWrap wrapS = TextureWrap::Repeat, wrapT = TextureWrap::Repeat;
    /// The texture's UV for a vertex's `uv` (the transform above applied).
    glm::vec2 textureUV(glm::vec2 uv) const;
    /// Whether `o` reads the same texels: the same set, transform and wraps.
    bool sameSampling(const TextureCoords& o) const
    {
        return texCoord == o.texCoord && uvOffset == o.uvOffset && uvScale == o.uvScale &&
               uvRotation == o.uvRotation && wrapS == o.wrapS && wrapT == o.wrapT;
    }
};

/// A material's textures are read through at most two UV channels: the
/// first (the TextureCoords a MaterialInfo is: the base colour texture's,
/// or its first other texture's without one, SceneMaterials::fileUVs) and a
/// second (MaterialInfo::second, SceneMaterials::fileUVs2) for textures on
/// another set, transform or sampler wrap, an occlusion texture on
/// TEXCOORD_1 as exporters often write it.
struct MaterialInfo : TextureCoords {
    std::string name;
    glm::vec4 baseColor{1.0f};  ///< baseColorFactor
    int image = -1;             ///< index into SceneMaterials::images of the base colour texture, or -1
    AlphaMode alphaMode = AlphaMode::Opaque;
    float alphaCutoff = 0.5f;
    bool doubleSided = false;
    float metallic = 1.0f, roughness = 1.0f;  ///< metallicFactor, roughnessFactor (glTF's defaults)
    glm::vec3 emissive{0.0f};  ///< emissiveFactor (linear), times KHR_materials_emissive_strength's strength
    /// The metallic-roughness texture (G roughness, B metallic, linear), the
    /// emissive texture (sRGB-coded) and the occlusion texture (R, linear),
    /// indices into SceneMaterials::images (-1: none).  Each is read through
    /// the first UV channel (channel 0: the base colour texture's UVs,
    /// transform and sampler) or the second (1: `second`).
    int metallicRoughnessImage = -1, emissiveImage = -1, occlusionImage = -1;
    int metallicRoughnessChannel = 0, emissiveChannel = 0, occlusionChannel = 0;
    TextureCoords second;      ///< the second channel's UVs, where a texture above uses it
    bool hasSecond = false;    ///< whether one does
    float occlusionStrength = 1.0f;  ///< the occlusion texture's strength
    /// The normal texture (tangent space, linear, glTF's: +X along +u, +Y
    /// along -v), an index into SceneMaterials::images (-1: none), its UV
    /// channel as the three above, and its scale (X and Y's).
    int normalImage = -1, normalChannel = 0;
    float normalScale = 1.0f;
    /// Of those four, how many are on a third UV set, transform or wrap,
    /// or have no image Strata decodes (not read).
    int unreadTextures = 0;
    /// UV channel c's coordinates (0: the first, 1: `second`).
    const TextureCoords& channel(int c) const { return c == 1 ? second : *this; }
    /// Whether any of its five textures is read (its UVs are then needed).
    bool textured() const
    {
        return image >= 0 || metallicRoughnessImage >= 0 || emissiveImage >= 0 || occlusionImage >= 0 ||
               normalImage >= 0;
    }
};

struct ImageRGBA {
    int width = 0, height = 0;
    std::vector<uint8_t> rgba;  ///< 4 bytes per pixel, row 0 first (glTF's v = 0)
};

struct SceneMaterials {
    std::vector<MaterialInfo> materials;  ///< the file's materials, plus glTF's default one last
    std::vector<ImageRGBA> images;        ///< decoded base colour images (same indices as the file's images)
    std::vector<int> partMaterial;        ///< per rig.parts entry: index into materials
    std::vector<glm::vec2> fileUVs;       ///< per file vertex: its part's base colour texture's UVs, transformed
                                          ///< (MaterialInfo::textureUV); (0, 0) without
    /// Per file vertex: its part's second UV channel, transformed
    /// (MaterialInfo::second.textureUV); (0, 0) without; empty when no
    /// material has one.
    std::vector<glm::vec2> fileUVs2;
    /// Per file vertex: its COLOR_0 as linear RGBA (RGB with alpha 1 from a
    /// VEC3), white where a part has none; empty when no part has one.
    std::vector<glm::vec4> fileColours;
    /// Per file vertex: its NORMAL in the scene's space (through its part's
    /// RigPart::toScene, as its position), unit; (0, 0, 0) where its part
    /// has none (glTF draws that part flat) or the normal is not a
    /// direction; empty when no part has one.
    std::vector<glm::vec3> fileNormals;
    /// Per file vertex: its TANGENT in the scene's space (xyz through its
    /// part's toScene, unit; w its bitangent's sign, turned where toScene
    /// mirrors); (0, 0, 0, 0) where its part has none; empty when no part
    /// has one.
    std::vector<glm::vec4> fileTangents;
};

/// The sRGB transfer function (IEC 61966-2-1) and its inverse, on one
/// channel in [0, 1].  glTF's base colour textures are sRGB-coded; its
/// base colour factors and vertex colours are linear.
double srgbToLinear(double coded);
double linearToSrgb(double linear);
/// An sRGB-coded colour (a texel, a PLY's or OBJ's vertex colour) in linear
/// light: RGB decoded, alpha as it is.
glm::dvec4 srgbToLinear(const glm::dvec4& coded);

/// The image at `uv` through `material`'s sampler, its RGB sRGB-decoded
/// (a base colour or emissive texture as glTF reads it), alpha as stored.
glm::dvec4 sampleLinear(const TextureCoords& material, const ImageRGBA& image, const glm::dvec2& uv,
                        bool nearest = false);

/// The base colour glTF draws with, linear RGBA: the material's factor
/// times its texture at `uv` (a texture UV, MaterialInfo::textureUV's;
/// sRGB-decoded; alpha as stored) times the vertex colour (`vertexColour`,
/// linear; white without).  `image`: the material's decoded image, or
/// null; `nearest` reads its nearest texel rather than bilinear.
glm::dvec4 baseColourAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv,
                        const glm::dvec4& vertexColour = glm::dvec4(1.0), bool nearest = false);

/// The metallic (x) and roughness (y) glTF draws with at `uv` (a texture
/// UV of the texture's channel, metallicRoughnessChannel: SceneMaterials'
/// fileUVs or fileUVs2): the factors times the metallic-roughness
/// texture's B and G (`image`: its decoded image, or null).
glm::dvec2 metallicRoughnessAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv,
                               bool nearest = false);

/// The emissive colour glTF draws with at `uv` (of emissiveChannel), linear
/// RGB: the factor times the emissive texture (sRGB-decoded; `image` or null).
glm::dvec3 emissiveAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest = false);

/// The ambient occlusion glTF draws with at `uv` (of occlusionChannel):
/// 1 + strength x (R - 1) of the occlusion texture (`image`), 1 without.
double occlusionAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest = false);

/// The tangent-space normal glTF draws with at `uv` (a texture UV of the
/// normal texture's channel, normalChannel): the texel's RGB as a vector in
/// [-1, 1] (linear), X and Y times normalScale, normalised; (0, 0, 1)
/// without an image.  Its frame is the surface's: X along the tangent (+u),
/// Y along the bitangent (-v, glTF's V running down its images), Z along
/// the normal.
glm::dvec3 normalAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest = false);

/// The image at UV `uv` as a glTF sampler reads it: bilinear (texel (x, y)
/// centred at ((x + 0.5) / width, (y + 0.5) / height)), or its nearest texel
/// when `nearest`, past its edges as wrapS and wrapT say (glTF's default:
/// repeating); RGBA in 0..1.  An empty image reads 1.
glm::dvec4 sampleImage(const ImageRGBA& image, const glm::dvec2& uv, bool nearest = false,
                       TextureWrap wrapS = TextureWrap::Repeat, TextureWrap wrapT = TextureWrap::Repeat);

/// Reads the materials of a rig loaded from glTF (rig.source).  Rigs from
/// other sources get the default material for every part.  Images that
/// cannot be decoded become untextured (a warning says which).
Status loadSceneMaterials(const Rig& rig, SceneMaterials* out, std::vector<std::string>* warnings = nullptr);

/// What an automatic cage made from a glTF scene leaves behind (its base
/// colour, metallic, roughness and emissive re-baked into textures of one
/// material with `main`'s alpha mode and sidedness, its shape one skinned
/// mesh), as a list for one line: normal textures, metallic-roughness,
/// emissive and occlusion textures not read (on a third UV set or
/// transform, past the base colour texture's and a second, or no image
/// Strata decodes; `materials` says, where given), material extensions,
/// materials whose alpha mode or sidedness differ from `main` (-1: none),
/// vertex colours other than COLOR_0 (which the re-baked texture carries),
/// point and line primitives, morph targets, primitives' own extensions
/// (KHR_materials_variants'; Draco's is decoded), cameras and lights, each with
/// how many materials, primitives or nodes have it.  Empty when nothing is
/// left behind, or the rig is not from glTF.
std::string featuresNotCarried(const Rig& rig, int main, const SceneMaterials* materials = nullptr);

}  // namespace io
}  // namespace strata
