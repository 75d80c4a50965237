// Sampling distortion of a flattening, shared by the chart atlas and the
// one-chart atlas (private to the baker).
#pragma once

#include "strata/control_mesh.h"
#include "strata/plane.h"

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace strata {
namespace baker {

// Local isometric coordinates of face f's corners: corner 0 at the origin,
// corner 1 on the x axis.  False for a degenerate face.
inline bool isometric(const ControlMesh& mesh, uint32_t f, glm::dvec2 q[3])
{
    glm::dvec3 p[3];
    for (int k = 0; k < 3; ++k)
        p[k] = glm::dvec3(mesh.positions[mesh.triangles[3 * size_t(f) + size_t(k)]]);
    const glm::dvec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
    const double l1 = glm::length(e1);
    const glm::dvec3 nrm = glm::cross(e1, e2);
    if (!(l1 > 0.0) || !(glm::length(nrm) > 0.0))
        return false;
    const glm::dvec3 ex = e1 / l1, ey = glm::normalize(glm::cross(nrm, e1));
    q[0] = glm::dvec2(0.0);
    q[1] = glm::dvec2(l1, 0.0);
    q[2] = glm::dvec2(glm::dot(e2, ex), glm::dot(e2, ey));
    return true;
}

// Over a flattening's faces, the largest ratio of a direction's length on
// the surface to its length in the plane (the singular values of the
// face's Jacobian) against the flattening's mean scale, or its inverse.  A
// displacement map is as coarse as its worst direction, so this bounds how
// much finer the map must be than an undistorted one.
class SamplingDistortion {
public:
    // Face q (its own plane, from isometric) flattened to w.  False where
    // w is degenerate or turned clockwise.
    bool add(const glm::dvec2 q[3], const glm::dvec2 w[3])
    {
        // J maps the flattening's plane to the face's own: J = Q W^-1.
        const glm::dvec2 w1 = w[1] - w[0], w2 = w[2] - w[0], q1 = q[1] - q[0], q2 = q[2] - q[0];
        const double det = cross2(w1, w2);
        if (!(det > 0.0))
            return false;
        const double i00 = w2.y / det, i01 = -w2.x / det, i10 = -w1.y / det, i11 = w1.x / det;
        const double a = q1.x * i00 + q2.x * i10, b = q1.x * i01 + q2.x * i11;
        const double c = q1.y * i00 + q2.y * i10, d = q1.y * i01 + q2.y * i11;
        const double e = 0.5 * (a * a + b * b + c * c + d * d), g = std::fabs(a * d - b * c);
        const double root = std::sqrt(std::max(0.0, e * e - g * g));
        sigma_.push_back({std::sqrt(e + root), std::sqrt(std::max(0.0, e - root))});
        area3_ += 0.5 * cross2(q1, q2);
        area2_ += 0.5 * det;
        return true;
    }

    // The worst direction over the faces added (1 for an isometry up to
    // scale); 1e300 where nothing was.
    double worst() const
    {
        if (!(area2_ > 0.0))
            return 1e300;
        const double mean = std::sqrt(area3_ / area2_);
        double result = 1.0;
        for (const auto& s : sigma_)
            result = std::max({result, s.first / mean, s.second > 0.0 ? mean / s.second : 1e300});
        return result;
    }

private:
    std::vector<std::pair<double, double>> sigma_;
    double area3_ = 0.0, area2_ = 0.0;
};

}  // namespace baker
}  // namespace strata
