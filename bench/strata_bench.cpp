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
// plus bake time by stage and regeneration time at N = 0..6 on one core,
// and the size/error trade-off (Strata at tolerances 0.005%..0.2%, Draco at
// qp 8..14, decimate-then-Draco at 1..50%, gltfpack) as a table and an SVG
// plot per pair (DIR/tradeoff_NAME.svg).
// Writes DIR/RESULTS.md and DIR/results.json.
//
// strata-bench tradeoff --out DIR [--pairs NAME,NAME]: the size/error sweeps
// alone, with --control auto (default coding and a Draco-coded cage) against
// decimate-then-Draco on every pair, every point measured by area-weighted
// sampling and a verdict per tolerance (issue 29).  Writes DIR/TRADEOFF.md,
// DIR/tradeoff.json and the plots.
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
#include "strata/surface.h"
#ifdef STRATA_HAVE_GL
#include "strata/gl/context.h"
#include "strata/gl/gpu_surface.h"
#endif

#include <nlohmann/json.hpp>

#include <algorithm>
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

// Both directions between a candidate surface and the original, by
// area-weighted sampling of both.
Accuracy accuracy(const std::vector<glm::vec3>& p, const std::vector<uint32_t>& t, const baker::TriangleMesh& high,
                  const baker::TriangleIndex& highIndex, double diag)
{
    Accuracy a;
    if (t.empty())
        return a;
    baker::TriangleIndex index;
    index.build(p.data(), t.data(), t.size() / 3);
    // Area-weighted both ways, as an independent tool measures.
    const baker::DistanceStats to = baker::sampleDistance(
        baker::areaSamples(p.data(), t.data(), t.size() / 3, p.size() + t.size() / 3), highIndex, 2);
    const baker::DistanceStats from = baker::sampleDistance(
        baker::areaSamples(high.positions.data(), high.triangles.data(), high.faceCount(),
                           high.positions.size() + high.faceCount()),
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

// The mesh through draco_encoder (at `qp` position bits; 0: its defaults,
// which are 11) and back through draco_decoder.
Status draco(const std::string& dir, const std::string& stem, const std::vector<glm::vec3>& p,
             const std::vector<uint32_t>& t, int qp, double* bytes, std::vector<glm::vec3>* dp,
             std::vector<uint32_t>* dt)
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
    const std::string bits = qp > 0 ? "-qp " + std::to_string(qp) + " " : "";
    if (shell("draco_encoder " + bits + "-i '" + ply + "' -o '" + drc + "'") != 0 ||
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

// One curve of the size/error plot: (RMS over the diagonal, bytes) points.
struct Curve {
    std::string name, color;
    std::vector<std::pair<double, double>> points;  // rms, bytes
};

// Bytes against RMS error, both on log axes, as a small standalone SVG.
std::string tradeoffSvg(const std::string& title, const std::vector<Curve>& curves)
{
    const double W = 640, H = 420, left = 70, right = 170, top = 40, bottom = 50;
    double x0 = 1e-5, x1 = 1e-2, y0 = 1e2, y1 = 1e6;  // 0.001%..1%, 100 B..1 MB
    auto X = [&](double rms) {
        return left + (std::log10(std::clamp(rms, x0, x1)) - std::log10(x0)) / (std::log10(x1) - std::log10(x0)) *
                          (W - left - right);
    };
    auto Y = [&](double bytes) {
        return H - bottom - (std::log10(std::clamp(bytes, y0, y1)) - std::log10(y0)) /
                                (std::log10(y1) - std::log10(y0)) * (H - top - bottom);
    };
    std::ostringstream o;
    o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H
      << "\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    o << "<text x=\"" << left << "\" y=\"22\" font-size=\"14\">" << title << "</text>\n";
    for (double e = -5; e <= -2; e += 1) {  // x grid: decades of RMS
        const double x = X(std::pow(10.0, e));
        o << "<line x1=\"" << x << "\" y1=\"" << top << "\" x2=\"" << x << "\" y2=\"" << H - bottom
          << "\" stroke=\"#ddd\"/>\n<text x=\"" << x - 18 << "\" y=\"" << H - bottom + 16 << "\">"
          << std::pow(10.0, e + 2) << "%</text>\n";
    }
    for (double e = 2; e <= 6; e += 1) {  // y grid: decades of bytes
        const double y = Y(std::pow(10.0, e));
        o << "<line x1=\"" << left << "\" y1=\"" << y << "\" x2=\"" << W - right << "\" y2=\"" << y
          << "\" stroke=\"#ddd\"/>\n<text x=\"" << 8 << "\" y=\"" << y + 4 << "\">"
          << (e == 2 ? "100 B" : e == 3 ? "1 KB" : e == 4 ? "10 KB" : e == 5 ? "100 KB" : "1 MB") << "</text>\n";
    }
    o << "<text x=\"" << left + 120 << "\" y=\"" << H - 12 << "\">RMS distance to the original / diagonal</text>\n";
    int row = 0;
    for (const Curve& c : curves) {
        if (c.points.empty())
            continue;
        std::vector<std::pair<double, double>> pts = c.points;
        std::sort(pts.begin(), pts.end());
        o << "<polyline fill=\"none\" stroke=\"" << c.color << "\" stroke-width=\"2\" points=\"";
        for (const auto& [r, b] : pts)
            o << X(r) << "," << Y(b) << " ";
        o << "\"/>\n";
        for (const auto& [r, b] : pts)
            o << "<circle cx=\"" << X(r) << "\" cy=\"" << Y(b) << "\" r=\"3\" fill=\"" << c.color << "\"/>\n";
        const double ly = top + 14 + 18 * row++;
        o << "<rect x=\"" << W - right + 12 << "\" y=\"" << ly - 8 << "\" width=\"12\" height=\"4\" fill=\"" << c.color
          << "\"/><text x=\"" << W - right + 30 << "\" y=\"" << ly - 2 << "\">" << c.name << "</text>\n";
    }
    o << "</svg>\n";
    return o.str();
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

// The strata-bake command line that bakes a pair into `rig` with its
// report at `report`, plus `extra` flags.
std::string bakeCommand(const std::string& bakeExe, const Pair& pair, const std::string& rig, const std::string& report,
                        const std::string& extra)
{
    // The compact coding: the rig against Draco and gltfpack is the smallest
    // Strata writes (the default, plain accessors, opens in more tools).
    return bakeExe + " --high '" + pair.high + "' --control '" + pair.control + "' " + pair.flags + extra +
           " --mesh-coding draco --threads 2 -o '" + rig + "' --report '" + report + "'";
}

// One row of the atlas table: the pair baked again with --exr, where the
// atlas the baker lays out is an output (issue 11's targets: at least 70%
// of the map's texels inside charts, at most 1.3x the control vertices).
std::string atlasRow(const Pair& pair, const std::string& dir, const std::string& bakeExe, Json* j)
{
    if (shell(bakeCommand(bakeExe, pair, dir + "/atlas.glb", dir + "/atlas.json", " --exr") + " > /dev/null") != 0)
        return "| " + pair.name + " | bake with --exr failed | | | | | | | |\n";
    Json report;
    std::ifstream(dir + "/atlas.json") >> report;
    if (!report.contains("atlas"))
        return "";
    const Json& a = report["atlas"];
    const int size = report["map"]["size"].get<int>(), level = report["recommendedLevel"].get<int>();
    double rms = -1.0;
    for (const Json& e : report["tradeOff"])
        if (e["size"].get<int>() == size && e["level"].get<int>() == level)
            rms = e["rms"].get<double>();
    const size_t charts = a["charts"].get<size_t>();  // 0: the per-triangle atlas, which reports no fill
    const double vertices = double(report["control"]["vertices"].get<size_t>());
    const double split = double(a["splitVertices"].get<size_t>());
    const double fill = a.value("texelFill", 0.0), worst = a.value("maxDistortion", 0.0);
    const double stretch = a.value("stretch", 0.0);  // one chart over the whole map: its L2 stretch
    const std::string kind = a.value("kind", std::string("charts"));
    const double exrBytes = fileBytes(dir + "/atlas.exr"), glbBytes = fileBytes(dir + "/atlas.glb");
    *j = {{"charts", charts}, {"kind", kind}, {"texelFill", fill}, {"maxDistortion", worst}, {"stretch", stretch},
          {"splitVertices", split}, {"controlVertices", vertices}, {"mapSize", size}, {"level", level},
          {"mapRms", rms}, {"exrBytes", exrBytes}, {"glbBytes", glbBytes}};
    char chartText[64], distortionText[64];
    if (kind == "whole map") {
        std::snprintf(chartText, sizeof(chartText), "1 (whole map)");
        std::snprintf(distortionText, sizeof(distortionText), "L2 %.2f, max %.1f", stretch, worst);
    } else {
        std::snprintf(chartText, sizeof(chartText), "%zu", charts);
        std::snprintf(distortionText, sizeof(distortionText), "max %.2f", worst);
    }
    char fillText[64] = "per-triangle atlas";
    if (charts)
        std::snprintf(fillText, sizeof(fillText), "%.1f%% (%s)", 100.0 * fill, fill >= 0.70 ? "yes" : "no");
    char line[400];
    std::snprintf(line, sizeof(line),
                  "| %s | %s | %d^2 | %s | %.0f / %.0f = %.2fx (%s) | %s | %s at level %d | %s | %s |\n",
                  pair.name.c_str(), chartText, size, fillText, split, vertices, split / vertices,
                  split <= 1.3 * vertices ? "yes" : "no", distortionText, rms >= 0.0 ? pct(rms).c_str() : "-", level,
                  kb(exrBytes).c_str(), kb(glbBytes).c_str());
    return line;
}

// The bytes a curve spends at `rms`: log-log between the two points that
// bracket it; -1 outside the curve's range.
double bytesAt(std::vector<std::pair<double, double>> points, double rms)
{
    std::sort(points.begin(), points.end());
    for (size_t i = 1; i < points.size(); ++i) {
        const auto [r0, b0] = points[i - 1];
        const auto [r1, b1] = points[i];
        if (rms < r0 || rms > r1 || !(r0 > 0.0) || !(b0 > 0.0) || !(b1 > 0.0))
            continue;
        const double t = r1 > r0 ? std::log(rms / r0) / std::log(r1 / r0) : 0.0;
        return std::exp(std::log(b0) + t * (std::log(b1) - std::log(b0)));
    }
    return -1.0;
}

// A rig as a user's engine draws it: rebuilt by strata-reconstruct at its
// recommended level, then measured like every other representation.
Accuracy rigAccuracy(const std::string& rig, const std::string& dir, const baker::TriangleMesh& high,
                     const baker::TriangleIndex& highIndex, double diag)
{
    const std::string mesh = dir + "/sweep_reconstructed.ply";
    if (shell(std::string(STRATA_RECONSTRUCT_EXE) + " '" + rig + "' --static -o '" + mesh + "'") != 0)
        return Accuracy();
    baker::TriangleMesh drawn;
    if (!baker::loadHighMesh(mesh, &drawn, nullptr))
        return Accuracy();
    return accuracy(drawn.positions, drawn.triangles, high, highIndex, diag);
}

// The size/error trade-off of one pair: Strata at tolerances 0.2%..0.005%
// (--control auto with the default coding and with a Draco-coded cage, and
// onto the pair's own cage), Draco of the original at qp 8..14,
// decimate-then-Draco at 0.5..50% of the faces (qp 11) and gltfpack.  Every
// point is measured the same way, by area-weighted sampling of both
// surfaces (Strata's rebuilt from its file).  Appends the tables and the
// verdict against decimate-then-Draco to `md`; writes OUT/tradeoff_NAME.svg.
Json sweepPair(const Pair& pair, const std::string& dir, const baker::TriangleMesh& high,
               const baker::TriangleIndex& highIndex, double diag, const std::string& out, const std::string& bakeExe,
               std::string* md)
{
    enum { kAuto, kAutoDraco, kCage, kDraco, kDecimated, kDecimatedGlb, kGltfpack };
    std::vector<Curve> curves = {{"Strata auto (default)", "#d62728", {}},
                                 {"Strata auto, Draco cage", "#ff7f0e", {}},
                                 {"Strata, its cage", "#8c564b", {}},
                                 {"Draco qp 8-14", "#1f77b4", {}},
                                 {"decimate + Draco .drc", "#2ca02c", {}},
                                 {"decimate + Draco glb", "#17becf", {}},
                                 {"gltfpack -cc", "#9467bd", {}}};
    // gltf-transform from the project's npm tools (js/), where installed.
    const std::string gltfTransformPath = std::string(STRATA_SOURCE_DIR) + "/js/node_modules/.bin/gltf-transform";
    const std::string gltfTransform = fileBytes(gltfTransformPath) > 0.0 ? "'" + gltfTransformPath + "'" : "";
    Json sweep = Json::array();
    const double tolerances[] = {0.002, 0.001, 0.0005, 0.0002, 0.0001, 0.00005};
    struct Config {
        int curve;
        const char* name;
        std::string flags;
    };
    std::vector<Config> configs = {{kAuto, "strata auto", "--control auto"},
                                   {kAutoDraco, "strata auto draco", "--control auto --mesh-coding draco"}};
    if (pair.control != "auto")
        configs.push_back({kCage, "strata cage", "--control '" + pair.control + "' " + pair.flags});
    for (const Config& c : configs) {
        for (double tol : tolerances) {
            const std::string rig = dir + "/sweep.glb", report = dir + "/sweep.json";
            char tolText[32];
            std::snprintf(tolText, sizeof(tolText), "%g", tol);
            const double t0 = bench::nowMs();
            if (shell(bakeExe + " --high '" + pair.high + "' " + c.flags + " --threads 2 --tolerance " + tolText +
                      " -o '" + rig + "' --report '" + report + "'") != 0)
                continue;
            const double seconds = (bench::nowMs() - t0) / 1000.0;
            Json sr;
            std::ifstream(report) >> sr;
            const int level = sr["recommendedLevel"].get<int>();
            double bakeRms = -1.0;
            for (const Json& e : sr["closedLoop"])
                if (e["level"].get<int>() == level)
                    bakeRms = std::max(e["forwardRms"].get<double>(), e["backwardRms"].get<double>());
            const Accuracy a = rigAccuracy(rig, dir, high, highIndex, diag);
            if (a.rms < 0.0)
                continue;
            const double bytes = fileBytes(rig);
            curves[size_t(c.curve)].points.push_back({a.rms, bytes});
            sweep.push_back({{"curve", c.name}, {"tolerance", tol}, {"level", level}, {"bytes", bytes},
                             {"rms", a.rms}, {"max", a.max}, {"bakeRms", bakeRms},
                             {"cageFaces", sr["control"]["triangles"].get<size_t>()}, {"seconds", seconds}});
            std::printf("  %s %s: %.0f B, %.4f%% (bake says %.4f%%), %.1f s\n", c.name, pct(tol).c_str(), bytes,
                        100.0 * a.rms, 100.0 * bakeRms, seconds);
            std::fflush(stdout);
        }
    }
    const bool haveDraco = have("draco_encoder") && have("draco_decoder");
    if (haveDraco) {
        for (int qp = 8; qp <= 14; ++qp) {
            double bytes = 0;
            std::vector<glm::vec3> p;
            std::vector<uint32_t> t;
            if (draco(dir, "sweep_draco", high.positions, high.triangles, qp, &bytes, &p, &t)) {
                const double rms = accuracy(p, t, high, highIndex, diag).rms;
                curves[kDraco].points.push_back({rms, bytes});
                sweep.push_back({{"curve", "draco"}, {"qp", qp}, {"bytes", bytes}, {"rms", rms}});
            }
        }
        for (double fraction : {0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5}) {
            ControlMesh dec;
            const size_t faces = std::max<size_t>(8, size_t(fraction * double(high.faceCount())));
            if (!baker::decimateToControlMesh(high, faces, &dec))
                continue;
            double bytes = 0;
            std::vector<glm::vec3> p;
            std::vector<uint32_t> t;
            if (draco(dir, "sweep_decimated", dec.positions, dec.triangles, 11, &bytes, &p, &t)) {
                const double rms = accuracy(p, t, high, highIndex, diag).rms;
                curves[kDecimated].points.push_back({rms, bytes});
                sweep.push_back({{"curve", "decimate+draco"}, {"fraction", fraction}, {"bytes", bytes}, {"rms", rms}});
            }
            // The same decimation as the file a user ships: a glb that
            // gltf-transform Draco-codes at qp 11.
            if (!gltfTransform.empty() && writeGlb(dir + "/sweep_decimated.glb", dec.positions, dec.triangles) &&
                shell(gltfTransform + " draco '" + dir + "/sweep_decimated.glb' '" + dir +
                      "/sweep_decimated_draco.glb' --quantize-position 11") == 0 &&
                io::loadGltfTriangles(dir + "/sweep_decimated_draco.glb", &p, &t)) {
                const double glbBytes = fileBytes(dir + "/sweep_decimated_draco.glb");
                const double rms = accuracy(p, t, high, highIndex, diag).rms;
                curves[kDecimatedGlb].points.push_back({rms, glbBytes});
                sweep.push_back(
                    {{"curve", "decimate+draco glb"}, {"fraction", fraction}, {"bytes", glbBytes}, {"rms", rms}});
            }
        }
    }
    if (have("gltfpack")) {
        writeGlb(dir + "/original.glb", high.positions, high.triangles);
        for (const char* q : {"-cc", "-cc -vp 10", "-cc -vp 12"}) {
            if (shell("gltfpack -i '" + dir + "/original.glb' -o '" + dir + "/sweep_gltfpack.glb' " + q) != 0)
                continue;
            std::vector<glm::vec3> p;
            std::vector<uint32_t> t;
            if (!io::loadGltfTriangles(dir + "/sweep_gltfpack.glb", &p, &t))
                continue;
            const double bytes = fileBytes(dir + "/sweep_gltfpack.glb");
            const double rms = accuracy(p, t, high, highIndex, diag).rms;
            curves[kGltfpack].points.push_back({rms, bytes});
            sweep.push_back({{"curve", "gltfpack"}, {"flags", q}, {"bytes", bytes}, {"rms", rms}});
        }
    }
    std::ofstream(out + "/tradeoff_" + pair.name + ".svg") << tradeoffSvg(pair.name + ": bytes against RMS error", curves);
    *md += "\nSize against error (plot: `tradeoff_" + pair.name +
           ".svg`; every RMS measured by area-weighted sampling of both surfaces, Strata's rebuilt from the file "
           "by strata-reconstruct at its recommended level):\n\n| curve | setting | bytes | RMS | bake's own RMS |\n"
           "|---|---|---|---|---|\n";
    for (const Json& e : sweep) {
        std::string setting = e.contains("tolerance")  ? "tolerance " + pct(e["tolerance"].get<double>()) + ", " +
                                                              std::to_string(e["cageFaces"].get<size_t>()) +
                                                              " cage faces, level " + std::to_string(e["level"].get<int>())
                              : e.contains("qp")       ? "qp " + std::to_string(e["qp"].get<int>())
                              : e.contains("fraction") ? std::to_string(e["fraction"].get<double>() * 100.0).substr(0, 3) +
                                                             "% of the faces, qp 11"
                                                       : e["flags"].get<std::string>();
        *md += "| " + e["curve"].get<std::string>() + " | " + setting + " | " + kb(e["bytes"].get<double>()) + " | " +
               pct(e["rms"].get<double>()) + " | " + (e.contains("bakeRms") ? pct(e["bakeRms"].get<double>()) : "") +
               " |\n";
    }
    // The verdict: each --control auto point against decimate-then-Draco at
    // the same RMS, as the raw .drc bitstream and as a Draco glb: at or
    // below where no decimated point is both smaller and at least as
    // close, and the decimated curve interpolated to the same RMS is no
    // smaller.
    // The .drc curve ends at the whole capture: Draco of the original at qp 11.
    std::vector<std::pair<double, double>> wholeDrc = curves[kDecimated].points;
    for (const Json& e : sweep)
        if (e["curve"] == "draco" && e["qp"].get<int>() == 11)
            wholeDrc.push_back({e["rms"].get<double>(), e["bytes"].get<double>()});
    auto verdict = [&](int curve, double rms, double bytes, double* at) {
        const std::vector<std::pair<double, double>>& points =
            curve == kDecimated ? wholeDrc : curves[size_t(curve)].points;
        *at = bytesAt(points, rms);
        for (const auto& [r, b] : points)
            if (r <= rms && b < bytes)
                return false;
        return *at < 0.0 || bytes <= *at;
    };
    if (!curves[kDecimated].points.empty()) {
        *md += "\n`--control auto` against decimate-then-Draco (qp 11) at the same RMS (the .drc curve ends at the whole "
               "capture, Draco of the original at qp 11; \"-\": that RMS is outside the decimated curve's range; a "
               "decimated point both smaller and at least as close still loses it):\n\n"
               "| coding | tolerance | RMS | Strata bytes | decimate+Draco .drc | verdict | decimate+Draco glb | verdict |\n"
               "|---|---|---|---|---|---|---|---|\n";
        for (Json& e : sweep) {
            const std::string curve = e["curve"].get<std::string>();
            if (curve != "strata auto" && curve != "strata auto draco")
                continue;
            const double rms = e["rms"].get<double>(), bytes = e["bytes"].get<double>();
            double drc = -1.0, glb = -1.0;
            const bool beatsDrc = verdict(kDecimated, rms, bytes, &drc);
            const bool beatsGlb = verdict(kDecimatedGlb, rms, bytes, &glb);
            const bool haveGlb = !curves[kDecimatedGlb].points.empty();
            char line[400];
            std::snprintf(line, sizeof(line), "| %s | %s | %s | %s | %s | %s | %s | %s |\n",
                          curve == "strata auto" ? "default (plain)" : "`--mesh-coding draco`",
                          pct(e["tolerance"].get<double>()).c_str(), pct(rms).c_str(), kb(bytes).c_str(),
                          drc > 0.0 ? kb(drc).c_str() : "-", beatsDrc ? "at or below" : "**loses**",
                          !haveGlb ? "not measured" : glb > 0.0 ? kb(glb).c_str() : "-",
                          !haveGlb ? "" : beatsGlb ? "at or below" : "**loses**");
            *md += line;
            e["decimatedDrcBytesAtRms"] = drc;
            e["beatsDecimatedDrc"] = beatsDrc;
            if (haveGlb) {
                e["decimatedGlbBytesAtRms"] = glb;
                e["beatsDecimatedGlb"] = beatsGlb;
            }
        }
    }
    return sweep;
}

Json runPair(const Pair& pair, const std::string& out, const std::string& bakeExe, std::string* md,
             std::string* atlasMd)
{
    Json j;
    j["name"] = pair.name;
    const std::string dir = out + "/" + pair.name;
    shell("mkdir -p '" + dir + "'");
    std::printf("== %s\n", pair.name.c_str());
    std::fflush(stdout);
    const std::string rigPath = dir + "/rig.glb";
    const std::string cmd = bakeCommand(bakeExe, pair, rigPath, dir + "/bake.json", "");
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
        if (draco(dir, "original", high.positions, high.triangles, 0, &r.bytes, &p, &t)) {
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
            if (!draco(dir, "decimated", dec.positions, dec.triangles, 0, &r.bytes, &p, &t))
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
    // Regeneration at N = 0..6 on one core, through strata::Surface in the rig's own scheme.
    // Regeneration at N = 0..6 on one core (linear and the bake's scheme).
    Rig rig;
    io::loadRig(rigPath, &rig);
    DisplacementMap map;
    io::loadRigDisplacementMap(rigPath, rig, &map);
    Json regen = Json::array();
    std::string regenMd = "| N | refined vertices | triangles | setup ms | regenerate ms (eq. 2) | + shading normals ms |"
                          " GPU (" + gpuName() + ") stencils + displace + normals ms |\n"
                          "|---|---|---|---|---|---|---|\n";
    for (int n = 0; n <= kMaxLevel; ++n) {
        // Through strata::Surface, as an engine draws the rig (its own scheme).
        const double t0 = bench::nowMs();
        std::unique_ptr<Surface> drawn;
        SurfaceOptions surfaceOptions;
        surfaceOptions.level = n;
        if (!Surface::create(&drawn, rig, &map, surfaceOptions))
            break;
        const double setup = bench::nowMs() - t0;
        const Plan* plan = &drawn->plan();
        std::vector<glm::vec3> pos(drawn->vertexCount()), sn(pos.size());
        const double eval = bench::medianMs([&] { drawn->evaluate(pos.data(), nullptr, pos.size()); }, 5, 20.0);
        const double shade =
            bench::medianMs([&] { drawn->evaluate(pos.data(), sn.data(), pos.size()); }, 5, 20.0) - eval;
        const std::vector<glm::vec3>& normals = drawn->controlNormals();
        double gpu = -1.0;
#ifdef STRATA_HAVE_GL
        std::unique_ptr<gl::GpuSurface> surface;
        if (gpuContext() && n <= 5 && gl::GpuSurface::create(&surface, *plan) && surface->setDisplacementMap(map)) {
            gpu = bench::medianMs([&] {
                surface->update(drawn->controlPositions().data(), normals.data(), normals.size());
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

    std::string sweepMd;
    const Json sweep = sweepPair(pair, dir, high, highIndex, diag, out, bakeExe, &sweepMd);

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
    *md += sweepMd;
    j["rows"] = jr;
    j["tradeoff"] = sweep;
    j["bakeMs"] = tm;
    j["regeneration"] = regen;
    j["diagonal"] = diag;
    j["recommendedLevel"] = level;
    if (report.contains("atlas")) {
        Json atlas;
        *atlasMd += atlasRow(pair, dir, bakeExe, &atlas);
        j["atlasWithExr"] = atlas;
    }
    return j;
}

}  // namespace

int main(int argc, char** argv)
{
    std::string out = "report";
    std::string mode;
    std::string only;  // tradeoff: a comma-separated list of pairs, or all
    const char* usage = "usage: strata-bench paper|tradeoff [--out DIR] [--pairs NAME,NAME]\n";
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "paper" || a == "tradeoff")
            mode = a;
        else if (a == "--pairs" && i + 1 < argc)
            only = "," + std::string(argv[++i]) + ",";
        else if (a == "--version") {
            std::printf("strata-bench %s\n", STRATA_VERSION);
            return 0;
        }
        else if (a == "--out" && i + 1 < argc)
            out = argv[++i];
        else {
            std::fprintf(stderr, "%s", usage);
            return 2;
        }
    }
    if (mode.empty()) {
        std::fprintf(stderr, "%s", usage);
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
    if (!only.empty())
        pairs.erase(std::remove_if(pairs.begin(), pairs.end(),
                                   [&](const Pair& p) { return only.find("," + p.name + ",") == std::string::npos; }),
                    pairs.end());
    if (mode == "tradeoff") {
        // The size/error sweeps alone (issue 29: --control auto against
        // decimate-then-Draco on every real pair).
        std::string md = "# Strata: bytes against error\n\nMade by `strata-bench tradeoff --out " + out + "`.\n";
        Json all = Json::array();
        for (const Pair& p : pairs) {
            std::printf("== %s\n", p.name.c_str());
            std::fflush(stdout);
            const std::string dir = out + "/" + p.name;
            shell("mkdir -p '" + dir + "'");
            baker::TriangleMesh high;
            if (!baker::loadHighMesh(p.high, &high, nullptr))
                continue;
            glm::vec3 lo(1e30f), hi(-1e30f);
            for (const glm::vec3& q : high.positions) {
                lo = glm::min(lo, q);
                hi = glm::max(hi, q);
            }
            const double diag = glm::length(glm::dvec3(hi) - glm::dvec3(lo));
            baker::TriangleIndex highIndex;
            highIndex.build(high.positions.data(), high.triangles.data(), high.faceCount(), 2);
            char head[256];
            std::snprintf(head, sizeof(head), "\n### %s\n\n%zu triangles, diagonal %.4g.\n", p.name.c_str(),
                          high.faceCount(), diag);
            md += head;
            Json j;
            j["name"] = p.name;
            j["diagonal"] = diag;
            j["tradeoff"] = sweepPair(p, dir, high, highIndex, diag, out, bakeExe, &md);
            all.push_back(j);
        }
        std::ofstream(out + "/TRADEOFF.md") << md;
        std::ofstream(out + "/tradeoff.json") << all.dump(2) << "\n";
        std::printf("%s", md.c_str());
        return 0;
    }
    std::string md = "# Strata evidence report\n\nMade by `strata-bench paper --out " + out +
                     "`.  Sizes are file bytes; errors are surface distances to the original, area-weighted samples "
                     "of both surfaces in both directions (the larger), relative to the bounding-box diagonal.\n";
    Json all = Json::array();
    std::string atlasMd;
    for (const Pair& p : pairs)
        all.push_back(runPair(p, out, bakeExe, &md, &atlasMd));
    if (!atlasMd.empty())
        md += "\n### The atlas, baked again with `--exr`\n\nThe atlas is an output only where the map is "
              "(`--exr`, `--png8/16`); the default rig leaves it out.  Targets: at least 70% of the map's texels "
              "inside charts, at most 1.3x as many glb vertices as control vertices; where the chart atlas misses "
              "them, one chart over the whole map.  Distortion: a chart atlas's worst direction against its "
              "chart's mean (max); the whole map's L2 stretch (1 is an isometry) and worst direction.  Map RMS: "
              "the map's own samples at the chosen size and level, both directions, the larger.\n\n"
              "| pair | charts | map | texels inside charts (>= 70%) | glb / control vertices (<= 1.3x) | "
              "distortion | map RMS | EXR | glb |\n|---|---|---|---|---|---|---|---|---|\n" +
              atlasMd;
    std::ofstream(out + "/RESULTS.md") << md;
    std::ofstream(out + "/results.json") << all.dump(2) << "\n";
    std::printf("%s", md.c_str());
    return 0;
}
