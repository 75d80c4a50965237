// Surface: the one sequence from a rig to a displaced frame (surface.h).
#include "strata/surface.h"

#include "strata/normals.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

namespace strata {

int Surface::levelFor(const Rig& rig, const SurfaceOptions& options)
{
    if (options.level >= 0)
        return options.level;
    return rig.hasDisplacement && options.displace ? rig.displacement.recommendedLevel : 0;
}

Scheme Surface::schemeFor(const Rig& rig, const SurfaceOptions& options)
{
    if (rig.hasDisplacement && options.displace)
        return rig.displacement.scheme;
    return options.schemeGiven ? options.scheme : Scheme::Linear;
}

Status Surface::check(const Rig& rig, const SurfaceOptions& options)
{
    const int level = levelFor(rig, options);
    if (level < 0 || level > kMaxLevel)
        return Status(StatusCode::InvalidArgument,
                      "level " + std::to_string(level) + " is out of range (0.." + std::to_string(kMaxLevel) + ")");
    if (!options.displace)
        return Status::ok();
    // A glTF whose layer is gone is not drawn as if it were the baked
    // surface: the last tool to touch the file may have dropped it.
    if (!rig.hasDisplacement && !rig.layerMissing.empty())
        return Status(StatusCode::InvalidData, "no displacement layer (" + rig.layerMissing + ")");
    if (rig.hasDisplacement && options.schemeGiven && options.scheme != rig.displacement.scheme)
        return Status(StatusCode::InvalidArgument,
                      std::string("the rig was baked against the ") + schemeName(rig.displacement.scheme) +
                          " scheme, and its displacement drawn in the " + schemeName(options.scheme) +
                          " scheme is another surface");
    if (!(options.scale == options.scale) || options.scale > 1e6f || options.scale < -1e6f)
        return Status(StatusCode::InvalidArgument, "the displacement scale is not a finite number in -1e6..1e6");
    return Status::ok();
}

Status Surface::create(std::unique_ptr<Surface>* out, const Rig& rig, const DisplacementMap* map,
                       const SurfaceOptions& options)
{
    if (!out)
        return Status(StatusCode::InvalidArgument, "Surface::create: null output");
    if (Status st = check(rig, options); !st)
        return st;
    std::unique_ptr<Surface> s(new Surface());
    s->mesh_ = rig.mesh;
    s->skeleton_ = rig.skeleton;
    s->method_ = options.method;
    // A rig assembled by hand (not loaded from a file, no layer recorded)
    // with a map of the caller's: the map is sampled in the scheme asked for.
    const bool callersMap = !rig.hasDisplacement && !rig.source && rig.layerMissing.empty() && map &&
                            !map->texels.empty();
    s->displaced_ = options.displace && (rig.hasDisplacement || callersMap);
    Status st = Plan::create(&s->plan_, s->mesh_, schemeFor(rig, options), levelFor(rig, options));
    if (!st)
        return st;
    if (s->displaced_ && rigNeedsMap(rig) && (!map || map->texels.empty()))
        return Status(StatusCode::InvalidArgument,
                      "the rig samples a displacement map and none was given (io::loadRigDisplacementMap)");
    if (s->displaced_ && !(st = applyRigDisplacement(s->plan_.get(), rig, map, options.scale)))
        return st;
    for (float d : s->plan_->displacements())
        s->largestDisplacement_ = std::max(s->largestDisplacement_, std::fabs(d));
    if (!s->skeleton_.empty()) {
        s->animator_ = std::make_unique<Animator>();
        if (!(st = s->animator_->init(s->skeleton_, s->mesh_)))
            return st;
    }
    s->frame_ = std::make_unique<FrameEvaluator>(*s->plan_, options.layout);
    if (!(st = s->setRestPose()))
        return st;
    *out = std::move(s);
    return Status::ok();
}

Surface::~Surface() = default;

int Surface::level() const
{
    return plan_->level();
}

Scheme Surface::scheme() const
{
    return plan_->scheme();
}

size_t Surface::vertexCount() const
{
    return plan_->refinedVertexCount();
}

size_t Surface::triangleCount() const
{
    return plan_->refinedFaceCount();
}

const std::vector<uint32_t>& Surface::triangles() const
{
    return frame_->layout() == FrameLayout::Plan ? plan_->refinedTriangles() : frame_->triangles();
}

const std::vector<uint32_t>& Surface::vertexOrder() const
{
    return frame_->vertexOrder();
}

void Surface::refinedUVs(std::vector<glm::vec2>* values, std::vector<uint32_t>* indices) const
{
    plan_->refinedUVs(values, indices);
}

namespace {

std::string seconds(float t)
{
    char text[32];
    std::snprintf(text, sizeof(text), "%g s", double(t));
    return text;
}

std::string printed(const glm::vec3& p)
{
    char text[96];
    std::snprintf(text, sizeof(text), "(%g, %g, %g)", double(p.x), double(p.y), double(p.z));
    return text;
}

}  // namespace

size_t Surface::firstOutOfRange(const glm::vec3* values, size_t count)
{
    // A pass without branches first (it vectorises), the search only where
    // it fails.
    const float* f = count ? &values[0].x : nullptr;
    int bad = 0;
    for (size_t i = 0; i < 3 * count; ++i)
        bad |= int(!(std::fabs(f[i]) <= kLargestCoordinate));
    if (!bad)
        return count;
    size_t i = 0;
    while (std::fabs(f[i]) <= kLargestCoordinate)
        ++i;
    return i / 3;
}

std::string Surface::overflowingJoint(const glm::mat4* skin, size_t count) const
{
    for (size_t j = 0; j < count; ++j) {
        bool finite = true;
        for (int k = 0; k < 16; ++k)
            finite = finite && std::isfinite(skin[j][k / 4][k % 4]);
        if (finite)
            continue;
        std::string joint = "joint " + std::to_string(j);
        if (j < skeleton_.skin.joints.size()) {
            const int node = skeleton_.skin.joints[j];
            joint += " (node " + std::to_string(node);
            if (node >= 0 && size_t(node) < skeleton_.nodes.size() && !skeleton_.nodes[size_t(node)].name.empty())
                joint += " \"" + skeleton_.nodes[size_t(node)].name.substr(0, 64) + "\"";
            joint += ")";
        }
        return joint;
    }
    return std::string();
}

Status Surface::poseError(const std::vector<glm::vec3>& positions, size_t v, const std::string& what,
                          const std::string& cause)
{
    static_assert(kLargestCoordinate == 1e9f, "the message below names the bound");
    const glm::vec3 p = positions[v];
    const bool finite = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    return Status(StatusCode::InvalidArgument,
                  what + (finite ? " is out of range" : " is not finite") + ": control vertex " + std::to_string(v) +
                      " at " + printed(p) +
                      (finite ? " lies beyond +-1e9, where the normals' squared products overflow" : "") +
                      (cause.empty() ? std::string() : ": " + cause));
}

Status Surface::adoptPending(const char* what, const char* cause)
{
    if (const size_t v = firstOutOfRange(pendingPositions_.data(), pendingPositions_.size());
        v < pendingPositions_.size())
        return poseError(pendingPositions_, v, what, cause);
    pendingNormals_.assign(pendingPositions_.size(), glm::vec3(0.0f));
    computeControlNormals(pendingNormals_.data(), pendingPositions_.data(), pendingPositions_.size(),
                          mesh_.triangles.data(), mesh_.faceCount());
    controlPositions_.swap(pendingPositions_);
    controlNormals_.swap(pendingNormals_);
    ++poseVersion_;
    return Status::ok();
}

void Surface::bounds(glm::vec3* lo, glm::vec3* hi) const
{
    glm::vec3 a(0.0f), b(0.0f);
    float longest = plan_->scheme() == Scheme::Smooth ? 1.0f : 0.0f;  // the smooth direction is a unit normal
    for (size_t v = 0; v < controlPositions_.size(); ++v) {
        a = v ? glm::min(a, controlPositions_[v]) : controlPositions_[v];
        b = v ? glm::max(b, controlPositions_[v]) : controlPositions_[v];
        longest = std::max(longest, glm::length(controlNormals_[v]));
    }
    const glm::vec3 grow(largestDisplacement_ * longest);
    *lo = a - grow;
    *hi = b + grow;
}

Status Surface::setRestPose()
{
    pendingPositions_ = mesh_.positions;
    if (Status st = adoptPending("the rest pose", ""); !st)
        return st;
    skinMatrices_.clear();
    return Status::ok();
}

Status Surface::setAnimationTime(int animation, float time)
{
    if (!animator_)
        return Status(StatusCode::InvalidArgument, "the rig has no skin to animate");
    if (animation < -1 || animation >= int(skeleton_.animations.size()))
        return Status(StatusCode::InvalidArgument, "animation " + std::to_string(animation) + " does not exist (the rig has " +
                                                       std::to_string(skeleton_.animations.size()) + ")");
    if (!(time == time))
        return Status(StatusCode::InvalidArgument, "the animation time is not a number");
    Status st = animator_->pose(animation, time, method_);
    if (!st)
        return st;
    // Refused: the message (and the joint to blame) made only then.
    const std::vector<glm::vec3>& posed = animator_->positions();
    if (const size_t v = firstOutOfRange(posed.data(), posed.size()); v < posed.size()) {
        const std::vector<glm::mat4>& skin = animator_->skinMatrices();
        const std::string joint = overflowingJoint(skin.data(), skin.size());
        return poseError(posed, v,
                         "the pose of animation " + std::to_string(animation) + " at " + seconds(time),
                         joint.empty() ? std::string() : joint + " has a posed transform that overflows");
    }
    // The same pose again (a paused clip) keeps its version, and what a
    // choice measured for it.
    if (controlPositions_ != animator_->positions() || controlNormals_ != animator_->normals()) {
        controlPositions_ = animator_->positions();
        controlNormals_ = animator_->normals();
        ++poseVersion_;
    }
    skinMatrices_ = animator_->skinMatrices();
    return Status::ok();
}

Status Surface::setJointMatrices(const glm::mat4* matrices, size_t count)
{
    if (skeleton_.empty())
        return Status(StatusCode::InvalidArgument, "the rig has no skin to pose");
    if (!matrices || count != skeleton_.skin.joints.size())
        return Status(StatusCode::InvalidArgument, std::to_string(matrices ? count : 0) + " joint matrices for a skin of " +
                                                       std::to_string(skeleton_.skin.joints.size()) + " joints");
    const std::string joint = overflowingJoint(matrices, count);
    if (!joint.empty())
        return Status(StatusCode::InvalidArgument, "the joint matrices are not finite: " + joint + "'s is not");
    pendingPositions_.resize(mesh_.positions.size());
    skinLinear(pendingPositions_.data(), mesh_.positions.data(), mesh_.positions.size(), skeleton_.weights, matrices);
    if (Status st = adoptPending("the skinned pose", "the joint matrices overflow it"); !st)
        return st;
    skinMatrices_.assign(matrices, matrices + count);
    return Status::ok();
}

Status Surface::setControlPositions(const glm::vec3* positions, size_t count)
{
    if (!positions || count != mesh_.positions.size())
        return Status(StatusCode::InvalidArgument, std::to_string(positions ? count : 0) + " control positions for " +
                                                       std::to_string(mesh_.positions.size()) + " control vertices");
    pendingPositions_.assign(positions, positions + count);
    if (Status st = adoptPending("the control positions", ""); !st)
        return st;
    skinMatrices_.clear();
    return Status::ok();
}

Status Surface::evaluate(glm::vec3* positions, glm::vec3* normals, size_t count, int threads)
{
    if (!positions)
        return Status(StatusCode::InvalidArgument, "Surface::evaluate: no position buffer");
    if (count != vertexCount())
        return Status(StatusCode::InvalidArgument, "buffers of " + std::to_string(count) + " vertices for a surface of " +
                                                       std::to_string(vertexCount()) + " refined vertices");
    return frame_->evaluate(positions, normals, nullptr, controlPositions_.data(), controlNormals_.data(),
                            controlPositions_.size(), threads < 1 ? 1 : threads);
}

const AdaptiveFrame& Surface::adaptiveFrame()
{
    if (!adaptive_)
        adaptive_ = std::make_unique<AdaptiveFrame>(*plan_);
    return *adaptive_;
}

Status Surface::setFaceLevels(const uint8_t* levels, size_t count)
{
    adaptiveFrame();
    return adaptive_->setLevels(levels, count);
}

Status Surface::setQuarterLevels(const uint8_t* quarters, size_t count)
{
    adaptiveFrame();
    return adaptive_->setQuarterLevels(quarters, count);
}

const FaceLevelErrors& Surface::faceLevelErrors()
{
    if (!chooser_) {
        chooser_ = std::make_unique<LevelChooser>();
        std::vector<glm::vec3> restNormals(mesh_.positions.size(), glm::vec3(0.0f));
        computeControlNormals(restNormals.data(), mesh_.positions.data(), mesh_.positions.size(), mesh_.triangles.data(),
                              mesh_.faceCount());
        // A plan that is no grid per face (never from Plan::create) has no
        // levels to choose: the errors stay empty, and choosing is refused.
        if (!chooser_->init(*plan_, nullptr, mesh_.positions.data(), restNormals.data(), mesh_.positions.size()))
            chooser_ = std::make_unique<LevelChooser>();
    }
    return chooser_->errors();
}

Status Surface::chooseFaceLevels(const ViewSpec& view, float pixelError)
{
    const FaceLevelErrors& errors = faceLevelErrors();
    if (errors.faceCount != mesh_.faceCount())
        return Status(StatusCode::InvalidData, "the surface's refined faces are not a grid per control face");
    chosen_.resize(4 * errors.faceCount);
    // The frame's levels hold where they still fit, if a choice made them;
    // for the same view, tolerance and pose, they are the choice.
    const bool held = adaptive_ && adaptive_->topologyVersion() == chosenVersion_ &&
                      adaptive_->quarterLevels().size() == chosen_.size();
    const bool sameView = view.eye == chosenView_.eye && view.target == chosenView_.target &&
                          view.fovYDegrees == chosenView_.fovYDegrees && view.heightPx == chosenView_.heightPx;
    if (held && sameView && pixelError == chosenTolerance_ && poseVersion_ == chosenPose_)
        return Status::ok();
    const float scale = skinMatrices_.empty() ? 1.0f : skinScale(&skinMatrices_[0][0][0], skinMatrices_.size());
    if (Status st = chooser_->choose(chosen_.data(), view, pixelError, controlPositions_.data(), controlPositions_.size(),
                                     scale, controlNormals_.data(), held ? adaptive_->quarterLevels().data() : nullptr,
                                     poseVersion_);
        !st)
        return st;
    chosenView_ = view;
    chosenTolerance_ = pixelError;
    chosenPose_ = poseVersion_;
    // Other levels than drawn set the frame's topology; the same keep it.
    if (!adaptive_ || adaptive_->quarterLevels() != chosen_) {
        if (Status st = setQuarterLevels(chosen_.data(), chosen_.size()); !st) {
            chosenVersion_ = ~uint64_t(0);
            return st;
        }
    }
    chosenVersion_ = adaptive_->topologyVersion();
    return Status::ok();
}

Status Surface::evaluateAdaptive(glm::vec3* positions, glm::vec3* normals, size_t count, int threads)
{
    const AdaptiveFrame& frame = adaptiveFrame();
    if (count != frame.vertexCount())
        return Status(StatusCode::InvalidArgument, "buffers of " + std::to_string(count) + " vertices for an adaptive frame of " +
                                                       std::to_string(frame.vertexCount()) + " vertices");
    return adaptive_->evaluate(positions, normals, nullptr, controlPositions_.data(), controlNormals_.data(),
                               controlPositions_.size(), threads < 1 ? 1 : threads);
}

}  // namespace strata
