// PLY (ascii, binary little and big endian), OFF and STL (ascii and binary)
// readers for untrusted files.  Every count is checked against the bytes
// that remain before anything is reserved, every index against the vertex
// count, and every read against the end of the buffer; work is linear in
// the file size.  Nothing is printed: problems come back as one Status.
#include "strata/io/mesh_io.h"

#include "strata/io/file.h"
#include "strata/io/materials.h"
#include "weld.h"

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <cmath>
#include <cstdlib>
#include <cstring>

namespace strata {
namespace io {
namespace {

constexpr size_t kMaxPolygonCorners = 1u << 16;

struct Cursor {
    const unsigned char* p;
    const unsigned char* end;
    size_t left() const { return size_t(end - p); }
};

// ---- text tokens (ascii PLY, OFF, ascii STL) ----

void skipSpace(Cursor& c, bool comments)
{
    while (c.p < c.end) {
        if (*c.p == ' ' || *c.p == '\t' || *c.p == '\r' || *c.p == '\n') {
            ++c.p;
        } else if (comments && *c.p == '#') {
            while (c.p < c.end && *c.p != '\n')
                ++c.p;
        } else {
            break;
        }
    }
}

bool token(Cursor& c, std::string* out, bool comments = false)
{
    skipSpace(c, comments);
    const unsigned char* s = c.p;
    while (c.p < c.end && !std::isspace(*c.p))
        ++c.p;
    if (c.p == s || c.p - s > 64)
        return false;
    out->assign(reinterpret_cast<const char*>(s), size_t(c.p - s));
    return true;
}

bool number(Cursor& c, double* v, bool comments = false)
{
    std::string t;
    if (!token(c, &t, comments))
        return false;
    char* end = nullptr;
    errno = 0;
    *v = std::strtod(t.c_str(), &end);
    return end && *end == 0 && errno != ERANGE && std::isfinite(*v);
}

bool integer(Cursor& c, long* v, bool comments = false)
{
    std::string t;
    if (!token(c, &t, comments))
        return false;
    char* end = nullptr;
    errno = 0;
    *v = std::strtol(t.c_str(), &end, 10);
    return end && *end == 0 && errno != ERANGE;
}

Status fail(const std::string& path, const std::string& what)
{
    return Status(StatusCode::InvalidData, path + ": " + what);
}

// Appends a polygon's fan triangulation; checks the indices.
Status addPolygon(const std::string& path, const std::vector<long>& idx, size_t vertexCount, size_t face,
                  PolygonMesh* out)
{
    if (idx.size() < 3)
        return fail(path, "face " + std::to_string(face) + " has fewer than 3 corners");
    for (long i : idx)
        if (i < 0 || size_t(i) >= vertexCount)
            return fail(path, "face " + std::to_string(face) + " references vertex " + std::to_string(i) + " of " +
                                  std::to_string(vertexCount));
    out->polygonsTriangulated += idx.size() > 3;
    for (size_t k = 1; k + 1 < idx.size(); ++k) {
        out->triangles.push_back(uint32_t(idx[0]));
        out->triangles.push_back(uint32_t(idx[k]));
        out->triangles.push_back(uint32_t(idx[k + 1]));
    }
    return Status::ok();
}

// ---- PLY ----

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64, None };

PlyType plyType(const std::string& t)
{
    if (t == "char" || t == "int8")
        return PlyType::Int8;
    if (t == "uchar" || t == "uint8")
        return PlyType::UInt8;
    if (t == "short" || t == "int16")
        return PlyType::Int16;
    if (t == "ushort" || t == "uint16")
        return PlyType::UInt16;
    if (t == "int" || t == "int32")
        return PlyType::Int32;
    if (t == "uint" || t == "uint32")
        return PlyType::UInt32;
    if (t == "float" || t == "float32")
        return PlyType::Float32;
    if (t == "double" || t == "float64")
        return PlyType::Float64;
    return PlyType::None;
}

size_t plySize(PlyType t)
{
    switch (t) {
    case PlyType::Int8:
    case PlyType::UInt8: return 1;
    case PlyType::Int16:
    case PlyType::UInt16: return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
    default: return 0;
    }
}

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::None;
    PlyType countType = PlyType::None;  // lists only
};

struct PlyElement {
    std::string name;
    size_t count = 0;
    std::vector<PlyProperty> properties;
};

// One binary value, or false at the end of the data.
bool binaryValue(Cursor& c, PlyType t, bool bigEndian, double* v)
{
    const size_t n = plySize(t);
    if (c.left() < n)
        return false;
    unsigned char b[8];
    std::memcpy(b, c.p, n);
    c.p += n;
    if (bigEndian)
        for (size_t i = 0; i < n / 2; ++i)
            std::swap(b[i], b[n - 1 - i]);
    switch (t) {
    case PlyType::Int8: *v = double(int8_t(b[0])); break;
    case PlyType::UInt8: *v = double(b[0]); break;
    case PlyType::Int16: { int16_t x; std::memcpy(&x, b, 2); *v = x; break; }
    case PlyType::UInt16: { uint16_t x; std::memcpy(&x, b, 2); *v = x; break; }
    case PlyType::Int32: { int32_t x; std::memcpy(&x, b, 4); *v = x; break; }
    case PlyType::UInt32: { uint32_t x; std::memcpy(&x, b, 4); *v = x; break; }
    case PlyType::Float32: { float x; std::memcpy(&x, b, 4); *v = x; break; }
    case PlyType::Float64: { double x; std::memcpy(&x, b, 8); *v = x; break; }
    default: return false;
    }
    return true;
}

// Whether a face property is the vertex index list (both spellings in use).
bool isIndexList(const std::string& name)
{
    return name == "vertex_indices" || name == "vertex_index";
}

bool littleEndianHost()
{
    const uint16_t one = 1;
    unsigned char b;
    std::memcpy(&b, &one, 1);
    return b == 1;
}

// The layout nearly every binary scan uses, read without per-value dispatch:
// a vertex element of fixed-size scalars with float32 x, y, z, and a face
// element whose only property is its index list with 32-bit indices.  False
// when the element is not of that layout (the general reader takes it);
// errors otherwise carry the general reader's messages.
bool readPlyFast(const std::string& path, const PlyElement& e, bool isVertex, const int xyz[3], size_t nv, Cursor& c,
                 PolygonMesh* out, Status* st)
{
    if (!littleEndianHost())
        return false;
    if (isVertex) {
        size_t stride = 0, offset[3] = {0, 0, 0};
        for (size_t k = 0; k < e.properties.size(); ++k) {
            const PlyProperty& p = e.properties[k];
            if (p.countType != PlyType::None)
                return false;
            for (int a = 0; a < 3; ++a)
                if (int(k) == xyz[a]) {
                    if (p.type != PlyType::Float32)
                        return false;
                    offset[a] = stride;
                }
            stride += plySize(p.type);
        }
        // The element's size was checked against the file by the caller.
        for (size_t i = 0; i < e.count; ++i, c.p += stride) {
            glm::vec3 f;
            for (int a = 0; a < 3; ++a)
                std::memcpy(&f[a], c.p + offset[a], 4);
            if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.z)) {
                *st = fail(path, "vertex " + std::to_string(i) + " is not finite");
                return true;
            }
            out->positions.push_back(f);
        }
        return true;
    }
    if (e.properties.size() != 1)
        return false;
    const PlyProperty& p = e.properties[0];
    if (!isIndexList(p.name) || (p.countType != PlyType::UInt8 && p.countType != PlyType::Int8) ||
        (p.type != PlyType::Int32 && p.type != PlyType::UInt32))
        return false;
    std::vector<long> idx;
    for (size_t i = 0; i < e.count; ++i) {
        if (c.left() < 1) {
            *st = fail(path, "PLY " + e.name + " " + std::to_string(i) + " is truncated or malformed");
            return true;
        }
        const long count = p.countType == PlyType::UInt8 ? long(*c.p) : long(int8_t(*c.p));
        ++c.p;
        if (count < 0 || size_t(count) > c.left() / 4) {
            *st = fail(path, "PLY " + e.name + " " + std::to_string(i) + " has a list of " + std::to_string(count) +
                                 " entries");
            return true;
        }
        uint32_t v[3];
        if (count == 3) {
            std::memcpy(v, c.p, 12);
            c.p += 12;
            const bool inRange = p.type == PlyType::UInt32 ? v[0] < nv && v[1] < nv && v[2] < nv
                                                           : int32_t(v[0]) >= 0 && int32_t(v[1]) >= 0 &&
                                                                 int32_t(v[2]) >= 0 && v[0] < nv && v[1] < nv && v[2] < nv;
            if (inRange) {
                out->triangles.insert(out->triangles.end(), v, v + 3);
                continue;
            }
            c.p -= 12;  // let the general path name the bad index
        }
        idx.resize(size_t(count));
        for (long j = 0; j < count; ++j) {
            uint32_t u;
            std::memcpy(&u, c.p, 4);
            c.p += 4;
            idx[size_t(j)] = p.type == PlyType::Int32 ? long(int32_t(u)) : long(u);
        }
        if (!(*st = addPolygon(path, idx, nv, i, out)))
            return true;
    }
    return true;
}

