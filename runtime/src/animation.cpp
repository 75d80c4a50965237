// Skeleton animation and skinning (paper 2.4 with glTF skins).
#include "strata/animation.h"

#include "strata/normals.h"
#include "strata/segment_deformer.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtx/quaternion.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace strata {

namespace {

// Whether weights `w` skin `vertexCount` vertices (4 or 8 influences each)
// with joints of a `jointCount`-joint skin where they weigh anything.
Status checkWeights(const VertexWeights& w, size_t jointCount, size_t vertexCount)
{
    if (w.influences != 4 && w.influences != 8)
        return Status(StatusCode::InvalidData, "the skin has " + std::to_string(w.influences) +
                                                   " influences a vertex (4 or 8 are read)");
    const size_t k = size_t(w.influences);
    if (w.weights.size() != w.joints.size())
        return Status(StatusCode::InvalidData, "the skin has " + std::to_string(w.joints.size()) + " joint indices and " +
                                                   std::to_string(w.weights.size()) + " weights");
    if (w.joints.size() != vertexCount * k)
        return Status(StatusCode::InvalidData, "the skin weighs " + std::to_string(w.joints.size() / k) +
                                                   " vertices and the control mesh has " + std::to_string(vertexCount));
    for (size_t i = 0; i < w.joints.size(); ++i)
        if (w.weights[i] != 0.0f && w.joints[i] >= jointCount)
            return Status(StatusCode::InvalidData, "vertex " + std::to_string(i / k) + " references joint " +
                                                       std::to_string(w.joints[i]) + " of a " +
                                                       std::to_string(jointCount) + "-joint skin");
    return Status::ok();
}

}  // namespace

Status finalizeSkeleton(Skeleton* s, size_t vertexCount)
{
    const int n = int(s->nodes.size());
    for (int i = 0; i < n; ++i)
        if (s->nodes[size_t(i)].parent < -1 || s->nodes[size_t(i)].parent >= n || s->nodes[size_t(i)].parent == i)
            return Status(StatusCode::InvalidData, "node " + std::to_string(i) + " has an invalid parent");
    // Order parents before children; a node whose chain of parents never
    // reaches a root is on a cycle.
    s->order.clear();
    std::vector<int> state(size_t(n), 0);  // 0 unvisited, 1 on the current chain, 2 placed
    for (int i = 0; i < n; ++i) {
        std::vector<int> chain;
        int v = i;
        while (v >= 0 && state[size_t(v)] == 0) {
            state[size_t(v)] = 1;
            chain.push_back(v);
            v = s->nodes[size_t(v)].parent;
        }
        if (v >= 0 && state[size_t(v)] == 1)
            return Status(StatusCode::InvalidData, "the node hierarchy has a cycle through node " + std::to_string(v) +
                                                       " (" + s->nodes[size_t(v)].name + ")");
        for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
            state[size_t(*it)] = 2;
            s->order.push_back(*it);
        }
    }
    const size_t nj = s->skin.joints.size();
    for (size_t j = 0; j < nj; ++j)
        if (s->skin.joints[j] < 0 || s->skin.joints[j] >= n)
            return Status(StatusCode::InvalidData, "skin joint " + std::to_string(j) + " is not a node");
    if (s->skin.inverseBindMatrices.empty())
        s->skin.inverseBindMatrices.assign(nj, glm::mat4(1.0f));
    if (s->skin.inverseBindMatrices.size() != nj)
        return Status(StatusCode::InvalidData, "the skin has " + std::to_string(nj) + " joints but " +
                                                   std::to_string(s->skin.inverseBindMatrices.size()) +
                                                   " inverse bind matrices");
    if (nj > 0)
        if (Status st = checkWeights(s->weights, nj, vertexCount); !st)
            return st;
    for (size_t a = 0; a < s->animations.size(); ++a) {
        Animation& anim = s->animations[a];
        if (anim.channels.empty())
            return Status(StatusCode::InvalidData, "animation " + std::to_string(a) + " (" + anim.name +
                                                       ") has no channels or samplers");
        anim.start = 1e30f;
        anim.end = -1e30f;
        for (const AnimationChannel& c : anim.channels) {
            if (c.node < 0 || c.node >= n)
                return Status(StatusCode::InvalidData, "animation " + anim.name + " targets a missing node");
            if (s->nodes[size_t(c.node)].hasMatrix)
                return Status(StatusCode::InvalidData, "animation " + anim.name + " targets matrix node " +
                                                           std::to_string(c.node));
            const size_t comps = c.path == AnimationPath::Rotation ? 4 : 3;
            const size_t per = c.interpolation == AnimationInterpolation::CubicSpline ? 3 * comps : comps;
            if (c.times.empty() || c.values.size() != c.times.size() * per)
                return Status(StatusCode::InvalidData, "animation " + anim.name + " has a sampler whose output count "
                                                       "does not match its " + std::to_string(c.times.size()) + " keys");
            for (size_t k = 0; k < c.times.size(); ++k) {
                if (!std::isfinite(c.times[k]) || (k > 0 && c.times[k] < c.times[k - 1]))
                    return Status(StatusCode::InvalidData, "animation " + anim.name + " has key times that are not "
                                                           "finite and non-decreasing");
            }
            for (float v : c.values)
                if (!std::isfinite(v))
                    return Status(StatusCode::InvalidData, "animation " + anim.name + " has a non-finite key value");
            anim.start = std::min(anim.start, c.times.front());
            anim.end = std::max(anim.end, c.times.back());
        }
    }
    return Status::ok();
}

