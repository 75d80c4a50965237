// A glTF scene's nodes, skin, per-vertex influences and animations as the
// rig's Skeleton (rigid parts ride on their node as an extra joint).
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

int SkinUnion::indexOf(int skin) const
{
    const auto it = std::find(skins.begin(), skins.end(), skin);
    return it == skins.end() ? -1 : int(it - skins.begin());
}

namespace {

// Two inverse bind matrices the same within float rounding of their size
// (never where either holds a NaN or an infinity).
bool sameBinding(const glm::mat4& a, const glm::mat4& b)
{
    float size = 1.0f;
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            size = std::max({size, std::fabs(a[c][r]), std::fabs(b[c][r])});
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!(std::fabs(a[c][r] - b[c][r]) <= 1e-4f * size))
                return false;
    return true;
}

}  // namespace

Status readInfluenceSet(const std::string& path, const tinygltf::Model& model, const tinygltf::Primitive& prim,
                        const RigPart& part, int set, std::vector<uint32_t>* joints, std::vector<float>* weights)
{
    joints->clear();
    weights->clear();
    const std::string js = "JOINTS_" + std::to_string(set), ws = "WEIGHTS_" + std::to_string(set);
    if (attributeOf(prim, js) < 0 || attributeOf(prim, ws) < 0)
        return Status::ok();
    Status st;
    if (!(st = readUintAccessor(model, attributeOf(prim, js), 4, js, joints)) ||
        !(st = readFloatAccessor(model, attributeOf(prim, ws), 4, ws, weights)))
        return Status(st.code(), path + ": " + part.name + ": " + st.message());
    if (joints->size() != 4 * size_t(part.vertexCount) || weights->size() != joints->size())
        return Status(StatusCode::InvalidData,
                      path + ": " + part.name + ": " + js + "/" + ws + " do not have one element per vertex");
    return Status::ok();
}

Status uniteSkins(const std::string& path, const tinygltf::Model& model, const std::vector<RigPart>& parts,
                  SkinUnion* out)
{
    *out = SkinUnion();
    for (const RigPart& part : parts)
        if (part.skinned && part.node >= 0 && size_t(part.node) < model.nodes.size()) {
            const int s = model.nodes[size_t(part.node)].skin;
            if (out->indexOf(s) < 0)
                out->skins.push_back(s);
        }
    std::map<int, uint16_t> unionJoint;  // node -> its joint in the union
    for (size_t k = 0; k < out->skins.size(); ++k) {
        const int skinIndex = out->skins[k];
        if (skinIndex < 0 || size_t(skinIndex) >= model.skins.size())
            return Status(StatusCode::InvalidData, path + ": a mesh node references missing skin " +
                                                       std::to_string(skinIndex));
        const tinygltf::Skin& skin = model.skins[size_t(skinIndex)];
        const std::string what = path + ": skin " + std::to_string(skinIndex);
        if (skin.joints.empty())
            return Status(StatusCode::InvalidData, what + " has no joints");
        for (int j : skin.joints)
            if (j < 0 || size_t(j) >= model.nodes.size())
                return Status(StatusCode::InvalidData, what + " names missing node " + std::to_string(j));
        std::vector<glm::mat4> ibm(skin.joints.size(), glm::mat4(1.0f));
        if (skin.inverseBindMatrices >= 0) {
            std::vector<float> m;
            Status st = readFloatAccessor(model, skin.inverseBindMatrices, 16, "inverseBindMatrices", &m);
            if (!st)
                return Status(st.code(), path + ": " + st.message());
            if (m.size() / 16 < skin.joints.size())
                return Status(StatusCode::InvalidData, path + ": inverseBindMatrices holds " +
                                                           std::to_string(m.size() / 16) + " matrices for " +
                                                           std::to_string(skin.joints.size()) + " joints");
            for (size_t j = 0; j < skin.joints.size(); ++j)
                for (int e = 0; e < 16; ++e)
                    ibm[j][e / 4][e % 4] = m[16 * j + size_t(e)];
        }
        // M: exactly the identity where every joint the union has is bound
        // alike (the same vertices weld across the skins), else from the
        // first such joint; checked at every other below.
        glm::mat4 toFirst(1.0f);
        bool alike = true;
        for (size_t j = 0; j < skin.joints.size() && alike; ++j) {
            const auto it = unionJoint.find(skin.joints[j]);
            alike = it == unionJoint.end() || sameBinding(out->inverseBindMatrices[it->second], ibm[j]);
        }
        for (size_t j = 0; j < skin.joints.size() && !alike; ++j) {
            const auto it = unionJoint.find(skin.joints[j]);
            if (it != unionJoint.end()) {
                toFirst = glm::inverse(out->inverseBindMatrices[it->second]) * ibm[j];
                break;
            }
        }
        for (int e = 0; e < 16; ++e)
            if (!std::isfinite(toFirst[e / 4][e % 4]))
                return Status(StatusCode::InvalidData,
                              what + "'s inverse bind matrices are not invertible where skin " +
                                  std::to_string(out->skins[0]) + "'s share its joints");
        // A joint M does not reconcile: the skin's meshes were bound in
        // another pose (converters keep each mesh's own bind pose).  Its
        // vertices are then rebound one by one, each by the blend of its
        // joints' moves from this skin's bind space into the union's
        // (rig_scene checks that its joints agree where it lies).
        int apart = -1;
        for (size_t j = 0; j < skin.joints.size() && k > 0 && apart < 0; ++j) {
            const auto it = unionJoint.find(skin.joints[j]);
            if (it != unionJoint.end() && !sameBinding(out->inverseBindMatrices[it->second] * toFirst, ibm[j]))
                apart = skin.joints[j];
        }
        std::vector<glm::mat4> rebind;
        if (apart >= 0) {
            toFirst = glm::mat4(1.0f);
            rebind.assign(skin.joints.size(), glm::mat4(1.0f));
        }
        std::vector<uint16_t> jointOf(skin.joints.size());
        for (size_t j = 0; j < skin.joints.size(); ++j) {
            const int node = skin.joints[j];
            const auto it = unionJoint.find(node);
            if (it == unionJoint.end()) {
                if (out->joints.size() >= 0xffff)
                    return Status(StatusCode::InvalidData, path + ": the skins have too many joints");
                jointOf[j] = uint16_t(out->joints.size());
                unionJoint.emplace(node, jointOf[j]);
                out->joints.push_back(node);
                out->inverseBindMatrices.push_back(ibm[j] * glm::inverse(toFirst));
            } else {
                jointOf[j] = it->second;
                if (!rebind.empty()) {
                    rebind[j] = glm::inverse(out->inverseBindMatrices[it->second]) * ibm[j];
                    for (int e = 0; e < 16; ++e)
                        if (!std::isfinite(rebind[j][e / 4][e % 4]))
                            return Status(StatusCode::InvalidData,
                                          what + " binds joint node " + std::to_string(node) +
                                              " where skin " + std::to_string(out->skins[0]) +
                                              "'s inverse bind matrix is not invertible");
                }
            }
        }
        out->rebind.push_back(std::move(rebind));
        out->apartJoint.push_back(apart);
        out->jointOf.push_back(std::move(jointOf));
        out->toFirst.push_back(toFirst);
    }
    return Status::ok();
}

