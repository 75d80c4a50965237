// strata-bench paper --out DIR: the paper's Table 1, and Strata against what
// a user would pick instead (issue: evidence).  For each real pair in
// ../shared/data and the built-in example it bakes with strata-bake, then
// measures, in bytes and in surface distance to the original (both
// directions, relative to the bounding-box diagonal, the project's own
// distance code):
//   * the original as a plain indexed glb (float positions, 32-bit indices);
//   * the original through Debian's draco_encoder (default settings) and
//     gltfpack -cc, when installed;
//   * a quadric-decimated mesh (OpenMesh) given the Strata rig's byte
//     budget, plain and Draco-compressed;
//   * the Strata rig: one glb with the map embedded, default settings;
// plus bake time by stage and regeneration time at N = 0..6 on one core.
// Writes DIR/RESULTS.md and DIR/results.json.
#include "bench_common.h"
#include "procedural.h"
#include "strata/baker/bake.h"
#include "strata/baker/distance.h"
#include "strata/baker/mesh_input.h"
#include "strata/io/file.h"
#include "strata/io/mesh_io.h"
#include "strata/io/rig_io.h"
#include "strata/normals.h"
#include "strata/plan.h"
#ifdef STRATA_HAVE_GL
#include "strata/gl/context.h"
#include "strata/gl/gpu_surface.h"
#endif

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/stat.h>

using namespace strata;
using Json = nlohmann::json;

