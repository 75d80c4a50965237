// The command-line tools: success paths and bad input (one-line error naming
// the file, exit code 2, no output left behind).
#include "test_util.h"

namespace {

using Result = strata::test::CommandResult;
Result run(const std::string& command)
{
    return strata::test::runCommand(command);
}

const std::string demo = STRATA_DEMO_EXE;
const std::string reconstruct = STRATA_RECONSTRUCT_EXE;

}  // namespace

TEST(Tools, DemoThenReconstructEveryFormat)
{
    const std::string dir = strata::test::tempDir("tools_demo");
    Result r = run(demo + " --out '" + dir + "' --max-level 3 --size 256");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("wrote"), std::string::npos) << r.output;
    ASSERT_TRUE(strata::test::fileExists(dir + "/head.glb"));
    ASSERT_TRUE(strata::test::fileExists(dir + "/head.exr"));
    for (const char* ext : {"obj", "ply", "glb"}) {
        const std::string out = dir + "/out." + ext;
        r = run(reconstruct + " '" + dir + "/head.glb' --level 2 --scheme smooth -o '" + out + "'");
        EXPECT_EQ(r.code, 0) << r.output;
        EXPECT_TRUE(strata::test::fileExists(out)) << out;
    }
}

TEST(Tools, ReconstructRejectsBadInputWithExitCode2)
{
    const std::string dir = strata::test::tempDir("tools_bad");
    ASSERT_EQ(run(demo + " --out '" + dir + "' --max-level 0 --size 256").code, 0);
    struct Case {
        std::string args, needle;
    };
    const Case cases[] = {
        {"'" + dir + "/missing.glb' -o '" + dir + "/o.obj'", "missing.glb"},
        {"'" + dir + "/head.glb' --level 9 -o '" + dir + "/o.obj'", "--level"},
        {"'" + dir + "/head.glb' --scheme cubic -o '" + dir + "/o.obj'", "--scheme"},
        {"'" + dir + "/head.glb' -o '" + dir + "/o.xyz'", "unknown output format"},
        {"'" + dir + "/head.glb' -o '" + dir + "/head.glb/sub/o.obj'", "cannot create the output folder"},
        {"'" + dir + "/head.glb'", "-o OUTPUT"},
        {"'" + dir + "/head.glb' --bogus -o '" + dir + "/o.obj'", "unknown option"},
    };
    for (const Case& c : cases) {
        const Result r = run(reconstruct + " " + c.args);
        EXPECT_EQ(r.code, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find("strata-reconstruct: error:"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(c.needle), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_FALSE(strata::test::fileExists(dir + "/o.obj"));
    }
    // The map travels inside the rig: the EXR beside it is for pipelines only.
    ASSERT_EQ(std::remove((dir + "/head.exr").c_str()), 0);
    const Result r = run(reconstruct + " '" + dir + "/head.glb' -o '" + dir + "/o.obj'");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(strata::test::fileExists(dir + "/o.obj"));
}
