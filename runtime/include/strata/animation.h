// Strata runtime: skeletons, glTF animation sampling and skinning of the
// control mesh (paper section 2.4: the skeleton moves, the control mesh
// deforms, the detail follows through the unchanged barycentric samples).
//
// Plain data plus free functions over caller-owned arrays; the Animator
// bundles the per-frame scratch so a frame allocates nothing.
#pragma once

#include "strata/control_mesh.h"
#include "strata/status.h"

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace strata {

struct NodeTransform {
    glm::vec3 translation{0.0f};
    glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};  // w, x, y, z
    glm::vec3 scale{1.0f};
};

struct SkeletonNode {
    std::string name;
    int parent = -1;
    NodeTransform rest;            ///< glTF TRS in its parent's space
    bool hasMatrix = false;        ///< glTF `matrix` node (never animated)
    glm::mat4 matrix{1.0f};
};

enum class AnimationPath { Translation, Rotation, Scale };
enum class AnimationInterpolation { Linear, Step, CubicSpline };

struct AnimationChannel {
    int node = -1;
    AnimationPath path = AnimationPath::Translation;
    AnimationInterpolation interpolation = AnimationInterpolation::Linear;
    std::vector<float> times;   ///< non-decreasing key times (s)
    std::vector<float> values;  ///< 3 or 4 floats per key; CubicSpline: in-tangent, value, out-tangent per key
};

struct Animation {
    std::string name;
    std::vector<AnimationChannel> channels;
    float start = 0.0f, end = 0.0f;  ///< key range (s)
};

/// Per-vertex skin influences: `influences` (4 or 8) joint slots per vertex.
struct VertexWeights {
    int influences = 0;
    std::vector<uint16_t> joints;  ///< index into Skin::joints
    std::vector<float> weights;    ///< sum to 1 per vertex
};

struct Skin {
    std::vector<int> joints;                       ///< node index per joint
    std::vector<glm::mat4> inverseBindMatrices;    ///< one per joint
};

struct Skeleton {
    std::vector<SkeletonNode> nodes;
    std::vector<int> order;        ///< node indices, parents before children
    Skin skin;
    VertexWeights weights;         ///< per control vertex
    std::vector<Animation> animations;
    int meshNode = -1;             ///< the node that instances the skinned mesh, if it is one of `nodes`

    bool empty() const { return skin.joints.empty(); }
};

/// Checks node parents (in range, acyclic) and fills `order`; checks skin
/// joints, inverse bind matrix count, weights against vertexCount, channel
/// targets and key arrays.  Messages name the offending item.
Status finalizeSkeleton(Skeleton* skeleton, size_t vertexCount);

/// Finds an animation by name, or by index when `key` is a number.  -1 if none.
int findAnimation(const Skeleton& skeleton, const std::string& key);

/// Local transforms at `time` (clamped to the key range): starts from every
/// node's rest transform and applies the animation's channels (LINEAR with
/// normalised slerp for rotations, STEP, CUBICSPLINE Hermite).
/// \param local  skeleton.nodes.size() transforms (caller-owned)
void sampleAnimation(NodeTransform* local, const Skeleton& skeleton, const Animation* animation, float time);

/// World matrices from local transforms, in `order`.
void computeWorldMatrices(glm::mat4* world, const Skeleton& skeleton, const NodeTransform* local);

/// Skin matrices: world(joint) * inverseBind(joint), one per joint.
void computeSkinMatrices(glm::mat4* skinMatrices, const Skeleton& skeleton, const glm::mat4* world);

/// Linear blend skinning, dual quaternions, or the paper's point-to-line
/// segment deformer (eq. 6, segment_deformer.h), which ignores the weights.
enum class SkinningMethod { Linear, DualQuaternion, Segments };

/// Linear blend skinning of n control positions.
void skinLinear(glm::vec3* dst, const glm::vec3* rest, size_t n, const VertexWeights& weights,
                const glm::mat4* skinMatrices);

/// Dual-quaternion skinning (Kavan et al. 2007): rigid parts of the skin
/// matrices blended as unit dual quaternions, so twisted joints keep their
/// volume (no candy-wrapper collapse).  Scale in skin matrices is ignored.
/// \param scratch  joint-count * 8 floats (caller-owned)
void skinDualQuaternion(glm::vec3* dst, const glm::vec3* rest, size_t n, const VertexWeights& weights,
                        const glm::mat4* skinMatrices, size_t jointCount, float* scratch);

/// Everything a frame needs, sized once: pose the skeleton at (animation,
/// time), skin the control vertices and recompute their normals with the
/// same computeControlNormals the baker uses.  pose() allocates nothing.
class Animator {
public:
    Animator();
    ~Animator();
    Animator(Animator&&) noexcept;
    Animator& operator=(Animator&&) noexcept;

    /// \pre skeleton was finalised for mesh.vertexCount(); both outlive the animator.
    Status init(const Skeleton& skeleton, const ControlMesh& mesh);

    /// animation -1: the rest pose of the nodes (no channel applied).
    Status pose(int animation, float time, SkinningMethod method = SkinningMethod::Linear);

    const std::vector<glm::vec3>& positions() const { return positions_; }
    const std::vector<glm::vec3>& normals() const { return normals_; }
    const std::vector<glm::mat4>& skinMatrices() const { return skinMatrices_; }

    /// Why SkinningMethod::Segments is unavailable (ok when it is): it needs
    /// a skin with at least one joint whose parent is a joint.  The paper's
    /// deformer is bound on first use (this, or a pose with it), not by init.
    const Status& segmentStatus() const;

    /// The stages of pose(), for benchmarks: sample + world + skin matrices,
    /// vertex skinning, control normals.
    void sample(int animation, float time);
    void skin(SkinningMethod method);
    void updateNormals();

private:
    const Skeleton* skeleton_ = nullptr;
    const ControlMesh* mesh_ = nullptr;
    std::vector<NodeTransform> local_;
    std::vector<glm::mat4> world_, skinMatrices_;
    std::vector<float> dualQuaternions_;
    std::vector<glm::vec3> positions_, normals_;
    struct Segments;
    mutable std::unique_ptr<Segments> segments_;  // bound on first use
    mutable Status segmentStatus_;
};

}  // namespace strata
