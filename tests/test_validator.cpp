// Every glTF the project writes (rigs, reconstructions, a character's
// automatic rig) passes the Khronos glTF-Validator with 0 errors and 0
// warnings (node + npm gltf-validator, installed by
// cmake/install-deps.sh).
#include "procedural.h"
#include "strata/baker/bake_rig.h"
#include "strata/io/exr.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "test_rigs.h"


using namespace strata;


TEST(GltfValidator, EveryFileTheProjectWritesIsClean)
{
    ASSERT_TRUE(test::fileExists(std::string(STRATA_VALIDATOR_MODULES) + "/gltf-validator/package.json"))
        << "gltf-validator is not installed; run cmake/install-deps.sh";
    const std::string dir = test::tempDir("validator");
    Rig rig;
    DisplacementMap map;
    ASSERT_NO_FATAL_FAILURE(test::makeExampleRig(&rig, &map));
    rig.displacement.uri = "rig.exr";
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/rig.exr", map).isOk());
    std::vector<std::string> files = {dir + "/rig.glb", dir + "/rig.gltf"};
    ASSERT_TRUE(io::saveRig(files[0], rig).isOk());
    ASSERT_TRUE(io::saveRig(files[1], rig).isOk());
    // A rig without UVs or displacement, and reconstructions in both schemes.
    Rig plain;
    plain.mesh = examples::makeIcosphere(0);
    files.push_back(dir + "/plain.glb");
    ASSERT_TRUE(io::saveRig(files.back(), plain).isOk());
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        io::Reconstruction rec;
        // The displacement only in the scheme it was baked against.
        ASSERT_TRUE(io::reconstruct(&rec, rig, scheme == rig.displacement.scheme ? &map : nullptr, scheme, 3).isOk());
        files.push_back(dir + "/level3_" + schemeName(scheme) + ".glb");
        ASSERT_TRUE(io::writeReconstruction(files.back(), rec).isOk());
    }
    // A character through --control auto: skin, animations and its flat
    // colours re-baked as an indexed PNG.
    STRATA_REQUIRE_DATA(fox, "Fox.glb");
    baker::BakeRequest request;
    request.high = fox;
    request.control = "auto";
    request.controlFaces = 200;
    request.output = dir + "/fox_rig.glb";
    baker::BakeResult result;
    ASSERT_TRUE(baker::bakeRig(request, &result).isOk());
    files.push_back(request.output);
    int code = 0;
    const std::string report = test::runGltfValidator(files, &code);
    EXPECT_EQ(code, 0) << report;
    EXPECT_NE(report.find("0 errors, 0 warnings"), std::string::npos) << report;
}
