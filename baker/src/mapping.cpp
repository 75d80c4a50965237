// Normal-volume mapping of the high-resolution vertices (paper 2.1), through
// a BVH over the normal-volume prisms rather than a scan of all triangles.
#include "mapping.h"
#include "parallel.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace strata {
namespace baker {

NormalVolumeTriangle SurfaceIndex::triangle(uint32_t f) const
{
    return triangles_[f];
}

void SurfaceIndex::build(const BakeSurface& surface, double searchDistance)
{
    buildFaces(surface);
    buildPrisms(searchDistance);
}

void SurfaceIndex::buildFaces(const BakeSurface& surface)
{
    surface_ = &surface;
    const size_t nf = surface.faceCount();
    triangles_.resize(nf);
    cubics_.resize(nf);
    for (size_t f = 0; f < nf; ++f) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = surface.triangles[3 * f + k];
            triangles_[f].v[k] = glm::dvec3(surface.positions[v]);
            triangles_[f].n[k] = glm::dvec3(surface.normals[v]);
        }
        cubics_[f] = NormalVolumeCubic::of(triangles_[f]);
    }
    faces_.build(surface.positions.data(), surface.triangles.data(), nf);
}

void SurfaceIndex::buildPrisms(double searchDistance)
{
    const BakeSurface& surface = *surface_;
    searchDistance_ = searchDistance;
    const size_t nf = surface.faceCount();
    std::vector<Box> prisms(nf);
    const float D = float(searchDistance);
    for (size_t f = 0; f < nf; ++f) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = surface.triangles[3 * f + k];
            const glm::vec3 p = surface.positions[v], n = surface.normals[v];
            // T(d) moves linearly in d, so the prism lies in the hull of T(-D) and T(D).
            prisms[f].extend(p + D * n);
            prisms[f].extend(p - D * n);
        }
        // Pad by a relative epsilon so points on a shared face are found from both sides.
        const glm::vec3 pad = 1e-5f * (prisms[f].hi - prisms[f].lo) + glm::vec3(1e-7f);
        prisms[f].lo -= pad;
        prisms[f].hi += pad;
    }
    prisms_.build(prisms);
    prismBoxes_ = std::move(prisms);
}

double SurfaceIndex::nearestFace(const glm::dvec3& x, uint32_t shell, uint32_t* face, double* b1, double* b2,
                                 int64_t hint) const
{
    if (shell == kAnyShell || faceShells_.empty())
        return faces_.nearest(x, face, b1, b2, hint);
    return faces_.nearestLabelled(x, faceShells_.data(), shell, face, b1, b2, hint);
}

bool SurfaceIndex::map(const glm::dvec3& x, VertexMapping* out, int64_t hint, uint32_t shell) const
{
    bool found = false;
    NormalVolumeHit best;
    uint32_t bestFace = 0;
    const bool anyShell = shell == kAnyShell || faceShells_.empty();
    auto consider = [&](uint32_t f) {
        if (!anyShell && faceShells_[f] != shell)
            return;  // another piece's face
        if (!prismBoxes_[f].contains(glm::vec3(x)))
            return;  // outside the volume's bounding box
        NormalVolumeHit hit;
        // Only a root no farther than the best so far can win.
        const double window = found ? std::fabs(best.d) : searchDistance_;
        if (!mapToNormalVolume(triangles_[f], cubics_[f], x, window, 1e-7, &hit))
            return;
        // Smallest |d| wins; ties (shared edges) go to the lower face index
        // so the result does not depend on visiting order.
        if (!found || std::fabs(hit.d) < std::fabs(best.d) ||
            (std::fabs(hit.d) == std::fabs(best.d) && f < bestFace)) {
            best = hit;
            bestFace = f;
            found = true;
        }
    };
    // First the volumes around the nearest surface triangle (its corners'
    // rings): the point's own neighbourhood, a handful of cubic solves.
    uint32_t nearest = 0;
    if (nearestFace(x, shell, &nearest, nullptr, nullptr, hint) >= 0) {
        const BakeSurface& s = *surface_;
        uint32_t seen[96];
        int nseen = 0;
        // The nearest triangle's own volume first: it usually holds the
        // point, and its distance then narrows every other solve.
        consider(nearest);
        seen[nseen++] = nearest;
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = s.triangles[3 * size_t(nearest) + k];
            for (uint32_t r = s.ringOffsets[v]; r < s.ringOffsets[v + 1]; ++r) {
                const uint32_t f = s.ringFaces[r];
                bool dup = false;
                for (int i = 0; i < nseen && !dup; ++i)
                    dup = seen[i] == f;
                if (dup)
                    continue;
                if (nseen < 96)
                    seen[nseen++] = f;
                consider(f);
            }
        }
    }
    // Then, only if the neighbourhood holds no volume containing the point
    // (concave regions), every prism of the index.
    if (!found)
        prisms_.forEachContaining(glm::vec3(x), consider);
    if (found) {
        // Clamp the tolerance band back onto the triangle.
        double b1 = std::max(best.b1, 0.0), b2 = std::max(best.b2, 0.0);
        const double sum = b1 + b2;
        if (sum > 1.0) {
            b1 /= sum;
            b2 /= sum;
        }
        *out = {bestFace, float(b1), float(b2), float(best.d)};
    }
    return found;
}

