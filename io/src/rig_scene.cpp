// A glTF scene's triangle geometry as one welded control mesh: node
// transforms at rest, every triangle primitive of every mesh in the scene's
// space, one part per primitive (docs/FORMAT.md).
#include "strata/io/rig_io.h"

#include "rig_internal.h"

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
#include <glm/matrix.hpp>

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

namespace rigfile {

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

bool mirrors(const RigPart& part)
{
    return !part.skinned && glm::determinant(glm::mat3(part.toScene)) < 0.0f;
}

void reverseWinding(std::vector<uint32_t>* triangles)
{
    for (size_t t = 0; t + 2 < triangles->size(); t += 3)
        std::swap((*triangles)[t + 1], (*triangles)[t + 2]);
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


// Welds file vertices into topological vertices (exact position match, over
// every primitive: coincident vertices of different primitives join, so the
// refined surface is watertight wherever the input is).
void weldFileVertices(const std::vector<float>& pos, std::vector<glm::vec2>&& uv, const std::vector<uint32_t>& tri,
                      const std::vector<uint32_t>& partOfTri, bool withUV, int texCoord, Rig* rigOut)
{
    Rig& rig = *rigOut;
    const size_t nFile = pos.size() / 3;
    weldByPosition(reinterpret_cast<const glm::vec3*>(pos.data()), nFile, &rig.sourceVertex, &rig.mesh.positions);
    rig.mesh.triangles.clear();
    rig.fileCorners.clear();
    for (RigPart& part : rig.parts)
        part.firstFace = part.faceCount = 0;
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
}

// The one uniform scale that skin `skin` puts between its meshes' bind
// space and the scene at rest: every joint's rest world matrix times its
// inverse bind matrix a similarity of that scale.  gltfpack puts its
// position dequantisation there, and exporters an armature's unit scale.
// A displacement is baked in bind space and applied to the posed surface,
// so the bind space is read at the scene's scale (RigPart::toScene; the
// inverse bind matrices take the scale out again: loadSkeleton).  1 where
// there is no one uniform scale: then *spread holds the smallest and
// largest scale any joint gives along any axis.
float bindSpaceScale(const tinygltf::Model& model, int skin, const std::vector<glm::mat4>& world, glm::vec2* spread)
{
    *spread = glm::vec2(1.0f);
    if (skin < 0 || size_t(skin) >= model.skins.size())
        return 1.0f;
    const tinygltf::Skin& sk = model.skins[size_t(skin)];
    std::vector<float> m;
    if (sk.joints.empty() || sk.inverseBindMatrices < 0 ||
        !readFloatAccessor(model, sk.inverseBindMatrices, 16, "inverseBindMatrices", &m) ||
        m.size() < 16 * sk.joints.size())
        return 1.0f;  // the skeleton reader names what is wrong
    float lo = std::numeric_limits<float>::max(), hi = 0.0f;
    bool similar = true;
    for (size_t j = 0; j < sk.joints.size(); ++j) {
        const int node = sk.joints[j];
        if (node < 0 || size_t(node) >= world.size())
            return 1.0f;
        glm::mat4 ibm;
        for (int k = 0; k < 16; ++k)
            ibm[k / 4][k % 4] = m[16 * j + size_t(k)];
        const glm::mat3 a(world[size_t(node)] * ibm);
        const float c[3] = {glm::length(a[0]), glm::length(a[1]), glm::length(a[2])};
        const float mean = (c[0] + c[1] + c[2]) / 3.0f;
        if (!std::isfinite(mean) || !(mean > 0.0f))
            return 1.0f;
        for (int k = 0; k < 3; ++k) {
            similar = similar && std::fabs(c[k] - mean) <= 1e-3f * mean &&
                      std::fabs(glm::dot(a[k], a[(k + 1) % 3])) <= 1e-3f * mean * mean;
            lo = std::min(lo, c[k]);
            hi = std::max(hi, c[k]);
        }
    }
    *spread = glm::vec2(lo, hi);
    if (!similar || hi - lo > 2e-3f * hi)
        return 1.0f;
    const float scale = 0.5f * (lo + hi);
    return std::fabs(scale - 1.0f) <= 1e-4f ? 1.0f : scale;
}

namespace {

// EXT_mesh_gpu_instancing's instances, each one's transform in its node's
// space (translation x rotation x scale, each optional): float accessors, or
// normalized unsigned ones, of one count, at most 2^20.  False where they
// cannot be read (signed normalized rotations, counts that differ).
bool readInstances(const tinygltf::Model& model, const tinygltf::Value& extension, std::vector<glm::mat4>* out)
{
    out->clear();
    if (!extension.IsObject() || !extension.Get("attributes").IsObject())
        return false;
    const tinygltf::Value& attributes = extension.Get("attributes");
    std::vector<float> t, r, s;
    size_t count = 0;
    bool any = false;
    const auto read = [&](const char* name, int components, std::vector<float>* values) {
        if (!attributes.Has(name))
            return true;
        const tinygltf::Value& index = attributes.Get(name);
        if (!index.IsInt() || !readFloatAccessor(model, index.Get<int>(), components, name, values))
            return false;
        const size_t n = values->size() / size_t(components);
        if (any && n != count)
            return false;
        count = n;
        any = true;
        return true;
    };
    if (!read("TRANSLATION", 3, &t) || !read("ROTATION", 4, &r) || !read("SCALE", 3, &s) || !any || count == 0 ||
        count > (size_t(1) << 20))
        return false;
    // Each instance's TRS as a node's, through the nodes' own composition.
    for (size_t i = 0; i < count; ++i) {
        tinygltf::Node place;
        if (!t.empty())
            place.translation = {t[3 * i], t[3 * i + 1], t[3 * i + 2]};
        if (!r.empty()) {
            const glm::dvec4 q(r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]);  // x, y, z, w
            const double length = glm::length(q);
            if (!(length > 0.0))
                return false;
            place.rotation = {q.x / length, q.y / length, q.z / length, q.w / length};
        }
        if (!s.empty())
            place.scale = {s[3 * i], s[3 * i + 1], s[3 * i + 2]};
        out->push_back(rigfile::localMatrix(place));
    }
    return true;
}

// A primitive whose every corner's NORMAL is its triangle's own normal (to
// about a degree, either way round): an exporter's faceted mesh, its
// vertices split at every face.  glTF draws it faceted, as it draws a
// primitive without NORMAL.  False where it has none, or none readable.
bool facetedNormals(const tinygltf::Model& model, const tinygltf::Primitive& prim, const std::vector<float>& pos,
                    const std::vector<uint32_t>& tri)
{
    const int accessor = attributeOf(prim, "NORMAL");
    std::vector<float> normals;
    if (accessor < 0 || !readFloatAccessor(model, accessor, 3, "NORMAL", &normals) || normals.size() != pos.size())
        return false;
    auto at = [](const std::vector<float>& v, uint32_t i) { return glm::vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]); };
    size_t faces = 0;
    for (size_t t = 0; t + 2 < tri.size(); t += 3) {
        const glm::vec3 a = at(pos, tri[t]);
        const glm::vec3 face = glm::cross(at(pos, tri[t + 1]) - a, at(pos, tri[t + 2]) - a);
        const float area = glm::length(face);
        if (!(area > 0.0f) || !std::isfinite(area))
            continue;  // no direction of its own
        for (int k = 0; k < 3; ++k) {
            const glm::vec3 n = at(normals, tri[t + size_t(k)]);
            const float length = glm::length(n);
            if (!(std::fabs(glm::dot(n, face)) >= 0.9998f * length * area))
                return false;
        }
        ++faces;
    }
    return faces > 0;
}

