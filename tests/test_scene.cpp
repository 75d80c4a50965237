// Real characters in, complete assets out (issue 10): a bake keeps what the
// source glTF had, and a multi-primitive, multi-material skinned character
// with a non-manifold fin and a rigid eye bakes onto itself and
// reconstructs watertight, posed, matching plain linear blend skinning.
#include "strata/animation.h"
#include "strata/frame.h"
#include "strata/io/exr.h"
#include "strata/io/reconstruct.h"
#include "strata/io/materials.h"
#include "strata/io/png.h"
#include "strata/io/mesh_io.h"
#include "strata/io/render_mesh.h"
#include "strata/io/rig_io.h"
#include "test_rigs.h"
#include "test_util.h"

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>
#include <avif/avif.h>
#include <webp/decode.h>
#include <webp/encode.h>

#include <set>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <map>
#include <tuple>

using namespace strata;
using strata::test::addAccessor;
using strata::test::addBufferView;
using nlohmann::json;

namespace {

struct Glb {
    json doc;
    std::string bin;
};

Glb readGlb(const std::string& path)
{
    std::string bytes;  // meshopt-coded views decoded, as any glTF client would
    if (!io::readPlainGlb(path, &bytes))
        return Glb();
    Glb g;
    if (bytes.size() < 20)
        return g;
    uint32_t jsonLength = 0;
    std::memcpy(&jsonLength, bytes.data() + 12, 4);
    g.doc = json::parse(bytes.substr(20, jsonLength));
    const size_t binAt = 20 + jsonLength;
    if (bytes.size() >= binAt + 8) {
        uint32_t binLength = 0;
        std::memcpy(&binLength, bytes.data() + binAt, 4);
        g.bin = bytes.substr(binAt + 8, binLength);
    }
    return g;
}

std::string imageBytes(const Glb& g, size_t image)
{
    const json& im = g.doc["images"][image];
    if (!im.contains("bufferView"))
        return std::string();
    const json& view = g.doc["bufferViews"][im["bufferView"].get<size_t>()];
    return g.bin.substr(view.value("byteOffset", size_t(0)), view["byteLength"].get<size_t>());
}

// Removes members equal to glTF's defaults, so that two writers that differ
// only in spelling defaults out compare equal.
json withoutDefaults(json j)
{
    static const std::vector<std::pair<std::string, json>> defaults = {
        {"wrapS", 10497}, {"wrapT", 10497}, {"texCoord", 0}, {"emissiveFactor", {0, 0, 0}},
        {"alphaMode", "OPAQUE"}, {"alphaCutoff", 0.5}, {"doubleSided", false}, {"baseColorFactor", {1, 1, 1, 1}},
        {"metallicFactor", 1}, {"roughnessFactor", 1}, {"scale", 1}, {"strength", 1}};
    if (j.is_object()) {
        for (const auto& [key, value] : defaults)
            if (j.contains(key) && j[key] == value)
                j.erase(key);
        for (auto& [key, value] : j.items())
            value = withoutDefaults(value);
    } else if (j.is_array()) {
        for (auto& v : j)
            v = withoutDefaults(v);
    }
    return j;
}

json names(const json& array)
{
    json out = json::array();
    for (const json& e : array)
        out.push_back(e.value("name", ""));
    return out;
}

json extrasWithoutStrata(json e)
{
    if (e.is_object())
        e.erase("strata");
    return e.is_object() && e.empty() ? json() : e;
}

void checkKeepsEverything(const std::string& source, const std::string& dir, const std::string& stem)
{
    const std::string rig = dir + "/" + stem + ".glb";
    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + source + " --control " +
                                                   source + " --error-levels none -o " + rig);
    ASSERT_EQ(r.code, 0) << r.output;
    const Glb in = readGlb(source), out = readGlb(rig);
    ASSERT_FALSE(out.doc.is_null());
    const json& a = in.doc;
    const json& b = out.doc;
    EXPECT_EQ(a["asset"].value("copyright", ""), b["asset"].value("copyright", ""));
    EXPECT_EQ(withoutDefaults(a.value("materials", json::array())), withoutDefaults(b.value("materials", json::array())));
    EXPECT_EQ(a.value("textures", json::array()), b.value("textures", json::array()));
    EXPECT_EQ(withoutDefaults(a.value("samplers", json::array())), withoutDefaults(b.value("samplers", json::array())));
    EXPECT_EQ(names(a["meshes"]), names(b["meshes"]));
    EXPECT_EQ(names(a["nodes"]), names(b["nodes"]));
    EXPECT_EQ(a["skins"], b["skins"]);  // names, joints, skeleton and the inverse bind accessor's place
    ASSERT_EQ(a["animations"].size(), b["animations"].size());
    for (size_t i = 0; i < a["animations"].size(); ++i) {
        EXPECT_EQ(a["animations"][i].value("name", ""), b["animations"][i].value("name", ""));
        EXPECT_EQ(a["animations"][i]["channels"], b["animations"][i]["channels"]);
    }
    for (size_t i = 0; i < a["nodes"].size(); ++i)
        EXPECT_EQ(a["nodes"][i].value("extras", json()), b["nodes"][i].value("extras", json()));
    for (size_t i = 0; i < a["meshes"].size(); ++i)
        EXPECT_EQ(a["meshes"][i].value("extras", json()), extrasWithoutStrata(b["meshes"][i].value("extras", json())));
    // Every source image, byte for byte (the displacements are per vertex,
    // not an image).
    ASSERT_EQ(b.value("images", json::array()).size(), a.value("images", json::array()).size());
    for (size_t i = 0; i < a.value("images", json::array()).size(); ++i) {
        EXPECT_EQ(imageBytes(in, i), imageBytes(out, i)) << "image " << i;
        EXPECT_EQ(a["images"][i].value("mimeType", ""), b["images"][i].value("mimeType", ""));
    }
    const json& block = b["meshes"][0]["extensions"][io::kLayerExtension];
    EXPECT_FALSE(block.contains("version"));
    if (block.contains("displacementGeometryTexture")) {  // left out without UVs
        EXPECT_EQ(block["displacementGeometryTexture"]["encoding"], "vertex");
        EXPECT_FALSE(block["displacementGeometryTexture"].contains("image"));
    }
    ASSERT_TRUE(block["displacementVertices"].is_object());
    EXPECT_EQ(block["displacementVertices"]["level"], block["recommendedLevel"]);
    EXPECT_LT(block["displacementVertices"]["accessor"].get<size_t>(), b["accessors"].size());
    Rig loaded;
    const Status st = io::loadRig(rig, &loaded);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(int(loaded.displacement.vertexValues.size()), block["displacementVertices"]["count"].get<int>());
    int code = 0;
    const std::string report = test::runGltfValidator({rig}, &code);
    EXPECT_NE(report.find("0 errors, 0 warnings"), std::string::npos) << report;
}

// A surface of `rig` at `level` (displaced or not, no map) and its render
// layout; null when either fails.
std::unique_ptr<Surface> surfaceWithLayout(const Rig& rig, int level, bool displace, io::RenderMesh* layout)
{
    SurfaceOptions options;
    options.level = level;
    options.displace = displace;
    std::unique_ptr<Surface> surface;
    if (!Surface::create(&surface, rig, nullptr, options).isOk() || !io::buildRenderMesh(rig, surface->plan(), layout).isOk())
        return nullptr;
    return surface;
}

// The adaptive layout of `rig` at `level` for `trials` random mixes of
// quarter levels (all at the finest first): every corner is drawn at its
// frame vertex, with the attribute values the uniform layout gives that
// refined vertex in the same control face; parts are the uniform parts'
// faces; gather places the frame's positions.
void expectAdaptiveLayout(const Rig& rig, bool displace, int level, int trials, size_t* splitVertices)
{
    io::RenderMesh uniform;
    std::unique_ptr<Surface> surface = surfaceWithLayout(rig, level, displace, &uniform);
    ASSERT_TRUE(surface);
    const Plan& plan = surface->plan();
    const size_t faces = rig.mesh.faceCount(), perFace = size_t(1) << (2 * level);
    const std::vector<uint32_t>& tris = plan.refinedTriangles();
    std::mt19937 rng(7);
    std::vector<uint8_t> quarters(4 * faces);
    for (int trial = 0; trial < trials; ++trial) {
        SCOPED_TRACE("trial " + std::to_string(trial));
        for (size_t f = 0; f < faces; ++f) {
            const bool whole = trial > 0 && rng() % 4 == 0;
            for (int k = 0; k < 4; ++k)
                quarters[4 * f + size_t(k)] = uint8_t(trial == 0 ? level : whole ? 0 : 1 + int(rng() % uint32_t(level)));
        }
        ASSERT_TRUE(surface->setQuarterLevels(quarters.data(), quarters.size()).isOk());
        const AdaptiveFrame& frame = surface->adaptiveFrame();
        io::RenderMesh rm;
        ASSERT_TRUE(io::buildAdaptiveRenderMesh(uniform, plan, frame, &rm).isOk());
        if (trial < 2) {  // a layout made without its seam table (by hand): the same
            io::RenderMesh bare = uniform, again;
            bare.seams = {};
            ASSERT_TRUE(io::buildAdaptiveRenderMesh(bare, plan, frame, &again).isOk());
            EXPECT_EQ(again.indices, rm.indices);
            EXPECT_EQ(again.refinedVertex, rm.refinedVertex);
        }
        const size_t n = frame.vertexCount();
        ASSERT_EQ(rm.refinedVertexCount, n);
        for (size_t v = 0; v < n; ++v)
            ASSERT_EQ(rm.refinedVertex[v], v);
        if (trial == 0) {
            EXPECT_EQ(rm.vertexCount(), uniform.vertexCount());  // the same seams
        }
        *splitVertices += rm.vertexCount() - n;
        ASSERT_EQ(rm.indices.size(), frame.triangles().size());
        for (size_t c = 0; c < rm.indices.size(); ++c) {
            ASSERT_EQ(rm.refinedVertex[rm.indices[c]], frame.triangles()[c]);
            // Uniform's render vertex of this refined vertex in this face.
            const uint32_t v = frame.vertices()[frame.triangles()[c]], f = frame.triangleFaces()[c / 3];
            uint32_t want = ~0u;
            for (size_t u = 3 * perFace * f; u < 3 * perFace * (f + 1) && want == ~0u; ++u)
                if (tris[u] == v)
                    want = uniform.indices[u];
            ASSERT_NE(want, ~0u) << "corner " << c << " outside its face";
            ASSERT_EQ(rm.attributes.size(), uniform.attributes.size());
            for (size_t a = 0; a < rm.attributes.size(); ++a) {
                const size_t k = size_t(rm.attributes[a].components);
                for (size_t i = 0; i < k; ++i)
                    ASSERT_EQ(rm.attributes[a].values[rm.indices[c] * k + i], uniform.attributes[a].values[want * k + i])
                        << rm.attributes[a].name << " at corner " << c;
            }
        }
        ASSERT_EQ(rm.parts.size(), uniform.parts.size());
        size_t covered = 0;
        for (size_t p = 0; p < rm.parts.size(); ++p) {
            EXPECT_EQ(rm.parts[p].firstIndex, covered);
            EXPECT_EQ(rm.parts[p].material, uniform.parts[p].material);
            const size_t f0 = uniform.parts[p].firstIndex / (3 * perFace);
            const size_t f1 = f0 + uniform.parts[p].indexCount / (3 * perFace);
            for (size_t c = rm.parts[p].firstIndex; c < size_t(rm.parts[p].firstIndex) + rm.parts[p].indexCount; c += 3)
                ASSERT_TRUE(frame.triangleFaces()[c / 3] >= f0 && frame.triangleFaces()[c / 3] < f1);
            covered += rm.parts[p].indexCount;
        }
        EXPECT_EQ(covered, rm.indices.size());
        std::vector<glm::vec3> positions(n), drawn(rm.vertexCount());
        ASSERT_TRUE(surface->evaluateAdaptive(positions.data(), nullptr, n).isOk());
        rm.gather(positions.data(), drawn.data());
        for (size_t i = 0; i < drawn.size(); ++i)
            ASSERT_EQ(drawn[i], positions[rm.refinedVertex[i]]);
    }
}

}  // namespace

TEST(Scene, FoxKeepsEverythingThroughABake)
{
    STRATA_REQUIRE_DATA(fox, "Fox.glb");
    checkKeepsEverything(fox, test::tempDir("scene_fox"), "fox");
}

TEST(Scene, CesiumManKeepsEverythingThroughABake)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    checkKeepsEverything(man, test::tempDir("scene_cesium"), "man");
}

