// The source glTF document: confined loading, and the document-level edits
// the rig and scene writers share (embedding images, dropping what nothing
// references, one buffer for .glb).
#include "gltf_document.h"

#include "strata/io/file.h"
#include "strata/io/rig_io.h"
#include "gltf_mesh_writer.h"

#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <cctype>
#include <cstring>

namespace strata {
namespace io {

namespace {

// ---- Confined file access for external buffers and images ----

struct FsContext {
    std::string base;  // the document's folder ("" for the working directory)
};

// The part of `full` below the document's folder, or "" when it is not a
// plain relative path inside it.
std::string confinedRelative(const std::string& full, const FsContext& ctx)
{
    std::string rel = full;
    if (!ctx.base.empty()) {
        if (full.compare(0, ctx.base.size() + 1, ctx.base + "/") != 0)
            return std::string();
        rel = full.substr(ctx.base.size() + 1);
    }
    if (rel.empty() || rel[0] == '/' || rel.find(':') != std::string::npos || rel.find('\\') != std::string::npos)
        return std::string();
    size_t pos = 0;
    while (pos <= rel.size()) {
        const size_t slash = rel.find('/', pos);
        const std::string part = rel.substr(pos, slash == std::string::npos ? std::string::npos : slash - pos);
        if (part == ".." || part.empty())
            return std::string();
        if (slash == std::string::npos)
            break;
        pos = slash + 1;
    }
    return rel;
}


// Confinement by file, not by spelling: the path with every symbolic link
// resolved must still lie inside the document's folder (resolved too), so a
// buffer, image or sub-folder that links outside it is refused.
bool resolvesInside(const std::string& path, const FsContext& ctx)
{
    return resolvesInsideFolder(path, ctx.base);
}

}  // namespace

bool resolvesInsideFolder(const std::string& path, const std::string& folder)
{
    std::error_code ec;
    const std::filesystem::path file = std::filesystem::canonical(path, ec);
    if (ec)
        return false;
    const std::filesystem::path base = std::filesystem::canonical(folder.empty() ? "." : folder, ec);
    if (ec)
        return false;
    const std::string f = file.string(), b = base.string();
    return f.size() > b.size() && f.compare(0, b.size(), b) == 0 && (b.back() == '/' || f[b.size()] == '/');
}

namespace {

bool fsExists(const std::string& path, void* user)
{
    const FsContext& ctx = *static_cast<FsContext*>(user);
    return !confinedRelative(path, ctx).empty() && isRegularFile(path);  // fsRead says why a link is refused
}

std::string fsExpand(const std::string& path, void*)
{
    return path;  // no ~ or $VAR expansion
}

bool fsRead(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user)
{
    const FsContext& ctx = *static_cast<FsContext*>(user);
    if (confinedRelative(path, ctx).empty() || !isRegularFile(path)) {
        if (err)
            *err += "external files must be regular files inside the rig's folder";
        return false;
    }
    if (!resolvesInside(path, ctx)) {
        if (err)
            *err += "leads outside the rig's folder through a symbolic link (external files must resolve inside it)";
        return false;
    }
    const Status st = readFile(path, out, size_t(1) << 30);
    if (!st && err)
        *err += st.message();
    return bool(st);
}

bool fsWrite(std::string*, const std::string&, const std::vector<unsigned char>&, void*)
{
    return false;  // loading never writes
}

// Keeps an image's encoded bytes instead of decoding it (the runtime never
// needs texture pixels; the writer embeds them again).
bool keepImageBytes(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                    const unsigned char* bytes, int size, void* user)
{
    auto* doc = static_cast<SourceDocument*>(user);
    if (index < 0 || size < 0)
        return true;
    if (doc->imageBytes.size() <= size_t(index))
        doc->imageBytes.resize(size_t(index) + 1);
    if (image->bufferView < 0)
        doc->imageBytes[size_t(index)].assign(bytes, bytes + size);
    return true;
}

}  // namespace




Status overBudget(const std::string& what, double needBytes, size_t maxBytes)
{
    const double mb = 1024.0 * 1024.0;
    return Status(StatusCode::InvalidArgument, what + " needs about " + std::to_string(long(std::ceil(needBytes / mb))) +
                                                   " MB, over the " + std::to_string(long(double(maxBytes) / mb)) +
                                                   " MB budget (raise it with --max-memory MB)");
}

Status loadGltfDocument(const std::string& path, SourceDocument* doc, size_t maxBytes)
{
    const std::string ext = extensionOf(path);
    if (ext != ".glb" && ext != ".gltf")
        return Status(StatusCode::InvalidArgument, path + ": not a .glb or .gltf file");
    std::vector<unsigned char> bytes;
    // The file, a decoded copy and tinygltf's buffers: three times its size.
    std::error_code ec;
    const uintmax_t fileSize = std::filesystem::file_size(path, ec);
    if (!ec && 3.0 * double(fileSize) > double(maxBytes))
        return overBudget(path + ": loading its " + std::to_string(fileSize) + " bytes", 3.0 * double(fileSize), maxBytes);
    Status st = readFile(path, &bytes);
    if (!st)
        return st;
    return parseGltfDocument(bytes.data(), bytes.size(), ext == ".glb", directoryOf(path), path, doc, maxBytes);
}

namespace {

// The bytes [offset, offset + length) of bufferView `index`, or nullptr.
const unsigned char* viewRange(const tinygltf::Model& model, int index, size_t offset, size_t length)
{
    if (index < 0 || size_t(index) >= model.bufferViews.size())
        return nullptr;
    const tinygltf::BufferView& view = model.bufferViews[size_t(index)];
    if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
        return nullptr;
    const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
    if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset ||
        offset > view.byteLength || length > view.byteLength - offset)
        return nullptr;
    return data.data() + view.byteOffset + offset;
}

}  // namespace

// glTF allows an accessor without a bufferView (all zeros) and sparse
// accessors (a base, or zeros, with some elements replaced).  Both are made
// plain here, once, so that every reader and writer downstream sees tightly
// packed data.  What they add is bounded by the file's own size: zeros cost
// no bytes in a file, so a few bytes could otherwise declare gigabytes.
Status densifyAccessors(tinygltf::Model& model, size_t fileBytes, const std::string& path, size_t maxBytes)
{
    const double budget = 16.0 * double(fileBytes) + double(64u << 20);
    double needed = 0.0;
    for (const tinygltf::Accessor& acc : model.accessors)
        if (acc.bufferView < 0 || acc.sparse.isSparse)
            needed += double(acc.count) * double(std::max(0, tinygltf::GetNumComponentsInType(uint32_t(acc.type)))) *
                      double(std::max(0, tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType))));
    if (needed <= budget && double(fileBytes) + 2.0 * needed > double(maxBytes))
        return overBudget(path + ": its sparse and bufferView-less accessors", double(fileBytes) + 2.0 * needed, maxBytes);
    double added = 0.0;
    for (size_t a = 0; a < model.accessors.size(); ++a) {
        tinygltf::Accessor& acc = model.accessors[a];
        if (acc.bufferView >= 0 && !acc.sparse.isSparse)
            continue;
        const std::string what = path + ": accessor " + std::to_string(a);
        const int ncomp = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
        const int cbytes = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
        if (ncomp <= 0 || cbytes <= 0)
            return Status(StatusCode::InvalidData, what + " has an unknown type or component type");
        const size_t element = size_t(ncomp) * size_t(cbytes);
        added += double(acc.count) * double(element);
        if (added > budget)
            return Status(StatusCode::InvalidData, what + " declares " + std::to_string(acc.count) +
                                                       " elements without the bytes to back them (sparse or no "
                                                       "bufferView), far more than the file's size justifies");
        std::vector<unsigned char> dense(acc.count * element, 0);
        if (acc.bufferView >= 0) {
            if (size_t(acc.bufferView) >= model.bufferViews.size())
                return Status(StatusCode::InvalidData, what + " names a bufferView the file does not have");
            const size_t stride = model.bufferViews[size_t(acc.bufferView)].byteStride;
            const size_t s = stride ? stride : element;
            const size_t span = acc.count ? s * (acc.count - 1) + element : 0;
            const unsigned char* base = s >= element ? viewRange(model, acc.bufferView, acc.byteOffset, span) : nullptr;
            if (!base)
                return Status(StatusCode::InvalidData, what + " reads past the end of its bufferView");
            for (size_t i = 0; i < acc.count; ++i)
                std::memcpy(&dense[i * element], base + i * s, element);
        }
        if (acc.sparse.isSparse) {
            const size_t n = size_t(std::max(0, acc.sparse.count));
            const int icomp = acc.sparse.indices.componentType;
            const int ibytes = icomp == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                               : icomp == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                               : icomp == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                 : 0;
            if (n == 0 || n > acc.count || ibytes == 0)
                return Status(StatusCode::InvalidData, what + " has a sparse part of " + std::to_string(n) +
                                                           " elements (1 to its count, indices of unsigned integers)");
            const unsigned char* indices =
                viewRange(model, acc.sparse.indices.bufferView, size_t(acc.sparse.indices.byteOffset), n * size_t(ibytes));
            const unsigned char* values =
                viewRange(model, acc.sparse.values.bufferView, size_t(acc.sparse.values.byteOffset), n * element);
            if (!indices || !values)
                return Status(StatusCode::InvalidData, what + ": its sparse indices or values read past their bufferView");
            uint64_t previous = 0;
            for (size_t k = 0; k < n; ++k) {
                uint32_t i = 0;
                if (ibytes == 1) {
                    i = indices[k];
                } else if (ibytes == 2) {
                    uint16_t u;
                    std::memcpy(&u, indices + 2 * k, 2);
                    i = u;
                } else {
                    std::memcpy(&i, indices + 4 * k, 4);
                }
                if (i >= acc.count || (k > 0 && uint64_t(i) <= previous))
                    return Status(StatusCode::InvalidData, what + ": sparse index " + std::to_string(i) + " at " +
                                                               std::to_string(k) +
                                                               " is out of range or not increasing");
                previous = i;
                std::memcpy(&dense[size_t(i) * element], values + k * element, element);
            }
        }
        const int view = appendBufferView(model, dense.data(), dense.size(), -1);
        model.bufferViews[size_t(view)].target = 0;
        acc.bufferView = view;
        acc.byteOffset = 0;
        acc.sparse.isSparse = false;
        acc.sparse.count = 0;
        acc.sparse.indices.bufferView = acc.sparse.values.bufferView = -1;
        acc.sparse.indices.byteOffset = acc.sparse.values.byteOffset = 0;
    }
    return Status::ok();
}

