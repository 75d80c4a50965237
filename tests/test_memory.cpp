// Memory a file can justify: each tool run under a 2 GB address-space limit
// on crafted rigs and meshes that declare far more than their bytes back,
// and the reconstruction's memory estimate against its measured peak.
// Not built with sanitizers: AddressSanitizer reserves terabytes of address
// space (no RLIMIT_AS fits it) and doubles every peak.
#include "test_util.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>

namespace {

using strata::test::CommandResult;
using strata::test::glbJson;
using strata::test::glbWithJson;
using strata::test::readText;
using strata::test::writeText;

const std::string bake = STRATA_BAKE_EXE;
const std::string reconstruct = STRATA_RECONSTRUCT_EXE;
const std::string data = STRATA_SHARED_DATA;

// Runs `command` through /bin/sh with stdout and stderr captured, under an
// address-space limit of `limitMB` (0: none); *peakKB gets the child's
// largest resident set.
CommandResult runLimited(const std::string& command, long limitMB, long* peakKB = nullptr)
{
    CommandResult r;
    int fds[2];
    if (pipe(fds) != 0)
        return r;
    const pid_t pid = fork();
    if (pid == 0) {
        dup2(fds[1], 1);
        dup2(fds[1], 2);
        close(fds[0]);
        close(fds[1]);
        if (limitMB > 0) {
            const rlim_t bytes = rlim_t(limitMB) << 20;
            const rlimit lim{bytes, bytes};
            setrlimit(RLIMIT_AS, &lim);
        }
        execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
        _exit(127);
    }
    close(fds[1]);
    char buf[512];
    ssize_t n;
    while ((n = read(fds[0], buf, sizeof(buf))) > 0)
        r.output.append(buf, size_t(n));
    close(fds[0]);
    int status = 0;
    rusage usage{};
    wait4(pid, &status, 0, &usage);
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (peakKB)
        *peakKB = usage.ru_maxrss;
    return r;
}

std::string q(const std::string& path)
{
    return "'" + path + "'";
}

// The one line a refusal is: exit 2, one line, naming `needle`.
void expectRefusal(const CommandResult& r, const std::string& needle, const std::string& what)
{
    EXPECT_EQ(r.code, 2) << what << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << what << "\n" << r.output;
    EXPECT_NE(r.output.find("error:"), std::string::npos) << what << "\n" << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << what << ": expected \"" << needle << "\"\n" << r.output;
}

// The rigs every test reads, baked once per process in SetUp (a failure
// there fails the test; in SetUpTestSuite gtest would report it skipped).
class Memory : public ::testing::Test {
protected:
    void SetUp() override
    {
        if (ready)
            return;
        dir = strata::test::tempDir("memory");
        const std::string spotArgs = " --high " + q(data + "/spot_triangulated.obj") + " --control " +
                                     q(data + "/spot_control_mesh.obj");
        ASSERT_EQ(strata::test::runCommand(bake + spotArgs + " -o " + q(dir + "/spot.glb")).code, 0);
        ASSERT_EQ(strata::test::runCommand(bake + spotArgs + " --mesh-coding meshopt -o " + q(dir + "/spot_meshopt.glb")).code, 0);
        ASSERT_EQ(strata::test::runCommand(bake + " --high " + q(data + "/CesiumMan.glb") + " --control " +
                                           q(data + "/CesiumMan.glb") + " -o " + q(dir + "/cesium.glb"))
                      .code,
                  0);
        ready = true;
    }
    static std::string dir;
    static bool ready;
};
std::string Memory::dir;
bool Memory::ready = false;

// Each class of file that once bought gigabytes with a few bytes, under a
// 2 GB address-space limit: refused in one line, nothing written.
TEST_F(Memory, CraftedFilesAreRefusedInOneLineUnderTwoGigabytes)
{
    const std::string out = dir + "/out.glb";
    struct Case {
        std::string name, command, needle;
    };
    std::vector<Case> cases;

    // A meshopt fallback buffer that declares 2^31 bytes (a fallback is no backing).
    {
        nlohmann::json j = glbJson(readText(dir + "/spot_meshopt.glb"));
        bool found = false;
        for (nlohmann::json& b : j["buffers"])
            if (b.contains("extensions") && b["extensions"].contains("EXT_meshopt_compression")) {
                b["byteLength"] = uint64_t(1) << 31;
                found = true;
            }
        ASSERT_TRUE(found) << "the meshopt rig has no fallback buffer";
        writeText(dir + "/fallback.glb", glbWithJson(readText(dir + "/spot_meshopt.glb"), j));
        cases.push_back({"fallback", reconstruct + " " + q(dir + "/fallback.glb") + " --level 1 -o " + q(out),
                         "fallback buffer"});
    }
    // Per-vertex displacements that declare a level far past their bytes,
    // and one the budget (not the bytes) refuses.
    for (int level : {6, 9}) {
        for (const char* rig : {"spot", "cesium"}) {
            nlohmann::json j = glbJson(readText(dir + "/" + rig + ".glb"));
            bool found = false;
            for (nlohmann::json& m : j["meshes"])
                if (m.contains("extensions") && m["extensions"].contains("STRATA_layered_displacement")) {
                    m["extensions"]["STRATA_layered_displacement"]["displacementVertices"]["level"] = level;
                    found = true;
                }
            ASSERT_TRUE(found) << rig << " has no layer";
            const std::string name = std::string(rig) + "_level" + std::to_string(level);
            writeText(dir + "/" + name + ".glb", glbWithJson(readText(dir + "/" + rig + ".glb"), j));
            cases.push_back({name, reconstruct + " " + q(dir + "/" + name + ".glb") + " --level 1 -o " + q(out),
                             name + ".glb"});
        }
    }
    {
        nlohmann::json j = glbJson(readText(dir + "/spot.glb"));
        for (nlohmann::json& m : j["meshes"])
            if (m.contains("extensions") && m["extensions"].contains("STRATA_layered_displacement"))
                m["extensions"]["STRATA_layered_displacement"]["displacementVertices"]["level"] = 6;
        writeText(dir + "/spot_budget.glb", glbWithJson(readText(dir + "/spot.glb"), j));
        cases.push_back({"budget", reconstruct + " " + q(dir + "/spot_budget.glb") + " --level 1 --max-memory 64 -o " + q(out),
                         "--max-memory"});
    }
    // A skinned character whose animation input claims 2^30 keys without
    // a bufferView (zeros cost no bytes), and one at 2^24 keys that only
    // the budget refuses.
    for (uint64_t keys : {uint64_t(1) << 30, uint64_t(1) << 24}) {
        nlohmann::json j = glbJson(readText(dir + "/cesium.glb"));
        ASSERT_FALSE(j["animations"].empty());
        const int input = j["animations"][0]["samplers"][0]["input"].get<int>();
        j["accessors"][size_t(input)].erase("bufferView");
        j["accessors"][size_t(input)].erase("byteOffset");
        j["accessors"][size_t(input)]["count"] = keys;
        const bool unbacked = keys > (uint64_t(1) << 29);
        const std::string name = unbacked ? "keys_unbacked" : "keys_budget";
        writeText(dir + "/" + name + ".glb", glbWithJson(readText(dir + "/cesium.glb"), j));
        cases.push_back({name, reconstruct + " " + q(dir + "/" + name + ".glb") + (unbacked ? "" : " --max-memory 16") +
                                   " --level 1 -o " + q(out),
                         unbacked ? "without the bytes" : "--max-memory"});
    }
    // A node that is its own grandparent.
    {
        nlohmann::json j = glbJson(readText(dir + "/cesium.glb"));
        nlohmann::json& nodes = j["nodes"];
        size_t child = 0;
        for (size_t n = 0; n < nodes.size() && !child; ++n)
            if (nodes[n].contains("children") && !nodes[n]["children"].empty())
                child = nodes[n]["children"][0].get<size_t>();
        ASSERT_GT(child, 0u);
        nodes[child]["children"] = nlohmann::json::array({0});
        writeText(dir + "/cycle.glb", glbWithJson(readText(dir + "/cesium.glb"), j));
        cases.push_back({"cycle", reconstruct + " " + q(dir + "/cycle.glb") + " --level 1 -o " + q(out), "cycle.glb"});
    }
    // A control mesh with one vertex two billion units out: refused before
    // the atlas, the map or Draco ever see it.
    {
        std::ifstream in(data + "/spot_control_mesh.obj");
        std::string line, obj;
        int v = 0;
        while (std::getline(in, line))
            obj += (line.rfind("v ", 0) == 0 && ++v == 5 ? std::string("v 0.1 -2147483649 0.2") : line) + "\n";
        writeText(dir + "/far_vertex.obj", obj);
        for (const char* coding : {"plain", "draco"})
            cases.push_back({std::string("far vertex ") + coding,
                             bake + " --high " + q(data + "/spot_triangulated.obj") + " --control " +
                                 q(dir + "/far_vertex.obj") + " --mesh-coding " + coding + " -o " + q(out),
                             "not in one frame"});
    }
    // A high-resolution mesh larger than the budget allows reading.
    {
        writeText(dir + "/big.obj", readText(data + "/spot_triangulated.obj"));
        std::filesystem::resize_file(dir + "/big.obj", uintmax_t(64) << 20);  // sparse: no disk
        cases.push_back({"big capture",
                         bake + " --high " + q(dir + "/big.obj") + " --control " + q(data + "/spot_control_mesh.obj") +
                             " --max-memory 16 -o " + q(out),
                         "--max-memory"});
    }
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const auto t0 = std::chrono::steady_clock::now();
        const CommandResult r = runLimited(c.command, 2048);
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        expectRefusal(r, c.needle, c.name);
        EXPECT_LT(seconds, 10.0) << c.name;
        EXPECT_FALSE(strata::test::fileExists(out)) << c.name << " left an output";
    }
}