namespace {

// A mesh of one primitive, on a new node of its own; returns the node.
int addMeshNode(tinygltf::Model& m, const std::string& name, const tinygltf::Primitive& prim)
{
    tinygltf::Mesh mesh;
    mesh.name = name;
    mesh.primitives.push_back(prim);
    m.meshes.push_back(mesh);
    tinygltf::Node node;
    node.name = name;
    node.mesh = int(m.meshes.size() - 1);
    m.nodes.push_back(node);
    return int(m.nodes.size() - 1);
}

template <typename T>
std::vector<T> accessorData(const tinygltf::Model& m, int index, int components)
{
    const tinygltf::Accessor& acc = m.accessors[size_t(index)];
    const tinygltf::BufferView& view = m.bufferViews[size_t(acc.bufferView)];
    const size_t elem = sizeof(T) * size_t(components);
    const size_t stride = view.byteStride ? view.byteStride : elem;
    std::vector<T> out(acc.count * size_t(components));
    for (size_t i = 0; i < acc.count; ++i)
        std::memcpy(&out[i * size_t(components)],
                    m.buffers[size_t(view.buffer)].data.data() + view.byteOffset + acc.byteOffset + i * stride, elem);
    return out;
}

std::vector<uint32_t> indicesOf(const tinygltf::Model& m, int index)
{
    const tinygltf::Accessor& acc = m.accessors[size_t(index)];
    std::vector<uint32_t> out;
    if (acc.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)
        for (uint16_t v : accessorData<uint16_t>(m, index, 1))
            out.push_back(v);
    else
        out = accessorData<uint32_t>(m, index, 1);
    return out;
}

// A one-primitive glTF character with that primitive taken out of its mesh
// (to be split), and its triangles' indices.
bool takeFirstPrimitive(const std::string& source, tinygltf::Model* m, tinygltf::Primitive* whole,
                        std::vector<uint32_t>* idx)
{
    tinygltf::TinyGLTF io;
    std::string err, warn;
    if (!io.LoadBinaryFromFile(m, &err, &warn, source) || m->meshes.empty() || m->meshes[0].primitives.empty())
        return false;
    *whole = m->meshes[0].primitives[0];
    *idx = indicesOf(*m, whole->indices);
    m->meshes[0].primitives.clear();
    return true;
}

// CesiumMan as a production character: its primitive split in three with
// three materials, a fin triangle (own primitive) on an existing edge, and a
// closed "eye" mesh on a node parented to a joint, not skinned.
bool makeCharacter(const std::string& source, const std::string& path, size_t* finEdgeFaces)
{
    tinygltf::TinyGLTF io;
    tinygltf::Model m;
    tinygltf::Primitive whole;
    std::vector<uint32_t> idx;
    if (!takeFirstPrimitive(source, &m, &whole, &idx))
        return false;
    tinygltf::Mesh& mesh = m.meshes[0];
    const size_t faces = idx.size() / 3;
    for (int k = 0; k < 3; ++k) {
        tinygltf::Primitive p = whole;
        const size_t f0 = faces * size_t(k) / 3, f1 = faces * size_t(k + 1) / 3;
        std::vector<uint32_t> part(idx.begin() + long(3 * f0), idx.begin() + long(3 * f1));
        p.indices = addAccessor(m, part.data(), part.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                TINYGLTF_TYPE_SCALAR, part.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        if (k > 0) {
            tinygltf::Material mat = m.materials[0];
            mat.name = "part" + std::to_string(k);
            mat.pbrMetallicRoughness.baseColorFactor = {1.0, 0.5 * k, 0.2, 1.0};
            m.materials.push_back(mat);
            p.material = int(m.materials.size() - 1);
        }
        mesh.primitives.push_back(p);
    }
    // The fin: the first triangle's first edge plus a point off the surface.
    const std::vector<float> pos = accessorData<float>(m, whole.attributes.at("POSITION"), 3);
    const std::vector<float> uv = accessorData<float>(m, whole.attributes.at("TEXCOORD_0"), 2);
    const std::vector<uint16_t> joints = accessorData<uint16_t>(m, whole.attributes.at("JOINTS_0"), 4);
    const std::vector<float> weights = accessorData<float>(m, whole.attributes.at("WEIGHTS_0"), 4);
    const uint32_t e0 = idx[0], e1 = idx[1], e2 = idx[2];
    size_t edgeFaces = 0;
    for (size_t f = 0; f < faces; ++f)
        for (int c = 0; c < 3; ++c) {
            const uint32_t a = idx[3 * f + size_t(c)], b = idx[3 * f + size_t((c + 1) % 3)];
            auto same = [&](uint32_t x, uint32_t y) {
                return std::memcmp(&pos[3 * x], &pos[3 * y], 12) == 0;
            };
            edgeFaces += (same(a, e0) && same(b, e1)) || (same(a, e1) && same(b, e0));
        }
    *finEdgeFaces = edgeFaces + 1;
    float fin[9];
    for (int c = 0; c < 3; ++c) {
        fin[c] = pos[3 * e0 + size_t(c)];
        fin[3 + c] = pos[3 * e1 + size_t(c)];
        const float mid = 0.5f * (fin[c] + fin[3 + c]);
        fin[6 + c] = mid + 0.5f * (mid - pos[3 * e2 + size_t(c)]);
    }
    float finUV[6] = {uv[2 * e0], uv[2 * e0 + 1], uv[2 * e1], uv[2 * e1 + 1], uv[2 * e2], uv[2 * e2 + 1]};
    uint16_t finJoints[12];
    float finWeights[12];
    for (int k = 0; k < 4; ++k) {
        finJoints[k] = joints[4 * e0 + size_t(k)];
        finJoints[4 + k] = joints[4 * e1 + size_t(k)];
        finJoints[8 + k] = joints[4 * e0 + size_t(k)];
        finWeights[k] = weights[4 * e0 + size_t(k)];
        finWeights[4 + k] = weights[4 * e1 + size_t(k)];
        finWeights[8 + k] = weights[4 * e0 + size_t(k)];
    }
    tinygltf::Primitive finPrim;
    finPrim.mode = TINYGLTF_MODE_TRIANGLES;
    finPrim.material = 1;
    finPrim.attributes["POSITION"] = addAccessor(m, fin, sizeof(fin), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                                                 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    for (int c = 0; c < 3; ++c) {
        m.accessors.back().minValues.push_back(std::min({fin[c], fin[3 + c], fin[6 + c]}));
        m.accessors.back().maxValues.push_back(std::max({fin[c], fin[3 + c], fin[6 + c]}));
    }
    finPrim.attributes["TEXCOORD_0"] = addAccessor(m, finUV, sizeof(finUV), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                   TINYGLTF_TYPE_VEC2, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    finPrim.attributes["JOINTS_0"] = addAccessor(m, finJoints, sizeof(finJoints), TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                                 TINYGLTF_TYPE_VEC4, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    finPrim.attributes["WEIGHTS_0"] = addAccessor(m, finWeights, sizeof(finWeights), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                  TINYGLTF_TYPE_VEC4, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    mesh.primitives.push_back(finPrim);

    // The eye: a closed tetrahedron on a new node under the last joint.
    const float s = 0.03f;
    float eye[12] = {s, s, s, -s, -s, s, -s, s, -s, s, -s, -s};
    float eyeUV[8] = {0.1f, 0.1f, 0.2f, 0.1f, 0.1f, 0.2f, 0.2f, 0.2f};
    uint16_t eyeIdx[12] = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
    tinygltf::Primitive eyePrim;
    eyePrim.mode = TINYGLTF_MODE_TRIANGLES;
    eyePrim.material = 2;
    eyePrim.attributes["POSITION"] = addAccessor(m, eye, sizeof(eye), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                                                 4, TINYGLTF_TARGET_ARRAY_BUFFER);
    m.accessors.back().minValues = {-s, -s, -s};
    m.accessors.back().maxValues = {s, s, s};
    eyePrim.attributes["TEXCOORD_0"] = addAccessor(m, eyeUV, sizeof(eyeUV), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                   TINYGLTF_TYPE_VEC2, 4, TINYGLTF_TARGET_ARRAY_BUFFER);
    eyePrim.indices = addAccessor(m, eyeIdx, sizeof(eyeIdx), TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                  TINYGLTF_TYPE_SCALAR, 12, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    const int eyeNode = addMeshNode(m, "eye", eyePrim);
    m.nodes[size_t(eyeNode)].translation = {0.0, 0.1, 0.0};
    m.nodes[size_t(m.skins[0].joints.back())].children.push_back(eyeNode);
    return io.WriteGltfSceneToFile(&m, path, true, true, false, true);
}

// Plain linear blend skinning of the source file's vertices, computed here
// from its accessors: the reference an independent glTF client would draw.
std::vector<glm::vec3> plainLbs(const tinygltf::Model& m, const Rig& rig, const std::vector<glm::mat4>& world)
{
    std::vector<glm::vec3> out;
    const tinygltf::Skin& skin = m.skins[0];
    const std::vector<float> ibm = accessorData<float>(m, skin.inverseBindMatrices, 16);
    for (const RigPart& part : rig.parts) {
        const tinygltf::Primitive& p = m.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
        const std::vector<float> pos = accessorData<float>(m, p.attributes.at("POSITION"), 3);
        if (!part.skinned) {
            glm::mat4 place = world[size_t(part.node)];
            if (part.instance >= 0) {  // EXT_mesh_gpu_instancing: the instance's TRANSLATION in its node
                const tinygltf::Value& attributes =
                    m.nodes[size_t(part.node)].extensions.at("EXT_mesh_gpu_instancing").Get("attributes");
                const std::vector<float> t = accessorData<float>(m, attributes.Get("TRANSLATION").Get<int>(), 3);
                place = glm::translate(place, glm::make_vec3(&t[3 * size_t(part.instance)]));
            }
            for (size_t v = 0; v < pos.size() / 3; ++v)
                out.push_back(glm::vec3(place * glm::vec4(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2], 1.0f)));
            continue;
        }
        const std::vector<uint16_t> j = accessorData<uint16_t>(m, p.attributes.at("JOINTS_0"), 4);
        const std::vector<float> w = accessorData<float>(m, p.attributes.at("WEIGHTS_0"), 4);
        for (size_t v = 0; v < pos.size() / 3; ++v) {
            glm::mat4 sum(0.0f);
            for (int k = 0; k < 4; ++k) {
                const size_t joint = j[4 * v + size_t(k)];
                sum += w[4 * v + size_t(k)] * (world[size_t(skin.joints[joint])] * glm::make_mat4(&ibm[16 * joint]));
            }
            out.push_back(glm::vec3(sum * glm::vec4(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2], 1.0f)));
        }
    }
    return out;
}

// plainLbs with the rig's skeleton posed by animation `a` at `time`.
std::vector<glm::vec3> plainLbsAt(const tinygltf::Model& m, const Rig& rig, size_t a, float time)
{
    const Skeleton& sk = rig.skeleton;
    std::vector<NodeTransform> local(sk.nodes.size());
    std::vector<glm::mat4> world(sk.nodes.size());
    sampleAnimation(local.data(), sk, &sk.animations[a], time);
    computeWorldMatrices(world.data(), sk, local.data());
    return plainLbs(m, rig, world);
}

// A glb read by tinygltf after its meshopt-coded views are decoded, as a
// glTF client with meshopt support would.
::testing::AssertionResult loadPlainModel(const std::string& path, tinygltf::Model* model)
{
    std::string plain, err, warn;
    if (!io::readPlainGlb(path, &plain))
        return ::testing::AssertionFailure() << path << ": cannot read";
    tinygltf::TinyGLTF loader;
    if (!loader.LoadBinaryFromMemory(model, &err, &warn, reinterpret_cast<const unsigned char*>(plain.data()),
                                     unsigned(plain.size())))
        return ::testing::AssertionFailure() << path << ": " << err;
    return ::testing::AssertionSuccess();
}

// The test character (makeCharacter) written to dir and baked onto itself
// with default settings; returns the rig's path.
::testing::AssertionResult bakeCharacter(const std::string& man, const std::string& dir, std::string* input,
                                         std::string* rigPath, size_t* finEdgeFaces)
{
    *input = dir + "/character.glb";
    *rigPath = dir + "/rig.glb";
    if (!makeCharacter(man, *input, finEdgeFaces))
        return ::testing::AssertionFailure() << "cannot write " << *input;
    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + *input + " --control " +
                                                   *input + " --error-levels none -o " + *rigPath);
    if (r.code != 0)
        return ::testing::AssertionFailure() << r.output;
    return ::testing::AssertionSuccess();
}

}  // namespace

namespace {

// CesiumMan laid out as a production file is: its primitive split into
// `parts` primitives, each with its own vertices (so the parts meet along
// open seams) and its own material, a tint of the original.  The first
// `flat` parts are left without NORMAL (glTF draws them flat).
bool splitIntoParts(const std::string& source, const std::string& path, int parts, int flat = 0)
{
    tinygltf::TinyGLTF io;
    tinygltf::Model m;
    tinygltf::Primitive whole;
    std::vector<uint32_t> idx;
    if (!takeFirstPrimitive(source, &m, &whole, &idx))
        return false;
    tinygltf::Mesh& mesh = m.meshes[0];
    const size_t faces = idx.size() / 3;
    for (int k = 0; k < parts; ++k) {
        const size_t f0 = faces * size_t(k) / size_t(parts), f1 = faces * size_t(k + 1) / size_t(parts);
        std::vector<uint32_t> used(idx.begin() + long(3 * f0), idx.begin() + long(3 * f1));
        std::sort(used.begin(), used.end());
        used.erase(std::unique(used.begin(), used.end()), used.end());
        std::map<uint32_t, uint32_t> local;
        for (uint32_t v : used)
            local.emplace(v, uint32_t(local.size()));
        tinygltf::Primitive p;
        p.mode = TINYGLTF_MODE_TRIANGLES;
        for (const auto& [name, accessor] : whole.attributes) {
            if (name == "NORMAL" && k < flat)
                continue;
            const tinygltf::Accessor& a = m.accessors[size_t(accessor)];
            const size_t elem = size_t(tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType)) *
                                       tinygltf::GetNumComponentsInType(uint32_t(a.type)));
            const tinygltf::BufferView& view = m.bufferViews[size_t(a.bufferView)];
            const size_t stride = view.byteStride ? view.byteStride : elem;
            std::vector<unsigned char> bytes(used.size() * elem);
            for (size_t i = 0; i < used.size(); ++i)
                std::memcpy(&bytes[i * elem],
                            m.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset + used[i] * stride,
                            elem);
            const int type = a.type, componentType = a.componentType;
            const bool normalized = a.normalized;
            p.attributes[name] = addAccessor(m, bytes.data(), bytes.size(), componentType, type, used.size(),
                                             TINYGLTF_TARGET_ARRAY_BUFFER);
            m.accessors.back().normalized = normalized;
            if (name == "POSITION") {
                std::vector<float> xyz(3 * used.size());
                std::memcpy(xyz.data(), bytes.data(), bytes.size());
                tinygltf::Accessor& added = m.accessors.back();
                added.minValues.assign(3, 1e30);
                added.maxValues.assign(3, -1e30);
                for (size_t i = 0; i < xyz.size(); ++i) {
                    added.minValues[i % 3] = std::min(added.minValues[i % 3], double(xyz[i]));
                    added.maxValues[i % 3] = std::max(added.maxValues[i % 3], double(xyz[i]));
                }
            }
        }
        std::vector<uint32_t> tris;
        for (size_t c = 3 * f0; c < 3 * f1; ++c)
            tris.push_back(local.at(idx[c]));
        p.indices = addAccessor(m, tris.data(), tris.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                TINYGLTF_TYPE_SCALAR, tris.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        tinygltf::Material mat = m.materials[size_t(whole.material)];
        mat.name = "part" + std::to_string(k);
        mat.pbrMetallicRoughness.baseColorFactor = {1.0, 0.4 + 0.6 * (k % 2), 0.4 + 0.6 * (k % 3 == 0), 1.0};
        m.materials.push_back(mat);
        p.material = int(m.materials.size() - 1);
        mesh.primitives.push_back(p);
    }
    return io.WriteGltfSceneToFile(&m, path, true, true, false, true);
}

}  // namespace

using test::kFixedMapSizeFlag;

// A character in many parts, each with its own vertices and material (a
// production file's layout, as the held-out 59-primitive character has it),
// through --control auto: one cage for all of them that keeps the skin and
// the animation, carries the parts' colours as one texture, and poses within
// 1% of the source.  Ten parts have no NORMAL: the one cage cannot draw
// them flat and the rest smooth, and says so in one line.
namespace {

// An arm of three rigid pieces that pass through each other, as a robot's
// parts do at their joints (BrainStem): an upper arm on the shoulder joint,
// and an elbow ball and a forearm on the elbow joint, each a closed
// ellipsoid of its own, weight 1 on its joint.  The elbow bends 1.2 rad.
bool writePiecewiseArm(const std::string& path)
{
    tinygltf::Model m;
    m.asset.version = "2.0";
    struct Piece {
        glm::vec3 centre, radii;
        uint16_t joint;
    };
    const Piece pieces[] = {{{0.55f, 0.0f, 0.0f}, {0.62f, 0.2f, 0.2f}, 0},
                            {{1.0f, 0.0f, 0.0f}, {0.27f, 0.27f, 0.27f}, 1},
                            {{1.55f, 0.0f, 0.0f}, {0.65f, 0.16f, 0.16f}, 1}};
    tinygltf::Scene scene;
    for (const char* name : {"shoulder", "elbow"}) {
        tinygltf::Node n;
        n.name = name;
        m.nodes.push_back(n);
    }
    m.nodes[1].translation = {1.0, 0.0, 0.0};
    m.nodes[0].children = {1};
    scene.nodes.push_back(0);
    const int segments = 48, rings = 24;
    for (const Piece& piece : pieces) {
        std::vector<glm::vec3> pos, nrm;
        std::vector<uint32_t> tri;
        for (int i = 0; i <= rings; ++i)
            for (int j = 0; j < segments; ++j) {
                const float th = 3.14159265f * float(i) / float(rings), ph = 6.2831853f * float(j) / float(segments);
                const glm::vec3 d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
                pos.push_back(piece.centre + glm::vec3(d.y, d.x, d.z) * piece.radii);
                nrm.push_back(glm::normalize(glm::vec3(d.y, d.x, d.z) / piece.radii));
            }
        for (int i = 0; i < rings; ++i)
            for (int j = 0; j < segments; ++j) {
                const uint32_t a = uint32_t(i * segments + j), b = uint32_t(i * segments + (j + 1) % segments),
                               c = a + uint32_t(segments), d = b + uint32_t(segments);
                if (i > 0)
                    tri.insert(tri.end(), {a, c, b});
                if (i < rings - 1)
                    tri.insert(tri.end(), {b, c, d});
            }
        const std::vector<uint16_t> joints(4 * pos.size(), 0);
        std::vector<uint16_t> own = joints;
        std::vector<float> weights(4 * pos.size(), 0.0f);
        for (size_t v = 0; v < pos.size(); ++v) {
            own[4 * v] = piece.joint;
            weights[4 * v] = 1.0f;
        }
        tinygltf::Primitive prim;
        prim.attributes["POSITION"] = test::addAccessor(m, pos.data(), pos.size() * 12, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                        TINYGLTF_TYPE_VEC3, pos.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
        glm::vec3 lo = pos[0], hi = pos[0];
        for (const glm::vec3& q : pos) {
            lo = glm::min(lo, q);
            hi = glm::max(hi, q);
        }
        m.accessors.back().minValues = {lo.x, lo.y, lo.z};
        m.accessors.back().maxValues = {hi.x, hi.y, hi.z};
        prim.attributes["NORMAL"] = test::addAccessor(m, nrm.data(), nrm.size() * 12, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                      TINYGLTF_TYPE_VEC3, nrm.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
        prim.attributes["JOINTS_0"] =
            test::addAccessor(m, own.data(), own.size() * 2, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC4,
                              pos.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
        prim.attributes["WEIGHTS_0"] =
            test::addAccessor(m, weights.data(), weights.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4,
                              pos.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
        prim.indices = test::addAccessor(m, tri.data(), tri.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                         TINYGLTF_TYPE_SCALAR, tri.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        tinygltf::Mesh mesh;
        mesh.primitives.push_back(prim);
        m.meshes.push_back(mesh);
        tinygltf::Node node;
        node.mesh = int(m.meshes.size()) - 1;
        node.skin = 0;
        m.nodes.push_back(node);
        scene.nodes.push_back(int(m.nodes.size()) - 1);
    }
    const float ibm[32] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1,
                           1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1, 0, 0, 1};
    tinygltf::Skin skin;
    skin.joints = {0, 1};
    skin.inverseBindMatrices = test::addAccessor(m, ibm, sizeof(ibm), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                 TINYGLTF_TYPE_MAT4, 2, 0);
    m.bufferViews.back().target = 0;
    m.skins.push_back(skin);
    const float times[2] = {0.0f, 1.0f};
    const glm::quat bent = glm::angleAxis(1.2f, glm::vec3(0.0f, 0.0f, 1.0f));
    const float keys[8] = {0, 0, 0, 1, bent.x, bent.y, bent.z, bent.w};
    tinygltf::AnimationSampler sampler;
    sampler.input = test::addAccessor(m, times, sizeof(times), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, 2, 0);
    m.bufferViews.back().target = 0;
    m.accessors.back().minValues = {0.0};
    m.accessors.back().maxValues = {1.0};
    sampler.output = test::addAccessor(m, keys, sizeof(keys), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, 2, 0);
    m.bufferViews.back().target = 0;
    sampler.interpolation = "LINEAR";
    tinygltf::Animation bend;
    bend.name = "bend";
    bend.samplers.push_back(sampler);
    tinygltf::AnimationChannel channel;
    channel.sampler = 0;
    channel.target_node = 1;
    channel.target_path = "rotation";
    bend.channels.push_back(channel);
    m.animations.push_back(bend);
    m.scenes.push_back(scene);
    m.defaultScene = 0;
    tinygltf::TinyGLTF gltf;
    return gltf.WriteGltfSceneToFile(&m, path, true, true, false, true);
}

}  // namespace

// Pieces that pass through each other (the robot's parts at its joints):
// each piece's vertices map onto its own piece of the automatic cage, and
// each cage vertex takes its skin weights from its own piece.  Mapped onto
// the nearest cage, the forearm's end inside the elbow ball rode on the
// ball's cage and the other way round, and cage vertices near the junction
// blended both joints: posed, the rig went 2-4x past what it measured at
// rest, and a 59-piece robot's search fell back to the capture itself.
TEST(Scene, AutomaticCageOfPiecesThatPassThroughEachOtherKeepsEachOnItsJoint)
{
    const std::string dir = test::tempDir("scene_pieces");
    const std::string input = dir + "/arm.glb", rigPath = dir + "/rig.glb";
    ASSERT_TRUE(writePiecewiseArm(input));
    const test::CommandResult r =
        test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + input + " --control auto --control-faces 600 " +
                         kFixedMapSizeFlag + " -o " + rigPath + " --report " + dir + "/report.json");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("the capture's 3 separate pieces each mapped onto its own"), std::string::npos)
        << r.output;
    const json report = json::parse(test::readText(dir + "/report.json"));
    EXPECT_EQ(report["control"]["pieces"], 3);
    // Every cage vertex follows its piece's one joint, as the capture does.
    ASSERT_TRUE(report.contains("skinFit"));
    EXPECT_LT(report["skinFit"]["after"].get<double>(), 1e-6) << report["skinFit"].dump();
    // So the posed surface is as close to the posed capture as the rest
    // surface is to the capture at rest.
    double rest = 0.0;
    for (const json& l : report["closedLoop"])
        if (l["level"] == report["recommendedLevel"])
            rest = std::max(l["forwardRms"].get<double>(), l["backwardRms"].get<double>());
    ASSERT_GT(rest, 0.0) << report["closedLoop"].dump();
    ASSERT_EQ(report["posed"]["frames"].size(), 10u);
    for (const json& f : report["posed"]["frames"])
        EXPECT_LT(f["rms"].get<double>(), 1.2 * rest) << "at " << f["time"] << "; at rest " << rest;
}

TEST(Scene, AutomaticCageOfAManyPartCharacterKeepsItsParts)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_many_parts");
    const std::string input = dir + "/parts.glb", rigPath = dir + "/rig.glb";
    ASSERT_TRUE(splitIntoParts(man, input, 59, 10));
    const test::CommandResult r =
        test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + input + " --control auto --control-faces 400 " +
                         kFixedMapSizeFlag + " -o " + rigPath + " --report " + dir + "/report.json");
    ASSERT_EQ(r.code, 0) << r.output;
    Rig source, rig;
    ASSERT_TRUE(io::loadRig(input, &source).isOk());
    ASSERT_EQ(source.parts.size(), 59u);
    ASSERT_TRUE(io::loadRig(rigPath, &rig).isOk());
    EXPECT_EQ(rig.skeleton.skin.joints.size(), source.skeleton.skin.joints.size());
    EXPECT_EQ(rig.skeleton.animations.size(), source.skeleton.animations.size());
    EXPECT_NE(r.output.find("materials carried as one"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("10 of its 59 primitives are drawn flat (no NORMAL, or their faces' normals); the "
                            "automatic cage is one mesh, drawn smooth"),
              std::string::npos)
        << r.output;
    EXPECT_FALSE(rig.displacement.flatShading);
    for (size_t p = 0; p < source.parts.size(); ++p)
        EXPECT_EQ(source.parts[p].flat, p < 10) << p;
    io::SceneMaterials materials;
    ASSERT_TRUE(io::loadSceneMaterials(rig, &materials).isOk());
    ASSERT_FALSE(materials.materials.empty());
    EXPECT_GE(materials.materials[0].image, 0);
    const json report = json::parse(test::readText(dir + "/report.json"));
    ASSERT_TRUE(report.contains("posed"));
    EXPECT_EQ(report["posed"]["frames"].size(), 10u);
    for (const json& f : report["posed"]["frames"])
        EXPECT_LT(f["rms"].get<double>(), 0.01) << "at " << f["time"];
}

namespace {

enum class SecondSkin { Alike, Moved, Mirrored, Apart, OneJoint, OneJointElsewhere };

// CesiumMan as converters that write a skin per mesh leave it: its
// triangles in two meshes on two nodes, each with its own skin over the
// same joints, the second listing them in reverse order.  Alike: both bind
// the joints alike.  Moved: the second mesh's vertices are moved by a
// transform T and its inverse bind matrices take T out again (a mesh node
// whose bind transform the converter folded into its skin), so it poses the
// same.  Mirrored: so, with T a mirror (x -> -x) as well.  Apart: the
// second skin binds one joint elsewhere, which no transform of its mesh
// reconciles with the first.  OneJoint: the second mesh follows one joint
// alone (kOneJoint, weight 1), bound alike.  OneJointElsewhere: so, bound
// in another pose: that joint's inverse bind matrix takes a transform T
// out, and the mesh's vertices are moved by T (as a mesh bound after the
// skeleton was posed), so it poses as OneJoint does.
constexpr size_t kOneJoint = 5;  // of CesiumMan's skin

bool skinPerMesh(const std::string& source, const std::string& path, SecondSkin how)
{
    tinygltf::Model m;
    tinygltf::Primitive whole;
    std::vector<uint32_t> idx;
    if (!takeFirstPrimitive(source, &m, &whole, &idx) || m.skins.size() != 1)
        return false;
    const size_t half = 3 * (idx.size() / 6);
    tinygltf::Primitive a = whole, b = whole;
    a.indices = addAccessor(m, idx.data(), half * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, half,
                            TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    b.indices = addAccessor(m, idx.data() + half, (idx.size() - half) * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                            TINYGLTF_TYPE_SCALAR, idx.size() - half, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    m.meshes[0].primitives.push_back(a);
    // The second skin: the joints reversed, each bound by M = IBM * T^-1.
    const tinygltf::Skin first = m.skins[0];
    const size_t nj = first.joints.size();
    const std::vector<float> ibm = accessorData<float>(m, first.inverseBindMatrices, 16);
    glm::mat4 t(1.0f);
    if (how == SecondSkin::Moved || how == SecondSkin::Mirrored || how == SecondSkin::OneJointElsewhere)
        t = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.3f, -0.2f, 0.1f)), 0.4f, glm::vec3(0.0f, 0.0f, 1.0f));
    const bool oneJoint = how == SecondSkin::OneJoint || how == SecondSkin::OneJointElsewhere;
    if (how == SecondSkin::Mirrored)
        t = glm::scale(t, glm::vec3(-1.0f, 1.0f, 1.0f));
    std::vector<float> ibm2(16 * nj);
    tinygltf::Skin second;
    second.name = "second";
    for (size_t k = 0; k < nj; ++k) {
        const size_t j = nj - 1 - k;
        second.joints.push_back(first.joints[j]);
        glm::mat4 mk = glm::make_mat4(&ibm[16 * j]);
        if (!oneJoint || j == kOneJoint)
            mk = mk * glm::inverse(t);
        if (how == SecondSkin::Apart && k == 3)
            mk[3][0] += 0.05f;
        std::memcpy(&ibm2[16 * k], &mk[0][0], 64);
    }
    second.inverseBindMatrices = addAccessor(m, ibm2.data(), ibm2.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                             TINYGLTF_TYPE_MAT4, nj, 0);
    m.skins.push_back(second);
    std::vector<uint16_t> joints = accessorData<uint16_t>(m, whole.attributes.at("JOINTS_0"), 4);
    for (uint16_t& j : joints)
        j = uint16_t(nj - 1 - j);
    if (oneJoint) {
        std::vector<float> weights(joints.size(), 0.0f);
        for (size_t v = 0; v < joints.size() / 4; ++v) {
            joints[4 * v] = uint16_t(nj - 1 - kOneJoint);
            weights[4 * v] = 1.0f;
        }
        b.attributes["WEIGHTS_0"] = addAccessor(m, weights.data(), weights.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                TINYGLTF_TYPE_VEC4, weights.size() / 4, TINYGLTF_TARGET_ARRAY_BUFFER);
    }
    b.attributes["JOINTS_0"] = addAccessor(m, joints.data(), joints.size() * 2, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                           TINYGLTF_TYPE_VEC4, joints.size() / 4, TINYGLTF_TARGET_ARRAY_BUFFER);
    std::vector<float> xyz = accessorData<float>(m, whole.attributes.at("POSITION"), 3);
    std::vector<double> lo(3, 1e30), hi(3, -1e30);
    for (size_t v = 0; v < xyz.size() / 3; ++v) {
        const glm::vec4 q = t * glm::vec4(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2], 1.0f);
        for (int c = 0; c < 3; ++c) {
            xyz[3 * v + size_t(c)] = q[c];
            lo[size_t(c)] = std::min(lo[size_t(c)], double(q[c]));
            hi[size_t(c)] = std::max(hi[size_t(c)], double(q[c]));
        }
    }
    b.attributes["POSITION"] = addAccessor(m, xyz.data(), xyz.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                           TINYGLTF_TYPE_VEC3, xyz.size() / 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    m.accessors.back().minValues = lo;
    m.accessors.back().maxValues = hi;
    b.attributes.erase("NORMAL");  // its normals would want T too; glTF draws it flat
    const int lower = addMeshNode(m, "lower", b);
    m.nodes[size_t(lower)].skin = 1;
    m.scenes[size_t(std::max(m.defaultScene, 0))].nodes.push_back(lower);
    tinygltf::TinyGLTF io;
    return io.WriteGltfSceneToFile(&m, path, true, true, false, true);
}

// Sum over triangles of p0 . (p1 x p2) / 6: the enclosed volume of a closed
// mesh, and of an open one still a figure whose sign follows each
// triangle's winding.
double signedVolume(const std::vector<glm::vec3>& p, const std::vector<uint32_t>& triangles)
{
    double v = 0.0;
    for (size_t t = 0; t + 2 < triangles.size(); t += 3)
        v += glm::dot(glm::dvec3(p[triangles[t]]),
                      glm::cross(glm::dvec3(p[triangles[t + 1]]), glm::dvec3(p[triangles[t + 2]]))) / 6.0;
    return v;
}

// The largest distance from a point of `a` to the nearest point of `b`.
float farthestFromNearest(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b)
{
    float worst = 0.0f;
    for (const glm::vec3& p : a) {
        float nearest = std::numeric_limits<float>::max();
        for (const glm::vec3& q : b)
            nearest = std::min(nearest, glm::length(p - q));
        worst = std::max(worst, nearest);
    }
    return worst;
}

}  // namespace

// A character whose meshes each have a skin of their own poses as one rig
// with one skin (their union), welded where the meshes meet, whether its
// skins bind the joints alike or one mesh's bind space is moved by its
// skin; --control auto keeps its skin and animation.  Skins that bind a
// joint in poses no transform reconciles, where a vertex's joints would
// put it in different places, are refused, naming the joint and the vertex
// (AMeshBoundInAnotherPoseIsReboundVertexByVertex: where they agree).
TEST(Scene, ACharacterWithASkinPerMeshPosesAsOne)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_skin_per_mesh");
    Rig source;
    ASSERT_TRUE(io::loadRig(man, &source).isOk());
    const Skeleton& sk = source.skeleton;
    ASSERT_FALSE(sk.animations.empty());
    io::Reconstruction expected;
    io::Pose pose;
    ASSERT_TRUE(io::reconstruct(&expected, source, nullptr, Scheme::Linear, 0, 1.0f, &pose).isOk());
    const double volume = signedVolume(source.mesh.positions, source.mesh.triangles);
    for (SecondSkin how : {SecondSkin::Alike, SecondSkin::Moved, SecondSkin::Mirrored}) {
        const std::string input = dir + (how == SecondSkin::Alike   ? "/alike.glb"
                                         : how == SecondSkin::Moved ? "/moved.glb"
                                                                    : "/mirrored.glb");
        SCOPED_TRACE(input);
        ASSERT_TRUE(skinPerMesh(man, input, how));
        Rig rig;
        const Status st = io::loadRig(input, &rig);
        ASSERT_TRUE(st.isOk()) << st.message();
        EXPECT_EQ(rig.skeleton.skin.joints.size(), sk.skin.joints.size());
        EXPECT_EQ(rig.mesh.positions.size(), source.mesh.positions.size()) << "the meshes weld where they meet";
        // Every triangle wound as the one-skin character's (as glTF draws it).
        EXPECT_NEAR(signedVolume(rig.mesh.positions, rig.mesh.triangles), volume, 1e-4 * std::abs(volume));
        io::Reconstruction rec;
        ASSERT_TRUE(io::reconstruct(&rec, rig, nullptr, Scheme::Linear, 0, 1.0f, &pose).isOk());
        for (int k = 0; k <= 3; ++k) {
            pose.animation = 0;
            pose.time = sk.animations[0].start + (sk.animations[0].end - sk.animations[0].start) * float(k) / 3.0f;
            ASSERT_TRUE(io::reconstructPose(&expected, pose).isOk());
            ASSERT_TRUE(io::reconstructPose(&rec, pose).isOk());
            EXPECT_LT(farthestFromNearest(rec.positions, expected.positions), 1e-5f) << "at " << pose.time;
            EXPECT_LT(farthestFromNearest(expected.positions, rec.positions), 1e-5f) << "at " << pose.time;
        }
    }
    // Its detailed scene keeps each mesh on its own skin's joints, so it
    // poses as the one-skin character's detailed scene does, its triangles
    // wound alike.
    std::vector<io::Reconstruction> posed(3);
    std::vector<double> volumes(3);
    for (int k = 0; k < 3; ++k) {
        Rig rig, back;
        ASSERT_TRUE(io::loadRig(k == 0 ? man : dir + (k == 1 ? "/moved.glb" : "/mirrored.glb"), &rig).isOk());
        io::Reconstruction rec;
        ASSERT_TRUE(io::reconstruct(&rec, rig, nullptr, Scheme::Linear, 1).isOk());
        const std::string scene = dir + "/scene" + std::to_string(k) + ".glb";
        ASSERT_TRUE(io::writeReconstructedScene(scene, rig, rec).isOk());
        ASSERT_TRUE(io::loadRig(scene, &back).isOk());
        pose.time = 0.5f * (sk.animations[0].start + sk.animations[0].end);
        ASSERT_TRUE(io::reconstruct(&posed[size_t(k)], back, nullptr, Scheme::Linear, 0, 1.0f, &pose).isOk());
        volumes[size_t(k)] = signedVolume(back.mesh.positions, back.mesh.triangles);
    }
    for (int k = 1; k < 3; ++k) {
        EXPECT_LT(farthestFromNearest(posed[size_t(k)].positions, posed[0].positions), 1e-5f) << k;
        EXPECT_LT(farthestFromNearest(posed[0].positions, posed[size_t(k)].positions), 1e-5f) << k;
        EXPECT_NEAR(volumes[size_t(k)], volumes[0], 1e-4 * std::abs(volumes[0])) << k;
    }

    const std::string rigPath = dir + "/rig.glb";
    test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + dir +
                                             "/moved.glb --control auto --control-faces 400 " + kFixedMapSizeFlag +
                                             " -o " + rigPath);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(r.output.find("carries its shape only"), std::string::npos) << r.output;
    Rig baked;
    ASSERT_TRUE(io::loadRig(rigPath, &baked).isOk());
    EXPECT_EQ(baked.skeleton.skin.joints.size(), sk.skin.joints.size());
    EXPECT_EQ(baked.skeleton.animations.size(), sk.animations.size());