Status readPly(const std::string& path, const std::vector<unsigned char>& bytes, PolygonMesh* out)
{
    Cursor c{bytes.data(), bytes.data() + bytes.size()};
    // Header: lines up to end_header, at most 64 KiB.
    const size_t headerLimit = std::min<size_t>(bytes.size(), 65536);
    const std::string head(reinterpret_cast<const char*>(bytes.data()), headerLimit);
    const size_t endHeader = head.find("end_header");
    if (head.compare(0, 3, "ply") != 0 || endHeader == std::string::npos)
        return fail(path, "not a PLY file (no \"ply\" ... \"end_header\" header in the first 64 KiB)");
    size_t dataStart = head.find('\n', endHeader);
    if (dataStart == std::string::npos)
        return fail(path, "the PLY header does not end with a newline");
    ++dataStart;
    int format = -1;  // 0 ascii, 1 little, 2 big
    std::vector<PlyElement> elements;
    size_t pos = head.find('\n') + 1;
    while (pos < endHeader) {
        size_t eol = head.find('\n', pos);
        std::string line = head.substr(pos, eol - pos);
        pos = eol + 1;
        if (!line.empty() && line.back() == '\r')
            line.pop_back();
        Cursor lc{reinterpret_cast<const unsigned char*>(line.data()),
                  reinterpret_cast<const unsigned char*>(line.data()) + line.size()};
        std::string word;
        if (!token(lc, &word) || word == "comment" || word == "obj_info")
            continue;
        if (word == "format") {
            std::string f, version;
            token(lc, &f);
            token(lc, &version);
            format = f == "ascii" ? 0 : f == "binary_little_endian" ? 1 : f == "binary_big_endian" ? 2 : -1;
            if (format < 0 || version != "1.0")
                return fail(path, "unsupported PLY format line");
        } else if (word == "element") {
            PlyElement e;
            long count = 0;
            if (!token(lc, &e.name) || !integer(lc, &count) || count < 0)
                return fail(path, "malformed PLY element line");
            // Every element takes at least one byte: more than the file holds is a lie.
            if (size_t(count) > bytes.size())
                return fail(path, "PLY element \"" + e.name + "\" declares " + std::to_string(count) +
                                      " entries, more than the file's " + std::to_string(bytes.size()) + " bytes");
            e.count = size_t(count);
            elements.push_back(e);
        } else if (word == "property") {
            if (elements.empty())
                return fail(path, "PLY property before any element");
            PlyProperty p;
            std::string t;
            if (!token(lc, &t))
                return fail(path, "malformed PLY property line");
            if (t == "list") {
                std::string ct, it;
                if (!token(lc, &ct) || !token(lc, &it) || !token(lc, &p.name))
                    return fail(path, "malformed PLY list property");
                p.countType = plyType(ct);
                p.type = plyType(it);
                if (p.countType == PlyType::None || p.type == PlyType::None || p.countType == PlyType::Float32 ||
                    p.countType == PlyType::Float64)
                    return fail(path, "unsupported PLY list types");
            } else {
                p.type = plyType(t);
                if (p.type == PlyType::None || !token(lc, &p.name))
                    return fail(path, "unsupported PLY property type");
            }
            elements.back().properties.push_back(p);
        } else {
            return fail(path, "unknown PLY header keyword \"" + word.substr(0, 32) + "\"");
        }
    }
    if (format < 0)
        return fail(path, "the PLY header has no format line");
    const PlyElement* vertexElement = nullptr;
    for (const PlyElement& e : elements)
        if (e.name == "vertex")
            vertexElement = &e;
    if (!vertexElement)
        return fail(path, "the PLY file has no vertex element");
    int xyz[3] = {-1, -1, -1};
    for (size_t k = 0; k < vertexElement->properties.size(); ++k)
        for (int a = 0; a < 3; ++a)
            if (vertexElement->properties[k].name == std::string(1, char('x' + a)) &&
                vertexElement->properties[k].countType == PlyType::None)
                xyz[a] = int(k);
    if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
        return fail(path, "the PLY vertex element has no x, y and z");
    // Vertex colours: red, green and blue (alpha optional), as scanners and
    // MeshLab write them; integers coded over their type's range.
    int rgba[4] = {-1, -1, -1, -1};
    double colourScale[4] = {1.0, 1.0, 1.0, 1.0};
    static const char* const kColourNames[4] = {"red", "green", "blue", "alpha"};
    for (size_t k = 0; k < vertexElement->properties.size(); ++k)
        for (int a = 0; a < 4; ++a) {
            const PlyProperty& prop = vertexElement->properties[k];
            if (prop.countType == PlyType::None &&
                (prop.name == kColourNames[a] || prop.name == std::string("diffuse_") + kColourNames[a])) {
                rgba[a] = int(k);
                colourScale[a] = prop.type == PlyType::UInt8 || prop.type == PlyType::Int8     ? 1.0 / 255.0
                                 : prop.type == PlyType::UInt16 || prop.type == PlyType::Int16 ? 1.0 / 65535.0
                                 : prop.type == PlyType::Float32 || prop.type == PlyType::Float64
                                     ? 1.0
                                     : 1.0 / 4294967295.0;
            }
        }
    const bool coloured = rgba[0] >= 0 && rgba[1] >= 0 && rgba[2] >= 0;
    size_t nv = 0;
    c.p = bytes.data() + dataStart;
    const bool big = format == 2;
    for (const PlyElement& e : elements) {
        if (format != 0) {
            // Fixed-size elements can be checked against the file at once.
            size_t fixed = 0;
            for (const PlyProperty& p : e.properties)
                fixed += p.countType == PlyType::None ? plySize(p.type) : plySize(p.countType);
            if (fixed && e.count > c.left() / fixed)
                return fail(path, "PLY element \"" + e.name + "\" is truncated");
        }
        const bool isVertex = &e == vertexElement, isFace = e.name == "face";
        if (isVertex)
            out->positions.reserve(e.count);
        if (isFace)
            out->triangles.reserve(out->triangles.size() + 3 * std::min(e.count, c.left() / 4));
        if (format == 1 && (isFace || (isVertex && !coloured))) {
            Status st;
            if (readPlyFast(path, e, isVertex, xyz, nv, c, out, &st)) {
                if (!st)
                    return st;
                if (isVertex)
                    nv = out->positions.size();
                continue;
            }
        }
        std::vector<char> wantedList(e.properties.size(), 0);  // the face's index list, decided once
        for (size_t k = 0; k < e.properties.size(); ++k)
            wantedList[k] = isFace && isIndexList(e.properties[k].name);
        std::vector<double> values;
        std::vector<long> idx;
        if (isVertex && coloured)
            out->colours.reserve(e.count);
        for (size_t i = 0; i < e.count; ++i) {
            glm::dvec3 p(0.0);
            glm::dvec4 colour(1.0);
            for (size_t k = 0; k < e.properties.size(); ++k) {
                const PlyProperty& prop = e.properties[k];
                if (prop.countType == PlyType::None) {
                    double v = 0.0;
                    const bool ok = format == 0 ? number(c, &v) : binaryValue(c, prop.type, big, &v);
                    if (!ok)
                        return fail(path, "PLY " + e.name + " " + std::to_string(i) + " is truncated or malformed");
                    for (int a = 0; a < 3; ++a)
                        if (isVertex && int(k) == xyz[a])
                            p[a] = v;
                    for (int a = 0; a < 4; ++a)
                        if (isVertex && coloured && int(k) == rgba[a])
                            colour[a] = std::isfinite(v) ? std::clamp(v * colourScale[a], 0.0, 1.0) : 0.0;
                    continue;
                }
                double n = 0.0;
                long count = 0;
                if (format == 0 ? !integer(c, &count) : !binaryValue(c, prop.countType, big, &n))
                    return fail(path, "PLY " + e.name + " " + std::to_string(i) + " is truncated or malformed");
                if (format != 0)
                    count = long(n);
                if (count < 0 || size_t(count) > kMaxPolygonCorners ||
                    (format != 0 && size_t(count) > c.left() / plySize(prop.type)))
                    return fail(path, "PLY " + e.name + " " + std::to_string(i) + " has a list of " +
                                          std::to_string(count) + " entries");
                const bool wanted = wantedList[k] != 0;
                if (wanted)
                    idx.clear();
                for (long j = 0; j < count; ++j) {
                    double v = 0.0;
                    if (format == 0 ? !number(c, &v) : !binaryValue(c, prop.type, big, &v))
                        return fail(path, "PLY " + e.name + " " + std::to_string(i) + " is truncated or malformed");
                    if (wanted)
                        idx.push_back(v >= 0.0 && v < 4294967296.0 && v == std::floor(v) ? long(v) : -1);
                }
                if (wanted) {
                    Status st = addPolygon(path, idx, nv, i, out);
                    if (!st)
                        return st;
                }
            }
            if (isVertex) {
                const glm::vec3 f(p);
                if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.z))
                    return fail(path, "vertex " + std::to_string(i) + " is not finite");
                out->positions.push_back(f);
                if (coloured)
                    out->colours.emplace_back(srgbToLinear(colour));
            }
        }
        if (isVertex)
            nv = out->positions.size();
    }
    return Status::ok();
}

