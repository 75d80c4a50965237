// glTF 2.0 control rigs (docs/FORMAT.md).  Reading assumes hostile input;
// writing produces files the Khronos glTF-Validator accepts without warnings.
//
// A rig is the whole source scene: every triangle primitive of every mesh
// becomes part of one welded control mesh (in the scene's space at rest),
// and the source document is kept so that saving writes back everything the
// input had (materials, textures, names, extras, points and lines) with the
// displacement block and the embedded map added.
#include "strata/io/rig_io.h"

#include "strata/io/exr.h"
#include "strata/io/file.h"
#include "gltf_accessor.h"
#include "strata/io/png.h"
#include "gltf_document.h"
#include "vertex_codec.h"
#include "gltf_mesh_writer.h"
#include "weld.h"
#include "strata/displacement_math.h"
#include "strata/normals.h"

#include <meshoptimizer.h>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>
#include <unordered_map>

namespace strata {
namespace io {
namespace {

// A number from a file as its author wrote it: 9, not 9.000000.
std::string shortNumber(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.9g", v);
    return buf;
}

size_t budgetBytes(const LoadOptions& options)
{
    const double bytes = options.maxMemoryMB * 1024.0 * 1024.0;
    return std::isnan(bytes) || bytes >= double(SIZE_MAX) ? SIZE_MAX : size_t(std::max(0.0, bytes));
}

const tinygltf::Value* member(const tinygltf::Value& obj, const char* name)
{
    if (!obj.IsObject() || !obj.Has(name))
        return nullptr;
    return &obj.Get(name);
}

bool writtenByStrata(const tinygltf::Model& model)
{
    return model.asset.generator.rfind("Strata", 0) == 0;
}

std::string generatorName(const tinygltf::Model& model)
{
    return model.asset.generator.empty() ? std::string("a tool that names no generator")
                                         : "\"" + printable(model.asset.generator, 60) + "\"";
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

// The layer of mesh m and its format version: the declared extension
// (version 5), else the "strata" block of its extras (versions 1 to 4).
const tinygltf::Value* layerBlock(const tinygltf::Mesh& mesh, bool* extension)
{
    auto it = mesh.extensions.find(kLayerExtension);
    *extension = it != mesh.extensions.end();
    if (*extension)
        return &it->second;
    return member(mesh.extras, "strata");
}

Status parseStrataBlock(const tinygltf::Value& block, bool extension, const std::string& path,
                        const tinygltf::Model& model, DisplacementInfo* info)
{
    double version = kRigFormatVersion;
    Status st;
    if (!block.IsObject())
        return Status(StatusCode::InvalidData, path + ": the displacement layer is not a JSON object");
    if (!extension && !(st = numberField(block, "version", path, &version)))
        return st;
    if (!extension && !(version >= 1 && version <= 4 && version == std::floor(version)))
        return Status(StatusCode::Unsupported, path + ": rig format version " + std::to_string(int(version)) +
                                                   " in extras, this build reads versions 1 to 4 there (and " +
                                                   kLayerExtension + ")");
    // Version 4 may leave out the texture object of per-vertex values
    // without UVs, and the fields that have one value (docs/FORMAT.md).
    const tinygltf::Value* vertexBlock = version >= 3 ? member(block, "displacementVertices") : nullptr;
    const tinygltf::Value* tex = member(block, "displacementGeometryTexture");
    const tinygltf::Value none{tinygltf::Value::Object()};
    const bool texOmitted = !tex && version >= 4 && vertexBlock;
    if (texOmitted)
        tex = &none;
    if (!tex || !tex->IsObject())
        return Status(StatusCode::InvalidData, path + ": strata metadata has no displacementGeometryTexture object");
    double w = 0, h = 0, texCoord = 0, factor = 0, offset = 0, level = 0;
    std::string scheme, direction = "interpolated-control-normal", weighting = "angle";
    const tinygltf::Value* image = member(*tex, "image");
    if (version >= 2 && image) {
        if (!image->IsNumber() || image->GetNumberAsDouble() < 0 ||
            image->GetNumberAsDouble() >= double(model.images.size()))
            return Status(StatusCode::InvalidData, path + ": the displacement block names image " +
                                                       (image->IsNumber() ? std::to_string(int(image->GetNumberAsDouble()))
                                                                          : std::string("?")) +
                                                       ", which the file does not have (the map is missing)");
        info->image = int(image->GetNumberAsDouble());
        info->uri.clear();
    } else if (const tinygltf::Value* vertices = vertexBlock) {
        double view = -1, vlevel = -1;
        if (!vertices->IsObject())
            return Status(StatusCode::InvalidData, path + ": displacementVertices is not an object");
        if (!(st = numberField(*vertices, extension ? "accessor" : "bufferView", path, &view)) ||
            !(st = numberField(*vertices, "level", path, &vlevel)))
            return st;
        const size_t available = extension ? model.accessors.size() : model.bufferViews.size();
        if (view < 0 || view >= double(available) || view != std::floor(view))
            return Status(StatusCode::InvalidData, path + ": displacementVertices names " +
                                                       (extension ? "an accessor" : "a bufferView") +
                                                       " the file does not have (the displacements are missing)");
        if (vlevel < 0 || vlevel > kMaxLevel || vlevel != std::floor(vlevel))
            return Status(StatusCode::InvalidData, path + ": displacementVertices level " + shortNumber(vlevel) +
                                                       " is outside 0.." + std::to_string(kMaxLevel));
        const tinygltf::Value* coding = member(*vertices, "coding");
        if (coding && (!coding->IsString() || coding->Get<std::string>() != "subdivision-midpoint-zstd"))
            return Status(StatusCode::Unsupported,
                          path + ": displacementVertices coding \"" +
                              printable(coding->IsString() ? coding->Get<std::string>() : std::string("?"), 40) +
                              "\" is not supported (this build reads \"subdivision-midpoint-zstd\")");
        (extension ? info->vertexAccessor : info->vertexView) = int(view);
        info->vertexLevel = int(vlevel);
        info->uri.clear();
    } else if (!(st = stringField(*tex, "uri", path, &info->uri))) {
        return st;
    }
    // A vertex-coded rig may have no UVs at all (texCoord absent): the
    // values are then its only form of the map.
    const bool uvless = info->vertexLevel >= 0 && !member(*tex, "texCoord");
    if (texOmitted) {
        info->encoding = "vertex";
    } else if (!(st = stringField(*tex, "encoding", path, &info->encoding)) ||
               !(st = numberField(*tex, "width", path, &w)) || !(st = numberField(*tex, "height", path, &h))) {
        return st;
    }
    if ((!uvless && !(st = numberField(*tex, "texCoord", path, &texCoord))) ||
        !(st = numberField(block, "displacementGeometryFactor", path, &factor)) ||
        !(st = numberField(block, "displacementGeometryOffset", path, &offset)) ||
        !(st = stringField(block, "scheme", path, &scheme)) ||
        !(st = numberField(block, "recommendedLevel", path, &level)) ||
        ((version < 4 || member(block, "direction")) && !(st = stringField(block, "direction", path, &direction))) ||
        ((version < 4 || member(block, "normalWeighting")) &&
         !(st = stringField(block, "normalWeighting", path, &weighting))))
        return st;
    if (info->vertexLevel >= 0) {
        if (info->encoding != "vertex")
            return Status(StatusCode::InvalidData, path + ": displacementVertices with encoding \"" +
                                                       printable(info->encoding, 40) + "\" (expected \"vertex\")");
    } else if (info->image < 0) {
        if (info->uri.empty() || info->uri.find("..") != std::string::npos || info->uri[0] == '/' ||
            info->uri.find(':') != std::string::npos || info->uri.find('\\') != std::string::npos)
            return Status(StatusCode::InvalidData, path + ": displacement map URI \"" + printable(info->uri, 80) +
                                                       "\" must be a relative path beside the rig");
        if (info->encoding != "exr")
            return Status(StatusCode::Unsupported, path + ": displacement encoding \"" + printable(info->encoding, 40) +
                                                       "\" is not supported for an external map (this build reads \"exr\")");
    } else if (info->encoding != "png16" && info->encoding != "png8") {
        return Status(StatusCode::Unsupported, path + ": embedded displacement encoding \"" +
                                                   printable(info->encoding, 40) + "\" is not supported (png8, png16)");
    }
    if (!texOmitted && (w < 1 || h < 1 || w > kMaxDisplacementMapSize || h > kMaxDisplacementMapSize ||
                        w != std::floor(w) || h != std::floor(h)))
        return Status(StatusCode::InvalidData, path + ": displacement map size " + std::to_string(w) + "x" +
                                                   std::to_string(h) + " is invalid");
    if (texCoord < 0 || texCoord > 7 || texCoord != std::floor(texCoord))
        return Status(StatusCode::Unsupported, path + ": displacement texCoord must be 0..7");
    if (!parseScheme(scheme, &info->scheme))
        return Status(StatusCode::Unsupported, path + ": unknown subdivision scheme \"" + printable(scheme, 40) + "\"");
    if (level < 0 || level > kMaxLevel || level != std::floor(level))
        return Status(StatusCode::InvalidData, path + ": recommendedLevel " + std::to_string(level) + " is outside 0.." +
                                                   std::to_string(kMaxLevel));
    if (direction != "interpolated-control-normal")
        return Status(StatusCode::Unsupported, path + ": displacement direction \"" + printable(direction, 40) +
                                                   "\" is not supported");
    if (weighting != "angle")
        return Status(StatusCode::Unsupported, path + ": normal weighting \"" + printable(weighting, 40) +
                                                   "\" is not supported");
    if (const tinygltf::Value* q = member(block, "quantizedMap")) {
        double bits = 0, dmin = 0, dmax = 0;
        if (!(st = stringField(*q, "uri", path, &info->quantized.uri)) || !(st = numberField(*q, "bits", path, &bits)) ||
            !(st = numberField(*q, "dmin", path, &dmin)) || !(st = numberField(*q, "dmax", path, &dmax)))
            return st;
        if ((bits != 8 && bits != 16) || !(dmax >= dmin))
            return Status(StatusCode::InvalidData, path + ": quantizedMap needs bits 8 or 16 and dmin <= dmax");
        if (info->quantized.uri.find("..") != std::string::npos || info->quantized.uri.find(':') != std::string::npos ||
            (!info->quantized.uri.empty() && info->quantized.uri[0] == '/'))
            return Status(StatusCode::InvalidData, path + ": quantizedMap URI must be a relative path beside the rig");
        info->quantized.bits = int(bits);
        info->quantized.dmin = float(dmin);
        info->quantized.dmax = float(dmax);
    }
    info->width = int(w);
    info->height = int(h);
    info->texCoord = uvless ? -1 : int(texCoord);
    info->factor = float(factor);
    info->offset = float(offset);
    info->recommendedLevel = int(level);
    return Status::ok();
}



// 64-bit FNV-1a of `size` bytes, continuing from `h`.
uint64_t fnvBytes(uint64_t h, const void* data, size_t size)
{
    const unsigned char* b = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i)
        h = (h ^ b[i]) * 0x100000001b3ull;
    return h;
}

constexpr uint64_t kFnvOffset = 0xcbf29ce484222325ull;

uint64_t uvHash(const std::vector<glm::vec2>& uvs)
{
    return fnvBytes(kFnvOffset, uvs.data(), uvs.size() * sizeof(glm::vec2));
}

glm::mat4 localMatrix(const tinygltf::Node& n)
{
    glm::mat4 m(1.0f);
    if (n.matrix.size() == 16) {
        for (int k = 0; k < 16; ++k)
            m[k / 4][k % 4] = float(n.matrix[size_t(k)]);
        return m;
    }
    if (n.translation.size() == 3)
        m = glm::translate(m, glm::vec3(float(n.translation[0]), float(n.translation[1]), float(n.translation[2])));
    if (n.rotation.size() == 4)
        m = m * glm::mat4_cast(glm::quat(float(n.rotation[3]), float(n.rotation[0]), float(n.rotation[1]),
                                         float(n.rotation[2])));
    if (n.scale.size() == 3)
        m = glm::scale(m, glm::vec3(float(n.scale[0]), float(n.scale[1]), float(n.scale[2])));
    return m;
}

// Every node's parent and its world matrix at rest.  A node with two
// parents, a missing child or a cycle is an error.
Status restWorldMatrices(const std::string& path, const tinygltf::Model& model, std::vector<int>* parentOut,
                         std::vector<glm::mat4>* world)
{
    const size_t n = model.nodes.size();
    std::vector<int> parent(n, -1);
    for (size_t i = 0; i < n; ++i)
        for (int c : model.nodes[i].children) {
            if (c < 0 || size_t(c) >= n)
                return Status(StatusCode::InvalidData, path + ": node " + std::to_string(i) + " has a missing child");
            if (parent[size_t(c)] >= 0 || size_t(c) == i)
                return Status(StatusCode::InvalidData, path + ": node " + std::to_string(c) + " has two parents");
            parent[size_t(c)] = int(i);
        }
    world->assign(n, glm::mat4(1.0f));
    std::vector<uint8_t> state(n, 0);  // 0 unvisited, 1 on the current chain, 2 done
    std::vector<size_t> chain;
    for (size_t i = 0; i < n; ++i) {
        chain.clear();
        int v = int(i);
        while (v >= 0 && state[size_t(v)] == 0) {
            state[size_t(v)] = 1;
            chain.push_back(size_t(v));
            v = parent[size_t(v)];
        }
        if (v >= 0 && state[size_t(v)] == 1)
            return Status(StatusCode::InvalidData, path + ": the node hierarchy has a cycle through node " +
                                                       std::to_string(v));
        for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
            const int p = parent[*it];
            (*world)[*it] = (p >= 0 ? (*world)[size_t(p)] : glm::mat4(1.0f)) * localMatrix(model.nodes[*it]);
            state[*it] = 2;
        }
    }
    for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < 16; ++k)
            if (!std::isfinite((*world)[i][k / 4][k % 4]))
                return Status(StatusCode::InvalidData, path + ": node " + std::to_string(i) + " (" +
                                                           printable(model.nodes[i].name, 60) +
                                                           ") has a non-finite transform");
    *parentOut = std::move(parent);
    return Status::ok();
}

int attributeOf(const tinygltf::Primitive& prim, const std::string& name)
{
    auto it = prim.attributes.find(name);
    return it == prim.attributes.end() ? -1 : it->second;
}

bool isTriangles(int mode)
{
    return mode == TINYGLTF_MODE_TRIANGLES || mode == -1 || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
           mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

// Triangle-list indices of a triangle primitive (strips and fans unrolled).
Status primitiveTriangles(const tinygltf::Model& model, const tinygltf::Primitive& prim, size_t vertexCount,
                          const std::string& what, std::vector<uint32_t>* out)
{
    std::vector<uint32_t> idx;
    if (prim.indices >= 0) {
        Status st = readUintAccessor(model, prim.indices, 1, what + " indices", &idx);
        if (!st)
            return st;
    } else {
        idx.resize(vertexCount);
        for (size_t i = 0; i < vertexCount; ++i)
            idx[i] = uint32_t(i);
    }
    for (size_t i = 0; i < idx.size(); ++i)
        if (idx[i] >= vertexCount)
            return Status(StatusCode::InvalidData, what + ": index " + std::to_string(idx[i]) + " at position " +
                                                       std::to_string(i) + " is beyond the " +
                                                       std::to_string(vertexCount) + " vertices");
    out->clear();
    if (prim.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 2; i < idx.size(); ++i) {
            if (i % 2 == 0)
                out->insert(out->end(), {idx[i - 2], idx[i - 1], idx[i]});
            else
                out->insert(out->end(), {idx[i - 1], idx[i - 2], idx[i]});
        }
    } else if (prim.mode == TINYGLTF_MODE_TRIANGLE_FAN) {
        for (size_t i = 2; i < idx.size(); ++i)
            out->insert(out->end(), {idx[0], idx[i - 1], idx[i]});
    } else {
        if (idx.size() % 3 != 0)
            return Status(StatusCode::InvalidData, what + ": " + std::to_string(idx.size()) +
                                                       " indices, not a multiple of 3");
        *out = std::move(idx);
    }
    return Status::ok();
}

// The whole scene's triangle geometry, welded, with one part per primitive.
struct SceneGeometry {
    Rig rig;                 // mesh (not yet validated), sourceVertex, fileCorners, parts
    std::vector<const tinygltf::Primitive*> primitives;  // per part
    int blockMesh = -1;      // a mesh carrying a displacement layer, or -1
    bool blockIsExtension = false;  // the layer is STRATA_layered_displacement (else extras.strata)
    size_t passThrough = 0;  // point and line primitives, kept untouched
    size_t missingUV = 0;    // triangle parts without the displacement UV set
    std::string firstMissingUV;
};

Status readSceneGeometry(const std::string& path, const SourceDocument& doc, SceneGeometry* out)
{
    const tinygltf::Model& model = doc.model;
    std::vector<int> parent;
    std::vector<glm::mat4> world;
    Status st = restWorldMatrices(path, model, &parent, &world);
    if (!st)
        return st;
    // The block: version 1 rigs carry it on the one mesh they displace.
    int texCoord = 0;
    bool legacy = false;
    for (size_t m = 0; m < model.meshes.size() && out->blockMesh < 0; ++m)
        if (const tinygltf::Value* block = layerBlock(model.meshes[m], &out->blockIsExtension)) {
            out->blockMesh = int(m);
            const tinygltf::Value* v = member(*block, "version");
            legacy = v && v->IsNumber() && v->GetNumberAsDouble() == 1.0;
            const tinygltf::Value* tex = member(*block, "displacementGeometryTexture");
            const tinygltf::Value* tc = tex ? member(*tex, "texCoord") : nullptr;
            if (tc && tc->IsNumber() && tc->GetNumberAsDouble() >= 0 && tc->GetNumberAsDouble() <= 7)
                texCoord = int(tc->GetNumberAsDouble());
            else if (!tc && member(*block, "displacementVertices"))
                texCoord = -1;  // per-vertex values without UVs
        }
    std::vector<int> firstNode(model.meshes.size(), -1);
    for (size_t i = 0; i < model.nodes.size(); ++i) {
        const int m = model.nodes[i].mesh;
        if (m >= 0 && size_t(m) < model.meshes.size() && firstNode[size_t(m)] < 0)
            firstNode[size_t(m)] = int(i);
        else if (m >= 0 && size_t(m) >= model.meshes.size())
            return Status(StatusCode::InvalidData, path + ": node " + std::to_string(i) + " references missing mesh " +
                                                       std::to_string(m));
    }
    Rig& rig = out->rig;
    std::vector<float> pos;  // all file vertices, scene space
    std::vector<glm::vec2> uv;
    std::vector<uint32_t> tri;  // file-vertex triangles
    std::vector<uint32_t> partOfTri;
    const std::string uvName = "TEXCOORD_" + std::to_string(texCoord);
    for (size_t m = 0; m < model.meshes.size(); ++m) {
        if (legacy && int(m) != out->blockMesh)
            continue;
        const tinygltf::Mesh& mesh = model.meshes[m];
        for (size_t p = 0; p < mesh.primitives.size(); ++p) {
            const tinygltf::Primitive& prim = mesh.primitives[p];
            if (!isTriangles(prim.mode)) {
                ++out->passThrough;
                continue;
            }
            RigPart part;
            part.mesh = int(m);
            part.primitive = int(p);
            part.node = firstNode[m];
            part.material = prim.material;
            part.skinned = part.node >= 0 && model.nodes[size_t(part.node)].skin >= 0;
            part.toScene = part.node >= 0 && !part.skinned ? world[size_t(part.node)] : glm::mat4(1.0f);
            part.name = (mesh.name.empty() ? "mesh " + std::to_string(m) : "mesh " + printable(mesh.name, 60)) +
                        " primitive " + std::to_string(p);
            const std::string what = path + ": " + part.name;
            if (attributeOf(prim, "POSITION") < 0)
                return Status(StatusCode::InvalidData, what + " has no POSITION attribute");
            std::vector<float> ppos, puv;
            if (!(st = readFloatAccessor(model, attributeOf(prim, "POSITION"), 3, "POSITION", &ppos)))
                return Status(st.code(), what + ": " + st.message());
            const size_t n = ppos.size() / 3;
            if (n == 0)
                continue;
            if (pos.size() / 3 + n >= 0x7fffffffu)
                return Status(StatusCode::InvalidData, path + ": the scene has too many vertices");
            const int uvAcc = texCoord >= 0 ? attributeOf(prim, uvName) : -1;
            if (uvAcc >= 0) {
                if (!(st = readFloatAccessor(model, uvAcc, 2, uvName, &puv)))
                    return Status(st.code(), what + ": " + st.message());
                if (puv.size() / 2 != n)
                    return Status(StatusCode::InvalidData, what + ": " + uvName + " has " +
                                                               std::to_string(puv.size() / 2) + " elements for " +
                                                               std::to_string(n) + " vertices");
            } else if (out->missingUV++ == 0) {
                out->firstMissingUV = part.name;
            }
            std::vector<uint32_t> ptri;
            if (!(st = primitiveTriangles(model, prim, n, what, &ptri)))
                return st;
            part.firstVertex = uint32_t(pos.size() / 3);
            part.vertexCount = uint32_t(n);
            for (size_t i = 0; i < n; ++i) {
                const glm::vec4 q = part.toScene * glm::vec4(ppos[3 * i], ppos[3 * i + 1], ppos[3 * i + 2], 1.0f);
                if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z))
                    return Status(StatusCode::InvalidData, what + ": vertex " + std::to_string(i) +
                                                               " is not finite in the scene's space");
                pos.insert(pos.end(), {q.x, q.y, q.z});
                uv.push_back(puv.empty() ? glm::vec2(0.0f) : glm::vec2(puv[2 * i], puv[2 * i + 1]));
            }
            for (uint32_t i : ptri) {
                tri.push_back(part.firstVertex + i);
                if (tri.size() % 3 == 0)
                    partOfTri.push_back(uint32_t(rig.parts.size()));
            }
            out->primitives.push_back(&prim);
            rig.parts.push_back(std::move(part));
        }
    }
    if (rig.parts.empty())
        return Status(StatusCode::InvalidData, path + ": no triangle mesh in the file");
    const size_t nFile = pos.size() / 3;
    if (nFile == 0)
        return Status(StatusCode::InvalidData, path + ": the meshes have no vertices");

    // Weld file vertices into topological vertices (exact position match, over
    // every primitive: coincident vertices of different primitives join, so the
    // refined surface is watertight wherever the input is).
    weldByPosition(reinterpret_cast<const glm::vec3*>(pos.data()), nFile, &rig.sourceVertex, &rig.mesh.positions);
    const bool withUV = out->missingUV == 0;
    for (size_t t = 0; t < tri.size(); t += 3) {
        const uint32_t a = rig.sourceVertex[tri[t]], b = rig.sourceVertex[tri[t + 1]], c = rig.sourceVertex[tri[t + 2]];
        RigPart& part = rig.parts[partOfTri[t / 3]];
        if (part.faceCount == 0)
            part.firstFace = uint32_t(rig.mesh.triangles.size() / 3);
        if (a == b || b == c || a == c)
            continue;  // zero area after welding: no surface to refine (the file keeps it)
        rig.mesh.triangles.insert(rig.mesh.triangles.end(), {a, b, c});
        rig.fileCorners.insert(rig.fileCorners.end(), {tri[t], tri[t + 1], tri[t + 2]});
        ++part.faceCount;
    }
    if (withUV) {
        rig.mesh.uvs = std::move(uv);
        rig.mesh.uvIndices = rig.fileCorners;
        rig.fileTexCoord = texCoord;
        rig.fileUVHash = uvHash(rig.mesh.uvs);
    }
    return Status::ok();
}

}  // namespace

