// Strata runtime: a render-ready frame (displaced positions and shading
// normals) on several threads.
//
// Plan::evaluate is range-parallel as it is; shading normals are a scatter
// over faces, which is not.  A FrameEvaluator keeps what makes them
// parallel: each refined vertex's faces (in face order) and a face-normal
// scratch, so a frame runs in three range-parallel passes:
//   1. Plan::evaluate over vertex ranges,
//   2. face normals (cross products, twice the area) over face ranges,
//   3. per vertex, the sum of its faces' normals in face order, normalised.
// Pass 3 adds in the same order as Plan::computeShadingNormals' scatter,
// so the normals are bit-identical to it for any thread count.
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
    /// Builds the vertex -> faces table (4 bytes per refined face corner)
    /// for `plan`, which must outlive the evaluator.
    explicit FrameEvaluator(const Plan& plan);

    /// One frame: positions (and, when normals is not null, shading normals)
    /// of every refined vertex, on `threads` threads (1: the calling thread
    /// only).  displacements: the plan's own when null.  Arguments as
    /// Plan::evaluate.  Not re-entrant (the face-normal scratch is shared).
    Status evaluate(glm::vec3* positions, glm::vec3* normals, const float* displacements,
                    const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount,
                    int threads);

    /// The passes, for callers with their own thread pool: face normals of
    /// faces [begin, end), then vertex normals of vertices [begin, end).
    void faceNormals(const glm::vec3* positions, size_t begin, size_t end);
    void vertexNormals(glm::vec3* dst, size_t begin, size_t end) const;

    size_t bytes() const;

private:
    const Plan& plan_;
    std::vector<uint32_t> offsets_, faces_;  // CSR: the faces of each refined vertex, ascending
    std::vector<glm::vec3> faceNormals_;
};

}  // namespace strata