    const std::string apart = dir + "/apart.glb";
    ASSERT_TRUE(skinPerMesh(man, apart, SecondSkin::Apart));
    Rig refused;
    const Status st = io::loadRig(apart, &refused);
    ASSERT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("apart.glb: skins 0 and 1 bind joint node "), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("no one transform of their meshes reconciles"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("of mesh lower primitive 0 lies "), std::string::npos) << st.message();
}

// A mesh whose skin binds a joint in another pose than the first skin does
// (converters keep each mesh's own bind pose): no one transform takes its
// bind space to the first's, so its vertices are rebound one by one, each
// by its joints' moves.  Exact for a mesh on one joint: it loads and poses
// as the same mesh bound alike, at every time.  (It was refused, and
// --control auto carried the shape alone.)  Its refined scene, which would
// need each mesh back on its own skin, is refused by name; a mesh whose
// joints disagree (Apart, above) still is.
TEST(Scene, AMeshBoundInAnotherPoseIsReboundVertexByVertex)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_rebound_skin");
    const std::string alike = dir + "/one_joint.glb", elsewhere = dir + "/one_joint_elsewhere.glb";
    ASSERT_TRUE(skinPerMesh(man, alike, SecondSkin::OneJoint));
    ASSERT_TRUE(skinPerMesh(man, elsewhere, SecondSkin::OneJointElsewhere));
    Rig a, b;
    ASSERT_TRUE(io::loadRig(alike, &a).isOk());
    const Status st = io::loadRig(elsewhere, &b);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(b.mesh.positions.size(), a.mesh.positions.size()) << "welded alike";
    EXPECT_EQ(b.skeleton.skin.joints.size(), a.skeleton.skin.joints.size());
    io::Reconstruction ra, rb;
    io::Pose pose;
    ASSERT_TRUE(io::reconstruct(&ra, a, nullptr, Scheme::Linear, 0, 1.0f, &pose).isOk());
    ASSERT_TRUE(io::reconstruct(&rb, b, nullptr, Scheme::Linear, 0, 1.0f, &pose).isOk());
    const Animation& an = a.skeleton.animations.at(0);
    for (int k = 0; k <= 4; ++k) {
        pose.animation = 0;
        pose.time = an.start + (an.end - an.start) * float(k) / 4.0f;
        ASSERT_TRUE(io::reconstructPose(&ra, pose).isOk());
        ASSERT_TRUE(io::reconstructPose(&rb, pose).isOk());
        EXPECT_LT(farthestFromNearest(rb.positions, ra.positions), 1e-5f) << "at " << pose.time;
        EXPECT_LT(farthestFromNearest(ra.positions, rb.positions), 1e-5f) << "at " << pose.time;
    }
    io::Reconstruction rec;
    ASSERT_TRUE(io::reconstruct(&rec, b, nullptr, Scheme::Linear, 1).isOk());
    const Status written = io::writeReconstructedScene(dir + "/scene.glb", b, rec);
    ASSERT_FALSE(written.isOk());
    EXPECT_NE(written.message().find("binds its meshes in another pose than skin 0"), std::string::npos)
        << written.message();
}

// A mesh two nodes place (a pair of eyes, each on its own joint, one the
// other's mirror) is read at both places, follows each node and faces
// outward at each, as glTF draws it; before, the second place was dropped
// without a word.  A third node outside the scene adds nothing; a fourth
// that draws it at two places through EXT_mesh_gpu_instancing is read at
// both (it was read once, where the node itself places it, and named).  A
// bake onto such a file as its own control mesh, whose rig would need UVs
// of their own at each place, is refused naming the mesh and its nodes, or
// its node and the extension.
TEST(Scene, AMeshTwoNodesPlaceIsReadAtBoth)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_mesh_placed_twice");
    const std::string input = dir + "/eyes.glb";
    tinygltf::Model m;
    {
        tinygltf::TinyGLTF io;
        std::string err, warn;
        ASSERT_TRUE(io.LoadBinaryFromFile(&m, &err, &warn, man)) << err;
        const float s = 0.02f;
        float eye[12] = {s, s, s, -s, -s, s, -s, s, -s, s, -s, -s};
        uint16_t eyeIdx[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};  // counter-clockwise seen from outside
        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        prim.attributes["POSITION"] = addAccessor(m, eye, sizeof(eye), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                  TINYGLTF_TYPE_VEC3, 4, TINYGLTF_TARGET_ARRAY_BUFFER);
        m.accessors.back().minValues = {-s, -s, -s};
        m.accessors.back().maxValues = {s, s, s};
        prim.indices = addAccessor(m, eyeIdx, sizeof(eyeIdx), TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                   TINYGLTF_TYPE_SCALAR, 12, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        // The left eye, the right one (its mirror, as exporters write it) and
        // a third outside the scene, which glTF does not draw.
        const int eyeL = addMeshNode(m, "eye", prim);
        tinygltf::Node eyeR = m.nodes[size_t(eyeL)], spare = eyeR;
        m.nodes[size_t(eyeL)].translation = {0.05, 0.1, 0.0};
        eyeR.translation = {-0.05, 0.1, 0.0};
        eyeR.scale = {-1.0, 1.0, 1.0};
        m.nodes.push_back(eyeR);
        m.nodes.push_back(spare);
        // A fourth draws it at two more places, through GPU instancing.
        const float shift[6] = {0.0f, 0.05f, 0.0f, 0.0f, -0.05f, 0.0f};
        tinygltf::Value::Object instancing, attributes;
        attributes["TRANSLATION"] = tinygltf::Value(addAccessor(m, shift, sizeof(shift), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                                TINYGLTF_TYPE_VEC3, 2, 0));
        instancing["attributes"] = tinygltf::Value(attributes);
        tinygltf::Node crowd = spare;
        crowd.name = "instanced eyes";
        crowd.extensions["EXT_mesh_gpu_instancing"] = tinygltf::Value(instancing);
        m.nodes.push_back(crowd);
        m.scenes[size_t(std::max(m.defaultScene, 0))].nodes.push_back(int(m.nodes.size() - 1));
        m.extensionsUsed.push_back("EXT_mesh_gpu_instancing");
        const std::vector<int>& joints = m.skins[0].joints;
        m.nodes[size_t(joints[joints.size() - 1])].children.push_back(eyeL);
        m.nodes[size_t(joints[joints.size() - 2])].children.push_back(eyeL + 1);
        ASSERT_TRUE(io.WriteGltfSceneToFile(&m, input, true, true, false, true));
    }
    Rig source, rig;
    ASSERT_TRUE(io::loadRig(man, &source).isOk());
    ASSERT_TRUE(io::loadRig(input, &rig).isOk());
    ASSERT_EQ(rig.parts.size(), source.parts.size() + 4);
    const RigPart& left = rig.parts[rig.parts.size() - 4];
    const RigPart& right = rig.parts[rig.parts.size() - 3];
    for (const std::string& w : rig.warnings)
        EXPECT_EQ(w.find("EXT_mesh_gpu_instancing"), std::string::npos) << w;
    EXPECT_EQ(left.mesh, right.mesh);
    EXPECT_NE(left.node, right.node);
    EXPECT_EQ(rig.mesh.positions.size(), source.mesh.positions.size() + 16);
    // The instances: one node, each instance's place (its node is at rest
    // where the scene's root is).
    for (int k = 0; k < 2; ++k) {
        const RigPart& instance = rig.parts[rig.parts.size() - 2 + size_t(k)];
        EXPECT_EQ(instance.node, rig.parts.back().node);
        EXPECT_EQ(instance.instance, k);
        EXPECT_NE(instance.name.find("instance " + std::to_string(k)), std::string::npos) << instance.name;
        const glm::vec3 first = rig.mesh.positions[rig.sourceVertex[instance.firstVertex]];
        EXPECT_LT(glm::length(first - glm::vec3(0.02f, 0.02f + (k ? -0.05f : 0.05f), 0.02f)), 1e-6f) << k;
    }
    // Both eyes face outward, the mirrored one too (glTF draws a mirrored
    // node's triangles with their winding reversed).
    for (const RigPart* eye : {&left, &right}) {
        double volume = 0.0;
        for (uint32_t f = eye->firstFace; f < eye->firstFace + eye->faceCount; ++f) {
            const uint32_t* t = &rig.mesh.triangles[3 * size_t(f)];
            volume += double(glm::dot(rig.mesh.positions[t[0]],
                                      glm::cross(rig.mesh.positions[t[1]], rig.mesh.positions[t[2]])));
        }
        EXPECT_GT(volume, 0.0) << eye->name;
    }
    // Posed, every vertex where plain skinning of the file puts it: each
    // eye on its own joint.
    const Skeleton& sk = rig.skeleton;
    ASSERT_FALSE(sk.animations.empty());
    io::Reconstruction rec;
    io::Pose pose;
    pose.animation = 0;
    pose.time = 0.5f * (sk.animations[0].start + sk.animations[0].end);
    ASSERT_TRUE(io::reconstruct(&rec, rig, nullptr, Scheme::Linear, 0, 1.0f, &pose).isOk());
    const std::vector<glm::vec3> lbs = plainLbsAt(m, rig, 0, pose.time);
    ASSERT_EQ(lbs.size(), rig.sourceVertex.size());
    float worst = 0.0f;
    for (size_t f = 0; f < lbs.size(); ++f)
        worst = std::max(worst, glm::length(lbs[f] - rec.positions[rig.sourceVertex[f]]));
    EXPECT_LT(worst, 1e-5f);
    const glm::vec3 apart = lbs[left.firstVertex] - lbs[right.firstVertex];
    EXPECT_GT(glm::length(apart), 0.05f) << "the eyes are at two places";
    // The detailed scene keeps the file's winding: the eye's mesh, which both
    // nodes draw, faces outward in its own space.
    io::Reconstruction fine;
    ASSERT_TRUE(io::reconstruct(&fine, rig, nullptr, Scheme::Linear, 1).isOk());
    ASSERT_TRUE(io::writeReconstructedScene(dir + "/scene.glb", rig, fine).isOk());
    {
        tinygltf::Model scene;
        tinygltf::TinyGLTF io;
        std::string err, warn;
        ASSERT_TRUE(io.LoadBinaryFromFile(&scene, &err, &warn, dir + "/scene.glb")) << err;
        const tinygltf::Primitive& prim = scene.meshes[size_t(left.mesh)].primitives[0];
        const std::vector<float> p = accessorData<float>(scene, prim.attributes.at("POSITION"), 3);
        const std::vector<uint32_t> tri = indicesOf(scene, prim.indices);
        ASSERT_EQ(tri.size(), 4u * 12u);
        double volume = 0.0;
        for (size_t t = 0; t < tri.size(); t += 3) {
            auto at = [&](size_t c) {
                return glm::vec3(p[3 * tri[t + c]], p[3 * tri[t + c] + 1], p[3 * tri[t + c] + 2]);
            };
            volume += double(glm::dot(at(0), glm::cross(at(1), at(2))));
        }
        EXPECT_GT(volume, 0.0);
    }

    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + input + " --control " +
                                                   input + " -o " + dir + "/rig.glb");
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.output.find("eyes.glb: mesh " + std::to_string(left.mesh) + " (eye) is placed by nodes "),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("give each node its own copy of the mesh"), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir + "/rig.glb"));
    // The instanced node alone: the capture is both its places; as its own
    // control it is refused, naming the node and the extension.
    tinygltf::Model crowd;
    crowd.asset.version = "2.0";
    crowd.buffers.emplace_back();
    {
        const tinygltf::Mesh& eyeMesh = m.meshes[size_t(left.mesh)];
        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        const std::vector<float> eye = accessorData<float>(m, eyeMesh.primitives[0].attributes.at("POSITION"), 3);
        const std::vector<uint32_t> eyeIdx = indicesOf(m, eyeMesh.primitives[0].indices);
        prim.attributes["POSITION"] = addAccessor(crowd, eye.data(), eye.size() * 4, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                  TINYGLTF_TYPE_VEC3, eye.size() / 3, TINYGLTF_TARGET_ARRAY_BUFFER);
        crowd.accessors.back().minValues = {-0.02, -0.02, -0.02};
        crowd.accessors.back().maxValues = {0.02, 0.02, 0.02};
        prim.indices = addAccessor(crowd, eyeIdx.data(), eyeIdx.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                   TINYGLTF_TYPE_SCALAR, eyeIdx.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        const float shift[6] = {0.0f, 0.05f, 0.0f, 0.0f, -0.05f, 0.0f};
        tinygltf::Value::Object instancing, attributes;
        attributes["TRANSLATION"] = tinygltf::Value(addAccessor(
            crowd, shift, sizeof(shift), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 2, 0));
        instancing["attributes"] = tinygltf::Value(attributes);
        const int node = addMeshNode(crowd, "eye", prim);
        crowd.nodes[size_t(node)].extensions["EXT_mesh_gpu_instancing"] = tinygltf::Value(instancing);
        crowd.extensionsUsed.push_back("EXT_mesh_gpu_instancing");
        crowd.scenes.emplace_back().nodes.push_back(node);
        crowd.defaultScene = 0;
        tinygltf::TinyGLTF io;
        ASSERT_TRUE(io.WriteGltfSceneToFile(&crowd, dir + "/crowd.glb", true, true, false, true));
    }
    Rig both;
    ASSERT_TRUE(io::loadRig(dir + "/crowd.glb", &both).isOk());
    ASSERT_EQ(both.parts.size(), 2u);
    EXPECT_EQ(both.mesh.positions.size(), 8u);
    const test::CommandResult own = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + dir +
                                                     "/crowd.glb --control " + dir + "/crowd.glb -o " + dir +
                                                     "/crowd_rig.glb");
    EXPECT_NE(own.code, 0);
    EXPECT_NE(own.output.find("is placed many times by node 0 (eye) through EXT_mesh_gpu_instancing"),
              std::string::npos)
        << own.output;
    EXPECT_FALSE(std::filesystem::exists(dir + "/crowd_rig.glb"));
}