VertexMapping SurfaceIndex::mapNearest(const glm::dvec3& x, uint32_t shell) const
{
    VertexMapping m{0, 0.0f, 0.0f, 0.0f};
    uint32_t face = 0;
    double b1 = 0.0, b2 = 0.0;
    if (nearestFace(x, shell, &face, &b1, &b2, -1) < 0.0)
        return m;
    const NormalVolumeTriangle t = triangle(face);
    const glm::dvec3 c = evaluateNormalVolume(t, b1, b2, 0.0);
    const double b0 = 1.0 - b1 - b2;
    const glm::dvec3 n = b0 * t.n[0] + b1 * t.n[1] + b2 * t.n[2];
    const double nn = glm::dot(n, n);
    m.face = face;
    m.b1 = float(b1);
    m.b2 = float(b2);
    m.d = nn > 0.0 ? float(glm::dot(x - c, n) / nn) : 0.0f;
    return m;
}

double SurfaceIndex::nearestDistance(const glm::vec3& x, uint32_t shell) const
{
    return nearestFace(glm::dvec3(x), shell, nullptr, nullptr, nullptr, -1);
}

Status mapVertices(std::vector<VertexMapping>* out, SurfaceIndex* index, const BakeSurface& surface,
                   const glm::vec3* points, size_t n, int threads, MappingStats* stats, double maxSearchFraction,
                   const uint32_t* pointShells)
{
    auto shellOf = [&](size_t i) { return pointShells ? pointShells[i] : SurfaceIndex::kAnyShell; };
    if (surface.faceCount() == 0)
        return Status(StatusCode::InvalidArgument, "empty bake surface");
    Box bounds;
    for (const glm::vec3& p : surface.positions)
        bounds.extend(p);
    const double diag = glm::length(glm::dvec3(bounds.hi - bounds.lo));
    // Index the triangles first: their nearest distances size the prisms.
    index->buildFaces(surface);
    const size_t step = std::max<size_t>(1, n / 4096);
    std::vector<double> sample((n + step - 1) / step, 0.0);
    parallelFor(sample.size(), threads, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i)
            sample[i] = index->nearestDistance(points[i * step], shellOf(i * step));
    });
    double far = 0.0;
    for (double s : sample)
        far = std::max(far, s);
    const double D = std::min(2.0 * far + 1e-4 * diag, maxSearchFraction * diag);
    index->buildPrisms(D);

    out->resize(n);
    std::vector<uint8_t> fellBack(n, 0);
    parallelFor(n, threads, [&](size_t b, size_t e) {
        int64_t hint = -1;  // consecutive vertices are usually neighbours
        for (size_t i = b; i < e; ++i) {
            const glm::dvec3 x(points[i]);
            if (index->map(x, &(*out)[i], hint, shellOf(i))) {
                hint = (*out)[i].face;
            } else {
                (*out)[i] = index->mapNearest(x, shellOf(i));
                fellBack[i] = 1;
            }
        }
    });
    if (stats) {
        stats->vertices = n;
        stats->fallbacks = size_t(std::count(fellBack.begin(), fellBack.end(), uint8_t(1)));
        stats->searchDistance = D;
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
