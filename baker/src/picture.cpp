// A character and its rig drawn on the CPU (picture.h).
#include "strata/baker/picture.h"

#include "strata/uv_raster.h"

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat4x4.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {
namespace baker {

PictureCamera frameBox(const glm::vec3& lo, const glm::vec3& hi, int size)
{
    PictureCamera c;
    c.size = size;
    c.target = 0.5f * (lo + hi);
    const float radius = std::max(0.5f * glm::length(hi - lo), 1e-6f);
    // Far enough that the box's sphere fills about 90% of the view.
    const float distance = radius / std::sin(0.45f * glm::radians(c.fovYDegrees));
    c.eye = c.target + distance * glm::normalize(glm::vec3(0.35f, 0.25f, 1.0f));
    return c;
}

void renderPicture(const PictureMesh& mesh, const PictureCamera& camera, std::vector<uint8_t>* rgb)
{
    const int n = std::max(camera.size, 1);
    rgb->assign(3 * size_t(n) * size_t(n), 0);
    std::vector<float> depth(size_t(n) * size_t(n), std::numeric_limits<float>::infinity());
    const float distance = std::max(glm::length(camera.eye - camera.target), 1e-6f);
    const glm::mat4 view = glm::lookAt(camera.eye, camera.target, camera.up);
    const glm::mat4 clip =
        glm::perspective(glm::radians(camera.fovYDegrees), 1.0f, 0.01f * distance, 100.0f * distance) * view;
    // One light from over the eye's shoulder, and an ambient term.
    const glm::vec3 light = glm::normalize(glm::normalize(camera.eye - camera.target) + glm::vec3(0.3f, 0.6f, 0.0f));
    const size_t vertices = mesh.positions.size();
    for (const PicturePart& part : mesh.parts) {
        for (size_t t = part.firstTriangle; t < part.firstTriangle + part.triangleCount; ++t) {
            if (3 * t + 2 >= mesh.triangles.size())
                break;
            uint32_t v[3];
            glm::vec4 c[3];
            glm::vec2 screen[3];
            bool visible = true;
            for (int k = 0; k < 3; ++k) {
                v[k] = mesh.triangles[3 * t + size_t(k)];
                if (v[k] >= vertices) {
                    visible = false;
                    break;
                }
                c[k] = clip * glm::vec4(mesh.positions[v[k]], 1.0f);
                visible = visible && c[k].w > 1e-6f;
                // Pixel (x, y) spans [x, x + 1] x [y, y + 1], row 0 at the top;
                // in units of the picture, as forEachTexelInUVTriangle takes them.
                screen[k] = visible ? glm::vec2(0.5f * (c[k].x / c[k].w + 1.0f), 0.5f * (1.0f - c[k].y / c[k].w))
                                    : glm::vec2(0.0f);
            }
            if (!visible)
                continue;
            const glm::vec3& p0 = mesh.positions[v[0]];
            const glm::vec3 faceNormal = glm::cross(mesh.positions[v[1]] - p0, mesh.positions[v[2]] - p0);
            // The normal texture's dP/du and dP/dv on this triangle, in the
            // texture's own UVs (after its transform), as a viewer's screen
            // derivatives give them.
            glm::dvec3 dPdu(0.0), dPdv(0.0);
            bool normalMapped = false;
            const io::TextureCoords* normalCoords =
                part.normalMaterial ? &part.normalMaterial->channel(part.normalMaterial->normalChannel) : nullptr;
            if (part.normalImage && part.normalUvs && normalCoords) {
                glm::dvec2 st[3];
                for (int k = 0; k < 3; ++k)
                    st[k] = glm::dvec2(
                        normalCoords->textureUV(glm::vec2(part.normalUvs[2 * v[k]], part.normalUvs[2 * v[k] + 1])));
                const glm::dvec3 q0(p0);
                normalMapped = uvDerivatives(glm::dvec3(mesh.positions[v[1]]) - q0, glm::dvec3(mesh.positions[v[2]]) - q0,
                                             st[1] - st[0], st[2] - st[0], &dPdu, &dPdv);
            }
            forEachTexelInUVTriangle(screen, n, n, [&](int x, int y, double b0, double b1, double b2) {
                // Depth is affine in the picture; attributes are affine over 1/w.
                const double bs[3] = {b0, b1, b2};
                double z = 0.0, inv = 0.0, wp[3];
                for (int k = 0; k < 3; ++k) {
                    z += bs[k] * double(c[k].z / c[k].w);
                    wp[k] = bs[k] / double(c[k].w);
                    inv += wp[k];
                }
                const size_t at = size_t(y) * size_t(n) + size_t(x);
                if (!(inv > 0.0) || !(z >= -1.0 && z <= 1.0) || !(float(z) < depth[at]))
                    return;
                for (double& w : wp)
                    w /= inv;
                glm::dvec3 position(0.0), normal(0.0);
                glm::dvec2 uv(0.0), normalUv(0.0);
                for (int k = 0; k < 3; ++k) {
                    position += wp[k] * glm::dvec3(mesh.positions[v[k]]);
                    if (!part.flat && v[k] < mesh.normals.size())
                        normal += wp[k] * glm::dvec3(mesh.normals[v[k]]);
                    if (part.uvs)
                        uv += wp[k] * glm::dvec2(part.uvs[2 * v[k]], part.uvs[2 * v[k] + 1]);
                    if (normalMapped)
                        normalUv += wp[k] * glm::dvec2(part.normalUvs[2 * v[k]], part.normalUvs[2 * v[k] + 1]);
                }
                if (part.flat || !(glm::length(normal) > 0.0))
                    normal = glm::dvec3(faceNormal);
                const double length = glm::length(normal);
                normal = length > 0.0 ? normal / length : glm::dvec3(0.0, 0.0, 1.0);
                glm::dvec3 decodeX, decodeY, encodeX, encodeY;
                if (normalMapped && normalTextureFrame(normal, dPdu, dPdv, &decodeX, &decodeY, &encodeX, &encodeY)) {
                    const glm::dvec3 local = io::normalAt(*part.normalMaterial, part.normalImage,
                                                      glm::dvec2(normalCoords->textureUV(glm::vec2(normalUv))));
                    const glm::dvec3 bent = local.x * decodeX + local.y * decodeY + local.z * normal;
                    if (glm::length(bent) > 0.0)
                        normal = glm::normalize(bent);
                }
                if (glm::dot(normal, glm::dvec3(camera.eye) - position) < 0.0)
                    normal = -normal;  // either side drawn, lit from the front
                // glTF's base colour (linear: factor x decoded texture x
                // COLOR_0), shown sRGB-coded, then lit.
                glm::dvec4 colour(part.colour);
                if (part.colours)
                    for (int ch = 0; ch < part.colourComponents; ++ch) {
                        double value = 0.0;
                        for (int k = 0; k < 3; ++k)
                            value += wp[k] * double(part.colours[size_t(part.colourComponents) * v[k] + size_t(ch)]);
                        colour[ch] *= value;
                    }
                if (part.image && part.uvs) {
                    const io::TextureCoords plain;  // glTF's default sampler
                    const io::TextureCoords& mat = part.material ? *part.material : plain;
                    colour *= io::sampleLinear(mat, *part.image,
                                               part.material ? glm::dvec2(mat.textureUV(glm::vec2(uv))) : uv);
                }
                const double lit = 0.3 + 0.7 * std::max(0.0, glm::dot(normal, glm::dvec3(light)));
                depth[at] = float(z);
                for (int k = 0; k < 3; ++k)
                    (*rgb)[3 * at + size_t(k)] =
                        uint8_t(std::clamp(std::lround(255.0 * io::linearToSrgb(colour[k]) * lit), 0L, 255L));
            });
        }
    }
}

double picturePsnr(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b)
{
    if (a.size() != b.size())
        return 0.0;
    double se = 0.0;
    size_t n = 0;
    for (size_t i = 0; i + 2 < a.size(); i += 3) {
        if (!(a[i] | a[i + 1] | a[i + 2] | b[i] | b[i + 1] | b[i + 2]))
            continue;
        for (size_t k = 0; k < 3; ++k) {
            const double d = double(a[i + k]) - double(b[i + k]);
            se += d * d;
        }
        n += 3;
    }
    if (n == 0)
        return 0.0;
    if (se == 0.0)
        return 99.0;
    return std::min(99.0, 10.0 * std::log10(255.0 * 255.0 / (se / double(n))));
}

PictureMesh pictureOf(const io::RenderMesh& layout, const std::vector<glm::vec3>& positions,
                      const std::vector<glm::vec3>& normals, const io::SceneMaterials& materials,
                      bool normalTextures)
{
    PictureMesh m;
    m.positions.resize(layout.vertexCount());
    layout.gather(positions.data(), m.positions.data());
    if (normals.size() == positions.size()) {
        m.normals.resize(layout.vertexCount());
        layout.gather(normals.data(), m.normals.data());
    }
    m.triangles = layout.indices;
    for (size_t p = 0; p < layout.parts.size(); ++p) {
        const io::RenderPart& rp = layout.parts[p];
        PicturePart part;
        part.firstTriangle = rp.firstIndex / 3;
        part.triangleCount = rp.indexCount / 3;
        part.flat = rp.flat;
        // The part's material (glTF's default one last), its textures and UV sets.
        const auto uvSet = [&](int texCoord) -> const float* {
            const std::string set = "TEXCOORD_" + std::to_string(texCoord);
            for (const io::RenderAttribute& a : layout.attributes)
                if (a.name == set && a.components == 2 && a.values.size() == 2 * layout.vertexCount())
                    return a.values.data();
            return nullptr;
        };
        const auto image = [&](int index) -> const io::ImageRGBA* {
            return index >= 0 && size_t(index) < materials.images.size() && !materials.images[size_t(index)].rgba.empty()
                       ? &materials.images[size_t(index)]
                       : nullptr;
        };
        const int material = p < materials.partMaterial.size() ? materials.partMaterial[p] : -1;
        if (material >= 0 && size_t(material) < materials.materials.size()) {
            const io::MaterialInfo& info = materials.materials[size_t(material)];
            part.colour = info.baseColor;
            if (image(info.image) && (part.uvs = uvSet(info.texCoord)) != nullptr) {
                part.image = image(info.image);
                part.material = &info;
            }
            if (normalTextures && image(info.normalImage) &&
                (part.normalUvs = uvSet(info.channel(info.normalChannel).texCoord)) != nullptr) {
                part.normalImage = image(info.normalImage);
                part.normalMaterial = &info;
            }
        }
        for (const io::RenderAttribute& a : layout.attributes)
            if (a.name == "COLOR_0" && (a.components == 3 || a.components == 4) &&
                a.values.size() == size_t(a.components) * layout.vertexCount()) {
                part.colours = a.values.data();
                part.colourComponents = a.components;
            }
        m.parts.push_back(part);
    }
    return m;
}

}  // namespace baker
}  // namespace strata
