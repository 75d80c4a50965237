// Fuzz target: the displacement map as OpenEXR bytes (what --exr writes and
// version-1 rigs reference), through the same decoder the file path uses.
#include "strata/io/exr.h"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    strata::DisplacementMap map;
    // A texel budget keeps each run short; the size checks it skips past are
    // the same comparisons, tested in tests/test_exr.cpp.
    strata::io::decodeDisplacementExr(data, size, "fuzz.exr", &map, 0, 0, size_t(1) << 14);
    return 0;
}
