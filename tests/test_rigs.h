// Rigs several tests share: the built-in example, the baked penguin, and
// the watertightness check of an animated reconstruction.
#pragma once

#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/baker/bake.h"
#include "strata/baker/mesh_input.h"
#include "strata/io/exr.h"
#include "strata/io/png.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "strata/surface.h"
#include "test_grid.h"
#include "test_util.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <tiny_gltf.h>

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace strata {
namespace test {

/// `bytes` of `data` as a new bufferView of buffer 0 (created if missing),
/// 4-byte aligned; its index.
inline int addBufferView(tinygltf::Model& m, const void* data, size_t bytes, int target)
{
    if (m.buffers.empty())
        m.buffers.emplace_back();
    std::vector<unsigned char>& buf = m.buffers[0].data;
    while (buf.size() % 4)
        buf.push_back(0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = buf.size();
    view.byteLength = bytes;
    view.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    buf.insert(buf.end(), p, p + bytes);
    m.bufferViews.push_back(view);
    return int(m.bufferViews.size() - 1);
}

/// `count` elements of `data` (`bytes` of them) as an accessor over a new
/// bufferView (addBufferView); its index.
inline int addAccessor(tinygltf::Model& m, const void* data, size_t bytes, int componentType, int type, size_t count,
                       int target)
{
    tinygltf::Accessor acc;
    acc.bufferView = addBufferView(m, data, bytes, target);
    acc.componentType = componentType;
    acc.type = type;
    acc.count = count;
    m.accessors.push_back(acc);
    return int(m.accessors.size() - 1);
}

/// The colour of writeColouredSphere's COLOR_0 at a point: linear, a
/// linear function of the direction.
inline glm::vec4 colouredSphereColour(const glm::vec3& p)
{
    const glm::vec3 n = glm::normalize(p);
    return glm::vec4(0.5f + 0.4f * n.x, 0.5f + 0.4f * n.y, 0.5f + 0.4f * n.z, 1.0f);
}

/// How writeColouredSphere colours its sphere.
enum class SphereColour {
    VertexAndFactor,   ///< COLOR_0 (colouredSphereColour, float RGBA) under a factor (0.5, 1, 1, 1)
    HalfFactor,        ///< a base colour factor of linear 0.5 grey alone
    HalfVertexColour,  ///< COLOR_0 of linear 0.5 grey (normalized bytes 128, RGB), a factor of 1
    HalfTexture,       ///< a 2x2 texture of sRGB code 188 (linear 0.5029), a factor of 1
    /// Two materials, each on the faces whose centre lies above (y > 0) or
    /// below: kTopMaterial and kBottomMaterial's metallic, roughness and
    /// emissive factors, a white base colour; the bottom's emission made
    /// kBottomEmissiveStrength times stronger (KHR_materials_emissive_strength).
    TwoMaterials,
    /// HalfTexture's base colour, with occlusion (strength 1) and emission
    /// (a factor of kSecondSetEmissive, red) read from one texture on
    /// TEXCOORD_1, as exporters write baked occlusion: a grey ramp whose
    /// code at u is 255 u, through u = secondSetU(point), v = 0.5.
    SecondUVSet,
    /// HalfTexture's base colour through a stereographic projection
    /// (normalTextureUV), and a normal texture of one tangent-space normal
    /// (kNormalCode, scale kNormalScale) through the same UVs; smooth
    /// (radial) NORMALs.
    NormalTexture,
    /// NormalTexture with NORMALs bent off the radius (normalTextureNormal):
    /// an exporter's custom normals, which glTF draws as they are.
    NormalTextureBent,
    /// NormalTexture with TANGENTs a quarter turn from its UVs' +u
    /// (normalTextureTangent): glTF reads the normal texture in their frame.
    NormalTextureTangents,
};

/// NormalTextureTangents' TANGENT at a point: along its UVs' -v (the
/// gradient of -v across the radius), w 1.
inline glm::vec4 normalTextureTangent(const glm::vec3& p)
{
    const glm::vec3 radial = glm::normalize(p);
    const float w = 1.0f + std::max(radial.z, -0.9f);
    glm::vec3 g(0.0f, 1.0f / w, -radial.y / (w * w));
    g -= radial * glm::dot(radial, g);
    return glm::vec4(glm::normalize(g), 1.0f);
}

/// NormalTexture's and NormalTextureBent's NORMAL at a point.
inline glm::vec3 normalTextureNormal(const glm::vec3& p, SphereColour how)
{
    const glm::vec3 radial = glm::normalize(p);
    return how == SphereColour::NormalTextureBent ? glm::normalize(radial + glm::vec3(0.4f, 0.0f, 0.0f)) : radial;
}

/// NormalTexture's texel (RGB codes) and normalTexture.scale.
constexpr uint8_t kNormalCode[3] = {173, 93, 242};
constexpr float kNormalScale = 0.8f;

/// NormalTexture's TEXCOORD_0 at a point: a stereographic projection from
/// the pole at -z (conformal: every tangent frame glTF viewers derive
/// agrees), v running down; held at z = -0.9 past there.
inline glm::vec2 normalTextureUV(const glm::vec3& p)
{
    const float k = 0.4f / (1.0f + std::max(p.z, -0.9f));
    return glm::vec2(0.5f + k * p.x, 0.5f - k * p.y);
}

/// SecondUVSet's emissive factor: red alone, under the lit grey's white.
constexpr float kSecondSetEmissive = 0.4f;

/// SecondUVSet's TEXCOORD_1 u at a point: a linear function of the direction.
inline float secondSetU(const glm::vec3& p)
{
    return 0.5f + 0.4f * glm::normalize(p).x;
}

/// TwoMaterials' factors: metallic, roughness, emissive red, green, blue.
constexpr float kTopMaterial[5] = {0.0f, 0.2f, 0.0f, 0.0f, 0.0f};
constexpr float kBottomMaterial[5] = {1.0f, 0.9f, 1.0f, 0.5f, 0.0f};
constexpr float kBottomEmissiveStrength = 3.0f;

/// A unit sphere (icosphere 4) as a glb coloured as `how` says.
inline bool writeColouredSphere(const std::string& path, SphereColour how = SphereColour::VertexAndFactor)
{
    const ControlMesh sphere = examples::makeIcosphere(4);
    tinygltf::Model model;
    model.asset.version = "2.0";
    constexpr int kVertices = TINYGLTF_TARGET_ARRAY_BUFFER;
    tinygltf::Primitive prim;
    prim.attributes["POSITION"] = addAccessor(model, sphere.positions.data(), sphere.positions.size() * 12,
                                              TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                                              sphere.positions.size(), kVertices);
    std::vector<double>& lo = model.accessors.back().minValues;
    std::vector<double>& hi = model.accessors.back().maxValues;
    lo.assign(3, 1e30);
    hi.assign(3, -1e30);
    for (const glm::vec3& p : sphere.positions)
        for (size_t c = 0; c < 3; ++c) {
            lo[c] = std::min(lo[c], double(p[int(c)]));
            hi[c] = std::max(hi[c], double(p[int(c)]));
        }
    tinygltf::Material material;
    const size_t n = sphere.positions.size();
    if (how == SphereColour::VertexAndFactor) {
        std::vector<glm::vec4> colours;
        for (const glm::vec3& p : sphere.positions)
            colours.push_back(colouredSphereColour(p));
        prim.attributes["COLOR_0"] = addAccessor(model, colours.data(), n * 16, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                 TINYGLTF_TYPE_VEC4, n, kVertices);
        material.pbrMetallicRoughness.baseColorFactor = {0.5, 1.0, 1.0, 1.0};
    } else if (how == SphereColour::HalfFactor) {
        material.pbrMetallicRoughness.baseColorFactor = {0.5, 0.5, 0.5, 1.0};
    } else if (how == SphereColour::HalfVertexColour) {
        const std::vector<uint8_t> grey(4 * n, 128);  // 128 / 255 = 0.502 linear; RGB padded to 4 bytes
        prim.attributes["COLOR_0"] = addAccessor(model, grey.data(), grey.size(), TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                                 TINYGLTF_TYPE_VEC3, n, kVertices);
        model.bufferViews.back().byteStride = 4;
        model.accessors.back().normalized = true;
    } else if (how == SphereColour::TwoMaterials) {
        tinygltf::Material bottom;
        for (const float* f : {kTopMaterial, kBottomMaterial}) {
            tinygltf::Material& m = f == kTopMaterial ? material : bottom;
            m.pbrMetallicRoughness.metallicFactor = f[0];
            m.pbrMetallicRoughness.roughnessFactor = f[1];
            m.emissiveFactor = {f[2], f[3], f[4]};
        }
        tinygltf::Value::Object strength;
        strength["emissiveStrength"] = tinygltf::Value(double(kBottomEmissiveStrength));
        bottom.extensions["KHR_materials_emissive_strength"] = tinygltf::Value(strength);
        model.extensionsUsed.push_back("KHR_materials_emissive_strength");
        model.materials.push_back(bottom);  // material 1; material 0 below
    } else {
        std::vector<glm::vec2> uvs(n, glm::vec2(0.5f));
        const bool normalTexture = how == SphereColour::NormalTexture || how == SphereColour::NormalTextureBent ||
                                   how == SphereColour::NormalTextureTangents;
        if (normalTexture) {
            std::vector<glm::vec3> normals;
            std::vector<glm::vec4> tangents;
            for (size_t v = 0; v < n; ++v) {
                uvs[v] = normalTextureUV(sphere.positions[v]);
                normals.push_back(normalTextureNormal(sphere.positions[v], how));
                tangents.push_back(normalTextureTangent(sphere.positions[v]));
            }
            prim.attributes["NORMAL"] = addAccessor(model, normals.data(), n * 12, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                    TINYGLTF_TYPE_VEC3, n, kVertices);
            if (how == SphereColour::NormalTextureTangents)
                prim.attributes["TANGENT"] = addAccessor(model, tangents.data(), n * 16,
                                                         TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, n,
                                                         kVertices);
        }
        prim.attributes["TEXCOORD_0"] = addAccessor(model, uvs.data(), n * 8, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                    TINYGLTF_TYPE_VEC2, n, kVertices);
        // A PNG of `rgba` as the next image and texture.
        const auto addTexture = [&](int width, int height, const std::vector<uint8_t>& rgba) {
            std::string png;
            if (!io::encodePngRgba(width, height, rgba, &png))
                return false;
            tinygltf::Image image;
            image.bufferView = addBufferView(model, png.data(), png.size(), 0);
            image.mimeType = "image/png";
            model.images.push_back(image);
            model.textures.emplace_back().source = int(model.images.size()) - 1;
            return true;
        };
        std::vector<uint8_t> grey;  // 2x2 of sRGB code 188, opaque
        for (int texel = 0; texel < 4; ++texel)
            grey.insert(grey.end(), {188, 188, 188, 255});
        if (!addTexture(2, 2, grey))
            return false;
        material.pbrMetallicRoughness.baseColorTexture.index = 0;
        if (how == SphereColour::SecondUVSet) {
            std::vector<glm::vec2> second;
            for (const glm::vec3& p : sphere.positions)
                second.emplace_back(secondSetU(p), 0.5f);
            prim.attributes["TEXCOORD_1"] = addAccessor(model, second.data(), n * 8, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                        TINYGLTF_TYPE_VEC2, n, kVertices);
            constexpr int kRamp = 64;
            std::vector<uint8_t> ramp;
            for (int y = 0; y < 2; ++y)
                for (int x = 0; x < kRamp; ++x)
                    for (int k = 0; k < 4; ++k)
                        ramp.push_back(k == 3 ? 255 : uint8_t(std::lround(255.0 * (x + 0.5) / kRamp)));
            if (!addTexture(kRamp, 2, ramp))
                return false;
            material.occlusionTexture.index = 1;
            material.occlusionTexture.texCoord = 1;
            material.emissiveTexture.index = 1;
            material.emissiveTexture.texCoord = 1;
            material.emissiveFactor = {double(kSecondSetEmissive), 0.0, 0.0};
        }
        if (normalTexture) {
            std::vector<uint8_t> normal;
            for (int texel = 0; texel < 4; ++texel)
                normal.insert(normal.end(), {kNormalCode[0], kNormalCode[1], kNormalCode[2], 255});
            if (!addTexture(2, 2, normal))
                return false;
            material.normalTexture.index = 1;
            material.normalTexture.scale = double(kNormalScale);
        }
    }
    std::vector<uint32_t> halves[2];  // faces above y = 0, then below
    for (size_t f = 0; f < sphere.faceCount(); ++f) {
        const uint32_t* t = &sphere.triangles[3 * f];
        const float y = sphere.positions[t[0]].y + sphere.positions[t[1]].y + sphere.positions[t[2]].y;
        std::vector<uint32_t>& half = halves[how == SphereColour::TwoMaterials && y < 0.0f ? 1 : 0];
        half.insert(half.end(), t, t + 3);
    }
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    model.materials.insert(model.materials.begin(), material);
    tinygltf::Mesh& mesh = model.meshes.emplace_back();
    for (int h = 0; h < 2; ++h) {
        if (halves[h].empty())
            continue;
        prim.indices = addAccessor(model, halves[h].data(), halves[h].size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                   TINYGLTF_TYPE_SCALAR, halves[h].size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        prim.material = h;
        mesh.primitives.push_back(prim);
    }
    model.nodes.emplace_back().mesh = 0;
    model.scenes.emplace_back().nodes.push_back(0);
    model.defaultScene = 0;
    tinygltf::TinyGLTF gltf;
    return gltf.WriteGltfSceneToFile(&model, path, true, true, false, true);
}

/// The built-in example's rig: icosphere(1) with a per-triangle atlas and
/// the closed-form head map at mapSize^2.
inline void makeExampleRig(Rig* rig, DisplacementMap* map, int mapSize = 256)
{
    rig->mesh = examples::makeIcosphere(1);
    ASSERT_TRUE(baker::buildTriangleAtlas(&rig->mesh, {mapSize, 2}).isOk());
    ASSERT_TRUE(examples::bakeRadialSurface(map, rig->mesh, mapSize, 2, examples::headRadius).isOk());
    rig->hasDisplacement = true;
    rig->displacement.encoding = "exr";
    rig->displacement.width = rig->displacement.height = mapSize;
    rig->displacement.recommendedLevel = 4;
}

/// Writes the example rig as dir/stem.glb beside dir/stem.exr; returns the glb path.
inline std::string writeExampleRig(const std::string& dir, const std::string& stem, Rig* rigOut = nullptr)
{
    Rig rig;
    DisplacementMap map;
    makeExampleRig(&rig, &map);
    rig.displacement.uri = stem + ".exr";
    EXPECT_TRUE(io::writeDisplacementExr(dir + "/" + stem + ".exr", map).isOk());
    EXPECT_TRUE(io::saveRig(dir + "/" + stem + ".glb", rig).isOk());
    if (rigOut)
        *rigOut = rig;
    return dir + "/" + stem + ".glb";
}

/// The penguin pair baked at 512^2 (per-triangle atlas, linear scheme).
/// \pre ../shared/data holds penguin_hr.obj and penguin_control_mesh.obj
inline void bakePenguin(const std::string& highPath, const std::string& controlPath, Rig* rig, DisplacementMap* map)
{
    baker::TriangleMesh high;
    ASSERT_TRUE(baker::loadHighMesh(highPath, &high, nullptr).isOk());
    ASSERT_TRUE(baker::loadControlMesh(controlPath, &rig->mesh).isOk());
    ASSERT_TRUE(baker::buildTriangleAtlas(&rig->mesh, {512, 2}).isOk());
    baker::BakeOptions options;
    options.size = 512;
    ASSERT_TRUE(baker::bake(map, nullptr, nullptr, rig->mesh, high, options).isOk());
}

/// Writes rec as glb, loads it back welded by position, and checks it is as
/// closed as the control mesh: same Euler characteristic, no boundary, no
/// vertex merged or split.
inline void expectWatertightRoundTrip(const io::Reconstruction& rec, const MeshTopologyStats& control,
                                      const std::string& path, const std::string& label)
{
    ASSERT_TRUE(io::writeReconstruction(path, rec).isOk());
    Rig back;
    ASSERT_TRUE(io::loadRig(path, &back).isOk());
    const MeshTopologyStats st = computeTopologyStats(back.mesh.triangles.data(), back.mesh.faceCount());
    EXPECT_EQ(back.mesh.positions.size(), rec.positions.size()) << label;
    EXPECT_EQ(st.eulerCharacteristic, control.eulerCharacteristic) << label;
    EXPECT_EQ(st.boundaryEdges, 0u) << label;
}

/// A two-joint glTF-style skin on `mesh`: `root` at rootPosition, `child`
/// at rootPosition + childOffset, inverse bind matrices from those places,
/// and per vertex the weight childWeight(position) on the child (4 influences).
inline void twoJointSkin(Skeleton* s, const ControlMesh& mesh, const char* root, const char* child,
                         glm::vec3 rootPosition, glm::vec3 childOffset,
                         const std::function<float(const glm::vec3&)>& childWeight)
{
    s->nodes.resize(2);
    s->nodes[0].name = root;
    s->nodes[0].rest.translation = rootPosition;
    s->nodes[1].name = child;
    s->nodes[1].parent = 0;
    s->nodes[1].rest.translation = childOffset;
    s->skin.joints = {0, 1};
    s->skin.inverseBindMatrices = {glm::translate(glm::mat4(1.0f), -rootPosition),
                                   glm::translate(glm::mat4(1.0f), -(rootPosition + childOffset))};
    s->weights.influences = 4;
    s->weights.joints.clear();
    s->weights.weights.clear();
    for (const glm::vec3& p : mesh.positions) {
        const float w = childWeight(p);
        s->weights.joints.insert(s->weights.joints.end(), {0, 1, 0, 0});
        s->weights.weights.insert(s->weights.weights.end(), {1.0f - w, w, 0.0f, 0.0f});
    }
}

/// A LINEAR rotation channel on `node` through the given keys.
inline AnimationChannel rotationKeys(int node, const std::vector<float>& times, const std::vector<glm::quat>& keys)
{
    AnimationChannel c;
    c.node = node;
    c.path = AnimationPath::Rotation;
    c.times = times;
    for (const glm::quat& q : keys)
        c.values.insert(c.values.end(), {q.x, q.y, q.z, q.w});
    return c;
}

// An animation "grow" scaling nodes 0 and 1 (a joint and its child) by
// 1e20 at every key: posed, their transforms overflow a float.
inline Animation overflowingAnimation()
{
    Animation grow;
    grow.name = "grow";
    for (int node : {0, 1}) {
        AnimationChannel c;
        c.node = node;
        c.path = AnimationPath::Scale;
        c.times = {0.0f, 1.0f};
        c.values = {1e20f, 1e20f, 1e20f, 1e20f, 1e20f, 1e20f};
        grow.channels.push_back(c);
    }
    return grow;
}

/// The example rig skinned to two joints ("hips", "chest") with one
/// animation, "bend", that turns the chest 0.6 rad about z over 1 s, its
/// layer in `scheme`.
inline void makeBendingExampleRig(Rig* rig, DisplacementMap* map, Scheme scheme = Scheme::Linear)
{
    makeExampleRig(rig, map);
    rig->displacement.scheme = scheme;
    twoJointSkin(&rig->skeleton, rig->mesh, "hips", "chest", glm::vec3(0.0f), glm::vec3(0.0f, 0.5f, 0.0f),
                 [](const glm::vec3& p) { return glm::clamp(p.y + 0.5f, 0.0f, 1.0f); });
    Animation bend;
    bend.name = "bend";
    bend.channels.push_back(rotationKeys(
        1, {0.0f, 1.0f}, {glm::quat(1, 0, 0, 0), glm::angleAxis(0.6f, glm::vec3(0.0f, 0.0f, 1.0f))}));
    bend.end = 1.0f;
    rig->skeleton.animations.push_back(bend);
    ASSERT_TRUE(finalizeSkeleton(&rig->skeleton, rig->mesh.vertexCount()).isOk());
}

// The bending example rig's Surface (recommended level, in `scheme`) posed
// at `time` of its animation, or null when either step fails; the rig and
// map come back for other surfaces.
inline std::unique_ptr<Surface> bendingSurfaceAt(float time, Rig* rig, DisplacementMap* map,
                                                 Scheme scheme = Scheme::Linear)
{
    makeBendingExampleRig(rig, map, scheme);
    std::unique_ptr<Surface> s;
    if (!Surface::create(&s, *rig, map).isOk() || !s->setAnimationTime(0, time).isOk())
        s.reset();
    return s;
}


}  // namespace test
}  // namespace strata