namespace {

// Nodes, the skin of the skinned parts (rigid parts ride on their node as an
// extra joint), per-vertex influences and animations.
Status loadSkeleton(const std::string& path, const tinygltf::Model& model, const SceneGeometry& scene, Rig* rig)
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
            out.matrix = localMatrix(n);
        }
        if (n.translation.size() == 3)
            out.rest.translation = glm::vec3(float(n.translation[0]), float(n.translation[1]), float(n.translation[2]));
        if (n.rotation.size() == 4)
            out.rest.rotation = glm::quat(float(n.rotation[3]), float(n.rotation[0]), float(n.rotation[1]),
                                          float(n.rotation[2]));
        if (n.scale.size() == 3)
            out.rest.scale = glm::vec3(float(n.scale[0]), float(n.scale[1]), float(n.scale[2]));
        for (int c : n.children)
            sk.nodes[size_t(c)].parent = int(i);  // checked by restWorldMatrices
    }
    int skinIndex = -1;
    for (const RigPart& part : rig->parts)
        if (part.skinned) {
            const int s = model.nodes[size_t(part.node)].skin;
            if (skinIndex < 0) {
                skinIndex = s;
                sk.meshNode = part.node;
            } else if (s != skinIndex) {
                return Status(StatusCode::Unsupported, path + ": meshes use different skins (" + std::to_string(skinIndex) +
                                                           " and " + std::to_string(s) +
                                                           "); a Strata rig has one skin");
            }
        }
    Status st;
    if (skinIndex >= 0) {
        if (size_t(skinIndex) >= model.skins.size())
            return Status(StatusCode::InvalidData, path + ": a mesh node references missing skin " +
                                                       std::to_string(skinIndex));
        const tinygltf::Skin& skin = model.skins[size_t(skinIndex)];
        sk.skin.joints = skin.joints;
        if (sk.skin.joints.empty())
            return Status(StatusCode::InvalidData, path + ": skin " + std::to_string(skinIndex) + " has no joints");
        for (int j : sk.skin.joints)
            if (j < 0 || size_t(j) >= nn)
                return Status(StatusCode::InvalidData, path + ": skin " + std::to_string(skinIndex) +
                                                           " names missing node " + std::to_string(j));
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
        } else {
            sk.skin.inverseBindMatrices.assign(sk.skin.joints.size(), glm::mat4(1.0f));
        }
        // Influences per file vertex, then per topological vertex (its first copy).
        int sets = 1;
        for (size_t p = 0; p < rig->parts.size(); ++p)
            if (rig->parts[p].skinned && attributeOf(*scene.primitives[p], "JOINTS_1") >= 0 &&
                attributeOf(*scene.primitives[p], "WEIGHTS_1") >= 0)
                sets = 2;
        const int inf = 4 * sets;
        const size_t nFile = rig->sourceVertex.size();
        std::vector<uint16_t> fileJoints(nFile * size_t(inf), 0);
        std::vector<float> fileWeights(nFile * size_t(inf), 0.0f);
        std::map<int, uint16_t> rigidJoint;  // node -> its extra joint
        for (size_t p = 0; p < rig->parts.size(); ++p) {
            const RigPart& part = rig->parts[p];
            const tinygltf::Primitive& prim = *scene.primitives[p];
            if (!part.skinned) {
                // A rigid part follows its node: one extra joint whose inverse
                // bind matrix undoes the node's rest transform.
                uint16_t j = 0;
                if (part.node >= 0) {
                    auto it = rigidJoint.find(part.node);
                    if (it == rigidJoint.end()) {
                        if (sk.skin.joints.size() >= 0xffff)
                            return Status(StatusCode::InvalidData, path + ": too many joints");
                        it = rigidJoint.emplace(part.node, uint16_t(sk.skin.joints.size())).first;
                        sk.skin.joints.push_back(part.node);
                        sk.skin.inverseBindMatrices.push_back(glm::inverse(part.toScene));
                    }
                    j = it->second;
                }
                for (uint32_t v = 0; v < part.vertexCount; ++v) {
                    fileJoints[size_t(part.firstVertex + v) * size_t(inf)] = j;
                    fileWeights[size_t(part.firstVertex + v) * size_t(inf)] = 1.0f;
                }
                continue;
            }
            if (attributeOf(prim, "JOINTS_0") < 0 || attributeOf(prim, "WEIGHTS_0") < 0)
                return Status(StatusCode::InvalidData, path + ": " + part.name + " is skinned but has no JOINTS_0/WEIGHTS_0");
            for (int set = 0; set < sets; ++set) {
                const std::string js = "JOINTS_" + std::to_string(set), ws = "WEIGHTS_" + std::to_string(set);
                if (attributeOf(prim, js) < 0 || attributeOf(prim, ws) < 0)
                    continue;
                std::vector<uint32_t> joints;
                std::vector<float> weights;
                if (!(st = readUintAccessor(model, attributeOf(prim, js), 4, js, &joints)) ||
                    !(st = readFloatAccessor(model, attributeOf(prim, ws), 4, ws, &weights)))
                    return Status(st.code(), path + ": " + part.name + ": " + st.message());
                if (joints.size() != 4 * size_t(part.vertexCount) || weights.size() != joints.size())
                    return Status(StatusCode::InvalidData, path + ": " + part.name + ": " + js + "/" + ws +
                                                               " do not have one element per vertex");
                for (uint32_t v = 0; v < part.vertexCount; ++v)
                    for (int k = 0; k < 4; ++k) {
                        const uint32_t j = joints[4 * v + uint32_t(k)];
                        const float w = weights[4 * v + uint32_t(k)];
                        if (w != 0.0f && j >= skin.joints.size())
                            return Status(StatusCode::InvalidData, path + ": " + part.name + ": vertex " +
                                                                       std::to_string(v) + " is skinned to joint " +
                                                                       std::to_string(j) + " of a " +
                                                                       std::to_string(skin.joints.size()) +
                                                                       "-joint skin");
                        if (!(w >= 0.0f))
                            return Status(StatusCode::InvalidData, path + ": " + part.name + ": vertex " +
                                                                       std::to_string(v) + " has a negative skin weight");
                        const size_t slot = size_t(part.firstVertex + v) * size_t(inf) + size_t(4 * set + k);
                        fileJoints[slot] = uint16_t(w != 0.0f ? j : 0);
                        fileWeights[slot] = w;
                    }
            }
        }
        const size_t nv = rig->mesh.positions.size();
        std::vector<uint32_t> firstCopy(nv, uint32_t(-1));
        for (size_t f = 0; f < nFile; ++f)
            if (firstCopy[rig->sourceVertex[f]] == uint32_t(-1))
                firstCopy[rig->sourceVertex[f]] = uint32_t(f);
        VertexWeights& vw = sk.weights;
        vw.influences = inf;
        vw.joints.assign(nv * size_t(inf), 0);
        vw.weights.assign(nv * size_t(inf), 0.0f);
        size_t renormalised = 0;
        for (size_t v = 0; v < nv; ++v) {
            const size_t f = firstCopy[v];
            float sum = 0.0f;
            for (int k = 0; k < inf; ++k) {
                vw.joints[v * size_t(inf) + size_t(k)] = fileJoints[f * size_t(inf) + size_t(k)];
                sum += vw.weights[v * size_t(inf) + size_t(k)] = fileWeights[f * size_t(inf) + size_t(k)];
            }
            if (!(sum > 0.0f) || !std::isfinite(sum))
                return Status(StatusCode::InvalidData, path + ": file vertex " + std::to_string(f) +
                                                           " has no usable skin weight");
            if (std::fabs(sum - 1.0f) > 1e-3f) {
                ++renormalised;
                for (int k = 0; k < inf; ++k)
                    vw.weights[v * size_t(inf) + size_t(k)] /= sum;
            }
        }
        if (renormalised)
            rig->warnings.push_back(std::to_string(renormalised) +
                                    " vertices had skin weights not summing to 1; renormalised");
        if (!rigidJoint.empty())
            rig->warnings.push_back(std::to_string(rigidJoint.size()) +
                                    " unskinned mesh nodes follow their node as rigid parts");
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
                rig->warnings.push_back("animation " + printable(anim.name, 60) + ": morph-target weights are not supported, ignored");
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
                                                           printable(ch.target_path, 40) + "'");
            if (sa.interpolation == "LINEAR" || sa.interpolation.empty())
                c.interpolation = AnimationInterpolation::Linear;
            else if (sa.interpolation == "STEP")
                c.interpolation = AnimationInterpolation::Step;
            else if (sa.interpolation == "CUBICSPLINE")
                c.interpolation = AnimationInterpolation::CubicSpline;
            else
                return Status(StatusCode::InvalidData, path + ": animation " + anim.name + " has an unknown interpolation");
            const std::string what = "animation " + printable(anim.name, 60);
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

}  // namespace

