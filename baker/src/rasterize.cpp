// Forward mapping (paper 3.2): each high-resolution triangle is drawn into
// the texture plane through the normal-volume mapping of its vertices.
#include "rasterize.h"
#include "parallel.h"
#include "strata/plane.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace strata {
namespace baker {
namespace {

// Paper eq. 5: the distance at a texel centre inside a UV triangle, the
// linear interpolation of its three vertices' distances, from the texel's
// unnormalised barycentric weights (sub-triangle areas) and the triangle's
// area.
double interpolateDistance(const double weights[3], const float distances[3], double area)
{
    return (weights[0] * distances[0] + weights[1] * distances[1] + weights[2] * distances[2]) / area;
}

// One high-res triangle as seen by one bake-surface triangle: texel-space
// corners and the eq. 2 distances of its vertices.
struct Piece {
    uint32_t face;
    glm::vec2 t[3];
    float d[3];
    int x0, x1, y0, y1;  // texels that can lie in both the piece and its control UV triangle
};

// The texel range a piece can cover inside its control triangle `ct`
// (texel units); false when it is empty.
bool clipRange(Piece* p, const glm::vec2 ct[3], int size)
{
    const float minY = std::max(std::min({p->t[0].y, p->t[1].y, p->t[2].y}), std::min({ct[0].y, ct[1].y, ct[2].y}));
    const float maxY = std::min(std::max({p->t[0].y, p->t[1].y, p->t[2].y}), std::max({ct[0].y, ct[1].y, ct[2].y}));
    const float minX = std::max(std::min({p->t[0].x, p->t[1].x, p->t[2].x}), std::min({ct[0].x, ct[1].x, ct[2].x}));
    const float maxX = std::min(std::max({p->t[0].x, p->t[1].x, p->t[2].x}), std::max({ct[0].x, ct[1].x, ct[2].x}));
    p->y0 = std::max(0, int(std::floor(minY - 0.5f)));
    p->y1 = std::min(size - 1, int(std::ceil(maxY - 0.5f)));
    p->x0 = std::max(0, int(std::floor(minX - 0.5f)));
    p->x1 = std::min(size - 1, int(std::ceil(maxX - 0.5f)));
    return p->y0 <= p->y1 && p->x0 <= p->x1;
}

// Edge function with exact antisymmetry: the edge is evaluated from its
// lexicographically smaller endpoint, so E(a, b, p) == -E(b, a, p) bit for bit
// and a texel centre on a shared edge is claimed by exactly one side.
inline double edgeFunction(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& p, bool* owns)
{
    const bool swap = (b.x < a.x) || (b.x == a.x && b.y < a.y);
    const glm::dvec2& s = swap ? b : a;
    const glm::dvec2& e = swap ? a : b;
    const double v = orient2(s, e, p);
    // Ownership of points exactly on the edge, a property of the directed edge.
    const double dx = b.x - a.x, dy = b.y - a.y;
    *owns = dy > 0.0 || (dy == 0.0 && dx < 0.0);
    return swap ? -v : v;
}

struct Triangle2 {
    glm::dvec2 p[3];
    double area;  // positive after orientation fix
    bool flipped;
};

inline Triangle2 makeTriangle(const glm::vec2 t[3])
{
    Triangle2 tr;
    for (int k = 0; k < 3; ++k)
        tr.p[k] = glm::dvec2(t[k]);
    bool owns;
    tr.area = edgeFunction(tr.p[0], tr.p[1], tr.p[2], &owns);
    tr.flipped = tr.area < 0.0;
    if (tr.flipped) {
        std::swap(tr.p[1], tr.p[2]);
        tr.area = -tr.area;
    }
    return tr;
}

// Inside test with the fill rule; on success w[k] are the (unnormalised)
// weights of the corners in the triangle's original order.
inline bool inside(const Triangle2& t, const glm::dvec2& c, double w[3])
{
    bool own0, own1, own2;
    const double e0 = edgeFunction(t.p[1], t.p[2], c, &own0);  // weight of p0
    const double e1 = edgeFunction(t.p[2], t.p[0], c, &own1);  // weight of p1
    const double e2 = edgeFunction(t.p[0], t.p[1], c, &own2);  // weight of p2
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0)
        return false;
    if ((e0 == 0.0 && !own0) || (e1 == 0.0 && !own1) || (e2 == 0.0 && !own2))
        return false;
    w[0] = e0;
    w[1] = t.flipped ? e2 : e1;
    w[2] = t.flipped ? e1 : e2;
    return true;
}

glm::vec2 texelUV(const BakeSurface& s, uint32_t face, double b1, double b2, double size)
{
    const glm::dvec2 u0(s.uvs[s.uvIndices[3 * size_t(face)]]), u1(s.uvs[s.uvIndices[3 * size_t(face) + 1]]),
        u2(s.uvs[s.uvIndices[3 * size_t(face) + 2]]);
    return glm::vec2(((1.0 - b1 - b2) * u0 + b1 * u1 + b2 * u2) * size);  // eq. 3, in texel units
}

// Whether high-res triangle tri passes close to control vertex v: closer than
// its longest edge plus the largest |d| of its vertices (both bound how far
// the triangle's image can reach across the vertex's faces).
bool nearControlVertex(const BakeSurface& s, uint32_t v, const glm::vec3* pos, const uint32_t* tri,
                       const VertexMapping* const m[3])
{
    const glm::dvec3 a(pos[tri[0]]), b(pos[tri[1]]), c(pos[tri[2]]);
    const double edge = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
    const double reach = edge + std::max({std::fabs(double(m[0]->d)), std::fabs(double(m[1]->d)),
                                          std::fabs(double(m[2]->d))});
    double u, w;
    const glm::dvec3 p = closestPointOnTriangle(glm::dvec3(s.positions[v]), a, b, c, &u, &w);
    return glm::length(p - glm::dvec3(s.positions[v])) <= reach;
}

// The pieces of one high-res triangle (paper 3.2.2).
void triangulatePieces(const SurfaceIndex& index, const glm::vec3* pos, const uint32_t* tri,
                       const std::vector<VertexMapping>& mapping, double size, std::vector<Piece>* out,
                       RasterStats* stats)
{
    const BakeSurface& s = index.surface();
    const VertexMapping* m[3] = {&mapping[tri[0]], &mapping[tri[1]], &mapping[tri[2]]};
    if (m[0]->face == m[1]->face && m[1]->face == m[2]->face) {
        Piece p;
        p.face = m[0]->face;
        for (int k = 0; k < 3; ++k) {
            p.t[k] = texelUV(s, p.face, m[k]->b1, m[k]->b2, size);
            p.d[k] = m[k]->d;
        }
        out->push_back(p);
        return;
    }
    ++stats->borderTriangles;
    // Candidate control triangles: the vertices' own, plus the triangles
    // around shared vertices where two of them are not edge-adjacent.
    uint32_t cand[64];
    int nc = 0;
    auto add = [&](uint32_t f) {
        for (int i = 0; i < nc; ++i)
            if (cand[i] == f)
                return;
        if (nc < 64)
            cand[nc++] = f;
    };
    for (int k = 0; k < 3; ++k)
        add(m[k]->face);
    // The triangle's interior can cross triangles none of its vertices map
    // to: the ones around the control vertices its vertices' triangles
    // share.  Triangles with nothing in common: step through both rings.
    auto addRing = [&](uint32_t v) {
        for (uint32_t r = s.ringOffsets[v]; r < s.ringOffsets[v + 1]; ++r)
            add(s.ringFaces[r]);
    };
    for (int a = 0; a < 3; ++a)
        for (int b = a + 1; b < 3; ++b) {
            const uint32_t fa = m[a]->face, fb = m[b]->face;
            if (fa == fb)
                continue;
            bool sharedVertex = false;
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    if (s.triangles[3 * size_t(fa) + i] == s.triangles[3 * size_t(fb) + j]) {
                        sharedVertex = true;
                        // Only a triangle that comes near the shared control
                        // vertex can reach the faces around it.
                        const uint32_t v = s.triangles[3 * size_t(fa) + i];
                        if (nearControlVertex(s, v, pos, tri, m))
                            addRing(v);
                    }
            if (!sharedVertex)
                for (uint32_t f : {fa, fb})
                    for (int i = 0; i < 3; ++i)
                        addRing(s.triangles[3 * size_t(f) + i]);
        }
    for (int c = 0; c < nc; ++c) {
        Piece p;
        p.face = cand[c];
        const NormalVolumeTriangle nv = index.triangle(p.face);
        const NormalVolumeCubic& cubic = index.cubic(p.face);
        bool ok = true;
        for (int k = 0; k < 3 && ok; ++k) {
            double b1 = m[k]->b1, b2 = m[k]->b2, d = m[k]->d;
            if (m[k]->face != p.face) {
                NormalVolumeHit hit;
                ok = mapToNormalVolumePlane(nv, cubic, glm::dvec3(pos[tri[k]]), d, index.searchDistance() + 1e-9,
                                            &hit);
                b1 = hit.b1;
                b2 = hit.b2;
                d = hit.d;
            }
            p.t[k] = texelUV(s, p.face, b1, b2, size);
            p.d[k] = float(d);
        }
        if (ok)
            out->push_back(p);
    }
}

}  // namespace