int findAnimation(const Skeleton& s, const std::string& key)
{
    for (size_t i = 0; i < s.animations.size(); ++i)
        if (s.animations[i].name == key)
            return int(i);
    char* end = nullptr;
    const long idx = std::strtol(key.c_str(), &end, 10);
    if (!key.empty() && *end == 0 && idx >= 0 && size_t(idx) < s.animations.size())
        return int(idx);
    return -1;
}

namespace {

glm::vec3 vec3At(const std::vector<float>& v, size_t i)
{
    return glm::vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
}

glm::quat quatAt(const std::vector<float>& v, size_t i)
{
    return glm::quat(v[4 * i + 3], v[4 * i], v[4 * i + 1], v[4 * i + 2]);  // glTF stores x, y, z, w
}

// Cubic Hermite (glTF Appendix C): p0, outTangent m0, p1, inTangent m1 over dt.
template <typename T>
T hermite(const T& p0, const T& m0, const T& p1, const T& m1, float s, float dt)
{
    const float s2 = s * s, s3 = s2 * s;
    return (2.0f * s3 - 3.0f * s2 + 1.0f) * p0 + (s3 - 2.0f * s2 + s) * dt * m0 + (-2.0f * s3 + 3.0f * s2) * p1 +
           (s3 - s2) * dt * m1;
}

void applyChannel(NodeTransform& t, const AnimationChannel& c, float time)
{
    const size_t nk = c.times.size();
    size_t k0 = 0, k1 = 0;
    float s = 0.0f;
    if (time <= c.times.front()) {
        k0 = k1 = 0;
    } else if (time >= c.times.back()) {
        k0 = k1 = nk - 1;
    } else {
        k1 = size_t(std::upper_bound(c.times.begin(), c.times.end(), time) - c.times.begin());
        k0 = k1 - 1;
        const float dt = c.times[k1] - c.times[k0];
        s = dt > 0.0f ? (time - c.times[k0]) / dt : 0.0f;
    }
    const float dt = c.times[k1] - c.times[k0];
    const bool cubic = c.interpolation == AnimationInterpolation::CubicSpline;
    if (c.interpolation == AnimationInterpolation::Step)
        k1 = k0, s = 0.0f;
    if (c.path == AnimationPath::Rotation) {
        glm::quat q;
        if (cubic) {
            // Per key: in-tangent (3k), value (3k+1), out-tangent (3k+2).
            const glm::quat p0 = quatAt(c.values, 3 * k0 + 1), m0 = quatAt(c.values, 3 * k0 + 2);
            const glm::quat p1 = quatAt(c.values, 3 * k1 + 1), m1 = quatAt(c.values, 3 * k1);
            const glm::vec4 v = hermite(glm::vec4(p0.x, p0.y, p0.z, p0.w), glm::vec4(m0.x, m0.y, m0.z, m0.w),
                                        glm::vec4(p1.x, p1.y, p1.z, p1.w), glm::vec4(m1.x, m1.y, m1.z, m1.w), s, dt);
            q = glm::quat(v.w, v.x, v.y, v.z);
        } else {
            glm::quat a = glm::normalize(quatAt(c.values, k0)), b = glm::normalize(quatAt(c.values, k1));
            if (glm::dot(a, b) < 0.0f)
                b = -b;  // shortest arc
            q = glm::slerp(a, b, s);
        }
        const float len = glm::length(q);
        t.rotation = len > 0.0f ? q / len : glm::quat(1.0f, 0.0f, 0.0f, 0.0f);
        return;
    }
    glm::vec3 v;
    if (cubic)
        v = hermite(vec3At(c.values, 3 * k0 + 1), vec3At(c.values, 3 * k0 + 2), vec3At(c.values, 3 * k1 + 1),
                    vec3At(c.values, 3 * k1), s, dt);
    else
        v = glm::mix(vec3At(c.values, k0), vec3At(c.values, k1), s);
    if (c.path == AnimationPath::Translation)
        t.translation = v;
    else
        t.scale = v;
}

glm::mat4 toMatrix(const NodeTransform& t)
{
    glm::mat4 m = glm::mat4_cast(t.rotation);
    m[0] *= t.scale.x;
    m[1] *= t.scale.y;
    m[2] *= t.scale.z;
    m[3] = glm::vec4(t.translation, 1.0f);
    return m;
}

}  // namespace

