// Uses the GPU evaluator from an installed package: links Strata::gl and,
// given a GL 4.5 context (headless EGL), evaluates a refined tetrahedron.
#include <strata/gl/context.h>
#include <strata/gl/evaluator.h>
#include <strata/normals.h>

#include <cstdio>

int main()
{
    std::unique_ptr<strata::gl::HeadlessContext> context;
    strata::Status st = strata::gl::HeadlessContext::create(&context);
    if (!st) {
        std::printf("linked; no GL context here (%s)\n", st.message().c_str());
        return 0;
    }
    strata::ControlMesh mesh;
    mesh.positions = {{1, 1, 1}, {-1, -1, 1}, {-1, 1, -1}, {1, -1, -1}};
    mesh.triangles = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
    std::unique_ptr<strata::Plan> plan;
    std::unique_ptr<strata::gl::Evaluator> evaluator;
    std::vector<glm::vec3> normals(4), positions;
    strata::computeControlNormals(normals.data(), mesh.positions.data(), 4, mesh.triangles.data(), 4);
    if ((st = strata::Plan::create(&plan, mesh, strata::Scheme::Linear, 2)) &&
        (st = strata::gl::Evaluator::create(&evaluator, *plan)) &&
        (st = evaluator->update(mesh.positions.data(), normals.data(), 4)))
        st = evaluator->readPositions(&positions);
    if (!st) {
        std::fprintf(stderr, "%s\n", st.message().c_str());
        return 1;
    }
    std::printf("evaluated %zu vertices on the GPU\n", positions.size());
    return positions.size() == plan->refinedVertexCount() ? 0 : 1;
}