// strata-reconstruct's estimate (the figure its --max-memory refusal names)
// against the peak resident memory the same run then takes.
TEST_F(Memory, ReconstructionEstimateIsWithinTwentyPercentOfThePeak)
{
    struct Case {
        std::string rig;
        int level;
        std::string ext;
    };
    const Case cases[] = {{"spot", 4, ".glb"}, {"spot", 5, ".glb"}, {"spot", 6, ".glb"}, {"spot", 6, ".ply"},
                          {"cesium", 4, ".glb"}, {"cesium", 4, ".obj"}, {"cesium", 5, ".ply"}};
    const std::regex figure("needs about ([0-9]+) MB");
    for (const Case& c : cases) {
        const std::string args =
            q(dir + "/" + c.rig + ".glb") + " --level " + std::to_string(c.level) + " -o " + q(dir + "/estimate" + c.ext);
        const CommandResult refused = runLimited(reconstruct + " " + args + " --max-memory 16", 0);
        std::smatch m;
        ASSERT_TRUE(std::regex_search(refused.output, m, figure)) << refused.output;
        const double estimateMB = std::stod(m[1]);
        long peakKB = 0;
        const CommandResult r = runLimited(reconstruct + " " + args, 0, &peakKB);
        ASSERT_EQ(r.code, 0) << r.output;
        const double ratio = estimateMB / (double(peakKB) / 1024.0);
        EXPECT_GT(ratio, 0.8) << c.rig << " level " << c.level << c.ext << ": " << estimateMB << " MB estimated, "
                              << peakKB / 1024 << " MB used";
        EXPECT_LT(ratio, 1.2) << c.rig << " level " << c.level << c.ext << ": " << estimateMB << " MB estimated, "
                              << peakKB / 1024 << " MB used";
    }
}

}  // namespace
