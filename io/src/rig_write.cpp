// Writing glTF 2.0 control rigs (docs/FORMAT.md) that the Khronos
// glTF-Validator accepts without warnings: the source document kept whole,
// the displacement layer added as STRATA_layered_displacement, and its
// fingerprint of the control mesh sealed from the file as it reads back.
#include "strata/io/rig_io.h"
#include "strata/uv_raster.h"

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
#include "strata/plane.h"

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
    if (d.flatShading)
        block["shading"] = tinygltf::Value(std::string("flat"));
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
    // A mirrored part's faces are the file's with their winding reversed:
    // its corners taken in the faces' order here, and the file's order given
    // back below.
    const bool mirrored = mirrors(part);
    if (mirrored)
        reverseWinding(&tri);
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
    if (mirrored)
        reverseWinding(&indices);
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
        const double area = orient2(t[0], t[1], t[2]);
        const TexelRect r = texelRect(t, width, height, reach);
        for (int y = r.y0; y <= r.y1; ++y)
            for (int x = r.x0; x <= r.x1; ++x) {
                uint8_t& u = used[size_t(y) * size_t(width) + size_t(x)];
                if (u)
                    continue;
                const glm::dvec2 p(x + 0.5, y + 0.5);
                bool inside = area != 0.0;
                double nearest = 1e300;
                for (int k = 0; k < 3; ++k) {
                    const glm::dvec2 a = t[k], b = t[(k + 1) % 3], ab = b - a;
                    const double cross = cross2(ab, p - a);
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
                   double positionError, bool draco, std::string* out, std::vector<std::string>* notes = nullptr)
{
    if (compressed)
        return encodeCompressedGlb(path, model, out, positionError, draco, notes);
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

Status probeVertexMesh(const tinygltf::Model& model, const Rig& rig, const DisplacementMap& map, int level,
                       bool compressed, double positionError, bool draco, const std::string& path,
                       ControlMesh* fileMesh, std::vector<float>* sampled)
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
    *fileMesh = std::move(mesh);
    *sampled = std::move(values);
    return Status::ok();
}

// The coded values as the layer's accessor of bytes.
Status embedVertexValues(tinygltf::Model& model, const ControlMesh& mesh, int level, const std::vector<float>& values,
                         double step, int mapWidth, int mapHeight, DisplacementInfo* info)
{
    std::string bytes;
    float factor = 1.0f, offset = 0.0f;
    Status st = encodeVertexDisplacements(mesh, level, values, step, &bytes, &factor, &offset);
    if (!st)
        return st;
    const int view = appendBufferView(model, bytes.data(), bytes.size(), -1);
    model.bufferViews[size_t(view)].target = 0;
    info->vertexView = view;
    info->vertexAccessor =
        appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_SCALAR, bytes.size());
    info->vertexLevel = level;
    info->vertexValues = values;
    info->image = -1;
    info->uri.clear();
    info->encoding = "vertex";
    info->width = mapWidth;
    info->height = mapHeight;
    info->factor = factor;
    info->offset = offset;
    return Status::ok();
}