namespace {

// "an accessor", "a bufferView": glTF's names for tinygltf's type names.
std::string withArticle(std::string type)
{
    if (type.empty())
        return "an object";
    type[0] = char(std::tolower(static_cast<unsigned char>(type[0])));
    return (std::string("aeio").find(type[0]) != std::string::npos ? "an " : "a ") + type;
}

// tinygltf's first error in Strata's words: what is wrong with the file,
// without the parser's internals ("[json.exception.parse_error.101]").
std::string plainGltfError(const std::string& err)
{
    std::string line = err.substr(0, err.find('\n'));
    while (!line.empty() && (line.back() == '.' || line.back() == ' ' || line.back() == '\r'))
        line.pop_back();
    if (line.empty())
        return "not a valid glTF file";
    if (line.find("glTF Binary") != std::string::npos || line.find("Invalid magic") != std::string::npos ||
        line.find("Invalid glTF binary") != std::string::npos || line.find("Invalid binary glTF") != std::string::npos)
        return "not a complete .glb file (truncated, or not glTF at all)";
    if (line.find("json.exception") != std::string::npos)
        return plainJsonError(line);
    // Plain string matching (no std::regex: see plainJsonError).
    auto startsWith = [&](const char* prefix) { return line.rfind(prefix, 0) == 0; };
    if (startsWith("File not found : "))
        return "the external file \"" + line.substr(17) + "\" it refers to is missing";
    if (startsWith("File read error : ")) {
        const std::string rest = line.substr(18);
        const size_t colon = rest.find(':');
        std::string reason = colon == std::string::npos ? std::string() : rest.substr(colon + 1);
        while (!reason.empty() && reason[0] == ' ')
            reason.erase(0, 1);
        return "cannot read the external file \"" + rest.substr(0, colon) + "\" it refers to" +
               (reason.empty() ? std::string() : " (" + reason + ")");
    }
    if (startsWith("'")) {
        const size_t quote = line.find('\'', 1);
        const std::string name = quote == std::string::npos ? std::string() : line.substr(1, quote - 1);
        const std::string missing = "' property is missing in ", is = "' property is not";
        if (!name.empty() && line.compare(quote, missing.size(), missing) == 0) {
            std::string type = line.substr(quote + missing.size());
            type = type.substr(0, type.find_first_not_of(
                                      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_"));
            return withArticle(type) + " has no \"" + name + "\", which glTF requires";
        }
        if (!name.empty() && line.compare(quote, is.size(), is) == 0)
            return "property \"" + name + "\" is " + line.substr(quote + is.size() - 3);
    }
    if (startsWith("Failed to decode 'uri' : data:")) {
        const size_t in = line.rfind(" in ");
        if (in != std::string::npos)
            return withArticle(line.substr(in + 4)) + "'s data: URI is not valid base64";
    }
    if (!line.empty())
        line[0] = char(std::tolower(static_cast<unsigned char>(line[0])));
    return line;
}

}  // namespace

Status parseGltfDocument(const unsigned char* data, size_t size, bool binary, const std::string& folder,
                         const std::string& path, SourceDocument* doc, size_t maxBytes)
{
    if (size == 0)
        return Status(StatusCode::InvalidData, path + ": file is empty");
    if (size > 0xffffffffu)
        return Status(StatusCode::InvalidData, path + ": file is larger than 4 GiB");
    const std::string ext = binary ? ".glb" : ".gltf";
    // EXT_meshopt_compression and KHR_draco_mesh_compression are decoded
    // first: tinygltf knows neither.
    std::string plain;
    if (!binary && std::string(reinterpret_cast<const char*>(data), size).find(kDracoExtension) !=
                       std::string::npos)
        return Status(StatusCode::Unsupported, path + ": Draco-compressed meshes are read from .glb only; "
                                                   "convert with gltf-transform or gltfpack first");
    if (binary) {
        Status st = decodeCompressedGlb(data, size, path, &plain);
        if (!st)
            return st;
        if (2.0 * double(plain.size()) + double(size) > double(maxBytes))
            return overBudget(path + ": its decoded buffers", 2.0 * double(plain.size()) + double(size), maxBytes);
        if (!plain.empty()) {
            data = reinterpret_cast<const unsigned char*>(plain.data());
            size = plain.size();
        }
    }
    FsContext ctx{folder};
    tinygltf::TinyGLTF loader;
    loader.SetFsCallbacks(tinygltf::FsCallbacks{fsExists, fsExpand, fsRead, fsWrite, &ctx});
    loader.SetImageLoader(keepImageBytes, doc);
    std::string err, warn;
    bool ok;
    if (ext == ".glb") {
        ok = loader.LoadBinaryFromMemory(&doc->model, &err, &warn, data, unsigned(size), ctx.base);
    } else {
        ok = loader.LoadASCIIFromString(&doc->model, &err, &warn, reinterpret_cast<const char*>(data), unsigned(size),
                                        ctx.base);
    }
    if (!ok)
        return Status(StatusCode::InvalidData, path + ": " + printable(plainGltfError(err)));
    doc->imageBytes.resize(doc->model.images.size());
    if (Status st = densifyAccessors(doc->model, size, path, maxBytes); !st)
        return st;
    for (const std::string& e : doc->model.extensionsRequired)
        if (e == kMeshoptExtension)  // only .gltf gets here
            return Status(StatusCode::Unsupported, path + ": meshopt-compressed meshes are read from .glb only; "
                                                       "decompress with gltfpack -noq or gltf-transform first");

    return Status::ok();
}



// Removes image `index`, renumbering texture sources, their extensions'
// too (textures that used it lose their source).
void removeImage(tinygltf::Model& model, std::vector<std::vector<unsigned char>>* bytes, int index)
{
    model.images.erase(model.images.begin() + index);
    if (bytes && size_t(index) < bytes->size())
        bytes->erase(bytes->begin() + index);
    // An image an extension names (EXT_texture_webp, KHR_texture_basisu,
    // EXT_texture_avif: {"source": n}) renumbered alike.
    const auto renumber = [index](int source) { return source == index ? -1 : source > index ? source - 1 : source; };
    for (tinygltf::Texture& t : model.textures) {
        t.source = renumber(t.source);
        for (auto& [name, value] : t.extensions) {
            if (!value.IsObject() || !value.Get("source").IsInt())
                continue;
            tinygltf::Value::Object o = value.Get<tinygltf::Value::Object>();
            const int source = renumber(value.Get("source").Get<int>());
            if (source < 0)
                o.erase("source");
            else
                o["source"] = tinygltf::Value(source);
            value = tinygltf::Value(std::move(o));
        }
    }
}

std::string sniffMime(const std::vector<unsigned char>& b)
{
    if (b.size() >= 8 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G')
        return "image/png";
    if (b.size() >= 3 && b[0] == 0xff && b[1] == 0xd8 && b[2] == 0xff)
        return "image/jpeg";
    if (b.size() >= 12 && std::memcmp(b.data(), "RIFF", 4) == 0 && std::memcmp(b.data() + 8, "WEBP", 4) == 0)
        return "image/webp";
    if (b.size() >= 4 && std::memcmp(b.data(), "\xabKTX", 4) == 0)
        return "image/ktx2";
    // AVIF: an ISO-BMFF file whose ftyp box names the avif (still) or avis
    // (sequence) brand, major or among its compatible ones.
    if (b.size() >= 16 && std::memcmp(b.data() + 4, "ftyp", 4) == 0) {
        const size_t box = std::min(b.size(), (size_t(b[0]) << 24 | size_t(b[1]) << 16 | size_t(b[2]) << 8 | b[3]));
        for (size_t at = 8; at + 4 <= box; at += at == 8 ? 8 : 4)
            if (std::memcmp(b.data() + at, "avif", 4) == 0 || std::memcmp(b.data() + at, "avis", 4) == 0)
                return "image/avif";
    }
    return std::string();
}



Status embedImages(tinygltf::Model& model, std::vector<std::vector<unsigned char>>& imageBytes,
                   std::vector<std::string>* notes)
{
    imageBytes.resize(model.images.size());
    for (size_t i = 0; i < model.images.size(); ++i) {
        tinygltf::Image& im = model.images[i];
        if (im.bufferView >= 0)
            continue;
        if (imageBytes[i].empty()) {
            if (notes)
                notes->push_back("image " + std::to_string(i) + " (" + printable(im.uri, 60) +
                                 ") could not be read, so the file still refers to it by URI");
            continue;
        }
        const int view = appendBufferView(model, imageBytes[i].data(), imageBytes[i].size(), -1);
        model.bufferViews[size_t(view)].target = 0;
        if (im.mimeType.empty())
            im.mimeType = sniffMime(imageBytes[i]);
        im.bufferView = view;
        im.uri.clear();
    }
    return Status::ok();
}

// Copies accessor `index` element by element in the order of `src` (source
// vertex per new vertex) into a new tightly packed, 4-byte aligned accessor.
Status gatherAccessor(tinygltf::Model& model, int index, const std::vector<uint32_t>& src, const std::string& what,
                      int* out)
{
    if (index < 0 || size_t(index) >= model.accessors.size())
        return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " does not exist");
    const tinygltf::Accessor acc = model.accessors[size_t(index)];
    if (acc.sparse.isSparse)
        return Status(StatusCode::Unsupported, what + ": sparse vertex attributes cannot be re-indexed yet");
    const int cbytes = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
    const int comps = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
    if (cbytes <= 0 || comps <= 0)
        return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " has an unknown type");
    const size_t elem = size_t(cbytes) * size_t(comps);
    const size_t packed = (elem + 3) & ~size_t(3);
    std::vector<unsigned char> bytes(packed * src.size(), 0);
    if (acc.bufferView >= 0) {
        if (size_t(acc.bufferView) >= model.bufferViews.size())
            return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " has no valid bufferView");
        const tinygltf::BufferView& view = model.bufferViews[size_t(acc.bufferView)];
        if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
            return Status(StatusCode::InvalidData, what + ": a bufferView references a missing buffer");
        const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
        const size_t stride = view.byteStride ? size_t(view.byteStride) : elem;
        for (size_t i = 0; i < src.size(); ++i) {
            if (src[i] >= acc.count)
                return Status(StatusCode::InvalidData, what + ": vertex " + std::to_string(src[i]) + " is beyond accessor " +
                                                           std::to_string(index));
            const size_t at = view.byteOffset + acc.byteOffset + size_t(src[i]) * stride;
            if (at > data.size() || elem > data.size() - at || at + elem > view.byteOffset + view.byteLength)
                return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) +
                                                           " reads past the end of its bufferView");
            std::memcpy(&bytes[i * packed], &data[at], elem);
        }
    }
    const int viewIndex = appendBufferView(model, bytes.data(), bytes.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
    if (packed != elem)
        model.bufferViews[size_t(viewIndex)].byteStride = packed;
    *out = appendAccessor(model, viewIndex, acc.componentType, acc.type, src.size());
    tinygltf::Accessor& copy = model.accessors[size_t(*out)];
    copy.normalized = acc.normalized;
    copy.minValues = acc.minValues;  // every source vertex is kept, so the bounds hold
    copy.maxValues = acc.maxValues;
    copy.name = acc.name;
    return Status::ok();
}