// A primitive whose normals are its faces' own (an exporter's faceted mesh,
// its vertices split at every face: Blender writes Fox so) is drawn faceted,
// as glTF draws it, like one without NORMAL; the same split mesh with
// normals that vary across its faces is drawn smooth.
TEST(Scene, NormalsThatAreTheFacesOwnDrawFlat)
{
    const std::string dir = test::tempDir("scene_faceted_normals");
    const glm::vec3 corner[4] = {{1, 1, 1}, {-1, -1, 1}, {-1, 1, -1}, {1, -1, -1}};
    const uint32_t faces[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    for (const bool faceted : {true, false}) {
        std::vector<glm::vec3> p, n;
        for (int f = 0; f < 4; ++f) {
            const glm::vec3 a = corner[faces[3 * f]], b = corner[faces[3 * f + 1]], c = corner[faces[3 * f + 2]];
            const glm::vec3 face = glm::normalize(glm::cross(b - a, c - a));
            for (const glm::vec3& q : {a, b, c}) {
                p.push_back(q);
                n.push_back(faceted ? face : glm::normalize(q));  // smooth: the sphere's normal at each corner
            }
        }
        tinygltf::Model m;
        m.asset.version = "2.0";
        m.buffers.resize(1);
        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        prim.attributes["POSITION"] = addAccessor(m, p.data(), p.size() * 12, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                  TINYGLTF_TYPE_VEC3, p.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
        m.accessors.back().minValues = {-1, -1, -1};
        m.accessors.back().maxValues = {1, 1, 1};
        prim.attributes["NORMAL"] = addAccessor(m, n.data(), n.size() * 12, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                TINYGLTF_TYPE_VEC3, n.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
        const int node = addMeshNode(m, "tetrahedron", prim);
        m.scenes.resize(1);
        m.scenes[0].nodes.push_back(node);
        m.defaultScene = 0;
        const std::string path = dir + (faceted ? "/faceted.glb" : "/smooth.glb");
        tinygltf::TinyGLTF io;
        ASSERT_TRUE(io.WriteGltfSceneToFile(&m, path, true, true, false, true));
        Rig rig;
        ASSERT_TRUE(io::loadRig(path, &rig).isOk());
        ASSERT_EQ(rig.parts.size(), 1u);
        EXPECT_EQ(rig.mesh.positions.size(), 4u) << "welded at its corners";
        EXPECT_EQ(rig.parts[0].flat, faceted) << path;
    }
}

// A character whose file keeps vertices no triangle uses (faces deleted in
// an editor, their skinned vertices left in the buffer): they are left out
// of the capture and of the character read from it alike, skin weights
// with them, so the cage still takes the character's skin and animation.
TEST(Scene, ACharactersUnusedVerticesAreLeftOutWithTheirWeights)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_unused_vertices");
    const std::string input = dir + "/cut.glb", rigPath = dir + "/rig.glb";
    {
        tinygltf::Model m;
        tinygltf::Primitive p;
        std::vector<uint32_t> idx;
        ASSERT_TRUE(takeFirstPrimitive(man, &m, &p, &idx));
        // Every fifth run of 40 faces is cut; the vertices stay.
        std::vector<uint32_t> kept;
        for (size_t f = 0; f < idx.size() / 3; ++f)
            if ((f / 40) % 5 != 0)
                kept.insert(kept.end(), &idx[3 * f], &idx[3 * f] + 3);
        p.indices = addAccessor(m, kept.data(), kept.size() * 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                TINYGLTF_TYPE_SCALAR, kept.size(), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        m.meshes[0].primitives.push_back(p);
        tinygltf::TinyGLTF io;
        ASSERT_TRUE(io.WriteGltfSceneToFile(&m, input, true, true, false, true));
    }
    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + input +
                                                   " --control auto --control-faces 400 " + kFixedMapSizeFlag + " -o " +
                                                   rigPath);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find(" vertices no triangle uses (left out)"), std::string::npos) << r.output;
    Rig source, rig;
    ASSERT_TRUE(io::loadRig(input, &source).isOk());
    ASSERT_TRUE(io::loadRig(rigPath, &rig).isOk());
    EXPECT_EQ(rig.skeleton.skin.joints.size(), source.skeleton.skin.joints.size());
    EXPECT_EQ(rig.skeleton.animations.size(), source.skeleton.animations.size());
    EXPECT_EQ(rig.skeleton.weights.joints.size(), rig.mesh.positions.size() * size_t(rig.skeleton.weights.influences));
}

// --control auto re-bakes a character's colour into one base colour texture
// (an emissive colour and its KHR_materials_emissive_strength into an
// emissive one, an occlusion texture into a metallic-roughness one's R,
// under the metallic and roughness factors it then holds) with the alpha
// mode and cutoff and sidedness of the material most of it wears, and its
// normal texture into one of the rig's own.  What that and one skinned mesh
// cannot carry (here a morph target, a camera and a point primitive) is
// named in one line, not dropped silently.
TEST(Scene, AutomaticCageNamesTheMaterialFeaturesItDoesNotCarry)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_material_features");
    tinygltf::TinyGLTF io;
    tinygltf::Model m;
    std::string err, warn;
    ASSERT_TRUE(io.LoadBinaryFromFile(&m, &err, &warn, man)) << err;
    ASSERT_EQ(m.materials.size(), 1u);
    tinygltf::Material& mat = m.materials[0];
    mat.normalTexture.index = 0;
    mat.occlusionTexture.index = 0;
    mat.emissiveFactor = {0.1, 0.0, 0.0};
    mat.pbrMetallicRoughness.metallicFactor = 0.125;
    mat.pbrMetallicRoughness.roughnessFactor = 0.25;
    mat.alphaMode = "MASK";
    mat.alphaCutoff = 0.375;
    tinygltf::Value::Object strength;
    strength["emissiveStrength"] = tinygltf::Value(2.0);
    mat.extensions["KHR_materials_emissive_strength"] = tinygltf::Value(strength);
    m.extensionsUsed.push_back("KHR_materials_emissive_strength");
    // A morph target (its position offsets: the positions themselves) and a camera.
    tinygltf::Primitive& prim = m.meshes[0].primitives[0];
    prim.targets.push_back({{"POSITION", prim.attributes.at("POSITION")}});
    m.meshes[0].weights = {0.0};
    tinygltf::Primitive points;  // and a point primitive beside the triangles
    points.mode = TINYGLTF_MODE_POINTS;
    points.attributes["POSITION"] = prim.attributes.at("POSITION");
    m.meshes[0].primitives.push_back(points);
    tinygltf::Camera camera;
    camera.type = "perspective";
    camera.perspective.yfov = 0.8;
    camera.perspective.znear = 0.1;
    m.cameras.push_back(camera);
    const std::string input = dir + "/man.glb", rigPath = dir + "/rig.glb";
    ASSERT_TRUE(io.WriteGltfSceneToFile(&m, input, true, true, false, true));
    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + input +
                                                   " --control auto --control-faces 400 " + kFixedMapSizeFlag + " -o " +
                                                   rigPath);
    ASSERT_EQ(r.code, 0) << r.output;
    const size_t at = r.output.find("not carried: ");
    ASSERT_NE(at, std::string::npos) << r.output;
    const std::string line = r.output.substr(at, r.output.find('\n', at) - at);
    for (const char* what : {"morph targets (1 primitive)", "cameras (1 camera)",
                             "point and line primitives (1 primitive)"})
        EXPECT_NE(line.find(what), std::string::npos) << what << " in " << line;
    EXPECT_EQ(line.find("normal"), std::string::npos) << line;
    // Not the control's "kept in the file": an automatic cage keeps none of them.
    EXPECT_EQ(r.output.find("kept in the file"), std::string::npos) << r.output;
    EXPECT_EQ(line.find("metallic"), std::string::npos) << line;  // one material: its factors are kept
    EXPECT_EQ(line.find("emissive colour"), std::string::npos) << line;
    EXPECT_EQ(line.find("occlusion"), std::string::npos) << line;
    EXPECT_EQ(line.find("emissive"), std::string::npos) << line;  // its strength carried too
    // The rig's material keeps the factors.
    tinygltf::Model rig;
    ASSERT_TRUE(io.LoadBinaryFromFile(&rig, &err, &warn, rigPath)) << err;
    ASSERT_FALSE(rig.materials.empty());
    const tinygltf::Material& out = rig.materials[0];
    EXPECT_EQ(out.alphaMode, "MASK");
    EXPECT_EQ(out.alphaCutoff, 0.375);
    EXPECT_GE(out.pbrMetallicRoughness.baseColorTexture.index, 0);
    EXPECT_GE(out.emissiveTexture.index, 0);
    EXPECT_GE(out.normalTexture.index, 0);
    EXPECT_EQ(out.emissiveFactor, std::vector<double>({1.0, 1.0, 1.0}));
    // The occlusion in the metallic-roughness texture's R, the factors in
    // its G and B: roughness 0.25 (64 of 255), metallic 0.125 (32); a PNG,
    // so every texel exactly.
    EXPECT_EQ(out.pbrMetallicRoughness.metallicFactor, 1.0);
    EXPECT_EQ(out.pbrMetallicRoughness.roughnessFactor, 1.0);
    ASSERT_GE(out.pbrMetallicRoughness.metallicRoughnessTexture.index, 0);
    EXPECT_EQ(out.occlusionTexture.index, out.pbrMetallicRoughness.metallicRoughnessTexture.index);
    Rig baked;
    io::SceneMaterials materials;
    ASSERT_TRUE(io::loadRig(rigPath, &baked).isOk());
    ASSERT_TRUE(io::loadSceneMaterials(baked, &materials).isOk());
    // Emission 0.1 x strength 2 = 0.2, under 1: no strength on the rig, the
    // texture's red sRGB-coded 0.2 (124) at every texel.
    EXPECT_FALSE(out.extensions.count("KHR_materials_emissive_strength"));
    const int glow = materials.materials[0].emissiveImage;
    ASSERT_GE(glow, 0);
    size_t reds = 0;
    const std::vector<uint8_t>& emitted = materials.images[size_t(glow)].rgba;
    for (size_t i = 0; i + 3 < emitted.size(); i += 4)
        reds += emitted[i] == 124 && emitted[i + 1] == 0 && emitted[i + 2] == 0;
    EXPECT_EQ(reds, emitted.size() / 4);
    const int orm = materials.materials[0].metallicRoughnessImage;
    ASSERT_GE(orm, 0);
    EXPECT_EQ(materials.materials[0].occlusionImage, orm);
    const io::ImageRGBA& image = materials.images[size_t(orm)];
    size_t factors = 0, shaded = 0;
    for (size_t i = 0; i + 3 < image.rgba.size(); i += 4) {
        factors += image.rgba[i + 1] == 64 && image.rgba[i + 2] == 32;
        shaded += image.rgba[i] < 255;
    }
    EXPECT_EQ(factors, image.rgba.size() / 4);
    EXPECT_GT(shaded, image.rgba.size() / 8) << "CesiumMan's texture, its occlusion here, is not white";
}

TEST(Scene, MultiPrimitiveNonManifoldCharacterBakesOntoItself)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_character");
    std::string input, rigPath;
    size_t finEdgeFaces = 0;
    ASSERT_TRUE(bakeCharacter(man, dir, &input, &rigPath, &finEdgeFaces));
    ASSERT_GE(finEdgeFaces, 3u) << "the fin must make its edge non-manifold";
    Rig rig;
    Status st = io::loadRig(rigPath, &rig);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(rig.parts.size(), 5u);  // three body parts, the fin, the eye
    EXPECT_EQ(rig.parts[3].faceCount, 1u);
    EXPECT_EQ(rig.parts[4].faceCount, 4u);
    EXPECT_FALSE(rig.parts[4].skinned);
    const Glb out = readGlb(rigPath);
    EXPECT_EQ(out.doc["materials"].size(), 3u);
    EXPECT_EQ(out.doc["meshes"][0]["primitives"].size(), 4u);
    EXPECT_EQ(out.doc["meshes"][1]["primitives"].size(), 1u);
    int code = 0;
    const std::string report = test::runGltfValidator({rigPath}, &code);
    EXPECT_NE(report.find("0 errors, 0 warnings"), std::string::npos) << report;

    // The atlas only served the bake: the rig stores its displacements per
    // vertex and adds no UV set (the character's own TEXCOORD_0 stays).
    EXPECT_FALSE(rigNeedsMap(rig));
    EXPECT_EQ(rig.displacement.texCoord, -1);
    DisplacementMap map;  // none needed
    EXPECT_FALSE(io::loadRigDisplacementMap(rigPath, rig, &map).isOk());
    const MeshTopologyStats s0 = computeTopologyStats(rig.mesh.triangles.data(), rig.mesh.faceCount());
    EXPECT_GE(s0.nonManifoldEdges, 1u);
    size_t split = 0;
    expectAdaptiveLayout(rig, true, 2, 4, &split);  // five parts, drawn adaptively
    tinygltf::Model source;
    // The rig's own accessors (the input's vertices, split where the new UV
    // set needs it) are the reference, read here by tinygltf.
    ASSERT_TRUE(loadPlainModel(rigPath, &source));
    const Skeleton& sk = rig.skeleton;
    ASSERT_FALSE(sk.empty());
    for (int level = 0; level <= 4; ++level) {
        SCOPED_TRACE("level " + std::to_string(level));
        io::Reconstruction rec;
        io::Pose pose;
        ASSERT_TRUE(io::reconstruct(&rec, rig, &map, Scheme::Linear, level, 1.0f, &pose).isOk());
        const MeshTopologyStats s = computeTopologyStats(rec.plan().refinedTriangles().data(), rec.plan().refinedFaceCount());
        EXPECT_EQ(s.boundaryEdges, s0.boundaryEdges << level);
        EXPECT_EQ(s.nonManifoldEdges, s0.nonManifoldEdges << level);
        EXPECT_EQ(s.eulerCharacteristic, s0.eulerCharacteristic);
        Animator animator;
        ASSERT_TRUE(animator.init(sk, rig.mesh).isOk());
        for (size_t a = 0; a < sk.animations.size(); ++a)
            for (int k = 0; k <= 4; ++k) {
                pose.animation = int(a);
                pose.time = sk.animations[a].start + (sk.animations[a].end - sk.animations[a].start) * float(k) / 4.0f;
                ASSERT_TRUE(io::reconstructPose(&rec, pose).isOk());
                for (const glm::vec3& p : rec.positions)
                    ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
                if (level != 0)
                    continue;
                // Level 0 of a self-bake is the posed control mesh: plain LBS of the file.
                const std::vector<glm::vec3> lbs = plainLbsAt(source, rig, a, pose.time);
                ASSERT_EQ(lbs.size(), rig.sourceVertex.size());
                float worst = 0.0f;
                for (size_t f = 0; f < lbs.size(); ++f)
                    worst = std::max(worst, glm::length(lbs[f] - rec.positions[rig.sourceVertex[f]]));
                EXPECT_LT(worst, 1e-4f * test::boundingBoxDiagonal(rig.mesh)) << "animation " << a << " time " << pose.time;
            }
    }
}

// glTF draws a primitive without NORMAL with face normals.  Fox has none:
// baked onto itself, its rig says its capture was drawn flat, so its parts
// (which, as every control mesh, have no NORMAL) read as flat, its render
// mesh's parts are flat, and its reconstructed scene leaves NORMAL out so
// that any viewer draws it flat too.  A rig whose layer does not say so
// (every control mesh lacks NORMAL) is drawn smooth.
TEST(Scene, AFlatShadedCaptureGivesAFlatShadedRig)
{
    STRATA_REQUIRE_DATA(fox, "Fox.glb");
    const std::string dir = test::tempDir("scene_flat");
    const std::string rigPath = dir + "/fox.glb", out = dir + "/fox_scene.glb";
    test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + fox + " --control " + fox +
                                             " --error-levels none -o " + rigPath);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("shading       flat"), std::string::npos) << r.output;
    Rig rig;
    ASSERT_TRUE(io::loadRig(rigPath, &rig).isOk());
    EXPECT_TRUE(rig.displacement.flatShading);
    ASSERT_FALSE(rig.parts.empty());
    for (const RigPart& part : rig.parts)
        EXPECT_TRUE(part.flat) << part.name;
    std::unique_ptr<Surface> surface;
    ASSERT_TRUE(Surface::create(&surface, rig, nullptr).isOk());
    io::RenderMesh layout;
    ASSERT_TRUE(io::buildRenderMesh(rig, surface->plan(), &layout).isOk());
    ASSERT_FALSE(layout.parts.empty());
    for (const io::RenderPart& part : layout.parts)
        EXPECT_TRUE(part.flat);
    r = test::runCommand(std::string(STRATA_RECONSTRUCT_EXE) + " " + rigPath + " -o " + out);
    ASSERT_EQ(r.code, 0) << r.output;
    auto expectNoNormals = [](const std::string& file) {
        tinygltf::TinyGLTF loader;
        tinygltf::Model m;
        std::string err, warn;
        ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, file)) << err;
        for (const tinygltf::Mesh& mesh : m.meshes)
            for (const tinygltf::Primitive& p : mesh.primitives)
                EXPECT_FALSE(p.attributes.count("NORMAL")) << file << ": " << mesh.name;
    };
    expectNoNormals(out);
    int code = 0;
    const std::string report = test::runGltfValidator({out}, &code);
    EXPECT_NE(report.find("0 errors, 0 warnings"), std::string::npos) << report;
    // Posed, and one view's adaptive mesh, as glTF meshes: no NORMAL either;
    // as OBJ the normals stay (data, not a shading rule).
    const std::string posed = dir + "/posed.glb", view = dir + "/view.glb", obj = dir + "/posed.obj";
    for (const std::string& args : {" --anim 0 --time 0.5 -o " + posed, " --view 0,0.5,3:0,0.3,0:40:1080 -o " + view,
                                    " --anim 0 --time 0.5 -o " + obj}) {
        r = test::runCommand(std::string(STRATA_RECONSTRUCT_EXE) + " " + rigPath + args);
        ASSERT_EQ(r.code, 0) << r.output;
    }
    expectNoNormals(posed);
    expectNoNormals(view);
    EXPECT_NE(test::readText(obj).find("\nvn "), std::string::npos);
    // That scene as the capture of a new character: still drawn flat, and
    // a capture is not warned of a layer it never needed (Strata wrote it).
    r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high " + out + " --control auto --control-faces 200 -o " +
                         dir + "/again.glb");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("shading       flat"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("displacement is gone"), std::string::npos) << r.output;
    // The same rig, its layer made smooth: the parts draw smooth.
    rig.displacement.flatShading = false;
    for (RigPart& part : rig.parts)
        part.flat = false;
    ASSERT_TRUE(io::saveRig(dir + "/smooth.glb", rig).isOk());
    Rig smooth;
    ASSERT_TRUE(io::loadRig(dir + "/smooth.glb", &smooth).isOk());
    EXPECT_FALSE(smooth.displacement.flatShading);
    for (const RigPart& part : smooth.parts)
        EXPECT_FALSE(part.flat) << part.name;
}

