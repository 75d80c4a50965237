// Fuzz target: the embedded displacement image (16- or 8-bit grey PNG).
#include "strata/io/png.h"

#include <cstddef>
#include <cstdint>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    int width = 0, height = 0, bits = 0;
    std::vector<uint16_t> samples;
    strata::io::decodePngGray(data, size, "fuzz.png", &width, &height, &bits, &samples);
    return 0;
}
