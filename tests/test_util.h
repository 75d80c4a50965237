// Shared helpers for Strata's tests.
#pragma once

#include "strata/control_mesh.h"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <dirent.h>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace strata {
namespace test {

// The map size of bakes whose subject is not the map-size search (files,
// errors, welds, warnings, what a character's cage carries): the search
// over a detailed capture tries sizes up to 2048 and is most of a default
// bake's time, ten times over under the sanitizers.
constexpr int kFixedMapSize = 512;
inline const std::string kFixedMapSizeFlag = "--size " + std::to_string(kFixedMapSize);

/// Path of a third-party asset in tests/data (STRATA_SHARED_DATA), or "" when it is missing.
inline std::string sharedData(const std::string& name)
{
    const std::string path = std::string(STRATA_SHARED_DATA) + "/" + name;
    struct stat st;
    return ::stat(path.c_str(), &st) == 0 ? path : std::string();
}

/// Fails the calling test when an asset of tests/data is missing: every
/// asset a test uses ships with the repository, so none is ever skipped.
#define STRATA_REQUIRE_DATA(var, name)                                                 \
    const std::string var = ::strata::test::sharedData(name);                          \
    if (var.empty())                                                                   \
    GTEST_FAIL() << "tests/data/" << name << " is missing (it ships with the repository)"

/// Rewrites a rig's JSON as format version 4 wrote it: the layer of each
/// mesh moves from its STRATA_layered_displacement extension to
/// extras.strata with "version": 4, the coded values are named by their
/// accessor's bufferView, and the control fingerprint goes.  For tests that
/// older rigs still load.
inline void layerToVersionFour(nlohmann::json& doc)
{
    const char* name = "STRATA_layered_displacement";
    for (nlohmann::json& mesh : doc["meshes"]) {
        if (!mesh.contains("extensions") || !mesh["extensions"].contains(name))
            continue;
        nlohmann::json block = mesh["extensions"][name];
        mesh["extensions"].erase(name);
        if (mesh["extensions"].empty())
            mesh.erase("extensions");
        block["version"] = 4;
        block.erase("control");
        if (block.contains("displacementVertices")) {
            nlohmann::json& v = block["displacementVertices"];
            v["bufferView"] = doc["accessors"][v["accessor"].get<size_t>()]["bufferView"];
            v.erase("accessor");
        }
        mesh["extras"]["strata"] = block;
    }
    for (const char* list : {"extensionsUsed", "extensionsRequired"})
        if (doc.contains(list)) {
            nlohmann::json kept = nlohmann::json::array();
            for (const auto& e : doc[list])
                if (e != name)
                    kept.push_back(e);
            if (kept.empty())
                doc.erase(list);
            else
                doc[list] = kept;
        }
}

/// A .glb's JSON chunk, parsed.
inline nlohmann::json glbJson(const std::string& glb)
{
    uint32_t length = 0;
    std::memcpy(&length, glb.data() + 12, 4);
    return nlohmann::json::parse(glb.substr(20, length));
}

/// The .glb with its JSON chunk replaced by `json` (the BIN chunk kept).
inline std::string glbWithJson(const std::string& glb, const nlohmann::json& json)
{
    uint32_t jsonLength = 0;
    std::memcpy(&jsonLength, glb.data() + 12, 4);
    std::string text = json.dump();
    while (text.size() % 4)
        text += ' ';
    const std::string bin = glb.substr(20 + jsonLength);
    std::string out(20, '\0');
    std::memcpy(&out[0], "glTF", 4);
    const uint32_t version = 2, total = uint32_t(20 + text.size() + bin.size()), n = uint32_t(text.size());
    std::memcpy(&out[4], &version, 4);
    std::memcpy(&out[8], &total, 4);
    std::memcpy(&out[12], &n, 4);
    std::memcpy(&out[16], "JSON", 4);
    return out + text + bin;
}

/// Runs a shell command, returning its exit code and its stdout + stderr.
struct CommandResult {
    int code = -1;
    std::string output;
};

inline CommandResult runCommand(const std::string& command)
{
    CommandResult r;
    FILE* pipe = popen((command + " 2>&1").c_str(), "r");
    if (!pipe)
        return r;
    char buf[512];
    while (fgets(buf, int(sizeof(buf)), pipe))
        r.output += buf;
    const int status = pclose(pipe);
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

/// Runs the Khronos glTF-Validator (node + npm gltf-validator) on files;
/// returns its report.
inline std::string runGltfValidator(const std::vector<std::string>& files, int* exitCode)
{
    std::string cmd = "node '" + std::string(STRATA_SOURCE_DIR) + "/tests/validate_gltf.mjs' '" +
                      std::string(STRATA_VALIDATOR_MODULES) + "'";
    for (const std::string& f : files)
        cmd += " '" + f + "'";
    const CommandResult r = runCommand(cmd);
    *exitCode = r.code;
    return r.output;
}

/// Largest distance between corresponding points of two equal-length arrays.
inline float maxDistance(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b)
{
    float m = 0.0f;
    for (size_t i = 0; i < a.size() && i < b.size(); ++i)
        m = std::max(m, glm::length(a[i] - b[i]));
    return m;
}

inline void writeText(const std::string& path, const std::string& text)
{
    std::ofstream(path, std::ios::binary) << text;
}

inline std::string readText(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/// Entries of a directory, not counting hidden ones unless asked.
inline size_t filesIn(const std::string& dir, bool withHidden = false)
{
    size_t n = 0;
    if (DIR* d = opendir(dir.c_str())) {
        while (dirent* e = readdir(d))
            n += withHidden ? std::strcmp(e->d_name, ".") != 0 && std::strcmp(e->d_name, "..") != 0 : e->d_name[0] != '.';
        closedir(d);
    }
    return n;
}

/// A fresh empty folder under the build tree's temp area, for one test
/// process: ctest runs the cases of a suite as parallel processes, so the
/// name carries the process id (two cases asking for one name never empty
/// each other's folder).
inline std::string tempDir(const std::string& name)
{
    const std::string dir = std::string(STRATA_TEST_TMP) + "/" + name + "." + std::to_string(::getpid());
    std::string cmd = "rm -rf '" + dir + "' && mkdir -p '" + dir + "'";
    if (std::system(cmd.c_str()) != 0)
        ADD_FAILURE() << "cannot create " << dir;
    return dir;
}

inline bool fileExists(const std::string& path)
{
    struct stat st;
    return ::stat(path.c_str(), &st) == 0;
}

inline float boundingBoxDiagonal(const ControlMesh& m)
{
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const glm::vec3& p : m.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    return glm::length(hi - lo);
}

/// Distance from p to triangle (a, b, c) (Ericson, Real-Time Collision
/// Detection 5.1.5), in double precision: the region tests cancel badly in
/// float on thin triangles.
inline float pointTriangleDistance(const glm::vec3& pf, const glm::vec3& af, const glm::vec3& bf, const glm::vec3& cf)
{
    const glm::dvec3 p(pf), a(af), b(bf), c(cf);
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0 && d2 <= 0)
        return float(glm::length(p - a));
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0 && d4 <= d3)
        return float(glm::length(p - b));
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0)
        return float(glm::length(p - (a + ab * (d1 / (d1 - d3)))));
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0 && d5 <= d6)
        return float(glm::length(p - c));
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0)
        return float(glm::length(p - (a + ac * (d2 / (d2 - d6)))));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
        return float(glm::length(p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))));
    const double denom = 1.0 / (va + vb + vc);
    return float(glm::length(p - (a + ab * (vb * denom) + ac * (vc * denom))));
}

}  // namespace test
}  // namespace strata