TEST(Scene, ReconstructedSceneIsASkinnedAnimatedCharacter)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_reconstructed");
    std::string input, rigPath;
    size_t finEdgeFaces = 0;
    ASSERT_TRUE(bakeCharacter(man, dir, &input, &rigPath, &finEdgeFaces));
    test::CommandResult r;
    Rig rig;
    ASSERT_TRUE(io::loadRig(rigPath, &rig).isOk());
    const Skeleton& sk = rig.skeleton;
    ASSERT_FALSE(sk.animations.empty());
    for (int level : {0, 2}) {
        SCOPED_TRACE("level " + std::to_string(level));
        const std::string out = dir + "/level" + std::to_string(level) + ".glb";
        r = test::runCommand(std::string(STRATA_RECONSTRUCT_EXE) + " " + rigPath + " --level " + std::to_string(level) +
                             " -o " + out);
        ASSERT_EQ(r.code, 0) << r.output;
        int code = 0;
        const std::string report = test::runGltfValidator({out}, &code);
        EXPECT_NE(report.find("0 errors, 0 warnings"), std::string::npos) << report;
        tinygltf::TinyGLTF loader;
        tinygltf::Model m;
        std::string err, warn;
        ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, out)) << err;
        EXPECT_EQ(m.materials.size(), 3u);
        EXPECT_EQ(m.skins.size(), 1u);
        EXPECT_EQ(m.animations.size(), sk.animations.size());
        EXPECT_EQ(m.images.size(), 1u) << "the texture stays, the displacement map goes";
        size_t triangles = 0;
        for (const tinygltf::Mesh& mesh : m.meshes)
            for (const tinygltf::Primitive& p : mesh.primitives) {
                triangles += m.accessors[size_t(p.indices)].count / 3;
                EXPECT_TRUE(p.attributes.count("TEXCOORD_0")) << mesh.name;
                EXPECT_TRUE(p.attributes.count("NORMAL")) << mesh.name << ": CesiumMan is drawn smooth";
            }
        EXPECT_EQ(triangles, rig.mesh.faceCount() << (2 * level));
        for (const tinygltf::Primitive& p : m.meshes[0].primitives) {
            ASSERT_TRUE(p.attributes.count("JOINTS_0") && p.attributes.count("WEIGHTS_0"));
            std::vector<float> w = accessorData<float>(m, p.attributes.at("WEIGHTS_0"), 4);
            if (p.attributes.count("WEIGHTS_1")) {
                const std::vector<float> w1 = accessorData<float>(m, p.attributes.at("WEIGHTS_1"), 4);
                for (size_t i = 0; i < w.size(); ++i)
                    w[i] += w1[i];
            }
            for (size_t v = 0; v < w.size() / 4; ++v)
                ASSERT_NEAR(w[4 * v] + w[4 * v + 1] + w[4 * v + 2] + w[4 * v + 3], 1.0f, 1e-5f);
        }
        if (level != 0)
            continue;
        // Played by plain LBS, level 0 is Strata's own posed control mesh.
        Rig written;
        ASSERT_TRUE(io::loadRig(out, &written).isOk());
        const Skeleton& wsk = written.skeleton;
        const float t = 0.5f * (wsk.animations[0].start + wsk.animations[0].end);
        const std::vector<glm::vec3> played = plainLbsAt(m, written, 0, t);
        tinygltf::Model rigModel;
        ASSERT_TRUE(loadPlainModel(rigPath, &rigModel));
        const std::vector<glm::vec3> reference = plainLbsAt(rigModel, rig, 0, t);
        // Match each played vertex to the reference vertex at the same rest
        // position (rigid parts went through their node's inverse and back:
        // equal to rounding).
        const float diag = test::boundingBoxDiagonal(rig.mesh);
        std::map<std::tuple<float, float, float>, size_t> at;
        for (size_t g = 0; g < rig.sourceVertex.size(); ++g) {
            const glm::vec3 q = rig.mesh.positions[rig.sourceVertex[g]];
            at.emplace(std::make_tuple(q.x, q.y, q.z), g);
        }
        float worst = 0.0f;
        for (size_t f = 0; f < played.size(); ++f) {
            const glm::vec3 p = written.mesh.positions[written.sourceVertex[f]];
            auto it = at.find(std::make_tuple(p.x, p.y, p.z));
            size_t g = it == at.end() ? 0 : it->second;
            if (it == at.end())
                for (size_t k = 0; k < rig.sourceVertex.size(); ++k)
                    if (glm::length(rig.mesh.positions[rig.sourceVertex[k]] - p) <
                        glm::length(rig.mesh.positions[rig.sourceVertex[g]] - p))
                        g = k;
            EXPECT_LT(glm::length(rig.mesh.positions[rig.sourceVertex[g]] - p), 1e-6f * diag);
            worst = std::max(worst, glm::length(played[f] - reference[g]));
        }
        EXPECT_LT(worst, 1e-4f * diag);
    }
}

namespace {

// The example rig with its map embedded (format version 2).
std::string writeEmbeddedExample(const std::string& dir, Rig* rig, DisplacementMap* map)
{
    test::makeExampleRig(rig, map);
    const std::string path = dir + "/example.glb";
    EXPECT_TRUE(io::saveRig(path, *rig, map).isOk());
    return path;
}

}  // namespace

TEST(Scene, EmbeddedMapRoundTripsWithinSixteenBitQuantisation)
{
    const std::string dir = test::tempDir("scene_embedded");
    Rig rig;
    DisplacementMap map;
    const std::string path = writeEmbeddedExample(dir, &rig, &map);
    Rig back;
    ASSERT_TRUE(io::loadRig(path, &back).isOk());
    EXPECT_EQ(back.displacement.encoding, "png16");
    DisplacementMap loaded;
    ASSERT_TRUE(io::loadRigDisplacementMap(path, back, &loaded).isOk());
    ASSERT_EQ(loaded.texels.size(), map.texels.size());
    float lo = map.texels[0], hi = map.texels[0], worst = 0.0f;
    for (float t : map.texels) {
        lo = std::min(lo, t);
        hi = std::max(hi, t);
    }
    // Every texel the runtime reads (those around the UV triangles; the
    // writer fills the rest as runs) is within half a step of eq. 12 at 16
    // bits, plus float rounding in the decode.
    const float bound = 0.5f * (hi - lo) / 65535.0f + 4.0f * 1.2e-7f * std::max(std::fabs(lo), std::fabs(hi));
    size_t checked = 0;
    for (size_t f = 0; f < rig.mesh.faceCount(); ++f) {
        glm::vec2 c(0.0f);
        for (int k = 0; k < 3; ++k)
            c += rig.mesh.uvs[rig.mesh.uvIndices[3 * f + size_t(k)]] / 3.0f;
        const size_t i = size_t(c.y * float(map.height)) * size_t(map.width) + size_t(c.x * float(map.width));
        worst = std::max(worst, std::fabs(loaded.texels[i] * loaded.factor + loaded.offset -
                                          (map.texels[i] * map.factor + map.offset)));
        ++checked;
    }
    EXPECT_EQ(checked, rig.mesh.faceCount());
    EXPECT_LE(worst, bound);
    // And what the runtime samples at level 3 agrees to the same bound.
    std::unique_ptr<Plan> a, b;
    ASSERT_TRUE(Plan::create(&a, rig.mesh, Scheme::Linear, 3).isOk());
    ASSERT_TRUE(Plan::create(&b, back.mesh, Scheme::Linear, 3).isOk());
    ASSERT_TRUE(a->setDisplacement(map).isOk());
    ASSERT_TRUE(b->setDisplacement(loaded).isOk());
    ASSERT_EQ(a->displacements().size(), b->displacements().size());
    for (size_t v = 0; v < a->displacements().size(); ++v)
        ASSERT_NEAR(a->displacements()[v], b->displacements()[v], bound) << v;
}

TEST(Scene, StrippedRigsFailLoudlyOrWarn)
{
    const std::string dir = test::tempDir("scene_stripped");
    Rig rig;
    DisplacementMap map;
    const std::string path = writeEmbeddedExample(dir, &rig, &map);
    tinygltf::TinyGLTF io;
    tinygltf::Model m;
    std::string err, warn;
    ASSERT_TRUE(io.LoadBinaryFromFile(&m, &err, &warn, path)) << err;
    // UVs stripped, block kept: an error naming what is missing.
    tinygltf::Model noUV = m;
    noUV.meshes[0].primitives[0].attributes.erase("TEXCOORD_0");
    ASSERT_TRUE(io.WriteGltfSceneToFile(&noUV, dir + "/nouv.glb", true, true, false, true));
    Rig out;
    Status st = io::loadRig(dir + "/nouv.glb", &out);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("TEXCOORD_0"), std::string::npos) << st.message();
    // The map image gone: an error naming the map.
    tinygltf::Model noImage = m;
    noImage.images.clear();
    ASSERT_TRUE(io.WriteGltfSceneToFile(&noImage, dir + "/noimage.glb", true, true, false, true));
    st = io::loadRig(dir + "/noimage.glb", &out);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("map is missing"), std::string::npos) << st.message();
    // The layer stripped from a Strata file, its declaration kept: loads
    // plain, with a warning that the displacement is gone.
    tinygltf::Model noBlock = m;
    noBlock.meshes[0].extensions.erase(io::kLayerExtension);
    ASSERT_TRUE(io.WriteGltfSceneToFile(&noBlock, dir + "/noblock.glb", true, true, false, true));
    ASSERT_TRUE(io::loadRig(dir + "/noblock.glb", &out).isOk());
    EXPECT_FALSE(out.hasDisplacement);
    ASSERT_EQ(out.warnings.size(), 1u);
    EXPECT_NE(out.warnings[0].find("declares STRATA_layered_displacement but no mesh carries the layer"),
              std::string::npos)
        << out.warnings[0];
    EXPECT_NE(io::missingLayerCause(out).find("a tool dropped it"), std::string::npos);
    // ... and its declaration too: Strata's generator is the trace left.
    noBlock.extensionsUsed.clear();
    noBlock.asset.generator = "Strata 0.5";
    ASSERT_TRUE(io.WriteGltfSceneToFile(&noBlock, dir + "/noblock2.glb", true, true, false, true));
    ASSERT_TRUE(io::loadRig(dir + "/noblock2.glb", &out).isOk());
    ASSERT_EQ(out.warnings.size(), 1u);
    EXPECT_NE(out.warnings[0].find("the displacement is gone"), std::string::npos) << out.warnings[0];
    // A surface Strata reconstructed never had a layer: it loads (as a
    // capture or a cage) without the warning, and a tool that needs a rig
    // says what it is rather than that a layer was stripped.
    io::MeshView view;
    view.positions = rig.mesh.positions.data();
    view.vertexCount = rig.mesh.positions.size();
    view.triangles = rig.mesh.triangles.data();
    view.faceCount = rig.mesh.faceCount();
    ASSERT_TRUE(io::writeMesh(dir + "/surface.glb", view).isOk());
    ASSERT_TRUE(io::loadRig(dir + "/surface.glb", &out).isOk());
    EXPECT_FALSE(out.hasDisplacement);
    EXPECT_TRUE(out.warnings.empty()) << out.warnings[0];
    EXPECT_NE(io::missingLayerCause(out).find("a displaced surface Strata reconstructed"), std::string::npos)
        << io::missingLayerCause(out);
}

// A rig placed elsewhere as a whole by its node since the bake
// (gltf-transform center, an editor): glTF draws the displaced surface
// through the node, so Strata draws it moved, turned and scaled with it, its
// displacements scaled too, in both the map and the per-vertex codings.
// Such files were refused as "vertices moved after the bake".  A node that
// scales unevenly would bend the surface out of its baked shape: refused.
TEST(Scene, ARigPlacedWholeByItsNodeDrawsItsSurfaceThere)
{
    const std::string dir = test::tempDir("scene_placed");
    Rig rig;
    DisplacementMap map;
    const std::string mapRig = writeEmbeddedExample(dir, &rig, &map);
    io::RigWriteOptions vertexCoded;
    vertexCoded.vertexDisplacements = true;
    const std::string vertexRig = dir + "/vertex.glb";
    ASSERT_TRUE(io::saveRig(vertexRig, rig, &map, nullptr, &vertexCoded).isOk());
    const glm::quat turn = glm::angleAxis(0.7f, glm::normalize(glm::vec3(1.0f, 2.0f, -0.5f)));
    const glm::vec3 move(3.0f, -1.0f, 0.25f);
    const float scale = 2.5f;
    const glm::mat4 M = glm::translate(glm::mat4(1.0f), move) * glm::mat4_cast(turn) *
                        glm::scale(glm::mat4(1.0f), glm::vec3(scale));
    for (const std::string& path : {mapRig, vertexRig}) {
        SCOPED_TRACE(path);
        tinygltf::TinyGLTF io;
        tinygltf::Model m;
        std::string err, warn;
        ASSERT_TRUE(io.LoadBinaryFromFile(&m, &err, &warn, path)) << err;
        ASSERT_EQ(m.nodes.size(), 1u);
        m.nodes[0].translation = {move.x, move.y, move.z};
        m.nodes[0].rotation = {turn.x, turn.y, turn.z, turn.w};
        m.nodes[0].scale = {scale, scale, scale};
        const std::string placed = dir + "/placed.glb";
        ASSERT_TRUE(io.WriteGltfSceneToFile(&m, placed, true, true, false, true));
        Rig a, b;
        ASSERT_TRUE(io::loadRig(path, &a).isOk());
        Status st = io::loadRig(placed, &b);
        ASSERT_TRUE(st.isOk()) << st.message();
        DisplacementMap ma, mb;
        if (rigNeedsMap(a)) {
            ASSERT_TRUE(io::loadRigDisplacementMap(path, a, &ma).isOk());
            ASSERT_TRUE(io::loadRigDisplacementMap(placed, b, &mb).isOk());
        }
        io::Reconstruction ra, rb;
        ASSERT_TRUE(io::reconstruct(&ra, a, &ma, Scheme::Linear, 3).isOk());
        ASSERT_TRUE(io::reconstruct(&rb, b, &mb, Scheme::Linear, 3).isOk());
        ASSERT_EQ(ra.positions.size(), rb.positions.size());
        // The displacement is no small part of the surface: without its
        // scale, the placed surface would be this far off.
        float displaced = 0.0f, worst = 0.0f, size = 0.0f;
        io::Reconstruction bare;
        ASSERT_TRUE(io::reconstruct(&bare, a, nullptr, Scheme::Linear, 3).isOk());
        for (size_t v = 0; v < ra.positions.size(); ++v) {
            const glm::vec3 expected(M * glm::vec4(ra.positions[v], 1.0f));
            worst = std::max(worst, glm::length(rb.positions[v] - expected));
            displaced = std::max(displaced, glm::length(ra.positions[v] - bare.positions[v]));
            size = std::max(size, glm::length(expected - move));
        }
        EXPECT_GT((scale - 1.0f) * displaced, 1e-2f * size);
        EXPECT_LE(worst, 1e-5f * size);
        // Scaled unevenly: refused, naming the node.
        m.nodes[0].scale = {scale, 1.0, 1.0};
        ASSERT_TRUE(io.WriteGltfSceneToFile(&m, placed, true, true, false, true));
        st = io::loadRig(placed, &b);
        ASSERT_FALSE(st.isOk());
        EXPECT_NE(st.message().find("scale the rig unevenly"), std::string::npos) << st.message();
        // Mirrored: its faces turn over, and the refinement's numbering with
        // them, so it is refused, by name.
        m.nodes[0].scale = {-scale, -scale, -scale};
        ASSERT_TRUE(io.WriteGltfSceneToFile(&m, placed, true, true, false, true));
        st = io::loadRig(placed, &b);
        ASSERT_FALSE(st.isOk());
        EXPECT_NE(st.message().find("mirror the rig"), std::string::npos) << st.message();
    }
}

// A rig merged with another model (gltf-transform merge): in a scene of its
// own, which a glTF viewer shows alone, the rig is read as before and the
// other scene's mesh named; in one scene with it, the refusal names the
// other model, where it blamed a weld or a simplification.
TEST(Scene, ARigMergedWithAnotherModelIsReadInItsSceneOrRefusedByName)
{
    const std::string dir = test::tempDir("scene_merged");
    Rig rig;
    DisplacementMap map;
    const std::string path = writeEmbeddedExample(dir, &rig, &map);
    tinygltf::TinyGLTF io;
    tinygltf::Model m;
    std::string err, warn;
    ASSERT_TRUE(io.LoadBinaryFromFile(&m, &err, &warn, path)) << err;
    // Another model: the rig's first triangle, far away, plain.
    tinygltf::Mesh other;
    other.name = "floor";
    tinygltf::Primitive prim;
    prim.attributes["POSITION"] = m.meshes[0].primitives[0].attributes.at("POSITION");
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    other.primitives.push_back(prim);
    m.meshes.push_back(other);
    tinygltf::Node node;
    node.mesh = int(m.meshes.size()) - 1;
    node.translation = {100.0, 0.0, 0.0};
    m.nodes.push_back(node);
    tinygltf::Scene second;
    second.nodes.push_back(int(m.nodes.size()) - 1);
    m.scenes.push_back(second);
    ASSERT_TRUE(io.WriteGltfSceneToFile(&m, dir + "/scenes.glb", true, true, false, true));
    Rig a, b;
    ASSERT_TRUE(io::loadRig(path, &a).isOk());
    Status st = io::loadRig(dir + "/scenes.glb", &b);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(b.mesh.positions, a.mesh.positions);
    ASSERT_EQ(b.warnings.size(), 1u);
    EXPECT_NE(b.warnings[0].find("another scene"), std::string::npos) << b.warnings[0];
    // Both in the default scene.
    m.scenes[0].nodes.push_back(int(m.nodes.size()) - 1);
    m.scenes.pop_back();
    ASSERT_TRUE(io.WriteGltfSceneToFile(&m, dir + "/one.glb", true, true, false, true));
    st = io::loadRig(dir + "/one.glb", &b);
    ASSERT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("mesh 1 (floor) beside the layered mesh"), std::string::npos) << st.message();
}

TEST(Scene, QuantizedGltfpackOutputLoadsInPlace)
{
    if (std::system("command -v gltfpack >/dev/null 2>&1") != 0)
        GTEST_FAIL() << "gltfpack is not installed (cmake/install-deps.sh installs it)";
    const std::string dir = test::tempDir("scene_gltfpack");
    Rig rig;
    DisplacementMap map;
    const std::string path = writeEmbeddedExample(dir, &rig, &map);
    const test::CommandResult r = test::runCommand("gltfpack -i '" + path + "' -o '" + dir + "/packed.glb'");
    ASSERT_EQ(r.code, 0) << r.output;
    ASSERT_NE(test::readText(dir + "/packed.glb").find("KHR_mesh_quantization"), std::string::npos);
    Rig packed;
    const Status st = io::loadRig(dir + "/packed.glb", &packed);
    ASSERT_TRUE(st.isOk()) << st.message();
    // gltfpack drops mesh extras (the block) but keeps the map image: the
    // loader says what it suspects instead of reconstructing silently.
    if (!packed.hasDisplacement) {
        ASSERT_EQ(packed.warnings.size(), 1u);
        EXPECT_NE(packed.warnings[0].find("dropped the layer"), std::string::npos) << packed.warnings[0];
    }
    // Integer positions with the dequantisation on the node: the same surface
    // to gltfpack's 14-bit precision.
    const float diag = test::boundingBoxDiagonal(rig.mesh);
    ASSERT_EQ(packed.mesh.faceCount(), rig.mesh.faceCount());
    for (const glm::vec3& p : packed.mesh.positions) {
        float best = 1e30f;
        for (const glm::vec3& q : rig.mesh.positions)
            best = std::min(best, glm::length(p - q));
        EXPECT_LT(best, 2e-4f * diag);
    }
}

namespace {

// A glTF file as tinygltf reads it, to edit.
::testing::AssertionResult readModel(const std::string& path, tinygltf::Model* model)
{
    tinygltf::TinyGLTF gltf;
    std::string err, warn;
    if (!gltf.LoadBinaryFromFile(model, &err, &warn, path))
        return ::testing::AssertionFailure() << path << ": " << err;
    return ::testing::AssertionSuccess();
}

// An edited model written to `path`, then read back as a rig and its
// materials, as the bake reads a capture's.
::testing::AssertionResult writeAndReadMaterials(tinygltf::Model& model, const std::string& path, Rig* rig,
                                                 io::SceneMaterials* materials,
                                                 std::vector<std::string>* warnings = nullptr)
{
    tinygltf::TinyGLTF gltf;
    if (!gltf.WriteGltfSceneToFile(&model, path, true, true, false, true))
        return ::testing::AssertionFailure() << "cannot write " << path;
    if (Status st = io::loadRig(path, rig); !st)
        return ::testing::AssertionFailure() << st.message();
    if (Status st = io::loadSceneMaterials(*rig, materials, warnings); !st)
        return ::testing::AssertionFailure() << st.message();
    return ::testing::AssertionSuccess();
}

// A file's model to edit, and its rig and materials as read unedited
// (written back first, as the edits will be).
::testing::AssertionResult readToEdit(const std::string& source, const std::string& dir, tinygltf::Model* model,
                                      Rig* rig, io::SceneMaterials* materials)
{
    ::testing::AssertionResult read = readModel(source, model);
    return read ? writeAndReadMaterials(*model, dir + "/unedited.glb", rig, materials) : read;
}

}  // namespace

