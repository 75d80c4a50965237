// OBJ: reading (bounded, strict numbers, every index form) and writing.
#include "strata/io/mesh_io.h"

#include "strata/io/file.h"
#include "strata/io/materials.h"
#include "mesh_writers.h"
#include "strata/plane.h"

#include <filesystem>
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
        area += cross2(a, b);
    }
    for (size_t s = 0; s < n; ++s) {
        bool consistent = true;
        for (size_t k = 1; k + 1 < n && consistent; ++k) {
            const glm::dvec2 a(uvs[ft[s]]), b(uvs[ft[(s + k) % n]]), c(uvs[ft[(s + k + 1) % n]]);
            const double t = orient2(a, b, c);
            consistent = t * area > 0.0;
        }
        if (consistent)
            return s;
    }
    return 0;
}

}  // namespace

Status readObj(const std::filesystem::path& pathFile, ControlMesh* out, ObjReadInfo* info)
{
    const std::string path = pathFile.string();
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
    std::vector<glm::vec4> colours;  // as read; -1: none given, alpha -2: none given
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
            // "v x y z r g b [a]": a vertex colour (a fourth number alone is w).
            glm::vec4 colour(1.0f);
            int extra = 0;
            while (extra < 4 && parseFloat(s, &colour[extra]))
                ++extra;
            if (extra >= 3) {
                if (colours.empty())
                    colours.assign(mesh.positions.size(), glm::vec4(-1.0f));  // white, coded below
                colours.resize(mesh.positions.size(), glm::vec4(-1.0f));
                colours.push_back(extra == 3 ? glm::vec4(glm::vec3(colour), -2.0f) : colour);
            }
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
                // One corner index at s (1-based, or negative from the end)
                // into `count` elements named `element`.
                char* end = nullptr;
                auto readIndex = [&](const char* malformed, const char* element, size_t count, uint32_t* index) {
                    const long raw = std::strtol(s, &end, 10);
                    if (end == s)
                        return lineError(path, lineNo, malformed);
                    s = end;
                    if (!resolveIndex(raw, count, index))
                        return lineError(path, lineNo, std::string("face references ") + element + " " +
                                                           std::to_string(raw) + " of " + std::to_string(count));
                    return Status::ok();
                };
                uint32_t v;
                if (Status st = readIndex("malformed face index", "vertex", mesh.positions.size(), &v); !st)
                    return st;
                fv.push_back(v);
                bool hasT = false;
                if (*s == '/') {
                    ++s;
                    if (*s != '/') {
                        uint32_t t;
                        if (Status st = readIndex("malformed texture index", "texture coordinate", mesh.uvs.size(), &t);
                            !st)
                            return st;
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
    if (!colours.empty()) {
        // Coded 0..1, or 0..255 where any value passes 1; sRGB, to linear.
        colours.resize(mesh.positions.size(), glm::vec4(-1.0f));
        float largest = 0.0f;
        for (const glm::vec4& c : colours)
            largest = std::max({largest, c.r, c.g, c.b, c.a});
        const double scale = largest > 1.0f ? 1.0 / 255.0 : 1.0;
        stats.colours.resize(colours.size());
        for (size_t i = 0; i < colours.size(); ++i) {
            const glm::vec4& c = colours[i];
            if (c.r < -0.5f) {
                stats.colours[i] = glm::vec4(1.0f);
                continue;
            }
            const glm::dvec4 coded = glm::clamp(glm::dvec4(c) * scale, 0.0, 1.0);
            stats.colours[i] = glm::vec4(srgbToLinear(glm::dvec4(glm::dvec3(coded), c.a < -1.5f ? 1.0 : coded.a)));
        }
    }
    *out = std::move(mesh);
    if (info)
        *info = stats;
    return Status::ok();
}

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

}  // namespace io
}  // namespace strata
