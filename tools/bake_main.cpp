// strata-bake: captured high-resolution mesh + control mesh -> one
// self-contained control rig (paper 2.1-2.3, 3.2).  Parses the command line
// into a baker::BakeRequest, calls baker::bakeRig and prints what it
// returns; the pipeline itself lives in baker/src/bake_rig.cpp.
#include "cli.h"

#include "strata/baker/bake_rig.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <thread>

using namespace strata;

namespace {

const char* kUsage =
    "usage: strata-bake --high HIGH.{obj,ply,stl,off,glb,gltf} --control CONTROL.{obj,glb,gltf}|auto\n"
    "                   [--control-faces K] [--uv keep|auto] [--size auto|N] [--scheme linear|smooth]\n"
    "                   [--float] [--png8|--png16] [--overlap max|nearest] [--threads N]\n"
    "                   [--tolerance E|P%] [--error-levels N|A:B|none] [--skeleton JOINTS.json] [--exr] [--layers]\n"
    "                   [--map-coding vertex|png] [--mesh-coding plain|meshopt|draco] [--keep-holes]\n"
    "                   [--no-fit] [--max-memory MB]\n"
    "                   -o RIG.{glb,gltf} [--report REPORT.json|-] [--version]\n"
    "--tolerance (default 0.01%: RMS distance over the diagonal, both directions) picks the\n"
    "smallest map size and level that reach it in the closed loop (--size forces a size), and\n"
    "for --control auto the fewest cage faces that do (--control-faces fixes the count);\n"
    "on a cage file that every level to the capture's density misses by over 2x, one level\n"
    "finer is tried.\n"
    "The rig is one self-contained file: the map is stored as its samples at the recommended\n"
    "level's refined vertices, quantised to the bits the tolerance needs, predicted in\n"
    "subdivision order and zstd-coded (--map-coding png embeds it as a grey PNG instead);\n"
    "the control mesh is written as plain accessors, which every glTF tool opens (Blender 3.4,\n"
    "gltfpack); --mesh-coding meshopt (EXT_meshopt_compression) or draco (a bare cage as\n"
    "KHR_draco_mesh_compression, positions to four times the tolerance) write smaller files\n"
    "that three.js, Babylon.js and Strata read but Blender 3.4 and gltfpack do not.  An atlas\n"
    "the baker lays out only serves the bake and stays out of the rig unless an output that is\n"
    "the map asks for it: --exr also writes it as RIG.exr for pipelines, --png8/--png16 as a\n"
    "PNG, --layers writes RIG_layers.png (surface layers per texel).\n"
    "A bare control mesh (OBJ or --control auto) is fitted to the capture first: its vertices\n"
    "move so that the scheme's base surface lies close to the capture in both directions\n"
    "(Displaced Subdivision Surfaces; --no-fit keeps them).  A glTF control's or a skinned\n"
    "cage's never move, nor does a cage file's when --exr or --png asks for the map itself.\n";

// Fills the request from the command line; false when the run is done
// (--help, --version).  Bad flags throw cli::Error.
bool parseArgs(int argc, char** argv, baker::BakeRequest* r)
{
    r->options.threads = int(std::max(1u, std::thread::hardware_concurrency()));
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&] { return cli::flagValue(argc, argv, &i); };
        if (a == "-h" || a == "--help") {
            std::fputs(kUsage, stdout);
            return false;
        } else if (a == "--version") {
            std::printf("strata-bake %s\n", cli::kVersion);
            return false;
        } else if (a == "--tolerance") {
            const std::string v = value();
            double& tolerance = r->tolerance;
            tolerance = double(cli::parseFloat(a, v.size() && v.back() == '%' ? v.substr(0, v.size() - 1) : v));
            if (v.size() && v.back() == '%')
                tolerance /= 100.0;
            if (!(tolerance >= 0.0 && tolerance < 1.0))
                throw cli::Error("--tolerance expects a fraction of the diagonal (or a percentage, 0.01%), got \"" + v +
                                 "\"");
        } else if (a == "--max-memory") {
            r->maxMemoryMB = double(cli::parseInt(a, value(), 16, 1 << 24));
        } else if (a == "--mesh-coding") {
            r->meshCoding = value();
            if (r->meshCoding != "plain" && r->meshCoding != "draco" && r->meshCoding != "meshopt")
                throw cli::Error("--mesh-coding takes plain, meshopt or draco, not " + r->meshCoding);
        } else if (a == "--no-compress") {
            r->compress = false;
        } else if (a == "--keep-holes") {
            r->closeHoles = false;
        } else if (a == "--no-fit") {
            r->fitCage = false;
        } else if (a == "--map-coding") {
            r->mapCoding = value();
            if (r->mapCoding != "vertex" && r->mapCoding != "png")
                throw cli::Error("--map-coding expects vertex or png");
        } else if (a == "--exr") {
            r->exr = true;
        } else if (a == "--layers") {
            r->layers = true;
        } else if (a == "--high") {
            r->high = value();
        } else if (a == "--control") {
            r->control = value();
        } else if (a == "--skeleton") {
            r->skeleton = value();
        } else if (a == "--control-faces") {
            r->controlFaces = size_t(cli::parseInt(a, value(), 4, 10000000));
        } else if (a == "--uv") {
            r->uv = value();
            if (r->uv != "keep" && r->uv != "auto")
                throw cli::Error("--uv expects keep or auto");
        } else if (a == "--size") {
            const std::string size = value();
            if (size != "auto")
                r->options.size = cli::parseInt(a, size, 16, 8192);
        } else if (a == "--scheme") {
            if (!parseScheme(value(), &r->options.scheme))
                throw cli::Error("--scheme expects linear or smooth");
            r->schemeGiven = true;
        } else if (a == "--float") {
            r->floatExr = true;
        } else if (a == "--png8") {
            r->pngBits = 8;
        } else if (a == "--png16") {
            r->pngBits = 16;
        } else if (a == "--overlap") {
            r->options.overlap = cli::parseChoice<baker::OverlapPolicy>(
                a, value(), {{"max", baker::OverlapPolicy::Max}, {"nearest", baker::OverlapPolicy::Nearest}});
        } else if (a == "--threads") {
            r->options.threads = cli::parseInt(a, value(), 1, 256);
        } else if (a == "--error-levels") {
            const std::string v = value();
            const size_t colon = v.find(':');
            if (v == "none") {
                r->errorFrom = r->errorTo = -1;
            } else if (colon == std::string::npos) {
                r->errorFrom = 0;
                r->errorTo = cli::parseInt(a, v, -1, kMaxLevel);
            } else {
                r->errorFrom = cli::parseInt(a, v.substr(0, colon), 0, kMaxLevel);
                r->errorTo = cli::parseInt(a, v.substr(colon + 1), r->errorFrom, kMaxLevel);
            }
        } else if (a == "-o" || a == "--output") {
            r->output = value();
        } else if (a == "--report") {
            r->report = value();
        } else {
            throw cli::Error("unknown argument " + a + " (see --help)");
        }
    }
    if (r->high.empty() || r->control.empty() || r->output.empty())
        throw cli::Error("--high, --control and -o are required (see --help)");
    return true;
}

}  // namespace

int main(int argc, char** argv)
{
    return cli::run("strata-bake", [&]() -> int {
        baker::BakeRequest request;
        if (!parseArgs(argc, argv, &request))
            return 0;
        const baker::BakeProgress progress = [](const char* stage, double seconds) {
            if (seconds < 0.0)
                std::fprintf(stderr, "strata-bake: %s...\n", stage);
            else
                std::fprintf(stderr, "strata-bake: %s done in %.1f s\n", stage, seconds);
        };
        baker::BakeResult result;
        const Status st = baker::bakeRig(request, &result, &progress);
        for (const std::string& w : result.warnings)
            std::fprintf(stderr, "strata-bake: warning: %s\n", cli::printable(w).c_str());
        if (!st)
            throw cli::Error(st.message());
        // With --report -, stdout carries the JSON and the summary goes to stderr.
        std::fputs(result.summary.c_str(), request.report == "-" ? stderr : stdout);
        if (request.report == "-")
            std::fputs(result.report.c_str(), stdout);
        return 0;
    });
}
