// glTF 2.0 control rigs (docs/FORMAT.md).  Reading assumes hostile input;
// writing produces files the Khronos glTF-Validator accepts without warnings.
#include "strata/io/rig_io.h"

#include "strata/io/exr.h"
#include "strata/io/file.h"
#include "strata/io/gltf_accessor.h"
#include "strata/io/png.h"
#include "gltf_mesh_writer.h"
#include "strata/normals.h"

#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <unordered_map>

namespace strata {
namespace io {
namespace {

bool skipImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*)
{
    return true;  // the runtime never needs texture pixels
}

Status loadModel(const std::string& path, tinygltf::Model* model)
{
    const std::string ext = extensionOf(path);
    if (ext != ".glb" && ext != ".gltf")
        return Status(StatusCode::InvalidArgument, path + ": not a .glb or .gltf file");
    std::vector<unsigned char> bytes;
    Status st = readFile(path, &bytes);
    if (!st)
        return st;
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(skipImage, nullptr);
    std::string err, warn;
    bool ok;
    if (ext == ".glb") {
        ok = loader.LoadBinaryFromMemory(model, &err, &warn, bytes.data(), unsigned(bytes.size()), directoryOf(path));
    } else {
        ok = loader.LoadASCIIFromString(model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                        unsigned(bytes.size()), directoryOf(path));
    }
    if (!ok) {
        std::string msg = err.empty() ? std::string("not a valid glTF file") : err;
        while (!msg.empty() && (msg.back() == '\n' || msg.back() == '\r'))
            msg.pop_back();
        for (char& c : msg)
            if (c == '\n')
                c = ' ';
        return Status(StatusCode::InvalidData, path + ": " + msg);
    }
    return Status::ok();
}

const tinygltf::Value* member(const tinygltf::Value& obj, const char* name)
{
    if (!obj.IsObject() || !obj.Has(name))
        return nullptr;
    return &obj.Get(name);
}

Status numberField(const tinygltf::Value& obj, const char* name, const std::string& where, double* out)
{
    const tinygltf::Value* v = member(obj, name);
    if (!v || !v->IsNumber())
        return Status(StatusCode::InvalidData, where + ": strata metadata field \"" + name + "\" is missing or not a number");
    *out = v->GetNumberAsDouble();
    if (!std::isfinite(*out))
        return Status(StatusCode::InvalidData, where + ": strata metadata field \"" + name + "\" is not finite");
    return Status::ok();
}

Status stringField(const tinygltf::Value& obj, const char* name, const std::string& where, std::string* out)
{
    const tinygltf::Value* v = member(obj, name);
    if (!v || !v->IsString())
        return Status(StatusCode::InvalidData, where + ": strata metadata field \"" + name + "\" is missing or not a string");
    *out = v->Get<std::string>();
    return Status::ok();
}

Status parseStrataBlock(const tinygltf::Value& block, const std::string& path, DisplacementInfo* info)
{
    double version = 0;
    Status st = numberField(block, "version", path, &version);
    if (!st)
        return st;
    if (version != double(kRigFormatVersion))
        return Status(StatusCode::Unsupported, path + ": rig format version " + std::to_string(int(version)) +
                                                   ", this build reads version " + std::to_string(kRigFormatVersion));
    const tinygltf::Value* tex = member(block, "displacementGeometryTexture");
    if (!tex || !tex->IsObject())
        return Status(StatusCode::InvalidData, path + ": strata metadata has no displacementGeometryTexture object");
    double w = 0, h = 0, texCoord = 0, factor = 0, offset = 0, level = 0;
    std::string scheme, direction, weighting;
    if (!(st = stringField(*tex, "uri", path, &info->uri)) || !(st = stringField(*tex, "encoding", path, &info->encoding)) ||
        !(st = numberField(*tex, "width", path, &w)) || !(st = numberField(*tex, "height", path, &h)) ||
        !(st = numberField(*tex, "texCoord", path, &texCoord)) ||
        !(st = numberField(block, "displacementGeometryFactor", path, &factor)) ||
        !(st = numberField(block, "displacementGeometryOffset", path, &offset)) ||
        !(st = stringField(block, "scheme", path, &scheme)) ||
        !(st = numberField(block, "recommendedLevel", path, &level)) ||
        !(st = stringField(block, "direction", path, &direction)) ||
        !(st = stringField(block, "normalWeighting", path, &weighting)))
        return st;
    if (info->uri.empty() || info->uri.find("..") != std::string::npos || info->uri[0] == '/' ||
        info->uri.find(':') != std::string::npos)
        return Status(StatusCode::InvalidData, path + ": displacement map URI \"" + info->uri +
                                                   "\" must be a relative path beside the rig");
    if (info->encoding != "exr")
        return Status(StatusCode::Unsupported, path + ": displacement encoding \"" + info->encoding +
                                                   "\" is not supported (this build reads \"exr\")");
    if (w < 1 || h < 1 || w > kMaxDisplacementMapSize || h > kMaxDisplacementMapSize || w != std::floor(w) ||
        h != std::floor(h))
        return Status(StatusCode::InvalidData, path + ": displacement map size " + std::to_string(w) + "x" +
                                                   std::to_string(h) + " is invalid");
    if (texCoord != 0)
        return Status(StatusCode::Unsupported, path + ": displacement must use TEXCOORD_0");
    if (!parseScheme(scheme, &info->scheme))
        return Status(StatusCode::Unsupported, path + ": unknown subdivision scheme \"" + scheme + "\"");
    if (level < 0 || level > kMaxLevel || level != std::floor(level))
        return Status(StatusCode::InvalidData, path + ": recommendedLevel " + std::to_string(level) + " is outside 0.." +
                                                   std::to_string(kMaxLevel));
    if (direction != "interpolated-control-normal")
        return Status(StatusCode::Unsupported, path + ": displacement direction \"" + direction + "\" is not supported");
    if (weighting != "angle")
        return Status(StatusCode::Unsupported, path + ": normal weighting \"" + weighting + "\" is not supported");
    if (const tinygltf::Value* q = member(block, "quantizedMap")) {
        double bits = 0, dmin = 0, dmax = 0;
        if (!(st = stringField(*q, "uri", path, &info->quantized.uri)) || !(st = numberField(*q, "bits", path, &bits)) ||
            !(st = numberField(*q, "dmin", path, &dmin)) || !(st = numberField(*q, "dmax", path, &dmax)))
            return st;
        if ((bits != 8 && bits != 16) || !(dmax >= dmin))
            return Status(StatusCode::InvalidData, path + ": quantizedMap needs bits 8 or 16 and dmin <= dmax");
        info->quantized.bits = int(bits);
        info->quantized.dmin = float(dmin);
        info->quantized.dmax = float(dmax);
    }
    info->width = int(w);
    info->height = int(h);
    info->factor = float(factor);
    info->offset = float(offset);
    info->recommendedLevel = int(level);
    return Status::ok();
}

struct VertexKey {
    uint32_t bits[3];
    bool operator==(const VertexKey& o) const { return std::memcmp(bits, o.bits, sizeof(bits)) == 0; }
};
struct VertexKeyHash {
    size_t operator()(const VertexKey& k) const
    {
        return (size_t(k.bits[0]) * 73856093u) ^ (size_t(k.bits[1]) * 19349663u) ^ (size_t(k.bits[2]) * 83492791u);
    }
};

}  // namespace

namespace {

// The geometry of the chosen triangle primitive, welded by exact position.
struct LoadedPrimitive {
    Rig rig;                 // mesh (not yet validated) and sourceVertex
    int meshIndex = -1;
};

Status loadPrimitive(const std::string& path, tinygltf::Model* modelOut, LoadedPrimitive* out)
{
    tinygltf::Model& model = *modelOut;
    Status st = loadModel(path, &model);
    if (!st)
        return st;
    int meshIndex = -1;
    for (size_t m = 0; m < model.meshes.size() && meshIndex < 0; ++m)
        if (member(model.meshes[m].extras, "strata"))
            meshIndex = int(m);
    for (size_t m = 0; m < model.meshes.size() && meshIndex < 0; ++m)
        for (const tinygltf::Primitive& p : model.meshes[m].primitives)
            if (p.mode == TINYGLTF_MODE_TRIANGLES || p.mode == -1)
                meshIndex = int(m);
    if (meshIndex < 0)
        return Status(StatusCode::InvalidData, path + ": no triangle mesh in the file");
    const tinygltf::Mesh& mesh = model.meshes[size_t(meshIndex)];
    const tinygltf::Primitive* prim = nullptr;
    for (const tinygltf::Primitive& p : mesh.primitives)
        if (!prim && (p.mode == TINYGLTF_MODE_TRIANGLES || p.mode == -1))
            prim = &p;
    if (!prim)
        return Status(StatusCode::InvalidData, path + ": mesh " + std::to_string(meshIndex) + " has no triangle primitive");

    auto attr = [&](const char* name) {
        auto it = prim->attributes.find(name);
        return it == prim->attributes.end() ? -1 : it->second;
    };
    if (attr("POSITION") < 0)
        return Status(StatusCode::InvalidData, path + ": the mesh has no POSITION attribute");
    std::vector<float> pos, uv;
    std::vector<uint32_t> idx;
    if (!(st = readFloatAccessor(model, attr("POSITION"), 3, "POSITION", &pos)))
        return Status(st.code(), path + ": " + st.message());
    const size_t nFile = pos.size() / 3;
    if (nFile == 0)
        return Status(StatusCode::InvalidData, path + ": the mesh has no vertices");
    if (attr("TEXCOORD_0") >= 0) {
        if (!(st = readFloatAccessor(model, attr("TEXCOORD_0"), 2, "TEXCOORD_0", &uv)))
            return Status(st.code(), path + ": " + st.message());
        if (uv.size() / 2 != nFile)
            return Status(StatusCode::InvalidData, path + ": TEXCOORD_0 has " + std::to_string(uv.size() / 2) +
                                                       " elements for " + std::to_string(nFile) + " vertices");
    }
    if (prim->indices >= 0) {
        if (!(st = readUintAccessor(model, prim->indices, 1, "indices", &idx)))
            return Status(st.code(), path + ": " + st.message());
    } else {
        idx.resize(nFile);
        for (size_t i = 0; i < nFile; ++i)
            idx[i] = uint32_t(i);
    }
    if (idx.empty() || idx.size() % 3 != 0)
        return Status(StatusCode::InvalidData, path + ": the triangle primitive has " + std::to_string(idx.size()) +
                                                   " indices, not a positive multiple of 3");
    for (size_t i = 0; i < idx.size(); ++i)
        if (idx[i] >= nFile)
            return Status(StatusCode::InvalidData, path + ": index " + std::to_string(idx[i]) + " at position " +
                                                       std::to_string(i) + " is beyond the " + std::to_string(nFile) +
                                                       " vertices");

    Rig rig;
    // Weld glTF's split vertices into topological vertices (exact position match).
    std::unordered_map<VertexKey, uint32_t, VertexKeyHash> welded;
    rig.sourceVertex.resize(nFile);
    for (size_t i = 0; i < nFile; ++i) {
        VertexKey key;
        std::memcpy(key.bits, &pos[3 * i], sizeof(key.bits));
        if (pos[3 * i] == 0.0f && pos[3 * i + 1] == 0.0f && pos[3 * i + 2] == 0.0f)
            std::memset(key.bits, 0, sizeof(key.bits));  // -0 and +0 are one point
        auto it = welded.emplace(key, uint32_t(rig.mesh.positions.size()));
        if (it.second)
            rig.mesh.positions.emplace_back(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]);
        rig.sourceVertex[i] = it.first->second;
    }
    for (size_t i = 0; i < idx.size(); i += 3) {
        const uint32_t a = rig.sourceVertex[idx[i]], b = rig.sourceVertex[idx[i + 1]], c = rig.sourceVertex[idx[i + 2]];
        if (a == b || b == c || a == c)
            continue;  // zero-area after welding: not part of the surface
        rig.mesh.triangles.insert(rig.mesh.triangles.end(), {a, b, c});
        if (!uv.empty())
            rig.mesh.uvIndices.insert(rig.mesh.uvIndices.end(), {idx[i], idx[i + 1], idx[i + 2]});
    }
    if (!uv.empty()) {
        rig.mesh.uvs.resize(nFile);
        for (size_t i = 0; i < nFile; ++i)
            rig.mesh.uvs[i] = glm::vec2(uv[2 * i], uv[2 * i + 1]);
    }
    out->rig = std::move(rig);
    out->meshIndex = meshIndex;
    return Status::ok();
}

}  // namespace