namespace {

struct Pair {
    std::string name, high, control, flags;
};

double fileBytes(const std::string& path)
{
    struct stat sb;
    return ::stat(path.c_str(), &sb) == 0 ? double(sb.st_size) : 0.0;
}

bool have(const char* tool)
{
    return std::system((std::string("command -v ") + tool + " >/dev/null 2>&1").c_str()) == 0;
}

int shell(const std::string& cmd)
{
    return std::system((cmd + " >/dev/null 2>&1").c_str());
}

struct Accuracy {
    double rms = -1, max = -1;  // symmetric: the larger of the two directions, / diagonal
    double toRms = -1, fromRms = -1;
};

// Both directions between a candidate surface and the original, sampled at
// every vertex and face centroid.
Accuracy accuracy(const std::vector<glm::vec3>& p, const std::vector<uint32_t>& t, const baker::TriangleMesh& high,
                  const baker::TriangleIndex& highIndex, double diag)
{
    Accuracy a;
    if (t.empty())
        return a;
    baker::TriangleIndex index;
    index.build(p.data(), t.data(), t.size() / 3);
    const baker::DistanceStats to =
        baker::sampleDistance(baker::surfaceSamples(p.data(), p.size(), t.data(), t.size() / 3), highIndex, 2);
    const baker::DistanceStats from = baker::sampleDistance(
        baker::surfaceSamples(high.positions.data(), high.positions.size(), high.triangles.data(), high.faceCount()),
        index, 2);
    a.toRms = to.rms / diag;
    a.fromRms = from.rms / diag;
    a.rms = std::max(to.rms, from.rms) / diag;
    a.max = std::max(to.max, from.max) / diag;
    return a;
}

Status writeGlb(const std::string& path, const std::vector<glm::vec3>& p, const std::vector<uint32_t>& t)
{
    io::MeshView v;
    v.positions = p.data();
    v.vertexCount = p.size();
    v.triangles = t.data();
    v.faceCount = t.size() / 3;
    return io::writeMesh(path, v);
}

std::string pct(double v)
{
    if (v < 0)
        return "n/a";
    char b[32];
    std::snprintf(b, sizeof(b), "%.4f%%", 100.0 * v);
    return b;
}

std::string kb(double bytes)
{
    char b[32];
    std::snprintf(b, sizeof(b), "%.1f KB", bytes / 1024.0);
    return b;
}

struct Row {
    std::string what;
    double bytes = 0;
    Accuracy acc;
    std::string note;
};

Status draco(const std::string& dir, const std::string& stem, const std::vector<glm::vec3>& p,
             const std::vector<uint32_t>& t, double* bytes, std::vector<glm::vec3>* dp, std::vector<uint32_t>* dt)
{
    const std::string ply = dir + "/" + stem + ".ply", drc = dir + "/" + stem + ".drc",
                      back = dir + "/" + stem + "_decoded.ply";
    io::MeshView v;
    v.positions = p.data();
    v.vertexCount = p.size();
    v.triangles = t.data();
    v.faceCount = t.size() / 3;
    if (Status st = io::writeMesh(ply, v); !st)
        return st;
    if (shell("draco_encoder -i '" + ply + "' -o '" + drc + "'") != 0 ||
        shell("draco_decoder -i '" + drc + "' -o '" + back + "'") != 0)
        return Status(StatusCode::IoError, "draco_encoder/decoder failed on " + ply);
    *bytes = fileBytes(drc);
    baker::TriangleMesh decoded;
    if (Status st = baker::loadHighMesh(back, &decoded, nullptr); !st)
        return st;
    *dp = std::move(decoded.positions);
    *dt = std::move(decoded.triangles);
    return Status::ok();
}

#ifdef STRATA_HAVE_GL
gl::HeadlessContext* gpuContext()
{
    static std::unique_ptr<gl::HeadlessContext> ctx;
    static const bool ok = gl::HeadlessContext::create(&ctx).isOk();
    return ok ? ctx.get() : nullptr;
}
#endif

std::string gpuName()
{
#ifdef STRATA_HAVE_GL
    if (gpuContext()) {
        const std::string d = gpuContext()->description();
        return d.substr(0, d.find(" ("));
    }
#endif
    return "none";
}

Json runPair(const Pair& pair, const std::string& out, const std::string& bakeExe, std::string* md)
{
    Json j;
    j["name"] = pair.name;
    const std::string dir = out + "/" + pair.name;
    shell("mkdir -p '" + dir + "'");
    std::printf("== %s\n", pair.name.c_str());
    std::fflush(stdout);
    const std::string rigPath = dir + "/rig.glb";
    const std::string cmd = bakeExe + " --high '" + pair.high + "' --control '" + pair.control + "' " + pair.flags +
                            " --threads 2 -o '" + rigPath + "' --report '" + dir + "/bake.json'";
    if (shell(cmd) != 0) {
        *md += "\n### " + pair.name + "\n\nbake failed: `" + cmd + "`\n";
        j["error"] = "bake failed";
        return j;
    }
    Json report;
    std::ifstream(dir + "/bake.json") >> report;
    baker::TriangleMesh high;
    if (!baker::loadHighMesh(pair.high, &high, nullptr))
        return j;
    const double diag = report["high"]["diagonal"].get<double>();
    baker::TriangleIndex highIndex;
    highIndex.build(high.positions.data(), high.triangles.data(), high.faceCount());
    const int level = report["recommendedLevel"].get<int>();
    std::vector<Row> rows;

    // The original, plain.
    Row plain{"original, plain glb", 0, {}, std::to_string(high.faceCount()) + " triangles"};
    writeGlb(dir + "/original.glb", high.positions, high.triangles);
    plain.bytes = fileBytes(dir + "/original.glb");
    plain.acc.rms = plain.acc.max = 0.0;
    rows.push_back(plain);

    // Strata rig: one self-contained glb (the map embedded), at its
    // recommended level, from the closed loop the bake measured on it.
    Json cl;
    for (const Json& e : report["closedLoop"])
        if (e["level"].get<int>() == level)
            cl = e;
    Row strata{"Strata rig (one glb, map embedded)", fileBytes(rigPath), {},
               "level " + std::to_string(level) + ", " + std::string(report["scheme"]) + ", " +
                   std::to_string(report["map"]["size"].get<int>()) + "^2 map"};
    if (!cl.is_null()) {
        strata.acc.toRms = cl["forwardRms"].get<double>();
        strata.acc.fromRms = cl["backwardRms"].get<double>();
        strata.acc.rms = std::max(strata.acc.toRms, strata.acc.fromRms);
        strata.acc.max = std::max(cl["forwardMax"].get<double>(), cl["backwardMax"].get<double>());
    }

    // Compressors on the original.
    const bool haveDraco = have("draco_encoder") && have("draco_decoder");
    double dracoRatio = 0.0;
    if (haveDraco) {
        Row r{"original, Draco (default settings)", 0, {}, "draco_encoder 1.5, 11-bit positions"};
        std::vector<glm::vec3> p;
        std::vector<uint32_t> t;
        if (draco(dir, "original", high.positions, high.triangles, &r.bytes, &p, &t)) {
            r.acc = accuracy(p, t, high, highIndex, diag);
            dracoRatio = r.bytes / plain.bytes;
            rows.push_back(r);
        }
    }
    if (have("gltfpack")) {
        Row r{"original, gltfpack -cc", 0, {}, "14-bit positions; error shown is the quantisation bound"};
        if (shell("gltfpack -i '" + dir + "/original.glb' -o '" + dir + "/original_gltfpack.glb' -cc") == 0) {
            r.bytes = fileBytes(dir + "/original_gltfpack.glb");
            glm::vec3 lo(1e30f), hi(-1e30f);
            for (const glm::vec3& q : high.positions) {
                lo = glm::min(lo, q);
                hi = glm::max(hi, q);
            }
            const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
            r.acc.max = 0.5 * std::sqrt(3.0) * extent / 16383.0 / diag;
            rows.push_back(r);
        }
    }

    // Decimated to the Strata rig's bytes, plain and Draco'd.
    for (int withDraco = 0; withDraco <= (haveDraco ? 1 : 0); ++withDraco) {
        const double budget = strata.bytes;
        // Plain glb: about 12 bytes per vertex + 12 per triangle, V ~ F / 2.
        size_t faces = size_t(std::max(8.0, budget / 18.0));
        if (withDraco && dracoRatio > 0.0)
            faces = size_t(double(faces) / dracoRatio);
        faces = std::min(faces, high.faceCount());
        ControlMesh dec;
        if (!baker::decimateToControlMesh(high, faces, &dec))
            continue;
        Row r{withDraco ? "decimated to equal bytes, Draco" : "decimated to equal bytes, plain glb", 0, {},
              faces >= high.faceCount()
                  ? "the budget holds the whole original (" + std::to_string(dec.faceCount()) + " triangles)"
                  : std::to_string(dec.faceCount()) + " triangles (OpenMesh quadric)"};
        if (withDraco) {
            std::vector<glm::vec3> p;
            std::vector<uint32_t> t;
            if (!draco(dir, "decimated", dec.positions, dec.triangles, &r.bytes, &p, &t))
                continue;
            r.acc = accuracy(p, t, high, highIndex, diag);
        } else {
            writeGlb(dir + "/decimated.glb", dec.positions, dec.triangles);
            r.bytes = fileBytes(dir + "/decimated.glb");
            r.acc = accuracy(dec.positions, dec.triangles, high, highIndex, diag);
        }
        rows.push_back(r);
    }
    rows.push_back(strata);

    // Regeneration at N = 0..6 on one core (linear and the bake's scheme).
    Rig rig;
    io::loadRig(rigPath, &rig);
    DisplacementMap map;
    io::loadRigDisplacementMap(rigPath, rig, &map);
    std::vector<glm::vec3> normals(rig.mesh.vertexCount());
    computeControlNormals(normals.data(), rig.mesh.positions.data(), normals.size(), rig.mesh.triangles.data(),
                          rig.mesh.faceCount());
    Json regen = Json::array();
    std::string regenMd = "| N | refined vertices | triangles | setup ms | regenerate ms (eq. 2) | + shading normals ms |"
                          " GPU (" + gpuName() + ") stencils + displace + normals ms |\n"
                          "|---|---|---|---|---|---|---|\n";
    for (int n = 0; n <= kMaxLevel; ++n) {
        const double t0 = bench::nowMs();
        std::unique_ptr<Plan> plan;
        if (!Plan::create(&plan, rig.mesh, Scheme::Linear, n) || !applyRigDisplacement(plan.get(), rig, &map))
            break;
        const double setup = bench::nowMs() - t0;
        std::vector<glm::vec3> pos(plan->refinedVertexCount()), sn(pos.size());
        const double eval = bench::medianMs([&] {
            plan->evaluate(pos.data(), nullptr, 0, pos.size(), rig.mesh.positions.data(), normals.data(),
                           normals.size());
        }, 5, 20.0);
        const double shade = bench::medianMs([&] { plan->computeShadingNormals(sn.data(), pos.data()); }, 5, 20.0);
        double gpu = -1.0;
#ifdef STRATA_HAVE_GL
        std::unique_ptr<gl::GpuSurface> surface;
        if (gpuContext() && n <= 5 && gl::GpuSurface::create(&surface, *plan) && surface->setDisplacementMap(map)) {
            gpu = bench::medianMs([&] {
                surface->update(rig.mesh.positions.data(), normals.data(), normals.size());
                glFinish();
            }, 5, 20.0);
        }
#endif
        regen.push_back({{"level", n}, {"vertices", pos.size()}, {"triangles", plan->refinedFaceCount()},
                         {"setupMs", setup}, {"regenerateMs", eval}, {"shadingNormalsMs", shade}, {"gpuMs", gpu}});
        char line[240];
        char gpuText[32] = "n/a";
        if (gpu >= 0.0)
            std::snprintf(gpuText, sizeof(gpuText), "%.3f", gpu);
        std::snprintf(line, sizeof(line), "| %d | %zu | %zu | %.1f | %.3f | %.3f | %s |\n", n, pos.size(),
                      plan->refinedFaceCount(), setup, eval, shade, gpuText);
        regenMd += line;
    }

    // Markdown and JSON.
    const Json& tm = report["timeMs"];
    char head[512];
    std::snprintf(head, sizeof(head),
                  "\n### %s\n\n%zu high-res triangles onto %zu control triangles (`%s`), diagonal %.4g.\n\n", pair.name.c_str(),
                  high.faceCount(), size_t(report["control"]["triangles"].get<size_t>()), pair.flags.c_str(), diag);
    *md += head;
    *md += "| representation | bytes | vs plain | RMS (max of both directions) | max | note |\n|---|---|---|---|---|---|\n";
    Json jr = Json::array();
    for (const Row& r : rows) {
        char line[400];
        std::snprintf(line, sizeof(line), "| %s | %s | %.1fx smaller | %s | %s | %s |\n", r.what.c_str(),
                      kb(r.bytes).c_str(), plain.bytes / std::max(r.bytes, 1.0), pct(r.acc.rms).c_str(),
                      pct(r.acc.max).c_str(), r.note.c_str());
        *md += line;
        jr.push_back({{"what", r.what}, {"bytes", r.bytes}, {"rms", r.acc.rms}, {"max", r.acc.max},
                      {"toOriginalRms", r.acc.toRms}, {"fromOriginalRms", r.acc.fromRms}, {"note", r.note}});
    }
    char bake[300];
    std::snprintf(bake, sizeof(bake),
                  "\nBake (2 threads): load %.0f ms, mapping %.0f ms, rasterise %.0f ms, fill + dilate %.0f ms, "
                  "write %.0f ms.\n\nRegeneration, linear scheme, one core:\n\n",
                  tm["load"].get<double>(), tm["mapping"].get<double>(), tm["rasterize"].get<double>(),
                  tm["dilate"].get<double>(), tm["write"].get<double>());
    *md += bake;
    *md += regenMd;
    j["rows"] = jr;
    j["bakeMs"] = tm;
    j["regeneration"] = regen;
    j["diagonal"] = diag;
    j["recommendedLevel"] = level;
    return j;
}

}  // namespace

