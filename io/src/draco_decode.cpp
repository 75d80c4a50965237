// KHR_draco_mesh_compression (libdraco), decoding: every .glb is decoded
// before tinygltf parses it (tinygltf needs every index accessor to have
// data), so Draco-compressed characters load like any other.  Writing is in
// draco_encode.cpp (a reader, such as the WebAssembly runtime, links no
// encoder).
#include "gltf_accessor.h"
#include "gltf_document.h"
#include "gltf_mesh_writer.h"

#include <nlohmann/json.hpp>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace strata {
namespace io {

namespace {

const tinygltf::Value* dracoBlock(const tinygltf::Primitive& p)
{
    const auto it = p.extensions.find(kDracoExtension);
    return it == p.extensions.end() ? nullptr : &it->second;
}

template <typename T>
bool putAll(const draco::PointAttribute& att, size_t points, int components, bool normalized, unsigned char* out)
{
    // Normalised integers come back from float data scaled to the type's range.
    const bool scale = normalized && std::is_integral<T>::value && att.data_type() == draco::DT_FLOAT32;
    std::vector<float> f(static_cast<size_t>(components));
    std::vector<T> v(static_cast<size_t>(components));
    for (size_t i = 0; i < points; ++i) {
        const draco::AttributeValueIndex at = att.mapped_index(draco::PointIndex(uint32_t(i)));
        if (scale) {
            if (!att.ConvertValue<float>(at, int8_t(components), f.data()))
                return false;
            for (int c = 0; c < components; ++c) {
                const double x = std::min(1.0, std::max(0.0, double(f[size_t(c)])));  // NaN -> 0
                v[size_t(c)] = T(std::lround(x * double(std::numeric_limits<T>::max())));
            }
        } else if (!att.ConvertValue<T>(at, int8_t(components), v.data())) {
            return false;
        }
        std::memcpy(out + i * sizeof(T) * size_t(components), v.data(), sizeof(T) * size_t(components));
    }
    return true;
}

}  // namespace

int dracoView(const tinygltf::Primitive& p)
{
    const tinygltf::Value* block = dracoBlock(p);
    if (!block || !block->IsObject() || !block->Has("bufferView") || !block->Get("bufferView").IsNumber())
        return -1;
    const double v = block->Get("bufferView").GetNumberAsDouble();
    return v >= 0 && v < 2147483647.0 ? int(v) : -1;
}

void setDracoView(tinygltf::Primitive* p, int view)
{
    tinygltf::Value::Object block = p->extensions[kDracoExtension].Get<tinygltf::Value::Object>();
    block["bufferView"] = tinygltf::Value(view);
    p->extensions[kDracoExtension] = tinygltf::Value(block);
}

Status decodeDracoJson(nlohmann::json& doc, std::vector<unsigned char>* bin, const std::string& path)
{
    using Json = nlohmann::json;
    auto bad = [&](const std::string& what) { return Status(StatusCode::InvalidData, path + ": " + kDracoExtension + ": " + what); };
    auto index = [](const Json& o, const char* name, size_t limit, size_t* out) {
        if (!o.is_object() || !o.contains(name) || !o[name].is_number_unsigned())
            return false;
        *out = o[name].get<size_t>();
        return *out < limit;
    };
    if (!doc.contains("meshes") || !doc["meshes"].is_array())
        return Status::ok();
    if (!doc.contains("accessors") || !doc["accessors"].is_array() || !doc.contains("bufferViews") ||
        !doc["bufferViews"].is_array() || !doc.contains("buffers") || !doc["buffers"].is_array() ||
        doc["buffers"].empty() || !doc["buffers"][0].is_object() || doc["buffers"][0].contains("uri"))
        return bad("needs accessors, bufferViews and the BIN chunk as buffer 0");
    Json& accessors = doc["accessors"];
    Json& views = doc["bufferViews"];
    bool any = false;
    // Appends bytes as a new view of buffer 0; returns its index.
    auto append = [&](const std::vector<unsigned char>& bytes) {
        while (bin->size() % 4)
            bin->push_back(0);
        Json view = Json::object();
        view["buffer"] = 0;
        view["byteOffset"] = bin->size();
        view["byteLength"] = bytes.size();
        bin->insert(bin->end(), bytes.begin(), bytes.end());
        views.push_back(view);
        return views.size() - 1;
    };
    for (size_t m = 0; m < doc["meshes"].size(); ++m) {
        Json& mesh = doc["meshes"][m];
        if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array())
            continue;
        for (size_t pi = 0; pi < mesh["primitives"].size(); ++pi) {
            Json& prim = mesh["primitives"][pi];
            if (!prim.is_object() || !prim.contains("extensions") || !prim["extensions"].is_object() ||
                !prim["extensions"].contains(kDracoExtension))
                continue;
            any = true;
            const std::string where = "mesh " + std::to_string(m) + " primitive " + std::to_string(pi);
            const Json block = prim["extensions"][kDracoExtension];
            size_t v = 0;
            if (!index(block, "bufferView", views.size(), &v) || !block.contains("attributes") ||
                !block["attributes"].is_object() || !prim.contains("attributes") || !prim["attributes"].is_object())
                return bad(where + " needs a bufferView and attributes");
            const Json& view = views[v];
            size_t buffer = 0, offset = 0, length = 0;
            if (!view.is_object() || (view.contains("buffer") && !index(view, "buffer", 1, &buffer)) ||
                !view.contains("byteLength") || !view["byteLength"].is_number_unsigned())
                return bad(where + ": its bufferView is not in the BIN chunk");
            if (view.contains("byteOffset") && !index(view, "byteOffset", bin->size() + 1, &offset))
                return bad(where + ": its bufferView lies outside the BIN chunk");
            length = view["byteLength"].get<size_t>();
            if (offset > bin->size() || length > bin->size() - offset)
                return bad(where + ": its bufferView lies outside the BIN chunk");
            const std::vector<unsigned char> encoded(bin->begin() + long(offset), bin->begin() + long(offset + length));
            draco::DecoderBuffer buf;
            buf.Init(reinterpret_cast<const char*>(encoded.data()), encoded.size());
            const auto type = draco::Decoder::GetEncodedGeometryType(&buf);
            if (!type.ok() || type.value() != draco::TRIANGULAR_MESH)
                return bad(where + " is not a Draco triangle mesh");
            draco::Decoder decoder;
            auto decoded = decoder.DecodeMeshFromBuffer(&buf);
            if (!decoded.ok())
                return bad(where + ": " + printable(decoded.status().error_msg_string(), 80));
            const std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
            const size_t points = dm->num_points(), faces = dm->num_faces();
            if (prim.contains("mode") && !(prim["mode"].is_number_unsigned() && prim["mode"].get<size_t>() == 4))
                return bad(where + " is not a triangle list");
            for (const auto& [name, id] : block["attributes"].items()) {
                size_t a = 0;
                if (!prim["attributes"].contains(name) || !index(prim["attributes"], name.c_str(), accessors.size(), &a) ||
                    !id.is_number_unsigned() || id.get<size_t>() > 0xffffffffu)
                    return bad(where + ": attribute " + printable(name, 40) + " has no accessor or no Draco id");
                Json& acc = accessors[a];
                const draco::PointAttribute* att = dm->GetAttributeByUniqueId(uint32_t(id.get<size_t>()));
                const std::string typeName = acc.is_object() && acc.contains("type") && acc["type"].is_string()
                                                 ? acc["type"].get<std::string>()
                                                 : "";
                const int comps = typeName == "SCALAR" ? 1 : typeName == "VEC2" ? 2 : typeName == "VEC3" ? 3 : typeName == "VEC4" ? 4 : 0;
                size_t count = 0;
                if (!att || comps == 0 || att->num_components() < comps || !acc.contains("count") ||
                    !acc["count"].is_number_unsigned() || !acc.contains("componentType") ||
                    !acc["componentType"].is_number_unsigned())
                    return bad(where + ": the Draco data has no " + printable(name, 40) + " its accessor can hold");
                count = acc["count"].get<size_t>();
                if (count != points)
                    return bad(where + ": " + printable(name, 40) + " declares " + std::to_string(count) +
                               " elements, Draco holds " + std::to_string(points));
                if (acc.contains("bufferView"))
                    continue;  // an uncompressed fallback is kept as it is
                const int componentType = acc["componentType"].get<int>();
                const bool n = acc.contains("normalized") && acc["normalized"].is_boolean() && acc["normalized"].get<bool>();
                int size = 0;
                bool converted = false;
                std::vector<unsigned char> out;
                auto put = [&](auto zero) {
                    using T = decltype(zero);
                    size = int(sizeof(T));
                    out.resize(points * size_t(comps) * sizeof(T));
                    converted = putAll<T>(*att, points, comps, n, out.data());
                };
                switch (componentType) {
                    case TINYGLTF_COMPONENT_TYPE_FLOAT: put(0.0f); break;
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: put(uint16_t(0)); break;
                    case TINYGLTF_COMPONENT_TYPE_SHORT: put(int16_t(0)); break;
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: put(uint8_t(0)); break;
                    case TINYGLTF_COMPONENT_TYPE_BYTE: put(int8_t(0)); break;
                    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: put(uint32_t(0)); break;
                    default: break;
                }
                if (!converted || size == 0)
                    return bad(where + ": " + printable(name, 40) + " cannot be read as its accessor's type");
                acc["bufferView"] = append(out);
                acc.erase("byteOffset");
            }
            size_t ia = 0;
            if (prim.contains("indices")) {
                if (!index(prim, "indices", accessors.size(), &ia))
                    return bad(where + ": its indices accessor does not exist");
                Json& acc = accessors[ia];
                if (!acc.is_object() || !acc.contains("count") || !acc["count"].is_number_unsigned() ||
                    acc["count"].get<size_t>() != 3 * faces)
                    return bad(where + ": its indices do not count the Draco mesh's " + std::to_string(3 * faces));
                if (!acc.contains("bufferView")) {
                    const int componentType =
                        acc.contains("componentType") && acc["componentType"].is_number_unsigned() ? acc["componentType"].get<int>() : 0;
                    const size_t size = componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                                        : componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                                        : componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                                  : 0;
                    if (size == 0 || (size < 4 && points > (size_t(1) << (8 * size))))
                        return bad(where + ": its indices cannot hold the Draco mesh's");
                    std::vector<unsigned char> out(3 * faces * size);
                    for (size_t f = 0; f < faces; ++f)
                        for (int k = 0; k < 3; ++k) {
                            const uint32_t x = dm->face(draco::FaceIndex(uint32_t(f)))[k].value();
                            std::memcpy(out.data() + (3 * f + size_t(k)) * size, &x, size);  // little-endian
                        }
                    acc["bufferView"] = append(out);
                    acc.erase("byteOffset");
                }
            }
            prim["extensions"].erase(kDracoExtension);
            if (prim["extensions"].empty())
                prim.erase("extensions");
        }
    }
    if (!any)
        return Status::ok();
    doc["buffers"][0]["byteLength"] = bin->size();
    dropExtension(doc, kDracoExtension);
    return Status::ok();
}

}  // namespace io
}  // namespace strata