Status loadGltfTriangles(const std::filesystem::path& pathFile, std::vector<glm::vec3>* positions, std::vector<uint32_t>* triangles,
                         const LoadOptions& options)
{
    const std::string path = pathFile.string();
    SourceDocument doc;
    Status st = loadGltfDocument(path, &doc, budgetBytes(options));
    if (!st)
        return st;
    SceneGeometry scene;
    if (!(st = readSceneGeometry(path, doc, &scene)))
        return st;
    if (scene.rig.mesh.triangles.empty())
        return Status(StatusCode::InvalidData, path + ": every triangle is degenerate");
    *positions = std::move(scene.rig.mesh.positions);
    *triangles = std::move(scene.rig.mesh.triangles);
    return Status::ok();
}

namespace {

// What finishRig does with a layer that does not match its control mesh:
// refuse the file (loadRig), skip the comparison (sealLayer, whose file has
// placeholders yet), or drop the layer with a warning (a control mesh for a
// new bake, whose layer the bake replaces).
enum class LayerCheck { Enforce, Seal, DropStale };

Status finishRig(const std::string& path, std::shared_ptr<SourceDocument> doc, Rig* out,
                 LayerCheck check = LayerCheck::Enforce, size_t maxBytes = size_t(2048) << 20);

// An image no texture uses whose bytes are a 16-bit greyscale PNG.
bool hasOrphanGreyImage(const SourceDocument& doc)
{
    const tinygltf::Model& m = doc.model;
    for (size_t i = 0; i < m.images.size(); ++i) {
        bool used = false;
        for (const tinygltf::Texture& t : m.textures)
            used = used || t.source == int(i);
        if (used)
            continue;
        const tinygltf::Image& im = m.images[i];
        const unsigned char* b = nullptr;
        size_t n = 0;
        if (im.bufferView >= 0 && size_t(im.bufferView) < m.bufferViews.size()) {
            const tinygltf::BufferView& v = m.bufferViews[size_t(im.bufferView)];
            if (v.buffer >= 0 && size_t(v.buffer) < m.buffers.size() &&
                v.byteOffset + 26 <= m.buffers[size_t(v.buffer)].data.size()) {
                b = m.buffers[size_t(v.buffer)].data.data() + v.byteOffset;
                n = std::min<size_t>(v.byteLength, 26);
            }
        } else if (i < doc.imageBytes.size() && doc.imageBytes[i].size() >= 26) {
            b = doc.imageBytes[i].data();
            n = 26;
        }
        // PNG signature, IHDR, then bit depth at byte 24 and colour type at 25.
        if (b && n >= 26 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G' && b[24] == 16 && b[25] == 0)
            return true;
    }
    return false;
}

}  // namespace

size_t characterBytes(const Rig& rig)
{
    if (!rig.source)
        return 0;
    const tinygltf::Model& model = rig.source->model;
    size_t total = 0;
    auto accessorBytes = [&](int a) {
        if (a < 0 || size_t(a) >= model.accessors.size())
            return size_t(0);
        const tinygltf::Accessor& acc = model.accessors[size_t(a)];
        const int c = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
        const int n = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
        return c > 0 && n > 0 ? acc.count * size_t(c) * size_t(n) : size_t(0);
    };
    for (const tinygltf::Animation& an : model.animations)
        for (const tinygltf::AnimationSampler& sa : an.samplers)
            total += accessorBytes(sa.input) + accessorBytes(sa.output);
    for (const tinygltf::Skin& sk : model.skins)
        total += accessorBytes(sk.inverseBindMatrices);
    for (size_t i = 0; i < model.images.size(); ++i) {
        if (int(i) == rig.displacement.image && rig.hasDisplacement)
            continue;
        const int v = model.images[i].bufferView;
        if (v >= 0 && size_t(v) < model.bufferViews.size())
            total += model.bufferViews[size_t(v)].byteLength;
        else if (i < rig.source->imageBytes.size())
            total += rig.source->imageBytes[i].size();
    }
    return total;
}

std::string missingLayerCause(const Rig& rig)
{
    if (!rig.source)
        return "it is a plain mesh file, not a baked rig";
    const tinygltf::Model& model = rig.source->model;
    if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), kLayerExtension) !=
        model.extensionsUsed.end())
        return std::string("it declares ") + kLayerExtension + " but no mesh carries the layer: a tool dropped it";
    if (writtenByStrata(model))
        return "Strata wrote it, but its displacement layer is gone: another tool stripped it";
    return "written by " + generatorName(model) + ", a tool that drops " + kLayerExtension +
           " (gltfpack, Blender, gltf-transform without js/gltf-transform.config.mjs), or never baked";
}