void rasterize(RasterResult* out, const SurfaceIndex& index, const glm::vec3* highPositions,
               const uint32_t* highTriangles, size_t highFaceCount, const std::vector<VertexMapping>& mapping,
               int size, OverlapPolicy policy, int threads)
{
    const BakeSurface& s = index.surface();
    threads = std::max(1, threads);
    RasterResult r;
    r.size = size;
    r.distance.assign(size_t(size) * size_t(size), 0.0f);
    r.layers.assign(size_t(size) * size_t(size), 0);

    // 1. Pieces, built in parallel per contiguous triangle range, each
    //    clipped to its control triangle's texel box and filed under the row
    //    bands (one per thread) it reaches.
    const size_t bands = size_t(threads), bandRows = (size_t(size) + bands - 1) / bands;
    std::vector<std::vector<std::vector<Piece>>> binned(bands, std::vector<std::vector<Piece>>(bands));
    std::vector<RasterStats> chunkStats(bands);
    std::vector<size_t> chunkPieces(bands, 0);
    parallelChunks(highFaceCount, threads, [&](int t, size_t b, size_t e) {
        std::vector<Piece> pieces;
        std::vector<std::vector<Piece>>& filed = binned[size_t(t)];
        for (size_t f = b; f < e; ++f) {
            const uint32_t* tri = &highTriangles[3 * f];
            const glm::vec3 n = glm::cross(highPositions[tri[1]] - highPositions[tri[0]],
                                           highPositions[tri[2]] - highPositions[tri[0]]);
            if (!(glm::dot(n, n) > 0.0f)) {
                ++chunkStats[size_t(t)].degenerateTriangles;
                continue;
            }
            pieces.clear();
            triangulatePieces(index, highPositions, tri, mapping, double(size), &pieces, &chunkStats[size_t(t)]);
            chunkPieces[size_t(t)] += pieces.size();
            for (Piece& p : pieces) {
                glm::vec2 ct[3];
                for (int k = 0; k < 3; ++k)
                    ct[k] = s.uvs[s.uvIndices[3 * size_t(p.face) + k]] * float(size);
                if (!clipRange(&p, ct, size))
                    continue;
                for (size_t band = size_t(p.y0) / bandRows; band <= size_t(p.y1) / bandRows; ++band)
                    filed[band].push_back(p);
            }
        }
    });
    r.stats.triangles = highFaceCount;
    for (size_t t = 0; t < bands; ++t) {
        r.stats.degenerateTriangles += chunkStats[t].degenerateTriangles;
        r.stats.borderTriangles += chunkStats[t].borderTriangles;
        r.stats.pieces += chunkPieces[t];
    }

    // 2. Raster, one row band per thread: a band draws the pieces filed
    //    under it, writes only its rows; per-texel updates are
    //    order-independent.
    parallelChunks(size_t(size), threads, [&](int band, size_t rowBegin, size_t rowEnd) {
        const int y0 = int(rowBegin), y1 = int(rowEnd);
        for (size_t t = 0; t < bands; ++t)
            for (const Piece& p : binned[t][size_t(band)]) {
                const int ya = std::max(y0, p.y0), yb = std::min(y1 - 1, p.y1);
                if (ya > yb)
                    continue;
                const Triangle2 piece = makeTriangle(p.t);
                if (!(piece.area > 0.0))
                    continue;
                glm::vec2 ct[3];
                for (int k = 0; k < 3; ++k)
                    ct[k] = s.uvs[s.uvIndices[3 * size_t(p.face) + k]] * float(size);
                const Triangle2 control = makeTriangle(ct);
                for (int y = ya; y <= yb; ++y)
                    for (int x = p.x0; x <= p.x1; ++x) {
                        const glm::dvec2 c(x + 0.5, y + 0.5);
                        double w[3], wc[3];
                        if (!inside(piece, c, w) || !inside(control, c, wc))
                            continue;
                        const double d = interpolateDistance(w, p.d, piece.area);
                        const size_t i = size_t(y) * size_t(size) + size_t(x);
                        float& dst = r.distance[i];
                        uint16_t& layers = r.layers[i];
                        const float v = float(d);
                        if (layers == 0)
                            dst = v;
                        else if (policy == OverlapPolicy::Max)
                            dst = std::max(dst, v);
                        else if (std::fabs(v) < std::fabs(dst) || (std::fabs(v) == std::fabs(dst) && v > dst))
                            dst = v;
                        if (layers < 0xffff)
                            ++layers;
                    }
            }
    });
    for (uint16_t l : r.layers) {
        r.stats.coveredTexels += l > 0;
        r.stats.multiLayerTexels += l > 1;
    }
    *out = std::move(r);
}

}  // namespace baker
}  // namespace strata
