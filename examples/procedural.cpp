#include "procedural.h"

#include "strata/normals.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

namespace strata {
namespace examples {

ControlMesh makeIcosphere(int subdivisions)
{
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    ControlMesh m;
    const glm::vec3 base[12] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (const glm::vec3& v : base)
        m.positions.push_back(glm::normalize(v));
    m.triangles = {0, 11, 5, 0, 5,  1,  0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11, 4,  11, 10, 2,  10, 7,
                   6, 7,  1, 8, 3, 9,  4, 3, 4, 2, 3, 2,  6,  3, 6,  8,  3, 8, 9, 4, 9,  5, 2,  4,  11, 6,
                   2, 10, 8, 6, 7, 9,  8, 1};
    for (int s = 0; s < subdivisions; ++s) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto key = std::make_pair(std::min(a, b), std::max(a, b));
            auto it = mid.find(key);
            if (it != mid.end())
                return it->second;
            m.positions.push_back(glm::normalize(m.positions[a] + m.positions[b]));
            const uint32_t idx = uint32_t(m.positions.size() - 1);
            mid.emplace(key, idx);
            return idx;
        };
        std::vector<uint32_t> next;
        for (size_t f = 0; f < m.triangles.size(); f += 3) {
            const uint32_t a = m.triangles[f], b = m.triangles[f + 1], c = m.triangles[f + 2];
            const uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
            next.insert(next.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
        }
        m.triangles.swap(next);
    }
    return m;
}

ControlMesh makeSquare()
{
    ControlMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    m.triangles = {0, 1, 2, 0, 2, 3};
    m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.uvIndices = m.triangles;
    return m;
}

namespace {

float bump(const glm::vec3& dir, const glm::vec3& centre, float width, float height)
{
    // 2 (1 - cos) is the squared chord, close to the squared angle for the
    // small widths used here and much cheaper than acos.
    const float c = glm::dot(dir, glm::normalize(centre));
    return height * std::exp(-2.0f * (1.0f - c) / (width * width));
}

}  // namespace

ControlMesh makeHead(int subdivisions)
{
    ControlMesh head = makeIcosphere(subdivisions);
    for (glm::vec3& p : head.positions)
        p *= headRadius(p);
    return head;
}

float headRadius(const glm::vec3& d)
{
    // An egg-shaped cranium, longer front-to-back, narrower at the jaw.
    float r = 0.92f + 0.06f * d.y - 0.05f * d.x * d.x + 0.04f * d.z * d.z;
    r += bump(d, {0.0f, 0.05f, 1.0f}, 0.16f, 0.20f);     // nose
    r += bump(d, {0.0f, -0.12f, 1.0f}, 0.10f, 0.05f);    // nose tip underside
    r += bump(d, {0.0f, 0.32f, 1.0f}, 0.35f, 0.05f);     // brow
    r -= bump(d, {0.30f, 0.22f, 1.0f}, 0.12f, 0.07f);    // eye sockets
    r -= bump(d, {-0.30f, 0.22f, 1.0f}, 0.12f, 0.07f);
    r += bump(d, {0.45f, -0.15f, 1.0f}, 0.22f, 0.03f);   // cheeks
    r += bump(d, {-0.45f, -0.15f, 1.0f}, 0.22f, 0.03f);
    r += bump(d, {0.0f, -0.75f, 1.0f}, 0.22f, 0.05f);    // chin
    r -= bump(d, {0.0f, -0.42f, 1.0f}, 0.05f, 0.02f);    // mouth line
    r += bump(d, {1.0f, 0.05f, -0.1f}, 0.14f, 0.12f);    // ears
    r += bump(d, {-1.0f, 0.05f, -0.1f}, 0.14f, 0.12f);
    // Fine detail: ripples over the scalp, the part a control mesh cannot hold.
    const float scalp = std::clamp(d.y + 0.2f - 0.5f * d.z, 0.0f, 1.0f);
    r += 0.012f * scalp * std::sin(40.0f * d.x + 9.0f * d.y) * std::sin(35.0f * d.z);
    return r;
}

namespace {

// Solves |p + d n| = R(unit(p + d n)) for d: bracket by stepping away from
// d = 0 toward the sign change, then bisect.
float solveRadial(const glm::vec3& p, const glm::vec3& n, const RadiusFunction& radius)
{
    auto f = [&](float d) {
        const glm::vec3 x = p + d * n;
        const float len = glm::length(x);
        return len > 0.0f ? len - radius(x / len) : -1.0f;
    };
    // Secant iterations from d = 0 converge in a few steps on these smooth
    // surfaces; the bracketing search below is the fallback.
    {
        float a = 0.0f, b = 0.02f, fa = f(a), fb = f(b);
        for (int k = 0; k < 16 && fb != fa; ++k) {
            const float c = b - fb * (b - a) / (fb - fa);
            a = b;
            fa = fb;
            b = c;
            fb = f(b);
            if (std::fabs(fb) < 1e-7f && std::fabs(b) < 1.0f)
                return b;
        }
    }
    const float f0 = f(0.0f);
    if (f0 == 0.0f)
        return 0.0f;
    const float step = f0 < 0.0f ? 0.01f : -0.01f;
    float a = 0.0f, fa = f0;
    for (int i = 0; i < 400; ++i) {
        const float b = a + step;
        const float fb = f(b);
        if ((fa < 0.0f) != (fb < 0.0f)) {
            float lo = a, hi = b, flo = fa;
            for (int k = 0; k < 30; ++k) {
                const float m = 0.5f * (lo + hi);
                const float fm = f(m);
                if ((fm < 0.0f) == (flo < 0.0f)) {
                    lo = m;
                    flo = fm;
                } else {
                    hi = m;
                }
            }
            return 0.5f * (lo + hi);
        }
        a = b;
        fa = fb;
    }
    return 0.0f;
}

}  // namespace

Status bakeRadialSurface(DisplacementMap* out, const ControlMesh& mesh, int mapSize, int gutter,
                         const RadiusFunction& radius)
{
    Status st = validateControlMesh(mesh);
    if (!st)
        return st;
    if (!mesh.hasUVs())
        return Status(StatusCode::InvalidArgument, "bakeRadialSurface needs a control mesh with UVs");
    if (mapSize < 1 || mapSize > kMaxDisplacementMapSize)
        return Status(StatusCode::InvalidArgument, "map size out of range");
    std::vector<glm::vec3> normals(mesh.positions.size());
    computeControlNormals(normals.data(), mesh.positions.data(), mesh.positions.size(), mesh.triangles.data(),
                          mesh.faceCount());
    DisplacementMap map;
    map.width = map.height = mapSize;
    map.texels.assign(size_t(mapSize) * size_t(mapSize), 0.0f);
    // Texels inside a UV triangle beat gutter texels; among gutter texels
    // the nearest triangle wins.
    std::vector<float> owner(map.texels.size(), 1e30f);
    const float size = float(mapSize);
    for (size_t f = 0; f < mesh.faceCount(); ++f) {
        glm::vec2 t[3];
        glm::vec3 P[3], N[3];
        for (int k = 0; k < 3; ++k) {
            t[k] = mesh.uvs[mesh.uvIndices[3 * f + size_t(k)]] * size;  // texel space
            P[k] = mesh.positions[mesh.triangles[3 * f + size_t(k)]];
            N[k] = normals[mesh.triangles[3 * f + size_t(k)]];
        }
        const glm::vec2 e1 = t[1] - t[0], e2 = t[2] - t[0];
        const float det = e1.x * e2.y - e1.y * e2.x;
        if (std::fabs(det) < 1e-12f)
            continue;
        const float g = float(gutter);
        const int x0 = std::max(0, int(std::floor(std::min({t[0].x, t[1].x, t[2].x}) - g)));
        const int x1 = std::min(mapSize - 1, int(std::ceil(std::max({t[0].x, t[1].x, t[2].x}) + g)));
        const int y0 = std::max(0, int(std::floor(std::min({t[0].y, t[1].y, t[2].y}) - g)));
        const int y1 = std::min(mapSize - 1, int(std::ceil(std::max({t[0].y, t[1].y, t[2].y}) + g)));
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const glm::vec2 c(float(x) + 0.5f, float(y) + 0.5f);
                const glm::vec2 r = c - t[0];
                float b1 = (r.x * e2.y - r.y * e2.x) / det;
                float b2 = (e1.x * r.y - e1.y * r.x) / det;
                float b0 = 1.0f - b1 - b2;
                // Gutter texels (outside the UV triangle) are evaluated on the
                // plane extension of eq. 2 with negative barycentrics, so
                // bilinear samples at chart borders stay second-order accurate;
                // the clamped point only measures how far outside they are.
                float outside = 0.0f;
                if (b0 < 0.0f || b1 < 0.0f || b2 < 0.0f) {
                    float c0 = std::max(b0, 0.0f), c1 = std::max(b1, 0.0f), c2 = std::max(b2, 0.0f);
                    const float s = c0 + c1 + c2;
                    outside = glm::length((c0 * t[0] + c1 * t[1] + c2 * t[2]) / s - c);
                    if (outside > g * 1.5f)
                        continue;
                }
                const size_t i = size_t(y) * size_t(mapSize) + size_t(x);
                if (outside >= owner[i])
                    continue;
                owner[i] = outside;
                const glm::vec3 p = b0 * P[0] + b1 * P[1] + b2 * P[2];
                const glm::vec3 n = b0 * N[0] + b1 * N[1] + b2 * N[2];
                map.texels[i] = solveRadial(p, n, radius);
            }
    }
    *out = std::move(map);
    return Status::ok();
}

}  // namespace examples
}  // namespace strata