// Nodes, the mesh node's skin, per-vertex influences and animations.
Status loadSkeleton(const std::string& path, const tinygltf::Model& model, int meshIndex, const tinygltf::Primitive& prim,
                    Rig* rig)
{
    Skeleton& sk = rig->skeleton;
    const size_t nn = model.nodes.size();
    sk.nodes.resize(nn);
    for (size_t i = 0; i < nn; ++i) {
        const tinygltf::Node& n = model.nodes[i];
        SkeletonNode& out = sk.nodes[i];
        out.name = n.name;
        if (n.matrix.size() == 16) {
            out.hasMatrix = true;
            for (int k = 0; k < 16; ++k)
                out.matrix[k / 4][k % 4] = float(n.matrix[size_t(k)]);
        }
        if (n.translation.size() == 3)
            out.rest.translation = glm::vec3(float(n.translation[0]), float(n.translation[1]), float(n.translation[2]));
        if (n.rotation.size() == 4)
            out.rest.rotation = glm::quat(float(n.rotation[3]), float(n.rotation[0]), float(n.rotation[1]),
                                          float(n.rotation[2]));
        if (n.scale.size() == 3)
            out.rest.scale = glm::vec3(float(n.scale[0]), float(n.scale[1]), float(n.scale[2]));
    }
    for (size_t i = 0; i < nn; ++i)
        for (int c : model.nodes[i].children) {
            if (c < 0 || size_t(c) >= nn)
                return Status(StatusCode::InvalidData, path + ": node " + std::to_string(i) + " has a missing child");
            if (sk.nodes[size_t(c)].parent >= 0)
                return Status(StatusCode::InvalidData, path + ": node " + std::to_string(c) + " has two parents");
            sk.nodes[size_t(c)].parent = int(i);
        }
    int skinIndex = -1;
    for (size_t i = 0; i < nn; ++i)
        if (model.nodes[i].mesh == meshIndex && model.nodes[i].skin >= 0 && skinIndex < 0) {
            skinIndex = model.nodes[i].skin;
            sk.meshNode = int(i);
        }
    Status st;
    if (skinIndex >= 0) {
        if (size_t(skinIndex) >= model.skins.size())
            return Status(StatusCode::InvalidData, path + ": the mesh node references a missing skin");
        const tinygltf::Skin& skin = model.skins[size_t(skinIndex)];
        sk.skin.joints = skin.joints;
        if (sk.skin.joints.empty())
            return Status(StatusCode::InvalidData, path + ": the skin has no joints");
        if (skin.inverseBindMatrices >= 0) {
            std::vector<float> m;
            if (!(st = readFloatAccessor(model, skin.inverseBindMatrices, 16, "inverseBindMatrices", &m)))
                return Status(st.code(), path + ": " + st.message());
            if (m.size() / 16 < sk.skin.joints.size())
                return Status(StatusCode::InvalidData, path + ": inverseBindMatrices holds " + std::to_string(m.size() / 16) +
                                                           " matrices for " + std::to_string(sk.skin.joints.size()) +
                                                           " joints");
            sk.skin.inverseBindMatrices.resize(sk.skin.joints.size());
            for (size_t j = 0; j < sk.skin.joints.size(); ++j)
                for (int k = 0; k < 16; ++k)
                    sk.skin.inverseBindMatrices[j][k / 4][k % 4] = m[16 * j + size_t(k)];
        }
        // Influences per file vertex, then per topological vertex (its first copy).
        auto attr = [&](const char* name) {
            auto it = prim.attributes.find(name);
            return it == prim.attributes.end() ? -1 : it->second;
        };
        if (attr("JOINTS_0") < 0 || attr("WEIGHTS_0") < 0)
            return Status(StatusCode::InvalidData, path + ": a skinned mesh needs JOINTS_0 and WEIGHTS_0");
        const int sets = attr("JOINTS_1") >= 0 && attr("WEIGHTS_1") >= 0 ? 2 : 1;
        const size_t nFile = rig->sourceVertex.size();
        std::vector<uint32_t> joints[2];
        std::vector<float> weights[2];
        for (int set = 0; set < sets; ++set) {
            const std::string js = "JOINTS_" + std::to_string(set), ws = "WEIGHTS_" + std::to_string(set);
            if (!(st = readUintAccessor(model, attr(js.c_str()), 4, js, &joints[set])) ||
                !(st = readFloatAccessor(model, attr(ws.c_str()), 4, ws, &weights[set])))
                return Status(st.code(), path + ": " + st.message());
            if (joints[set].size() != 4 * nFile || weights[set].size() != 4 * nFile)
                return Status(StatusCode::InvalidData, path + ": " + js + "/" + ws + " do not have one element per vertex");
        }
        const size_t nv = rig->mesh.positions.size();
        std::vector<uint32_t> firstCopy(nv, uint32_t(-1));
        for (size_t f = 0; f < nFile; ++f)
            if (firstCopy[rig->sourceVertex[f]] == uint32_t(-1))
                firstCopy[rig->sourceVertex[f]] = uint32_t(f);
        VertexWeights& vw = sk.weights;
        vw.influences = 4 * sets;
        vw.joints.assign(nv * size_t(vw.influences), 0);
        vw.weights.assign(nv * size_t(vw.influences), 0.0f);
        size_t renormalised = 0;
        for (size_t v = 0; v < nv; ++v) {
            const size_t f = firstCopy[v];
            float sum = 0.0f;
            for (int set = 0; set < sets; ++set)
                for (int k = 0; k < 4; ++k) {
                    const uint32_t j = joints[set][4 * f + size_t(k)];
                    const float w = weights[set][4 * f + size_t(k)];
                    if (w != 0.0f && j >= sk.skin.joints.size())
                        return Status(StatusCode::InvalidData, path + ": vertex " + std::to_string(f) +
                                                                   " is skinned to joint " + std::to_string(j) +
                                                                   " of a " + std::to_string(sk.skin.joints.size()) +
                                                                   "-joint skin");
                    if (w < 0.0f)
                        return Status(StatusCode::InvalidData, path + ": vertex " + std::to_string(f) +
                                                                   " has a negative skin weight");
                    const size_t slot = v * size_t(vw.influences) + size_t(4 * set + k);
                    vw.joints[slot] = uint16_t(w != 0.0f ? j : 0);
                    vw.weights[slot] = w;
                    sum += w;
                }
            if (!(sum > 0.0f))
                return Status(StatusCode::InvalidData, path + ": vertex " + std::to_string(f) + " has no skin weight");
            if (std::fabs(sum - 1.0f) > 1e-3f) {
                ++renormalised;
                for (int k = 0; k < vw.influences; ++k)
                    vw.weights[v * size_t(vw.influences) + size_t(k)] /= sum;
            }
        }
        if (renormalised)
            rig->warnings.push_back(std::to_string(renormalised) +
                                    " vertices had skin weights not summing to 1; renormalised");
    }
    for (size_t a = 0; a < model.animations.size(); ++a) {
        const tinygltf::Animation& in = model.animations[a];
        Animation anim;
        anim.name = in.name.empty() ? "animation" + std::to_string(a) : in.name;
        if (in.samplers.empty() || in.channels.empty())
            return Status(StatusCode::InvalidData, path + ": animation " + std::to_string(a) + " (" + anim.name +
                                                       ") has no samplers or channels");
        for (const tinygltf::AnimationChannel& ch : in.channels) {
            if (ch.target_path == "weights") {
                rig->warnings.push_back("animation " + anim.name + ": morph-target weights are not supported, ignored");
                continue;
            }
            if (ch.sampler < 0 || size_t(ch.sampler) >= in.samplers.size())
                return Status(StatusCode::InvalidData, path + ": animation " + anim.name + " has a channel without a sampler");
            const tinygltf::AnimationSampler& sa = in.samplers[size_t(ch.sampler)];
            AnimationChannel c;
            c.node = ch.target_node;
            if (ch.target_path == "translation")
                c.path = AnimationPath::Translation;
            else if (ch.target_path == "rotation")
                c.path = AnimationPath::Rotation;
            else if (ch.target_path == "scale")
                c.path = AnimationPath::Scale;
            else
                return Status(StatusCode::InvalidData, path + ": animation " + anim.name + " has an unknown path '" +
                                                           ch.target_path + "'");
            if (sa.interpolation == "LINEAR" || sa.interpolation.empty())
                c.interpolation = AnimationInterpolation::Linear;
            else if (sa.interpolation == "STEP")
                c.interpolation = AnimationInterpolation::Step;
            else if (sa.interpolation == "CUBICSPLINE")
                c.interpolation = AnimationInterpolation::CubicSpline;
            else
                return Status(StatusCode::InvalidData, path + ": animation " + anim.name + " has an unknown interpolation");
            const std::string what = "animation " + anim.name;
            if (!(st = readFloatAccessor(model, sa.input, 1, what + " key times", &c.times)) ||
                !(st = readFloatAccessor(model, sa.output, c.path == AnimationPath::Rotation ? 4 : 3, what + " key values",
                                         &c.values)))
                return Status(st.code(), path + ": " + st.message());
            anim.channels.push_back(std::move(c));
        }
        if (!anim.channels.empty())
            sk.animations.push_back(std::move(anim));
    }
    if (!(st = finalizeSkeleton(&sk, rig->mesh.positions.size())))
        return Status(st.code(), path + ": " + st.message());
    return Status::ok();
}