Status loadRig(const std::filesystem::path& pathFile, Rig* out, const LoadOptions& options)
{
    const std::string path = pathFile.string();
    auto doc = std::make_shared<SourceDocument>();
    Status st = loadGltfDocument(path, doc.get(), budgetBytes(options));
    if (!st)
        return st;
    return finishRig(path, std::move(doc), out, LayerCheck::Enforce, budgetBytes(options));
}

Status loadControlForBake(const std::filesystem::path& pathFile, Rig* out, const LoadOptions& options)
{
    const std::string path = pathFile.string();
    auto doc = std::make_shared<SourceDocument>();
    Status st = loadGltfDocument(path, doc.get(), budgetBytes(options));
    if (!st)
        return st;
    return finishRig(path, std::move(doc), out, LayerCheck::DropStale, budgetBytes(options));
}

Status loadRigFromMemory(const unsigned char* data, size_t size, bool binary, const std::string& name, Rig* out,
                         const LoadOptions& options)
{
    auto doc = std::make_shared<SourceDocument>();
    // No folder: a rig in memory has no files beside it.
    Status st =
        parseGltfDocument(data, size, binary, "/nonexistent-strata-folder", name, doc.get(), budgetBytes(options));
    if (!st)
        return st;
    return finishRig(name, std::move(doc), out, LayerCheck::Enforce, budgetBytes(options));
}

namespace {

// The bytes of bufferView `index`, or nullptr when it lies outside its buffer.
const unsigned char* viewBytes(const tinygltf::Model& model, int index)
{
    const tinygltf::BufferView& view = model.bufferViews[size_t(index)];
    if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size() ||
        view.byteOffset > model.buffers[size_t(view.buffer)].data.size() ||
        view.byteLength > model.buffers[size_t(view.buffer)].data.size() - view.byteOffset)
        return nullptr;
    return model.buffers[size_t(view.buffer)].data.data() + view.byteOffset;
}

int blockVersion(const tinygltf::Value& block)
{
    const tinygltf::Value* v = member(block, "version");
    return v && v->IsNumber() ? int(v->GetNumberAsDouble()) : 0;
}

// Whether an extras block reaches its data by index (a bufferView or an
// image) rather than by a URI beside the rig.
bool refersByIndex(const tinygltf::Value& block)
{
    const tinygltf::Value* tex = member(block, "displacementGeometryTexture");
    return member(block, "displacementVertices") || (tex && member(*tex, "image"));
}

std::string hex64(uint64_t v)
{
    char text[17];
    std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(v));
    return text;
}

// The placeholders saveRig writes for the fingerprint's hashes and then
// replaces, in the encoded file, by those of the control mesh that file
// reads back as (the same length, so no offset moves).
const char* const kTopologyToken = "~strata~topolog~";
const char* const kPositionsToken = "~strata~position";
const char* const kShapeToken = "~strata~shape~~~";
const char* const kUVToken = "~strata~uvs~~~~~";

// FNV-1a of the UVs of every face corner, in face order: what a map sampled
// through the UVs depends on (per-vertex values do not).
uint64_t cornerUVHash(const ControlMesh& mesh)
{
    uint64_t h = kFnvOffset;
    for (uint32_t i : mesh.uvIndices) {
        const glm::vec2 uv = i < mesh.uvs.size() ? mesh.uvs[i] : glm::vec2(0.0f);
        h = fnvBytes(h, &uv, sizeof(uv));
    }
    return h;
}

// Refuses a control mesh other than the one the layer was baked on, naming
// what changed (the per-vertex values are numbered by its refinement, and
// the displacement is measured from its surface).
Status checkLayerBinding(const tinygltf::Value& block, const std::string& path, const ControlMesh& mesh,
                         bool checkBinding)
{
    const tinygltf::Value* control = member(block, "control");
    if (!control || !control->IsObject())
        return Status(StatusCode::InvalidData, path + ": the displacement layer does not say which control mesh it was "
                                                   "baked on (no \"control\" object)");
    double vertices = 0, triangles = 0;
    std::string topology, positions, shape;
    Status st;
    if (!(st = numberField(*control, "vertices", path, &vertices)) ||
        !(st = numberField(*control, "triangles", path, &triangles)) ||
        !(st = stringField(*control, "topology", path, &topology)) ||
        !(st = stringField(*control, "positions", path, &positions)) ||
        !(st = stringField(*control, "shape", path, &shape)))
        return st;
    if (!checkBinding)
        return Status::ok();
    const ControlMeshFingerprint f = fingerprintControlMesh(mesh);
    const std::string advice = ": run that step before baking, or bake again";
    if (vertices != double(f.vertices) || triangles != double(f.faces))
        return Status(StatusCode::InvalidData,
                      path + ": the control mesh has " + std::to_string(f.vertices) + " vertices and " +
                          std::to_string(f.faces) + " triangles, but the displacement layer was baked on " +
                          std::to_string(size_t(std::max(0.0, vertices))) + " and " +
                          std::to_string(size_t(std::max(0.0, triangles))) +
                          ": a tool welded, split, simplified or rebuilt it after the bake (weld, simplify, "
                          "optimize, draco)" + advice);
    const bool sameOrder = topology == hex64(f.topology), samePlaces = positions == hex64(f.positions);
    std::string uvs;
    if (sameOrder && samePlaces && member(*control, "uvs") && (st = stringField(*control, "uvs", path, &uvs)) &&
        uvs != hex64(cornerUVHash(mesh)))
        return Status(StatusCode::InvalidData,
                      path + ": the control mesh's UVs changed after the bake (quantize, or a texture coordinate "
                             "edit), and the map is sampled through them" +
                          advice);
    if (sameOrder && samePlaces)
        return Status::ok();
    if (!sameOrder && shape == hex64(f.shape))
        return Status(StatusCode::InvalidData,
                      path + ": the control mesh was renumbered after the bake (weld, unweld, reorder, simplify and "
                             "optimize renumber vertices and triangles; the layer's values follow the baked order)" +
                          advice);
    if (sameOrder)
        return Status(StatusCode::InvalidData,
                      path + ": the control mesh's vertices moved after the bake (quantize, or a lossy re-encoding "
                             "such as draco or meshopt, changes positions; the surface would move with them)" +
                          advice);
    return Status(StatusCode::InvalidData,
                  path + ": the control mesh was renumbered and its vertices moved after the bake (meshopt, draco and "
                         "optimize reorder and quantize it; the layer's values follow the baked mesh)" + advice);
}

// The coded per-vertex values: a bufferView (versions 3 and 4) or an
// accessor of unsigned bytes (version 5).
Status layerVertexBytes(const tinygltf::Model& model, const DisplacementInfo& info, const std::string& path,
                        const unsigned char** bytes, size_t* length)
{
    if (info.vertexAccessor < 0) {
        *bytes = viewBytes(model, info.vertexView);
        *length = *bytes ? model.bufferViews[size_t(info.vertexView)].byteLength : 0;
        if (!*bytes)
            return Status(StatusCode::InvalidData, path + ": the displacements' bufferView is out of range");
        return Status::ok();
    }
    const tinygltf::Accessor& acc = model.accessors[size_t(info.vertexAccessor)];
    const std::string what = path + ": the displacements' accessor " + std::to_string(info.vertexAccessor);
    if (acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE || acc.type != TINYGLTF_TYPE_SCALAR ||
        acc.sparse.isSparse)
        return Status(StatusCode::InvalidData, what + " is not a plain SCALAR accessor of unsigned bytes");
    if (acc.bufferView < 0 || size_t(acc.bufferView) >= model.bufferViews.size())
        return Status(StatusCode::InvalidData, what + " has no bufferView (the displacements are missing)");
    const unsigned char* b = viewBytes(model, acc.bufferView);
    const tinygltf::BufferView& view = model.bufferViews[size_t(acc.bufferView)];
    if (!b || (view.byteStride != 0 && view.byteStride != 1) || acc.byteOffset > view.byteLength ||
        acc.count > view.byteLength - acc.byteOffset)
        return Status(StatusCode::InvalidData, what + " reads past the end of its bufferView");
    *bytes = b + acc.byteOffset;
    *length = acc.count;
    return Status::ok();
}