// Vertices read through another skin's bind space (moved[v]) carry its
// transform's rounding: each one within a millionth of the scene's diagonal
// of a vertex not moved takes that vertex's position, so that a seam split
// between two skins welds as it would in one.
void snapOntoUnmoved(std::vector<float>& pos, const std::vector<uint8_t>& moved)
{
    const size_t n = pos.size() / 3;
    auto at = [&](size_t v) { return glm::vec3(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]); };
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (size_t v = 0; v < n; ++v) {
        lo = glm::min(lo, at(v));
        hi = glm::max(hi, at(v));
    }
    const float eps = 1e-6f * glm::length(hi - lo);
    if (!(eps > 0.0f) || !std::isfinite(eps))
        return;
    auto cellOf = [&](size_t v, int c) { return int64_t(std::floor((pos[3 * v + size_t(c)] - lo[c]) / eps)); };
    auto key = [](int64_t x, int64_t y, int64_t z) {
        return uint64_t(x) * 0x9e3779b97f4a7c15ull ^ uint64_t(y) * 0xc2b2ae3d27d4eb4full ^
               uint64_t(z) * 0x165667b19e3779f9ull;
    };
    std::unordered_multimap<uint64_t, uint32_t> cells;
    for (size_t v = 0; v < n; ++v)
        if (!moved[v])
            cells.emplace(key(cellOf(v, 0), cellOf(v, 1), cellOf(v, 2)), uint32_t(v));
    if (cells.empty())
        return;
    for (size_t v = 0; v < n; ++v) {
        if (!moved[v])
            continue;
        const int64_t x = cellOf(v, 0), y = cellOf(v, 1), z = cellOf(v, 2);
        float best = eps * eps;
        int64_t nearest = -1;
        for (int64_t dx = -1; dx <= 1; ++dx)
            for (int64_t dy = -1; dy <= 1; ++dy)
                for (int64_t dz = -1; dz <= 1; ++dz) {
                    const auto range = cells.equal_range(key(x + dx, y + dy, z + dz));
                    for (auto it = range.first; it != range.second; ++it) {
                        const size_t u = it->second;
                        const glm::vec3 apart = at(u) - at(v);
                        const float d = glm::dot(apart, apart);
                        if (d <= best) {
                            best = d;
                            nearest = int64_t(u);
                        }
                    }
                }
        if (nearest >= 0)
            for (int c = 0; c < 3; ++c)
                pos[3 * v + size_t(c)] = pos[3 * size_t(nearest) + size_t(c)];
    }
}