// The material of a bare control mesh: its base colour texture as an
// embedded PNG, on every primitive of mesh 0.
Status addBaseColour(tinygltf::Model& model, const BaseColourTexture& colour)
{
    tinygltf::Sampler sampler;
    sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
    sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    model.samplers.push_back(sampler);
    // Each image a texture through that sampler; the texture's index.
    // Colours as JPEG or PNG, whichever is smaller; metallic, roughness and
    // occlusion and normals (`values`: values rather than colours) as PNG,
    // since JPEG's chroma would move one channel's values by the others'.
    const auto addTexture = [&](const std::vector<uint8_t>& rgba, const std::string& name, bool values, int* index,
                                int level = 9, int width = 0, int height = 0) {
        std::string bytes, mimeType = "image/png";
        width = width > 0 ? width : colour.width;
        height = height > 0 ? height : colour.height;
        Status st = values ? encodePngRgba(width, height, rgba, &bytes, level)
                           : encodeColourImage(width, height, rgba, 90, &bytes, &mimeType);
        if (!st)
            return Status(st.code(), "the " + name + " texture: " + st.message());
        const int view = appendBufferView(model, bytes.data(), bytes.size(), -1);
        model.bufferViews[size_t(view)].target = 0;
        tinygltf::Image image;
        image.name = name;
        image.mimeType = mimeType;
        image.bufferView = view;
        model.images.push_back(image);
        tinygltf::Texture texture;
        texture.source = int(model.images.size() - 1);
        texture.sampler = int(model.samplers.size() - 1);
        model.textures.push_back(texture);
        *index = int(model.textures.size() - 1);
        return Status::ok();
    };
    // The control mesh's own material (every primitive of mesh 0 wears it).
    if (model.materials.empty())
        model.materials.emplace_back();
    int base = -1, mr = -1, emissive = -1, normal = -1;
    Status st = addTexture(colour.rgba, colour.name.empty() ? "base_colour" : colour.name, false, &base);
    if (st && !colour.metallicRoughness.empty())
        st = addTexture(colour.metallicRoughness, "metallic_roughness", true, &mr);
    if (st && !colour.emissiveRGBA.empty())
        st = addTexture(colour.emissiveRGBA, "emissive", false, &emissive);
    // A direction: JPEG's chroma would turn it.  Every texel differs from
    // its neighbours (no flat factors), where zlib's level 9 costs a second
    // a megatexel, and a bake writes one per cage it tries: level 6.
    if (st && !colour.normalRGBA.empty())
        st = addTexture(colour.normalRGBA, "normal", true, &normal, 6, colour.normalWidth, colour.normalHeight);
    if (!st)
        return st;
    tinygltf::Material& material = model.materials[0];
    material.pbrMetallicRoughness.baseColorTexture.index = base;
    material.pbrMetallicRoughness.metallicRoughnessTexture.index = mr;
    material.occlusionTexture.index = colour.occlusion ? mr : -1;  // its R: an ORM texture
    material.emissiveTexture.index = emissive;
    material.normalTexture.index = normal;
    material.emissiveFactor = {double(colour.emissive[0]), double(colour.emissive[1]), double(colour.emissive[2])};
    if (colour.emissiveStrength > 1.0f) {
        tinygltf::Value::Object strength;
        strength["emissiveStrength"] = tinygltf::Value(double(colour.emissiveStrength));
        material.extensions["KHR_materials_emissive_strength"] = tinygltf::Value(strength);
        useExtension(model, "KHR_materials_emissive_strength", false);
    }
    material.pbrMetallicRoughness.metallicFactor = double(colour.metallic);
    material.pbrMetallicRoughness.roughnessFactor = double(colour.roughness);
    material.doubleSided = colour.doubleSided;
    if (colour.alphaMode == "MASK" || colour.alphaMode == "BLEND") {
        material.alphaMode = colour.alphaMode;
        if (colour.alphaMode == "MASK")
            material.alphaCutoff = double(colour.alphaCutoff);
    }
    for (tinygltf::Primitive& p : model.meshes[0].primitives)
        p.material = 0;
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

}  // namespace rigfile

using namespace rigfile;


struct RigWriter::State {
    std::string path;
    tinygltf::Model model;
    DisplacementInfo info;
    std::vector<int> blockMeshes;
    ControlMesh mesh;  // the control mesh as written
    bool hasDisplacement = false;
    bool compress = false;
    double positionError = 0.0;
    bool draco = false;
    // Per-vertex values still to give: over fileMesh, at level.
    bool needsValues = false;
    ControlMesh fileMesh;
    int level = -1;
    std::vector<float> sampled;
    double step = 0.0;
    int mapWidth = 0, mapHeight = 0;
    std::vector<std::string>* notes = nullptr;  // the caller's, until commit
};

RigWriter::RigWriter() = default;
RigWriter::~RigWriter() = default;

bool RigWriter::needsVertexValues() const { return state_ && state_->needsValues; }
const ControlMesh& RigWriter::fileMesh() const { return state_->fileMesh; }
int RigWriter::vertexLevel() const { return state_ ? state_->level : -1; }
const std::vector<float>& RigWriter::sampledValues() const { return state_->sampled; }
double RigWriter::quantizationStep() const { return state_ ? state_->step : 0.0; }