Status loadGltfTriangles(const std::string& path, std::vector<glm::vec3>* positions, std::vector<uint32_t>* triangles)
{
    tinygltf::Model model;
    LoadedPrimitive prim;
    Status st = loadPrimitive(path, &model, &prim);
    if (!st)
        return st;
    if (prim.rig.mesh.triangles.empty())
        return Status(StatusCode::InvalidData, path + ": every triangle is degenerate");
    *positions = std::move(prim.rig.mesh.positions);
    *triangles = std::move(prim.rig.mesh.triangles);
    return Status::ok();
}

Status loadRig(const std::string& path, Rig* out)
{
    tinygltf::Model model;
    LoadedPrimitive prim;
    Status st = loadPrimitive(path, &model, &prim);
    if (!st)
        return st;
    Rig rig = std::move(prim.rig);
    const tinygltf::Mesh& mesh = model.meshes[size_t(prim.meshIndex)];
    if (!(st = validateControlMesh(rig.mesh)))
        return Status(st.code(), path + ": " + st.message());
    const tinygltf::Primitive* triangles = nullptr;
    for (const tinygltf::Primitive& p : mesh.primitives)
        if (!triangles && (p.mode == TINYGLTF_MODE_TRIANGLES || p.mode == -1))
            triangles = &p;
    if (!(st = loadSkeleton(path, model, prim.meshIndex, *triangles, &rig)))
        return st;

    if (const tinygltf::Value* block = member(mesh.extras, "strata")) {
        if (!(st = parseStrataBlock(*block, path, &rig.displacement)))
            return st;
        if (!rig.mesh.hasUVs())
            return Status(StatusCode::InvalidData, path + ": the rig has a displacement map but no TEXCOORD_0");
        rig.hasDisplacement = true;
    }
    *out = std::move(rig);
    return Status::ok();
}