// KHR_texture_transform, as its specification's example reads: offset
// (0, 1), a quarter turn and half the scale draw the unit square from the
// image's lower-left quadrant, turned; a file's transform (and its texCoord)
// reaches every vertex's UV, and a malformed one is named and ignored.
TEST(Scene, TextureTransformsMoveTheUVsTheTextureReads)
{
    io::MaterialInfo m;
    m.uvOffset = glm::vec2(0.0f, 1.0f);
    m.uvRotation = 1.57079632679f;
    m.uvScale = glm::vec2(0.5f);
    const glm::vec2 corners[4][2] = {{{0, 0}, {0, 1}}, {{1, 0}, {0, 0.5f}}, {{0, 1}, {0.5f, 1}}, {{1, 1}, {0.5f, 0.5f}}};
    for (const auto& c : corners) {
        EXPECT_NEAR(m.textureUV(c[0]).x, c[1].x, 1e-6f);
        EXPECT_NEAR(m.textureUV(c[0]).y, c[1].y, 1e-6f);
    }

    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_texture_transform");
    tinygltf::Model model;
    Rig plain;
    io::SceneMaterials before;
    ASSERT_TRUE(readToEdit(man, dir, &model, &plain, &before));
    // CesiumMan's sampler repeats (glTF's default); a sampler that mirrors
    // along u and clamps along v is read so.
    EXPECT_EQ(before.materials[0].wrapS, io::TextureWrap::Repeat);
    EXPECT_EQ(before.materials[0].wrapT, io::TextureWrap::Repeat);
    tinygltf::Sampler sampler;
    sampler.wrapS = TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT;
    sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    model.samplers.push_back(sampler);
    model.textures[size_t(model.materials[0].pbrMetallicRoughness.baseColorTexture.index)].sampler =
        int(model.samplers.size() - 1);
    tinygltf::Value::Object t;
    t["offset"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(0.25), tinygltf::Value(-0.5)});
    t["scale"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(2.0), tinygltf::Value(3.0)});
    t["rotation"] = tinygltf::Value(0.5);
    model.materials[0].pbrMetallicRoughness.baseColorTexture.extensions["KHR_texture_transform"] = tinygltf::Value(t);
    model.extensionsUsed.push_back("KHR_texture_transform");
    Rig moved;
    io::SceneMaterials after;
    std::vector<std::string> warnings;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/moved.glb", &moved, &after, &warnings));
    EXPECT_TRUE(warnings.empty());
    const io::MaterialInfo& mat = after.materials[0];
    EXPECT_EQ(mat.uvScale, glm::vec2(2.0f, 3.0f));
    EXPECT_EQ(mat.wrapS, io::TextureWrap::MirroredRepeat);
    EXPECT_EQ(mat.wrapT, io::TextureWrap::ClampToEdge);
    ASSERT_EQ(after.fileUVs.size(), before.fileUVs.size());
    for (size_t v = 0; v < after.fileUVs.size(); v += 97) {
        const glm::vec2 s = glm::vec2(2.0f, 3.0f) * before.fileUVs[v];
        const glm::vec2 expected(0.25f + std::cos(0.5f) * s.x + std::sin(0.5f) * s.y,
                                 -0.5f - std::sin(0.5f) * s.x + std::cos(0.5f) * s.y);
        EXPECT_NEAR(after.fileUVs[v].x, expected.x, 1e-5f) << v;
        EXPECT_NEAR(after.fileUVs[v].y, expected.y, 1e-5f) << v;
    }
    // Not numbers: named once, and the UVs read as they are.
    t["scale"] = tinygltf::Value(std::string("big"));
    model.materials[0].pbrMetallicRoughness.baseColorTexture.extensions["KHR_texture_transform"] = tinygltf::Value(t);
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/bad.glb", &moved, &after, &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("KHR_texture_transform is not numbers"), std::string::npos) << warnings[0];
    EXPECT_EQ(after.fileUVs[5], before.fileUVs[5]);
}

namespace {

// An image as a lossless AVIF (4:4:4 with the identity matrix at quantiser
// 0, as avifenc --lossless writes it); empty where libavif cannot encode.
std::vector<unsigned char> losslessAvif(const io::ImageRGBA& in)
{
    avifImage* image = avifImageCreate(uint32_t(in.width), uint32_t(in.height), 8, AVIF_PIXEL_FORMAT_YUV444);
    image->matrixCoefficients = AVIF_MATRIX_COEFFICIENTS_IDENTITY;
    image->yuvRange = AVIF_RANGE_FULL;
    avifRGBImage rgb;
    avifRGBImageSetDefaults(&rgb, image);
    rgb.format = AVIF_RGB_FORMAT_RGBA;
    rgb.depth = 8;
    std::vector<uint8_t> pixels(in.rgba.begin(), in.rgba.end());
    rgb.pixels = pixels.data();
    rgb.rowBytes = uint32_t(4 * in.width);
    std::vector<unsigned char> out;
    avifEncoder* encoder = avifEncoderCreate();
    encoder->minQuantizer = encoder->maxQuantizer = AVIF_QUANTIZER_LOSSLESS;
    encoder->speed = 9;
    avifRWData data = AVIF_DATA_EMPTY;
    if (avifImageRGBToYUV(image, &rgb) == AVIF_RESULT_OK && avifEncoderWrite(encoder, image, &data) == AVIF_RESULT_OK)
        out.assign(data.data, data.data + data.size);
    avifRWDataFree(&data);
    avifEncoderDestroy(encoder);
    avifImageDestroy(image);
    return out;
}

// `bytes` as a new image of `model`, which texture `texture` reaches only
// through `extension` (as glTF Transform's webp and avif leave it).
void onlyThroughExtension(tinygltf::Model& model, int texture, const std::string& extension,
                          const std::vector<unsigned char>& bytes, const std::string& mime)
{
    tinygltf::Buffer& buffer = model.buffers[0];
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = buffer.data.size();
    view.byteLength = bytes.size();
    buffer.data.insert(buffer.data.end(), bytes.begin(), bytes.end());
    model.bufferViews.push_back(view);
    tinygltf::Image image;
    image.bufferView = int(model.bufferViews.size()) - 1;
    image.mimeType = mime;
    model.images.push_back(image);
    tinygltf::Value::Object o;
    o["source"] = tinygltf::Value(int(model.images.size()) - 1);
    tinygltf::Texture& t = model.textures[size_t(texture)];
    t.extensions.clear();
    t.extensions[extension] = tinygltf::Value(o);
    t.source = -1;
    for (std::vector<std::string>* list : {&model.extensionsUsed, &model.extensionsRequired})
        if (std::find(list->begin(), list->end(), extension) == list->end())
            list->push_back(extension);
}

}  // namespace

// A base colour texture whose image only EXT_texture_webp or
// EXT_texture_avif names (glTF Transform's optimize, webp and avif write
// them so) is decoded: CesiumMan's texture as a lossless WebP and as a
// lossless AVIF reads back as its JPEG decodes, texel for texel.  (They
// were drawn in their factor alone, white, and named.)  An AVIF whose
// container claims 65536^2 texels is refused before any AV1 is decoded,
// and named.  One only another extension names (KTX2 under
// KHR_texture_basisu) cannot be read: drawn in its factor, and the warning
// names the extension.
TEST(Scene, WebPAndAvifTexturesAreReadAndOtherExtensionsAreNamed)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_texture_extension");
    tinygltf::Model model;
    ASSERT_TRUE(readModel(man, &model));
    Rig original;
    io::SceneMaterials before;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/man.glb", &original, &before));
    const int image = before.materials[0].image;
    ASSERT_GE(image, 0);
    const io::ImageRGBA& jpeg = before.images[size_t(image)];
    uint8_t* webpBytes = nullptr;
    const size_t webpSize =
        WebPEncodeLosslessRGBA(jpeg.rgba.data(), jpeg.width, jpeg.height, 4 * jpeg.width, &webpBytes);
    ASSERT_GT(webpSize, 0u);
    const std::vector<unsigned char> webp(webpBytes, webpBytes + webpSize);
    WebPFree(webpBytes);
    const std::vector<unsigned char> avif = losslessAvif(jpeg);
    ASSERT_FALSE(avif.empty()) << "libavif encodes no AVIF here";
    const int texture = model.materials[0].pbrMetallicRoughness.baseColorTexture.index;
    const tinygltf::Model jpegModel = model;
    for (const auto& [extension, bytes, mime] :
         {std::make_tuple("EXT_texture_webp", webp, "image/webp"),
          std::make_tuple("EXT_texture_avif", avif, "image/avif")}) {
        SCOPED_TRACE(extension);
        model = jpegModel;
        onlyThroughExtension(model, texture, extension, bytes, mime);
        Rig rig;
        io::SceneMaterials materials;
        std::vector<std::string> warnings;
        ASSERT_TRUE(writeAndReadMaterials(model, dir + "/" + extension + ".glb", &rig, &materials, &warnings));
        EXPECT_TRUE(warnings.empty()) << warnings[0];
        const int read = materials.materials[0].image;
        ASSERT_GE(read, 0);
        EXPECT_EQ(materials.images[size_t(read)].width, jpeg.width);
        EXPECT_EQ(materials.images[size_t(read)].height, jpeg.height);
        EXPECT_TRUE(materials.images[size_t(read)].rgba == jpeg.rgba);
        EXPECT_EQ(io::featuresNotCarried(rig, 0, &materials), "");
    }
    // The AVIF's image spatial extent ('ispe': version and flags, then
    // width and height) made 65536^2.
    std::vector<unsigned char> huge = avif;
    const auto ispe = std::search(huge.begin(), huge.end(), std::begin("ispe"), std::end("ispe") - 1);
    ASSERT_NE(ispe, huge.end());
    ASSERT_LT(size_t(ispe - huge.begin()) + 16, huge.size());
    for (int k = 0; k < 8; ++k)
        ispe[8 + k] = (k % 4 == 1) ? 1 : 0;  // 0x00010000 each
    // Each drawn in its factor alone, with one warning saying why.
    const auto refused = [&](const char* extension, const std::vector<unsigned char>& bytes, const char* mime,
                             const std::string& file, const std::string& why) {
        SCOPED_TRACE(file);
        model = jpegModel;
        onlyThroughExtension(model, texture, extension, bytes, mime);
        Rig rig;
        io::SceneMaterials materials;
        std::vector<std::string> warnings;
        ASSERT_TRUE(writeAndReadMaterials(model, dir + "/" + file, &rig, &materials, &warnings));
        EXPECT_EQ(materials.materials[0].image, -1);
        ASSERT_EQ(warnings.size(), 1u);
        EXPECT_NE(warnings[0].find(why), std::string::npos) << warnings[0];
    };
    refused("EXT_texture_avif", huge, "image/avif", "huge.glb",
            "image 1 () cannot be decoded; drawn untextured (a broken avif");
    // KTX2 (here its extension over the same image): named, not read.
    refused("KHR_texture_basisu", webp, "image/webp", "ktx2.glb",
            "its base colour texture is only in KHR_texture_basisu, an image Strata does not decode");
}

// A PNG whose IDAT chunk declares 1.7 GB in a file of a few hundred bytes
// (what fuzz_rig found: stb_image grows its buffer to a chunk's declared
// length before reading it, and asked for 1.7 GB) is named and drawn
// untextured, as is an image that is neither PNG nor JPEG (a BMP, which
// stb would decode but glTF does not have).
TEST(Scene, AnImageWhoseChunkRunsPastItsBytesIsNamed)
{
    const std::string dir = test::tempDir("scene_png_chunks");
    ASSERT_TRUE(test::writeColouredSphere(dir + "/sphere.glb", test::SphereColour::HalfTexture));
    tinygltf::Model model;
    Rig rig;
    io::SceneMaterials before;
    ASSERT_TRUE(readToEdit(dir + "/sphere.glb", dir, &model, &rig, &before));
    ASSERT_GE(before.materials[0].image, 0);
    const tinygltf::BufferView& view = model.bufferViews[size_t(model.images[0].bufferView)];
    unsigned char* png = model.buffers[0].data.data() + view.byteOffset;
    EXPECT_TRUE(io::pngChunksFit(png, view.byteLength));
    // The IDAT chunk's length becomes 0x68000016.
    size_t at = 8;
    while (at + 12 <= view.byteLength && std::string(reinterpret_cast<const char*>(png) + at + 4, 4) != "IDAT")
        at += 12 + (size_t(png[at]) << 24 | size_t(png[at + 1]) << 16 | size_t(png[at + 2]) << 8 | png[at + 3]);
    ASSERT_LE(at + 12, view.byteLength);
    const unsigned char hostile[4] = {0x68, 0x00, 0x00, 0x16};
    std::copy(hostile, hostile + 4, png + at);
    EXPECT_FALSE(io::pngChunksFit(png, view.byteLength));
    io::SceneMaterials after;
    std::vector<std::string> warnings;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/hostile.glb", &rig, &after, &warnings));
    EXPECT_EQ(after.materials[0].image, -1);
    ASSERT_FALSE(warnings.empty());
    EXPECT_NE(warnings[0].find("image 0 () cannot be decoded; drawn untextured (a broken png"), std::string::npos)
        << warnings[0];
    // A BMP in its place: not glTF's, not read.
    const unsigned char bmp[2] = {'B', 'M'};
    std::copy(bmp, bmp + 2, png);
    warnings.clear();
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/bmp.glb", &rig, &after, &warnings));
    EXPECT_EQ(after.materials[0].image, -1);
    ASSERT_FALSE(warnings.empty());
    EXPECT_NE(warnings[0].find("(not PNG, JPEG, WebP or AVIF)"), std::string::npos) << warnings[0];
}

// A material in KHR_materials_pbrSpecularGlossiness (older exports, many of
// Sketchfab's): its diffuse colour and texture are read as the base colour,
// where the colour was left white.
TEST(Scene, ASpecularGlossinessMaterialsDiffuseIsItsColour)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_specular_glossiness");
    tinygltf::Model model;
    Rig plain;
    io::SceneMaterials before;
    ASSERT_TRUE(readToEdit(man, dir, &model, &plain, &before));
    tinygltf::Material& mat = model.materials[0];
    tinygltf::Value::Object texture, sg;
    texture["index"] = tinygltf::Value(mat.pbrMetallicRoughness.baseColorTexture.index);
    sg["diffuseTexture"] = tinygltf::Value(texture);
    sg["diffuseFactor"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(1.0), tinygltf::Value(0.5),
                                                                 tinygltf::Value(0.25), tinygltf::Value(1.0)});
    mat.extensions["KHR_materials_pbrSpecularGlossiness"] = tinygltf::Value(sg);
    mat.pbrMetallicRoughness.baseColorTexture = tinygltf::TextureInfo();
    model.extensionsUsed.push_back("KHR_materials_pbrSpecularGlossiness");
    Rig rig;
    io::SceneMaterials after;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/sg.glb", &rig, &after));
    EXPECT_EQ(after.materials[0].image, before.materials[0].image);
    EXPECT_GE(after.materials[0].image, 0);
    EXPECT_EQ(after.materials[0].baseColor, glm::vec4(1.0f, 0.5f, 0.25f, 1.0f));
    EXPECT_EQ(after.fileUVs, before.fileUVs);
    EXPECT_NE(io::featuresNotCarried(rig, 0).find("its diffuse carried"), std::string::npos)
        << io::featuresNotCarried(rig, 0);
}

// A material's metallic-roughness, emissive and occlusion textures are read
// through its base colour texture's UVs where they share its set and
// transform, through a second channel where they do not; one on a third
// set or transform is counted, and named among what is not carried.
TEST(Scene, MetallicRoughnessAndEmissiveTexturesAreRead)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_pbr_textures");
    tinygltf::Model model;
    Rig plain;
    io::SceneMaterials before;
    ASSERT_TRUE(readToEdit(man, dir, &model, &plain, &before));
    tinygltf::Material& mat = model.materials[0];
    const int texture = mat.pbrMetallicRoughness.baseColorTexture.index;
    ASSERT_GE(texture, 0);
    mat.pbrMetallicRoughness.metallicRoughnessTexture.index = texture;
    mat.emissiveTexture.index = texture;
    mat.emissiveFactor = {1.0, 0.5, 0.25};
    mat.occlusionTexture.index = texture;
    mat.occlusionTexture.strength = 0.5;
    Rig rig;
    io::SceneMaterials after;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/pbr.glb", &rig, &after));
    const io::MaterialInfo& m = after.materials[0];
    EXPECT_EQ(m.metallicRoughnessImage, m.image);
    EXPECT_EQ(m.emissiveImage, m.image);
    EXPECT_EQ(m.occlusionImage, m.image);
    EXPECT_EQ(m.occlusionStrength, 0.5f);
    EXPECT_EQ(m.emissive, glm::vec3(1.0f, 0.5f, 0.25f));
    EXPECT_EQ(m.unreadTextures, 0);
    EXPECT_EQ(after.fileUVs, before.fileUVs);
    // The texture's texel at a UV, through each reading.
    const io::ImageRGBA& image = after.images[size_t(m.image)];
    const glm::dvec2 uv = glm::dvec2(after.fileUVs[7]);
    const glm::dvec4 t = io::sampleImage(image, uv);
    const glm::dvec2 mr = io::metallicRoughnessAt(m, &image, uv);
    EXPECT_NEAR(mr.x, m.metallic * t.b, 1e-12);
    EXPECT_NEAR(mr.y, m.roughness * t.g, 1e-12);
    EXPECT_NEAR(io::emissiveAt(m, &image, uv).g, 0.5 * io::srgbToLinear(t.g), 1e-6);
    EXPECT_NEAR(io::occlusionAt(m, &image, uv), 1.0 + 0.5 * (t.r - 1.0), 1e-12);
    EXPECT_EQ(io::featuresNotCarried(rig, 0, &after).find("metallic-roughness"), std::string::npos);
    // The same UVs through another sampler (clamped): the second channel,
    // with that sampler's wraps.
    const int image0 = m.image;
    tinygltf::Sampler clamp;
    clamp.wrapS = clamp.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    model.samplers.push_back(clamp);
    tinygltf::Texture clamped = model.textures[size_t(texture)];
    clamped.sampler = int(model.samplers.size()) - 1;
    model.textures.push_back(clamped);
    mat.occlusionTexture.index = int(model.textures.size()) - 1;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/clamped.glb", &rig, &after));
    EXPECT_EQ(after.materials[0].occlusionImage, image0);
    EXPECT_EQ(after.materials[0].occlusionChannel, 1);
    EXPECT_EQ(after.materials[0].second.wrapS, io::TextureWrap::ClampToEdge);
    EXPECT_NE(after.materials[0].wrapS, io::TextureWrap::ClampToEdge);
    EXPECT_EQ(after.fileUVs2, before.fileUVs);
    mat.occlusionTexture.index = texture;
    // On another UV set: read through the second channel, that set's UVs.
    mat.emissiveTexture.texCoord = 1;
    for (tinygltf::Primitive& prim : model.meshes[0].primitives)
        prim.attributes["TEXCOORD_1"] = prim.attributes.at("TEXCOORD_0");
    std::vector<std::string> warnings;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/other_set.glb", &rig, &after, &warnings));
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    EXPECT_EQ(after.materials[0].emissiveImage, image0);
    EXPECT_EQ(after.materials[0].emissiveChannel, 1);
    EXPECT_EQ(after.materials[0].occlusionChannel, 0);
    EXPECT_TRUE(after.materials[0].hasSecond);
    EXPECT_EQ(after.materials[0].unreadTextures, 0);
    EXPECT_EQ(after.fileUVs2, before.fileUVs);
    // A third set or transform: not read, and named.
    tinygltf::Value::Object shift;
    shift["offset"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(0.5), tinygltf::Value(0.0)});
    mat.occlusionTexture.texCoord = 1;
    mat.occlusionTexture.extensions["KHR_texture_transform"] = tinygltf::Value(shift);
    model.extensionsUsed.push_back("KHR_texture_transform");
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/third.glb", &rig, &after));
    EXPECT_EQ(after.materials[0].emissiveImage, image0);
    EXPECT_EQ(after.materials[0].occlusionImage, -1);
    EXPECT_EQ(after.materials[0].unreadTextures, 1);
    EXPECT_NE(io::featuresNotCarried(rig, 0, &after)
                  .find("metallic-roughness, emissive, occlusion or normal textures on a third UV set or "
                        "transform, or not decoded (1 material)"),
              std::string::npos)
        << io::featuresNotCarried(rig, 0, &after);
}

