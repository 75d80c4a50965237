// EXT_meshopt_compression (libmeshoptimizer): rigs are written with their
// vertex attributes and triangle indices meshopt-coded, and any .glb that
// uses the extension (a Strata rig, gltfpack -c/-cc output) or
// KHR_draco_mesh_compression (draco_decode.cpp) is decoded back to a plain
// document before tinygltf, which knows neither, parses it.
#include "gltf_document.h"

#include "gltf_accessor.h"
#include "gltf_mesh_writer.h"
#include "strata/io/file.h"

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <map>
#include <sstream>

namespace strata {
namespace io {
namespace {

using Json = nlohmann::json;

uint32_t read32(const unsigned char* p)
{
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}

void putLittleEndian32(std::string& s, uint32_t v)
{
    s.append(reinterpret_cast<const char*>(&v), 4);
}

// A .glb from its JSON text and BIN bytes (both padded to 4 bytes).
std::string assembleGlb(std::string json, const std::vector<unsigned char>& bin)
{
    while (json.size() % 4)
        json.push_back(' ');
    std::string out = "glTF";
    putLittleEndian32(out, 2);
    const size_t binChunk = bin.empty() ? 0 : 8 + ((bin.size() + 3) & ~size_t(3));
    putLittleEndian32(out, uint32_t(12 + 8 + json.size() + binChunk));
    putLittleEndian32(out, uint32_t(json.size()));
    out += "JSON";
    out += json;
    if (!bin.empty()) {
        putLittleEndian32(out, uint32_t((bin.size() + 3) & ~size_t(3)));
        out += std::string("BIN\0", 4);
        out.append(reinterpret_cast<const char*>(bin.data()), bin.size());
        out.append((4 - bin.size() % 4) % 4, '\0');
    }
    return out;
}

// Splits a .glb into its JSON and BIN chunks; false if it is not one.
bool splitGlb(const unsigned char* data, size_t size, std::string* json, const unsigned char** bin, size_t* binSize)
{
    if (size < 20 || std::memcmp(data, "glTF", 4) != 0)
        return false;
    const size_t jsonLength = read32(data + 12);
    if (std::memcmp(data + 16, "JSON", 4) != 0 || jsonLength > size - 20)
        return false;
    json->assign(reinterpret_cast<const char*>(data + 20), jsonLength);
    *bin = nullptr;
    *binSize = 0;
    const size_t at = 20 + jsonLength;
    if (size >= at + 8 && std::memcmp(data + at + 4, "BIN\0", 4) == 0) {
        const size_t length = read32(data + at);
        if (length > size - at - 8)
            return false;
        *bin = data + at + 8;
        *binSize = length;
    }
    return true;
}

bool usesExtension(const Json& doc, const char* name = kMeshoptExtension)
{
    if (!doc.is_object() || !doc.contains("extensionsUsed") || !doc["extensionsUsed"].is_array())
        return false;
    for (const Json& e : doc["extensionsUsed"])
        if (e.is_string() && e.get<std::string>() == name)
            return true;
    return false;
}

size_t sizeField(const Json& o, const char* name, size_t fallback, bool* ok)
{
    if (!o.contains(name))
        return fallback;
    const Json& v = o[name];
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<long long>() >= 0)) {
        *ok = false;
        return 0;
    }
    return v.get<size_t>();
}

}  // namespace

void dropExtension(Json& doc, const char* name)
{
    for (const char* list : {"extensionsUsed", "extensionsRequired"})
        if (doc.contains(list) && doc[list].is_array()) {
            Json kept = Json::array();
            for (const Json& e : doc[list])
                if (!(e.is_string() && e.get<std::string>() == name))
                    kept.push_back(e);
            if (kept.empty())
                doc.erase(list);
            else
                doc[list] = kept;
        }
}