void useExtension(tinygltf::Model& model, const std::string& name, bool required)
{
    for (std::vector<std::string>* list : {&model.extensionsUsed, &model.extensionsRequired})
        if ((list == &model.extensionsUsed || required) && std::find(list->begin(), list->end(), name) == list->end())
            list->push_back(name);
}

// Extensions known not to reference accessors or bufferViews: with only
// these in use, unreferenced accessors and views can be dropped safely.
bool onlyKnownExtensions(const tinygltf::Model& model)
{
    for (const std::string& e : model.extensionsUsed)
        if (e.rfind("KHR_materials_", 0) != 0 && e != "KHR_texture_transform" && e != "KHR_lights_punctual" &&
            e != "KHR_mesh_quantization" && e != "KHR_texture_basisu" && e != "EXT_texture_webp" &&
            e != kDracoExtension && e != kLayerExtension)
            return false;
    return true;
}

// Drops accessors and bufferViews nothing references (when that is known to
// be safe) and merges every buffer into buffer 0, as a .glb needs.
void forEachAccessorReference(tinygltf::Model& model,
                              const std::function<void(int&, AccessorUse, const tinygltf::Primitive*)>& visit)
{
    for (tinygltf::Mesh& m : model.meshes)
        for (tinygltf::Primitive& p : m.primitives) {
            for (auto& [name, a] : p.attributes)
                visit(a, AccessorUse::Attribute, &p);
            visit(p.indices, AccessorUse::Indices, &p);
            for (auto& target : p.targets)
                for (auto& [name, a] : target)
                    visit(a, AccessorUse::MorphTarget, &p);
        }
    for (tinygltf::Mesh& m : model.meshes) {
        const int layer = layerAccessor(m);
        if (layer >= 0) {
            int a = layer;
            visit(a, AccessorUse::Other, nullptr);
            if (a != layer)
                setLayerAccessor(&m, a);
        }
    }
    for (tinygltf::Skin& sk : model.skins)
        visit(sk.inverseBindMatrices, AccessorUse::Other, nullptr);
    for (tinygltf::Animation& an : model.animations)
        for (tinygltf::AnimationSampler& sa : an.samplers) {
            visit(sa.input, AccessorUse::Other, nullptr);
            visit(sa.output, AccessorUse::Other, nullptr);
        }
}

