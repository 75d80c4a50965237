// OBJ reading and OBJ / PLY / glTF writing of plain meshes.
#include "strata/io/mesh_io.h"

#include "strata/io/file.h"
#include "gltf_mesh_writer.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <sstream>

namespace strata {
namespace io {
namespace {

// Strict number parsing: the whole token must be a finite number.
bool parseFloat(const char*& p, float* out)
{
    while (*p == ' ' || *p == '\t')
        ++p;
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(p, &end);
    if (end == p || errno == ERANGE || !std::isfinite(v) || std::fabs(v) > 3.0e38)
        return false;
    p = end;
    *out = float(v);
    return true;
}

Status lineError(const std::string& path, size_t line, const std::string& what)
{
    return Status(StatusCode::InvalidData, path + ":" + std::to_string(line) + ": " + what);
}

// Resolves a 1-based (or negative, relative) OBJ index against count.
bool resolveIndex(long raw, size_t count, uint32_t* out)
{
    long idx = raw > 0 ? raw - 1 : long(count) + raw;
    if (raw == 0 || idx < 0 || size_t(idx) >= count)
        return false;
    *out = uint32_t(idx);
    return true;
}

// The corner to fan-triangulate a polygon from: the first whose triangles
// all keep the polygon's orientation in UV space, so a non-convex UV polygon
// is not split into triangles that fold over each other (spot's control
// mesh has such quads).  Corner 0 when no fan qualifies.
size_t fanStart(const std::vector<glm::vec2>& uvs, const std::vector<uint32_t>& ft)
{
    const size_t n = ft.size();
    if (n <= 3)
        return 0;
    double area = 0.0;  // shoelace
    for (size_t k = 0; k < n; ++k) {
        const glm::dvec2 a(uvs[ft[k]]), b(uvs[ft[(k + 1) % n]]);
        area += a.x * b.y - a.y * b.x;
    }
    for (size_t s = 0; s < n; ++s) {
        bool consistent = true;
        for (size_t k = 1; k + 1 < n && consistent; ++k) {
            const glm::dvec2 a(uvs[ft[s]]), b(uvs[ft[(s + k) % n]]), c(uvs[ft[(s + k + 1) % n]]);
            const double t = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
            consistent = t * area > 0.0;
        }
        if (consistent)
            return s;
    }
    return 0;
}

}  // namespace

Status readObj(const std::string& path, ControlMesh* out, ObjReadInfo* info)
{
    std::vector<unsigned char> bytes;
    Status st = readFile(path, &bytes);
    if (!st)
        return st;
    return parseObj(bytes.data(), bytes.size(), path, out, info);
}

Status parseObj(const unsigned char* data, size_t size, const std::string& path, ControlMesh* out, ObjReadInfo* info)
{
    std::vector<unsigned char> bytes(data, data + size);
    bytes.push_back(0);
    ControlMesh mesh;
    ObjReadInfo stats;
    bool anyUV = false, anyNoUV = false;
    std::vector<uint32_t> fv, ft;
    const char* p = reinterpret_cast<const char*>(bytes.data());
    const char* endAll = p + bytes.size() - 1;
    size_t lineNo = 0;
    while (p < endAll) {
        ++lineNo;
        const char* eol = p;
        while (eol < endAll && *eol != '\n')
            ++eol;
        std::string line(p, eol);
        p = eol < endAll ? eol + 1 : endAll;
        if (!line.empty() && line.back() == '\r')
            line.pop_back();
        const size_t hash = line.find('#');
        if (hash != std::string::npos)
            line.resize(hash);  // a trailing comment, as in "f 1 2 3 # comment"
        if (line.find('\0') != std::string::npos)
            return lineError(path, lineNo, "binary data in a text OBJ file");
        const char* s = line.c_str();
        while (*s == ' ' || *s == '\t')
            ++s;
        if (s[0] == 'v' && (s[1] == ' ' || s[1] == '\t')) {
            s += 2;
            glm::vec3 v;
            if (!parseFloat(s, &v.x) || !parseFloat(s, &v.y) || !parseFloat(s, &v.z))
                return lineError(path, lineNo, "vertex position is not three finite numbers");
            mesh.positions.push_back(v);
        } else if (s[0] == 'v' && s[1] == 't' && (s[2] == ' ' || s[2] == '\t')) {
            s += 3;
            glm::vec2 t;
            if (!parseFloat(s, &t.x) || !parseFloat(s, &t.y))
                return lineError(path, lineNo, "texture coordinate is not two finite numbers");
            mesh.uvs.emplace_back(t.x, 1.0f - t.y);  // OBJ v points up; glTF's points down
        } else if (s[0] == 'f' && (s[1] == ' ' || s[1] == '\t')) {
            s += 2;
            fv.clear();
            ft.clear();
            bool faceUV = false, faceNoUV = false;
            while (true) {
                while (*s == ' ' || *s == '\t')
                    ++s;
                if (!*s)
                    break;
                char* end = nullptr;
                const long vi = std::strtol(s, &end, 10);
                if (end == s)
                    return lineError(path, lineNo, "malformed face index");
                s = end;
                uint32_t v;
                if (!resolveIndex(vi, mesh.positions.size(), &v))
                    return lineError(path, lineNo, "face references vertex " + std::to_string(vi) + " of " +
                                                       std::to_string(mesh.positions.size()));
                fv.push_back(v);
                bool hasT = false;
                if (*s == '/') {
                    ++s;
                    if (*s != '/') {
                        const long ti = std::strtol(s, &end, 10);
                        if (end == s)
                            return lineError(path, lineNo, "malformed texture index");
                        s = end;
                        uint32_t t;
                        if (!resolveIndex(ti, mesh.uvs.size(), &t))
                            return lineError(path, lineNo, "face references texture coordinate " +
                                                               std::to_string(ti) + " of " +
                                                               std::to_string(mesh.uvs.size()));
                        ft.push_back(t);
                        hasT = true;
                    }
                    if (*s == '/') {
                        ++s;
                        std::strtol(s, &end, 10);  // normal index: unused, control normals are computed
                        s = end;
                    }
                }
                (hasT ? faceUV : faceNoUV) = true;
                if (*s && *s != ' ' && *s != '\t')
                    return lineError(path, lineNo, "malformed face corner");
            }
            if (fv.size() < 3)
                return lineError(path, lineNo, "face has fewer than 3 corners");
            if (faceUV && faceNoUV)
                return lineError(path, lineNo, "face mixes corners with and without texture coordinates");
            anyUV = anyUV || faceUV;
            anyNoUV = anyNoUV || faceNoUV;
            ++stats.polygons;
            if (fv.size() > 3)
                ++stats.triangulated;
            const size_t start = faceUV ? fanStart(mesh.uvs, ft) : 0;
            const size_t n = fv.size();
            for (size_t k = 1; k + 1 < n; ++k) {
                const size_t a = start, b = (start + k) % n, c = (start + k + 1) % n;
                if (fv[a] == fv[b] || fv[b] == fv[c] || fv[a] == fv[c]) {
                    ++stats.degenerate;  // zero area: no surface to refine
                    continue;
                }
                mesh.triangles.insert(mesh.triangles.end(), {fv[a], fv[b], fv[c]});
                if (faceUV)
                    mesh.uvIndices.insert(mesh.uvIndices.end(), {ft[a], ft[b], ft[c]});
            }
        }
    }
    if (mesh.positions.empty())
        return Status(StatusCode::InvalidData, path + ": no vertices in the OBJ file");
    if (mesh.triangles.empty())
        return Status(StatusCode::InvalidData, path + ": no faces in the OBJ file");
    if (anyUV && anyNoUV)
        return Status(StatusCode::InvalidData, path + ": some faces have texture coordinates and some do not");
    if (!anyUV)
        mesh.uvs.clear();
    *out = std::move(mesh);
    if (info)
        *info = stats;
    return Status::ok();
}

namespace {

Status writeObj(const std::string& path, const MeshView& m)
{
    std::string out;
    out.reserve(m.vertexCount * 80 + m.faceCount * 40);
    out += "# written by Strata\n";
    char buf[128];
    for (size_t i = 0; i < m.vertexCount; ++i) {
        std::snprintf(buf, sizeof(buf), "v %.9g %.9g %.9g\n", double(m.positions[i].x), double(m.positions[i].y),
                      double(m.positions[i].z));
        out += buf;
    }
    for (size_t i = 0; m.uvs && i < m.uvCount; ++i) {
        std::snprintf(buf, sizeof(buf), "vt %.9g %.9g\n", double(m.uvs[i].x), double(1.0f - m.uvs[i].y));
        out += buf;
    }
    for (size_t i = 0; m.normals && i < m.vertexCount; ++i) {
        std::snprintf(buf, sizeof(buf), "vn %.7g %.7g %.7g\n", double(m.normals[i].x), double(m.normals[i].y),
                      double(m.normals[i].z));
        out += buf;
    }
    for (size_t f = 0; f < m.faceCount; ++f) {
        out += 'f';
        for (int c = 0; c < 3; ++c) {
            const unsigned v = m.triangles[3 * f + size_t(c)] + 1;
            if (m.uvs && m.normals)
                std::snprintf(buf, sizeof(buf), " %u/%u/%u", v, m.uvIndices[3 * f + size_t(c)] + 1, v);
            else if (m.uvs)
                std::snprintf(buf, sizeof(buf), " %u/%u", v, m.uvIndices[3 * f + size_t(c)] + 1);
            else if (m.normals)
                std::snprintf(buf, sizeof(buf), " %u//%u", v, v);
            else
                std::snprintf(buf, sizeof(buf), " %u", v);
            out += buf;
        }
        out += '\n';
    }
    return writeFileAtomic(path, out.data(), out.size());
}

Status writePly(const std::string& path, const MeshView& m)
{
    std::ostringstream header;
    header << "ply\nformat binary_little_endian 1.0\ncomment written by Strata\nelement vertex " << m.vertexCount
           << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (m.normals)
        header << "property float nx\nproperty float ny\nproperty float nz\n";
    header << "element face " << m.faceCount << "\nproperty list uchar uint vertex_indices\nend_header\n";
    std::string out = header.str();
    const size_t vbytes = m.normals ? 24 : 12;
    out.reserve(out.size() + m.vertexCount * vbytes + m.faceCount * 13);
    for (size_t i = 0; i < m.vertexCount; ++i) {
        out.append(reinterpret_cast<const char*>(&m.positions[i]), 12);
        if (m.normals)
            out.append(reinterpret_cast<const char*>(&m.normals[i]), 12);
    }
    for (size_t f = 0; f < m.faceCount; ++f) {
        out += char(3);
        out.append(reinterpret_cast<const char*>(&m.triangles[3 * f]), 12);
    }
    return writeFileAtomic(path, out.data(), out.size());
}

}  // namespace

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
    model.asset.generator = "Strata " STRATA_VERSION;
    model.buffers.resize(1);
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    int view = appendBufferView(model, pos.data(), nv * sizeof(glm::vec3), TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.attributes["POSITION"] = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
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
        tinygltf::Skin skin;
        skin.joints = skeleton->skin.joints;
        view = appendBufferView(model, skeleton->skin.inverseBindMatrices.data(),
                                skeleton->skin.inverseBindMatrices.size() * sizeof(glm::mat4), -1);
        model.bufferViews.back().target = 0;
        skin.inverseBindMatrices = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_MAT4,
                                                  skeleton->skin.inverseBindMatrices.size());
        model.skins.push_back(skin);
        for (const Animation& a : skeleton->animations) {
            tinygltf::Animation anim;
            anim.name = a.name;
            for (const AnimationChannel& c : a.channels) {
                tinygltf::AnimationSampler sa;
                view = appendBufferView(model, c.times.data(), c.times.size() * 4, -1);
                model.bufferViews.back().target = 0;
                sa.input = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, c.times.size());
                model.accessors.back().minValues = {double(c.times.front())};
                model.accessors.back().maxValues = {double(c.times.back())};
                const int comps = c.path == AnimationPath::Rotation ? 4 : 3;
                view = appendBufferView(model, c.values.data(), c.values.size() * 4, -1);
                model.bufferViews.back().target = 0;
                sa.output = appendAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                           comps == 4 ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3,
                                           c.values.size() / size_t(comps));
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

Status writeMesh(const std::string& path, const MeshView& mesh)
{
    if (!mesh.positions || !mesh.triangles || mesh.vertexCount == 0 || mesh.faceCount == 0)
        return Status(StatusCode::InvalidArgument, path + ": nothing to write (empty mesh)");
    if (mesh.uvs && !mesh.uvIndices)
        return Status(StatusCode::InvalidArgument, path + ": UVs without UV indices");
    const std::string ext = extensionOf(path);
    if (ext == ".obj")
        return writeObj(path, mesh);
    if (ext == ".ply")
        return writePly(path, mesh);
    if (ext == ".glb" || ext == ".gltf")
        return writeGltfMesh(path, mesh, "strata_mesh", nullptr);
    return Status(StatusCode::InvalidArgument, path + ": unknown output format \"" + ext +
                                                   "\" (use .obj, .ply, .glb or .gltf)");
}

}  // namespace io
}  // namespace strata
