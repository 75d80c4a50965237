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
        r = run(reconstruct + " '" + dir + "/head.glb' --level 2 -o '" + out + "'");
        EXPECT_EQ(r.code, 0) << r.output;
        EXPECT_TRUE(strata::test::fileExists(out)) << out;
    }
    // The rig was baked against the linear scheme: drawn with its
    // displacement in the smooth one it would be another surface.
    r = run(reconstruct + " '" + dir + "/head.glb' --level 2 --scheme smooth -o '" + dir + "/smooth.obj'");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("was baked against the linear scheme"), std::string::npos) << r.output;
    EXPECT_FALSE(strata::test::fileExists(dir + "/smooth.obj"));
    r = run(reconstruct + " '" + dir + "/head.glb' --level 2 --scheme smooth --no-displacement -o '" + dir +
            "/smooth.obj'");
    EXPECT_EQ(r.code, 0) << r.output;
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

namespace {

// A minimal .gltf rig text: one triangle whose POSITION buffer has `uri`.
std::string gltfWithBuffer(const std::string& uri, size_t bytes)
{
    return "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"uri\":\"" + uri + "\",\"byteLength\":" +
           std::to_string(bytes) +
           "}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],\"accessors\":[{\"bufferView\":0,"
           "\"componentType\":5126,\"count\":3,\"type\":\"VEC3\",\"min\":[0,0,0],\"max\":[1,1,0]}],"
           "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],\"nodes\":[{\"mesh\":0}],"
           "\"scenes\":[{\"nodes\":[0]}],\"scene\":0}";
}

}  // namespace

