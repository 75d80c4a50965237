// Fuzz target: the bake's input stage on a control mesh and a capture from
// bytes.  The input is two OBJ files separated by a line "#capture"; the
// control goes through what strata-bake does to a cage before baking
// (validation, boundary counting, hole closing, topology statistics, the
// fingerprint its layer records), the capture through the same reader.
#include "strata/baker/mesh_input.h"
#include "strata/io/mesh_io.h"

#include <cstddef>
#include <cstdint>
#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    using namespace strata;
    static const char kSplit[] = "\n#capture\n";
    const uint8_t* split = nullptr;
    for (size_t i = 0; i + sizeof(kSplit) - 1 <= size && !split; ++i)
        if (std::memcmp(data + i, kSplit, sizeof(kSplit) - 1) == 0)
            split = data + i;
    const size_t controlSize = split ? size_t(split - data) : size;
    ControlMesh control;
    if (io::parseObj(data, controlSize, "control.obj", &control).isOk()) {
        (void)computeTopologyStats(control.triangles.data(), control.faceCount());
        (void)baker::countBoundaryEdges(control.triangles.data(), control.faceCount());
        if (validateControlMesh(control).isOk()) {
            ControlMesh closed = control;
            if (baker::closeBoundaryLoops(&closed) > 0 && !validateControlMesh(closed).isOk())
                __builtin_trap();  // closing holes must leave a valid cage
            (void)fingerprintControlMesh(closed);
        }
    }
    if (split) {
        const uint8_t* capture = split + sizeof(kSplit) - 1;
        ControlMesh high;
        if (io::parseObj(capture, size_t(data + size - capture), "capture.obj", &high).isOk())
            (void)baker::countBoundaryEdges(high.triangles.data(), high.faceCount());
    }
    return 0;
}
