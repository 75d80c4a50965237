// A complete engine-side program over Strata's C++ API: load a rig, make
// its Surface (the rig's scheme, displacement and recommended level), pose
// it, evaluate a frame into the program's own buffers and write it as OBJ.
//
//   strata-example-engine RIG.glb OUT.obj [ANIMATION TIME]
//
// Built and run by the tests, which compare OUT.obj's vertices with
// strata-reconstruct's (the same surface, bit for bit).  Link Strata::io.
#include <strata/io/rig_io.h>
#include <strata/surface.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

int main(int argc, char** argv)
{
    if (argc != 3 && argc != 5) {
        std::fprintf(stderr, "usage: %s RIG.glb OUT.obj [ANIMATION TIME]\n", argv[0]);
        return 2;
    }
    // The rig, and its map when it samples one (a per-vertex rig has none).
    strata::Rig rig;
    strata::DisplacementMap map;
    strata::Status st = strata::io::loadRig(argv[1], &rig);
    if (st && strata::rigNeedsMap(rig))
        st = strata::io::loadRigDisplacementMap(argv[1], rig, &map);
    // The surface, once: refuses a rig whose layer a tool dropped.
    std::unique_ptr<strata::Surface> surface;
    if (st)
        st = strata::Surface::create(&surface, rig, &map);
    // A frame: pose, then positions and normals into our own buffers.
    if (st && argc == 5)
        st = surface->setAnimationTime(std::atoi(argv[3]), float(std::atof(argv[4])));
    std::vector<glm::vec3> positions, normals;
    if (st) {
        positions.resize(surface->vertexCount());
        normals.resize(surface->vertexCount());
        st = surface->evaluate(positions.data(), normals.data(), positions.size());
    }
    if (!st) {
        std::fprintf(stderr, "error: %s\n", st.message().c_str());
        return 1;
    }
    std::FILE* out = std::fopen(argv[2], "w");
    if (!out) {
        std::fprintf(stderr, "error: cannot write %s\n", argv[2]);
        return 1;
    }
    for (const glm::vec3& p : positions)
        std::fprintf(out, "v %.9g %.9g %.9g\n", double(p.x), double(p.y), double(p.z));
    for (const glm::vec3& n : normals)
        std::fprintf(out, "vn %.9g %.9g %.9g\n", double(n.x), double(n.y), double(n.z));
    const std::vector<uint32_t>& t = surface->triangles();
    for (size_t i = 0; i < t.size(); i += 3)
        std::fprintf(out, "f %u//%u %u//%u %u//%u\n", t[i] + 1, t[i] + 1, t[i + 1] + 1, t[i + 1] + 1, t[i + 2] + 1,
                     t[i + 2] + 1);
    std::fprintf(stderr, "level %d, %zu vertices, %zu triangles -> %s\n", surface->level(), positions.size(),
                 surface->triangleCount(), argv[2]);
    return std::fclose(out) == 0 ? 0 : 1;
}
