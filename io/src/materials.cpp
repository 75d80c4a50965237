// Materials of a rig's source document as plain data (viewer, engines).
#include "strata/io/materials.h"
#include "strata/io/png.h"

#include "gltf_accessor.h"
#include "gltf_document.h"
#include "refined_attributes.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <stb/stb_image.h>
#include <avif/avif.h>
#include <webp/decode.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace strata {
namespace io {
namespace {

// The encoded bytes of image i: its bufferView, or what the loader kept.
std::vector<unsigned char> encodedImage(const SourceDocument& doc, size_t i)
{
    const tinygltf::Model& m = doc.model;
    const tinygltf::Image& im = m.images[i];
    if (im.bufferView >= 0 && size_t(im.bufferView) < m.bufferViews.size()) {
        const tinygltf::BufferView& v = m.bufferViews[size_t(im.bufferView)];
        if (v.buffer >= 0 && size_t(v.buffer) < m.buffers.size()) {
            const std::vector<unsigned char>& data = m.buffers[size_t(v.buffer)].data;
            if (v.byteOffset <= data.size() && v.byteLength <= data.size() - v.byteOffset)
                return std::vector<unsigned char>(data.begin() + long(v.byteOffset),
                                                  data.begin() + long(v.byteOffset + v.byteLength));
        }
        return {};
    }
    return i < doc.imageBytes.size() ? doc.imageBytes[i] : std::vector<unsigned char>();
}

// The image texture `tex` reads: its source, else EXT_texture_webp's or
// EXT_texture_avif's (an image only that extension names, as glTF
// Transform's optimize, webp and avif write them); -1 for none.
int textureImage(const tinygltf::Model& m, int tex)
{
    const tinygltf::Texture& t = m.textures[size_t(tex)];
    if (t.source >= 0 && size_t(t.source) < m.images.size())
        return t.source;
    for (const char* name : {"EXT_texture_webp", "EXT_texture_avif"}) {
        const auto e = t.extensions.find(name);
        if (e == t.extensions.end() || !e->second.IsObject() || !e->second.Get("source").IsInt())
            continue;
        const int source = e->second.Get("source").Get<int>();
        if (source >= 0 && size_t(source) < m.images.size())
            return source;
    }
    return -1;
}

// An AVIF's first image as 8-bit RGBA (any depth, subsampling or alpha
// libavif reads), sized from its container before any AV1 is decoded and
// refused unless `fits` (a sequence gives its first frame).  False for a
// broken file or one that does not fit.
template <typename Fits>
bool decodeAvif(const std::vector<unsigned char>& bytes, const Fits& fits, ImageRGBA* out)
{
    avifDecoder* decoder = avifDecoderCreate();
    if (!decoder)
        return false;
    decoder->maxThreads = 1;
    decoder->ignoreExif = AVIF_TRUE;
    decoder->ignoreXMP = AVIF_TRUE;
    decoder->imageSizeLimit = 4096u * 4096u;
    decoder->imageDimensionLimit = 16384;
    bool ok = avifDecoderSetIOMemory(decoder, bytes.data(), bytes.size()) == AVIF_RESULT_OK &&
              avifDecoderParse(decoder) == AVIF_RESULT_OK && decoder->image &&
              decoder->image->width <= 16384 && decoder->image->height <= 16384 &&
              fits(int(decoder->image->width), int(decoder->image->height)) &&
              avifDecoderNextImage(decoder) == AVIF_RESULT_OK &&
              // The AV1 payload's own size, which may differ from its container's.
              decoder->image->width <= 16384 && decoder->image->height <= 16384 &&
              fits(int(decoder->image->width), int(decoder->image->height));
    if (ok) {
        avifRGBImage rgb;
        avifRGBImageSetDefaults(&rgb, decoder->image);
        rgb.format = AVIF_RGB_FORMAT_RGBA;
        rgb.depth = 8;
        out->width = int(rgb.width);
        out->height = int(rgb.height);
        out->rgba.assign(size_t(rgb.width) * size_t(rgb.height) * 4, 0);
        rgb.pixels = out->rgba.data();
        rgb.rowBytes = rgb.width * 4;
        ok = avifImageYUVToRGB(decoder->image, &rgb) == AVIF_RESULT_OK;
        if (!ok)
            *out = ImageRGBA();
    }
    avifDecoderDestroy(decoder);
    return ok;
}

// Decodes a PNG, JPEG, WebP or AVIF image into 4 bytes a pixel; false for
// any other or a broken one.  The header's size first: a hostile one would
// have the decoder allocate gigabytes before it finds no pixels behind it.
// Nor can a PNG or JPEG expand past deflate's limit (about 1032:1; a flat
// 4096^2 PNG is 64 MB from 64 KB): at most 2048x its bytes, plus 16 MB; a
// lossless WebP or an AVIF of one colour codes 4096^2 in a few hundred
// bytes, so any WebP or AVIF up to 4096^2 is decoded.  glTF's images are
// PNG, JPEG and (through EXT_texture_webp and EXT_texture_avif) WebP and
// AVIF, and stb_image would read others; a PNG's chunks must lie inside it
// (pngChunksFit, which checks its signature too).
bool decodeImage(const std::vector<unsigned char>& bytes, ImageRGBA* out)
{
    const std::string mime = sniffMime(bytes);
    const bool jpeg = mime == "image/jpeg", webp = mime == "image/webp", avif = mime == "image/avif";
    if (bytes.size() > (size_t(1) << 30))
        return false;
    const auto fits = [&](int w, int h) {
        const size_t pixels = 4 * size_t(w) * size_t(h);
        return w > 0 && h > 0 && w <= 16384 && h <= 16384 &&
               (pixels <= 2048 * bytes.size() + (size_t(16) << 20) ||
                ((webp || avif) && pixels <= (size_t(64) << 20)));
    };
    if (avif)
        return decodeAvif(bytes, fits, out);
    int w = 0, h = 0, comp = 0;
    if (webp) {
        if (!WebPGetInfo(bytes.data(), bytes.size(), &w, &h) || !fits(w, h))
            return false;
        uint8_t* px = WebPDecodeRGBA(bytes.data(), bytes.size(), &w, &h);
        if (!px)
            return false;
        out->width = w;
        out->height = h;
        out->rgba.assign(px, px + size_t(w) * size_t(h) * 4);
        WebPFree(px);
        return true;
    }
    if (!(jpeg || pngChunksFit(bytes.data(), bytes.size())) ||
        !stbi_info_from_memory(bytes.data(), int(bytes.size()), &w, &h, &comp) || !fits(w, h))
        return false;
    stbi_uc* px = stbi_load_from_memory(bytes.data(), int(bytes.size()), &w, &h, &comp, 4);
    if (!px)
        return false;
    const bool sized = w > 0 && h > 0 && w <= 16384 && h <= 16384;
    if (sized) {
        out->width = w;
        out->height = h;
        out->rgba.assign(px, px + size_t(w) * size_t(h) * 4);
    }
    stbi_image_free(px);
    return sized;
}

// Texture `tex`'s sampler's wraps, into `mat` (glTF's default: repeat).
void samplerOf(const tinygltf::Model& m, int tex, TextureCoords* mat)
{
    const int sampler = m.textures[size_t(tex)].sampler;
    if (sampler < 0 || size_t(sampler) >= m.samplers.size())
        return;
    auto mode = [](int code) {
        return code == int(TextureWrap::ClampToEdge)      ? TextureWrap::ClampToEdge
               : code == int(TextureWrap::MirroredRepeat) ? TextureWrap::MirroredRepeat
                                                          : TextureWrap::Repeat;
    };
    mat->wrapS = mode(m.samplers[size_t(sampler)].wrapS);
    mat->wrapT = mode(m.samplers[size_t(sampler)].wrapT);
}

// KHR_texture_transform of a texture reference, into `mat`; false (mat
// unchanged) when its values are not finite numbers of the right shape.
bool readTextureTransform(const tinygltf::ExtensionMap& extensions, TextureCoords* mat)
{
    const auto it = extensions.find("KHR_texture_transform");
    if (it == extensions.end() || !it->second.IsObject())
        return true;
    const tinygltf::Value& t = it->second;
    TextureCoords m = *mat;
    auto number = [](const tinygltf::Value& v, float* out) {
        if (!v.IsNumber() && !v.IsInt())
            return false;
        const double d = v.IsInt() ? double(v.Get<int>()) : v.Get<double>();
        *out = float(d);
        return std::isfinite(d) && std::isfinite(*out);
    };
    auto pair = [&](const char* key, glm::vec2* out) {
        if (!t.Has(key))
            return true;
        const tinygltf::Value& a = t.Get(key);
        return a.IsArray() && a.ArrayLen() == 2 && number(a.Get(0), &out->x) && number(a.Get(1), &out->y);
    };
    if (!pair("offset", &m.uvOffset) || !pair("scale", &m.uvScale) ||
        (t.Has("rotation") && !number(t.Get("rotation"), &m.uvRotation)))
        return false;
    if (t.Has("texCoord")) {
        if (!t.Get("texCoord").IsInt() || t.Get("texCoord").Get<int>() < 0 || t.Get("texCoord").Get<int>() > 7)
            return false;
        m.texCoord = t.Get("texCoord").Get<int>();
    }
    *mat = m;
    return true;
}

}  // namespace

glm::vec2 TextureCoords::textureUV(glm::vec2 uv) const
{
    const glm::vec2 s = uvScale * uv;
    const float c = std::cos(uvRotation), n = std::sin(uvRotation);
    return uvOffset + glm::vec2(c * s.x + n * s.y, c * s.y - n * s.x);
}

glm::dvec4 sampleImage(const ImageRGBA& image, const glm::dvec2& uv, bool nearest, TextureWrap wrapS,
                       TextureWrap wrapT)
{
    const int w = image.width, h = image.height;
    if (w <= 0 || h <= 0 || image.rgba.size() < 4 * size_t(w) * size_t(h))
        return glm::dvec4(1.0);
    const double x = uv.x * w - 0.5, y = uv.y * h - 0.5;
    // Texel index t of an axis of n texels, wrapped in doubles first (a UV
    // far outside [0, 1] stays in range).
    auto wrap = [](double t, int n, TextureWrap mode) {
        double at = t;
        if (mode == TextureWrap::ClampToEdge) {
            at = std::clamp(t, 0.0, double(n - 1));
        } else if (mode == TextureWrap::MirroredRepeat) {
            at = t - std::floor(t / (2.0 * n)) * (2.0 * n);  // [0, 2n): the image, then its mirror
            if (at >= n)
                at = 2.0 * n - 1.0 - at;
        } else {
            at = t - std::floor(t / n) * n;
        }
        return std::min(size_t(std::max(at, 0.0)), size_t(n - 1));
    };
    auto texel = [&](double tx, double ty) {
        const size_t ix = wrap(tx, w, wrapS), iy = wrap(ty, h, wrapT);
        const size_t i = 4 * (iy * size_t(w) + ix);
        return glm::dvec4(image.rgba[i], image.rgba[i + 1], image.rgba[i + 2], image.rgba[i + 3]) / 255.0;
    };
    if (!std::isfinite(x) || !std::isfinite(y))
        return texel(0.0, 0.0);
    if (nearest)
        return texel(std::floor(x + 0.5), std::floor(y + 0.5));
    const double fx = std::floor(x), fy = std::floor(y), ax = x - fx, ay = y - fy;
    return (1 - ax) * (1 - ay) * texel(fx, fy) + ax * (1 - ay) * texel(fx + 1, fy) + (1 - ax) * ay * texel(fx, fy + 1) +
           ax * ay * texel(fx + 1, fy + 1);
}

double srgbToLinear(double coded)
{
    const double c = std::clamp(coded, 0.0, 1.0);
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

double linearToSrgb(double linear)
{
    const double c = std::clamp(linear, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}

glm::dvec4 srgbToLinear(const glm::dvec4& coded)
{
    return glm::dvec4(srgbToLinear(coded.r), srgbToLinear(coded.g), srgbToLinear(coded.b), coded.a);
}

glm::dvec4 sampleLinear(const TextureCoords& material, const ImageRGBA& image, const glm::dvec2& uv, bool nearest)
{
    return srgbToLinear(sampleImage(image, uv, nearest, material.wrapS, material.wrapT));
}

glm::dvec4 baseColourAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv,
                        const glm::dvec4& vertexColour, bool nearest)
{
    glm::dvec4 c = glm::dvec4(material.baseColor) * vertexColour;
    if (image && image->width > 0 && image->height > 0)
        c *= sampleLinear(material, *image, uv, nearest);
    return c;
}

glm::dvec2 metallicRoughnessAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest)
{
    glm::dvec2 mr(material.metallic, material.roughness);
    if (image && image->width > 0 && image->height > 0) {
        const TextureCoords& c = material.channel(material.metallicRoughnessChannel);
        const glm::dvec4 t = sampleImage(*image, uv, nearest, c.wrapS, c.wrapT);
        mr *= glm::dvec2(t.b, t.g);
    }
    return mr;
}

glm::dvec3 emissiveAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest)
{
    glm::dvec3 e(material.emissive);
    if (image && image->width > 0 && image->height > 0)
        e *= glm::dvec3(sampleLinear(material.channel(material.emissiveChannel), *image, uv, nearest));
    return e;
}

double occlusionAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest)
{
    if (!image || image->width <= 0 || image->height <= 0)
        return 1.0;
    const TextureCoords& c = material.channel(material.occlusionChannel);
    const double r = sampleImage(*image, uv, nearest, c.wrapS, c.wrapT).r;
    return 1.0 + double(material.occlusionStrength) * (r - 1.0);
}

glm::dvec3 normalAt(const MaterialInfo& material, const ImageRGBA* image, const glm::dvec2& uv, bool nearest)
{
    if (!image || image->width <= 0 || image->height <= 0)
        return glm::dvec3(0.0, 0.0, 1.0);
    const TextureCoords& c = material.channel(material.normalChannel);
    const glm::dvec4 t = sampleImage(*image, uv, nearest, c.wrapS, c.wrapT);
    glm::dvec3 n(2.0 * t.x - 1.0, 2.0 * t.y - 1.0, 2.0 * t.z - 1.0);
    n.x *= double(material.normalScale);
    n.y *= double(material.normalScale);
    const double length = glm::length(n);
    return length > 1e-12 && std::isfinite(length) ? n / length : glm::dvec3(0.0, 0.0, 1.0);
}

Status loadSceneMaterials(const Rig& rig, SceneMaterials* out, std::vector<std::string>* warnings)
{
    SceneMaterials s;
    s.fileUVs.assign(rig.sourceVertex.size(), glm::vec2(0.0f));
    if (!rig.source) {
        s.materials.resize(1);
        s.partMaterial.assign(std::max<size_t>(rig.parts.size(), 1), 0);
        *out = std::move(s);
        return Status::ok();
    }
    const tinygltf::Model& m = rig.source->model;
    s.images.resize(m.images.size());
    std::vector<bool> used(m.images.size(), false);
    tinygltf::ExtensionMap diffuseExtensions;  // a specular-glossiness diffuse texture's own
    for (const tinygltf::Material& in : m.materials) {
        MaterialInfo mat;
        mat.name = in.name;
        const std::vector<double>& f = in.pbrMetallicRoughness.baseColorFactor;
        if (f.size() == 4)
            mat.baseColor = glm::vec4(float(f[0]), float(f[1]), float(f[2]), float(f[3]));
        int tex = in.pbrMetallicRoughness.baseColorTexture.index;
        const tinygltf::ExtensionMap* texExtensions = &in.pbrMetallicRoughness.baseColorTexture.extensions;
        int texCoord = in.pbrMetallicRoughness.baseColorTexture.texCoord;
        // KHR_materials_pbrSpecularGlossiness (older exports, Sketchfab's
        // among them): its diffuse colour and texture are the base colour.
        const auto sg = in.extensions.find("KHR_materials_pbrSpecularGlossiness");
        if (sg != in.extensions.end() && sg->second.IsObject()) {
            const tinygltf::Value& d = sg->second.Get("diffuseFactor");
            if (d.IsArray() && d.ArrayLen() == 4) {
                glm::vec4 c;
                bool numbers = true;
                for (int k = 0; k < 4; ++k) {
                    numbers = numbers && d.Get(k).IsNumber();
                    c[k] = numbers ? float(d.Get(k).GetNumberAsDouble()) : 0.0f;
                }
                if (numbers && std::isfinite(c.x + c.y + c.z + c.w))
                    mat.baseColor = c;
            }
            const tinygltf::Value& t = sg->second.Get("diffuseTexture");
            if (tex < 0 && t.IsObject() && t.Get("index").IsInt()) {
                tex = t.Get("index").Get<int>();
                texCoord = t.Get("texCoord").IsInt() ? t.Get("texCoord").Get<int>() : 0;
                diffuseExtensions.clear();  // its own KHR_texture_transform, read below
                if (t.Get("extensions").IsObject() && t.Get("extensions").Has("KHR_texture_transform"))
                    diffuseExtensions["KHR_texture_transform"] = t.Get("extensions").Get("KHR_texture_transform");
                texExtensions = &diffuseExtensions;
            }
        }
        if (tex >= 0 && size_t(tex) < m.textures.size()) {
            const int src = textureImage(m, tex);
            if (src >= 0) {
                mat.image = src;
                used[size_t(src)] = true;
            } else if (warnings) {
                // An image only an extension other than EXT_texture_webp
                // and EXT_texture_avif names (KTX2, DDS: no fallback in
                // `source`).
                std::string coded;
                for (const auto& [name, value] : m.textures[size_t(tex)].extensions)
                    coded += (coded.empty() ? "" : ", ") + name;
                warnings->push_back("material " + std::to_string(s.materials.size()) + " (" +
                                    printable(in.name, 60) + "): its base colour texture is " +
                                    (coded.empty() ? std::string("no image")
                                                   : "only in " + printable(coded, 120) +
                                                         ", an image Strata does not decode") +
                                    "; drawn in its colour factor alone");
            }
            mat.texCoord = std::clamp(texCoord, 0, 7);
            samplerOf(m, tex, &mat);
            if (!readTextureTransform(*texExtensions, &mat) && warnings)
                warnings->push_back("material " + std::to_string(s.materials.size()) + " (" + printable(in.name, 60) +
                                    "): its KHR_texture_transform is not numbers of the right shape; ignored");
        }
        // The metallic-roughness, emissive and occlusion textures, each read
        // through the base colour texture's UVs (the first texture's,
        // without one) where it shares their set, transform and wraps, else
        // through the second channel, which the first to differ sets.
        const auto alongside = [&](int index, int set, const tinygltf::ExtensionMap& extensions, int* image,
                                   int* channel) {
            if (index < 0 || size_t(index) >= m.textures.size())
                return;
            const int src = textureImage(m, index);
            TextureCoords probe;
            probe.texCoord = std::clamp(set, 0, 7);
            if (src < 0 || !readTextureTransform(extensions, &probe)) {
                ++mat.unreadTextures;
                return;
            }
            samplerOf(m, index, &probe);
            if (!mat.textured()) {
                static_cast<TextureCoords&>(mat) = probe;
                *channel = 0;
            } else if (probe.sameSampling(mat)) {
                *channel = 0;
            } else if (!mat.hasSecond || probe.sameSampling(mat.second)) {
                if (!mat.hasSecond)
                    mat.second = probe;
                mat.hasSecond = true;
                *channel = 1;
            } else {
                ++mat.unreadTextures;  // a third set or transform
                return;
            }
            *image = src;
            used[size_t(src)] = true;
        };
        const tinygltf::TextureInfo& mr = in.pbrMetallicRoughness.metallicRoughnessTexture;
        alongside(mr.index, mr.texCoord, mr.extensions, &mat.metallicRoughnessImage, &mat.metallicRoughnessChannel);
        alongside(in.emissiveTexture.index, in.emissiveTexture.texCoord, in.emissiveTexture.extensions,
                  &mat.emissiveImage, &mat.emissiveChannel);
        alongside(in.occlusionTexture.index, in.occlusionTexture.texCoord, in.occlusionTexture.extensions,
                  &mat.occlusionImage, &mat.occlusionChannel);
        if (std::isfinite(in.occlusionTexture.strength))
            mat.occlusionStrength = float(std::clamp(in.occlusionTexture.strength, 0.0, 1.0));
        alongside(in.normalTexture.index, in.normalTexture.texCoord, in.normalTexture.extensions, &mat.normalImage,
                  &mat.normalChannel);
        if (std::isfinite(in.normalTexture.scale))
            mat.normalScale = float(std::clamp(in.normalTexture.scale, -100.0, 100.0));
        const std::vector<double>& ef = in.emissiveFactor;
        if (ef.size() == 3 && std::isfinite(ef[0] + ef[1] + ef[2]))
            mat.emissive = glm::clamp(glm::vec3(float(ef[0]), float(ef[1]), float(ef[2])), glm::vec3(0.0f),
                                      glm::vec3(1.0f));
        // KHR_materials_emissive_strength scales it past 1 (up to 1000 here).
        const auto strength = in.extensions.find("KHR_materials_emissive_strength");
        if (strength != in.extensions.end() && strength->second.IsObject() &&
            strength->second.Get("emissiveStrength").IsNumber()) {
            const double k = strength->second.Get("emissiveStrength").GetNumberAsDouble();
            if (std::isfinite(k) && k >= 0.0)
                mat.emissive *= float(std::min(k, 1000.0));
        }
        mat.alphaMode = in.alphaMode == "MASK" ? AlphaMode::Mask : in.alphaMode == "BLEND" ? AlphaMode::Blend
                                                                                           : AlphaMode::Opaque;
        mat.alphaCutoff = float(in.alphaCutoff);
        mat.doubleSided = in.doubleSided;
        mat.metallic = float(in.pbrMetallicRoughness.metallicFactor);
        mat.roughness = float(in.pbrMetallicRoughness.roughnessFactor);
        s.materials.push_back(mat);
    }
    const int defaultMaterial = int(s.materials.size());
    s.materials.push_back(MaterialInfo());
    for (size_t i = 0; i < m.images.size(); ++i) {
        if (!used[i])
            continue;
        const std::vector<unsigned char> encoded = encodedImage(*rig.source, i);
        if (!decodeImage(encoded, &s.images[i])) {
            // What its bytes say it is: a broken or oversized one of the
            // kinds read, or another kind.
            const std::string mime = sniffMime(encoded);
            const bool read =
                mime == "image/png" || mime == "image/jpeg" || mime == "image/webp" || mime == "image/avif";
            const std::string why = read ? "a broken " + mime.substr(6) +
                                               ", or past 16384 texels a side or its bytes' worth"
                                         : std::string("not PNG, JPEG, WebP or AVIF");
            if (warnings)
                warnings->push_back("image " + std::to_string(i) + " (" + printable(m.images[i].name, 60) +
                                    ") cannot be decoded; drawn untextured (" + why + ")");
            for (MaterialInfo& mat : s.materials)
                for (int* texture :
                     {&mat.image, &mat.metallicRoughnessImage, &mat.emissiveImage, &mat.occlusionImage,
                      &mat.normalImage})
                    if (*texture == int(i))
                        *texture = -1;
            continue;
        }
    }
    for (const RigPart& part : rig.parts) {
        const tinygltf::Primitive& prim = m.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
        const int mi = prim.material >= 0 && prim.material < defaultMaterial ? prim.material : defaultMaterial;
        s.partMaterial.push_back(mi);
        // COLOR_0: VEC3 or VEC4, float or normalized integers.
        if (const auto c = prim.attributes.find("COLOR_0"); c != prim.attributes.end()) {
            const int components = attributeComponents(m, c->second);
            std::vector<float> rgba;
            if ((components != 3 && components != 4) ||
                !readFloatAccessor(m, c->second, components, "COLOR_0", &rgba) ||
                rgba.size() != size_t(components) * part.vertexCount) {
                if (warnings)
                    warnings->push_back(part.name + ": its COLOR_0 is not one RGB or RGBA colour per vertex; ignored");
            } else {
                if (s.fileColours.empty())
                    s.fileColours.assign(rig.sourceVertex.size(), glm::vec4(1.0f));
                for (uint32_t v = 0; v < part.vertexCount; ++v)
                    for (int k = 0; k < components; ++k)
                        s.fileColours[part.firstVertex + v][k] =
                            std::clamp(rgba[size_t(components) * v + size_t(k)], 0.0f, 1.0f);
            }
        }
        // NORMAL and TANGENT, into the scene's space as the positions went
        // (a tangent's w turned where the transform mirrors).  Each of its
        // vertices' values to `store`, or a warning.
        const auto perVertex = [&](const char* name, int components, const auto& store) {
            const auto a = prim.attributes.find(name);
            std::vector<float> values;
            if (a == prim.attributes.end())
                return;
            if (!readFloatAccessor(m, a->second, components, name, &values) ||
                values.size() != size_t(components) * part.vertexCount) {
                if (warnings)
                    warnings->push_back(part.name + ": its " + name + " is not one per vertex; ignored");
                return;
            }
            for (uint32_t v = 0; v < part.vertexCount; ++v)
                store(part.firstVertex + v, &values[size_t(components) * v]);
        };
        const glm::mat3 linear(part.toScene), normalMatrix = glm::transpose(glm::inverse(linear));
        const float mirror = glm::determinant(linear) < 0.0f ? -1.0f : 1.0f;
        perVertex("NORMAL", 3, [&](uint32_t file, const float* n) {
            if (s.fileNormals.empty())
                s.fileNormals.assign(rig.sourceVertex.size(), glm::vec3(0.0f));
            const glm::vec3 d = normalMatrix * glm::vec3(n[0], n[1], n[2]);
            const float length = glm::length(d);
            if (length > 0.0f && std::isfinite(length))
                s.fileNormals[file] = d / length;
        });
        perVertex("TANGENT", 4, [&](uint32_t file, const float* t) {
            if (s.fileTangents.empty())
                s.fileTangents.assign(rig.sourceVertex.size(), glm::vec4(0.0f));
            const glm::vec3 d = linear * glm::vec3(t[0], t[1], t[2]);
            const float length = glm::length(d);
            if (length > 0.0f && std::isfinite(length))
                s.fileTangents[file] = glm::vec4(d / length, t[3] < 0.0f ? -mirror : mirror);
        });
        const MaterialInfo& mat = s.materials[size_t(mi)];
        if (!mat.textured())
            continue;
        for (int c = 0; c < (mat.hasSecond ? 2 : 1); ++c) {
            const TextureCoords& coords = mat.channel(c);
            auto it = prim.attributes.find("TEXCOORD_" + std::to_string(coords.texCoord));
            std::vector<float> uv;
            if (it == prim.attributes.end() || !readFloatAccessor(m, it->second, 2, it->first, &uv) ||
                uv.size() != 2 * size_t(part.vertexCount)) {
                if (warnings)
                    warnings->push_back(part.name + ": its material's " + (c ? "second UV set" : "texture") +
                                        " has no usable UVs (TEXCOORD_" + std::to_string(coords.texCoord) +
                                        "); drawn untextured");
                continue;
            }
            std::vector<glm::vec2>& to = c ? s.fileUVs2 : s.fileUVs;
            if (to.empty())
                to.assign(rig.sourceVertex.size(), glm::vec2(0.0f));
            for (uint32_t v = 0; v < part.vertexCount; ++v)
                to[part.firstVertex + v] = coords.textureUV(glm::vec2(uv[2 * v], uv[2 * v + 1]));
        }
    }
    *out = std::move(s);
    return Status::ok();
}