Status loadRigDisplacementMap(const std::string& rigPath, const Rig& rig, DisplacementMap* out)
{
    if (!rig.hasDisplacement)
        return Status(StatusCode::InvalidArgument, rigPath + ": the rig has no displacement map");
    const std::string dir = directoryOf(rigPath);
    const std::string mapPath = dir.empty() ? rig.displacement.uri : dir + "/" + rig.displacement.uri;
    DisplacementMap map;
    Status st = readDisplacementExr(mapPath, &map);
    if (!st)
        return st;
    if (map.width != rig.displacement.width || map.height != rig.displacement.height)
        return Status(StatusCode::InvalidData, mapPath + ": image is " + std::to_string(map.width) + "x" +
                                                   std::to_string(map.height) + " but the rig " + rigPath + " declares " +
                                                   std::to_string(rig.displacement.width) + "x" +
                                                   std::to_string(rig.displacement.height));
    map.factor = rig.displacement.factor;
    map.offset = rig.displacement.offset;
    *out = std::move(map);
    return Status::ok();
}

Status loadRigQuantizedMap(const std::string& rigPath, const Rig& rig, DisplacementMap* out)
{
    const DisplacementInfo::Quantized& q = rig.displacement.quantized;
    if (!rig.hasDisplacement || q.uri.empty())
        return Status(StatusCode::InvalidArgument, rigPath + ": the rig has no quantised map");
    const std::string dir = directoryOf(rigPath);
    const std::string mapPath = dir.empty() ? q.uri : dir + "/" + q.uri;
    DisplacementMap map;
    int bits = 0;
    std::vector<uint16_t> samples;
    Status st = readPngGray(mapPath, &map.width, &map.height, &bits, &samples);
    if (!st)
        return st;
    if (bits != q.bits)
        return Status(StatusCode::InvalidData, mapPath + ": " + std::to_string(bits) + "-bit image, the rig declares " +
                                                   std::to_string(q.bits));
    if (map.width != rig.displacement.width || map.height != rig.displacement.height)
        return Status(StatusCode::InvalidData, mapPath + ": image size differs from the rig's");
    map.texels.assign(samples.begin(), samples.end());
    // Paper eq. 12 inverted: 2^n levels span [dmin, dmax] with the factor 2^n - 1.
    map.factor = (q.dmax - q.dmin) / float((1 << bits) - 1);
    map.offset = q.dmin;
    *out = std::move(map);
    return Status::ok();
}