Status finishRig(const std::string& path, std::shared_ptr<SourceDocument> doc, Rig* out, LayerCheck check,
                 size_t maxBytes)
{
    Status st;
    SceneGeometry scene;
    if (!(st = readSceneGeometry(path, *doc, &scene)))
        return st;
    Rig rig = std::move(scene.rig);
    if (rig.mesh.triangles.empty())
        return Status(StatusCode::InvalidData, path + ": every triangle is degenerate");
    if (!(st = validateControlMesh(rig.mesh)))
        return Status(st.code(), path + ": " + st.message());
    if (!(st = loadSkeleton(path, doc->model, scene, &rig)))
        return st;
    if (scene.passThrough)
        rig.warnings.push_back(std::to_string(scene.passThrough) +
                               " point or line primitives are kept in the file but not refined");
    const tinygltf::Model& model = doc->model;
    // The layer: read whole, or (a control mesh for a new bake) dropped with
    // a warning where it no longer matches, since the bake replaces it.
    auto readLayer = [&]() -> Status {
        bool extension = false;
        const tinygltf::Value& block = *layerBlock(model.meshes[size_t(scene.blockMesh)], &extension);
        // Versions 1 to 4 reach their data by a bufferView or image index in
        // extras, which tools that rewrite glTF renumber without knowing it:
        // after such a tool the index points at other data.
        if (!extension && !writtenByStrata(model) && refersByIndex(block))
            return Status(StatusCode::InvalidData,
                          path + ": a format " + std::to_string(blockVersion(block)) + " rig rewritten by " +
                              generatorName(model) +
                              ", which renumbers the bufferViews and images the layer in extras points at, so it "
                              "no longer finds its displacements: bake again (this strata-bake writes the layer as the "
                              "STRATA_layered_displacement extension, which such tools keep or drop whole)");
        if (!(st = parseStrataBlock(block, extension, path, model, &rig.displacement)))
            return st;
        // Per-vertex values need no UVs: a tool that dropped the set leaves
        // them intact (there is then no map to rasterise for textures).
        if (scene.missingUV && rig.displacement.texCoord >= 0 && rig.displacement.vertexLevel >= 0)
            rig.displacement.texCoord = -1;
        if (scene.missingUV && rig.displacement.texCoord >= 0)
            return Status(StatusCode::InvalidData, path + ": the rig has a displacement map but " + scene.firstMissingUV +
                                                       " has no TEXCOORD_" + std::to_string(rig.displacement.texCoord) +
                                                       " (a tool dropped it: prune, for one, drops texture coordinates "
                                                       "no material uses)");
        if (extension && !(st = checkLayerBinding(block, path, rig.mesh, check != LayerCheck::Seal)))
            return st;
        if (rig.displacement.vertexLevel >= 0) {
            DisplacementInfo& info = rig.displacement;
            const unsigned char* b = nullptr;
            size_t length = 0;
            if (!(st = layerVertexBytes(model, info, path, &b, &length)))
                return st;
            info.embedded.assign(b, b + length);
            // Refining costs per refined triangle, and zstd packs a field of
            // zeros into almost nothing: a level that declares far more
            // triangles than its bytes could plausibly describe is refused
            // before any refinement (a hostile file cannot buy gigabytes).
            const double refined = double(rig.mesh.faceCount()) * std::pow(4.0, info.vertexLevel);
            if (refined > double(1 << 22) && refined > 1024.0 * double(length))
                return Status(StatusCode::InvalidData, path + ": the per-vertex displacements declare level " +
                                                           std::to_string(info.vertexLevel) + " (" +
                                                           std::to_string(size_t(refined)) + " triangles) in only " +
                                                           std::to_string(length) + " bytes");
            // OpenSubdiv's refiner holds every level's topology while the
            // hierarchy is read off it (about 200 bytes per refined vertex,
            // measured), and the values take 4 more.
            const double need = 0.5 * refined * 204.0;
            if (need > double(maxBytes))
                return overBudget(path + ": decoding its level-" + std::to_string(info.vertexLevel) +
                                      " per-vertex displacements (" + std::to_string(size_t(refined)) + " triangles)",
                                  need, maxBytes);
            SubdivisionParents hierarchy;
            if (!(st = buildSubdivisionParents(&hierarchy, rig.mesh, info.vertexLevel)))
                return Status(st.code(), path + ": " + st.message());
            if (!(st = decodeVertexDisplacements(hierarchy, info.embedded.data(), info.embedded.size(), info.factor,
                                                 info.offset, path, &info.vertexValues)))
                return st;
        } else if (rig.displacement.image >= 0) {
            const tinygltf::Image& img = model.images[size_t(rig.displacement.image)];
            if (img.bufferView < 0 || size_t(img.bufferView) >= model.bufferViews.size())
                return Status(StatusCode::InvalidData, path + ": the displacement image " +
                                                           std::to_string(rig.displacement.image) +
                                                           " has no bufferView (the map is missing)");
            const tinygltf::BufferView& view = model.bufferViews[size_t(img.bufferView)];
            const unsigned char* b = viewBytes(model, img.bufferView);
            if (!b)
                return Status(StatusCode::InvalidData, path + ": the displacement image's bufferView is out of range");
            rig.displacement.embedded.assign(b, b + view.byteLength);
        }
        return Status::ok();
    };
    if (scene.blockMesh >= 0 && !(st = readLayer()) && check != LayerCheck::DropStale)
        return st;
    if (scene.blockMesh >= 0 && !st) {
        std::string why = st.message();
        if (why.rfind(path + ": ", 0) == 0)
            why = why.substr(path.size() + 2);
        rig.warnings.push_back("its displacement layer is ignored, since the new bake replaces it: " + why);
        rig.displacement = DisplacementInfo();
    } else if (scene.blockMesh >= 0) {
        rig.hasDisplacement = true;
    } else if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), kLayerExtension) !=
               model.extensionsUsed.end()) {
        rig.warnings.push_back(std::string("declares ") + kLayerExtension +
                               " but no mesh carries the layer (dropped by another tool?): the displacement is gone");
    } else if (writtenByStrata(model)) {
        rig.warnings.push_back("written by " + printable(model.asset.generator, 40) +
                               " but has no displacement layer (stripped by another tool?): the displacement is gone");
    } else if (hasOrphanGreyImage(*doc)) {
        // Tools such as gltfpack drop mesh extras and the generator but keep
        // images: a 16-bit grey PNG no material uses is most likely a map.
        rig.warnings.push_back("holds a 16-bit grey image no material uses but no displacement layer: if it is a "
                               "Strata rig, another tool dropped the layer and the displacement is gone");
    }
    rig.source = std::move(doc);
    if (!rig.hasDisplacement)
        rig.layerMissing = missingLayerCause(rig);
    *out = std::move(rig);
    return Status::ok();
}

}  // namespace

Status loadRigDisplacementMap(const std::filesystem::path& rigPathFile, const Rig& rig, DisplacementMap* out)
{
    const std::string rigPath = rigPathFile.string();
    if (!rig.hasDisplacement)
        return Status(StatusCode::InvalidArgument, rigPath + ": the rig has no displacement map");
    const DisplacementInfo& info = rig.displacement;
    DisplacementMap map;
    std::string mapName;
    if (info.vertexLevel >= 0 && !rig.mesh.hasUVs())
        return Status(StatusCode::InvalidArgument, rigPath + ": the rig stores its displacements per vertex and has no "
                                                             "UVs, so there is no map to rasterise (bake with --exr or "
                                                             "--map-coding png to keep one)");
    if (info.vertexLevel >= 0) {
        // Texture consumers get the map the per-vertex values stand for.
        std::unique_ptr<Plan> plan;  // UVs and topology only: the linear plan is the cheaper one
        Status st = Plan::create(&plan, rig.mesh, Scheme::Linear, info.vertexLevel);
        if (!st)
            return Status(st.code(), rigPath + ": " + st.message());
        map.width = info.width;
        map.height = info.height;
        if (!(st = rasterizeVertexDisplacements(&map, *plan, info.vertexValues)))
            return Status(st.code(), rigPath + ": " + st.message());
        *out = std::move(map);
        return Status::ok();
    }
    if (info.image >= 0) {
        mapName = rigPath + " (embedded displacement image)";
        if (info.embedded.empty())
            return Status(StatusCode::InvalidData, mapName + ": the image is empty");
        int bits = 0;
        std::vector<uint16_t> samples;
        Status st = decodePngGray(info.embedded.data(), info.embedded.size(), mapName, &map.width, &map.height, &bits,
                                  &samples, info.width, info.height);
        if (!st)
            return st;
        if ((info.encoding == "png16") != (bits == 16))
            return Status(StatusCode::InvalidData, mapName + ": a " + std::to_string(bits) + "-bit image, the rig says " +
                                                       info.encoding);
        map.texels.assign(samples.begin(), samples.end());
    } else {
        const std::string dir = directoryOf(rigPath);
        mapName = dir.empty() ? info.uri : dir + "/" + info.uri;
        if (isRegularFile(mapName) && !resolvesInsideFolder(mapName, dir))
            return Status(StatusCode::InvalidData, mapName + ": a symbolic link that leads outside the rig's folder; "
                                                             "the displacement map must resolve inside it");
        if (!isRegularFile(mapName))
            return Status(StatusCode::InvalidData, mapName + ": the rig's displacement map is missing or not a file");
        Status st = readDisplacementExr(mapName, &map, info.width, info.height);
        if (!st)
            return st;
    }
    if (map.width != info.width || map.height != info.height)
        return Status(StatusCode::InvalidData, mapName + ": image is " + std::to_string(map.width) + "x" +
                                                   std::to_string(map.height) + " but the rig " + rigPath + " declares " +
                                                   std::to_string(info.width) + "x" + std::to_string(info.height));
    map.factor = info.factor;
    map.offset = info.offset;
    *out = std::move(map);
    return Status::ok();
}

Status loadRigQuantizedMap(const std::filesystem::path& rigPathFile, const Rig& rig, DisplacementMap* out)
{
    const std::string rigPath = rigPathFile.string();
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
    // Paper eq. 12 inverted: 2^n levels span [dmin, dmax].
    const glm::vec2 decode = shared::strata_dequantize_factor_offset(q.dmin, q.dmax, float(1 << bits));
    map.factor = decode.x;
    map.offset = decode.y;
    *out = std::move(map);
    return Status::ok();
}