int layerAccessor(const tinygltf::Mesh& mesh)
{
    auto it = mesh.extensions.find(kLayerExtension);
    if (it == mesh.extensions.end() || !it->second.IsObject() || !it->second.Has("displacementVertices"))
        return -1;
    const tinygltf::Value& vertices = it->second.Get("displacementVertices");
    if (!vertices.IsObject() || !vertices.Has("accessor") || !vertices.Get("accessor").IsNumber())
        return -1;
    const double a = vertices.Get("accessor").GetNumberAsDouble();
    return a >= 0 && a < 2147483647.0 ? int(a) : -1;
}

void setLayerAccessor(tinygltf::Mesh* mesh, int accessor)
{
    tinygltf::Value::Object block = mesh->extensions[kLayerExtension].Get<tinygltf::Value::Object>();
    tinygltf::Value::Object vertices = block["displacementVertices"].Get<tinygltf::Value::Object>();
    vertices["accessor"] = tinygltf::Value(accessor);
    block["displacementVertices"] = tinygltf::Value(vertices);
    mesh->extensions[kLayerExtension] = tinygltf::Value(block);
}

int dropLayers(tinygltf::Model& model)
{
    int mapImage = -1;
    auto imageOf = [&](const tinygltf::Value& block) {
        if (!block.IsObject() || !block.Has("displacementGeometryTexture"))
            return;
        const tinygltf::Value& tex = block.Get("displacementGeometryTexture");
        if (tex.IsObject() && tex.Has("image") && tex.Get("image").IsNumber()) {
            const double i = tex.Get("image").GetNumberAsDouble();
            if (i >= 0 && i < double(model.images.size()))
                mapImage = int(i);
        }
    };
    for (tinygltf::Mesh& m : model.meshes) {
        auto it = m.extensions.find(kLayerExtension);
        if (it != m.extensions.end()) {
            imageOf(it->second);
            m.extensions.erase(it);
        }
        if (m.extras.IsObject() && m.extras.Has("strata")) {
            imageOf(m.extras.Get("strata"));
            tinygltf::Value::Object obj = m.extras.Get<tinygltf::Value::Object>();
            obj.erase("strata");
            m.extras = obj.empty() ? tinygltf::Value() : tinygltf::Value(obj);
        }
    }
    for (std::vector<std::string>* list : {&model.extensionsUsed, &model.extensionsRequired})
        list->erase(std::remove(list->begin(), list->end(), std::string(kLayerExtension)), list->end());
    return mapImage;
}