namespace {

tinygltf::Value strataBlock(const DisplacementInfo& d)
{
    tinygltf::Value::Object tex;
    tex["uri"] = tinygltf::Value(d.uri);
    tex["encoding"] = tinygltf::Value(d.encoding);
    tex["width"] = tinygltf::Value(d.width);
    tex["height"] = tinygltf::Value(d.height);
    tex["texCoord"] = tinygltf::Value(0);
    tinygltf::Value::Object subdivision;
    subdivision["rule"] = tinygltf::Value(std::string("loop"));
    subdivision["boundary"] = tinygltf::Value(std::string("edge-and-corner"));
    subdivision["faceVaryingInterpolation"] = tinygltf::Value(std::string("linear-all"));
    tinygltf::Value::Object block;
    block["version"] = tinygltf::Value(kRigFormatVersion);
    block["displacementGeometryTexture"] = tinygltf::Value(tex);
    block["displacementGeometryFactor"] = tinygltf::Value(double(d.factor));
    block["displacementGeometryOffset"] = tinygltf::Value(double(d.offset));
    block["scheme"] = tinygltf::Value(std::string(schemeName(d.scheme)));
    block["recommendedLevel"] = tinygltf::Value(d.recommendedLevel);
    block["direction"] = tinygltf::Value(std::string("interpolated-control-normal"));
    block["normalWeighting"] = tinygltf::Value(std::string("angle"));
    block["subdivision"] = tinygltf::Value(subdivision);
    if (!d.quantized.uri.empty()) {
        tinygltf::Value::Object q;
        q["uri"] = tinygltf::Value(d.quantized.uri);
        q["bits"] = tinygltf::Value(d.quantized.bits);
        q["dmin"] = tinygltf::Value(double(d.quantized.dmin));
        q["dmax"] = tinygltf::Value(double(d.quantized.dmax));
        block["quantizedMap"] = tinygltf::Value(q);
    }
    return tinygltf::Value(block);
}

}  // namespace