// The vertices of parts on a skin that binds its joints in another pose
// than the union (SkinUnion::rebind), each moved into the union's bind
// space by the blend of its joints' moves (weights as its JOINTS_n and
// WEIGHTS_n give them), then placed by the first skin's part transform.
// Exact where a vertex follows one joint (a helmet, a rigid piece) or
// joints bound alike; refused where its joints would put it more than
// 1e-4 of the scene's diagonal apart (it would bend unlike its source),
// and then nothing is moved.
Status rebindVertices(const std::string& path, const tinygltf::Model& model, const glm::mat4& firstToScene,
                      SceneGeometry* out, std::vector<float>* pos, std::vector<uint8_t>* moved)
{
    Rig& rig = out->rig;
    const SkinUnion& skins = out->skins;
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (size_t v = 0; 3 * v + 2 < pos->size(); ++v) {
        const glm::vec3 p((*pos)[3 * v], (*pos)[3 * v + 1], (*pos)[3 * v + 2]);
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const double bound = 1e-4 * double(glm::length(hi - lo));
    std::vector<std::pair<size_t, glm::vec3>> placed;  // applied once every part agrees
    double worst = 0.0;
    std::string worstWhere;
    int worstSkin = -1;
    for (size_t p = 0; p < rig.parts.size(); ++p) {
        const RigPart& part = rig.parts[p];
        const int k = part.skinned ? skins.indexOf(model.nodes[size_t(part.node)].skin) : -1;
        if (k <= 0 || skins.rebind[size_t(k)].empty())
            continue;
        const std::vector<glm::mat4>& rebind = skins.rebind[size_t(k)];
        const tinygltf::Primitive& prim = *out->primitives[p];
        std::vector<uint32_t> joints;
        std::vector<float> weights;
        for (int set = 0; set < 4; ++set) {
            std::vector<uint32_t> j;
            std::vector<float> w;
            if (Status st = readInfluenceSet(path, model, prim, part, set, &j, &w); !st)
                return st;
            if (j.empty())
                break;
            joints.insert(joints.end(), j.begin(), j.end());
            weights.insert(weights.end(), w.begin(), w.end());
        }
        const size_t perVertex = 4, sets = joints.size() / std::max<size_t>(1, 4 * size_t(part.vertexCount));
        const glm::mat4 toLocal = glm::inverse(part.toScene);
        for (uint32_t v = 0; v < part.vertexCount; ++v) {
            const size_t i = size_t(part.firstVertex) + v;
            const glm::vec4 local = toLocal * glm::vec4((*pos)[3 * i], (*pos)[3 * i + 1], (*pos)[3 * i + 2], 1.0f);
            glm::dvec4 blend(0.0);
            double sum = 0.0;
            for (size_t set = 0; set < sets; ++set)
                for (size_t c = 0; c < perVertex; ++c) {
                    const size_t slot = (set * size_t(part.vertexCount) + v) * perVertex + c;
                    const double w = double(weights[slot]);
                    if (!(w > 0.0) || joints[slot] >= rebind.size())
                        continue;
                    blend += w * glm::dvec4(rebind[joints[slot]] * local);
                    sum += w;
                }
            if (!(sum > 0.0))
                continue;  // no weight: loadSkeleton names it
            const glm::vec3 at(firstToScene * glm::vec4(glm::vec3(blend / sum), 1.0f));
            for (size_t set = 0; set < sets; ++set)
                for (size_t c = 0; c < perVertex; ++c) {
                    const size_t slot = (set * size_t(part.vertexCount) + v) * perVertex + c;
                    if (!(weights[slot] > 0.0f) || joints[slot] >= rebind.size())
                        continue;
                    const glm::vec3 own(firstToScene * (rebind[joints[slot]] * local));
                    const double apart = double(glm::length(own - at));
                    if (apart > worst || !std::isfinite(apart)) {
                        worst = std::isfinite(apart) ? apart : std::numeric_limits<double>::infinity();
                        worstWhere = "vertex " + std::to_string(v) + " of " + part.name;
                        worstSkin = k;
                    }
                }
            placed.emplace_back(i, at);
        }
    }
    if (worst > bound || !std::isfinite(worst)) {
        const int node = skins.apartJoint[size_t(worstSkin)];
        char amount[96];
        std::snprintf(amount, sizeof(amount), "%.3g apart (%.3g%% of the scene's size)", worst,
                      100.0 * worst / std::max(1e4 * bound, 1e-30));
        return Status(StatusCode::Unsupported,
                      path + ": skins " + std::to_string(skins.skins[0]) + " and " +
                          std::to_string(skins.skins[size_t(worstSkin)]) + " bind joint node " + std::to_string(node) +
                          " (" + printable(model.nodes[size_t(node)].name, 60) +
                          ") in poses no one transform of their meshes reconciles, and " + worstWhere +
                          " lies " + amount + " in the bind spaces of its joints; a Strata rig has one skin");
    }
    for (const auto& [i, at] : placed) {
        for (int c = 0; c < 3; ++c)
            (*pos)[3 * i + size_t(c)] = at[c];
        (*moved)[i] = 1;
    }
    for (size_t p = 0; p < rig.parts.size(); ++p) {
        RigPart& part = rig.parts[p];
        const int k = part.skinned ? skins.indexOf(model.nodes[size_t(part.node)].skin) : -1;
        if (k > 0 && !skins.rebind[size_t(k)].empty())
            part.toScene = firstToScene;
    }
    return Status::ok();
}

}  // namespace

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
    // Every node of the scene that draws each mesh: a mesh two nodes place
    // (a pair of eyes, a row of buttons) is read once at each place.  A mesh
    // only nodes outside the scene place is read at the first of them, and
    // one no node places once as it is.
    std::vector<uint8_t> inScene(model.nodes.size(), model.scenes.empty() ? 1 : 0);
    if (!model.scenes.empty()) {
        const bool named = model.defaultScene >= 0 && size_t(model.defaultScene) < model.scenes.size();
        std::vector<int> stack = model.scenes[named ? size_t(model.defaultScene) : 0].nodes;
        while (!stack.empty()) {  // restWorldMatrices refused cycles and shared children
            const int n = stack.back();
            stack.pop_back();
            if (n < 0 || size_t(n) >= model.nodes.size() || inScene[size_t(n)])
                continue;
            inScene[size_t(n)] = 1;
            stack.insert(stack.end(), model.nodes[size_t(n)].children.begin(), model.nodes[size_t(n)].children.end());
        }
    }
    // Every place each mesh is drawn: its node's, or, through
    // EXT_mesh_gpu_instancing, each instance's transform within its node.
    struct Place {
        int node = -1, instance = -1;
        glm::mat4 local{1.0f};  // the instance's transform in its node's space
    };
    std::vector<std::vector<Place>> placesOf(model.meshes.size());
    std::vector<int> firstNode(model.meshes.size(), -1);
    size_t readOnce = 0;  // instanced nodes whose instances cannot be read (or are skinned)
    Rig& rig = out->rig;
    for (size_t i = 0; i < model.nodes.size(); ++i) {
        const int m = model.nodes[i].mesh;
        if (m >= 0 && size_t(m) < model.meshes.size()) {
            if (inScene[i]) {
                std::vector<glm::mat4> instances;
                const auto e = model.nodes[i].extensions.find("EXT_mesh_gpu_instancing");
                if (e != model.nodes[i].extensions.end() &&
                    !(model.nodes[i].skin < 0 && readInstances(model, e->second, &instances)))
                    ++readOnce;
                if (instances.empty())
                    placesOf[size_t(m)].push_back({int(i), -1, glm::mat4(1.0f)});
                for (size_t k = 0; k < instances.size(); ++k)
                    placesOf[size_t(m)].push_back({int(i), int(k), instances[k]});
            }
            if (firstNode[size_t(m)] < 0)
                firstNode[size_t(m)] = int(i);
        } else if (m >= 0) {
            return Status(StatusCode::InvalidData, path + ": node " + std::to_string(i) + " references missing mesh " +
                                                       std::to_string(m));
        }
    }
    if (readOnce)
        rig.warnings.push_back(std::to_string(readOnce) +
                               (readOnce == 1 ? " node draws its mesh" : " nodes draw their meshes") +
                               " at many places through EXT_mesh_gpu_instancing, skinned or with instances Strata "
                               "cannot read (float TRANSLATION, ROTATION and SCALE, or normalized unsigned); read "
                               "once each, where the node itself places it");
    std::vector<float> pos;  // all file vertices, scene space
    std::vector<glm::vec2> uv;
    std::vector<uint32_t> tri;  // file-vertex triangles
    std::vector<uint32_t> partOfTri;
    const std::string uvName = "TEXCOORD_" + std::to_string(texCoord);
    std::map<int, float> skinScales;  // per skin: bindSpaceScale, measured once
    // A rig whose file holds other models in other scenes (gltf-transform
    // merge puts each model in a scene of its own): the layered model is
    // what its scene draws, as a glTF viewer shows the default scene alone.
    const bool sceneAlone = out->blockMesh >= 0 && !placesOf[size_t(out->blockMesh)].empty();
    size_t elsewhere = 0;
    for (size_t m = 0; m < model.meshes.size(); ++m) {
        if (legacy && int(m) != out->blockMesh)
            continue;
        if (sceneAlone && placesOf[m].empty()) {
            ++elsewhere;
            continue;
        }
        const tinygltf::Mesh& mesh = model.meshes[m];
        if (placesOf[m].empty())
            placesOf[m].push_back({firstNode[m], -1, glm::mat4(1.0f)});
        for (size_t instance = 0; instance < placesOf[m].size(); ++instance) {
            const Place& place = placesOf[m][instance];
            for (size_t p = 0; p < mesh.primitives.size(); ++p) {
                const tinygltf::Primitive& prim = mesh.primitives[p];
                if (!isTriangles(prim.mode)) {
                    out->passThrough += instance == 0;
                    continue;
                }
                RigPart part;
                part.mesh = int(m);
                part.primitive = int(p);
                part.node = place.node;
                part.instance = place.instance;
                part.instanceTransform = place.local;
                part.material = prim.material;
                part.skinned = part.node >= 0 && model.nodes[size_t(part.node)].skin >= 0;
                // glTF shades it flat without NORMAL, and draws it faceted
                // with its faces' normals (below; finishRig asks the layer).
                part.flat = attributeOf(prim, "NORMAL") < 0;
                part.toScene =
                    part.node >= 0 && !part.skinned ? world[size_t(part.node)] * place.local : glm::mat4(1.0f);
                if (part.skinned) {
                    glm::vec2 spread(1.0f);
                    const int skin = model.nodes[size_t(part.node)].skin;
                    auto known = skinScales.find(skin);
                    if (known == skinScales.end())
                        known = skinScales.emplace(skin, bindSpaceScale(model, skin, world, &spread)).first;
                    const float scale = known->second;
                    part.toScene = glm::scale(glm::mat4(1.0f), glm::vec3(scale));
                    if (scale == 1.0f && spread.y - spread.x > 0.01f * spread.y && !out->bindScaleWarned) {
                        out->bindScaleWarned = true;
                        char line[200];
                        std::snprintf(line, sizeof(line),
                                      "skin %d places its meshes at scales %.4g to %.4g at rest (by joint or axis), "
                                      "not one: a displacement baked in their bind space poses off by up to that ratio",
                                      skin, double(spread.x), double(spread.y));
                        rig.warnings.push_back(line);
                    }
                }
                part.name = (mesh.name.empty() ? "mesh " + std::to_string(m) : "mesh " + printable(mesh.name, 60)) +
                            " primitive " + std::to_string(p);
                if (instance > 0)
                    part.name += " on node " + std::to_string(part.node) + " (" +
                                 printable(model.nodes[size_t(part.node)].name, 60) + ")";
                if (part.instance >= 0)
                    part.name += " instance " + std::to_string(part.instance);
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
                part.flat = part.flat || facetedNormals(model, prim, ppos, ptri);
                part.firstVertex = uint32_t(pos.size() / 3);
                part.vertexCount = uint32_t(n);
                for (size_t i = 0; i < n; ++i) {
                    const glm::vec4 q = part.toScene * glm::vec4(ppos[3 * i], ppos[3 * i + 1], ppos[3 * i + 2], 1.0f);
                    if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z))
                        return Status(StatusCode::InvalidData, what + ": vertex " + std::to_string(i) +
                                                                   " is not finite in the scene's space");
                    pos.insert(pos.end(), {q.x, q.y, q.z});
                    out->meshSpace.emplace_back(ppos[3 * i], ppos[3 * i + 1], ppos[3 * i + 2]);
                    uv.push_back(puv.empty() ? glm::vec2(0.0f) : glm::vec2(puv[2 * i], puv[2 * i + 1]));
                }
                if (mirrors(part))
                    reverseWinding(&ptri);
                for (uint32_t i : ptri)
                    tri.push_back(part.firstVertex + i);
                partOfTri.insert(partOfTri.end(), ptri.size() / 3, uint32_t(rig.parts.size()));
                out->primitives.push_back(&prim);
                rig.parts.push_back(std::move(part));
            }
        }
    }
    if (elsewhere)
        rig.warnings.push_back(std::to_string(elsewhere) + (elsewhere == 1 ? " mesh" : " meshes") +
                               " that only another scene draws (another model merged into the file) " +
                               (elsewhere == 1 ? "is" : "are") + " not read: the rig is the default scene's");
    if (rig.parts.empty())
        return Status(StatusCode::InvalidData, path + ": no triangle mesh in the file");
    const size_t nFile = pos.size() / 3;
    if (nFile == 0)
        return Status(StatusCode::InvalidData, path + ": the meshes have no vertices");

    // Parts on other skins than the first part's are read into its bind
    // space (SkinUnion).  Skins that do not unite leave the geometry as
    // read: a capture still gives its shape (loadSkeleton refuses the rest).
    out->skinsUnited = uniteSkins(path, model, rig.parts, &out->skins);
    if (out->skinsUnited && out->skins.skins.size() > 1) {
        glm::mat4 firstToScene(1.0f);
        for (const RigPart& part : rig.parts)
            if (part.skinned && model.nodes[size_t(part.node)].skin == out->skins.skins[0]) {
                firstToScene = part.toScene;
                break;
            }
        std::vector<uint8_t> moved(pos.size() / 3, 0);
        // Where a skin's vertices are rebound one by one and their joints
        // disagree, the geometry stands as read (loadSkeleton refuses).
        if (Status rebound = rebindVertices(path, model, firstToScene, out, &pos, &moved); !rebound)
            out->skinsUnited = rebound;
        for (RigPart& part : rig.parts) {
            const int k = part.skinned ? out->skins.indexOf(model.nodes[size_t(part.node)].skin) : 0;
            if (k <= 0 || !out->skinsUnited || !out->skins.rebind[size_t(k)].empty())
                continue;
            const glm::mat4 toScene = firstToScene * out->skins.toFirst[size_t(k)];
            const glm::mat4 move = toScene * glm::inverse(part.toScene);
            part.toScene = toScene;
            if (move == glm::mat4(1.0f))
                continue;
            for (size_t i = part.firstVertex; i < size_t(part.firstVertex) + part.vertexCount; ++i) {
                const glm::vec4 q = move * glm::vec4(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], 1.0f);
                if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z))
                    return Status(StatusCode::InvalidData, path + ": " + part.name + ": vertex " +
                                                               std::to_string(i - part.firstVertex) +
                                                               " is not finite in the first skin's bind space");
                pos[3 * i] = q.x;
                pos[3 * i + 1] = q.y;
                pos[3 * i + 2] = q.z;
                moved[i] = 1;
            }
        }
        snapOntoUnmoved(pos, moved);
    }

    out->fileTriangles = tri;
    out->fileTriangleParts = partOfTri;
    weldFileVertices(pos, std::move(uv), tri, partOfTri, out->missingUV == 0, texCoord, &rig);
    return Status::ok();
}

}  // namespace rigfile

}  // namespace io
}  // namespace strata
