#include "strata/segment_deformer.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace strata {

namespace {

// Joint planes never get closer than this to containing their segment
// (cos of the plane normal against the segment): beyond it a fully folded
// joint would send the carried normals to infinity.
constexpr float kMinPlaneCos = 0.05f;

glm::vec3 anyPerpendicular(const glm::vec3& s)
{
    const glm::vec3 axis = std::fabs(s.x) < 0.6f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    return glm::normalize(glm::cross(s, axis));
}

// The joint plane's normal at the joint between unit directions `in` (into
// the joint) and `out` (out of it): the bisector of the angle between the
// segments, which leaves the joint's two segments mirror images in it.
glm::vec3 bisectingPlane(const glm::vec3& in, const glm::vec3& out)
{
    const glm::vec3 p = in + out;
    const float len = glm::length(p);
    return len > 1e-3f ? p / len : out;
}

// Unit direction from a to b, or `fallback` when they (nearly) coincide.
glm::vec3 direction(const glm::vec3& a, const glm::vec3& b, const glm::vec3& fallback)
{
    const glm::vec3 d = b - a;
    const float len = glm::length(d);
    return len > 1e-12f ? d / len : fallback;
}

void jointPlanes(glm::vec3* startPlane, glm::vec3* endPlane, const glm::vec3* joints,
                 const std::vector<SkeletonSegment>& segments)
{
    for (size_t i = 0; i < segments.size(); ++i) {
        const SkeletonSegment& g = segments[i];
        const glm::vec3 s = direction(joints[g.from], joints[g.to], glm::vec3(0, 1, 0));
        startPlane[i] = g.before >= 0 ? bisectingPlane(direction(joints[g.before], joints[g.from], s), s) : s;
        endPlane[i] = g.after >= 0 ? bisectingPlane(s, direction(joints[g.to], joints[g.after], s)) : s;
    }
}

// How far along the segment direction s the perpendicular direction n must
// lean to lie in the plane with normal p.
float lean(const glm::vec3& n, const glm::vec3& s, const glm::vec3& p)
{
    return -glm::dot(n, p) / std::max(glm::dot(s, p), kMinPlaneCos);
}

glm::vec3 closestOnSegment(const glm::vec3& v, const glm::vec3& a, const glm::vec3& b)
{
    const glm::vec3 ab = b - a;
    const float len2 = glm::dot(ab, ab);
    const float t = len2 > 0.0f ? glm::clamp(glm::dot(v - a, ab) / len2, 0.0f, 1.0f) : 0.0f;
    return a + t * ab;
}

struct Mapping {
    float alpha = 0.0f, d = 0.0f;
    glm::vec3 n{0.0f};
    bool valid = false;
};

// Inverse of eq. 6 for one segment, in closed form.  With n the unit
// perpendicular from the segment's line to v and t_a, t_b its leans into the
// two joint planes, the along-segment coordinate x of v satisfies
//     x = (1 - alpha) L + d (alpha t_a + (1 - alpha) t_b),
// which is linear in alpha.
Mapping mapToSegment(const glm::vec3& v, const glm::vec3& a, const glm::vec3& b, const glm::vec3& pa,
                     const glm::vec3& pb)
{
    Mapping m;
    const glm::vec3 ab = b - a;
    const float len = glm::length(ab);
    const glm::vec3 s = ab / len;
    const glm::vec3 r = v - a;
    const float x = glm::dot(r, s);
    const glm::vec3 perp = r - x * s;
    m.d = glm::length(perp);
    m.n = m.d > 1e-7f * len ? perp / m.d : anyPerpendicular(s);
    const float ta = lean(m.n, s, pa), tb = lean(m.n, s, pb);
    const float den = len + m.d * (tb - ta);
    // The planes cross closer to the line than v: no alpha reaches it.
    if (!(den > 0.05f * len))
        return m;
    m.alpha = (len + m.d * tb - x) / den;
    m.valid = std::isfinite(m.alpha);
    return m;
}

}  // namespace

