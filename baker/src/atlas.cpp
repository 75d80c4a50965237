// Per-triangle UV atlas, paired into square cells.
#include "strata/baker/atlas.h"

#include <cmath>
#include <string>

namespace strata {
namespace baker {

Status buildTriangleAtlas(ControlMesh* mesh, const AtlasOptions& options)
{
    const size_t nf = mesh->faceCount();
    if (nf == 0)
        return Status(StatusCode::InvalidArgument, "cannot build an atlas for a mesh without faces");
    if (options.mapSize < 8 || options.gutter < 1)
        return Status(StatusCode::InvalidArgument, "atlas map size must be at least 8 and the gutter at least 1");
    const size_t cells = (nf + 1) / 2;
    const int grid = int(std::ceil(std::sqrt(double(cells))));
    const int cell = options.mapSize / grid;  // texels per cell side, integral so corners sit on texel edges
    const int g = options.gutter;
    // Each triangle needs room for gutters on all sides plus a usable interior.
    if (cell < 4 * g + 6)
        return Status(StatusCode::InvalidArgument,
                      "a " + std::to_string(options.mapSize) + " map is too small for " + std::to_string(nf) +
                          " per-triangle charts (" + std::to_string(cell) + " texels per cell); use a larger map");
    const float inv = 1.0f / float(options.mapSize);
    mesh->uvs.clear();
    mesh->uvIndices.resize(nf * 3);
    for (size_t f = 0; f < nf; ++f) {
        const int c = int(f / 2);
        const float x0 = float((c % grid) * cell), y0 = float((c / grid) * cell);
        const float lo = float(g), hi = float(cell - g);
        // Two right triangles per cell; the diagonal gap is 2g texels wide
        // along the axes, so each side keeps a full gutter.
        glm::vec2 corners[3];
        if (f % 2 == 0) {
            corners[0] = {lo, lo};
            corners[1] = {hi - 2.0f * float(g), lo};
            corners[2] = {lo, hi - 2.0f * float(g)};
        } else {
            corners[0] = {hi, hi};
            corners[1] = {lo + 2.0f * float(g), hi};
            corners[2] = {hi, lo + 2.0f * float(g)};
        }
        for (int k = 0; k < 3; ++k) {
            mesh->uvIndices[3 * f + size_t(k)] = uint32_t(mesh->uvs.size());
            mesh->uvs.emplace_back((x0 + corners[k].x) * inv, (y0 + corners[k].y) * inv);
        }
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
