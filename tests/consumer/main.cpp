// Uses only the core runtime: refine a tetrahedron to level 2 and displace it.
#include <strata/normals.h>
#include <strata/plan.h>

#include <cstdio>

int main()
{
    strata::ControlMesh mesh;
    mesh.positions = {{1, 1, 1}, {-1, -1, 1}, {-1, 1, -1}, {1, -1, -1}};
    mesh.triangles = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
    std::unique_ptr<strata::Plan> plan;
    strata::Status st = strata::Plan::create(&plan, mesh, strata::Scheme::Linear, 2);
    if (!st) {
        std::fprintf(stderr, "%s\n", st.message().c_str());
        return 1;
    }
    std::vector<glm::vec3> normals(4), out(plan->refinedVertexCount());
    strata::computeControlNormals(normals.data(), mesh.positions.data(), 4, mesh.triangles.data(), 4);
    st = plan->evaluate(out.data(), nullptr, 0, out.size(), mesh.positions.data(), normals.data(), 4);
    std::printf("%zu vertices, %zu triangles\n", out.size(), plan->refinedFaceCount());
    return st && out.size() == 34 && plan->refinedFaceCount() == 64 ? 0 : 1;
}