// ---- OFF ----

Status readOff(const std::string& path, const std::vector<unsigned char>& bytes, PolygonMesh* out)
{
    Cursor c{bytes.data(), bytes.data() + bytes.size()};
    std::string magic;
    if (!token(c, &magic, true) || magic.size() < 3 || magic.compare(magic.size() - 3, 3, "OFF") != 0)
        return fail(path, "not an OFF file (it must start with OFF)");
    if (magic != "OFF")
        return fail(path, "OFF variant \"" + magic.substr(0, 16) + "\" is not supported (plain OFF is)");
    long nv = 0, nf = 0, ne = 0;
    if (!integer(c, &nv, true) || !integer(c, &nf, true) || !integer(c, &ne, true) || nv < 0 || nf < 0)
        return fail(path, "the OFF counts line is malformed");
    // Each vertex needs at least 6 bytes ("0 0 0\n"), each face 8.
    if (size_t(nv) > c.left() / 6 || size_t(nf) > c.left() / 8)
        return fail(path, "the OFF file declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                              " faces, more than its size allows");
    out->positions.reserve(size_t(nv));
    for (long i = 0; i < nv; ++i) {
        double x, y, z;
        if (!number(c, &x, true) || !number(c, &y, true) || !number(c, &z, true))
            return fail(path, "OFF vertex " + std::to_string(i) + " is not three finite numbers");
        const glm::vec3 p(glm::dvec3(x, y, z));
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            return fail(path, "OFF vertex " + std::to_string(i) + " is not finite");
        out->positions.push_back(p);
    }
    std::vector<long> idx;
    for (long f = 0; f < nf; ++f) {
        long n = 0;
        if (!integer(c, &n, true) || n < 0 || size_t(n) > kMaxPolygonCorners || size_t(n) > c.left() / 2)
            return fail(path, "OFF face " + std::to_string(f) + " is malformed");
        idx.resize(size_t(n));
        for (long k = 0; k < n; ++k)
            if (!integer(c, &idx[size_t(k)], true))
                return fail(path, "OFF face " + std::to_string(f) + " is malformed");
        Status st = addPolygon(path, idx, size_t(nv), size_t(f), out);
        if (!st)
            return st;
        // Anything after the indices on that line (a colour) is skipped.
        while (c.p < c.end && *c.p != '\n')
            ++c.p;
    }
    return Status::ok();
}

// ---- STL ----

// STL stores three vertices per facet: exact duplicates are welded.
Status readStl(const std::string& path, const std::vector<unsigned char>& bytes, PolygonMesh* out)
{
    std::vector<glm::vec3> corners;
    bool binary = false;
    if (bytes.size() >= 84) {
        uint32_t n = 0;
        std::memcpy(&n, bytes.data() + 80, 4);
        if (size_t(n) <= (bytes.size() - 84) / 50 && bytes.size() == 84 + size_t(n) * 50) {
            binary = true;
            corners.reserve(3 * size_t(n));
            for (size_t f = 0; f < n; ++f) {
                const unsigned char* p = bytes.data() + 84 + f * 50 + 12;
                for (int k = 0; k < 3; ++k) {
                    glm::vec3 v;
                    std::memcpy(&v, p + 12 * k, 12);
                    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
                        return fail(path, "STL facet " + std::to_string(f) + " has a non-finite vertex");
                    corners.push_back(v);
                }
            }
        }
    }
    if (!binary) {
        Cursor c{bytes.data(), bytes.data() + bytes.size()};
        std::string word;
        if (!token(c, &word) || word != "solid")
            return fail(path, "not an STL file (neither a binary STL of consistent size nor ascii \"solid\")");
        while (token(c, &word)) {
            if (word != "vertex")
                continue;
            double x, y, z;
            if (!number(c, &x) || !number(c, &y) || !number(c, &z))
                return fail(path, "STL vertex of facet " + std::to_string(corners.size() / 3) +
                                      " is not three finite numbers");
            const glm::vec3 v(glm::dvec3(x, y, z));
            if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
                return fail(path, "STL facet " + std::to_string(corners.size() / 3) + " has a non-finite vertex");
            corners.push_back(v);
        }
        if (corners.size() % 3 != 0)
            return fail(path, "the last STL facet is incomplete");
    }
    std::vector<uint32_t> ids;
    weldByPosition(corners.data(), corners.size(), &ids, &out->positions);
    out->triangles = std::move(ids);
    return Status::ok();
}

}  // namespace

