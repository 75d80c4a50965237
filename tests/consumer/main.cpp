// Uses only the core runtime: a tetrahedron assembled in memory, its
// Surface at level 2 (34 vertices, 64 triangles), posed by control
// positions, evaluated into our own buffers.
#include <strata/surface.h>

#include <cstdio>

int main()
{
    strata::Rig rig;
    rig.mesh.positions = {{1, 1, 1}, {-1, -1, 1}, {-1, 1, -1}, {1, -1, -1}};
    rig.mesh.triangles = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
    strata::SurfaceOptions options;
    options.level = 2;
    std::unique_ptr<strata::Surface> surface;
    strata::Status st = strata::Surface::create(&surface, rig, nullptr, options);
    std::vector<glm::vec3> moved = rig.mesh.positions, out;
    for (glm::vec3& p : moved)
        p *= 2.0f;
    if (st)
        st = surface->setControlPositions(moved.data(), moved.size());
    if (st) {
        out.resize(surface->vertexCount());
        st = surface->evaluate(out.data(), nullptr, out.size());
    }
    if (!st) {
        std::fprintf(stderr, "%s\n", st.message().c_str());
        return 1;
    }
    std::printf("%zu vertices, %zu triangles\n", out.size(), surface->triangleCount());
    // The scaled tetrahedron's vertices are the first four refined ones.
    return out.size() == 34 && surface->triangleCount() == 64 && out[0] == moved[0] ? 0 : 1;
}
