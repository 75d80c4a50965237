// Strata GL: the evaluator's embedded shaders (shaders/*.glsl) and program
// building.
//
// Every program is "#version 450 core", the caller's defines, the shared
// displacement_math.h (the very header the CPU runtime compiles), the map
// sampler (sample_map.glsl), then the stage's own source.  samplingPrelude()
// gives the same start to an engine's own shaders.
#pragma once

#include "strata/gl/gl.h"
#include "strata/status.h"

#include <string>
#include <vector>

namespace strata {
namespace gl {

enum class ShaderId { Refine, Displace, Normals };

/// Full source of one of the evaluator's stages, ready for glShaderSource.
std::string shaderSource(ShaderId id, const std::string& defines = std::string());

/// "#version 450 core", `defines`, the shared displacement math and the
/// map sampler: the start of any shader that samples a rig's displacement
/// itself (strata_sample_displacement(uv, vertex); Evaluator::bindSampling
/// sets what it reads).
std::string samplingPrelude(const std::string& defines = std::string());

struct StageSource {
    GLenum stage;
    std::string source;
};

/// Compiles and links; on failure the message names `label` and carries
/// the driver's log.  `feedbackVaryings`: transform feedback outputs
/// (interleaved) captured by this program.
Status buildProgram(GLuint* program, const std::string& label, const std::vector<StageSource>& stages,
                    const std::vector<const char*>& feedbackVaryings = {});

}  // namespace gl
}  // namespace strata