Status decodeCompressedGlb(const unsigned char* data, size_t size, const std::string& path, std::string* plain)
{
    plain->clear();
    std::string jsonText;
    const unsigned char* bin = nullptr;
    size_t binSize = 0;
    if (!splitGlb(data, size, &jsonText, &bin, &binSize))
        return Status::ok();  // not a glb: tinygltf reports it
    if (jsonText.find(kMeshoptExtension) == std::string::npos && jsonText.find(kDracoExtension) == std::string::npos)
        return Status::ok();
    Json doc = Json::parse(jsonText, nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded())
        return Status::ok();
    const bool meshopt = usesExtension(doc), draco = usesExtension(doc, kDracoExtension);
    if (!meshopt && !draco)
        return Status::ok();
    if (!meshopt) {
        std::vector<unsigned char> out(bin, bin + binSize);
        Status st = decodeDracoJson(doc, &out, path);
        if (!st)
            return st;
        *plain = assembleGlb(doc.dump(), out);
        return Status::ok();
    }
    auto bad = [&](const std::string& what) {
        return Status(StatusCode::InvalidData, path + ": " + kMeshoptExtension + ": " + what);
    };
    if (!doc.contains("buffers") || !doc["buffers"].is_array() || !doc.contains("bufferViews") ||
        !doc["bufferViews"].is_array())
        return bad("no buffers or bufferViews");
    Json& buffers = doc["buffers"];
    Json& views = doc["bufferViews"];
    // Buffer 0 is the BIN chunk; every other buffer must be a fallback (no
    // data) whose views are all compressed.
    std::vector<bool> fallback(buffers.size(), false);
    for (size_t b = 0; b < buffers.size(); ++b) {
        const Json& buf = buffers[b];
        if (!buf.is_object())
            return bad("buffer " + std::to_string(b) + " is not an object");
        if (b == 0 && !buf.contains("uri"))
            continue;
        const bool isFallback = buf.contains("extensions") && buf["extensions"].is_object() &&
                                buf["extensions"].contains(kMeshoptExtension);
        if (!isFallback)
            return bad("buffer " + std::to_string(b) + " is not the BIN chunk nor a fallback (external buffers are not read here)");
        fallback[b] = true;
    }
    // Memory justified by bytes: a fallback buffer is no backing, so it may
    // declare no more than the views coded into it fill (with alignment),
    // and each view may decode to no more than its coded bytes can carry
    // (meshopt's codecs reach about 64:1 on constant data).
    std::vector<double> filled(buffers.size(), 0.0);
    for (size_t v = 0; v < views.size(); ++v) {
        const Json& view = views[v];
        if (!view.is_object() || !view.contains("extensions") || !view["extensions"].is_object() ||
            !view["extensions"].contains(kMeshoptExtension))
            continue;
        bool ok = true;
        const Json& ext = view["extensions"][kMeshoptExtension];
        const size_t buffer = sizeField(view, "buffer", 0, &ok), dstLength = sizeField(view, "byteLength", 0, &ok),
                     srcLength = sizeField(ext, "byteLength", 0, &ok);
        if (!ok || buffer >= buffers.size())
            return bad("bufferView " + std::to_string(v) + " has an invalid compressed range");
        if (double(dstLength) > 128.0 * double(srcLength) + 4096.0)
            return bad("bufferView " + std::to_string(v) + " declares " + std::to_string(dstLength) +
                       " bytes decoded from only " + std::to_string(srcLength) + " coded bytes");
        filled[buffer] += double(dstLength) + 16.0;
    }
    std::vector<unsigned char> out(bin, bin + binSize);
    std::vector<size_t> fallbackBase(buffers.size(), 0);
    for (size_t b = 0; b < buffers.size(); ++b)
        if (fallback[b]) {
            bool ok = true;
            const size_t length = sizeField(buffers[b], "byteLength", 0, &ok);
            if (!ok || length > (size_t(1) << 31))
                return bad("fallback buffer " + std::to_string(b) + " has an invalid byteLength");
            if (double(length) > filled[b] + 64.0)
                return bad("fallback buffer " + std::to_string(b) + " declares " + std::to_string(length) +
                           " bytes but its coded views fill only " + std::to_string(size_t(filled[b])) +
                           " (a fallback is no backing)");
            while (out.size() % 16)
                out.push_back(0);
            fallbackBase[b] = out.size();
            out.resize(out.size() + length, 0);
        }
    for (size_t v = 0; v < views.size(); ++v) {
        Json& view = views[v];
        if (!view.is_object())
            return bad("bufferView " + std::to_string(v) + " is not an object");
        bool ok = true;
        const size_t buffer = sizeField(view, "buffer", 0, &ok);
        if (!ok || buffer >= buffers.size())
            return bad("bufferView " + std::to_string(v) + " has no valid buffer");
        const bool compressed = view.contains("extensions") && view["extensions"].is_object() &&
                                view["extensions"].contains(kMeshoptExtension);
        if (!compressed) {
            if (fallback[buffer])
                return bad("bufferView " + std::to_string(v) + " reads a fallback buffer without being compressed");
            continue;
        }
        const Json& ext = view["extensions"][kMeshoptExtension];
        const size_t src = sizeField(ext, "buffer", 0, &ok), srcOffset = sizeField(ext, "byteOffset", 0, &ok),
                     srcLength = sizeField(ext, "byteLength", 0, &ok), stride = sizeField(ext, "byteStride", 0, &ok),
                     count = sizeField(ext, "count", 0, &ok);
        const std::string mode = ext.contains("mode") && ext["mode"].is_string() ? ext["mode"].get<std::string>() : "";
        const std::string filter =
            ext.contains("filter") && ext["filter"].is_string() ? ext["filter"].get<std::string>() : "NONE";
        const size_t dstOffset = sizeField(view, "byteOffset", 0, &ok), dstLength = sizeField(view, "byteLength", 0, &ok);
        if (!ok || src != 0 || fallback[src] || srcOffset > binSize || srcLength > binSize - srcOffset || stride == 0 ||
            stride > 256 || count > (size_t(1) << 28) || count * stride > dstLength)
            return bad("bufferView " + std::to_string(v) + " has an invalid compressed range");
        const size_t base = fallback[buffer] ? fallbackBase[buffer] : 0;
        const size_t bufferLength = fallback[buffer] ? sizeField(buffers[buffer], "byteLength", 0, &ok) : binSize;
        if (dstOffset > bufferLength || dstLength > bufferLength - dstOffset)
            return bad("bufferView " + std::to_string(v) + " lies outside its buffer");
        unsigned char* dst = out.data() + base + dstOffset;
        const unsigned char* encoded = bin + srcOffset;
        int rc = -1;
        if (mode == "ATTRIBUTES" && stride % 4 == 0)
            rc = meshopt_decodeVertexBuffer(dst, count, stride, encoded, srcLength);
        else if (mode == "TRIANGLES" && (stride == 2 || stride == 4) && count % 3 == 0)
            rc = meshopt_decodeIndexBuffer(dst, count, stride, encoded, srcLength);
        else if (mode == "INDICES" && (stride == 2 || stride == 4))
            rc = meshopt_decodeIndexSequence(dst, count, stride, encoded, srcLength);
        if (rc != 0)
            return bad("bufferView " + std::to_string(v) + " does not decode (mode " + printable(mode, 20) + ")");
        if (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8))
            meshopt_decodeFilterOct(dst, count, stride);
        else if (filter == "QUATERNION" && stride == 8)
            meshopt_decodeFilterQuat(dst, count, stride);
        else if (filter == "EXPONENTIAL" && stride % 4 == 0)
            meshopt_decodeFilterExp(dst, count, stride);
        else if (filter != "NONE")
            return bad("bufferView " + std::to_string(v) + " uses filter " + printable(filter, 20));
        view.erase("extensions");
        // An ATTRIBUTES view decodes to elements `stride` apart.  Writers
        // that pad small elements (glTF Transform pads a SCALAR of bytes to
        // 4) may leave byteStride off a view no vertex attribute reads; the
        // elements are still that far apart.
        if (mode == "ATTRIBUTES" && !view.contains("byteStride") && count > 1 && count * stride == dstLength)
            view["byteStride"] = stride;
        view["buffer"] = 0;
        view["byteOffset"] = base + dstOffset;
    }
    // One buffer: the BIN chunk with the decoded data after it.
    Json plainBuffer = Json::object();
    plainBuffer["byteLength"] = out.size();
    doc["buffers"] = Json::array({plainBuffer});
    if (draco) {
        Status st = decodeDracoJson(doc, &out, path);
        if (!st)
            return st;
    }
    dropExtension(doc, kMeshoptExtension);
    *plain = assembleGlb(doc.dump(), out);
    return Status::ok();
}

