// Fuzz target: the paper's joint file (JSON).
#include "strata/io/joint_file.h"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    strata::Skeleton skeleton;
    strata::io::parseJointFile(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json", &skeleton);
    return 0;
}