Status RigWriter::begin(const std::filesystem::path& pathFile, const Rig& input, const DisplacementMap* map,
                        const RigWriteOptions& writeOptions, std::vector<std::string>* notes)
{
    state_.reset();
    const RigWriteOptions* options = &writeOptions;
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
                         rig.hasDisplacement && !options->baseColour;
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
    bool needsValues = false;
    ControlMesh fileMesh;
    std::vector<float> sampled;
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
        if (options && options->baseColour && cm.hasUVs() && !(st = addBaseColour(model, *options->baseColour)))
            return Status(st.code(), path + ": " + st.message());
    }
    if (rig.hasDisplacement) {
        if (!cm.hasUVs())
            return Status(StatusCode::InvalidArgument, path + ": a rig with a displacement map needs UVs");
        const double step = options ? options->maxQuantizationStep : 0.0;
        if (map && options && options->vertexDisplacements) {
            needsValues = true;
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
                    st = probeVertexMesh(model, rig, *map, info.recommendedLevel, compressed, error, withDraco, path,
                                         &fileMesh, &sampled);
                    if (st) {
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
        if (!needsValues && info.image < 0 && info.uri.empty() && info.vertexLevel < 0)
            return Status(StatusCode::InvalidArgument, path + ": the rig names no displacement map");
    }
    auto state = std::make_unique<State>();
    state->path = path;
    state->model = std::move(model);
    state->info = std::move(info);
    state->blockMeshes = std::move(blockMeshes);
    state->mesh = cm;
    state->hasDisplacement = rig.hasDisplacement;
    state->compress = extensionOf(path) == ".glb" && options && options->compress;
    state->positionError = positionError;
    state->draco = draco;
    state->needsValues = needsValues;
    state->fileMesh = std::move(fileMesh);
    state->level = needsValues ? state->info.recommendedLevel : -1;
    state->sampled = std::move(sampled);
    state->step = options ? options->maxQuantizationStep : 0.0;
    state->mapWidth = map ? map->width : 0;
    state->mapHeight = map ? map->height : 0;
    state->notes = notes;
    state_ = std::move(state);
    return Status::ok();
}

Status RigWriter::setVertexValues(const std::vector<float>& values, double step)
{
    if (!state_ || !state_->needsValues)
        return Status(StatusCode::InvalidArgument, "RigWriter::setVertexValues: the rig takes no per-vertex values");
    State& s = *state_;
    Status st = embedVertexValues(s.model, s.fileMesh, s.level, values, step, s.mapWidth, s.mapHeight, &s.info);
    if (!st)
        return Status(st.code(), s.path + ": " + st.message());
    s.needsValues = false;
    return Status::ok();
}

Status RigWriter::commit()
{
    if (!state_)
        return Status(StatusCode::InvalidArgument, "RigWriter::commit: begin did not succeed");
    const std::string path = state_->path;
    std::string bytes;
    Status st = commit(&bytes);
    return st ? writeFileAtomic(path, bytes.data(), bytes.size()) : st;
}

Status RigWriter::commit(std::string* out)
{
    if (!state_)
        return Status(StatusCode::InvalidArgument, "RigWriter::commit: begin did not succeed");
    if (!out)
        return Status(StatusCode::InvalidArgument, "RigWriter::commit: no output");
    State& s = *state_;
    if (s.needsValues)
        return Status(StatusCode::InvalidArgument, s.path + ": the per-vertex displacements were not given");
    Status st;
    if (s.hasDisplacement) {
        if (s.info.image < 0 && s.info.uri.empty() && s.info.vertexLevel < 0)
            return Status(StatusCode::InvalidArgument, s.path + ": the rig names no displacement map");
        const tinygltf::Value block = layerBlockValue(s.info, s.mesh);
        for (int m : s.blockMeshes)
            setLayer(&s.model, &s.model.meshes[size_t(m)], &block);
    }
    // Compact rigs: Draco- or meshopt-coded vertex data and indices (.glb).
    std::string bytes;
    const bool binary = extensionOf(s.path) == ".glb";
    if (!(st = encodeModel(s.path, s.model, binary && s.compress, binary, s.positionError, s.draco, &bytes, s.notes)))
        return st;
    if (s.hasDisplacement && !(st = sealLayer(s.path, &bytes)))
        return st;
    *out = std::move(bytes);
    state_.reset();
    return Status::ok();
}

Status saveRig(const std::filesystem::path& path, const Rig& rig, const DisplacementMap* map,
               std::vector<std::string>* notes, const RigWriteOptions* options)
{
    RigWriter writer;
    Status st = writer.begin(path, rig, map, options ? *options : RigWriteOptions(), notes);
    if (st && writer.needsVertexValues())
        st = writer.setVertexValues(writer.sampledValues(), writer.quantizationStep());
    return st ? writer.commit() : st;
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
