// Strata runtime: the paper's own skeleton deformer (section 2.4, eq. 6,
// after Sun et al. [17]) for control meshes that come with a bare joint
// hierarchy instead of skin weights.
//
// Each control vertex is registered once, in the bind pose, to one skeleton
// segment (o_j, o_k) by a point-to-line mapping (alpha, d, n):
//
//     v = alpha o_j + (1 - alpha) o_k + d (alpha n_j + (1 - alpha) n_k)    (6)
//
// n is the unit direction from the segment to the vertex, perpendicular to
// the segment; n_j and n_k are n carried along the segment into the joint
// planes at o_j and o_k.  A joint plane bisects the angle between the two
// segments that meet at the joint (perpendicular to the segment at an end or
// a branch), so the planes move with the joints and the two segments sharing
// a joint deform the surface continuously across it.  n_j keeps a unit
// component perpendicular to the segment, so d is exactly the vertex's
// distance from the segment's line.  Near acute joints a vertex on the outer
// side would be carried away from the joint; it is scaled back towards the
// segment so that its distance from the segment stays what it was in the bind
// pose (the paper's rounding of the joint).
//
// Joints are a skin's joints; their motion comes as skin matrices (posed
// world * inverse bind), the same input linear blend skinning takes, so the
// deformer runs from glTF node animations and from a joint file's keyframes.
#pragma once

#include "strata/animation.h"
#include "strata/control_mesh.h"
#include "strata/status.h"

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace strata {

struct SkeletonSegment {
    int from = -1, to = -1;  ///< joint indices: o_j (parent) and o_k (child)
    int before = -1;         ///< the joint before `from` (its parent) or -1: start plane bisects (before, from, to)
    int after = -1;          ///< the only child of `to` or -1: end plane bisects (from, to, after)
};

struct SegmentBinding {
    std::vector<glm::vec3> bindJoints;        ///< joint positions in the bind pose
    std::vector<SkeletonSegment> segments;
    std::vector<uint32_t> segment;             ///< per vertex
    std::vector<float> alpha;                  ///< eq. 6: 1 at o_j, 0 at o_k
    std::vector<float> distance;               ///< d, distance from the segment's line
    std::vector<float> reach;                  ///< bind-pose distance from the segment itself
    std::vector<glm::vec3> direction;          ///< n, unit, bind space, perpendicular to the segment
    bool keepDistance = true;                  ///< the acute-joint scaling

    size_t vertexCount() const { return segment.size(); }
};

/// Registers n vertices to the segments of a joint hierarchy.  A segment joins
/// every joint to its parent; a vertex goes to the segment whose joint planes
/// enclose it (alpha in [0, 1]) at the smallest distance, else to the nearest.
/// \param parents  per joint, the parent joint index or -1
Status bindSegments(SegmentBinding* binding, const glm::vec3* joints, const int* parents, size_t jointCount,
                    const glm::vec3* positions, size_t n);

/// Per-frame scratch: posed joints and joint-plane normals per segment end.
struct SegmentPose {
    std::vector<glm::vec3> joints, startPlane, endPlane;
};

/// Eq. 6 in the pose given by one skin matrix per joint (posed world *
/// inverse bind).  `pose` is resized on first use only.
void deformSegments(glm::vec3* dst, const SegmentBinding& binding, const glm::mat4* skinMatrices,
                    SegmentPose* pose);

/// Standard skin weights that approximate the binding for any glTF viewer:
/// a vertex follows the joint that starts its segment, blended half-and-half
/// at each joint plane with the neighbouring segment's joint over a width
/// equal to the vertex's distance from the bone (so joints bend round).
void segmentSkinWeights(VertexWeights* weights, const SegmentBinding& binding, const int* parents);

/// The skeleton's skin joints as a hierarchy: bind positions (from the
/// inverse bind matrices) and, per joint, the nearest ancestor node that is
/// also a skin joint (-1 if none).
void skinJointHierarchy(std::vector<glm::vec3>* positions, std::vector<int>* parents, const Skeleton& skeleton);

/// Fills skeleton->weights from the paper's point-to-line binding of the
/// mesh's vertices to the skin's joints, then finalises the skeleton.  For a
/// joint file: turns a bare skeleton into one any glTF viewer can play.
Status bindSkeletonWeights(Skeleton* skeleton, const ControlMesh& mesh);

}  // namespace strata
