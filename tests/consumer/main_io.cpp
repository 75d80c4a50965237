// Uses the io adapter: write and read back a rig.
#include <strata/io/rig_io.h>

#include <cstdio>

int main(int argc, char** argv)
{
    if (argc < 2)
        return 1;
    strata::Rig rig;
    rig.mesh.positions = {{1, 1, 1}, {-1, -1, 1}, {-1, 1, -1}, {1, -1, -1}};
    rig.mesh.triangles = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
    const std::string path = std::string(argv[1]) + "/tetra.glb";
    strata::Status st = strata::io::saveRig(path, rig);
    strata::Rig back;
    if (st)
        st = strata::io::loadRig(path, &back);
    if (!st) {
        std::fprintf(stderr, "%s\n", st.message().c_str());
        return 1;
    }
    std::printf("round-tripped %zu vertices\n", back.mesh.positions.size());
    return back.mesh.positions.size() == 4 ? 0 : 1;
}