std::string featuresNotCarried(const Rig& rig, int main, const SceneMaterials* materials)
{
    if (!rig.source)
        return std::string();
    const tinygltf::Model& m = rig.source->model;
    // Only the materials and primitives the rig's parts use count.
    std::vector<bool> usedMaterial(m.materials.size(), false);
    size_t colours = 0, morphs = 0;
    std::map<std::string, size_t> primitiveExtensions;  // extension -> primitives
    for (const RigPart& part : rig.parts) {
        if (part.mesh < 0 || size_t(part.mesh) >= m.meshes.size() || part.primitive < 0 ||
            size_t(part.primitive) >= m.meshes[size_t(part.mesh)].primitives.size())
            continue;
        const tinygltf::Primitive& prim = m.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
        if (prim.material >= 0 && size_t(prim.material) < m.materials.size())
            usedMaterial[size_t(prim.material)] = true;
        for (const auto& a : prim.attributes)
            colours += a.first.rfind("COLOR_", 0) == 0 && a.first != "COLOR_0";
        morphs += !prim.targets.empty();
        // A primitive's own extensions (KHR_materials_variants' material
        // per variant, for one); Draco's geometry is decoded.
        for (const auto& e : prim.extensions)
            if (e.first != "KHR_draco_mesh_compression")
                ++primitiveExtensions[e.first];
    }
    std::map<std::string, size_t> counts;  // feature -> materials
    const tinygltf::Material* kept =
        main >= 0 && size_t(main) < m.materials.size() ? &m.materials[size_t(main)] : nullptr;
    for (size_t i = 0; i < m.materials.size(); ++i) {
        if (!usedMaterial[i])
            continue;
        const tinygltf::Material& in = m.materials[i];
        if (!materials && in.normalTexture.index >= 0)
            ++counts["normal textures"];
        if (!materials && in.occlusionTexture.index >= 0)
            ++counts["occlusion textures"];
        if (materials && i < materials->materials.size() && materials->materials[i].unreadTextures > 0)
            ++counts["metallic-roughness, emissive, occlusion or normal textures on a third UV set or transform, "
                     "or not decoded"];
        for (const auto& e : in.extensions)
            if (e.first != "KHR_materials_emissive_strength")  // carried
                ++counts[e.first == "KHR_materials_pbrSpecularGlossiness"
                             ? "specular and glossiness (KHR_materials_pbrSpecularGlossiness, its diffuse carried)"
                             : e.first];
        if (kept && (in.alphaMode != kept->alphaMode || in.doubleSided != kept->doubleSided))
            ++counts["other alpha modes or sidedness"];
    }
    std::string out;
    auto add = [&](size_t n, const std::string& what, const char* one, const char* many) {
        if (n)
            out += (out.empty() ? "" : ", ") + what + " (" + std::to_string(n) + " " + (n == 1 ? one : many) + ")";
    };
    for (const auto& [what, n] : counts)
        add(n, what, "material", "materials");
    size_t lines = 0;  // point and line primitives (the rig reader keeps them only in a control's file)
    for (const tinygltf::Mesh& mesh : m.meshes)
        for (const tinygltf::Primitive& prim : mesh.primitives)
            lines += prim.mode >= TINYGLTF_MODE_POINTS && prim.mode <= TINYGLTF_MODE_LINE_STRIP;
    add(colours, "vertex colour sets past COLOR_0", "set", "sets");
    add(lines, "point and line primitives", "primitive", "primitives");
    add(morphs, "morph targets", "primitive", "primitives");
    for (const auto& [what, n] : primitiveExtensions)
        add(n, what, "primitive", "primitives");
    add(m.cameras.size(), "cameras", "camera", "cameras");
    add(m.lights.size(), "lights", "light", "lights");
    // Any other extension the document uses (KHR_animation_pointer's
    // channels, KHR_xmp_json_ld's metadata): what is read, decoded or named
    // above is not named again.
    static const char* const kAccountedFor[] = {"KHR_texture_transform",       "KHR_mesh_quantization",
                                                "KHR_draco_mesh_compression",  "EXT_meshopt_compression",
                                                "STRATA_layered_displacement", "EXT_mesh_gpu_instancing",
                                                "KHR_lights_punctual",         "KHR_texture_basisu",
                                                "EXT_texture_webp",            "EXT_texture_avif"};
    for (const std::string& e : m.extensionsUsed) {
        const bool listed =
            std::find(std::begin(kAccountedFor), std::end(kAccountedFor), e) != std::end(kAccountedFor);
        const bool accounted = listed || e.rfind("KHR_materials_", 0) == 0 || primitiveExtensions.count(e);
        if (!accounted)
            out += (out.empty() ? "" : ", ") + printable(e, 60) + " (the document's)";
    }
    return out;
}

}  // namespace io
}  // namespace strata