Status saveRig(const std::string& path, const Rig& rig)
{
    const std::string ext = extensionOf(path);
    if (ext != ".glb" && ext != ".gltf")
        return Status(StatusCode::InvalidArgument, path + ": a rig must be written as .glb or .gltf");
    Status st = validateControlMesh(rig.mesh);
    if (!st)
        return Status(st.code(), path + ": " + st.message());
    const ControlMesh& cm = rig.mesh;
    std::vector<glm::vec3> normals(cm.positions.size());
    computeControlNormals(normals.data(), cm.positions.data(), cm.positions.size(), cm.triangles.data(),
                          cm.faceCount());
    MeshView view;
    view.positions = cm.positions.data();
    view.normals = normals.data();
    view.vertexCount = cm.positions.size();
    view.triangles = cm.triangles.data();
    view.faceCount = cm.faceCount();
    if (cm.hasUVs()) {
        view.uvs = cm.uvs.data();
        view.uvCount = cm.uvs.size();
        view.uvIndices = cm.uvIndices.data();
    }
    if (rig.hasDisplacement) {
        const tinygltf::Value block = strataBlock(rig.displacement);
        tinygltf::Value::Object extras;
        extras["strata"] = block;
        const tinygltf::Value value(extras);
        return writeGltfMesh(path, view, "control_mesh", &value, &rig.skeleton);
    }
    return writeGltfMesh(path, view, "control_mesh", nullptr, &rig.skeleton);
}

}  // namespace io
}  // namespace strata
