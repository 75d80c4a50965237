// Reading glTF 2.0 control rigs (docs/FORMAT.md), hostile input assumed:
// the displacement layer (STRATA_layered_displacement, or the extras block of
// format versions 1-4) and its binding to the control mesh, the load entry
// points, and the map a rig carries.  The scene's geometry is welded in
// rig_scene.cpp, its skeleton read in rig_skeleton.cpp; rig_write.cpp writes.
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

// A surface or scene Strata reconstructed (or another mesh it wrote): never
// a rig, so it has no layer to lose.
bool strataSurface(const tinygltf::Model& model)
{
    const std::string& g = model.asset.generator;
    const size_t n = std::char_traits<char>::length(kSurfaceGeneratorSuffix);
    return writtenByStrata(model) && g.size() >= n && g.compare(g.size() - n, n, kSurfaceGeneratorSuffix) == 0;
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
    if (const tinygltf::Value* shading = member(block, "shading")) {
        const std::string how = shading->IsString() ? shading->Get<std::string>() : std::string("?");
        if (how != "flat" && how != "smooth")
            return Status(StatusCode::InvalidData, path + ": shading \"" + printable(how, 40) +
                                                       "\" is not one of \"flat\" and \"smooth\"");
        info->flatShading = how == "flat";
    }
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


uint64_t uvHash(const std::vector<glm::vec2>& uvs)
{
    return fnvBytes(kFnvOffset, uvs.data(), uvs.size() * sizeof(glm::vec2));
}

}  // namespace rigfile

using namespace rigfile;

Status loadGltfTriangles(const std::filesystem::path& pathFile, std::vector<glm::vec3>* positions, std::vector<uint32_t>* triangles,
                         const LoadOptions& options, bool* flat)
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
    if (flat)
        *flat = allPartsFlat(scene.rig);
    return Status::ok();
}

namespace rigfile {


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

}  // namespace rigfile

CharacterBytes characterBytesOf(const Rig& rig)
{
    CharacterBytes out;
    if (!rig.source)
        return out;
    const tinygltf::Model& model = rig.source->model;
    std::vector<uint8_t> counted(model.accessors.size(), 0);  // an accessor two samplers share, once
    auto accessorBytes = [&](int a) {
        if (a < 0 || size_t(a) >= model.accessors.size() || counted[size_t(a)])
            return size_t(0);
        counted[size_t(a)] = 1;
        const tinygltf::Accessor& acc = model.accessors[size_t(a)];
        const int c = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
        const int n = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
        return c > 0 && n > 0 ? acc.count * size_t(c) * size_t(n) : size_t(0);
    };
    for (const tinygltf::Animation& an : model.animations)
        for (const tinygltf::AnimationSampler& sa : an.samplers)
            out.animations += accessorBytes(sa.input) + accessorBytes(sa.output);
    for (const tinygltf::Skin& sk : model.skins)
        out.skins += accessorBytes(sk.inverseBindMatrices);
    for (size_t i = 0; i < model.images.size(); ++i) {
        if (int(i) == rig.displacement.image && rig.hasDisplacement)
            continue;
        const int v = model.images[i].bufferView;
        if (v >= 0 && size_t(v) < model.bufferViews.size())
            out.images += model.bufferViews[size_t(v)].byteLength;
        else if (i < rig.source->imageBytes.size())
            out.images += rig.source->imageBytes[i].size();
    }
    return out;
}

size_t characterBytes(const Rig& rig)
{
    const CharacterBytes b = characterBytesOf(rig);
    return b.images + b.animations + b.skins;
}

std::string missingLayerCause(const Rig& rig)
{
    if (!rig.source)
        return "it is a plain mesh file, not a baked rig";
    const tinygltf::Model& model = rig.source->model;
    if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), kLayerExtension) !=
        model.extensionsUsed.end())
        return std::string("it declares ") + kLayerExtension + " but no mesh carries the layer: a tool dropped it";
    if (strataSurface(model))
        return "it is a displaced surface Strata reconstructed, its detail already in its triangles, not a rig";
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