void sampleAnimation(NodeTransform* local, const Skeleton& s, const Animation* animation, float time)
{
    for (size_t i = 0; i < s.nodes.size(); ++i)
        local[i] = s.nodes[i].rest;
    if (!animation)
        return;
    for (const AnimationChannel& c : animation->channels)
        applyChannel(local[c.node], c, time);
}

void computeWorldMatrices(glm::mat4* world, const Skeleton& s, const NodeTransform* local)
{
    for (int i : s.order) {
        const SkeletonNode& n = s.nodes[size_t(i)];
        const glm::mat4 m = n.hasMatrix ? n.matrix : toMatrix(local[i]);
        world[i] = n.parent >= 0 ? world[n.parent] * m : m;
    }
}

void computeSkinMatrices(glm::mat4* skinMatrices, const Skeleton& s, const glm::mat4* world)
{
    for (size_t j = 0; j < s.skin.joints.size(); ++j)
        skinMatrices[j] = world[s.skin.joints[j]] * s.skin.inverseBindMatrices[j];
}

void skinLinear(glm::vec3* dst, const glm::vec3* rest, size_t n, const VertexWeights& w, const glm::mat4* skin)
{
    const size_t k = size_t(w.influences);
    for (size_t v = 0; v < n; ++v) {
        const glm::vec4 p(rest[v], 1.0f);
        glm::vec3 acc(0.0f);
        for (size_t i = 0; i < k; ++i) {
            const float weight = w.weights[v * k + i];
            if (weight != 0.0f)
                acc += weight * glm::vec3(skin[w.joints[v * k + i]] * p);
        }
        dst[v] = acc;
    }
}