namespace {

// The layer as STRATA_layered_displacement writes it (format version 5,
// docs/STRATA_layered_displacement.md): version 4's fields, the coded values
// reached through an accessor, and the control mesh it was baked on, whose
// hashes are placeholders until sealLayer reads the encoded file back.  What
// has one value (direction, normal weighting, subdivision rule, coding) is
// left out, and so is the texture object of per-vertex values without UVs.
tinygltf::Value layerBlockValue(const DisplacementInfo& d, const ControlMesh& mesh)
{
    tinygltf::Value::Object block;
    if (d.vertexLevel < 0 || d.texCoord >= 0) {
        tinygltf::Value::Object tex;
        if (d.image >= 0)
            tex["image"] = tinygltf::Value(d.image);
        else if (d.vertexLevel < 0)
            tex["uri"] = tinygltf::Value(d.uri);
        tex["encoding"] = tinygltf::Value(d.encoding);
        tex["width"] = tinygltf::Value(d.width);
        tex["height"] = tinygltf::Value(d.height);
        if (d.texCoord >= 0)
            tex["texCoord"] = tinygltf::Value(d.texCoord);
        block["displacementGeometryTexture"] = tinygltf::Value(tex);
    }
    block["displacementGeometryFactor"] = tinygltf::Value(jsonFloat(d.factor));
    block["displacementGeometryOffset"] = tinygltf::Value(jsonFloat(d.offset));
    block["scheme"] = tinygltf::Value(std::string(schemeName(d.scheme)));
    block["recommendedLevel"] = tinygltf::Value(d.recommendedLevel);
    if (d.vertexLevel >= 0) {
        tinygltf::Value::Object vertices;
        vertices["accessor"] = tinygltf::Value(d.vertexAccessor);
        vertices["level"] = tinygltf::Value(d.vertexLevel);
        vertices["count"] = tinygltf::Value(int(d.vertexValues.size()));
        block["displacementVertices"] = tinygltf::Value(vertices);
    }
    if (!d.quantized.uri.empty()) {
        tinygltf::Value::Object q;
        q["uri"] = tinygltf::Value(d.quantized.uri);
        q["bits"] = tinygltf::Value(d.quantized.bits);
        q["dmin"] = tinygltf::Value(jsonFloat(d.quantized.dmin));
        q["dmax"] = tinygltf::Value(jsonFloat(d.quantized.dmax));
        block["quantizedMap"] = tinygltf::Value(q);
    }
    tinygltf::Value::Object control;
    control["vertices"] = tinygltf::Value(int(mesh.vertexCount()));
    control["triangles"] = tinygltf::Value(int(mesh.faceCount()));
    control["topology"] = tinygltf::Value(std::string(kTopologyToken));
    control["positions"] = tinygltf::Value(std::string(kPositionsToken));
    control["shape"] = tinygltf::Value(std::string(kShapeToken));
    if (d.vertexLevel < 0 && d.texCoord >= 0)  // a map sampled through the UVs
        control["uvs"] = tinygltf::Value(std::string(kUVToken));
    block["control"] = tinygltf::Value(control);
    return tinygltf::Value(block);
}

// Replaces every placeholder hash in an encoded rig by the fingerprint of
// the control mesh the file reads back as, after checking that it reads
// back with the counts the layer declares.
Status sealLayer(const std::string& path, std::string* bytes)
{
    Rig loaded;
    const bool binary = extensionOf(path) == ".glb";
    auto doc = std::make_shared<SourceDocument>();
    Status st = parseGltfDocument(reinterpret_cast<const unsigned char*>(bytes->data()), bytes->size(), binary,
                                  "/nonexistent-strata-folder", path, doc.get());
    if (!st || !(st = finishRig(path, std::move(doc), &loaded, LayerCheck::Seal)))
        return Status(st.code(), "the rig does not read back: " + st.message());
    const ControlMeshFingerprint f = fingerprintControlMesh(loaded.mesh);
    const std::pair<const char*, std::string> tokens[] = {{kTopologyToken, hex64(f.topology)},
                                                          {kPositionsToken, hex64(f.positions)},
                                                          {kShapeToken, hex64(f.shape)},
                                                          {kUVToken, hex64(cornerUVHash(loaded.mesh))}};
    for (const auto& [token, value] : tokens) {
        size_t at = 0, n = 0;
        while ((at = bytes->find(token, at)) != std::string::npos) {
            bytes->replace(at, value.size(), value);
            ++n;
        }
        if (n == 0 && token != kUVToken)
            return Status(StatusCode::InvalidData, path + ": the layer's control fingerprint is missing from the file");
    }
    return Status::ok();
}

void setStrataExtras(tinygltf::Value* extras, const tinygltf::Value* block);

// Sets (or removes, with a null block) the layer of a mesh, in its
// extensions; any format 1-4 block in extras goes.
void setLayer(tinygltf::Model* model, tinygltf::Mesh* mesh, const tinygltf::Value* block)
{
    if (block)
        mesh->extensions[kLayerExtension] = *block;
    else
        mesh->extensions.erase(kLayerExtension);
    setStrataExtras(&mesh->extras, nullptr);
    bool used = false;
    for (const tinygltf::Mesh& m : model->meshes)
        used = used || m.extensions.count(kLayerExtension);
    auto& list = model->extensionsUsed;
    list.erase(std::remove(list.begin(), list.end(), std::string(kLayerExtension)), list.end());
    if (used)
        list.push_back(kLayerExtension);
}

// Sets (or removes, with a null block) the "strata" member of extras,
// keeping every other member.
void setStrataExtras(tinygltf::Value* extras, const tinygltf::Value* block)
{
    tinygltf::Value::Object obj;
    if (extras->IsObject())
        obj = extras->Get<tinygltf::Value::Object>();
    if (block)
        obj["strata"] = *block;
    else
        obj.erase("strata");
    *extras = obj.empty() ? tinygltf::Value() : tinygltf::Value(obj);
}

// Rewrites a part's primitive with the rig's (new) UVs as TEXCOORD_set:
// vertices split where the new UVs differ, every original vertex kept in
// place, every attribute and morph target carried along.
Status reindexWithUVs(tinygltf::Model& model, const Rig& rig, const RigPart& part, int set, const std::string& path)
{
    tinygltf::Primitive& prim = model.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
    const std::string what = path + ": " + part.name;
    std::vector<uint32_t> tri;
    Status st = primitiveTriangles(model, prim, part.vertexCount, what, &tri);
    if (!st)
        return st;
    const uint32_t none = 0xffffffffu;
    const size_t n = part.vertexCount;
    std::vector<uint32_t> primary(n, none), src(n), indices(tri.size());
    for (size_t i = 0; i < n; ++i)
        src[i] = uint32_t(i);
    std::unordered_map<uint64_t, uint32_t> extra;
    std::vector<uint32_t> uvOf(n, none);  // uv index per new vertex (grown below)
    size_t face = part.firstFace;
    for (size_t t = 0; t < tri.size(); t += 3) {
        const uint32_t* c = &tri[t];
        const uint32_t a = rig.sourceVertex[part.firstVertex + c[0]], b = rig.sourceVertex[part.firstVertex + c[1]],
                       d = rig.sourceVertex[part.firstVertex + c[2]];
        if (a == b || b == d || a == d) {
            for (int k = 0; k < 3; ++k)
                indices[t + size_t(k)] = c[k];  // zero area: kept as it was, on the primary copies
            continue;
        }
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = c[k], u = rig.mesh.uvIndices[3 * face + size_t(k)];
            if (primary[v] == none || primary[v] == u) {
                primary[v] = u;
                indices[t + size_t(k)] = v;
                continue;
            }
            const uint64_t key = (uint64_t(v) << 32) | u;
            auto it = extra.emplace(key, uint32_t(src.size()));
            if (it.second) {
                src.push_back(v);
                uvOf.push_back(u);
            }
            indices[t + size_t(k)] = it.first->second;
        }
        ++face;
    }
    std::vector<glm::vec2> uv(src.size(), glm::vec2(0.0f));
    for (size_t i = 0; i < src.size(); ++i) {
        const uint32_t u = i < n ? primary[i] : uvOf[i];
        if (u != none)
            uv[i] = rig.mesh.uvs[u];
    }
    if (src.size() > n) {
        for (auto& [name, acc] : prim.attributes)
            if (!(st = gatherAccessor(model, acc, src, what + " " + name, &acc)))
                return st;
        for (auto& target : prim.targets)
            for (auto& [name, acc] : target)
                if (!(st = gatherAccessor(model, acc, src, what + " morph target " + name, &acc)))
                    return st;
    }
    int view = appendBufferView(model, uv.data(), uv.size() * sizeof(glm::vec2), TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.attributes["TEXCOORD_" + std::to_string(set)] =
        appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, uv.size());
    view = appendBufferView(model, indices.data(), indices.size() * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    prim.indices = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    return Status::ok();
}

// Quantises a map to 16 bits with paper eq. 12 over its own range and
// encodes it as a PNG; sets the rig's encoding, factor and offset to match.
// Texels the runtime can read: within 2.5 texels of a UV triangle (bilinear
// samples inside a triangle touch texels up to one texel away).
std::vector<uint8_t> usedTexels(const ControlMesh& mesh, int width, int height)
{
    std::vector<uint8_t> used(size_t(width) * size_t(height), 0);
    const double reach = 2.5;
    for (size_t f = 0; f < mesh.faceCount(); ++f) {
        glm::dvec2 t[3];
        for (int k = 0; k < 3; ++k) {
            const glm::vec2 uv = mesh.uvs[mesh.uvIndices[3 * f + size_t(k)]];
            t[k] = glm::dvec2(double(uv.x) * width, double(uv.y) * height);
        }
        const double area = (t[1].x - t[0].x) * (t[2].y - t[0].y) - (t[1].y - t[0].y) * (t[2].x - t[0].x);
        const int x0 = std::max(0, int(std::floor(std::min({t[0].x, t[1].x, t[2].x}) - reach)));
        const int x1 = std::min(width - 1, int(std::ceil(std::max({t[0].x, t[1].x, t[2].x}) + reach)));
        const int y0 = std::max(0, int(std::floor(std::min({t[0].y, t[1].y, t[2].y}) - reach)));
        const int y1 = std::min(height - 1, int(std::ceil(std::max({t[0].y, t[1].y, t[2].y}) + reach)));
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                uint8_t& u = used[size_t(y) * size_t(width) + size_t(x)];
                if (u)
                    continue;
                const glm::dvec2 p(x + 0.5, y + 0.5);
                bool inside = area != 0.0;
                double nearest = 1e300;
                for (int k = 0; k < 3; ++k) {
                    const glm::dvec2 a = t[k], b = t[(k + 1) % 3], ab = b - a;
                    const double cross = ab.x * (p.y - a.y) - ab.y * (p.x - a.x);
                    inside = inside && cross * area >= 0.0;
                    const double len2 = glm::dot(ab, ab);
                    const double s = len2 > 0.0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
                    nearest = std::min(nearest, glm::length(p - (a + s * ab)));
                }
                u = inside || nearest <= reach;
            }
    }
    return used;
}