TEST(Tools, HostileRigsAndPathsAreOneLineErrors)
{
    const std::string dir = strata::test::tempDir("tools_hostile");
    ASSERT_EQ(run(demo + " --out '" + dir + "' --max-level 0 --size 256").code, 0);
    using strata::test::writeText;
    // Files outside the rig's folder, and a FIFO beside it.
    writeText(dir + "/secret.bin", std::string(36, 'x'));
    std::system(("mkdir -p '" + dir + "/sub' && mkfifo '" + dir + "/sub/pipe.bin'").c_str());
    writeText(dir + "/sub/absolute.gltf", gltfWithBuffer(dir + "/secret.bin", 36));
    writeText(dir + "/sub/parent.gltf", gltfWithBuffer("../secret.bin", 36));
    writeText(dir + "/sub/fifo.gltf", gltfWithBuffer("pipe.bin", 36));
    writeText(dir + "/sub/scheme.gltf", gltfWithBuffer("file:///etc/passwd", 36));
    // A skin with no joints.
    std::string noJoints =
        gltfWithBuffer("data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA", 36);
    noJoints.replace(noJoints.find("\"nodes\":[{\"mesh\":0}]"), 20, "\"nodes\":[{\"mesh\":0,\"skin\":0}],\"skins\":[{\"joints\":[]}]");
    writeText(dir + "/nojoints.gltf", noJoints);
    struct Case {
        std::string args, needle;
    };
    const std::string rig = "'" + dir + "/head.glb'";
    std::string secretBefore = strata::test::readText(dir + "/secret.bin");
    std::system(("ln -sf '" + dir + "/secret.bin' '" + dir + "/link.obj'").c_str());
    // An accessor claiming 2^31 elements over a 36-byte buffer.
    std::string huge = gltfWithBuffer("data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA", 36);
    huge.replace(huge.find("\"count\":3"), 9, "\"count\":2147483648");
    writeText(dir + "/huge.gltf", huge);
    const Case cases[] = {
        {rig + " -o '" + dir + "/link.obj'", "symbolic link"},
        {"'" + dir + "/huge.gltf' -o '" + dir + "/o.obj'", "huge.gltf"},
        {"'" + dir + "/sub/absolute.gltf' -o '" + dir + "/o.obj'", "absolute.gltf"},
        {"'" + dir + "/sub/parent.gltf' -o '" + dir + "/o.obj'", "parent.gltf"},
        {"'" + dir + "/sub/fifo.gltf' -o '" + dir + "/o.obj'", "fifo.gltf"},
        {"'" + dir + "/sub/scheme.gltf' -o '" + dir + "/o.obj'", "scheme.gltf"},
        {"'" + dir + "/nojoints.gltf' -o '" + dir + "/o.obj'", "no joints"},
        {rig + " --level 12 -o '" + dir + "/o.obj'", "--level"},
        {rig + " -o " + rig, "overwrite the input"},
        {rig + " --level 6 --max-memory 16 -o '" + dir + "/o.obj'", "--max-memory"},
    };
    for (const Case& c : cases) {
        const Result r = run(reconstruct + " " + c.args);
        EXPECT_EQ(r.code, 2) << c.args << "\n" << r.output;
        EXPECT_NE(r.output.find("strata-reconstruct: error:"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(c.needle), std::string::npos) << c.args << "\n" << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        EXPECT_EQ(r.output.find("xxxx"), std::string::npos) << "the outside file's bytes leaked: " << r.output;
        EXPECT_FALSE(strata::test::fileExists(dir + "/o.obj"));
    }
    EXPECT_EQ(strata::test::readText(dir + "/secret.bin"), secretBefore) << "written through the symbolic link";
    // The input rig is intact after the refused overwrite.
    EXPECT_EQ(run(reconstruct + " " + rig + " -o '" + dir + "/o.obj'").code, 0);
    // Paths with spaces and non-ASCII characters are ordinary paths.
    std::system(("mkdir -p '" + dir + "/dossier é'").c_str());
    std::system(("cp '" + dir + "/head.glb' '" + dir + "/dossier é/tête rig.glb'").c_str());
    const Result r = run(reconstruct + " '" + dir + "/dossier é/tête rig.glb' -o '" + dir + "/dossier é/sortie ü.ply'");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(strata::test::fileExists(dir + "/dossier é/sortie ü.ply"));
}

// What tinygltf and nlohmann::json say about a broken file reaches the user
// in Strata's words, on one line, naming the file once: not "glTF Binary",
// "[json.exception.parse_error.101]" or "property is missing in Accessor".
TEST(Tools, LibraryMessagesAreInStrataWords)
{
    const std::string dir = strata::test::tempDir("tools_words");
    ASSERT_EQ(run(demo + " --out '" + dir + "' --max-level 0 --size 256").code, 0);
    using strata::test::writeText;
    const std::string glb = strata::test::readText(dir + "/head.glb");
    writeText(dir + "/cut.glb", glb.substr(0, 300));
    writeText(dir + "/json.gltf", "{\"asset\": ");
    const std::string data = "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";
    writeText(dir + "/missing.gltf", gltfWithBuffer("missing.bin", 36));
    writeText(dir + "/base64.gltf", gltfWithBuffer("data:application/octet-stream;base64,@@@@", 36));
    std::string noCount = gltfWithBuffer(data, 36);
    noCount.replace(noCount.find("\"count\":3,"), 10, "");
    writeText(dir + "/nocount.gltf", noCount);
    std::string negative = gltfWithBuffer(data, 36);
    negative.replace(negative.find("\"count\":3"), 9, "\"count\":-3");
    writeText(dir + "/negative.gltf", negative);
    struct Case {
        std::string file, needle;
    };
    const Case cases[] = {
        {"cut.glb", "not a complete .glb file"},
        {"json.gltf", "not valid JSON (line 1, column"},
        {"missing.gltf", "the external file \"missing.bin\" it refers to is missing"},
        {"base64.gltf", "data: URI is not valid base64"},
        {"nocount.gltf", "an accessor has no \"count\""},
        {"negative.gltf", "\"count\" is not a positive integer"},
    };
    for (const Case& c : cases) {
        const Result r = run(reconstruct + " '" + dir + "/" + c.file + "' -o '" + dir + "/o.obj'");
        EXPECT_EQ(r.code, 2) << c.file << "\n" << r.output;
        EXPECT_NE(r.output.find(c.needle), std::string::npos) << c.file << "\n" << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        EXPECT_EQ(r.output.find(c.file), r.output.rfind(c.file)) << "named twice: " << r.output;
        for (const char* foreign : {"json.exception", "glTF Binary", "property is missing", "File not found"})
            EXPECT_EQ(r.output.find(foreign), std::string::npos) << r.output;
        EXPECT_FALSE(strata::test::fileExists(dir + "/o.obj"));
    }
}

// strata-reconstruct never writes over its input: not through a folder
// that does not exist ("x/../rig.glb", and x is not made), and not as frame
// 0 of a sequence whose name is the input's.
TEST(Tools, ReconstructNeverOverwritesItsInput)
{
    const std::string dir = strata::test::tempDir("tools_overwrite");
    Result r = run(demo + " --out '" + dir + "' --max-level 1 --size 256");
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string rig = strata::test::readText(dir + "/head.glb");
    r = run(reconstruct + " '" + dir + "/head.glb' -o '" + dir + "/x/../head.glb'");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("would overwrite the input"), std::string::npos) << r.output;
    EXPECT_EQ(strata::test::readText(dir + "/head.glb"), rig);
    EXPECT_FALSE(strata::test::fileExists(dir + "/x"));
    // A control OBJ named out_0000.obj, and frames out_NNNN.obj.
    ASSERT_EQ(run(reconstruct + " '" + dir + "/head.glb' --level 0 -o '" + dir + "/out_0000.obj'").code, 0);
    const std::string control = strata::test::readText(dir + "/out_0000.obj");
    r = run(reconstruct + " '" + dir + "/out_0000.obj' --frames 0:1:1 -o '" + dir + "/out.obj'");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("would overwrite the input"), std::string::npos) << r.output;
    EXPECT_EQ(strata::test::readText(dir + "/out_0000.obj"), control);
    EXPECT_FALSE(strata::test::fileExists(dir + "/out_0001.obj"));
}