int strataVertexView(const tinygltf::Value& extras)
{
    if (!extras.IsObject() || !extras.Has("strata"))
        return -1;
    const tinygltf::Value& block = extras.Get("strata");
    if (!block.IsObject() || !block.Has("displacementVertices"))
        return -1;
    const tinygltf::Value& vertices = block.Get("displacementVertices");
    if (!vertices.IsObject() || !vertices.Has("bufferView") || !vertices.Get("bufferView").IsNumber())
        return -1;
    const double v = vertices.Get("bufferView").GetNumberAsDouble();
    return v >= 0 && v < 2147483647.0 ? int(v) : -1;
}

void setStrataVertexView(tinygltf::Value* extras, int view)
{
    tinygltf::Value::Object top = extras->Get<tinygltf::Value::Object>();
    tinygltf::Value::Object block = top["strata"].Get<tinygltf::Value::Object>();
    tinygltf::Value::Object vertices = block["displacementVertices"].Get<tinygltf::Value::Object>();
    vertices["bufferView"] = tinygltf::Value(view);
    block["displacementVertices"] = tinygltf::Value(vertices);
    top["strata"] = tinygltf::Value(block);
    *extras = tinygltf::Value(top);
}

Status packBuffers(tinygltf::Model& model)
{
    const size_t na = model.accessors.size();
    const bool collect = onlyKnownExtensions(model);
    std::vector<int> accessorMap(na, collect ? -1 : 0);
    if (collect)
        forEachAccessorReference(model, [&](int& a, AccessorUse, const tinygltf::Primitive*) {
            if (a >= 0 && size_t(a) < na)
                accessorMap[size_t(a)] = 0;
        });
    std::vector<tinygltf::Accessor> accessors;
    for (size_t a = 0; a < na; ++a)
        if (accessorMap[a] == 0) {
            accessorMap[a] = int(accessors.size());
            accessors.push_back(model.accessors[a]);
        }
    forEachAccessorReference(model, [&](int& a, AccessorUse, const tinygltf::Primitive*) {
        if (a >= 0 && size_t(a) < na)
            a = accessorMap[size_t(a)];
    });
    model.accessors = std::move(accessors);

    const size_t nv = model.bufferViews.size();
    std::vector<int> viewMap(nv, collect ? -1 : 0);
    auto useView = [&](int v) {
        if (v >= 0 && size_t(v) < nv)
            viewMap[size_t(v)] = 0;
    };
    for (const tinygltf::Accessor& a : model.accessors) {
        useView(a.bufferView);
        if (a.sparse.isSparse) {
            useView(a.sparse.indices.bufferView);
            useView(a.sparse.values.bufferView);
        }
    }
    for (const tinygltf::Image& im : model.images)
        useView(im.bufferView);
    for (tinygltf::Mesh& m : model.meshes) {
        useView(strataVertexView(m.extras));
        for (const tinygltf::Primitive& p : m.primitives)
            useView(dracoView(p));
    }
    std::vector<unsigned char> merged;
    std::vector<tinygltf::BufferView> views;
    for (size_t v = 0; v < nv; ++v) {
        if (viewMap[v] != 0)
            continue;
        tinygltf::BufferView view = model.bufferViews[v];
        if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
            return Status(StatusCode::InvalidData, "bufferView " + std::to_string(v) + " references a missing buffer");
        const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
        if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
            return Status(StatusCode::InvalidData, "bufferView " + std::to_string(v) + " extends past its buffer");
        while (merged.size() % 4 != view.byteOffset % 4)  // keeps every accessor's alignment
            merged.push_back(0);
        const size_t at = merged.size();
        merged.insert(merged.end(), data.begin() + long(view.byteOffset),
                      data.begin() + long(view.byteOffset + view.byteLength));
        view.buffer = 0;
        view.byteOffset = at;
        viewMap[v] = int(views.size());
        views.push_back(view);
    }
    while (merged.size() % 4)
        merged.push_back(0);
    for (tinygltf::Accessor& a : model.accessors) {
        if (a.bufferView >= 0 && size_t(a.bufferView) < nv)
            a.bufferView = viewMap[size_t(a.bufferView)];
        if (a.sparse.isSparse) {
            a.sparse.indices.bufferView = viewMap[size_t(a.sparse.indices.bufferView)];
            a.sparse.values.bufferView = viewMap[size_t(a.sparse.values.bufferView)];
        }
    }
    for (tinygltf::Image& im : model.images)
        if (im.bufferView >= 0 && size_t(im.bufferView) < nv)
            im.bufferView = viewMap[size_t(im.bufferView)];
    for (tinygltf::Mesh& m : model.meshes) {
        const int v = strataVertexView(m.extras);
        if (v >= 0 && size_t(v) < nv)
            setStrataVertexView(&m.extras, viewMap[size_t(v)]);
        for (tinygltf::Primitive& p : m.primitives) {
            const int d = dracoView(p);
            if (d >= 0 && size_t(d) < nv)
                setDracoView(&p, viewMap[size_t(d)]);
        }
    }
    model.bufferViews = std::move(views);
    model.buffers.clear();
    if (!merged.empty()) {
        tinygltf::Buffer buffer;
        buffer.data = std::move(merged);
        model.buffers.push_back(std::move(buffer));
    }
    return Status::ok();
}


