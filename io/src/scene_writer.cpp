// A reconstruction written as the rig's own glTF scene: every refined
// primitive in place of its control primitive, with the materials, skin,
// skeleton, animations, names and extras of the source, so a detailed
// character plays in any glTF viewer.
#include "strata/io/reconstruct.h"

#include "strata/io/file.h"
#include "gltf_accessor.h"
#include "gltf_document.h"
#include "gltf_mesh_writer.h"
#include "refined_attributes.h"
#include "rig_internal.h"

#include <filesystem>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace strata {
namespace io {
namespace {

constexpr int kMaxInfluences = 8;

// Skin influences of refined vertex v: the control vertices' influences
// blended with its barycentric weights in its control face, as joints of
// the part's own skin (ownJoint: per joint of the rig's skin, its joint in
// that skin, or -1 for one it lacks, as Strata's own rigid-part joints),
// the largest kMaxInfluences kept and renormalised.
int refinedInfluences(const Rig& rig, const SampleLocation& s, const std::vector<int>& ownJoint, uint16_t* joints,
                      float* weights)
{
    const VertexWeights& vw = rig.skeleton.weights;
    const size_t inf = size_t(vw.influences);
    std::pair<float, uint16_t> acc[3 * 8];
    int n = 0;
    const float bary[3] = {1.0f - s.bary.x - s.bary.y, s.bary.x, s.bary.y};
    for (int c = 0; c < 3; ++c) {
        if (s.face == kNoControlFace && c > 0)
            break;
        const uint32_t cv = s.face == kNoControlFace ? 0 : rig.mesh.triangles[3 * size_t(s.face) + size_t(c)];
        const float b = s.face == kNoControlFace ? 1.0f : bary[c];
        if (b <= 0.0f)
            continue;
        for (size_t k = 0; k < inf; ++k) {
            const float w = vw.weights[cv * inf + k] * b;
            const uint16_t rigJoint = vw.joints[cv * inf + k];
            if (w <= 0.0f || rigJoint >= ownJoint.size() || ownJoint[rigJoint] < 0)
                continue;
            const uint16_t j = uint16_t(ownJoint[rigJoint]);
            int at = 0;
            while (at < n && acc[at].second != j)
                ++at;
            if (at == n)
                acc[n++] = {0.0f, j};
            acc[at].first += w;
        }
    }
    std::sort(acc, acc + n, [](const auto& x, const auto& y) { return x.first > y.first; });
    n = std::min(n, kMaxInfluences);
    float sum = 0.0f;
    for (int k = 0; k < n; ++k)
        sum += acc[k].first;
    for (int k = 0; k < kMaxInfluences; ++k) {
        joints[k] = k < n ? acc[k].second : 0;
        weights[k] = k < n && sum > 0.0f ? acc[k].first / sum : 0.0f;
    }
    return n;
}

}  // namespace

Status writeReconstructedScene(const std::filesystem::path& pathFile, const Rig& rig, const Reconstruction& rec,
                               std::vector<std::string>* notes)
{
    const std::string path = pathFile.string();
    const std::string ext = extensionOf(path);
    if (ext != ".glb" && ext != ".gltf")
        return Status(StatusCode::InvalidArgument, path + ": a scene must be written as .glb or .gltf");
    if (!rig.source || rig.parts.empty() || rig.fileCorners.size() != rig.mesh.triangles.size())
        return Status(StatusCode::InvalidArgument, path + ": the rig was not loaded from a glTF scene");
    const Plan& plan = rec.plan();
    if (rec.positions.size() != plan.refinedVertexCount() || rec.normals.size() != plan.refinedVertexCount())
        return Status(StatusCode::InvalidArgument, path + ": the reconstruction has not been evaluated");
    for (const glm::vec3& p : rec.positions)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            return Status(StatusCode::InvalidData, path + ": the reconstruction has non-finite positions");
    const int level = plan.level();
    FaceVaryingRefinement fv;
    Status st = refineFaceVarying(&fv, rig.mesh, rig.fileCorners.data(), rig.sourceVertex.size(), level);
    if (!st)
        return Status(st.code(), path + ": " + st.message());

    tinygltf::Model model = rig.source->model;
    std::vector<std::vector<unsigned char>> imageBytes = rig.source->imageBytes;
    imageBytes.resize(model.images.size());
    // The output is a plain detailed mesh: no displacement block, no map.
    const int mapImage = dropLayers(model);
    if (mapImage >= 0 && size_t(mapImage) < model.images.size())
        removeImage(model, &imageBytes, mapImage);
    embedImages(model, imageBytes, notes);

    const size_t perFace = size_t(1) << (2 * level);
    // The rig's skin is the union of the file's (rigfile::SkinUnion): each
    // part's influences go back to its own skin's joints.
    rigfile::SkinUnion skins;
    if (!(st = rigfile::uniteSkins(path, model, rig.parts, &skins)))
        return st;
    // A mesh whose vertices were rebound one by one into the union's bind
    // space has no one transform back to its own skin's.
    for (size_t k = 0; k < skins.rebind.size(); ++k)
        if (!skins.rebind[k].empty())
            return Status(StatusCode::Unsupported,
                          path + ": skin " + std::to_string(skins.skins[k]) +
                              " binds its meshes in another pose than skin " + std::to_string(skins.skins[0]) +
                              "; their refined scene cannot be written back on their own skins");
    size_t droppedTangents = 0, droppedTargets = 0;
    for (const RigPart& part : rig.parts) {
        if (part.faceCount == 0)
            continue;  // only zero-area triangles: kept as they were
        tinygltf::Primitive& prim = model.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
        const std::string what = path + ": " + part.name;
        // Output vertices: one per (refined vertex, refined corner value).
        std::unordered_map<uint64_t, uint32_t> vertexOf;
        std::vector<uint32_t> refinedVertex, cornerValue, indices;
        const size_t f0 = size_t(part.firstFace) * perFace, f1 = size_t(part.firstFace + part.faceCount) * perFace;
        indices.reserve((f1 - f0) * 3);
        for (size_t f = f0; f < f1; ++f)
            for (int c = 0; c < 3; ++c) {
                const uint32_t v = plan.refinedTriangles()[3 * f + size_t(c)], u = fv.corners[3 * f + size_t(c)];
                auto it = vertexOf.emplace((uint64_t(v) << 32) | u, uint32_t(refinedVertex.size()));
                if (it.second) {
                    refinedVertex.push_back(v);
                    cornerValue.push_back(u);
                }
                indices.push_back(it.first->second);
            }
        // A mirrored part's faces turn outward as drawn; the file's winding
        // is the other way (rigfile::mirrors).
        if (rigfile::mirrors(part))
            rigfile::reverseWinding(&indices);
        const size_t nv = refinedVertex.size();
        // Positions and normals in the mesh's own space.
        const glm::mat4 toMesh = glm::inverse(part.toScene);
        const glm::mat3 normalToMesh = glm::transpose(glm::mat3(part.toScene));
        std::vector<glm::vec3> pos(nv), nrm(nv);
        std::vector<double> lo(3, 1e300), hi(3, -1e300);
        for (size_t i = 0; i < nv; ++i) {
            pos[i] = glm::vec3(toMesh * glm::vec4(rec.positions[refinedVertex[i]], 1.0f));
            const glm::vec3 n = normalToMesh * rec.normals[refinedVertex[i]];
            const float len = glm::length(n);
            nrm[i] = len > 0.0f ? n / len : glm::vec3(0.0f, 0.0f, 1.0f);
            for (int c = 0; c < 3; ++c) {
                lo[size_t(c)] = std::min(lo[size_t(c)], double(pos[i][c]));
                hi[size_t(c)] = std::max(hi[size_t(c)], double(pos[i][c]));
            }
        }
        std::map<std::string, int> attributes;
        int view = appendBufferView(model, pos.data(), nv * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
        attributes["POSITION"] = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
        model.accessors.back().minValues = lo;
        model.accessors.back().maxValues = hi;
        // A flat part keeps no NORMAL, so that viewers shade it flat as
        // glTF asks (the capture was drawn so).
        if (!part.flat) {
            view = appendBufferView(model, nrm.data(), nv * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
            attributes["NORMAL"] = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
        }
        // Per-corner attributes (material UVs, colours, custom data), refined
        // linearly inside each control face.
        for (const auto& [name, acc] : prim.attributes) {
            if (!isRefinedAttribute(name)) {
                droppedTangents += name == "TANGENT";
                continue;
            }
            const int comps = attributeComponents(model, acc);
            if (comps <= 0)
                return Status(StatusCode::InvalidData, what + ": " + name + " has no valid accessor");
            std::vector<float> out(nv * size_t(comps), 0.0f);
            if (!(st = refinePartAttribute(model, part, fv, cornerValue.data(), nv, acc, name, comps, out.data(),
                                           size_t(comps))))
                return Status(st.code(), what + ": " + st.message());
            const int type = model.accessors[size_t(acc)].type;
            view = appendBufferView(model, out.data(), out.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER);
            attributes[name] = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, type, nv);
        }
        // Skin influences, refined through the sample locations.
        const int skin = part.skinned ? skins.indexOf(model.nodes[size_t(part.node)].skin) : -1;
        if (skin >= 0) {
            std::vector<int> ownJoint(skins.joints.size(), -1);
            const std::vector<uint16_t>& jointOf = skins.jointOf[size_t(skin)];
            for (size_t j = 0; j < jointOf.size(); ++j)
                ownJoint[jointOf[j]] = int(j);
            std::vector<uint16_t> joints(nv * kMaxInfluences);
            std::vector<float> weights(nv * kMaxInfluences);
            int most = 0;
            for (size_t i = 0; i < nv; ++i) {
                const int n = refinedInfluences(rig, plan.sampleLocations()[refinedVertex[i]], ownJoint,
                                                &joints[i * kMaxInfluences], &weights[i * kMaxInfluences]);
                if (n == 0)
                    return Status(StatusCode::InvalidData, what + ": a refined vertex has no skin weight");
                most = std::max(most, n);
            }
            for (int set = 0; set * 4 < most; ++set) {
                std::vector<uint16_t> j(nv * 4);
                std::vector<float> w(nv * 4);
                for (size_t i = 0; i < nv; ++i)
                    for (int k = 0; k < 4; ++k) {
                        j[4 * i + size_t(k)] = joints[i * kMaxInfluences + size_t(4 * set + k)];
                        w[4 * i + size_t(k)] = weights[i * kMaxInfluences + size_t(4 * set + k)];
                    }
                view = appendBufferView(model, j.data(), j.size() * 2, TINYGLTF_TARGET_ARRAY_BUFFER);
                attributes["JOINTS_" + std::to_string(set)] =
                    appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC4, nv);
                view = appendBufferView(model, w.data(), w.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER);
                attributes["WEIGHTS_" + std::to_string(set)] =
                    appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, nv);
            }
        }
        view = appendBufferView(model, indices.data(), indices.size() * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
        prim.indices = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
                                      indices.size());
        prim.attributes = std::move(attributes);
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        if (!prim.targets.empty()) {
            ++droppedTargets;
            prim.targets.clear();
        }
    }
    if (droppedTargets)
        for (const RigPart& part : rig.parts)
            model.meshes[size_t(part.mesh)].weights.clear();
    if (notes && droppedTangents)
        notes->push_back(std::to_string(droppedTangents) +
                         " primitives had TANGENTs, which are not refined; viewers compute them");
    if (notes && droppedTargets)
        notes->push_back(std::to_string(droppedTargets) + " primitives had morph targets, which are not refined yet");
    rootSkinnedMeshNodes(model, notes);
    return packAndWrite(path, model, true);
}

}  // namespace io
}  // namespace strata