// Nodes, the skinned parts' skins as one (rigid parts ride on their node as
// an extra joint), per-vertex influences and animations.
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
    if (!scene.skinsUnited)
        return scene.skinsUnited;
    const SkinUnion& skins = scene.skins;
    for (const RigPart& part : rig->parts)
        if (part.skinned) {
            sk.meshNode = part.node;
            break;
        }
    Status st;
    // Without a skin, meshes an animation moves (it targets their node or
    // a node above it) are rigid parts of a skeleton all the same: played
    // and carried as one, where they were left standing.
    bool rigidAnimated = false;
    if (skins.skins.empty()) {
        std::vector<uint8_t> animated(nn, 0);
        for (const tinygltf::Animation& a : model.animations)
            for (const tinygltf::AnimationChannel& c : a.channels)
                if (c.target_node >= 0 && size_t(c.target_node) < nn)
                    animated[size_t(c.target_node)] = 1;
        for (const RigPart& part : rig->parts)
            for (int n = part.node, steps = 0; n >= 0 && size_t(n) < nn && steps <= int(nn) && !rigidAnimated;
                 n = sk.nodes[size_t(n)].parent, ++steps)
                rigidAnimated = animated[size_t(n)] != 0;
    }
    if (!skins.skins.empty() || rigidAnimated) {
        sk.skin.joints = skins.joints;
        sk.skin.inverseBindMatrices = skins.inverseBindMatrices;
        // The bind space was read at the scene's scale (bindSpaceScale):
        // the inverse bind matrices take that scale out again.
        for (const RigPart& part : rig->parts)
            if (part.skinned) {
                if (part.toScene != glm::mat4(1.0f)) {
                    const glm::mat4 fromScene = glm::inverse(part.toScene);
                    for (glm::mat4& ibm : sk.skin.inverseBindMatrices)
                        ibm = ibm * fromScene;
                }
                break;
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
                // bind matrix undoes the node's rest transform (an instance's
                // own transform within the node stays in its positions).
                uint16_t j = 0;
                if (part.node >= 0) {
                    auto it = rigidJoint.find(part.node);
                    if (it == rigidJoint.end()) {
                        if (sk.skin.joints.size() >= 0xffff)
                            return Status(StatusCode::InvalidData, path + ": too many joints");
                        it = rigidJoint.emplace(part.node, uint16_t(sk.skin.joints.size())).first;
                        sk.skin.joints.push_back(part.node);
                        sk.skin.inverseBindMatrices.push_back(
                            glm::inverse(part.toScene * glm::inverse(part.instanceTransform)));
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
            const int own = skins.indexOf(model.nodes[size_t(part.node)].skin);
            if (own < 0)
                return Status(StatusCode::InvalidData, path + ": " + part.name + "'s skin is not among the scene's");
            const std::vector<uint16_t>& jointOf = skins.jointOf[size_t(own)];
            for (int set = 0; set < sets; ++set) {
                std::vector<uint32_t> joints;
                std::vector<float> weights;
                if (!(st = readInfluenceSet(path, model, prim, part, set, &joints, &weights)))
                    return st;
                if (joints.empty())
                    continue;
                for (uint32_t v = 0; v < part.vertexCount; ++v)
                    for (int k = 0; k < 4; ++k) {
                        const uint32_t j = joints[4 * v + uint32_t(k)];
                        const float w = weights[4 * v + uint32_t(k)];
                        if (w != 0.0f && j >= jointOf.size())
                            return Status(StatusCode::InvalidData, path + ": " + part.name + ": vertex " +
                                                                       std::to_string(v) + " is skinned to joint " +
                                                                       std::to_string(j) + " of a " +
                                                                       std::to_string(jointOf.size()) +
                                                                       "-joint skin");
                        if (!(w >= 0.0f))
                            return Status(StatusCode::InvalidData, path + ": " + part.name + ": vertex " +
                                                                       std::to_string(v) + " has a negative skin weight");
                        const size_t slot = size_t(part.firstVertex + v) * size_t(inf) + size_t(4 * set + k);
                        fileJoints[slot] = w != 0.0f ? jointOf[j] : uint16_t(0);
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

}  // namespace rigfile

}  // namespace io
}  // namespace strata
