// Closed-form normal-volume mapping (paper 2.1, eq. 2): a cubic in d.
#include "strata/baker/normal_volume.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace strata {
namespace baker {
namespace {

double det3(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c)
{
    return glm::dot(a, glm::cross(b, c));
}

// Real roots of c3 d^3 + c2 d^2 + c1 d + c0 = 0, degrading gracefully to
// quadratic and linear when the leading coefficients vanish (parallel
// normals make the offset planes parallel).  Returns the count.
int solveCubic(double c3, double c2, double c1, double c0, double roots[3])
{
    const double scale = std::max({std::fabs(c3), std::fabs(c2), std::fabs(c1), std::fabs(c0)});
    if (scale == 0.0)
        return 0;
    c3 /= scale;
    c2 /= scale;
    c1 /= scale;
    c0 /= scale;
    const double eps = 1e-12;
    if (std::fabs(c3) < eps) {
        if (std::fabs(c2) < eps) {
            if (std::fabs(c1) < eps)
                return 0;
            roots[0] = -c0 / c1;
            return 1;
        }
        const double disc = c1 * c1 - 4.0 * c2 * c0;
        if (disc < 0.0)
            return 0;
        // Numerically stable quadratic roots.
        const double q = -0.5 * (c1 + std::copysign(std::sqrt(disc), c1));
        int n = 0;
        if (q != 0.0) {
            roots[n++] = q / c2;
            roots[n++] = c0 / q;
        } else {
            roots[n++] = 0.0;
        }
        return n;
    }
    // Depressed cubic t^3 + p t + q with d = t - a/3.
    const double a = c2 / c3, b = c1 / c3, c = c0 / c3;
    const double p = b - a * a / 3.0;
    const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
    const double shift = -a / 3.0;
    const double disc = q * q / 4.0 + p * p * p / 27.0;
    if (disc > 0.0) {
        const double s = std::sqrt(disc);
        roots[0] = std::cbrt(-q / 2.0 + s) + std::cbrt(-q / 2.0 - s) + shift;
        return 1;
    }
    if (p == 0.0) {
        roots[0] = shift;
        return 1;
    }
    const double r = 2.0 * std::sqrt(-p / 3.0);
    const double phi = std::acos(std::clamp(3.0 * q / (p * r), -1.0, 1.0)) / 3.0;
    for (int k = 0; k < 3; ++k)
        roots[k] = r * std::cos(phi - 2.0 * M_PI * k / 3.0) + shift;
    return 3;
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
bool solve(const NormalVolumeTriangle& t, const glm::dvec3& x, double centre, double maxDistance, Accept accept,
           NormalVolumeHit* hit)
{
    const glm::dvec3 e1 = t.v[1] - t.v[0], e2 = t.v[2] - t.v[0];
    const glm::dvec3 f1 = t.n[1] - t.n[0], f2 = t.n[2] - t.n[0];
    const glm::dvec3 g = x - t.v[0], h = -t.n[0];
    // det[e1 + d f1, e2 + d f2, g + d h], expanded by powers of d.
    const double c0 = det3(e1, e2, g);
    const double c1 = det3(f1, e2, g) + det3(e1, f2, g) + det3(e1, e2, h);
    const double c2 = det3(f1, f2, g) + det3(f1, e2, h) + det3(e1, f2, h);
    const double c3 = det3(f1, f2, h);
    double roots[3];
    const int n = solveCubic(c3, c2, c1, c0, roots);
    bool found = false;
    for (int k = 0; k < n; ++k) {
        double d = roots[k];
        // Two Newton steps polish the closed-form root to full precision.
        for (int it = 0; it < 2; ++it) {
            const double f = ((c3 * d + c2) * d + c1) * d + c0;
            const double df = (3.0 * c3 * d + 2.0 * c2) * d + c1;
            if (df != 0.0)
                d -= f / df;
        }
        if (!std::isfinite(d) || std::fabs(d - centre) > maxDistance)
            continue;
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

bool mapToNormalVolume(const NormalVolumeTriangle& tri, const glm::dvec3& x, double maxDistance, double tolerance,
                       NormalVolumeHit* hit)
{
    return solve(
        tri, x, 0.0, maxDistance,
        [&](double b1, double b2) { return b1 >= -tolerance && b2 >= -tolerance && 1.0 - b1 - b2 >= -tolerance; },
        hit);
}

bool mapToNormalVolumePlane(const NormalVolumeTriangle& tri, const glm::dvec3& x, double nearD, double maxDeviation,
                            NormalVolumeHit* hit)
{
    return solve(tri, x, nearD, maxDeviation, [](double, double) { return true; }, hit);
}

glm::dvec3 evaluateNormalVolume(const NormalVolumeTriangle& t, double b1, double b2, double d)
{
    const double b0 = 1.0 - b1 - b2;
    return b0 * (t.v[0] + d * t.n[0]) + b1 * (t.v[1] + d * t.n[1]) + b2 * (t.v[2] + d * t.n[2]);
}

}  // namespace baker
}  // namespace strata