// COLOR_0 as exporters write it (normalized unsigned bytes, RGB) is read
// as linear RGBA per file vertex, alpha 1; one that is not a colour per
// vertex is named and ignored.  A second set is named as not carried.
TEST(Scene, VertexColoursAreRead)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_vertex_colours");
    tinygltf::Model model;
    Rig plain;
    io::SceneMaterials before;
    ASSERT_TRUE(readToEdit(man, dir, &model, &plain, &before));
    EXPECT_TRUE(before.fileColours.empty());
    tinygltf::Primitive& prim = model.meshes[0].primitives[0];
    const size_t n = model.accessors[size_t(prim.attributes.at("POSITION"))].count;
    std::vector<uint8_t> rgb;
    for (size_t v = 0; v < n; ++v)
        for (uint8_t c : {uint8_t(v % 256), uint8_t(255 - v % 256), uint8_t(51), uint8_t(0)})
            rgb.push_back(c);
    prim.attributes["COLOR_0"] = addAccessor(model, rgb.data(), rgb.size(), TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                             TINYGLTF_TYPE_VEC3, n, TINYGLTF_TARGET_ARRAY_BUFFER);
    // RGB padded to 4 bytes, as the specification asks of byte attributes.
    model.bufferViews[size_t(model.accessors.back().bufferView)].byteStride = 4;
    model.accessors.back().normalized = true;
    prim.attributes["COLOR_1"] = int(model.accessors.size()) - 1;
    Rig rig;
    io::SceneMaterials after;
    std::vector<std::string> warnings;
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/colours.glb", &rig, &after, &warnings));
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    ASSERT_EQ(after.fileColours.size(), rig.sourceVertex.size());
    for (size_t v = 0; v < n; v += 37)
        EXPECT_EQ(after.fileColours[v], glm::vec4(float(v % 256) / 255.0f, float(255 - v % 256) / 255.0f, 0.2f, 1.0f))
            << v;
    EXPECT_EQ(after.fileUVs, before.fileUVs);
    const std::string left = io::featuresNotCarried(rig, 0);
    EXPECT_NE(left.find("vertex colour sets past COLOR_0 (1 set)"), std::string::npos) << left;
    // A primitive's own extension (a material per variant) is named too.
    tinygltf::Value::Object variants;
    variants["mappings"] = tinygltf::Value(tinygltf::Value::Array{});
    prim.extensions["KHR_materials_variants"] = tinygltf::Value(variants);
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/variants.glb", &rig, &after));
    EXPECT_NE(io::featuresNotCarried(rig, 0).find("KHR_materials_variants (1 primitive)"), std::string::npos)
        << io::featuresNotCarried(rig, 0);
    prim.extensions.clear();
    // And an extension of the document's that nothing here reads (animated
    // material properties, whose channels are not carried).
    model.extensionsUsed.push_back("KHR_animation_pointer");
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/pointer.glb", &rig, &after));
    EXPECT_NE(io::featuresNotCarried(rig, 0).find("KHR_animation_pointer (the document's)"), std::string::npos)
        << io::featuresNotCarried(rig, 0);
    model.extensionsUsed.pop_back();
    // Two components are no colour.
    model.accessors.back().type = TINYGLTF_TYPE_VEC2;
    warnings.clear();
    ASSERT_TRUE(writeAndReadMaterials(model, dir + "/two.glb", &rig, &after, &warnings));
    EXPECT_TRUE(after.fileColours.empty());
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("its COLOR_0 is not one RGB or RGBA colour per vertex; ignored"), std::string::npos)
        << warnings[0];
}

// A skin whose joints place its meshes at different scales at rest has no
// one scale to read its bind space at: it is read as it is, and named once.
TEST(Scene, ASkinOfManyScalesIsNamed)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_skin_scales");
    tinygltf::TinyGLTF gltf;
    tinygltf::Model model;
    std::string err, warn;
    ASSERT_TRUE(gltf.LoadBinaryFromFile(&model, &err, &warn, man)) << err;
    const tinygltf::Accessor& a = model.accessors[size_t(model.skins[0].inverseBindMatrices)];
    const tinygltf::BufferView& view = model.bufferViews[size_t(a.bufferView)];
    float* m = reinterpret_cast<float*>(model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset);
    for (int k = 0; k < 12; ++k)
        m[k] *= 2.0f;  // joint 0's inverse bind matrix: twice the scale
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/scales.glb", true, true, false, true));
    Rig rig, source;
    ASSERT_TRUE(io::loadRig(dir + "/scales.glb", &rig).isOk());
    ASSERT_TRUE(io::loadRig(man, &source).isOk());
    ASSERT_EQ(rig.warnings.size(), 1u);
    EXPECT_NE(rig.warnings[0].find("skin 0 places its meshes at scales 1 to 2 at rest (by joint or axis)"),
              std::string::npos)
        << rig.warnings[0];
    EXPECT_EQ(rig.mesh.positions, source.mesh.positions);
    // One scale for every joint, but not the same along every axis.
    ASSERT_TRUE(gltf.LoadBinaryFromFile(&model, &err, &warn, man)) << err;
    m = reinterpret_cast<float*>(model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset);
    for (size_t j = 0; j < a.count; ++j)
        for (int r = 0; r < 4; ++r)
            m[16 * j + 8 + size_t(r)] *= 0.5f;  // every inverse bind matrix's third column: half
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/axes.glb", true, true, false, true));
    ASSERT_TRUE(io::loadRig(dir + "/axes.glb", &rig).isOk());
    ASSERT_EQ(rig.warnings.size(), 1u);
    EXPECT_NE(rig.warnings[0].find("skin 0 places its meshes at scales 0.5 to 1 at rest"), std::string::npos)
        << rig.warnings[0];

    // A bind space squashed 1000x along one axis (positions along it 1000x
    // smaller, the inverse bind matrices 1000x larger there: the file poses
    // as CesiumMan does) cannot be read at one scale: a character baked in
    // it poses with its displacements squashed, and the bake says so in its
    // first line as well as naming the skin (its pictures 9 dB from the
    // source's; the RMS, of the squashed space's diagonal, 4.7%).
    ASSERT_TRUE(gltf.LoadBinaryFromFile(&model, &err, &warn, man)) << err;
    m = reinterpret_cast<float*>(model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset);
    for (size_t j = 0; j < a.count; ++j)
        for (int r = 0; r < 4; ++r)
            m[16 * j + 8 + size_t(r)] *= 1000.0f;
    tinygltf::Accessor& pa = model.accessors[size_t(model.meshes[0].primitives[0].attributes.at("POSITION"))];
    const tinygltf::BufferView& pv = model.bufferViews[size_t(pa.bufferView)];
    const size_t stride = pv.byteStride ? pv.byteStride : 12;
    unsigned char* p = model.buffers[size_t(pv.buffer)].data.data() + pv.byteOffset + pa.byteOffset;
    for (size_t v = 0; v < pa.count; ++v)
        reinterpret_cast<float*>(p + v * stride)[2] *= 0.001f;
    pa.minValues[2] *= 0.001;
    pa.maxValues[2] *= 0.001;
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/squashed.glb", true, true, false, true));
    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high '" + dir +
                                                   "/squashed.glb' --control auto --control-faces 400 -o '" + dir +
                                                   "/rig.glb'");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("skin 0 places its meshes at scales"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("DOES NOT LOOK LIKE ITS SOURCE: picture PSNR"), std::string::npos) << r.output;
}

// gltfpack, as a web pipeline runs it, quantises a character: integer
// positions whose dequantisation it folds into the inverse bind matrices
// (a 1e-4 scale), and UVs whose dequantisation is the base colour
// texture's KHR_texture_transform.  --control auto bakes such a capture at
// the scene's scale (a displacement baked in the integer units blew the
// posed rig up 20x, while the bake's own figures, relative to that bind
// space's diagonal, read 0.05%), and carries its colour through the
// transform (the pictures were 5 dB apart).
TEST(Scene, AGltfpackedCharacterBakesAtItsScenesScale)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    if (std::system("command -v gltfpack >/dev/null 2>&1") != 0)
        GTEST_FAIL() << "gltfpack is not installed (cmake/install-deps.sh installs it)";
    const std::string dir = test::tempDir("scene_gltfpacked_character");
    const std::string packed = dir + "/packed.glb", rigPath = dir + "/rig.glb";
    test::CommandResult r = test::runCommand("gltfpack -i '" + man + "' -o '" + packed + "'");
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string bytes = test::readText(packed);
    ASSERT_NE(bytes.find("KHR_mesh_quantization"), std::string::npos);
    ASSERT_NE(bytes.find("KHR_texture_transform"), std::string::npos);
    Rig source, quantised;
    ASSERT_TRUE(io::loadRig(man, &source).isOk());
    ASSERT_TRUE(io::loadRig(packed, &quantised).isOk());
    EXPECT_TRUE(quantised.warnings.empty()) << quantised.warnings[0];
    // Read at the scene's scale: the same bind-space size as the source's.
    EXPECT_NEAR(test::boundingBoxDiagonal(quantised.mesh), test::boundingBoxDiagonal(source.mesh),
                0.01f * test::boundingBoxDiagonal(source.mesh));

    r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high '" + packed + "' --control auto --control-faces 400 -o '" +
                         rigPath + "' --report '" + dir + "/report.json'");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(r.output.find("texture transforms"), std::string::npos) << r.output;
    const json report = json::parse(test::readText(dir + "/report.json"));
    ASSERT_EQ(report["posed"]["frames"].size(), 10u);
    for (const json& f : report["posed"]["frames"]) {
        EXPECT_LT(f["rms"].get<double>(), 0.002) << "at " << f["time"];
        EXPECT_GT(f["psnr"].get<double>(), 17.0) << "at " << f["time"];
    }
    // Posed by the runtime, the rig stands where the unpacked source does.
    Rig rig;
    ASSERT_TRUE(io::loadRig(rigPath, &rig).isOk());
    DisplacementMap map;
    io::loadRigDisplacementMap(rigPath, rig, &map);
    std::unique_ptr<Surface> layered, original;
    SurfaceOptions plain;
    plain.displace = false;
    plain.level = 0;
    ASSERT_TRUE(Surface::create(&layered, rig, &map).isOk());
    ASSERT_TRUE(Surface::create(&original, source, nullptr, plain).isOk());
    for (float t : {0.25f, 1.0f, 1.75f}) {
        ASSERT_TRUE(layered->setAnimationTime(0, t).isOk());
        ASSERT_TRUE(original->setAnimationTime(0, t).isOk());
        // The boxes of the evaluated surfaces (bounds() pads the layered
        // one by its displacement's range).
        auto box = [](Surface& s, glm::vec3* lo, glm::vec3* hi) {
            std::vector<glm::vec3> p(s.vertexCount());
            ASSERT_TRUE(s.evaluate(p.data(), nullptr, p.size()).isOk());
            *lo = glm::vec3(1e30f);
            *hi = glm::vec3(-1e30f);
            for (const glm::vec3& q : p) {
                *lo = glm::min(*lo, q);
                *hi = glm::max(*hi, q);
            }
        };
        glm::vec3 lo, hi, slo, shi;
        box(*layered, &lo, &hi);
        box(*original, &slo, &shi);
        const float diag = glm::length(shi - slo);
        EXPECT_LT(glm::length(lo - slo), 0.02f * diag) << "at " << t;
        EXPECT_LT(glm::length(hi - shi), 0.02f * diag) << "at " << t;
    }
}

TEST(Scene, SkinWith256JointsRoundTripsAndPoses)
{
    // A ribbon of 256 quads along x, quad k skinned to joint k of a
    // 256-joint chain; the root bends over one second.
    const int joints = 256;
    Rig rig;
    for (int k = 0; k <= joints; ++k) {
        rig.mesh.positions.push_back({float(k), 0.0f, 0.0f});
        rig.mesh.positions.push_back({float(k), 1.0f, 0.0f});
    }
    for (uint32_t k = 0; k < uint32_t(joints); ++k)
        rig.mesh.triangles.insert(rig.mesh.triangles.end(),
                                  {2 * k, 2 * k + 2, 2 * k + 3, 2 * k, 2 * k + 3, 2 * k + 1});
    Skeleton& s = rig.skeleton;
    s.nodes.resize(size_t(joints));
    for (int k = 0; k < joints; ++k) {
        s.nodes[size_t(k)].name = "j" + std::to_string(k);
        s.nodes[size_t(k)].parent = k - 1;
        s.nodes[size_t(k)].rest.translation = k == 0 ? glm::vec3(0.0f) : glm::vec3(1.0f, 0.0f, 0.0f);
        s.skin.joints.push_back(k);
        s.skin.inverseBindMatrices.push_back(glm::translate(glm::mat4(1.0f), glm::vec3(-float(k), 0.0f, 0.0f)));
    }
    s.weights.influences = 4;
    for (int v = 0; v < 2 * (joints + 1); ++v) {
        const uint16_t j = uint16_t(std::min(v / 2, joints - 1));
        s.weights.joints.insert(s.weights.joints.end(), {j, 0, 0, 0});
        s.weights.weights.insert(s.weights.weights.end(), {1.0f, 0.0f, 0.0f, 0.0f});
    }
    Animation bend;
    bend.name = "bend";
    bend.channels.push_back(test::rotationKeys(
        0, {0.0f, 1.0f}, {glm::quat(1, 0, 0, 0), glm::angleAxis(0.5f, glm::vec3(0.0f, 0.0f, 1.0f))}));
    s.animations.push_back(bend);
    ASSERT_TRUE(finalizeSkeleton(&s, rig.mesh.positions.size()).isOk());
    const std::string dir = test::tempDir("scene_joints");
    ASSERT_TRUE(io::saveRig(dir + "/ribbon.glb", rig).isOk());
    Rig back;
    const Status st = io::loadRig(dir + "/ribbon.glb", &back);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(back.skeleton.skin.joints.size(), size_t(joints));
    Animator animator;
    ASSERT_TRUE(animator.init(back.skeleton, back.mesh).isOk());
    ASSERT_TRUE(animator.pose(0, 1.0f).isOk());
    // Every vertex turns rigidly by 0.5 rad about the origin.
    const glm::mat4 turn = glm::mat4_cast(glm::angleAxis(0.5f, glm::vec3(0.0f, 0.0f, 1.0f)));
    for (size_t v = 0; v < back.mesh.positions.size(); ++v) {
        const glm::vec3 expected = glm::vec3(turn * glm::vec4(back.mesh.positions[v], 1.0f));
        ASSERT_LT(glm::length(animator.positions()[v] - expected), 1e-3f) << v;
    }
}

TEST(Scene, OverflowingPoseIsAnErrorNamingTheJoint)
{
    // Node scales of 1e20 on two nested joints overflow float when posed.
    Rig rig;
    DisplacementMap map;
    test::makeExampleRig(&rig, &map);
    test::twoJointSkin(&rig.skeleton, rig.mesh, "hip", "knee", glm::vec3(0.0f), glm::vec3(0.0f, 0.5f, 0.0f),
                       [](const glm::vec3& p) { return p.y > 0.0f ? 1.0f : 0.0f; });
    rig.skeleton.animations.push_back(test::overflowingAnimation());
    ASSERT_TRUE(finalizeSkeleton(&rig.skeleton, rig.mesh.positions.size()).isOk());
    const std::string dir = test::tempDir("scene_overflow");
    ASSERT_TRUE(io::saveRig(dir + "/huge.glb", rig, &map).isOk());
    const test::CommandResult r = test::runCommand(std::string(STRATA_RECONSTRUCT_EXE) + " " + dir +
                                                   "/huge.glb --level 1 --time 0.5 -o " + dir + "/out.ply");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("not finite"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("knee"), std::string::npos) << r.output;
    EXPECT_FALSE(test::fileExists(dir + "/out.ply"));
}

TEST(Scene, VersionOneRigsStillLoad)
{
    // A version 1 rig: the map in an EXR beside it, the block naming it by URI.
    const std::string dir = test::tempDir("scene_v1");
    Rig rig;
    DisplacementMap map;
    test::makeExampleRig(&rig, &map);
    rig.displacement.uri = "v1.exr";
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/v1.exr", map).isOk());
    ASSERT_TRUE(io::saveRig(dir + "/v2.gltf", rig).isOk());
    // Version 1: the block in extras, with the fields that later versions
    // may leave out spelled out.
    nlohmann::json doc = nlohmann::json::parse(test::readText(dir + "/v2.gltf"));
    test::layerToVersionFour(doc);
    nlohmann::json& block = doc["meshes"][0]["extras"]["strata"];
    block["version"] = 1;
    block["direction"] = "interpolated-control-normal";
    block["normalWeighting"] = "angle";
    test::writeText(dir + "/v1.gltf", doc.dump());
    Rig back;
    const Status st = io::loadRig(dir + "/v1.gltf", &back);
    ASSERT_TRUE(st.isOk()) << st.message();
    DisplacementMap loaded;
    ASSERT_TRUE(io::loadRigDisplacementMap(dir + "/v1.gltf", back, &loaded).isOk());
    ASSERT_EQ(loaded.texels.size(), map.texels.size());
    for (size_t i = 0; i < map.texels.size(); ++i)  // half floats: 11 significant bits
        ASSERT_NEAR(loaded.texels[i], map.texels[i], 1e-3f * std::fabs(map.texels[i]) + 1e-7f) << i;
}

TEST(Scene, EveryToolAnswersVersion)
{
    for (const char* exe : {STRATA_BAKE_EXE, STRATA_RECONSTRUCT_EXE, STRATA_DEMO_EXE}) {
        const test::CommandResult r = test::runCommand(std::string(exe) + " --version");
        EXPECT_EQ(r.code, 0) << exe;
        EXPECT_NE(r.output.find(" 0."), std::string::npos) << r.output;
    }
}

TEST(Scene, MeshoptCodedRigsAreSmallerAndLoadTheSame)
{
    const std::string dir = test::tempDir("scene_meshopt");
    Rig rig;
    DisplacementMap map;
    test::makeExampleRig(&rig, &map);
    rig.mesh = examples::makeIcosphere(3);  // a mesh big enough for the codec to matter
    ASSERT_TRUE(baker::buildTriangleAtlas(&rig.mesh, {1024, 2}).isOk());
    io::RigWriteOptions plainOptions, coded;
    coded.compress = true;
    ASSERT_TRUE(io::saveRig(dir + "/plain.glb", rig, &map, nullptr, &plainOptions).isOk());
    ASSERT_TRUE(io::saveRig(dir + "/coded.glb", rig, &map, nullptr, &coded).isOk());
    const size_t plainBytes = test::readText(dir + "/plain.glb").size(), codedBytes = test::readText(dir + "/coded.glb").size();
    EXPECT_LT(double(codedBytes), 0.8 * double(plainBytes)) << plainBytes << " -> " << codedBytes;
    EXPECT_NE(test::readText(dir + "/coded.glb").find("EXT_meshopt_compression"), std::string::npos);
    Rig a, b;
    ASSERT_TRUE(io::loadRig(dir + "/plain.glb", &a).isOk());
    const Status st = io::loadRig(dir + "/coded.glb", &b);
    ASSERT_TRUE(st.isOk()) << st.message();
    // The same faces (positions lossless, UVs within a 16-bit step), in the
    // order that codes best: each face as its corners' positions and UVs,
    // from its smallest position on (the index codec may rotate corners).
    auto faces = [](const ControlMesh& m) {
        std::vector<std::array<float, 15>> out(m.faceCount());
        for (size_t f = 0; f < m.faceCount(); ++f) {
            int first = 0;
            for (int k = 1; k < 3; ++k) {
                const glm::vec3 p = m.positions[m.triangles[3 * f + size_t(k)]];
                const glm::vec3 q = m.positions[m.triangles[3 * f + size_t(first)]];
                if (std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z))
                    first = k;
            }
            for (int k = 0; k < 3; ++k) {
                const size_t c = 3 * f + size_t((first + k) % 3);
                const glm::vec3 p = m.positions[m.triangles[c]];
                // Compact rigs store UVs in [0, 1] as 16-bit: compared in steps.
                const glm::vec2 uv = m.uvs[m.uvIndices[c]] * 65535.0f;
                const float corner[5] = {p.x, p.y, p.z, uv.x, uv.y};
                std::copy_n(corner, 5, &out[f][size_t(5 * k)]);
            }
        }
        // Sorted by the positions (no two faces share all three here).
        std::sort(out.begin(), out.end(), [](const std::array<float, 15>& x, const std::array<float, 15>& y) {
            const float px[9] = {x[0], x[1], x[2], x[5], x[6], x[7], x[10], x[11], x[12]};
            const float py[9] = {y[0], y[1], y[2], y[5], y[6], y[7], y[10], y[11], y[12]};
            return std::lexicographical_compare(px, px + 9, py, py + 9);
        });
        return out;
    };
    ASSERT_TRUE(a.mesh.hasUVs() && b.mesh.hasUVs());
    EXPECT_EQ(a.mesh.positions.size(), b.mesh.positions.size());
    const auto fa = faces(a.mesh), fb = faces(b.mesh);
    ASSERT_EQ(fa.size(), fb.size());
    for (size_t f = 0; f < fa.size(); ++f)
        for (size_t i = 0; i < 15; ++i)
            ASSERT_NEAR(fa[f][i], fb[f][i], i % 5 < 3 ? 0.0f : 1.0f) << f;
    // Positions stored to a given error (meshopt's EXPONENTIAL filter): each
    // coordinate within it, fewer bytes, the same faces in the same order.
    io::RigWriteOptions lossy = coded;
    lossy.maxPositionError = 1e-4;
    ASSERT_TRUE(io::saveRig(dir + "/lossy.glb", rig, &map, nullptr, &lossy).isOk());
    const std::string lossyBytes = test::readText(dir + "/lossy.glb");
    EXPECT_LT(lossyBytes.size(), codedBytes);
    EXPECT_NE(lossyBytes.find("\"EXPONENTIAL\""), std::string::npos);
    Rig d;
    ASSERT_TRUE(io::loadRig(dir + "/lossy.glb", &d).isOk());
    ASSERT_EQ(d.mesh.positions.size(), b.mesh.positions.size());
    EXPECT_EQ(d.mesh.triangles, b.mesh.triangles);
    for (size_t v = 0; v < d.mesh.positions.size(); ++v)
        for (int k = 0; k < 3; ++k)
            ASSERT_NEAR(d.mesh.positions[v][k], b.mesh.positions[v][k], 1e-4f) << v;
    int code = 0;
    const std::string report = test::runGltfValidator({dir + "/coded.glb", dir + "/lossy.glb"}, &code);
    for (const char* f : {"coded.glb", "lossy.glb"})
        EXPECT_NE(report.find(std::string(f) + ": 0 errors, 0 warnings"), std::string::npos) << report;
    // gltfpack's own meshopt output (with its filters) loads too.
    if (std::system("command -v gltfpack >/dev/null 2>&1") == 0) {
        ASSERT_EQ(test::runCommand("gltfpack -i '" + dir + "/plain.glb' -o '" + dir + "/packed.glb' -cc").code, 0);
        Rig c;
        const Status pst = io::loadRig(dir + "/packed.glb", &c);
        ASSERT_TRUE(pst.isOk()) << pst.message();
        EXPECT_EQ(c.mesh.faceCount(), a.mesh.faceCount());
    }
}

