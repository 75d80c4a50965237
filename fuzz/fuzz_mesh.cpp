// Fuzz target: the mesh readers (OBJ, PLY, OFF, STL).  The first byte picks
// the format; the rest is the file.
#include "strata/io/mesh_io.h"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    using namespace strata;
    if (size < 1)
        return 0;
    const uint8_t kind = data[0] % 4;
    ++data;
    --size;
    if (kind == 0) {
        ControlMesh mesh;
        io::ObjReadInfo info;  // its vertex colours too
        io::parseObj(data, size, "fuzz.obj", &mesh, &info);
    } else {
        static const char* const formats[] = {".ply", ".off", ".stl"};
        io::PolygonMesh mesh;
        io::parsePolygonMesh(data, size, formats[kind - 1], "fuzz", &mesh);
    }
    return 0;
}
