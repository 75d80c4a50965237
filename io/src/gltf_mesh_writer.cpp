// glTF: writing a plain mesh (one primitive, split where UVs differ, an
// optional skin), shared by rigs and reconstructions.
#include "gltf_mesh_writer.h"

#include "gltf_accessor.h"
#include "gltf_document.h"

#include "strata/io/file.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

namespace strata {
namespace io {

int appendBufferView(tinygltf::Model& model, const void* data, size_t bytes, int target)
{
    if (model.buffers.empty())
        model.buffers.resize(1);
    std::vector<unsigned char>& buf = model.buffers[0].data;
    while (buf.size() % 4)
        buf.push_back(0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = buf.size();
    view.byteLength = bytes;
    view.target = target;
    const unsigned char* p = static_cast<const unsigned char*>(data);
    buf.insert(buf.end(), p, p + bytes);
    model.bufferViews.push_back(view);
    return int(model.bufferViews.size() - 1);
}

int appendAccessor(tinygltf::Model& model, int view, int componentType, int type, size_t count)
{
    tinygltf::Accessor acc;
    acc.bufferView = view;
    acc.componentType = componentType;
    acc.type = type;
    acc.count = count;
    model.accessors.push_back(acc);
    return int(model.accessors.size() - 1);
}

void buildGltfMesh(tinygltf::Model* out, const MeshView& m, const char* name, const tinygltf::Value* meshExtras,
                   const Skeleton* skeleton)
{
    const bool hasUV = m.uvs != nullptr;
    // Split vertices where their UVs differ (glTF attributes are per vertex).
    // File vertices are ordered by (topological vertex, UV), so the first copy
    // of each vertex appears in topological order and a welding loader
    // restores the original numbering.
    std::vector<uint64_t> keys(m.faceCount * 3);
    for (size_t i = 0; i < keys.size(); ++i)
        keys[i] = (uint64_t(m.triangles[i]) << 32) | (hasUV ? m.uvIndices[i] : 0u);
    std::vector<uint64_t> unique = keys;
    std::sort(unique.begin(), unique.end());
    unique.erase(std::unique(unique.begin(), unique.end()), unique.end());
    std::vector<uint32_t> fileVertexOf(unique.size());
    std::vector<glm::vec2> fileUV(hasUV ? unique.size() : 0);
    for (size_t i = 0; i < unique.size(); ++i) {
        fileVertexOf[i] = uint32_t(unique[i] >> 32);
        if (hasUV)
            fileUV[i] = m.uvs[uint32_t(unique[i])];
    }
    std::vector<uint32_t> indices(keys.size());
    for (size_t i = 0; i < keys.size(); ++i)
        indices[i] = uint32_t(std::lower_bound(unique.begin(), unique.end(), keys[i]) - unique.begin());
    const size_t nv = fileVertexOf.size();
    std::vector<glm::vec3> pos(nv), nrm(m.normals ? nv : 0);
    std::vector<double> pmin(3, 1e300), pmax(3, -1e300);
    bool unitNormals = m.normals != nullptr;
    for (size_t i = 0; i < nv; ++i) {
        pos[i] = m.positions[fileVertexOf[i]];
        for (int c = 0; c < 3; ++c) {
            pmin[size_t(c)] = std::min(pmin[size_t(c)], double(pos[i][c]));
            pmax[size_t(c)] = std::max(pmax[size_t(c)], double(pos[i][c]));
        }
        if (m.normals) {
            nrm[i] = m.normals[fileVertexOf[i]];
            const float l2 = nrm[i].x * nrm[i].x + nrm[i].y * nrm[i].y + nrm[i].z * nrm[i].z;
            unitNormals = unitNormals && std::fabs(l2 - 1.0f) < 1e-4f;
        }
    }

    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = STRATA_SURFACE_GENERATOR;
    model.buffers.resize(1);
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    int view = appendBufferView(model, pos.data(), nv * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.attributes["POSITION"] = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
    jsonFloats(&pmin);
    jsonFloats(&pmax);
    model.accessors.back().minValues = pmin;
    model.accessors.back().maxValues = pmax;
    if (unitNormals) {
        view = appendBufferView(model, nrm.data(), nv * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
        prim.attributes["NORMAL"] = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
    }
    bool unitUVs = hasUV && m.compactUVs;
    for (size_t i = 0; unitUVs && i < fileUV.size(); ++i)
        unitUVs = fileUV[i].x >= 0.0f && fileUV[i].x <= 1.0f && fileUV[i].y >= 0.0f && fileUV[i].y <= 1.0f;
    if (unitUVs) {
        std::vector<uint16_t> q(2 * nv);
        for (size_t i = 0; i < nv; ++i)
            for (int c = 0; c < 2; ++c)
                q[2 * i + size_t(c)] = uint16_t(std::lround(double(fileUV[i][c]) * 65535.0));
        view = appendBufferView(model, q.data(), q.size() * sizeof(uint16_t), TINYGLTF_TARGET_ARRAY_BUFFER);
        prim.attributes["TEXCOORD_0"] =
            appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC2, nv);
        model.accessors.back().normalized = true;
    } else if (hasUV) {
        view = appendBufferView(model, fileUV.data(), nv * sizeof(glm::vec2), TINYGLTF_TARGET_ARRAY_BUFFER);
        prim.attributes["TEXCOORD_0"] =
            appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, nv);
    }
    if (nv <= 65535) {
        // Half the bytes: 16-bit indices whenever the vertices allow.
        std::vector<uint16_t> small(indices.begin(), indices.end());
        view = appendBufferView(model, small.data(), small.size() * sizeof(uint16_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        prim.indices =
            appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR, small.size());
    } else {
        view = appendBufferView(model, indices.data(), indices.size() * sizeof(uint32_t),
                                TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        prim.indices =
            appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
    }
    prim.material = 0;

    tinygltf::Material material;
    material.name = name;
    material.pbrMetallicRoughness.metallicFactor = 0.0;
    material.pbrMetallicRoughness.roughnessFactor = 0.6;
    model.materials.push_back(material);
    tinygltf::Mesh mesh;
    mesh.name = name;
    mesh.primitives.push_back(prim);
    if (meshExtras)
        mesh.extras = *meshExtras;
    model.meshes.push_back(mesh);
    tinygltf::Scene scene;
    const bool skinned = skeleton && !skeleton->empty();
    if (skinned) {
        // Influences per file vertex, copied from its topological vertex.
        const VertexWeights& vw = skeleton->weights;
        for (int set = 0; set * 4 < vw.influences; ++set) {
            std::vector<uint16_t> joints(nv * 4);
            std::vector<float> weights(nv * 4);
            for (size_t i = 0; i < nv; ++i)
                for (int k = 0; k < 4; ++k) {
                    const size_t slot = size_t(fileVertexOf[i]) * size_t(vw.influences) + size_t(4 * set + k);
                    joints[4 * i + size_t(k)] = vw.weights[slot] != 0.0f ? vw.joints[slot] : 0;
                    weights[4 * i + size_t(k)] = vw.weights[slot];
                }
            view = appendBufferView(model, joints.data(), joints.size() * 2, TINYGLTF_TARGET_ARRAY_BUFFER);
            model.meshes[0].primitives[0].attributes["JOINTS_" + std::to_string(set)] =
                appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC4, nv);
            view = appendBufferView(model, weights.data(), weights.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER);
            model.meshes[0].primitives[0].attributes["WEIGHTS_" + std::to_string(set)] =
                appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, nv);
        }
        for (size_t i = 0; i < skeleton->nodes.size(); ++i) {
            const SkeletonNode& sn = skeleton->nodes[i];
            tinygltf::Node n;
            n.name = sn.name.empty() ? "node" + std::to_string(i) : sn.name;
            if (sn.hasMatrix) {
                for (int k = 0; k < 16; ++k)
                    n.matrix.push_back(double(sn.matrix[k / 4][k % 4]));
            } else {
                const NodeTransform& t = sn.rest;
                if (t.translation != glm::vec3(0.0f))
                    n.translation = {t.translation.x, t.translation.y, t.translation.z};
                if (t.rotation != glm::quat(1.0f, 0.0f, 0.0f, 0.0f))
                    n.rotation = {t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w};
                if (t.scale != glm::vec3(1.0f))
                    n.scale = {t.scale.x, t.scale.y, t.scale.z};
            }
            model.nodes.push_back(n);
        }
        for (size_t i = 0; i < skeleton->nodes.size(); ++i) {
            const int parent = skeleton->nodes[i].parent;
            if (parent >= 0)
                model.nodes[size_t(parent)].children.push_back(int(i));
            else
                scene.nodes.push_back(int(i));
        }
        // glTF asks a skin's joints for a common root: where they hang from
        // several (rigid parts on nodes of their own), one node above them,
        // at rest, is theirs.
        std::vector<int> roots;
        for (const int joint : skeleton->skin.joints) {
            int r = joint;
            const size_t nn = skeleton->nodes.size();
            for (size_t steps = 0; r >= 0 && size_t(r) < nn && skeleton->nodes[size_t(r)].parent >= 0 && steps < nn;
                 ++steps)
                r = skeleton->nodes[size_t(r)].parent;
            if (r >= 0 && std::find(roots.begin(), roots.end(), r) == roots.end())
                roots.push_back(r);
        }
        if (roots.size() > 1) {
            tinygltf::Node above;
            above.name = "joints";
            above.children = roots;
            model.nodes.push_back(above);
            const auto joint = [&](int n) { return std::find(roots.begin(), roots.end(), n) != roots.end(); };
            scene.nodes.erase(std::remove_if(scene.nodes.begin(), scene.nodes.end(), joint), scene.nodes.end());
            scene.nodes.push_back(int(model.nodes.size()) - 1);
        }
        tinygltf::Skin skin;
        skin.joints = skeleton->skin.joints;
        view = appendBufferView(model, skeleton->skin.inverseBindMatrices.data(),
                                skeleton->skin.inverseBindMatrices.size() * sizeof(glm::mat4), -1);
        model.bufferViews.back().target = 0;
        skin.inverseBindMatrices = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_MAT4,
                                                  skeleton->skin.inverseBindMatrices.size());
        model.skins.push_back(skin);
        // Every animation's key times in one bufferView and its values in
        // another; channels keyed at the same times (exporters key every
        // joint alike) share one accessor of them.
        std::vector<float> times, values;
        std::map<std::vector<float>, int> timesAccessor;
        // Accessor, and its offset in floats in `times` or in `values`.
        std::vector<std::pair<int, size_t>> timesPlaced, valuesPlaced;
        for (const Animation& a : skeleton->animations) {
            tinygltf::Animation anim;
            anim.name = a.name;
            for (const AnimationChannel& c : a.channels) {
                tinygltf::AnimationSampler sa;
                auto known = timesAccessor.find(c.times);
                if (known == timesAccessor.end()) {
                    sa.input = appendAccessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR,
                                              c.times.size());
                    model.accessors.back().minValues = {double(c.times.front())};
                    model.accessors.back().maxValues = {double(c.times.back())};
                    timesPlaced.push_back({sa.input, times.size()});
                    times.insert(times.end(), c.times.begin(), c.times.end());
                    timesAccessor.emplace(c.times, sa.input);
                } else {
                    sa.input = known->second;
                }
                const int comps = c.path == AnimationPath::Rotation ? 4 : 3;
                sa.output = appendAccessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                           comps == 4 ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3,
                                           c.values.size() / size_t(comps));
                valuesPlaced.push_back({sa.output, values.size()});
                values.insert(values.end(), c.values.begin(), c.values.end());
                sa.interpolation = c.interpolation == AnimationInterpolation::Step          ? "STEP"
                                   : c.interpolation == AnimationInterpolation::CubicSpline ? "CUBICSPLINE"
                                                                                            : "LINEAR";
                anim.samplers.push_back(sa);
                tinygltf::AnimationChannel ch;
                ch.sampler = int(anim.samplers.size() - 1);
                ch.target_node = c.node;
                ch.target_path = c.path == AnimationPath::Translation ? "translation"
                                 : c.path == AnimationPath::Rotation  ? "rotation"
                                                                      : "scale";
                anim.channels.push_back(ch);
            }
            model.animations.push_back(anim);
        }
        // Each list of keys in one bufferView, its accessors at their offsets.
        auto place = [&](const std::vector<float>& data, const std::vector<std::pair<int, size_t>>& placed) {
            if (placed.empty())
                return;
            const int keyView = appendBufferView(model, data.data(), data.size() * 4, -1);
            model.bufferViews.back().target = 0;
            for (const auto& [accessor, offset] : placed) {
                model.accessors[size_t(accessor)].bufferView = keyView;
                model.accessors[size_t(accessor)].byteOffset = 4 * offset;
            }
        };
        place(times, timesPlaced);
        place(values, valuesPlaced);
    }
    if (skinned && skeleton->meshNode >= 0 && size_t(skeleton->meshNode) < skeleton->nodes.size() &&
        skeleton->nodes[size_t(skeleton->meshNode)].parent < 0) {
        // Keep the mesh on the root node that carried it (a skinned mesh
        // elsewhere goes on a new root node: parents cannot move it anyway).
        model.nodes[size_t(skeleton->meshNode)].mesh = 0;
        model.nodes[size_t(skeleton->meshNode)].skin = 0;
    } else {
        tinygltf::Node node;
        node.name = name;
        node.mesh = 0;
        if (skinned)
            node.skin = 0;
        model.nodes.push_back(node);
        scene.nodes.push_back(int(model.nodes.size() - 1));
    }
    model.scenes.push_back(scene);
    model.defaultScene = 0;
    model.buffers[0].data.resize((model.buffers[0].data.size() + 3) & ~size_t(3), 0);
    *out = std::move(model);
}

Status writeGltfModel(const std::string& path, const tinygltf::Model& model)
{
    tinygltf::TinyGLTF writer;
    std::ostringstream stream;
    const bool binary = extensionOf(path) == ".glb";
    if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/!binary, binary))
        return Status(StatusCode::IoError, path + ": glTF serialisation failed");
    const std::string bytes = stream.str();
    return writeFileAtomic(path, bytes.data(), bytes.size());
}

Status writeGltfMesh(const std::string& path, const MeshView& m, const char* name, const tinygltf::Value* meshExtras,
                     const Skeleton* skeleton)
{
    tinygltf::Model model;
    buildGltfMesh(&model, m, name, meshExtras, skeleton);
    return writeGltfModel(path, model);
}

}  // namespace io
}  // namespace strata