void skinDualQuaternion(glm::vec3* dst, const glm::vec3* rest, size_t n, const VertexWeights& w,
                        const glm::mat4* skin, size_t jointCount, float* scratch)
{
    // Rigid part of each skin matrix as a unit dual quaternion (real, dual).
    for (size_t j = 0; j < jointCount; ++j) {
        glm::mat3 r(skin[j]);
        for (int c = 0; c < 3; ++c) {
            const float len = glm::length(r[c]);
            if (len > 0.0f)
                r[c] /= len;
        }
        const glm::quat q = glm::normalize(glm::quat_cast(r));
        const glm::vec3 t(skin[j][3]);
        const glm::quat d = 0.5f * (glm::quat(0.0f, t.x, t.y, t.z) * q);
        float* o = scratch + 8 * j;
        o[0] = q.w, o[1] = q.x, o[2] = q.y, o[3] = q.z;
        o[4] = d.w, o[5] = d.x, o[6] = d.y, o[7] = d.z;
    }
    const size_t k = size_t(w.influences);
    for (size_t v = 0; v < n; ++v) {
        float b[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        const float* first = nullptr;
        for (size_t i = 0; i < k; ++i) {
            const float weight = w.weights[v * k + i];
            if (weight == 0.0f)
                continue;
            const float* q = scratch + 8 * w.joints[v * k + i];
            if (!first)
                first = q;
            // Antipodal quaternions are the same rotation: blend on one hemisphere.
            const float sign = first[0] * q[0] + first[1] * q[1] + first[2] * q[2] + first[3] * q[3] < 0.0f ? -1.0f : 1.0f;
            for (int c = 0; c < 8; ++c)
                b[c] += sign * weight * q[c];
        }
        const glm::quat real(b[0], b[1], b[2], b[3]), dual(b[4], b[5], b[6], b[7]);
        const float len = glm::length(real);
        if (!(len > 0.0f)) {
            dst[v] = rest[v];
            continue;
        }
        const glm::quat rn = real / len, dn = dual / len;
        const glm::quat tq = 2.0f * (dn * glm::conjugate(rn));
        dst[v] = glm::rotate(rn, rest[v]) + glm::vec3(tq.x, tq.y, tq.z);
    }
}

struct Animator::Segments {
    SegmentBinding binding;
    SegmentPose pose;
};

Animator::Animator() = default;
Animator::~Animator() = default;
Animator::Animator(Animator&&) noexcept = default;
Animator& Animator::operator=(Animator&&) noexcept = default;

Status Animator::init(const Skeleton& skeleton, const ControlMesh& mesh)
{
    if (skeleton.empty())
        return Status(StatusCode::InvalidArgument, "the rig has no skin to animate");
    if (skeleton.order.size() != skeleton.nodes.size())
        return Status(StatusCode::InvalidArgument, "the skeleton was not finalised");
    // The mesh may have changed since the skeleton was finalised: a skin
    // that weighs other vertices than the mesh has is refused, not read
    // past its end.
    if (Status st = checkWeights(skeleton.weights, skeleton.skin.joints.size(), mesh.positions.size()); !st)
        return st;
    skeleton_ = &skeleton;
    mesh_ = &mesh;
    local_.assign(skeleton.nodes.size(), NodeTransform());
    world_.assign(skeleton.nodes.size(), glm::mat4(1.0f));
    skinMatrices_.assign(skeleton.skin.joints.size(), glm::mat4(1.0f));
    dualQuaternions_.assign(skeleton.skin.joints.size() * 8, 0.0f);
    positions_ = mesh.positions;
    normals_.assign(mesh.positions.size(), glm::vec3(0.0f));
    updateNormals();
    segments_.reset();  // bound from the bind pose on first use
    return Status::ok();
}

const Status& Animator::segmentStatus() const
{
    if (!segments_ && skeleton_) {
        // The paper's deformer, bound once from the bind pose, when the
        // skin's joints form at least one segment.
        std::vector<glm::vec3> joints;
        std::vector<int> parents;
        skinJointHierarchy(&joints, &parents, *skeleton_);
        segments_ = std::make_unique<Segments>();
        segmentStatus_ = bindSegments(&segments_->binding, joints.data(), parents.data(), joints.size(),
                                      mesh_->positions.data(), mesh_->vertexCount());
        if (segmentStatus_.isOk())
            segments_->pose.joints.reserve(joints.size());
    }
    return segmentStatus_;
}

void Animator::sample(int animation, float time)
{
    const Animation* anim = animation >= 0 && size_t(animation) < skeleton_->animations.size()
                                ? &skeleton_->animations[size_t(animation)]
                                : nullptr;
    sampleAnimation(local_.data(), *skeleton_, anim, time);
    computeWorldMatrices(world_.data(), *skeleton_, local_.data());
    computeSkinMatrices(skinMatrices_.data(), *skeleton_, world_.data());
}

void Animator::skin(SkinningMethod method)
{
    // Zero joint motion (every skin matrix exactly identity, as at the bind
    // pose): the rest positions themselves, so the frame reproduces the
    // static reconstruction bit for bit rather than up to blending round-off.
    bool identity = true;
    for (const glm::mat4& m : skinMatrices_)
        identity = identity && m == glm::mat4(1.0f);
    if (identity) {
        std::copy(mesh_->positions.begin(), mesh_->positions.end(), positions_.begin());
        return;
    }
    if (method == SkinningMethod::Segments && segmentStatus().isOk())
        deformSegments(positions_.data(), segments_->binding, skinMatrices_.data(), &segments_->pose);
    else if (method == SkinningMethod::DualQuaternion)
        skinDualQuaternion(positions_.data(), mesh_->positions.data(), positions_.size(), skeleton_->weights,
                           skinMatrices_.data(), skinMatrices_.size(), dualQuaternions_.data());
    else
        skinLinear(positions_.data(), mesh_->positions.data(), positions_.size(), skeleton_->weights,
                   skinMatrices_.data());
}

void Animator::updateNormals()
{
    computeControlNormals(normals_.data(), positions_.data(), positions_.size(), mesh_->triangles.data(),
                          mesh_->faceCount());
}

Status Animator::pose(int animation, float time, SkinningMethod method)
{
    if (!skeleton_)
        return Status(StatusCode::InvalidArgument, "Animator::pose before init");
    if (animation >= int(skeleton_->animations.size()))
        return Status(StatusCode::InvalidArgument, "animation " + std::to_string(animation) + " does not exist");
    if (!std::isfinite(time))
        return Status(StatusCode::InvalidArgument, "animation time is not finite");
    if (method == SkinningMethod::Segments && !segmentStatus().isOk())
        return segmentStatus();
    sample(animation, time);
    skin(method);
    updateNormals();
    return Status::ok();
}

}  // namespace strata