TEST(Tools, DeepNodeChainsLoad)
{
    // A 300-deep chain of nodes above the mesh: loads and places the mesh.
    const std::string dir = strata::test::tempDir("tools_deep");
    std::string nodes = "[{\"mesh\":0}";
    for (int i = 1; i <= 300; ++i)
        nodes += ",{\"children\":[" + std::to_string(i - 1) + "],\"translation\":[0.001,0,0]}";
    nodes += "]";
    const std::string data = "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";
    std::string text = gltfWithBuffer(data, 36);
    text.replace(text.find("\"nodes\":[{\"mesh\":0}]"), 20, "\"nodes\":" + nodes);
    text.replace(text.find("\"scenes\":[{\"nodes\":[0]}]"), 24, "\"scenes\":[{\"nodes\":[300]}]");
    strata::test::writeText(dir + "/deep.gltf", text);
    const Result r = run(reconstruct + " '" + dir + "/deep.gltf' --level 1 --no-displacement -o '" + dir + "/o.obj'");
    EXPECT_EQ(r.code, 0) << r.output;
    // 300 translations of 0.001 along x: the first vertex sits at x = 0.3.
    const std::string obj = strata::test::readText(dir + "/o.obj");
    const size_t v = obj.find("\nv ");
    ASSERT_NE(v, std::string::npos);
    EXPECT_NEAR(std::atof(obj.c_str() + v + 3), 0.3, 1e-5) << obj.substr(0, 80);
}