// A bare cage coded with KHR_draco_mesh_compression: fewer bytes than
// meshopt, every position within the error asked, the same displaced
// surface (the example head, radially), and valid glTF.
TEST(Scene, DracoCodedCageIsSmallerAndReconstructsTheSameSurface)
{
    const std::string dir = test::tempDir("scene_draco");
    Rig rig;
    DisplacementMap map;
    test::makeExampleRig(&rig, &map);
    rig.displacement.recommendedLevel = 3;
    io::RigWriteOptions meshopt;
    meshopt.compress = true;
    meshopt.vertexDisplacements = true;
    meshopt.maxQuantizationStep = 1e-4;
    meshopt.maxPositionError = 2e-4;
    io::RigWriteOptions draco = meshopt;
    draco.draco = true;
    ASSERT_TRUE(io::saveRig(dir + "/meshopt.glb", rig, &map, nullptr, &meshopt).isOk());
    ASSERT_TRUE(io::saveRig(dir + "/draco.glb", rig, &map, nullptr, &draco).isOk());
    const std::string a = test::readText(dir + "/meshopt.glb"), b = test::readText(dir + "/draco.glb");
    EXPECT_EQ(a.find("KHR_draco_mesh_compression"), std::string::npos);
    EXPECT_NE(b.find("KHR_draco_mesh_compression"), std::string::npos);
    EXPECT_LT(b.size(), a.size());
    Rig ra, rb;
    ASSERT_TRUE(io::loadRig(dir + "/meshopt.glb", &ra).isOk());
    const Status st = io::loadRig(dir + "/draco.glb", &rb);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(rb.mesh.faceCount(), rig.mesh.faceCount());
    ASSERT_EQ(rb.mesh.vertexCount(), rig.mesh.vertexCount());
    ASSERT_TRUE(rb.mesh.hasUVs());
    for (const glm::vec3& p : rb.mesh.positions) {
        float nearest = 1e30f;
        for (const glm::vec3& q : rig.mesh.positions)
            nearest = std::min(nearest, std::max({std::fabs(p.x - q.x), std::fabs(p.y - q.y), std::fabs(p.z - q.z)}));
        EXPECT_LE(nearest, 2.001e-4f);
    }
    auto radialRms = [](const std::vector<glm::vec3>& p) {
        double sum = 0.0;
        for (const glm::vec3& x : p) {
            const double e = double(glm::length(x)) - double(examples::headRadius(glm::normalize(x)));
            sum += e * e;
        }
        return std::sqrt(sum / double(p.size()));
    };
    const DisplacementMap none;  // per-vertex rigs need no map
    io::Reconstruction ca, cb;
    ASSERT_TRUE(io::reconstruct(&ca, ra, &none, Scheme::Linear, 3).isOk());
    ASSERT_TRUE(io::reconstruct(&cb, rb, &none, Scheme::Linear, 3).isOk());
    // The map's samples are not measured again here (the baker does that),
    // so a moved cage moves the surface by up to the position error.
    EXPECT_LT(radialRms(cb.positions), radialRms(ca.positions) + 2e-4)
        << radialRms(cb.positions) << " vs " << radialRms(ca.positions);
    int code = 0;
    const std::string report = test::runGltfValidator({dir + "/draco.glb"}, &code);
    EXPECT_NE(report.find("draco.glb: 0 errors, 0 warnings"), std::string::npos) << report;
}

// A cage edge shorter than the position error asked would collapse under
// Draco's quantisation; the writer takes a finer error and still codes the
// cage with Draco, every face read back.
TEST(Scene, DracoTakesAFinerErrorWhereAnEdgeWouldCollapse)
{
    const std::string dir = test::tempDir("scene_draco_short_edge");
    Rig rig;
    DisplacementMap map;
    test::makeExampleRig(&rig, &map);
    rig.displacement.recommendedLevel = 2;
    const uint32_t a = rig.mesh.triangles[0], b = rig.mesh.triangles[1];
    const glm::vec3 along = glm::normalize(rig.mesh.positions[b] - rig.mesh.positions[a]);
    rig.mesh.positions[b] = rig.mesh.positions[a] + 6e-4f * along;  // far below the 2e-3 asked
    io::RigWriteOptions options;
    options.compress = true;
    options.vertexDisplacements = true;
    options.maxQuantizationStep = 1e-4;
    options.maxPositionError = 2e-3;
    options.draco = true;
    const Status st = io::saveRig(dir + "/rig.glb", rig, &map, nullptr, &options);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_NE(test::readText(dir + "/rig.glb").find("KHR_draco_mesh_compression"), std::string::npos);
    Rig loaded;
    ASSERT_TRUE(io::loadRig(dir + "/rig.glb", &loaded).isOk());
    ASSERT_EQ(loaded.mesh.faceCount(), rig.mesh.faceCount());
    ASSERT_EQ(loaded.mesh.vertexCount(), rig.mesh.vertexCount());
    float shortest = 1e30f;
    for (size_t c = 0; c < loaded.mesh.triangles.size(); ++c)
        shortest = std::min(shortest, glm::length(loaded.mesh.positions[loaded.mesh.triangles[c]] -
                                                  loaded.mesh.positions[loaded.mesh.triangles[c - c % 3 + (c + 1) % 3]]));
    EXPECT_GT(shortest, 3e-4f);  // the short edge survived
    for (const glm::vec3& p : loaded.mesh.positions) {
        float nearest = 1e30f;
        for (const glm::vec3& q : rig.mesh.positions)
            nearest = std::min(nearest, std::max({std::fabs(p.x - q.x), std::fabs(p.y - q.y), std::fabs(p.z - q.z)}));
        EXPECT_LE(nearest, 2.001e-3f);
    }
}

// A Draco-compressed character (draco_transcoder, as glTF pipelines make
// them) loads like the plain file: the same faces, skin and UVs, positions
// within Draco's quantisation, and it bakes.
TEST(Scene, DracoCompressedCharacterLoadsLikeThePlainFile)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_draco_input");
    const test::CommandResult t = test::runCommand("draco_transcoder -i '" + man + "' -o '" + dir + "/man.glb'");
    ASSERT_EQ(t.code, 0) << "draco_transcoder (Debian package draco) is needed: " << t.output;
    ASSERT_NE(test::readText(dir + "/man.glb").find("KHR_draco_mesh_compression"), std::string::npos);
    Rig plain, packed;
    ASSERT_TRUE(io::loadRig(man, &plain).isOk());
    const Status st = io::loadRig(dir + "/man.glb", &packed);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(packed.mesh.faceCount(), plain.mesh.faceCount());
    EXPECT_EQ(packed.parts.size(), plain.parts.size());
    EXPECT_EQ(packed.skeleton.skin.joints.size(), plain.skeleton.skin.joints.size());
    EXPECT_EQ(packed.mesh.hasUVs(), plain.mesh.hasUVs());
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const glm::vec3& p : plain.mesh.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    // draco_transcoder's default: 11-bit positions over the largest extent.
    const float step = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}) / 2047.0f;
    // Every sampled face of the Draco file lies where a face of the plain one
    // does (the transcoder reorders faces), within the quantisation.
    auto centroid = [](const ControlMesh& m, size_t f) {
        return (m.positions[m.triangles[3 * f]] + m.positions[m.triangles[3 * f + 1]] +
                m.positions[m.triangles[3 * f + 2]]) / 3.0f;
    };
    double worst = 0.0;
    for (size_t f = 0; f < packed.mesh.faceCount(); f += 97) {
        const glm::vec3 c = centroid(packed.mesh, f);
        float nearest = 1e30f;
        for (size_t g = 0; g < plain.mesh.faceCount(); ++g)
            nearest = std::min(nearest, glm::length(c - centroid(plain.mesh, g)));
        worst = std::max(worst, double(nearest));
    }
    EXPECT_LE(worst, double(step));
    const test::CommandResult r = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high '" + dir + "/man.glb' --control '" +
                                                   dir + "/man.glb' --error-levels none -o '" + dir + "/rig.glb'");
    EXPECT_EQ(r.code, 0) << r.output;
}

// The C API (strata/strata.h) from a C99 program equals the C++ path bit for
// bit: a skinned, animated, vertex-coded compact rig drawn by FrameEvaluator
// (plan order) in the bind pose and posed, against the C program's
// strata_surface_evaluate of the same file.  The frame's positions are
// io::reconstruct's bit for bit and its normals the scatter's to 1e-5.
TEST(CApi, MatchesTheCppPathBitForBit)
{
    const std::string dir = test::tempDir("c_api");
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map);
    rig.displacement.recommendedLevel = 3;
    io::RigWriteOptions options;
    options.compress = true;
    options.vertexDisplacements = true;
    const std::string path = dir + "/skinned.glb";
    ASSERT_TRUE(io::saveRig(path, rig, &map, nullptr, &options).isOk());

    Rig loaded;
    DisplacementMap loadedMap;
    ASSERT_TRUE(io::loadRig(path, &loaded).isOk());
    ASSERT_TRUE(io::loadRigDisplacementMap(path, loaded, &loadedMap).isOk());
    const int level = 3;
    io::Reconstruction rest, posed;
    ASSERT_TRUE(io::reconstruct(&rest, loaded, &loadedMap, loaded.displacement.scheme, level).isOk());
    io::Pose pose;
    pose.animation = 0;
    pose.time = 0.5f;
    ASSERT_TRUE(io::reconstruct(&posed, loaded, &loadedMap, loaded.displacement.scheme, level, 1.0f, &pose).isOk());
    Animator animator;
    ASSERT_TRUE(animator.init(loaded.skeleton, loaded.mesh).isOk());
    ASSERT_TRUE(animator.pose(pose.animation, pose.time).isOk());
    std::string expected;
    const uint32_t header[2] = {uint32_t(level), uint32_t(rest.positions.size())};
    expected.append(reinterpret_cast<const char*>(header), sizeof(header));
    FrameEvaluator frame(rest.plan(), FrameLayout::Plan);
    for (const io::Reconstruction* r : {&rest, &posed}) {
        const glm::vec3* control = r == &rest ? loaded.mesh.positions.data() : animator.positions().data();
        std::vector<glm::vec3> p(r->positions.size()), n(p.size());
        const std::vector<glm::vec3>& controlNormals = r->surface->controlNormals();
        ASSERT_TRUE(frame.evaluate(p.data(), n.data(), nullptr, control, controlNormals.data(), controlNormals.size(), 1)
                        .isOk());
        EXPECT_EQ(std::memcmp(p.data(), r->positions.data(), p.size() * sizeof(glm::vec3)), 0);
        float worst = 0.0f;
        for (size_t v = 0; v < n.size(); ++v)
            worst = std::max(worst, glm::length(n[v] - r->normals[v]));
        EXPECT_EQ(worst, 0.0f) << "io::reconstruct and the frame evaluator are one path";
        // The C API must give the surface io::reconstruct gives, bit for bit.
        expected.append(reinterpret_cast<const char*>(r->positions.data()), p.size() * sizeof(glm::vec3));
        expected.append(reinterpret_cast<const char*>(r->normals.data()), n.size() * sizeof(glm::vec3));
    }
    test::writeText(dir + "/expected.bin", expected);
    // The pose moved something, so the comparison is not of two bind poses.
    float moved = 0.0f;
    for (size_t v = 0; v < rest.positions.size(); ++v)
        moved = std::max(moved, glm::length(rest.positions[v] - posed.positions[v]));
    EXPECT_GT(moved, 0.1f);
    const test::CommandResult r =
        test::runCommand(std::string(STRATA_C_API_TEST_EXE) + " " + path + " " + dir + "/expected.bin");
    EXPECT_EQ(r.code, 0) << r.output;
}

// A meshopt-coded character: its skin and animation data are coded too
// (losslessly), so only the images and the layer's values (coded already)
// stay plain, and nothing is left plain without a note saying so.
TEST(Scene, MeshoptCodesSkinAndAnimationData)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("scene_meshopt_animation");
    Rig rig;
    ASSERT_TRUE(io::loadRig(man, &rig, io::LoadOptions()).isOk());
    io::RigWriteOptions coded;
    coded.compress = true;
    std::vector<std::string> notes;
    ASSERT_TRUE(io::saveRig(dir + "/coded.glb", rig, nullptr, &notes, &coded).isOk());
    for (const std::string& n : notes)
        EXPECT_EQ(n.find("left some data plain"), std::string::npos) << n;
    // The file as written (not decoded): which views are coded.
    const std::string bytes = test::readText(dir + "/coded.glb");
    uint32_t jsonLength = 0;
    std::memcpy(&jsonLength, bytes.data() + 12, 4);
    const json doc = json::parse(bytes.substr(20, jsonLength));
    std::vector<int> imageViews;
    for (const json& im : doc["images"])
        imageViews.push_back(im.value("bufferView", -1));
    size_t plainData = 0, animationViews = 0;
    std::set<size_t> animationAccessorViews;
    for (const json& an : doc["animations"])
        for (const json& s : an["samplers"])
            for (const char* k : {"input", "output"})
                animationAccessorViews.insert(doc["accessors"][s[k].get<size_t>()]["bufferView"].get<size_t>());
    for (size_t v = 0; v < doc["bufferViews"].size(); ++v) {
        const bool isCoded = doc["bufferViews"][v].contains("extensions");
        if (animationAccessorViews.count(v))
            animationViews += isCoded;
        if (!isCoded && std::find(imageViews.begin(), imageViews.end(), int(v)) == imageViews.end())
            ++plainData;
    }
    EXPECT_EQ(plainData, 0u);
    EXPECT_EQ(animationViews, animationAccessorViews.size());
    ASSERT_FALSE(animationAccessorViews.empty());
    // Lossless: the same skeleton and animations as the source.
    Rig back;
    const Status st = io::loadRig(dir + "/coded.glb", &back);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(back.skeleton.animations.size(), rig.skeleton.animations.size());
    for (size_t a = 0; a < rig.skeleton.animations.size(); ++a) {
        ASSERT_EQ(back.skeleton.animations[a].channels.size(), rig.skeleton.animations[a].channels.size());
        for (size_t c = 0; c < rig.skeleton.animations[a].channels.size(); ++c) {
            EXPECT_EQ(back.skeleton.animations[a].channels[c].times, rig.skeleton.animations[a].channels[c].times);
            EXPECT_EQ(back.skeleton.animations[a].channels[c].values, rig.skeleton.animations[a].channels[c].values);
        }
    }
    EXPECT_EQ(back.skeleton.skin.inverseBindMatrices, rig.skeleton.skin.inverseBindMatrices);
}

// The render mesh of a character (CesiumMan: UV seams): the refined vertices
// first in the plan's order, a copy for each other corner value, triangles
// on the same refined vertices as the plan's, one contiguous index range per
// part, and at level 0 each corner's TEXCOORD_0 exactly the file's.  At level
// 1 an edge's midpoint carries the mean of its ends' UVs (linear refinement
// of the face-varying values).
TEST(Scene, AdaptiveRenderMeshKeepsTheFinestLevelsTextureCoordinates)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    Rig rig;
    ASSERT_TRUE(io::loadRig(man, &rig, io::LoadOptions()).isOk());
    size_t split = 0;
    expectAdaptiveLayout(rig, false, 2, 6, &split);
    EXPECT_GT(split, 0u);  // its UV seams split frame vertices
}

TEST(Scene, RenderMeshSplitsAtSeamsAndKeepsThePlanOrder)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    Rig rig;
    ASSERT_TRUE(io::loadRig(man, &rig, io::LoadOptions()).isOk());
    tinygltf::Model m;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, man)) << err;
    ASSERT_EQ(rig.parts.size(), 1u);
    const std::vector<float> fileUV = accessorData<float>(m, m.meshes[0].primitives[0].attributes.at("TEXCOORD_0"), 2);
    for (int level : {0, 1}) {
        SCOPED_TRACE(level);
        io::RenderMesh rm;
        std::unique_ptr<Surface> surface = surfaceWithLayout(rig, level, false, &rm);
        ASSERT_TRUE(surface);
        const Plan& plan = surface->plan();
        const size_t n = plan.refinedVertexCount();
        ASSERT_EQ(rm.refinedVertexCount, n);
        ASSERT_GT(rm.vertexCount(), n);  // the seams split vertices
        for (size_t v = 0; v < n; ++v)
            ASSERT_EQ(rm.refinedVertex[v], v);
        const std::vector<uint32_t>& tris = plan.refinedTriangles();
        ASSERT_EQ(rm.indices.size(), tris.size());
        for (size_t c = 0; c < tris.size(); ++c)
            ASSERT_EQ(rm.refinedVertex[rm.indices[c]], tris[c]);
        ASSERT_EQ(rm.parts.size(), 1u);
        EXPECT_EQ(rm.parts[0].firstIndex, 0u);
        EXPECT_EQ(rm.parts[0].indexCount, tris.size());
        EXPECT_EQ(rm.parts[0].mesh, 0);
        EXPECT_EQ(rm.parts[0].material, m.meshes[0].primitives[0].material);
        ASSERT_EQ(rm.attributes.size(), 1u);
        const io::RenderAttribute& uv = rm.attributes[0];
        EXPECT_EQ(uv.name, "TEXCOORD_0");
        ASSERT_EQ(uv.components, 2);
        ASSERT_EQ(uv.values.size(), 2 * rm.vertexCount());
        if (level == 0) {
            for (size_t c = 0; c < tris.size(); ++c) {
                const uint32_t file = rig.fileCorners[c];
                EXPECT_EQ(uv.values[2 * rm.indices[c]], fileUV[2 * file]);
                EXPECT_EQ(uv.values[2 * rm.indices[c] + 1], fileUV[2 * file + 1]);
            }
        } else {
            // Each level-1 triangle of control face f: its corners are
            // corners or edge midpoints of f, whose UVs (in f's seam-side)
            // are those of f's corners or their means.
            const size_t faces = rig.mesh.faceCount();
            size_t checked = 0;
            for (size_t f = 0; f < faces; ++f) {
                glm::vec2 corner[3];
                for (int k = 0; k < 3; ++k) {
                    const uint32_t file = rig.fileCorners[3 * f + size_t(k)];
                    corner[k] = glm::vec2(fileUV[2 * file], fileUV[2 * file + 1]);
                }
                const glm::vec2 allowed[6] = {corner[0], corner[1], corner[2], 0.5f * (corner[0] + corner[1]),
                                              0.5f * (corner[1] + corner[2]), 0.5f * (corner[2] + corner[0])};
                for (size_t c = 12 * f; c < 12 * (f + 1); ++c) {
                    const glm::vec2 got(uv.values[2 * rm.indices[c]], uv.values[2 * rm.indices[c] + 1]);
                    float best = 1e30f;
                    for (const glm::vec2& a : allowed)
                        best = std::min(best, glm::length(got - a));
                    EXPECT_LT(best, 1e-6f) << "face " << f;
                    ++checked;
                }
            }
            EXPECT_EQ(checked, tris.size());
        }
        // gather places per-refined-vertex values at every render vertex.
        std::vector<glm::vec3> refined(n), drawn(rm.vertexCount());
        for (size_t v = 0; v < n; ++v)
            refined[v] = glm::vec3(float(v), 0.0f, 1.0f);
        rm.gather(refined.data(), drawn.data());
        for (size_t i = 0; i < drawn.size(); ++i)
            ASSERT_EQ(drawn[i].x, float(rm.refinedVertex[i]));
    }
}
