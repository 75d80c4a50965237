// Closed-form normal-volume mapping (paper 2.1, eq. 2): a cubic in d.
#include "strata/baker/normal_volume.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace strata {
namespace baker {
namespace {

// Real roots of c3 d^3 + c2 d^2 + c1 d + c0 inside [lo, hi].  The window is
// split at the cubic's critical points into monotonic pieces; a piece whose
// ends differ in sign holds exactly one root, found by Newton's method
// safeguarded by bisection.  No trigonometry, and pieces without a sign
// change cost two polynomial evaluations.  Degrades gracefully to quadratics
// and lines (parallel normals make c3 vanish).  Returns the count.
int solveCubicInRange(double c3, double c2, double c1, double c0, double lo, double hi, double roots[3])
{
    const double scale = std::max({std::fabs(c3), std::fabs(c2), std::fabs(c1), std::fabs(c0)});
    if (scale == 0.0 || !(lo <= hi))
        return 0;
    c3 /= scale;
    c2 /= scale;
    c1 /= scale;
    c0 /= scale;
    auto f = [&](double d) { return ((c3 * d + c2) * d + c1) * d + c0; };
    auto df = [&](double d) { return (3.0 * c3 * d + 2.0 * c2) * d + c1; };
    double cuts[4];
    int nc = 0;
    cuts[nc++] = lo;
    // Critical points: 3 c3 d^2 + 2 c2 d + c1 = 0.
    const double a = 3.0 * c3, b = 2.0 * c2, c = c1;
    double cp[2];
    int ncp = 0;
    if (std::fabs(a) > 1e-300) {
        const double disc = b * b - 4.0 * a * c;
        if (disc > 0.0) {
            const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
            cp[ncp++] = q / a;
            if (q != 0.0)
                cp[ncp++] = c / q;
        }
    } else if (std::fabs(b) > 1e-300) {
        cp[ncp++] = -c / b;
    }
    if (ncp == 2 && cp[0] > cp[1])
        std::swap(cp[0], cp[1]);
    for (int i = 0; i < ncp; ++i)
        if (cp[i] > lo && cp[i] < hi)
            cuts[nc++] = cp[i];
    cuts[nc++] = hi;
    int n = 0;
    for (int i = 0; i + 1 < nc; ++i) {
        double x0 = cuts[i], x1 = cuts[i + 1];
        double f0 = f(x0), f1 = f(x1);
        if (f0 == 0.0) {
            if (n == 0 || roots[n - 1] != x0)
                roots[n++] = x0;
            continue;
        }
        if (f1 == 0.0) {
            if (i + 2 == nc)
                roots[n++] = x1;  // the window's end; interior cuts are handled as the next piece's start
            continue;
        }
        if ((f0 < 0.0) == (f1 < 0.0))
            continue;
        double x = 0.5 * (x0 + x1);
        for (int it = 0; it < 60; ++it) {
            const double fx = f(x);
            if (fx == 0.0)
                break;
            if ((fx < 0.0) == (f0 < 0.0)) {
                x0 = x;
                f0 = fx;
            } else {
                x1 = x;
            }
            const double d = df(x);
            double next = d != 0.0 ? x - fx / d : 0.5 * (x0 + x1);
            if (!(next > x0 && next < x1))
                next = 0.5 * (x0 + x1);  // Newton left the bracket: bisect
            if (std::fabs(next - x) <= 1e-15 * std::max(1.0, std::fabs(x))) {
                x = next;
                break;
            }
            x = next;
        }
        roots[n++] = x;
    }
    return n;
}

// Barycentrics of x in the offset triangle T(d); false when T(d) is degenerate.
bool offsetBarycentrics(const NormalVolumeTriangle& t, const glm::dvec3& x, double d, double* b1, double* b2)
{
    const glm::dvec3 p0 = t.v[0] + d * t.n[0];
    const glm::dvec3 e1 = t.v[1] + d * t.n[1] - p0, e2 = t.v[2] + d * t.n[2] - p0, g = x - p0;
    const glm::dvec3 n = glm::cross(e1, e2);
    const double nn = glm::dot(n, n);
    if (!(nn > 0.0))
        return false;
    *b1 = glm::dot(glm::cross(g, e2), n) / nn;
    *b2 = glm::dot(glm::cross(e1, g), n) / nn;
    return true;
}

// Keeps, among roots with |d - centre| <= maxDistance and accepted
// barycentrics, the one closest to centre.
template <typename Accept>
bool solve(const NormalVolumeTriangle& t, const NormalVolumeCubic& cubic, const glm::dvec3& x, double centre,
           double maxDistance, Accept accept, NormalVolumeHit* hit)
{
    // det[e1 + d f1, e2 + d f2, g + d h], expanded by powers of d.
    const glm::dvec3 g = x - t.v[0];
    const double c0 = glm::dot(g, cubic.A);
    const double c1 = glm::dot(g, cubic.B) + cubic.hA;
    const double c2 = glm::dot(g, cubic.C) + cubic.hB;
    const double c3 = cubic.hC;
    double roots[3];
    const int n = solveCubicInRange(c3, c2, c1, c0, centre - maxDistance, centre + maxDistance, roots);
    bool found = false;
    for (int k = 0; k < n; ++k) {
        const double d = roots[k];
        double b1, b2;
        if (!offsetBarycentrics(t, x, d, &b1, &b2) || !accept(b1, b2))
            continue;
        if (!found || std::fabs(d - centre) < std::fabs(hit->d - centre)) {
            *hit = {b1, b2, d};
            found = true;
        }
    }
    return found;
}

}  // namespace

NormalVolumeCubic NormalVolumeCubic::of(const NormalVolumeTriangle& t)
{
    const glm::dvec3 e1 = t.v[1] - t.v[0], e2 = t.v[2] - t.v[0];
    const glm::dvec3 f1 = t.n[1] - t.n[0], f2 = t.n[2] - t.n[0];
    const glm::dvec3 h = -t.n[0];
    NormalVolumeCubic k;
    k.A = glm::cross(e1, e2);
    k.B = glm::cross(f1, e2) + glm::cross(e1, f2);
    k.C = glm::cross(f1, f2);
    k.hA = glm::dot(h, k.A);
    k.hB = glm::dot(h, k.B);
    k.hC = glm::dot(h, k.C);
    return k;
}

bool mapToNormalVolume(const NormalVolumeTriangle& tri, const NormalVolumeCubic& cubic, const glm::dvec3& x,
                       double maxDistance, double tolerance, NormalVolumeHit* hit)
{
    return solve(
        tri, cubic, x, 0.0, maxDistance,
        [&](double b1, double b2) { return b1 >= -tolerance && b2 >= -tolerance && 1.0 - b1 - b2 >= -tolerance; },
        hit);
}

bool mapToNormalVolume(const NormalVolumeTriangle& tri, const glm::dvec3& x, double maxDistance, double tolerance,
                       NormalVolumeHit* hit)
{
    return mapToNormalVolume(tri, NormalVolumeCubic::of(tri), x, maxDistance, tolerance, hit);
}

bool mapToNormalVolumePlane(const NormalVolumeTriangle& tri, const NormalVolumeCubic& cubic, const glm::dvec3& x,
                            double nearD, double maxDeviation, NormalVolumeHit* hit)
{
    // A root in the narrow window is the closest of all; the root sought
    // is the continuation of the vertex's own mapping, so it is usually there.
    auto any = [](double, double) { return true; };
    return solve(tri, cubic, x, nearD, 0.125 * maxDeviation, any, hit) ||
           solve(tri, cubic, x, nearD, maxDeviation, any, hit);
}

bool mapToNormalVolumePlane(const NormalVolumeTriangle& tri, const glm::dvec3& x, double nearD, double maxDeviation,
                            NormalVolumeHit* hit)
{
    return mapToNormalVolumePlane(tri, NormalVolumeCubic::of(tri), x, nearD, maxDeviation, hit);
}

glm::dvec3 evaluateNormalVolume(const NormalVolumeTriangle& t, double b1, double b2, double d)
{
    const double b0 = 1.0 - b1 - b2;
    return b0 * (t.v[0] + d * t.n[0]) + b1 * (t.v[1] + d * t.n[1]) + b2 * (t.v[2] + d * t.n[2]);
}

}  // namespace baker
}  // namespace strata