// The README's engine programs (examples/engine.cpp over strata::Surface,
// examples/engine.c over the C API) draw the surface strata-reconstruct
// writes, bit for bit: a smooth-scheme rig of spot at its recommended level,
// and CesiumMan posed at t = 1 s of its animation.
TEST(Examples, EngineProgramsDrawWhatStrataReconstructWrites)
{
    const std::string dir = strata::test::tempDir("examples_engine");
    const std::string data = STRATA_SHARED_DATA;
    const std::string bake = STRATA_BAKE_EXE;
    auto q = [](const std::string& s) { return "'" + s + "'"; };
    ASSERT_EQ(run(bake + " --high " + q(data + "/spot_triangulated.obj") + " --control " +
                  q(data + "/spot_control_mesh.obj") + " " + strata::test::kFixedMapSizeFlag + " -o " +
                  q(dir + "/spot.glb"))
                  .code,
              0);
    ASSERT_EQ(run(bake + " --high " + q(data + "/CesiumMan.glb") + " --control " + q(data + "/CesiumMan.glb") +
                  " -o " + q(dir + "/cesium.glb"))
                  .code,
              0);
    // Each file's "v" lines (positions at %.9g, which round-trip a float).
    auto vertexLines = [](const std::string& path) {
        std::vector<std::string> lines;
        std::istringstream in(strata::test::readText(path));
        for (std::string line; std::getline(in, line);)
            if (line.rfind("v ", 0) == 0)
                lines.push_back(line);
        return lines;
    };
    struct Case {
        std::string rig, pose, reconstructPose;
    };
    const Case cases[] = {{"spot", "", ""}, {"cesium", " 0 1", " --anim 0 --time 1"}};
    for (const Case& c : cases) {
        const std::string ref = dir + "/" + c.rig + "_reference.obj";
        Result r = run(reconstruct + " " + q(dir + "/" + c.rig + ".glb") + c.reconstructPose + " -o " + q(ref));
        ASSERT_EQ(r.code, 0) << r.output;
        const std::vector<std::string> expected = vertexLines(ref);
        ASSERT_GT(expected.size(), 1000u);
        for (const std::string exe : {STRATA_EXAMPLE_ENGINE_EXE, STRATA_EXAMPLE_ENGINE_C_EXE}) {
            const std::string out = dir + "/" + c.rig + "_example.obj";
            r = run(exe + " " + q(dir + "/" + c.rig + ".glb") + " " + q(out) + c.pose);
            ASSERT_EQ(r.code, 0) << exe << "\n" << r.output;
            EXPECT_TRUE(vertexLines(out) == expected) << exe << " on " << c.rig;
        }
    }
    // The spot rig was baked in the smooth scheme: the programs use it
    // without being told (the README's earlier snippet hard-coded linear).
    const Result r = run(std::string(STRATA_EXAMPLE_ENGINE_EXE) + " " + q(dir + "/spot.glb") + " " + q(dir + "/x.obj"));
    EXPECT_NE(r.output.find("level"), std::string::npos) << r.output;
}

// docs/CLI.md's option table is strata-bake's own (--help-options), which
// is also Python's docstring: the copy in the docs is current.
TEST(Tools, CliReferenceIsGeneratedFromTheOptionTable)
{
    const Result r = run(std::string(STRATA_BAKE_EXE) + " --help-options");
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string doc = strata::test::readText(std::string(STRATA_SOURCE_DIR) + "/docs/CLI.md");
    const std::string begin = "<!-- generated: strata-bake --help-options -->\n", end = "<!-- end generated -->";
    const size_t a = doc.find(begin), b = doc.find(end);
    ASSERT_NE(a, std::string::npos);
    ASSERT_NE(b, std::string::npos);
    EXPECT_EQ(doc.substr(a + begin.size(), b - a - begin.size()), r.output)
        << "docs/CLI.md is stale: paste `strata-bake --help-options` between its markers";
    // Every flag the usage line names has a row.
    const Result usage = run(std::string(STRATA_BAKE_EXE) + " --help");
    for (const char* flag : {"--tolerance", "--control-faces", "--mesh-coding", "--no-fit", "--png16", "--max-memory"}) {
        EXPECT_NE(usage.output.find(flag), std::string::npos) << flag;
        EXPECT_NE(r.output.find(std::string("`") + flag), std::string::npos) << flag;
    }
}