Status embedMap(tinygltf::Model& model, const DisplacementMap& map, double maxStep, const ControlMesh* mesh,
                DisplacementInfo* info)
{
    float dmin = 0.0f, dmax = 0.0f;
    bool first = true;
    for (float t : map.texels) {
        const float d = t * map.factor + map.offset;
        if (!std::isfinite(d))
            return Status(StatusCode::InvalidData, "the displacement map has a non-finite texel");
        dmin = first ? d : std::min(dmin, d);
        dmax = first ? d : std::max(dmax, d);
        first = false;
    }
    const double range = double(dmax) - double(dmin);
    // Paper eq. 12 with as many levels as the step allows (at most 2^16):
    // q = round((levels - 1) (d - dmin) / (dmax - dmin)).
    double levels = 65536.0;
    if (maxStep > 0.0 && range > 0.0)
        levels = std::clamp(std::ceil(range / maxStep) + 1.0, 2.0, 65536.0);
    const int bits = levels <= 256.0 ? 8 : 16;
    std::vector<uint16_t> q(map.texels.size());
    for (size_t i = 0; i < q.size(); ++i)
        q[i] = uint16_t(shared::strata_quantize(shared::strata_decode_distance(map.texels[i], map.factor, map.offset),
                                                dmin, dmax, float(levels)));
    if (mesh && mesh->hasUVs()) {
        // Texels nothing samples repeat their left neighbour (the one above at
        // a row start): PNG's filters turn them into runs of zeros.
        const std::vector<uint8_t> used = usedTexels(*mesh, map.width, map.height);
        for (int y = 0; y < map.height; ++y)
            for (int x = 0; x < map.width; ++x) {
                const size_t i = size_t(y) * size_t(map.width) + size_t(x);
                if (!used[i])
                    q[i] = x > 0 ? q[i - 1] : (y > 0 ? q[i - size_t(map.width)] : q[i]);
            }
    }
    std::string png;
    Status st = encodePngGray(map.width, map.height, bits, q, &png);
    if (!st)
        return st;
    const int view = appendBufferView(model, png.data(), png.size(), -1);
    model.bufferViews[size_t(view)].target = 0;
    tinygltf::Image image;
    image.name = "strata_displacement";
    image.mimeType = "image/png";
    image.bufferView = view;
    model.images.push_back(image);
    info->image = int(model.images.size() - 1);
    info->uri.clear();
    info->encoding = bits == 8 ? "png8" : "png16";
    info->width = map.width;
    info->height = map.height;
    const glm::vec2 decode = shared::strata_dequantize_factor_offset(dmin, dmax, float(levels));
    info->factor = decode.x;
    info->offset = decode.y;
    return Status::ok();
}

// Finds, for every face of `loaded`, the face of `rig` it was written from
// and the rotation of its corners: each corner within `error` of the rig
// corner in every coordinate (the positions' storage error), the rotation
// that moves them least.  The same face index first; else any face, through
// a grid of the rig faces' centroids.  False when some face has no match.
bool matchFaces(const ControlMesh& loaded, const ControlMesh& rig, double error, std::vector<uint32_t>* sourceFace,
                std::vector<int>* rotation)
{
    const size_t nf = loaded.faceCount();
    if (nf != rig.faceCount())
        return false;
    const double slack = 12.0 * error * error + 1e-30;  // twice the error per coordinate: rounding
    auto corner = [](const ControlMesh& m, size_t f, int k) { return glm::dvec3(m.positions[m.triangles[3 * f + size_t(k)]]); };
    // The rotation of rig face r that fits loaded face f best; -1 if none fits.
    auto fit = [&](size_t f, size_t r, double* cost) {
        int best = -1;
        for (int rot = 0; rot < 3; ++rot) {
            double sum = 0.0, worst = 0.0;
            for (int k = 0; k < 3; ++k) {
                const glm::dvec3 d = corner(loaded, f, k) - corner(rig, r, (k + rot) % 3);
                const double d2 = glm::dot(d, d);
                sum += d2;
                worst = std::max(worst, d2);
            }
            if (worst <= slack && (best < 0 || sum < *cost)) {
                best = rot;
                *cost = sum;
            }
        }
        return best;
    };
    sourceFace->assign(nf, 0);
    rotation->assign(nf, 0);
    bool inOrder = true;
    for (size_t f = 0; f < nf && inOrder; ++f) {
        double cost = 0.0;
        const int rot = fit(f, f, &cost);
        (*sourceFace)[f] = uint32_t(f);
        (*rotation)[f] = rot;
        inOrder = rot >= 0;
    }
    if (inOrder)
        return true;
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const glm::vec3& p : rig.positions) {
        lo = glm::min(lo, glm::dvec3(p));
        hi = glm::max(hi, glm::dvec3(p));
    }
    const double cell = std::max(4.0 * error, 1e-6 * std::max(glm::length(hi - lo), 1e-30));
    auto key = [&](const glm::dvec3& c, int dx, int dy, int dz) {
        const int64_t x = int64_t(std::floor((c.x - lo.x) / cell)) + dx, y = int64_t(std::floor((c.y - lo.y) / cell)) + dy,
                      z = int64_t(std::floor((c.z - lo.z) / cell)) + dz;
        return uint64_t(x) * 73856093u ^ uint64_t(y) * 19349663u ^ uint64_t(z) * 83492791u;
    };
    auto centroid = [&](const ControlMesh& m, size_t f) { return (corner(m, f, 0) + corner(m, f, 1) + corner(m, f, 2)) / 3.0; };
    std::unordered_map<uint64_t, std::vector<uint32_t>> grid;
    for (size_t r = 0; r < nf; ++r)
        grid[key(centroid(rig, r), 0, 0, 0)].push_back(uint32_t(r));
    std::vector<uint8_t> used(nf, 0);
    for (size_t f = 0; f < nf; ++f) {
        const glm::dvec3 c = centroid(loaded, f);
        int bestRot = -1;
        uint32_t bestFace = 0;
        double bestCost = 0.0;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const auto it = grid.find(key(c, dx, dy, dz));
                    if (it == grid.end())
                        continue;
                    for (uint32_t r : it->second) {
                        double cost = 0.0;
                        const int rot = used[r] ? -1 : fit(f, r, &cost);
                        if (rot >= 0 && (bestRot < 0 || cost < bestCost)) {
                            bestRot = rot;
                            bestFace = r;
                            bestCost = cost;
                        }
                    }
                }
        if (bestRot < 0)
            return false;
        used[bestFace] = 1;
        (*sourceFace)[f] = bestFace;
        (*rotation)[f] = bestRot;
    }
    return true;
}

// Embeds the map as its samples at the refined vertices of the recommended
// level (encoding "vertex").  The decoder numbers vertices as the loader
// rebuilds the control mesh from the file, which may differ from rig.mesh
// (welding, re-indexing, corners rotated by the index codec, faces
// reordered by Draco), so the file
// is written and loaded back in memory first and the map sampled on that
// topology, with rig.mesh's UVs (each loaded face matched to the rig face
// it was written from: matchFaces).
// The bytes of a model as a rig file: Draco- or meshopt-coded (.glb,
// `compressed`) or plain, .glb or pretty-printed .gltf.  The per-vertex
// values' probe and the file itself go through it, so they agree.
Status encodeModel(const std::string& path, tinygltf::Model& model, bool compressed, bool binary,
                   double positionError, bool draco, std::string* out)
{
    if (compressed)
        return encodeCompressedGlb(path, model, out, positionError, draco);
    Status st = prepareForWriting(path, model);
    if (!st)
        return st;
    tinygltf::TinyGLTF writer;
    std::ostringstream stream;
    if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/!binary, binary))
        return Status(StatusCode::IoError, path + ": glTF serialisation failed");
    *out = stream.str();
    return Status::ok();
}

Status embedVertexDisplacements(tinygltf::Model& model, const Rig& rig, const DisplacementMap& map, double maxStep,
                                bool compressed, double positionError, bool draco, const RigWriteOptions& options,
                                const std::string& path, DisplacementInfo* info)
{
    // Through the same writer as the final file (the meshopt index codec
    // rotates triangles, which renumbers refined vertices).
    tinygltf::Model probe = model;
    std::string glb;
    Status st = encodeModel(path, probe, compressed, true, positionError, draco, &glb);
    if (!st)
        return st;
    Rig loaded;
    if (!(st = loadRigFromMemory(reinterpret_cast<const unsigned char*>(glb.data()), glb.size(), true, path, &loaded)))
        return st;
    // Each loaded face is a rig face, its corners perhaps rotated (meshopt's
    // index codec) and the faces perhaps reordered (Draco's Edgebreaker);
    // each loaded corner takes the UV of the rig corner at its position.
    ControlMesh mesh = loaded.mesh;
    std::vector<uint32_t> sourceFace;
    std::vector<int> rotation;
    if (!matchFaces(mesh, rig.mesh, positionError, &sourceFace, &rotation))
        return Status(StatusCode::InvalidData, "the control mesh does not read back face for face; write the map as "
                                               "an image instead");
    mesh.uvs = rig.mesh.uvs;
    mesh.uvIndices.resize(mesh.triangles.size());
    for (size_t f = 0; f < mesh.faceCount(); ++f)
        for (int k = 0; k < 3; ++k)
            mesh.uvIndices[3 * f + size_t(k)] = rig.mesh.uvIndices[3 * size_t(sourceFace[f]) + size_t((k + rotation[f]) % 3)];
    const int level = info->recommendedLevel;
    std::unique_ptr<Plan> plan;
    if (!(st = Plan::create(&plan, mesh, Scheme::Linear, level)) || !(st = plan->setDisplacement(map)))
        return st;
    std::vector<float> values = plan->displacements();
    {
        // A vertex on a UV seam has one sample per chart around it: the
        // median, so that no single badly covered chart corner decides.
        const std::vector<uint32_t>& tri = plan->refinedTriangles();
        std::vector<glm::vec2> uvs;
        std::vector<uint32_t> uvi;
        plan->refinedUVs(&uvs, &uvi);
        std::vector<uint32_t> firstUV(values.size(), ~0u);
        std::vector<uint8_t> seam(values.size(), 0);
        for (size_t c = 0; c < tri.size(); ++c) {
            uint32_t& u = firstUV[tri[c]];
            seam[tri[c]] |= u != ~0u && u != uvi[c];
            u = u == ~0u ? uvi[c] : u;
        }
        std::vector<uint64_t> pairs;  // (vertex, UV) of seam corners
        for (size_t c = 0; c < tri.size(); ++c)
            if (seam[tri[c]])
                pairs.push_back(uint64_t(tri[c]) << 32 | uvi[c]);
        std::sort(pairs.begin(), pairs.end());
        pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
        std::vector<float> samples;
        for (size_t i = 0; i < pairs.size();) {
            const uint32_t v = uint32_t(pairs[i] >> 32);
            samples.clear();
            for (; i < pairs.size() && uint32_t(pairs[i] >> 32) == v; ++i)
                samples.push_back(sampleDisplacement(map, uvs[uint32_t(pairs[i])]));
            std::sort(samples.begin(), samples.end());
            const size_t k = samples.size();
            values[v] = k % 2 ? samples[k / 2] : 0.5f * (samples[k / 2 - 1] + samples[k / 2]);
        }
    }
    double step = maxStep;
    if (options.refineVertexDisplacements && !(st = options.refineVertexDisplacements(mesh, level, &values, &step)))
        return st;
    SubdivisionParents hierarchy;
    if (!(st = buildSubdivisionParents(&hierarchy, mesh, level)))
        return st;
    std::string bytes;
    float factor = 1.0f, offset = 0.0f;
    if (!(st = encodeVertexDisplacements(hierarchy, values, step, &bytes, &factor, &offset)))
        return st;
    const int view = appendBufferView(model, bytes.data(), bytes.size(), -1);
    model.bufferViews[size_t(view)].target = 0;
    info->vertexView = view;
    info->vertexAccessor =
        appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_SCALAR, bytes.size());
    info->vertexLevel = level;
    info->vertexValues = std::move(values);
    info->image = -1;
    info->uri.clear();
    info->encoding = "vertex";
    info->width = map.width;
    info->height = map.height;
    info->factor = factor;
    info->offset = offset;
    return Status::ok();
}