namespace {

Status plainGlb(const std::string& path, const tinygltf::Model& model, std::string* out)
{
    tinygltf::TinyGLTF writer;
    std::ostringstream stream;
    if (!writer.WriteGltfSceneToStream(&model, stream, false, true))
        return Status(StatusCode::IoError, path + ": glTF serialisation failed");
    *out = stream.str();
    return Status::ok();
}

}  // namespace

Status writeCompressedGlb(const std::string& path, tinygltf::Model& model, double positionError, bool draco)
{
    std::string bytes;
    Status st = encodeCompressedGlb(path, model, &bytes, positionError, draco);
    return st ? writeFileAtomic(path, bytes.data(), bytes.size()) : st;
}

namespace {

// Gives every primitive's attribute, morph target and index accessor a
// tightly packed bufferView of its own where its view is shared with
// another accessor, has a stride other than its element, or the accessor
// starts at an offset: the layout meshopt's codecs code.  Accessors that
// skins, animations or a layer also use keep their views.
Status ownViews(tinygltf::Model& model)
{
    const size_t na = model.accessors.size(), nv = model.bufferViews.size();
    std::vector<int> users(nv, 0);
    std::vector<uint8_t> geometry(na, 0), other(na, 0);
    for (const tinygltf::Accessor& a : model.accessors)
        if (a.bufferView >= 0 && size_t(a.bufferView) < nv)
            ++users[size_t(a.bufferView)];
    forEachAccessorReference(model, [&](int& a, AccessorUse use, const tinygltf::Primitive*) {
        if (a < 0 || size_t(a) >= na)
            return;
        (use == AccessorUse::Other ? other : geometry)[size_t(a)] = 1;
    });
    for (size_t a = 0; a < na; ++a) {
        const tinygltf::Accessor acc = model.accessors[a];
        if (!geometry[a] || other[a] || acc.bufferView < 0 || size_t(acc.bufferView) >= nv || acc.sparse.isSparse)
            continue;
        const tinygltf::BufferView view = model.bufferViews[size_t(acc.bufferView)];
        const int cbytes = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
        const int comps = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
        if (cbytes <= 0 || comps <= 0)
            continue;
        const size_t elem = size_t(cbytes) * size_t(comps);
        const size_t stride = view.byteStride ? size_t(view.byteStride) : elem;
        if (users[size_t(acc.bufferView)] == 1 && acc.byteOffset == 0 && stride == ((elem + 3) & ~size_t(3)) &&
            view.byteLength == stride * acc.count)
            continue;
        if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
            return Status(StatusCode::InvalidData, "bufferView " + std::to_string(acc.bufferView) +
                                                       " references a missing buffer");
        const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
        const bool indices = view.target == TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER || (comps == 1 && elem <= 4 &&
                                                                                    acc.type == TINYGLTF_TYPE_SCALAR &&
                                                                                    view.target != TINYGLTF_TARGET_ARRAY_BUFFER);
        const size_t packed = indices ? elem : (elem + 3) & ~size_t(3);
        std::vector<unsigned char> bytes(packed * acc.count, 0);
        for (size_t i = 0; i < acc.count; ++i) {
            const size_t at = view.byteOffset + acc.byteOffset + i * stride;
            if (at > data.size() || elem > data.size() - at || at + elem > view.byteOffset + view.byteLength)
                return Status(StatusCode::InvalidData, "accessor " + std::to_string(a) +
                                                           " reads past the end of its bufferView");
            std::memcpy(&bytes[i * packed], &data[at], elem);
        }
        const int v = appendBufferView(model, bytes.data(), bytes.size(),
                                       indices ? TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER : TINYGLTF_TARGET_ARRAY_BUFFER);
        if (packed != elem)
            model.bufferViews[size_t(v)].byteStride = packed;
        tinygltf::Accessor& moved = model.accessors[a];
        moved.bufferView = v;
        moved.byteOffset = 0;
    }
    return packBuffers(model);  // drops the views nothing uses now
}

}  // namespace