Status bindSegments(SegmentBinding* binding, const glm::vec3* joints, const int* parents, size_t jointCount,
                    const glm::vec3* positions, size_t n)
{
    SegmentBinding out;
    out.bindJoints.assign(joints, joints + jointCount);
    std::vector<int> childCount(jointCount, 0), onlyChild(jointCount, -1);
    for (size_t j = 0; j < jointCount; ++j) {
        if (!std::isfinite(joints[j].x) || !std::isfinite(joints[j].y) || !std::isfinite(joints[j].z))
            return Status(StatusCode::InvalidData, "joint " + std::to_string(j) + " has a non-finite position");
        const int p = parents[j];
        if (p < -1 || p >= int(jointCount) || p == int(j))
            return Status(StatusCode::InvalidData, "joint " + std::to_string(j) + " has an invalid parent");
        if (p >= 0) {
            ++childCount[size_t(p)];
            onlyChild[size_t(p)] = int(j);
        }
    }
    // Joints at their parent's place (a root and its hip, as many rigs
    // have) make no segment; planes look past them to the nearest joint
    // that is somewhere else.
    const auto apart = [&](int a, int b) {
        return glm::length(joints[a] - joints[b]) > 1e-6f * (1.0f + glm::length(joints[a]));
    };
    for (size_t j = 0; j < jointCount; ++j) {
        const int p = parents[j];
        if (p < 0 || !apart(p, int(j)))
            continue;
        SkeletonSegment g;
        g.from = p;
        g.to = int(j);
        for (int b = parents[size_t(p)]; b >= 0 && g.before < 0; b = parents[size_t(b)])
            if (apart(b, p))
                g.before = b;
        if (childCount[j] == 1 && apart(int(j), onlyChild[j]))
            g.after = onlyChild[j];
        out.segments.push_back(g);
    }
    if (out.segments.empty())
        return Status(StatusCode::InvalidArgument, "the skeleton has no segment (a joint apart from its parent)");

    const size_t segmentCount = out.segments.size();
    std::vector<glm::vec3> startPlane(segmentCount), endPlane(segmentCount);
    jointPlanes(startPlane.data(), endPlane.data(), joints, out.segments);

    out.segment.resize(n);
    out.alpha.resize(n);
    out.distance.resize(n);
    out.reach.resize(n);
    out.direction.resize(n);
    for (size_t v = 0; v < n; ++v) {
        const glm::vec3 p = positions[v];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            return Status(StatusCode::InvalidData, "vertex " + std::to_string(v) + " is not finite");
        // Enclosed by the segment's joint planes at the smallest distance
        // first; otherwise the segment nearest in space that has a mapping.
        size_t best = segmentCount;
        float bestKey = std::numeric_limits<float>::infinity(), bestReach = 0.0f;
        Mapping bestMap;
        for (size_t i = 0; i < segmentCount; ++i) {
            const SkeletonSegment& g = out.segments[i];
            const glm::vec3 a = joints[g.from], b = joints[g.to];
            const Mapping m = mapToSegment(p, a, b, startPlane[i], endPlane[i]);
            if (!m.valid)
                continue;
            const bool enclosed = m.alpha >= -1e-5f && m.alpha <= 1.0f + 1e-5f;
            const float reach = glm::length(p - closestOnSegment(p, a, b));
            // Enclosed candidates rank by d before every other by reach.
            const float key = enclosed ? m.d : 1e30f + reach;
            if (key < bestKey) {
                bestKey = key;
                best = i;
                bestMap = m;
                bestReach = reach;
            }
        }
        if (best == segmentCount)
            return Status(StatusCode::InvalidData,
                          "vertex " + std::to_string(v) + " cannot be mapped to any skeleton segment");
        out.segment[v] = uint32_t(best);
        out.alpha[v] = bestMap.alpha;
        out.distance[v] = bestMap.d;
        out.direction[v] = bestMap.n;
        out.reach[v] = bestReach;
    }
    *binding = std::move(out);
    return Status::ok();
}

void deformSegments(glm::vec3* dst, const SegmentBinding& binding, const glm::mat4* skinMatrices,
                    SegmentPose* pose)
{
    const size_t jointCount = binding.bindJoints.size(), segmentCount = binding.segments.size();
    pose->joints.resize(jointCount);
    pose->startPlane.resize(segmentCount);
    pose->endPlane.resize(segmentCount);
    for (size_t j = 0; j < jointCount; ++j)
        pose->joints[j] = glm::vec3(skinMatrices[j] * glm::vec4(binding.bindJoints[j], 1.0f));
    jointPlanes(pose->startPlane.data(), pose->endPlane.data(), pose->joints.data(), binding.segments);

    const size_t n = binding.vertexCount();
    for (size_t v = 0; v < n; ++v) {
        const uint32_t i = binding.segment[v];
        const SkeletonSegment& g = binding.segments[i];
        const glm::vec3 a = pose->joints[size_t(g.from)], b = pose->joints[size_t(g.to)];
        const glm::vec3 s = direction(a, b, glm::vec3(0, 1, 0));
        // n rides with the joint that starts the segment, then is made
        // perpendicular to the posed segment again.
        glm::vec3 dir = glm::mat3(skinMatrices[g.from]) * binding.direction[v];
        dir -= glm::dot(dir, s) * s;
        const float dl = glm::length(dir);
        dir = dl > 1e-12f ? dir / dl : anyPerpendicular(s);
        const float alpha = binding.alpha[v], d = binding.distance[v];
        const float t = alpha * lean(dir, s, pose->startPlane[i]) + (1.0f - alpha) * lean(dir, s, pose->endPlane[i]);
        glm::vec3 p = alpha * a + (1.0f - alpha) * b + d * (dir + t * s);
        if (binding.keepDistance) {
            const glm::vec3 q = closestOnSegment(p, a, b);
            const float reach = glm::length(p - q);
            if (reach > binding.reach[v])
                p = q + (p - q) * (binding.reach[v] / reach);
        }
        dst[v] = p;
    }
}