// A skinned mesh ignores its parents' transforms, so a childless skinned
// mesh node under another node draws the same as a root: move it there (the
// glTF-Validator warns about the other form, NODE_SKINNED_MESH_NON_ROOT).
void rootSkinnedMeshNodes(tinygltf::Model& model, std::vector<std::string>* notes)
{
    const size_t n = model.nodes.size();
    std::vector<int> parent(n, -1);
    for (size_t i = 0; i < n; ++i)
        for (int c : model.nodes[i].children)
            if (c >= 0 && size_t(c) < n)
                parent[size_t(c)] = int(i);
    for (size_t i = 0; i < n; ++i) {
        const tinygltf::Node& node = model.nodes[i];
        if (node.mesh < 0 || node.skin < 0 || parent[i] < 0 || !node.children.empty())
            continue;
        int root = parent[i];
        for (size_t guard = 0; parent[size_t(root)] >= 0 && guard < n; ++guard)
            root = parent[size_t(root)];
        std::vector<int>& siblings = model.nodes[size_t(parent[i])].children;
        siblings.erase(std::remove(siblings.begin(), siblings.end(), int(i)), siblings.end());
        for (tinygltf::Scene& scene : model.scenes)
            if (std::find(scene.nodes.begin(), scene.nodes.end(), root) != scene.nodes.end())
                scene.nodes.push_back(int(i));
        if (notes)
            notes->push_back("skinned mesh node " + std::to_string(i) + " (" + printable(node.name, 60) +
                             ") moved to the scene root, where glTF expects it (it draws the same)");
    }
}


Status prepareForWriting(const std::string& path, tinygltf::Model& model, bool surface)
{
    Status st = packBuffers(model);
    if (!st)
        return Status(st.code(), path + ": " + st.message());
    model.asset.version = "2.0";
    model.asset.generator = surface ? STRATA_SURFACE_GENERATOR : STRATA_RIG_GENERATOR;
    return Status::ok();
}

Status packAndWrite(const std::string& path, tinygltf::Model& model, bool surface)
{
    Status st = prepareForWriting(path, model, surface);
    return st ? writeGltfModel(path, model) : st;
}

}  // namespace io
}  // namespace strata
