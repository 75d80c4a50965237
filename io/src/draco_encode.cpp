// KHR_draco_mesh_compression (libdraco), encoding: a compact rig's bare
// control mesh, whose quantised, predicted positions and Edgebreaker
// connectivity take about half the bytes of meshopt's codecs.
#include "gltf_accessor.h"
#include "gltf_document.h"
#include "gltf_mesh_writer.h"

#include <draco/compression/expert_encode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace strata {
namespace io {

namespace {

bool hasAttributesOnly(const tinygltf::Primitive& p)
{
    for (const auto& [name, a] : p.attributes)
        if (name != "POSITION" && name.rfind("TEXCOORD_", 0) != 0)
            return false;
    return p.attributes.count("POSITION") == 1;
}

// Bytes as a new bufferView of buffer 0, with no target (Draco data).
int appendData(tinygltf::Model& model, const std::vector<unsigned char>& bytes)
{
    const int view = appendBufferView(model, bytes.data(), bytes.size(), -1);
    model.bufferViews[size_t(view)].target = 0;
    return view;
}

}  // namespace

Status encodeDracoPrimitives(tinygltf::Model& model, double positionError, size_t* codedCount)
{
    size_t coded = 0;
    if (!(positionError > 0.0) || !std::isfinite(positionError)) {
        if (codedCount)
            *codedCount = 0;
        return Status::ok();
    }
    // Accessors used by more than one primitive (or by anything else) stay.
    std::vector<int> uses(model.accessors.size(), 0);
    forEachAccessorReference(model, [&](int& a, AccessorUse, const tinygltf::Primitive*) {
        if (a >= 0 && size_t(a) < uses.size())
            ++uses[size_t(a)];
    });
    for (tinygltf::Mesh& mesh : model.meshes)
        for (tinygltf::Primitive& prim : mesh.primitives) {
            if ((prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) || prim.indices < 0 || !prim.targets.empty() ||
                prim.extensions.count(kDracoExtension) != 0 || !hasAttributesOnly(prim))
                continue;
            bool alone = uses[size_t(prim.indices)] == 1;
            for (const auto& [name, a] : prim.attributes)
                alone = alone && a >= 0 && size_t(a) < uses.size() && uses[size_t(a)] == 1;
            const tinygltf::Accessor& pa = model.accessors[size_t(prim.attributes.at("POSITION"))];
            if (!alone || pa.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || pa.type != TINYGLTF_TYPE_VEC3)
                continue;
            std::vector<float> positions;
            std::vector<uint32_t> indices;
            Status st = readFloatAccessor(model, prim.attributes.at("POSITION"), 3, "POSITION", &positions);
            if (st)
                st = readUintAccessor(model, prim.indices, 1, "indices", &indices);
            if (!st)
                return st;
            const size_t nv = positions.size() / 3, nf = indices.size() / 3;
            if (nv == 0 || nf == 0 || indices.size() % 3)
                continue;
            draco::Mesh dm;
            dm.set_num_points(uint32_t(nv));
            std::vector<std::pair<std::string, int>> ids;
            float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (size_t i = 0; i < positions.size(); ++i) {
                lo[i % 3] = std::min(lo[i % 3], positions[i]);
                hi[i % 3] = std::max(hi[i % 3], positions[i]);
            }
            {
                draco::GeometryAttribute ga;
                ga.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, 12, 0);
                const int id = dm.AddAttribute(ga, true, uint32_t(nv));
                for (size_t i = 0; i < nv; ++i)
                    dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(uint32_t(i)), &positions[3 * i]);
                ids.emplace_back("POSITION", id);
            }
            bool ok = true;
            for (const auto& [name, a] : prim.attributes) {
                if (name == "POSITION")
                    continue;
                std::vector<float> uv;
                if (!readFloatAccessor(model, a, 2, name, &uv) || uv.size() != 2 * nv) {
                    ok = false;
                    break;
                }
                draco::GeometryAttribute ga;
                ga.Init(draco::GeometryAttribute::TEX_COORD, nullptr, 2, draco::DT_FLOAT32, false, 8, 0);
                const int id = dm.AddAttribute(ga, true, uint32_t(nv));
                for (size_t i = 0; i < nv; ++i)
                    dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(uint32_t(i)), &uv[2 * i]);
                ids.emplace_back(name, id);
            }
            if (!ok)
                continue;
            for (size_t f = 0; f < nf; ++f) {
                draco::Mesh::Face face;
                for (int k = 0; k < 3; ++k)
                    face[k] = draco::PointIndex(indices[3 * f + size_t(k)]);
                dm.AddFace(face);
            }
            // Draco quantises over the largest extent: a step of range / (2^q - 1),
            // half of which is the error.
            const double range = std::max({double(hi[0] - lo[0]), double(hi[1] - lo[1]), double(hi[2] - lo[2])});
            // Past 24 bits a step is finer than a float resolves over the
            // range, and Draco's 30-bit limit is near: such a mesh (a vertex
            // billions of units out) is left to the exact coding.
            const double needed = std::ceil(std::log2(range / (2.0 * positionError) + 1.0));
            if (!(needed <= 24.0))
                continue;  // stays meshopt-coded, or plain
            const int bits = std::max(8, int(needed));
            draco::ExpertEncoder encoder(dm);
            encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
            encoder.SetSpeedOptions(0, 0);
            for (const auto& [name, id] : ids)
                encoder.SetAttributeQuantization(id, name == "POSITION" ? bits : 16);
            draco::EncoderBuffer out;
            if (!encoder.EncodeToBuffer(&out).ok())
                continue;  // stays meshopt-coded
            const std::vector<unsigned char> bytes(out.data(), out.data() + out.size());
            tinygltf::Value::Object attributes;
            for (const auto& [name, id] : ids) {
                attributes[name] = tinygltf::Value(int(dm.attribute(id)->unique_id()));
                tinygltf::Accessor& acc = model.accessors[size_t(prim.attributes.at(name))];
                acc.bufferView = -1;
                acc.byteOffset = 0;
                if (name != "POSITION") {  // decoded as floats
                    acc.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
                    acc.normalized = false;
                }
            }
            tinygltf::Accessor& ia = model.accessors[size_t(prim.indices)];
            ia.bufferView = -1;
            ia.byteOffset = 0;
            tinygltf::Value::Object block;
            block["bufferView"] = tinygltf::Value(appendData(model, bytes));
            block["attributes"] = tinygltf::Value(attributes);
            prim.extensions[kDracoExtension] = tinygltf::Value(block);
            ++coded;
        }
    if (coded)
        useExtension(model, kDracoExtension, true);
    if (codedCount)
        *codedCount = coded;
    return Status::ok();
}

}  // namespace io
}  // namespace strata
