// Validation and topology statistics of control meshes.  Control meshes come
// from files, so everything here assumes hostile input.
#include "strata/control_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

namespace strata {

EdgeGroups groupEdges(const uint32_t* triangles, size_t faceCount)
{
    EdgeGroups out;
    const size_t nc = 3 * faceCount;
    uint32_t maxIndex = 0;
    for (size_t i = 0; i < nc; ++i)
        maxIndex = std::max(maxIndex, triangles[i]);
    auto lower = [&](size_t c) {
        const size_t f = c / 3, k = c % 3;
        return std::min(triangles[3 * f + k], triangles[3 * f + (k + 1) % 3]);
    };
    auto higher = [&](size_t c) {
        const size_t f = c / 3, k = c % 3;
        return std::max(triangles[3 * f + k], triangles[3 * f + (k + 1) % 3]);
    };
    out.corners.resize(nc);
    if (nc > 0 && size_t(maxIndex) + 1 > 4 * nc + 1024) {
        // Sparse vertex numbers (far more than corners): one sort of the keys.
        std::vector<std::pair<uint64_t, uint32_t>> keys(nc);
        for (size_t c = 0; c < nc; ++c)
            keys[c] = {uint64_t(lower(c)) << 32 | higher(c), uint32_t(c)};
        std::sort(keys.begin(), keys.end());
        for (size_t c = 0; c < nc; ++c)
            out.corners[c] = keys[c].second;
    } else if (nc > 0) {
        // Corners grouped by their edge's lower vertex (a counting sort,
        // linear in the corners), then each group's few corners sorted by
        // the higher vertex: cheap on million-triangle meshes where sorting
        // 64-bit keys was not.
        std::vector<uint32_t> start(size_t(maxIndex) + 2, 0);
        for (size_t c = 0; c < nc; ++c)
            ++start[size_t(lower(c)) + 1];
        for (size_t g = 0; g + 1 < start.size(); ++g)
            start[g + 1] += start[g];
        std::vector<uint32_t> fill(start.begin(), start.end() - 1);
        for (size_t c = 0; c < nc; ++c)
            out.corners[fill[lower(c)]++] = uint32_t(c);
        for (size_t g = 0; g + 1 < start.size(); ++g)
            std::sort(out.corners.begin() + start[g], out.corners.begin() + start[g + 1],
                      [&](uint32_t x, uint32_t y) { return std::make_pair(higher(x), x) < std::make_pair(higher(y), y); });
    }
    out.offsets.reserve(nc / 2 + 2);
    for (size_t i = 0; i < nc;) {
        out.offsets.push_back(uint32_t(i));
        size_t j = i + 1;
        while (j < nc && lower(out.corners[j]) == lower(out.corners[i]) &&
               higher(out.corners[j]) == higher(out.corners[i]))
            ++j;
        i = j;
    }
    out.offsets.push_back(uint32_t(nc));
    return out;
}

MeshTopologyStats computeTopologyStats(const uint32_t* triangles, size_t faceCount)
{
    MeshTopologyStats s;
    const EdgeGroups edges = groupEdges(triangles, faceCount);
    s.edges = edges.edgeCount();
    for (size_t e = 0; e < s.edges; ++e) {
        const uint32_t n = edges.faceCountOf(e);
        s.boundaryEdges += n == 1;
        s.nonManifoldEdges += n > 2;
    }
    uint32_t maxIndex = 0;
    for (size_t i = 0; i < faceCount * 3; ++i)
        maxIndex = std::max(maxIndex, triangles[i]);
    if (size_t(maxIndex) + 1 <= 4 * faceCount * 3 + 1024) {
        std::vector<bool> used(faceCount ? size_t(maxIndex) + 1 : 0, false);
        for (size_t i = 0; i < faceCount * 3; ++i)
            used[triangles[i]] = true;
        s.vertices = size_t(std::count(used.begin(), used.end(), true));
    } else {  // sparse vertex numbers
        std::vector<uint32_t> used(triangles, triangles + faceCount * 3);
        std::sort(used.begin(), used.end());
        s.vertices = size_t(std::unique(used.begin(), used.end()) - used.begin());
    }
    s.eulerCharacteristic = long(s.vertices) - long(s.edges) + long(faceCount);
    return s;
}

Status validateControlMesh(const ControlMesh& mesh)
{
    const size_t nv = mesh.positions.size();
    if (mesh.triangles.empty())
        return Status(StatusCode::InvalidData, "control mesh has no faces");
    if (mesh.triangles.size() % 3 != 0)
        return Status(StatusCode::InvalidData, "control mesh index count " + std::to_string(mesh.triangles.size()) +
                                                   " is not a multiple of 3");
    if (nv >= 0xffffffffu)
        return Status(StatusCode::InvalidData, "control mesh has too many vertices");
    for (size_t i = 0; i < nv; ++i) {
        const glm::vec3& p = mesh.positions[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            return Status(StatusCode::InvalidData, "control vertex " + std::to_string(i) + " has a non-finite position");
    }
    const size_t nf = mesh.faceCount();
    for (size_t f = 0; f < nf; ++f) {
        const uint32_t a = mesh.triangles[3 * f], b = mesh.triangles[3 * f + 1], c = mesh.triangles[3 * f + 2];
        if (a >= nv || b >= nv || c >= nv)
            return Status(StatusCode::InvalidData, "control face " + std::to_string(f) + " references a vertex beyond the " +
                                                       std::to_string(nv) + " vertices");
        if (a == b || b == c || a == c)
            return Status(StatusCode::InvalidData, "control face " + std::to_string(f) + " repeats a vertex (" +
                                                       std::to_string(a) + ", " + std::to_string(b) + ", " +
                                                       std::to_string(c) + ")");
    }
    if (!mesh.uvIndices.empty()) {
        if (mesh.uvIndices.size() != mesh.triangles.size())
            return Status(StatusCode::InvalidData, "control mesh has " + std::to_string(mesh.uvIndices.size()) +
                                                       " UV indices for " + std::to_string(mesh.triangles.size()) +
                                                       " corners");
        for (size_t i = 0; i < mesh.uvIndices.size(); ++i)
            if (mesh.uvIndices[i] >= mesh.uvs.size())
                return Status(StatusCode::InvalidData, "control face " + std::to_string(i / 3) +
                                                           " references a UV beyond the " +
                                                           std::to_string(mesh.uvs.size()) + " UVs");
        for (size_t i = 0; i < mesh.uvs.size(); ++i)
            if (!std::isfinite(mesh.uvs[i].x) || !std::isfinite(mesh.uvs[i].y))
                return Status(StatusCode::InvalidData, "control UV " + std::to_string(i) + " is not finite");
    }

    return Status::ok();
}

namespace {

constexpr uint64_t kFnvOffset = 0xcbf29ce484222325ull, kFnvPrime = 0x100000001b3ull;

uint64_t fnv(uint64_t h, uint32_t word)
{
    for (int k = 0; k < 4; ++k) {
        h ^= (word >> (8 * k)) & 0xffu;
        h *= kFnvPrime;
    }
    return h;
}

uint32_t floatBits(float v)
{
    uint32_t b;
    std::memcpy(&b, &v, 4);
    return b == 0x80000000u ? 0u : b;  // -0 reads as +0, as the loaders weld it
}

// splitmix64's finaliser: spreads a position's bits over the word.
uint64_t mix(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

}  // namespace

uint64_t controlTopologyHash(const uint32_t* triangles, size_t faceCount, size_t vertexCount)
{
    uint64_t h = fnv(fnv(kFnvOffset, uint32_t(vertexCount)), uint32_t(uint64_t(vertexCount) >> 32));
    for (size_t i = 0; i < 3 * faceCount; ++i)
        h = fnv(h, triangles[i]);
    return h;
}

ControlMeshFingerprint fingerprintControlMesh(const ControlMesh& mesh)
{
    ControlMeshFingerprint f;
    f.vertices = mesh.vertexCount();
    f.faces = mesh.faceCount();
    f.topology = controlTopologyHash(mesh.triangles.data(), f.faces, f.vertices);
    std::vector<uint64_t> vertexHash(f.vertices);
    uint64_t h = kFnvOffset;
    for (size_t v = 0; v < f.vertices; ++v) {
        const uint32_t x = floatBits(mesh.positions[v].x), y = floatBits(mesh.positions[v].y),
                       z = floatBits(mesh.positions[v].z);
        h = fnv(fnv(fnv(h, x), y), z);
        vertexHash[v] = mix(mix(mix(uint64_t(x)) ^ y) ^ z);
    }
    f.positions = h;
    uint64_t shape = 0;
    for (size_t t = 0; t < f.faces; ++t) {
        uint64_t c[3];
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = mesh.triangles[3 * t + size_t(k)];
            c[k] = v < f.vertices ? vertexHash[v] : 0;
        }
        const int first = c[0] <= c[1] && c[0] <= c[2] ? 0 : (c[1] <= c[2] ? 1 : 2);
        shape += mix(mix(mix(c[first]) ^ c[(first + 1) % 3]) ^ c[(first + 2) % 3]);
    }
    f.shape = shape;
    return f;
}

}  // namespace strata