Status parsePolygonMesh(const unsigned char* data, size_t size, const std::string& format, const std::string& name,
                        PolygonMesh* out)
{
    if (format != ".ply" && format != ".off" && format != ".stl")
        return Status(StatusCode::InvalidArgument, name + ": not a .ply, .off or .stl file");
    if (size == 0)
        return fail(name, "file is empty");
    const std::vector<unsigned char> bytes(data, data + size);
    PolygonMesh mesh;
    Status st = format == ".ply" ? readPly(name, bytes, &mesh) : format == ".off" ? readOff(name, bytes, &mesh)
                                                                                  : readStl(name, bytes, &mesh);
    if (!st)
        return st;
    if (mesh.positions.empty())
        return fail(name, "no vertices");
    if (mesh.triangles.empty())
        return fail(name, "no faces");
    *out = std::move(mesh);
    return Status::ok();
}

Status readPolygonMesh(const std::filesystem::path& pathFile, PolygonMesh* out)
{
    const std::string path = pathFile.string();
    const std::string ext = extensionOf(path);
    if (ext != ".ply" && ext != ".off" && ext != ".stl")
        return Status(StatusCode::InvalidArgument, path + ": not a .ply, .off or .stl file");
    std::vector<unsigned char> bytes;
    Status st = readFile(path, &bytes);
    if (!st)
        return st;
    return parsePolygonMesh(bytes.data(), bytes.size(), ext, path, out);
}

}  // namespace io
}  // namespace strata