Status encodeCompressedGlb(const std::string& path, tinygltf::Model& model, std::string* out, double positionError,
                           bool draco, std::vector<std::string>* notes)
{
    Status st = prepareForWriting(path, model);
    if (!st)
        return st;
    size_t dracoCoded = 0;
    if (draco && positionError > 0.0) {
        if (!(st = encodeDracoPrimitives(model, positionError, &dracoCoded)))
            return Status(st.code(), path + ": " + st.message());
        if (dracoCoded && !(st = packBuffers(model)))  // drops the views Draco replaced
            return Status(st.code(), path + ": " + st.message());
    }
    if (model.buffers.empty())
        return plainGlb(path, model, out);
    // Accessors that share a bufferView or sit at an offset in it (as many
    // exporters write them) get views of their own first, so that every
    // vertex attribute and index list can be coded.
    if (!(st = ownViews(model)))
        return Status(st.code(), path + ": " + st.message());
    // Which views to code: vertex attributes with 4-byte-multiple strides and
    // triangle-list indices; each view must serve one kind of accessor only.
    const size_t nv = model.bufferViews.size();
    std::vector<int> kind(nv, 0);  // 0 keep, 1 attributes, 2 triangles, -1 mixed/other use
    std::vector<const char*> plainWhy(nv, nullptr);  // why a view that holds data stays plain (null: coded or exempt)
    std::vector<size_t> count(nv, 0), stride(nv, 0);
    auto mark = [&](int accessor, int as) {
        if (accessor < 0 || size_t(accessor) >= model.accessors.size())
            return;
        const tinygltf::Accessor& a = model.accessors[size_t(accessor)];
        if (a.bufferView < 0 || a.sparse.isSparse)
            return;
        const size_t v = size_t(a.bufferView);
        const tinygltf::BufferView& view = model.bufferViews[v];
        const size_t elem = size_t(tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType)) *
                                   tinygltf::GetNumComponentsInType(uint32_t(a.type)));
        const size_t s = as == 2 ? elem : (view.byteStride ? view.byteStride : elem);
        const bool fits = a.byteOffset == 0 && s > 0 && view.byteLength % s == 0 &&
                          (as == 1 ? s % 4 == 0 && s <= 256 : (s == 2 || s == 4) && a.count % 3 == 0) &&
                          view.byteLength / s == a.count;
        if (!fits || (kind[v] != 0 && kind[v] != as)) {
            kind[v] = -1;
            plainWhy[v] = !fits ? (as == 2 ? "indices of strips or fans, or not whole triangles"
                                           : "interleaved or padded attributes")
                                : "shared by indices and attributes";
        }
        else if (kind[v] == 0) {
            kind[v] = as;
            count[v] = a.count;
            stride[v] = s;
        }
    };
    // Skin and animation data: a view whose accessors all have elements of
    // whole 4-byte words is coded whole as attributes of that size
    // (losslessly: no filter; its accessors keep their offsets in the
    // decoded bytes).  The layer's bytes (zstd already) and images (PNG)
    // stay as they are, and so does a view with any other use.
    std::vector<size_t> dataElem(nv, 0);  // 0 none yet, SIZE_MAX not codable
    forEachAccessorReference(model, [&](int& a, AccessorUse use, const tinygltf::Primitive* p) {
        if (use == AccessorUse::Attribute || use == AccessorUse::MorphTarget) {
            mark(a, 1);
        } else if (use == AccessorUse::Indices) {
            mark(a, p->mode == TINYGLTF_MODE_TRIANGLES || p->mode == -1 ? 2 : -1);
        } else if (a >= 0 && size_t(a) < model.accessors.size() && model.accessors[size_t(a)].bufferView >= 0 &&
                   size_t(model.accessors[size_t(a)].bufferView) < nv) {
            const tinygltf::Accessor& acc = model.accessors[size_t(a)];
            const size_t v = size_t(acc.bufferView);
            const int elem = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType)) *
                             tinygltf::GetNumComponentsInType(uint32_t(acc.type));
            const bool whole = elem > 0 && elem % 4 == 0 && elem <= 256 && !acc.sparse.isSparse &&
                               !model.bufferViews[v].byteStride && acc.byteOffset % size_t(elem) == 0;
            dataElem[v] = !whole || (dataElem[v] != 0 && dataElem[v] != size_t(elem)) ? SIZE_MAX : size_t(elem);
        }
    });
    for (size_t v = 0; v < nv; ++v) {
        if (dataElem[v] == 0)
            continue;
        const size_t length = model.bufferViews[v].byteLength;
        if (kind[v] == 0 && dataElem[v] != SIZE_MAX && length % dataElem[v] == 0 && length > 0) {
            kind[v] = 1;
            stride[v] = dataElem[v];
            count[v] = length / dataElem[v];
        } else {
            plainWhy[v] = kind[v] != 0 ? "shared by vertex data and skin or animation data"
                                       : "skin or animation data of 1- or 2-byte elements, mixed sizes or interleaved";
            kind[v] = -1;
        }
    }
    for (const tinygltf::Image& im : model.images)  // after the data views: an image view is never coded
        if (im.bufferView >= 0 && size_t(im.bufferView) < nv) {
            kind[size_t(im.bufferView)] = -1;
            plainWhy[size_t(im.bufferView)] = nullptr;  // PNG or JPEG: coded already
        }
    for (const tinygltf::Mesh& mesh : model.meshes) {
        const int layer = layerAccessor(mesh);  // zstd frames: coded already
        if (layer >= 0 && size_t(layer) < model.accessors.size() && model.accessors[size_t(layer)].bufferView >= 0 &&
            size_t(model.accessors[size_t(layer)].bufferView) < nv)
            plainWhy[size_t(model.accessors[size_t(layer)].bufferView)] = nullptr;
    }

    // Positions that may be lossy go through the EXPONENTIAL filter: a
    // mantissa shared by each vertex's three coordinates, which the vertex
    // codec then compresses far better than raw floats.
    std::vector<std::vector<unsigned char>> filtered(nv);
    std::vector<int> filterBits(nv, 0);
    if (positionError > 0.0 && std::isfinite(positionError)) {
        std::vector<uint8_t> isPosition(nv, 0);
        for (const tinygltf::Mesh& mesh : model.meshes)
            for (const tinygltf::Primitive& prim : mesh.primitives) {
                const auto it = prim.attributes.find("POSITION");
                if (it == prim.attributes.end() || it->second < 0 || size_t(it->second) >= model.accessors.size())
                    continue;
                const tinygltf::Accessor& a = model.accessors[size_t(it->second)];
                if (a.bufferView >= 0 && a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT &&
                    a.type == TINYGLTF_TYPE_VEC3 && !a.normalized)
                    isPosition[size_t(a.bufferView)] = 1;
            }
        for (size_t v = 0; v < nv; ++v) {
            if (!isPosition[v] || kind[v] != 1 || stride[v] != 12)
                continue;
            std::vector<float> xyz(3 * count[v]);
            std::memcpy(xyz.data(), model.buffers[0].data.data() + model.bufferViews[v].byteOffset, xyz.size() * 4);
            float largest = 0.0f;
            for (float x : xyz)
                largest = std::max(largest, std::fabs(x));
            if (!std::isfinite(largest) || !(largest > 0.0f))
                continue;
            // The shared exponent makes the step 2^-(bits-1) of the vertex's
            // largest coordinate (rounded up to a power of two); the error
            // is half a step.
            const int bits = int(std::ceil(std::log2(2.0 * double(largest) / positionError))) + 1;
            if (bits >= 24)
                continue;
            filterBits[v] = std::max(bits, 2);
            std::vector<unsigned char> coded(xyz.size() * 4);
            meshopt_encodeFilterExp(coded.data(), count[v], 12, filterBits[v], xyz.data());
            // The file holds what decoding gives: store that, and bound it.
            std::vector<unsigned char> decoded = coded;
            meshopt_decodeFilterExp(decoded.data(), count[v], 12);
            std::memcpy(model.buffers[0].data.data() + model.bufferViews[v].byteOffset, decoded.data(), decoded.size());
            std::memcpy(xyz.data(), decoded.data(), decoded.size());
            for (tinygltf::Accessor& a : model.accessors)
                if (a.bufferView == int(v) && !a.minValues.empty()) {
                    a.minValues.assign(3, 1e300);
                    a.maxValues.assign(3, -1e300);
                    for (size_t i = 0; i < xyz.size(); ++i) {
                        a.minValues[i % 3] = std::min(a.minValues[i % 3], double(xyz[i]));
                        a.maxValues[i % 3] = std::max(a.maxValues[i % 3], double(xyz[i]));
                    }
                    jsonFloats(&a.minValues);
                    jsonFloats(&a.maxValues);
                }
            filtered[v] = std::move(coded);
        }
    }

    const std::vector<unsigned char>& data = model.buffers[0].data;
    std::vector<unsigned char> bin;
    struct Coded {
        size_t view, fallbackOffset, offset, length;
    };
    std::vector<Coded> coded;
    size_t fallbackSize = 0;
    meshopt_encodeIndexVersion(1);
    for (size_t v = 0; v < nv; ++v) {
        tinygltf::BufferView& view = model.bufferViews[v];
        const unsigned char* src = data.data() + view.byteOffset;
        if (kind[v] == 1 || kind[v] == 2) {
            std::vector<unsigned char> enc;
            if (kind[v] == 1) {
                enc.resize(meshopt_encodeVertexBufferBound(count[v], stride[v]));
                enc.resize(meshopt_encodeVertexBuffer(enc.data(), enc.size(),
                                                      filterBits[v] ? filtered[v].data() : src, count[v], stride[v]));
            } else {
                std::vector<unsigned int> idx(count[v]);
                for (size_t i = 0; i < count[v]; ++i) {
                    if (stride[v] == 2) {
                        uint16_t x;
                        std::memcpy(&x, src + 2 * i, 2);
                        idx[i] = x;
                    } else {
                        std::memcpy(&idx[i], src + 4 * i, 4);
                    }
                }
                const size_t vertices = idx.empty() ? 0 : size_t(*std::max_element(idx.begin(), idx.end())) + 1;
                enc.resize(meshopt_encodeIndexBufferBound(count[v], vertices));
                enc.resize(meshopt_encodeIndexBuffer(enc.data(), enc.size(), idx.data(), count[v]));
            }
            if (!enc.empty() && enc.size() < view.byteLength) {
                while (bin.size() % 4)
                    bin.push_back(0);
                while (fallbackSize % 4)
                    ++fallbackSize;
                coded.push_back({v, fallbackSize, bin.size(), enc.size()});
                bin.insert(bin.end(), enc.begin(), enc.end());
                fallbackSize += view.byteLength;
                continue;
            }
            plainWhy[v] = "coding would not make it smaller";
        }
        while (bin.size() % 4 != view.byteOffset % 4)
            bin.push_back(0);
        const size_t at = bin.size();
        bin.insert(bin.end(), src, src + view.byteLength);
        view.byteOffset = at;
    }
    if (notes) {
        // One line: what stayed plain, by reason, with its bytes.
        std::map<std::string, std::pair<size_t, size_t>> plain;  // reason -> views, bytes
        for (size_t v = 0; v < nv; ++v)
            if (plainWhy[v]) {
                ++plain[plainWhy[v]].first;
                plain[plainWhy[v]].second += model.bufferViews[v].byteLength;
            }
        std::string line;
        for (const auto& [why, n] : plain)
            line += (line.empty() ? "" : "; ") + std::to_string(n.first) + (n.first == 1 ? " view" : " views") + " (" +
                    std::to_string(n.second) + " B): " + why;
        if (!line.empty())
            notes->push_back("EXT_meshopt_compression left some data plain: " + line);
    }
    if (coded.empty())
        return plainGlb(path, model, out);
    model.buffers[0].data = bin;
    useExtension(model, kMeshoptExtension, true);
    // tinygltf cannot write a buffer without data: serialise, then set the
    // compressed views and the fallback buffer in the JSON.
    tinygltf::TinyGLTF writer;
    std::ostringstream stream;
    if (!writer.WriteGltfSceneToStream(&model, stream, false, true))
        return Status(StatusCode::IoError, path + ": glTF serialisation failed");
    const std::string glb = stream.str();
    std::string jsonText;
    const unsigned char* binPtr = nullptr;
    size_t binSize = 0;
    if (!splitGlb(reinterpret_cast<const unsigned char*>(glb.data()), glb.size(), &jsonText, &binPtr, &binSize))
        return Status(StatusCode::IoError, path + ": glTF serialisation failed");
    Json doc = Json::parse(jsonText);
    Json fallbackBuffer = Json::object();
    fallbackBuffer["byteLength"] = fallbackSize;
    fallbackBuffer["extensions"][kMeshoptExtension]["fallback"] = true;
    doc["buffers"].push_back(fallbackBuffer);
    const size_t fallbackIndex = doc["buffers"].size() - 1;
    for (const Coded& c : coded) {
        Json& view = doc["bufferViews"][c.view];
        const size_t length = view["byteLength"].get<size_t>();
        Json ext = Json::object();
        ext["buffer"] = 0;
        ext["byteOffset"] = c.offset;
        ext["byteLength"] = c.length;
        ext["byteStride"] = stride[c.view];
        ext["count"] = count[c.view];
        ext["mode"] = kind[c.view] == 1 ? "ATTRIBUTES" : "TRIANGLES";
        if (filterBits[c.view])
            ext["filter"] = "EXPONENTIAL";
        view["buffer"] = fallbackIndex;
        view["byteOffset"] = c.fallbackOffset;
        view["byteLength"] = length;
        view["extensions"][kMeshoptExtension] = ext;
    }
    const std::vector<unsigned char> binBytes(binPtr, binPtr + binSize);
    *out = assembleGlb(doc.dump(), binBytes);
    return Status::ok();
}

}  // namespace io
}  // namespace strata