void segmentSkinWeights(VertexWeights* weights, const SegmentBinding& binding, const int* parents)
{
    const size_t n = binding.vertexCount();
    const size_t jointCount = binding.bindJoints.size();
    std::vector<bool> drivesSegment(jointCount, false);
    for (const SkeletonSegment& g : binding.segments)
        drivesSegment[size_t(g.from)] = true;
    std::vector<glm::vec3> startPlane(binding.segments.size()), endPlane(binding.segments.size());
    jointPlanes(startPlane.data(), endPlane.data(), binding.bindJoints.data(), binding.segments);

    weights->influences = 4;
    weights->joints.assign(n * 4, 0);
    weights->weights.assign(n * 4, 0.0f);
    for (size_t v = 0; v < n; ++v) {
        const uint32_t i = binding.segment[v];
        const SkeletonSegment& g = binding.segments[i];
        const glm::vec3 a = binding.bindJoints[size_t(g.from)], b = binding.bindJoints[size_t(g.to)];
        const float alpha = binding.alpha[v], d = binding.distance[v];
        const glm::vec3 s = glm::normalize(b - a);
        const float t = alpha * lean(binding.direction[v], s, startPlane[i]) +
                        (1.0f - alpha) * lean(binding.direction[v], s, endPlane[i]);
        const glm::vec3 p = alpha * a + (1.0f - alpha) * b + d * (binding.direction[v] + t * s);
        // Blend over a width equal to the vertex's distance from the bone
        // (a round joint), at least a small fraction of the segment.
        const float width = std::max(d, 0.02f * glm::length(b - a));
        const auto half = [&](float signedDistance) {
            return 0.5f * (1.0f - glm::smoothstep(0.0f, width, std::max(signedDistance, 0.0f)));
        };
        const int parent = parents[size_t(g.from)];
        const float wBefore = parent >= 0 ? half(glm::dot(p - a, startPlane[i])) : 0.0f;
        const float wAfter = drivesSegment[size_t(g.to)] ? half(glm::dot(b - p, endPlane[i])) : 0.0f;
        uint16_t* jv = &weights->joints[v * 4];
        float* wv = &weights->weights[v * 4];
        jv[0] = uint16_t(g.from);
        wv[0] = 1.0f - wBefore - wAfter;
        jv[1] = uint16_t(g.to);
        wv[1] = wAfter;
        jv[2] = uint16_t(parent >= 0 ? parent : g.from);
        wv[2] = wBefore;
    }
}

void skinJointHierarchy(std::vector<glm::vec3>* positions, std::vector<int>* parents, const Skeleton& skeleton)
{
    const size_t jointCount = skeleton.skin.joints.size();
    std::vector<int> jointOfNode(skeleton.nodes.size(), -1);
    for (size_t j = 0; j < jointCount; ++j)
        jointOfNode[size_t(skeleton.skin.joints[j])] = int(j);
    positions->resize(jointCount);
    parents->assign(jointCount, -1);
    for (size_t j = 0; j < jointCount; ++j) {
        const glm::mat4 bind = glm::inverse(skeleton.skin.inverseBindMatrices[j]);
        (*positions)[j] = glm::vec3(bind[3]);
        // Nodes are finalised acyclic, so the walk ends.
        for (int node = skeleton.nodes[size_t(skeleton.skin.joints[j])].parent; node >= 0;
             node = skeleton.nodes[size_t(node)].parent) {
            if (jointOfNode[size_t(node)] >= 0) {
                (*parents)[j] = jointOfNode[size_t(node)];
                break;
            }
        }
    }
}

Status bindSkeletonWeights(Skeleton* skeleton, const ControlMesh& mesh)
{
    if (skeleton->skin.joints.size() > 65535)
        return Status(StatusCode::InvalidData, "a skin has at most 65535 joints");
    // Placeholder weights (everything on joint 0) so the hierarchy can be
    // checked and ordered before the binding produces the real ones.
    skeleton->weights.influences = 4;
    skeleton->weights.joints.assign(mesh.vertexCount() * 4, 0);
    skeleton->weights.weights.assign(mesh.vertexCount() * 4, 0.0f);
    for (size_t v = 0; v < mesh.vertexCount(); ++v)
        skeleton->weights.weights[v * 4] = 1.0f;
    if (Status st = finalizeSkeleton(skeleton, mesh.vertexCount()); !st.isOk())
        return st;
    std::vector<glm::vec3> joints;
    std::vector<int> parents;
    skinJointHierarchy(&joints, &parents, *skeleton);
    SegmentBinding binding;
    if (Status st = bindSegments(&binding, joints.data(), parents.data(), joints.size(), mesh.positions.data(),
                                 mesh.vertexCount());
        !st.isOk())
        return st;
    segmentSkinWeights(&skeleton->weights, binding, parents.data());
    return finalizeSkeleton(skeleton, mesh.vertexCount());
}

}  // namespace strata
