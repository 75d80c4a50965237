// Strata io: the paper's joint hierarchy file (JSON), see docs/FORMAT.md.
//
// For a bare control mesh with no skin: joint names, parents and rest
// positions, plus optional keyframed joint rotations and translations.  It
// loads as a Skeleton whose skin joints are the file's joints (bind pose =
// the rest positions), so the same Animator plays it with the paper's
// segment deformer, and bindSkeletonWeights turns it into glTF skin weights.
#pragma once

#include <filesystem>

#include "strata/animation.h"
#include "strata/status.h"

#include <string>

namespace strata {
namespace io {

/// Parses a joint file into a checked skeleton without weights (call
/// bindSkeletonWeights with the control mesh next).  Unknown or duplicate
/// names, a parent cycle, coincident joints, non-finite numbers and
/// decreasing key times are errors naming the file and the joint.
Status loadJointFile(const std::filesystem::path& path, Skeleton* out);

/// loadJointFile from text already in memory; `name` is used in messages.
Status parseJointFile(const std::string& text, const std::string& name, Skeleton* out);

}  // namespace io
}  // namespace strata
