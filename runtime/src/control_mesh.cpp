// Validation and topology statistics of control meshes.  Control meshes come
// from files, so everything here assumes hostile input.
#include "strata/control_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

namespace strata {

MeshTopologyStats computeTopologyStats(const uint32_t* triangles, size_t faceCount)
{
    // Undirected edges grouped by their smaller vertex (a counting sort, linear
    // in the corners), then each group's larger vertices sorted in place:
    // groups hold a handful of edges, so this is cheap on million-triangle
    // meshes where sorting 64-bit keys was not.
    MeshTopologyStats s;
    uint32_t maxIndex = 0;
    for (size_t i = 0; i < faceCount * 3; ++i)
        maxIndex = std::max(maxIndex, triangles[i]);
    const size_t groups = faceCount ? size_t(maxIndex) + 1 : 0;
    if (groups > 4 * faceCount + 1024) {
        // Sparse indices (far more vertex numbers than corners): the same
        // counts over the used vertices renumbered densely.
        std::vector<uint32_t> used(triangles, triangles + faceCount * 3), dense(faceCount * 3);
        std::sort(used.begin(), used.end());
        used.erase(std::unique(used.begin(), used.end()), used.end());
        for (size_t i = 0; i < dense.size(); ++i)
            dense[i] = uint32_t(std::lower_bound(used.begin(), used.end(), triangles[i]) - used.begin());
        return computeTopologyStats(dense.data(), faceCount);
    }
    std::vector<uint32_t> start(groups + 1, 0), other(faceCount * 3);
    for (size_t f = 0; f < faceCount; ++f)
        for (int c = 0; c < 3; ++c)
            ++start[std::min(triangles[3 * f + c], triangles[3 * f + (c + 1) % 3]) + 1];
    for (size_t g = 0; g < groups; ++g)
        start[g + 1] += start[g];
    {
        std::vector<uint32_t> fill(start.begin(), start.end() - 1);
        for (size_t f = 0; f < faceCount; ++f)
            for (int c = 0; c < 3; ++c) {
                const uint32_t a = triangles[3 * f + c], b = triangles[3 * f + (c + 1) % 3];
                other[fill[std::min(a, b)]++] = std::max(a, b);
            }
    }
    for (size_t g = 0; g < groups; ++g) {
        uint32_t* begin = other.data() + start[g];
        uint32_t* end = other.data() + start[g + 1];
        std::sort(begin, end);
        for (uint32_t* i = begin; i < end;) {
            uint32_t* j = i;
            while (j < end && *j == *i)
                ++j;
            ++s.edges;
            if (j - i == 1)
                ++s.boundaryEdges;
            else if (j - i > 2)
                ++s.nonManifoldEdges;
            i = j;
        }
    }
    std::vector<bool> used(faceCount ? size_t(maxIndex) + 1 : 0, false);
    for (size_t i = 0; i < faceCount * 3; ++i)
        used[triangles[i]] = true;
    s.vertices = size_t(std::count(used.begin(), used.end(), true));
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
