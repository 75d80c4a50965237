// Carrying a capture's appearance onto an automatic cage: its materials'
// base colour, metallic-roughness, occlusion and emission, and its vertex
// colours, re-baked as glTF draws them into textures in the cage's UVs.
#include "material_carry.h"

#include "strata/baker/texture_transfer.h"
#include "strata/uv_raster.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <unordered_map>

namespace strata {
namespace baker {
namespace {

// Whether an RGBA image is flat colours: the 256 most common of its
// colours cover 99% of its texels (a palette laid out by hand, its edges
// antialiased).  `palette` gets those colours, most common first.
bool flatColours(const std::vector<uint8_t>& rgba, std::vector<uint32_t>* palette)
{
    palette->clear();
    std::unordered_map<uint32_t, uint32_t> count;
    const size_t texels = rgba.size() / 4;
    for (size_t i = 0; i < texels; ++i) {
        uint32_t c;
        std::memcpy(&c, &rgba[4 * i], 4);
        ++count[c];
        if (count.size() > 65536)
            return false;
    }
    std::vector<std::pair<uint32_t, uint32_t>> byCount(count.begin(), count.end());
    std::sort(byCount.begin(), byCount.end(), [](const auto& a, const auto& b) {
        return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    if (byCount.size() > 256)
        byCount.resize(256);
    size_t covered = 0;
    for (const auto& e : byCount)
        covered += e.second;
    if (double(covered) < 0.99 * double(texels))
        return false;
    for (const auto& e : byCount)
        palette->push_back(e.first);
    return true;
}

// Every texel of `rgba` not in `palette` takes the nearest colour of it
// (RGBA, squared distance).
void snapToPalette(std::vector<uint8_t>* rgba, const std::vector<uint32_t>& palette)
{
    if (palette.empty())
        return;
    std::vector<uint32_t> sorted = palette;
    std::sort(sorted.begin(), sorted.end());
    for (size_t i = 0; i + 3 < rgba->size(); i += 4) {
        uint32_t c;
        std::memcpy(&c, &(*rgba)[i], 4);
        if (std::binary_search(sorted.begin(), sorted.end(), c))
            continue;
        long best = -1;
        uint32_t nearest = palette[0];
        for (uint32_t q : palette) {
            uint8_t a[4];
            std::memcpy(a, &q, 4);
            long d = 0;
            for (int k = 0; k < 4; ++k) {
                const long e = long(a[k]) - long((*rgba)[i + size_t(k)]);
                d += e * e;
            }
            if (best < 0 || d < best) {
                best = d;
                nearest = q;
            }
        }
        std::memcpy(&(*rgba)[i], &nearest, 4);
    }
}

// What the materials the capture's faces wear need of the rig's one
// material: which of glTF's metallic-roughness, occlusion and emission vary
// or come from textures (each then a texture of its own), and the strongest
// emission (KHR_materials_emissive_strength past 1: the texture holds the
// emission over it).
struct MaterialNeeds {
    std::vector<const io::MaterialInfo*> used;
    bool varyingMR = false, emits = false, occludes = false, mrTextured = false, emissiveTextured = false;
    bool normalTextured = false;
    float emissiveScale = 1.0f;
};

MaterialNeeds needsOf(const io::SceneMaterials& sm, const std::vector<int>& faceMaterial)
{
    MaterialNeeds n;
    std::vector<uint8_t> usedMaterial(sm.materials.size(), 0);
    for (int m : faceMaterial)
        if (m >= 0 && size_t(m) < usedMaterial.size())
            usedMaterial[size_t(m)] = 1;
    for (size_t i = 0; i < sm.materials.size(); ++i)
        if (usedMaterial[i])
            n.used.push_back(&sm.materials[i]);
    for (const io::MaterialInfo* m : n.used) {
        n.varyingMR = n.varyingMR || m->metallic != n.used[0]->metallic || m->roughness != n.used[0]->roughness;
        n.mrTextured = n.mrTextured || m->metallicRoughnessImage >= 0 || m->occlusionImage >= 0;
        n.occludes = n.occludes || m->occlusionImage >= 0;
        n.emissiveTextured = n.emissiveTextured || m->emissiveImage >= 0;
        n.normalTextured = n.normalTextured || m->normalImage >= 0;
        n.emits = n.emits || m->emissive != glm::vec3(0.0f);
        n.emissiveScale = std::max({n.emissiveScale, m->emissive.r, m->emissive.g, m->emissive.b});
    }
    n.varyingMR = n.varyingMR || n.mrTextured;
    n.emits = n.emits || n.emissiveTextured;
    return n;
}

// Metallic, roughness and emission are factors per material more often
// than textures: such an image (images[k], k >= 1: the metallic-roughness
// one where need.varyingMR, then the emissive one) holds one value a
// material, and every texel takes the nearest of those (the gutters'
// blends, and the fill past them, which no draw reads), so it codes as an
// indexed PNG of few colours (the 59-material CesiumMan: 215 + 62 KB as RGB
// PNG, 75 + 15 KB so).  Read from textures, it does so where they are flat.
void snapFactorImages(const MaterialNeeds& need, std::vector<ColorImage>* images)
{
    const auto code = [](double linear, bool srgb) {
        return uint32_t(std::lround(255.0 * (srgb ? io::linearToSrgb(linear) : std::clamp(linear, 0.0, 1.0))));
    };
    const auto rgbaCode = [](uint32_t r, uint32_t g, uint32_t b) {
        const uint8_t c[4] = {uint8_t(r), uint8_t(g), uint8_t(b), 255};
        uint32_t v;
        std::memcpy(&v, c, 4);
        return v;
    };
    std::vector<uint32_t> mrValues, emissiveValues, palette;
    for (const io::MaterialInfo* m : need.used) {
        mrValues.push_back(rgbaCode(255, code(m->roughness, false), code(m->metallic, false)));
        const glm::vec3 e = m->emissive / need.emissiveScale;
        emissiveValues.push_back(rgbaCode(code(e.r, true), code(e.g, true), code(e.b, true)));
    }
    for (size_t k = 1; k < images->size(); ++k) {
        std::vector<uint8_t>& rgba = (*images)[k].rgba;
        const bool isMR = k == 1 && need.varyingMR;
        if (isMR ? need.mrTextured : need.emissiveTextured) {
            if (flatColours(rgba, &palette))
                snapToPalette(&rgba, palette);
            continue;
        }
        std::vector<uint32_t> values = isMR ? mrValues : emissiveValues;
        std::sort(values.begin(), values.end());
        values.erase(std::unique(values.begin(), values.end()), values.end());
        snapToPalette(&rgba, values);
    }
}

// The tangents of the capture's normal textures per file vertex, as glTF
// draws a mesh without TANGENT: along +u and -v of each face's normal-
// texture UVs, the faces' directions summed by area (MikkTSpace's
// construction without its splits).
struct Tangents {
    std::vector<glm::dvec3> tangent, bitangent;
};

Tangents normalTextureTangents(const CaptureAppearance& capture, size_t fileVertices)
{
    const io::SceneMaterials& sm = capture.materials;
    const std::vector<uint32_t>& tri = capture.triangles;
    Tangents s;
    s.tangent.assign(fileVertices, glm::dvec3(0.0));
    s.bitangent.assign(fileVertices, glm::dvec3(0.0));
    for (size_t f = 0; f < tri.size() / 3; ++f) {
        const int mi = capture.faceMaterial[f];
        if (mi < 0 || size_t(mi) >= sm.materials.size() || sm.materials[size_t(mi)].normalImage < 0)
            continue;
        const std::vector<glm::vec2>& uvs = sm.materials[size_t(mi)].normalChannel == 1 ? sm.fileUVs2 : sm.fileUVs;
        if (uvs.size() != fileVertices)
            continue;
        uint32_t file[3];
        for (int k = 0; k < 3; ++k)
            file[k] = capture.fileCorners[3 * f + size_t(k)];
        const glm::dvec3 a(capture.positions[tri[3 * f]]);
        const glm::dvec3 e1 = glm::dvec3(capture.positions[tri[3 * f + 1]]) - a;
        const glm::dvec3 e2 = glm::dvec3(capture.positions[tri[3 * f + 2]]) - a;
        const glm::dvec2 d1 = glm::dvec2(uvs[file[1]]) - glm::dvec2(uvs[file[0]]);
        const glm::dvec2 d2 = glm::dvec2(uvs[file[2]]) - glm::dvec2(uvs[file[0]]);
        const double area = glm::length(glm::cross(e1, e2));
        glm::dvec3 dPdu, dPdv;
        if (!(area > 0.0) || !uvDerivatives(e1, e2, d1, d2, &dPdu, &dPdv))
            continue;
        const double lu = glm::length(dPdu), lv = glm::length(dPdv);
        if (!(lu > 0.0) || !(lv > 0.0) || !std::isfinite(lu + lv))
            continue;
        for (uint32_t fv : file) {
            s.tangent[fv] += area * dPdu / lu;
            s.bitangent[fv] -= area * dPdv / lv;
        }
    }
    return s;
}

}  // namespace

Status carryAppearance(const CaptureAppearance& capture, const ControlMesh& control, const DisplacementMap& map,
                       Scheme scheme, int level, const TriangleIndex& highIndex, double maxMemoryMB, int threads,
                       io::BaseColourTexture* out, std::string* note)
{
    const io::SceneMaterials& sm = capture.materials;
    const std::vector<int>& faceMaterial = capture.faceMaterial;
    // Each texture as large as the capture's images it is re-baked from (a
    // power of two, 256 to 2048): the colour, metallic-roughness, emissive
    // and occlusion ones as their largest, the normal texture as the largest
    // normal image (a 256^2 normal texture beside a 1024^2 colour image was
    // re-baked at 1024^2: a 874.6 KB rig where 256^2 gives 376.8 KB, within
    // 0.2 dB).
    int largest = 0, largestNormal = 0;
    const auto grow = [&](int* into, int image) {
        if (image >= 0 && size_t(image) < sm.images.size())
            *into = std::max({*into, sm.images[size_t(image)].width, sm.images[size_t(image)].height});
    };
    for (const io::MaterialInfo& m : sm.materials) {
        for (int image : {m.image, m.metallicRoughnessImage, m.emissiveImage, m.occlusionImage})
            grow(&largest, image);
        grow(&largestNormal, m.normalImage);
    }
    // Vertex colours vary from vertex to vertex: a texel per capture vertex
    // or so (1.5 for the atlas's gutters and packing).
    const bool vertexColours = !sm.fileColours.empty() || !capture.vertexColours.empty();
    if (vertexColours)
        largest = std::max(largest, int(std::ceil(std::sqrt(1.5 * double(capture.positions.size())))));
    const auto sideFor = [](int texels) {
        int side = 256;
        while (side < texels && side < 2048)
            side *= 2;
        return side;
    };
    const int side = sideFor(largest), normalSide = sideFor(largestNormal);
    const bool corners = capture.fileCorners.size() == capture.triangles.size();
    // An image of flat colours (laid out by hand, as a low-poly
    // character's are) is read at its nearest texel: its colours stay
    // exact and few, where bilinear reads would blend new ones along every
    // edge.  Where every base colour image is, the re-baked texture's rare
    // colours (its sources' antialiased edges, its gutters' blends) then take
    // the nearest of its 256 most common, and it is coded as an indexed PNG.
    // Fox's rig: 205 -> 140 KB (its 576-face cage), 191 -> 124 KB (200
    // faces), rendered within 1.1 dB PSNR of the bilinear re-bake.
    std::vector<uint8_t> flat(sm.images.size(), 0);
    std::vector<uint32_t> palette;
    for (size_t i = 0; i < sm.images.size(); ++i)
        flat[i] = flatColours(sm.images[i].rgba, &palette) ? 1 : 0;
    bool allFlat = true;
    for (const io::MaterialInfo& m : sm.materials)
        allFlat = allFlat && (m.image < 0 || size_t(m.image) >= flat.size() || flat[size_t(m.image)]);
    // The metallic-roughness, occlusion and emissive the capture's materials
    // draw with (glTF's: factors times textures) become textures of their
    // own where they vary: materials of different factors, or any such
    // texture (occlusion in the metallic-roughness texture's R, as glTF's
    // ORM packing has it).
    const MaterialNeeds need = needsOf(sm, faceMaterial);
    // A capture point's material, texture UVs (its two channels) and vertex colour.
    struct Point {
        const io::MaterialInfo* material;
        glm::dvec2 uv[2];
        glm::dvec4 vertexColour;
    };
    const auto pointOf = [&](uint32_t face, double b1, double b2) {
        Point p{&sm.materials[size_t(faceMaterial[face])], {glm::dvec2(0.0), glm::dvec2(0.0)},
                glm::dvec4(sm.fileColours.empty() ? 1.0 : 0.0)};
        const double w[3] = {1.0 - b1 - b2, b1, b2};
        for (int k = 0; k < 3 && corners; ++k) {
            const uint32_t file = capture.fileCorners[3 * size_t(face) + size_t(k)];
            p.uv[0] += w[k] * glm::dvec2(sm.fileUVs[file]);
            if (!sm.fileUVs2.empty())
                p.uv[1] += w[k] * glm::dvec2(sm.fileUVs2[file]);
            if (!sm.fileColours.empty())
                p.vertexColour += w[k] * glm::dvec4(sm.fileColours[file]);
        }
        if (!corners)
            p.vertexColour = glm::dvec4(1.0);
        return p;
    };
    const auto imageOf = [&](int index) {
        return index >= 0 && size_t(index) < sm.images.size() ? &sm.images[size_t(index)] : nullptr;
    };
    const auto nearest = [&](int index) { return index >= 0 && size_t(index) < flat.size() && flat[size_t(index)]; };
    // Linear, as glTF defines the base colour: factor x texture x COLOR_0;
    // a PLY's or OBJ's vertex colours alone.
    const CaptureColour colour = [&](uint32_t face, double b1, double b2) {
        if (sm.materials.empty()) {
            glm::vec4 c(0.0f);
            const float w[3] = {float(1.0 - b1 - b2), float(b1), float(b2)};
            for (int k = 0; k < 3; ++k)
                c += w[k] * capture.vertexColours[capture.triangles[3 * size_t(face) + size_t(k)]];
            return c;
        }
        const Point p = pointOf(face, b1, b2);
        const io::MaterialInfo& m = *p.material;
        if (!corners)
            return glm::vec4(m.baseColor);
        return glm::vec4(io::baseColourAt(m, imageOf(m.image), p.uv[0], p.vertexColour, nearest(m.image)));
    };
    std::vector<ColourLayer> textures{{colour, true}};
    if (need.varyingMR)  // R occlusion, G roughness, B metallic, as glTF reads them
        textures.push_back({[&](uint32_t face, double b1, double b2) {
                              const Point p = pointOf(face, b1, b2);
                              const io::MaterialInfo& m = *p.material;
                              const int image = corners ? m.metallicRoughnessImage : -1;
                              const int ao = corners ? m.occlusionImage : -1;
                              const glm::dvec2 mr = io::metallicRoughnessAt(
                                  m, imageOf(image), p.uv[m.metallicRoughnessChannel], nearest(image));
                              const double occlusion =
                                  io::occlusionAt(m, imageOf(ao), p.uv[m.occlusionChannel], nearest(ao));
                              return glm::vec4(float(occlusion), float(mr.y), float(mr.x), 1.0f);
                          },
                          false});
    if (need.emits)
        textures.push_back({[&](uint32_t face, double b1, double b2) {
                              const Point p = pointOf(face, b1, b2);
                              const int image = corners ? p.material->emissiveImage : -1;
                              const glm::dvec2 uv = p.uv[p.material->emissiveChannel];
                              return glm::vec4(glm::vec3(io::emissiveAt(*p.material, imageOf(image), uv,
                                                                        nearest(image))) /
                                                   need.emissiveScale,
                                               1.0f);
                          },
                          true});
    // Per texel: its face and barycentrics (16 bytes), four float channels
    // and four bytes a texture; the normal texture as one more (and its
    // refined surface, under a texel's worth).
    const bool normals = need.normalTextured && corners;
    const double needMB = (double(side) * double(side) * (16.0 + 20.0 * double(textures.size())) +
                           (normals ? double(normalSide) * double(normalSide) * 68.0 : 0.0)) /
                          (1024.0 * 1024.0);
    if (needMB > maxMemoryMB)
        return Status(StatusCode::InvalidArgument,
                      "re-baking its materials into " + std::to_string(textures.size()) + " " + std::to_string(side) +
                          "^2 textures needs about " + std::to_string(long(needMB)) + " MB, over the " +
                          std::to_string(long(maxMemoryMB)) + " MB budget (raise it with --max-memory MB)");
    std::vector<ColorImage> images;
    Status st = transferColours(control, map, highIndex, textures, side, &images, threads);
    if (!st)
        return st;
    if (normals) {
        // The capture's shading normals as glTF draws them (its NORMALs
        // blended; a face of a part without, its own), its normal textures
        // applied in its TANGENTs' frame, or its UVs' without.
        const Tangents frames = normalTextureTangents(capture, sm.fileUVs.size());
        const CaptureNormal normal = [&](uint32_t face, double b1, double b2) {
            const double w[3] = {1.0 - b1 - b2, b1, b2};
            glm::dvec3 n(0.0), t(0.0), b(0.0);
            bool faceted = capture.drawnFlat || sm.fileNormals.size() != sm.fileUVs.size();
            for (int k = 0; k < 3; ++k) {
                const uint32_t file = capture.fileCorners[3 * size_t(face) + size_t(k)];
                if (!faceted) {
                    faceted = sm.fileNormals[file] == glm::vec3(0.0f);
                    n += w[k] * glm::dvec3(sm.fileNormals[file]);
                }
                t += w[k] * frames.tangent[file];
                b += w[k] * frames.bitangent[file];
            }
            if (faceted) {
                const uint32_t* v = &capture.triangles[3 * size_t(face)];
                const glm::dvec3 a(capture.positions[v[0]]);
                n = glm::cross(glm::dvec3(capture.positions[v[1]]) - a, glm::dvec3(capture.positions[v[2]]) - a);
            }
            const double nl = glm::length(n);
            if (!(nl > 0.0) || !std::isfinite(nl))
                return glm::vec3(0.0f);  // no direction (transferNormals fills it)
            n /= nl;
            const Point p = pointOf(face, b1, b2);
            const io::MaterialInfo& m = *p.material;
            if (m.normalImage < 0)
                return glm::vec3(n);
            // The file's TANGENTs where each corner has one (its bitangent's
            // sign the blend's); else the directions of its UVs.
            if (sm.fileTangents.size() == sm.fileUVs.size()) {
                glm::dvec4 given(0.0);
                bool all = true;
                for (int k = 0; k < 3; ++k) {
                    const glm::vec4& g = sm.fileTangents[capture.fileCorners[3 * size_t(face) + size_t(k)]];
                    all = all && g.w != 0.0f;
                    given += w[k] * glm::dvec4(g);
                }
                if (all) {
                    t = glm::dvec3(given);
                    b = glm::cross(n, t) * (given.w < 0.0 ? -1.0 : 1.0);
                }
            }
            t -= n * glm::dot(n, t);
            const double tl = glm::length(t);
            if (!(tl > 0.0) || !std::isfinite(tl))
                return glm::vec3(n);
            t /= tl;
            glm::dvec3 bitangent = glm::cross(n, t);
            if (glm::dot(bitangent, b) < 0.0)
                bitangent = -bitangent;
            const glm::dvec3 local = io::normalAt(m, imageOf(m.normalImage), p.uv[m.normalChannel]);
            return glm::vec3(glm::normalize(local.x * t + local.y * bitangent + local.z * n));
        };
        ColorImage normalImage;
        st = transferNormals(control, map, scheme, level, capture.drawnFlat, highIndex, normal, normalSide,
                             &normalImage, threads);
        if (!st)
            return st;
        out->normalRGBA = std::move(normalImage.rgba);
        out->normalWidth = normalImage.width;
        out->normalHeight = normalImage.height;
    }
    snapFactorImages(need, &images);
    ColorImage& image = images[0];
    size_t next = 1;
    if (need.varyingMR)
        out->metallicRoughness = std::move(images[next++].rgba);
    out->occlusion = need.occludes;
    if (need.emits) {
        out->emissiveRGBA = std::move(images[next++].rgba);
        out->emissive[0] = out->emissive[1] = out->emissive[2] = 1.0f;
        out->emissiveStrength = need.emissiveScale;
    }
    if (allFlat && flatColours(image.rgba, &palette))
        snapToPalette(&image.rgba, palette);
    out->name = "base_colour";
    out->width = image.width;
    out->height = image.height;
    out->rgba = std::move(image.rgba);
    // The other factors of the material most of the capture wears (glTF's
    // default material's for a capture with none).
    const io::MaterialInfo fallback;
    const io::MaterialInfo& main =
        capture.mainMaterial < sm.materials.size() ? sm.materials[capture.mainMaterial] : fallback;
    out->doubleSided = main.doubleSided;
    out->metallic = need.varyingMR ? 1.0f : main.metallic;  // the texture holds them
    out->roughness = need.varyingMR ? 1.0f : main.roughness;
    out->alphaMode = main.alphaMode == io::AlphaMode::Mask    ? "MASK"
                     : main.alphaMode == io::AlphaMode::Blend ? "BLEND"
                                                              : "OPAQUE";
    out->alphaCutoff = main.alphaCutoff;
    // " with a normal one", its size where it is not the others'.
    std::string normalOne;
    if (normals) {
        char size[32] = "";
        if (normalSide != side)
            std::snprintf(size, sizeof(size), "%dx%d ", normalSide, normalSide);
        normalOne = std::string(need.varyingMR || need.emits ? " and a " : " with a ") + size + "normal one";
    }
    char text[240];
    if (sm.materials.empty())
        std::snprintf(text, sizeof(text),
                      "its vertex colours carried as one %dx%d base colour texture in the cage's UVs", side, side);
    else
        std::snprintf(text, sizeof(text),
                      "%zu material%s%s carried as one %dx%d base colour texture%s%s in the cage's UVs",
                      sm.materials.size() - 1, sm.materials.size() == 2 ? "" : "s",
                      vertexColours ? " and vertex colours" : "", side, side,
                      need.varyingMR && need.emits ? " with metallic-roughness and emissive ones"
                      : need.varyingMR             ? " with a metallic-roughness one"
                      : need.emits                 ? " with an emissive one"
                                                   : "",
                      normalOne.c_str());
    *note = text;
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