int main(int argc, char** argv)
{
    std::string out = "report";
    bool paper = false;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "paper")
            paper = true;
        else if (a == "--version") {
            std::printf("strata-bench %s\n", STRATA_VERSION);
            return 0;
        }
        else if (a == "--out" && i + 1 < argc)
            out = argv[++i];
        else {
            std::fprintf(stderr, "usage: strata-bench paper [--out DIR]\n");
            return 2;
        }
    }
    if (!paper) {
        std::fprintf(stderr, "usage: strata-bench paper [--out DIR]\n");
        return 2;
    }
    shell("mkdir -p '" + out + "/example'");
    const std::string bakeExe = STRATA_BAKE_EXE, demoExe = STRATA_DEMO_EXE;
    // The built-in example: the demo's generated capture over icosphere(1).
    std::vector<Pair> pairs;
    if (shell(demoExe + " --out '" + out + "/example'") == 0) {
        const ControlMesh ico = examples::makeIcosphere(1);
        io::MeshView v;
        v.positions = ico.positions.data();
        v.vertexCount = ico.positions.size();
        v.triangles = ico.triangles.data();
        v.faceCount = ico.faceCount();
        io::writeMesh(out + "/example/icosphere1.obj", v);
        pairs.push_back({"example", out + "/example/head_highres.ply", out + "/example/icosphere1.obj", "--uv auto"});
    }
    const std::string data = STRATA_SHARED_DATA;
    struct stat sb;
    if (::stat(data.c_str(), &sb) == 0) {
        pairs.push_back({"spot", data + "/spot_triangulated.obj", data + "/spot_control_mesh.obj",
                         ""});
        pairs.push_back({"penguin", data + "/penguin_hr.obj", data + "/penguin_control_mesh.obj",
                         ""});
        pairs.push_back({"hand", data + "/hand_closed.obj", data + "/hand_lowres.obj", ""});
        pairs.push_back({"nefertiti", data + "/nefertiti-lowres.obj", "auto", ""});
    }
    std::string md = "# Strata evidence report\n\nMade by `strata-bench paper --out " + out +
                     "`.  Sizes are file bytes; errors are surface distances to the original, sampled at every "
                     "vertex and face centroid in both directions, relative to the bounding-box diagonal.\n";
    Json all = Json::array();
    for (const Pair& p : pairs)
        all.push_back(runPair(p, out, bakeExe, &md));
    std::ofstream(out + "/RESULTS.md") << md;
    std::ofstream(out + "/results.json") << all.dump(2) << "\n";
    std::printf("%s", md.c_str());
    return 0;
}