Status checkEachMeshPlacedOnce(const std::string& path, const Rig& rig)
{
    if (!rig.source)
        return Status::ok();
    const tinygltf::Model& model = rig.source->model;
    std::map<std::pair<int, int>, int> placed;  // (mesh, primitive) -> the node that placed it first
    for (const RigPart& part : rig.parts) {
        const auto it = placed.emplace(std::make_pair(part.mesh, part.primitive), part.node);
        if (it.second || part.node < 0 || it.first->second < 0)
            continue;
        auto nodeName = [&](int node) {
            return std::to_string(node) + " (" + printable(model.nodes[size_t(node)].name, 60) + ")";
        };
        if (part.node == it.first->second)
            return Status(StatusCode::Unsupported,
                          path + ": mesh " + std::to_string(part.mesh) + " (" +
                              printable(model.meshes[size_t(part.mesh)].name, 60) + ") is placed many times by node " +
                              nodeName(part.node) +
                              " through EXT_mesh_gpu_instancing, and a rig written as this file needs UVs of its own "
                              "at each place: give each instance a node and a copy of the mesh of its own");
        return Status(StatusCode::Unsupported,
                      path + ": mesh " + std::to_string(part.mesh) + " (" +
                          printable(model.meshes[size_t(part.mesh)].name, 60) + ") is placed by nodes " +
                          nodeName(it.first->second) + " and " + nodeName(part.node) +
                          ", and a rig written as this file needs UVs of its own at each place: give each node its "
                          "own copy of the mesh");
    }
    return Status::ok();
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

namespace rigfile {

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

// The coded per-vertex values, copied into *out: a bufferView (versions 3
// and 4) or an accessor of unsigned bytes (version 5), strided where a
// meshopt-coded view padded each value to 4 bytes.
Status layerVertexBytes(const tinygltf::Model& model, const DisplacementInfo& info, const std::string& path,
                        std::vector<unsigned char>* out)
{
    if (info.vertexAccessor < 0) {
        const unsigned char* b = viewBytes(model, info.vertexView);
        if (!b)
            return Status(StatusCode::InvalidData, path + ": the displacements' bufferView is out of range");
        out->assign(b, b + model.bufferViews[size_t(info.vertexView)].byteLength);
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
    const size_t stride = view.byteStride ? view.byteStride : 1;
    const size_t avail = acc.byteOffset <= view.byteLength ? view.byteLength - acc.byteOffset : 0;
    if (!b || acc.byteOffset > view.byteLength || (acc.count && (avail == 0 || acc.count - 1 > (avail - 1) / stride)))
        return Status(StatusCode::InvalidData, what + " reads past the end of its bufferView");
    out->resize(acc.count);
    for (size_t i = 0; i < acc.count; ++i)
        (*out)[i] = b[acc.byteOffset + i * stride];
    return Status::ok();
}

// A rig merged into one scene with other models (gltf-transform merge
// --merge-scenes, an editor adding a floor): where the mesh carrying the
// layer (`layered`) alone welds to the counts the layer was baked on, the
// rest is another model, and the refusal names it rather than blaming a
// weld or a simplification.
Status checkNoOtherModel(const tinygltf::Value& block, const std::string& path, const tinygltf::Model& model,
                         int layered, const Rig& rig)
{
    const tinygltf::Value* control = member(block, "control");
    double vertices = 0, triangles = 0;
    if (!control || !numberField(*control, "vertices", path, &vertices) ||
        !numberField(*control, "triangles", path, &triangles) ||
        (vertices == double(rig.mesh.vertexCount()) && triangles == double(rig.mesh.faceCount())))
        return Status::ok();
    std::vector<uint8_t> used(rig.mesh.vertexCount(), 0);
    size_t ownVertices = 0, ownTriangles = 0;
    std::vector<std::string> others;
    for (const RigPart& part : rig.parts) {
        if (part.mesh != layered) {
            const std::string name = "mesh " + std::to_string(part.mesh) + " (" +
                                     printable(model.meshes[size_t(part.mesh)].name, 40) + ")";
            if (std::find(others.begin(), others.end(), name) == others.end())
                others.push_back(name);
            continue;
        }
        ownTriangles += part.faceCount;
        for (uint32_t v = 0; v < part.vertexCount; ++v) {
            const uint32_t t = rig.sourceVertex[part.firstVertex + v];
            ownVertices += t < used.size() && !used[t];
            if (t < used.size())
                used[t] = 1;
        }
    }
    if (others.empty() || double(ownVertices) != vertices || double(ownTriangles) != triangles)
        return Status::ok();
    std::string names = others[0];
    for (size_t i = 1; i < others.size() && i < 3; ++i)
        names += ", " + others[i];
    if (others.size() > 3)
        names += " and " + std::to_string(others.size() - 3) + " more";
    return Status(StatusCode::InvalidData,
                  path + ": the scene draws " + names + " beside the layered mesh, which the layer was not baked "
                         "with (another model merged into its scene): keep the rig in a scene of its own (gltf-transform "
                         "merge without --merge-scenes), or bake again");
}

// A rig placed elsewhere as a whole since the bake, by its nodes
// (gltf-transform center, an editor moving or scaling the model): every
// part unskinned and drawn through one transform, and the control mesh as its
// accessors hold it is the one the layer was baked on, at the place it was
// baked (an identity node, as strata-bake writes).  glTF draws the displaced
// surface through that transform, so the surface moves with it and its
// displacements scale by its scale; a transform that scales unevenly or
// shears would bend the surface out of its baked shape, and is refused by
// name.  *placement says whether the rig is placed so (if not, the usual
// check says what changed).
Status placedByNodes(const std::string& path, const tinygltf::Value& block, const tinygltf::Model& model,
                     const SceneGeometry& scene, const Rig& rig, Placement* placement)
{
    *placement = Placement();
    const tinygltf::Value* control = member(block, "control");
    const tinygltf::Value* positions = control ? member(*control, "positions") : nullptr;
    if (!positions || !positions->IsString() || rig.parts.empty() ||
        scene.meshSpace.size() != rig.sourceVertex.size() ||
        positions->Get<std::string>() == hex64(fingerprintControlMesh(rig.mesh).positions))
        return Status::ok();
    const glm::mat4 M = rig.parts[0].toScene;
    for (const RigPart& part : rig.parts)
        if (part.skinned || part.toScene != M)
            return Status::ok();
    if (M == glm::mat4(1.0f))
        return Status::ok();
    ControlMesh mesh = rig.mesh;
    for (size_t f = 0; f < rig.sourceVertex.size(); ++f)
        if (rig.sourceVertex[f] < mesh.positions.size())
            mesh.positions[rig.sourceVertex[f]] = scene.meshSpace[f];
    if (positions->Get<std::string>() != hex64(fingerprintControlMesh(mesh).positions))
        return Status::ok();
    // One scale in every direction (to what a tool's float composition of a
    // rotation leaves).
    double s = 1.0;
    if (!similarityScale(glm::dmat3(M), &s)) {
        const int node = rig.parts[0].node;
        std::string where = "its nodes";
        if (node >= 0 && size_t(node) < model.nodes.size())
            where = "node " + std::to_string(node) + " (" + printable(model.nodes[size_t(node)].name, 60) +
                    ") and its parents";
        return Status(StatusCode::InvalidData, path + ": " + where + " " + kUnevenlyScaled);
    }
    if (glm::determinant(glm::dmat3(M)) < 0.0)
        return Status(StatusCode::InvalidData, path + ": " + kMirrored);
    placement->baked = std::move(mesh);
    placement->scale = float(s);
    placement->placed = true;
    return Status::ok();
}

Status finishRig(const std::string& path, std::shared_ptr<SourceDocument> doc, Rig* out, LayerCheck check,
                 size_t maxBytes)
{
    Status st;
    SceneGeometry scene;
    if (!(st = readSceneGeometry(path, *doc, &scene)))
        return st;
    // A control mesh that Strata's glTF Transform extension carried through
    // a command that renumbered or moved it: the baked mesh takes its place.
    glm::mat4 bindFix(1.0f);
    Placement carried;
    if (scene.blockMesh >= 0 && scene.blockIsExtension && check == LayerCheck::Enforce) {
        bool extension = false;
        const tinygltf::Value& block = *layerBlock(doc->model.meshes[size_t(scene.blockMesh)], &extension);
        if (member(block, "baked") && !checkLayerBinding(block, path, scene.rig.mesh, true) &&
            !(st = carryBakedControl(path, doc->model, block, &scene, &bindFix, &carried)))
            return st;
    }
    Rig rig = std::move(scene.rig);
    if (rig.mesh.triangles.empty())
        return Status(StatusCode::InvalidData, path + ": every triangle is degenerate");
    if (!(st = validateControlMesh(rig.mesh)))
        return Status(st.code(), path + ": " + st.message());
    if (!(st = loadSkeleton(path, doc->model, scene, &rig)))
        return st;
    if (bindFix != glm::mat4(1.0f) && rig.skeleton.meshNode >= 0) {
        // The skins' joints (their union's, not the rigid parts' extra
        // joints after them) bind the baked vertices: a tool that moved the
        // bind space moved the inverse bind matrices with it.
        const size_t joints = scene.skins.joints.size();
        for (size_t j = 0; j < joints && j < rig.skeleton.skin.inverseBindMatrices.size(); ++j)
            rig.skeleton.skin.inverseBindMatrices[j] = rig.skeleton.skin.inverseBindMatrices[j] * bindFix;
    }
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
        if (extension && check != LayerCheck::Seal && !(st = checkNoOtherModel(block, path, model, scene.blockMesh, rig)))
            return st;
        Placement& placement = carried;
        if (extension && check != LayerCheck::Seal && !placement.placed &&
            !(st = placedByNodes(path, block, model, scene, rig, &placement)))
            return st;
        if (placement.placed) {
            DisplacementInfo& info = rig.displacement;
            info.factor *= placement.scale;
            info.offset *= placement.scale;
            info.quantized.dmin *= placement.scale;
            info.quantized.dmax *= placement.scale;
        }
        // Per-vertex values need no UVs: a tool that dropped the set leaves
        // them intact (there is then no map to rasterise for textures).
        if (scene.missingUV && rig.displacement.texCoord >= 0 && rig.displacement.vertexLevel >= 0)
            rig.displacement.texCoord = -1;
        if (scene.missingUV && rig.displacement.texCoord >= 0)
            return Status(StatusCode::InvalidData, path + ": the rig has a displacement map but " + scene.firstMissingUV +
                                                       " has no TEXCOORD_" + std::to_string(rig.displacement.texCoord) +
                                                       " (a tool dropped it: prune, for one, drops texture coordinates "
                                                       "no material uses)");
        const ControlMesh& bound = placement.placed ? placement.baked : rig.mesh;
        if (extension && !(st = checkLayerBinding(block, path, bound, check != LayerCheck::Seal)))
            return st;
        if (rig.displacement.vertexLevel >= 0) {
            DisplacementInfo& info = rig.displacement;
            if (!(st = layerVertexBytes(model, info, path, &info.embedded)))
                return st;
            const size_t length = info.embedded.size();
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
            if (!(st = decodeVertexDisplacements(rig.mesh, info.vertexLevel, info.embedded.data(),
                                                 info.embedded.size(), info.factor, info.offset, path,
                                                 &info.vertexValues)))
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
        // A rig's control mesh has no normals of its own: its primitives
        // without NORMAL are flat only where the capture was.
        for (RigPart& part : rig.parts)
            part.flat = part.flat && rig.displacement.flatShading;
    } else if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), kLayerExtension) !=
               model.extensionsUsed.end()) {
        rig.warnings.push_back(std::string("declares ") + kLayerExtension +
                               " but no mesh carries the layer (dropped by another tool?): the displacement is gone");
    } else if (writtenByStrata(model) && !strataSurface(model)) {
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

}  // namespace rigfile

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


}  // namespace io
}  // namespace strata
