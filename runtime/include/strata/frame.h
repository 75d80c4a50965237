// Strata runtime: a render-ready frame (displaced positions and shading
// normals) on several threads.
//
// Plan::evaluate is range-parallel as it is; shading normals are a scatter
// over faces, which is not.  On one thread a frame is Plan::evaluate and
// Plan::computeShadingNormals.  On N threads it runs three range-parallel
// passes:
//   1. Plan::evaluate over vertex ranges;
//   2. face normals (cross products, twice the area) over face ranges;
//   3. per vertex, the sum of its faces' normals in face order (a vertex ->
//      faces table built on first use, 4 bytes per face corner), normalised.
// Pass 3 adds in the scatter's order, so the normals are bit-identical to
// Plan::computeShadingNormals for any thread count.
#pragma once

#include "strata/plan.h"
#include "strata/status.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace strata {

class FrameEvaluator {
public:
    /// For `plan`, which must outlive the evaluator.
    explicit FrameEvaluator(const Plan& plan);

    /// One frame: positions (and, when normals is not null, shading normals)
    /// of every refined vertex, on `threads` threads (1: the calling thread
    /// only).  displacements: the plan's own when null.  Arguments as
    /// Plan::evaluate.  Not re-entrant (the face normals are shared scratch);
    /// allocates only on the first multi-threaded frame with normals.
    Status evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                    const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                    int threads);

    size_t bytes() const;

private:
    void buildFaceTable();
    void faceNormals(const glm::vec3* positions, size_t begin, size_t end);
    void vertexNormals(glm::vec3* dst, size_t begin, size_t end) const;

    const Plan& plan_;
    std::vector<uint32_t> offsets_, faces_;  // each refined vertex's faces, ascending (built on first use)
    std::vector<glm::vec3> faceNormals_;
};

}  // namespace strata
