// Carrying the displacement layer through tools that renumber or move the
// control mesh.  Strata's glTF Transform extension (js/) tags every control
// vertex with its number in the baked mesh (_STRATA_VERTEX) and, when a
// command changed the mesh, writes the baked parts beside the layer
// (docs/STRATA_layered_displacement.md, "Carrying the layer").  Here the
// baked control mesh is rebuilt from those parts, exactly as the file was
// welded at the bake, and accepted only when the tagged file still holds
// the same triangles with every vertex near its baked place: the surface is
// then the baked one, bit for bit, and the file's own (renumbered,
// quantised) mesh supplies what the layer does not hold (skin weights,
// materials, texture UVs).
#include "rig_internal.h"
#include "gltf_accessor.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace strata {
namespace io {
namespace rigfile {

namespace {

const char* const kTag = "_STRATA_VERTEX";

Status refuse(const std::string& path, const std::string& why)
{
    return Status(StatusCode::InvalidData, path + ": " + why + ": run that step before baking, or bake again");
}

// A triangle by its vertices, starting at the least (winding kept), and its part.
using TriangleKey = std::array<uint32_t, 4>;
TriangleKey triangleKey(uint32_t a, uint32_t b, uint32_t c, uint32_t part)
{
    if (b < a && b < c)
        return {b, c, a, part};
    if (c < a && c < b)
        return {c, a, b, part};
    return {a, b, c, part};
}

// The tags of a part's vertices: each vertex's number among the baked
// parts' vertices (two 16-bit halves; dequantize may have made them
// floats).  None when the part has no tags.
Status readTags(const tinygltf::Model& model, const tinygltf::Primitive& prim, size_t count, const std::string& what,
                std::vector<uint32_t>* out)
{
    const int acc = attributeOf(prim, kTag);
    if (acc < 0) {
        out->clear();
        return Status::ok();  // no tags: the caller says what that means
    }
    std::vector<uint32_t> halves;
    Status st = readUintAccessor(model, acc, 2, kTag, &halves);
    if (!st) {
        std::vector<float> f;
        if (!readFloatAccessor(model, acc, 2, kTag, &f))
            return st;
        halves.resize(f.size());
        for (size_t i = 0; i < f.size(); ++i) {
            if (!(f[i] >= 0.0f && f[i] <= 65535.0f && f[i] == std::floor(f[i])))
                return Status(StatusCode::InvalidData, what + ": " + kTag + " holds " + std::to_string(f[i]));
            halves[i] = uint32_t(f[i]);
        }
    }
    if (halves.size() != 2 * count)
        return Status(StatusCode::InvalidData, what + ": " + kTag + " does not have one element per vertex");
    out->resize(count);
    for (size_t i = 0; i < count; ++i) {
        if (halves[2 * i] > 0xffff || halves[2 * i + 1] > 0xffff)
            return Status(StatusCode::InvalidData, what + ": " + kTag + " holds a half above 65535");
        (*out)[i] = halves[2 * i] | (halves[2 * i + 1] << 16);
    }
    return Status::ok();
}

// The affine map F with baked ~ F * current, by least squares (centred, in
// double), and its largest residual.
bool fitAffine(const std::vector<glm::dvec3>& current, const std::vector<glm::dvec3>& baked, glm::dmat4* F,
               double* worst)
{
    const size_t n = current.size();
    if (n < 4)
        return false;
    glm::dvec3 cc(0.0), cb(0.0);
    for (size_t i = 0; i < n; ++i) {
        cc += current[i];
        cb += baked[i];
    }
    cc /= double(n);
    cb /= double(n);
    glm::dmat3 CC(0.0), BC(0.0);  // sum of (c - cc)(c - cc)^T and (b - cb)(c - cc)^T
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 c = current[i] - cc, b = baked[i] - cb;
        CC += glm::outerProduct(c, c);
        BC += glm::outerProduct(b, c);
    }
    const double det = glm::determinant(CC);
    const double scale = CC[0][0] + CC[1][1] + CC[2][2];
    if (!(std::fabs(det) > 1e-18 * scale * scale * scale))
        return false;  // flat or degenerate: the map is not determined
    const glm::dmat3 L = BC * glm::inverse(CC);
    *F = glm::dmat4(L);
    (*F)[3] = glm::dvec4(cb - L * cc, 1.0);
    *worst = 0.0;
    for (size_t i = 0; i < n; ++i)
        *worst = std::max(*worst, glm::length(glm::dvec3(*F * glm::dvec4(current[i], 1.0)) - baked[i]));
    return true;
}

}  // namespace

bool similarityScale(const glm::dmat3& A, double* s)
{
    *s = std::cbrt(std::fabs(glm::determinant(A)));
    const glm::dmat3 gram = glm::transpose(A) * A;
    double apart = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            apart = std::max(apart, std::fabs(gram[i][j] - (i == j ? *s * *s : 0.0)));
    return *s > 0.0 && std::isfinite(*s) && apart <= 1e-4 * *s * *s;
}

Status carryBakedControl(const std::string& path, const tinygltf::Model& model, const tinygltf::Value& block,
                         SceneGeometry* scene, glm::mat4* bindFix, Placement* placement)
{
    *bindFix = glm::mat4(1.0f);
    *placement = Placement();
    const tinygltf::Value* baked = member(block, "baked");
    const tinygltf::Value* parts = baked ? member(*baked, "parts") : nullptr;
    if (!parts || !parts->IsArray())
        return Status(StatusCode::InvalidData, path + ": the layer's \"baked\" has no parts array");
    Rig& rig = scene->rig;
    if (parts->ArrayLen() != rig.parts.size())
        return refuse(path, "the control mesh has " + std::to_string(rig.parts.size()) +
                                " triangle primitives but was baked as " + std::to_string(parts->ArrayLen()) +
                                " (a tool joined or split them: join, optimize)");

    // The baked mesh, welded as the bake welded it.
    Rig bakedRig;
    bakedRig.parts = rig.parts;
    std::vector<float> pos;
    std::vector<glm::vec2> uv;
    std::vector<uint32_t> tri, partOfTri;
    bool withUV = true;
    for (size_t k = 0; k < parts->ArrayLen(); ++k) {
        const tinygltf::Value& part = parts->Get(int(k));
        const std::string what = path + ": the layer's baked part " + std::to_string(k);
        auto index = [&](const char* name) {
            const tinygltf::Value* v = member(part, name);
            return v && v->IsNumber() ? int(v->GetNumberAsDouble()) : -1;
        };
        const int positions = index("POSITION"), indices = index("indices"), texCoord = index("texCoord");
        const tinygltf::Value* modeValue = member(part, "mode");
        tinygltf::Primitive prim;
        prim.indices = indices >= 0 && size_t(indices) < model.accessors.size() ? indices : -1;
        prim.mode = modeValue && modeValue->IsNumber() ? int(modeValue->GetNumberAsDouble()) : TINYGLTF_MODE_TRIANGLES;
        if (positions < 0 || size_t(positions) >= model.accessors.size() || (indices >= 0 && prim.indices < 0) ||
            (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
             prim.mode != TINYGLTF_MODE_TRIANGLE_FAN))
            return Status(StatusCode::InvalidData, what + " does not name a POSITION accessor, its indices and a "
                                                          "triangle mode");
        std::vector<float> p, t;
        Status st = readFloatAccessor(model, positions, 3, "POSITION", &p);
        if (!st)
            return Status(st.code(), what + ": " + st.message());
        const size_t n = p.size() / 3;
        if (texCoord >= 0) {
            if (size_t(texCoord) >= model.accessors.size() ||
                !(st = readFloatAccessor(model, texCoord, 2, "texCoord", &t)) || t.size() != 2 * n)
                return Status(StatusCode::InvalidData, what + ": its texCoord accessor does not give one UV per vertex");
        } else {
            withUV = false;
        }
        std::vector<uint32_t> ptri;
        if (!(st = primitiveTriangles(model, prim, n, what, &ptri)))
            return st;
        if (pos.size() / 3 + n >= 0x7fffffffu)
            return Status(StatusCode::InvalidData, what + ": too many vertices");
        const uint32_t first = uint32_t(pos.size() / 3);
        bakedRig.parts[k].firstVertex = first;
        bakedRig.parts[k].vertexCount = uint32_t(n);
        pos.insert(pos.end(), p.begin(), p.end());
        for (size_t i = 0; i < n; ++i)
            uv.push_back(t.empty() ? glm::vec2(0.0f) : glm::vec2(t[2 * i], t[2 * i + 1]));
        for (uint32_t i : ptri) {
            tri.push_back(first + i);
            if (tri.size() % 3 == 0)
                partOfTri.push_back(uint32_t(k));
        }
    }
    for (float v : pos)
        if (!std::isfinite(v))
            return Status(StatusCode::InvalidData, path + ": the layer's baked positions are not finite");
    weldFileVertices(pos, std::move(uv), tri, partOfTri, withUV, rig.fileTexCoord, &bakedRig);
    if (!checkLayerBinding(block, path, bakedRig.mesh, true))
        return Status(StatusCode::InvalidData, path + ": the layer's \"baked\" control mesh is not the one its "
                                                      "\"control\" record describes (the file is damaged)");
    const size_t nBakedFile = pos.size() / 3;

    // Each file vertex's baked vertex, through its tag.
    const size_t nFile = rig.sourceVertex.size();
    std::vector<uint32_t> toBaked(nFile);
    for (size_t p = 0; p < rig.parts.size(); ++p) {
        const RigPart& part = rig.parts[p];
        std::vector<uint32_t> tags;
        Status st = readTags(model, *scene->primitives[p], part.vertexCount, path + ": " + part.name, &tags);
        if (st && tags.empty() && part.vertexCount)
            return refuse(path, "the control mesh changed after the bake and " + part.name + " lost the " + kTag +
                                    " numbers that would carry the layer through (a tool that does not know "
                                    "STRATA_layered_displacement, or prune, ran after the one that did)");
        if (!st)
            return st;
        for (uint32_t v = 0; v < part.vertexCount; ++v) {
            if (tags[v] >= nBakedFile)
                return Status(StatusCode::InvalidData, path + ": " + part.name + ": " + kTag + " " +
                                                           std::to_string(tags[v]) + " is beyond the " +
                                                           std::to_string(nBakedFile) + " baked vertices");
            toBaked[part.firstVertex + v] = bakedRig.sourceVertex[tags[v]];
        }
    }

    // The file's triangles, through the tags, must be the baked triangles.
    std::vector<std::pair<TriangleKey, size_t>> fileKeys, bakedKeys;  // key, triangle
    for (size_t t = 0; t * 3 < scene->fileTriangles.size(); ++t) {
        const uint32_t* c = &scene->fileTriangles[3 * t];
        const uint32_t a = toBaked[c[0]], b = toBaked[c[1]], d = toBaked[c[2]];
        if (a != b && b != d && a != d)
            fileKeys.push_back({triangleKey(a, b, d, scene->fileTriangleParts[t]), t});
    }
    for (size_t p = 0; p < bakedRig.parts.size(); ++p)
        for (uint32_t f = 0; f < bakedRig.parts[p].faceCount; ++f) {
            const uint32_t* c = &bakedRig.mesh.triangles[3 * size_t(bakedRig.parts[p].firstFace + f)];
            bakedKeys.push_back({triangleKey(c[0], c[1], c[2], uint32_t(p)), bakedRig.parts[p].firstFace + f});
        }
    if (fileKeys.size() != bakedKeys.size())
        return refuse(path, "the control mesh has " + std::to_string(fileKeys.size()) + " triangles but was baked with " +
                                std::to_string(bakedKeys.size()) +
                                " (a tool simplified, decimated or rebuilt it: simplify, optimize)");
    std::sort(fileKeys.begin(), fileKeys.end());
    std::sort(bakedKeys.begin(), bakedKeys.end());
    std::vector<uint32_t> corners(bakedRig.mesh.triangles.size());
    for (size_t i = 0; i < fileKeys.size(); ++i) {
        if (fileKeys[i].first != bakedKeys[i].first)
            return refuse(path, "the control mesh's triangles are no longer the baked ones (a tool rebuilt, flipped "
                                "or simplified them)");
        // The file vertices of the baked triangle's corners, in its rotation.
        const uint32_t* c = &scene->fileTriangles[3 * fileKeys[i].second];
        const uint32_t* b = &bakedRig.mesh.triangles[3 * bakedKeys[i].second];
        int shift = 0;
        while (shift < 3 && toBaked[c[shift]] != b[0])
            ++shift;
        for (int k = 0; k < 3; ++k)
            corners[3 * bakedKeys[i].second + size_t(k)] = c[(shift + k) % 3];
    }

    // Every file vertex near its baked place: where the part sits in the
    // control mesh's space (rigid parts), directly; in a skin's bind space,
    // up to the one affine map a tool may have moved the bind space by.
    std::vector<glm::vec3>& B = bakedRig.mesh.positions;
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& q : B) {
        lo = glm::min(lo, q);
        hi = glm::max(hi, q);
    }
    const double tolerance = std::ldexp(double(glm::length(hi - lo)), -7);
    std::vector<glm::dvec3> current, target;
    std::vector<glm::dvec3> rigidCurrent, rigidBaked;
    double rigidWorst = 0.0;
    for (const RigPart& part : rig.parts)
        for (uint32_t v = 0; v < part.vertexCount; ++v) {
            const size_t f = part.firstVertex + v;
            const glm::dvec3 c(rig.mesh.positions[rig.sourceVertex[f]]), b(B[toBaked[f]]);
            if (part.skinned) {
                current.push_back(c);
                target.push_back(b);
            } else {
                rigidWorst = std::max(rigidWorst, glm::length(c - b));
                rigidCurrent.push_back(c);
                rigidBaked.push_back(b);
            }
        }
    // A rig without skin that its nodes moved whole after the tool: the
    // baked mesh goes where they put it (glTF draws it there), if one move,
    // turn and scale alike takes it to the file's vertices.
    glm::dmat4 toBakedPlace(1.0);
    double fitted = 0.0, s = 1.0;
    if (rigidWorst > tolerance && current.empty() && fitAffine(rigidCurrent, rigidBaked, &toBakedPlace, &fitted) &&
        fitted <= tolerance) {
        if (!similarityScale(glm::inverse(glm::dmat3(toBakedPlace)), &s))
            return Status(StatusCode::InvalidData, path + ": its nodes " + kUnevenlyScaled);
        if (glm::determinant(glm::dmat3(toBakedPlace)) < 0.0)
            return Status(StatusCode::InvalidData, path + ": " + kMirrored);
        placement->placed = true;
        placement->scale = float(s);
        placement->baked = bakedRig.mesh;
        const glm::dmat4 A = glm::inverse(toBakedPlace);
        for (glm::vec3& q : B)
            q = glm::vec3(A * glm::dvec4(glm::dvec3(q), 1.0));
        rigidWorst = 0.0;
    }
    if (rigidWorst > tolerance)
        return refuse(path, "the control mesh's vertices moved up to " + std::to_string(rigidWorst) +
                                " after the bake, beyond what quantisation explains (" + std::to_string(tolerance) + ")");
    if (!current.empty()) {
        double identityWorst = 0.0;
        for (size_t i = 0; i < current.size(); ++i)
            identityWorst = std::max(identityWorst, glm::length(current[i] - target[i]));
        if (identityWorst > 0.0) {
            glm::dmat4 F(1.0);
            double worst = 0.0;
            if (!fitAffine(current, target, &F, &worst) || worst > tolerance)
                return refuse(path, "the skinned control mesh's vertices moved after the bake, beyond what "
                                    "quantisation explains");
            // Skinning S * IBM_current * current = S * IBM_current * F^-1 * baked.
            if (identityWorst > tolerance)
                *bindFix = glm::mat4(glm::inverse(F));
        }
    }

    // The baked mesh in place of the file's: the file vertices (skin
    // weights, materials, texture UVs) now point at baked vertices.
    rig.mesh = std::move(bakedRig.mesh);
    rig.sourceVertex = std::move(toBaked);
    rig.fileCorners = std::move(corners);
    for (size_t p = 0; p < rig.parts.size(); ++p) {
        rig.parts[p].firstFace = bakedRig.parts[p].firstFace;
        rig.parts[p].faceCount = bakedRig.parts[p].faceCount;
    }
    rig.fileTexCoord = -1;  // the UVs are the baked ones, not the file's
    rig.fileUVHash = 0;
    return Status::ok();
}

}  // namespace rigfile
}  // namespace io
}  // namespace strata
