// Fuzz target: a rig as .glb or .gltf bytes (JSON, buffers, data URIs, the
// strata block, the embedded map), then, when it loads, its materials (images
// decoded, COLOR_0 read), its map and a small reconstruction.  Built with
// -DSTRATA_FUZZ=ON (tools/fuzz.sh).
#include "strata/io/materials.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"

#include <cstddef>
#include <cstdint>
#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    using namespace strata;
    const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
    Rig rig;
    if (!io::loadRigFromMemory(data, size, binary, binary ? "fuzz.glb" : "fuzz.gltf", &rig))
        return 0;
    // Its materials (images decoded, COLOR_0 read) as the viewer and the
    // bake read them.
    io::SceneMaterials materials;
    std::vector<std::string> warnings;
    io::loadSceneMaterials(rig, &materials, &warnings);
    io::featuresNotCarried(rig, 0);
    DisplacementMap map;
    const bool haveMap = rig.hasDisplacement && rig.displacement.image >= 0 &&
                         io::loadRigDisplacementMap("fuzz.glb", rig, &map).isOk();
    if (rig.mesh.faceCount() <= 4096) {
        io::Reconstruction rec;
        io::Pose pose;
        pose.animation = rig.skeleton.animations.empty() ? -1 : 0;
        pose.time = 0.25f;
        io::reconstruct(&rec, rig, haveMap ? &map : nullptr, rig.displacement.scheme, 1, 1.0f, &pose);
    }
    return 0;
}
