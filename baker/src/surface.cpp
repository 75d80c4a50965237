// The surface the baker maps onto, built with the runtime's own code
// (computeControlNormals, Plan) so that what is baked is what is drawn.
#include "strata/baker/surface.h"
#include "plans.h"

#include "strata/normals.h"

#include <algorithm>

namespace strata {
namespace baker {

bool BakeSurface::edgeAdjacent(uint32_t a, uint32_t b) const
{
    int shared = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            shared += triangles[3 * size_t(a) + i] == triangles[3 * size_t(b) + j];
    return shared >= 2;
}

Status buildBakeSurface(BakeSurface* out, const ControlMesh& control, Scheme scheme, int denseLevel)
{
    Status st = validateControlMesh(control);
    if (!st)
        return st;
    if (!control.hasUVs())
        return Status(StatusCode::InvalidArgument, "the control mesh has no UVs to bake into");
    BakeSurface s;
    if (scheme == Scheme::Linear) {
        s.positions = control.positions;
        s.normals.resize(control.positions.size());
        computeControlNormals(s.normals.data(), control.positions.data(), control.positions.size(),
                              control.triangles.data(), control.faceCount());
        s.triangles = control.triangles;
        s.uvs = control.uvs;
        s.uvIndices = control.uvIndices;
    } else {
        std::unique_ptr<Plan> plan;
        if (!(st = createPlan(&plan, control, Scheme::Smooth, denseLevel)))
            return st;
        const size_t n = plan->refinedVertexCount();
        s.positions.resize(n);
        s.normals.resize(n);
        if (!(st = plan->evaluate(s.positions.data(), s.normals.data(), 0, n, control.positions.data(), nullptr,
                                  control.positions.size())))
            return st;
        s.triangles = plan->refinedTriangles();
        plan->refinedUVs(&s.uvs, &s.uvIndices);
    }
    // Vertex -> face rings (the runtime's, ascending faces).
    buildVertexFaces(&s.ringOffsets, &s.ringFaces, s.triangles.data(), s.faceCount(), s.positions.size());
    *out = std::move(s);
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