// Faces in vertex-cache order, vertices in first-use order (unreferenced
// ones last, in their order): the order meshopt's codecs compress best, about
// half the index bytes of an arbitrary order.  UV corners and skin weights
// move with their faces and vertices; the map is in UV space, so it stays.
void orderForCoding(Rig* rig)
{
    ControlMesh& m = rig->mesh;
    const size_t nv = m.positions.size(), nf = m.faceCount();
    std::vector<uint32_t> tri(m.triangles.size());
    meshopt_optimizeVertexCache(tri.data(), m.triangles.data(), m.triangles.size(), nv);
    // The optimiser emits whole triangles, corners unrotated: find each one's
    // source face (repeated faces are taken in turn).
    std::unordered_map<uint64_t, std::vector<uint32_t>> facesOf;
    auto key = [](const uint32_t* t) {
        return (uint64_t(t[0]) * 2654435761u) ^ (uint64_t(t[1]) << 21) ^ (uint64_t(t[2]) << 42);
    };
    for (size_t f = nf; f-- > 0;)
        facesOf[key(&m.triangles[3 * f])].push_back(uint32_t(f));
    std::vector<uint32_t> sourceFace(nf);
    for (size_t f = 0; f < nf; ++f) {
        std::vector<uint32_t>& list = facesOf[key(&tri[3 * f])];
        for (size_t i = list.size(); i-- > 0;)
            if (std::equal(&tri[3 * f], &tri[3 * f] + 3, &m.triangles[3 * size_t(list[i])])) {
                sourceFace[f] = list[i];
                list.erase(list.begin() + long(i));
                break;
            }
    }
    std::vector<uint32_t> remap(nv);
    meshopt_optimizeVertexFetchRemap(remap.data(), tri.data(), tri.size(), nv);
    uint32_t next = 0;
    for (uint32_t r : remap)
        if (r != ~0u)
            next = std::max(next, r + 1);
    for (uint32_t& r : remap)
        if (r == ~0u)
            r = next++;
    std::vector<glm::vec3> positions(nv);
    for (size_t v = 0; v < nv; ++v)
        positions[remap[v]] = m.positions[v];
    std::vector<uint32_t> uvIndices(m.uvIndices.size());
    for (size_t f = 0; f < nf; ++f) {
        for (int k = 0; k < 3; ++k)
            tri[3 * f + size_t(k)] = remap[tri[3 * f + size_t(k)]];
        if (m.hasUVs())
            std::copy_n(&m.uvIndices[3 * size_t(sourceFace[f])], 3, &uvIndices[3 * f]);
    }
    m.positions = std::move(positions);
    m.triangles = std::move(tri);
    m.uvIndices = std::move(uvIndices);
    VertexWeights& w = rig->skeleton.weights;
    if (w.influences > 0 && w.joints.size() == nv * size_t(w.influences)) {
        const size_t k = size_t(w.influences);
        std::vector<uint16_t> joints(w.joints.size());
        std::vector<float> weights(w.weights.size());
        for (size_t v = 0; v < nv; ++v) {
            std::copy_n(&w.joints[k * v], k, &joints[k * remap[v]]);
            std::copy_n(&w.weights[k * v], k, &weights[k * remap[v]]);
        }
        w.joints = std::move(joints);
        w.weights = std::move(weights);
    }
}

}  // namespace

Status saveRig(const std::filesystem::path& pathFile, const Rig& input, const DisplacementMap* map, std::vector<std::string>* notes,
               const RigWriteOptions* options)
{
    const std::string path = pathFile.string();
    // A bare control mesh is written in the order that codes best (its
    // per-vertex values, when it has them, are computed on the file's order
    // below; those of a loaded rig written back keep its order).
    const bool fromSource = input.source && !input.parts.empty() && input.sourceVertex.size() &&
                            input.fileCorners.size() == input.mesh.triangles.size();
    const bool keepsValues = input.hasDisplacement && input.displacement.vertexLevel >= 0 && !map;
    Rig ordered;
    const bool reorder = !fromSource && !keepsValues && options && options->compress && extensionOf(path) == ".glb" &&
                         validateControlMesh(input.mesh).isOk();
    if (reorder) {
        ordered = input;
        orderForCoding(&ordered);
    }
    const Rig& rig = reorder ? ordered : input;
    // A character's own vertex data is kept exact; a bare cage's positions
    // may be stored to the error allowed.
    double positionError = options && !fromSource ? options->maxPositionError : 0.0;
    // Draco only where the per-vertex values' probe proves the cage reads
    // back face for face (below).
    bool draco = options && options->draco && options->vertexDisplacements && map && rig.hasDisplacement &&
                 !fromSource && positionError > 0.0 && rig.skeleton.empty();
    const bool omitUVs = options && options->vertexDisplacements && options->omitDisplacementUVs && map &&
                         rig.hasDisplacement;
    const std::string ext = extensionOf(path);
    if (ext != ".glb" && ext != ".gltf")
        return Status(StatusCode::InvalidArgument, path + ": a rig must be written as .glb or .gltf");
    Status st = validateControlMesh(rig.mesh);
    if (!st)
        return Status(st.code(), path + ": " + st.message());
    if (map && !(st = validateDisplacementMap(*map)))
        return Status(st.code(), path + ": " + st.message());
    const ControlMesh& cm = rig.mesh;
    DisplacementInfo info = rig.displacement;
    tinygltf::Model model;
    std::vector<int> blockMeshes;
    if (fromSource) {
        model = rig.source->model;
        std::vector<std::vector<unsigned char>> imageBytes = rig.source->imageBytes;
        imageBytes.resize(model.images.size());
        // The previous bake's block and embedded map go; the new ones replace them.
        const int oldImage = dropLayers(model);
        if (oldImage >= 0) {
            removeImage(model, &imageBytes, oldImage);
            if (info.image == oldImage)
                info.image = -1;
        }
        // Images from files or data URIs travel inside the rig.
        embedImages(model, imageBytes, notes);
        // New displacement UVs (an atlas made by the baker) go in a new set.
        // The file's own UVs, untouched (an atlas the baker laid out may
        // happen to number its UVs as the file numbers its vertices).
        bool sameUVs = cm.hasUVs() && rig.fileTexCoord >= 0 && cm.uvIndices == rig.fileCorners &&
                       cm.uvs.size() == rig.sourceVertex.size() && uvHash(cm.uvs) == rig.fileUVHash;
        if (omitUVs && !sameUVs) {
            info.texCoord = -1;
        } else if (cm.hasUVs() && !sameUVs) {
            int set = 0;
            for (const RigPart& part : rig.parts)
                for (const auto& [name, acc] : model.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)].attributes)
                    if (name.rfind("TEXCOORD_", 0) == 0)
                        set = std::max(set, std::atoi(name.c_str() + 9) + 1);
            if (set > 7)
                return Status(StatusCode::Unsupported, path + ": no free TEXCOORD set for the displacement UVs");
            for (const RigPart& part : rig.parts)
                if (!(st = reindexWithUVs(model, rig, part, set, path)))
                    return st;
            info.texCoord = set;
        }
        for (const RigPart& part : rig.parts)
            if (std::find(blockMeshes.begin(), blockMeshes.end(), part.mesh) == blockMeshes.end())
                blockMeshes.push_back(part.mesh);
        rootSkinnedMeshNodes(model, notes);
    } else {
        // No normals: the runtime computes its own (angle-weighted, eq. 1's n_k
        // of the paper), and glTF viewers shade a cage flat without them.
        MeshView view;
        view.positions = cm.positions.data();
        view.compactUVs = options && options->compress;
        view.vertexCount = cm.positions.size();
        view.triangles = cm.triangles.data();
        view.faceCount = cm.faceCount();
        if (cm.hasUVs() && !omitUVs) {
            view.uvs = cm.uvs.data();
            view.uvCount = cm.uvs.size();
            view.uvIndices = cm.uvIndices.data();
        }
        buildGltfMesh(&model, view, "control_mesh", nullptr, &rig.skeleton);
        info.texCoord = omitUVs ? -1 : 0;
        blockMeshes.push_back(0);
    }
    if (rig.hasDisplacement) {
        if (!cm.hasUVs())
            return Status(StatusCode::InvalidArgument, path + ": a rig with a displacement map needs UVs");
        const double step = options ? options->maxQuantizationStep : 0.0;
        if (map && options && options->vertexDisplacements) {
            const bool compressed = extensionOf(path) == ".glb" && options->compress;
            // Draco where it reads back face for face (it may weld or drop
            // faces the cage has, an edge shorter than the error collapsing),
            // at the error allowed or down to a sixteenth of it; meshopt, and
            // finer positions, otherwise.
            const double allowed = positionError;
            bool coded = false;
            for (const bool withDraco : {true, false}) {
                if (withDraco && !draco)
                    continue;
                for (int k = 0; k < 3 && !coded; ++k) {
                    const double error = allowed / double(1 << (2 * k));
                    DisplacementInfo tried = info;
                    st = embedVertexDisplacements(model, rig, *map, step, compressed, error, withDraco, *options,
                                                  path, &tried);
                    if (st) {
                        info = std::move(tried);
                        positionError = error;
                        coded = true;
                        draco = withDraco;
                    } else if (!withDraco && (st.code() != StatusCode::InvalidData || error == 0.0 || k == 2)) {
                        return Status(st.code(), path + ": " + st.message());
                    }
                }
                if (coded)
                    break;
            }
        } else if (map && !(st = embedMap(model, *map, step, &cm, &info))) {
            return Status(st.code(), path + ": " + st.message());
        }
        if (!map && info.vertexLevel >= 0) {
            // A loaded rig written back unchanged keeps its coded displacements.
            if (info.embedded.empty())
                return Status(StatusCode::InvalidArgument, path + ": the rig's per-vertex displacements have no data");
            info.vertexView = appendBufferView(model, info.embedded.data(), info.embedded.size(), -1);
            model.bufferViews[size_t(info.vertexView)].target = 0;
            info.vertexAccessor = appendAccessor(model, info.vertexView, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                                 TINYGLTF_TYPE_SCALAR, info.embedded.size());
        }
        if (info.image < 0 && info.uri.empty() && info.vertexLevel < 0)
            return Status(StatusCode::InvalidArgument, path + ": the rig names no displacement map");
        const tinygltf::Value block = layerBlockValue(info, cm);
        for (int m : blockMeshes)
            setLayer(&model, &model.meshes[size_t(m)], &block);
    }
    // Compact rigs: Draco- or meshopt-coded vertex data and indices (.glb).
    std::string bytes;
    const bool binary = extensionOf(path) == ".glb";
    if (!(st = encodeModel(path, model, binary && options && options->compress, binary, positionError, draco, &bytes)))
        return st;
    if (rig.hasDisplacement && !(st = sealLayer(path, &bytes)))
        return st;
    return writeFileAtomic(path, bytes.data(), bytes.size());
}

Status readPlainGlb(const std::filesystem::path& pathFile, std::string* bytes)
{
    const std::string path = pathFile.string();
    std::vector<unsigned char> data;
    Status st = readFile(path, &data);
    if (!st)
        return st;
    std::string plain;
    if (!(st = decodeCompressedGlb(data.data(), data.size(), path, &plain)))
        return st;
    *bytes = plain.empty() ? std::string(data.begin(), data.end()) : std::move(plain);
    return Status::ok();
}

}  // namespace io
}  // namespace strata
