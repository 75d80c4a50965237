// strata-bake: captured high-resolution mesh + control mesh -> control rig
// (RIG.glb) and displacement map (RIG.exr) beside it (paper 2.1-2.3, 3.2).
//
//   strata-bake --high HIGH --control CONTROL|auto [--control-faces K]
//       [--uv keep|auto] [--size auto|N] [--scheme linear|smooth] [--float]
//       [--png8|--png16] [--overlap max|nearest] [--threads N]
//       [--error-levels N] [--skeleton JOINTS.json] -o RIG.glb
//       [--report REPORT.json]
#include "cli.h"

#include "strata/baker/atlas.h"
#include "strata/baker/bake.h"
#include "strata/baker/mesh_input.h"
#include "strata/displacement_math.h"
#include "strata/segment_deformer.h"
#include "strata/io/exr.h"
#include "strata/io/file.h"
#include "strata/io/joint_file.h"
#include "strata/io/png.h"
#include "strata/io/rig_io.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>

using namespace strata;

namespace {

const char* kUsage =
    "usage: strata-bake --high HIGH.{obj,ply,stl,off,glb,gltf} --control CONTROL.{obj,glb,gltf}|auto\n"
    "                   [--control-faces K] [--uv keep|auto] [--size auto|N] [--scheme linear|smooth]\n"
    "                   [--float] [--png8|--png16] [--overlap max|nearest] [--threads N]\n"
    "                   [--tolerance E|P%] [--error-levels N|A:B|none] [--skeleton JOINTS.json] [--exr] [--layers]\n"
    "                   [--map-coding vertex|png] [--no-compress] [--max-memory MB]\n"
    "                   -o RIG.{glb,gltf} [--report REPORT.json|-] [--version]\n"
    "--tolerance (default 0.01%: RMS distance over the diagonal, both directions) picks the\n"
    "smallest map size and level that reach it in the closed loop; --size forces a size.\n"
    "The rig is one self-contained file: the map is stored as its samples at the recommended\n"
    "level's refined vertices, quantised to the bits the tolerance needs, predicted in\n"
    "subdivision order and zstd-coded (--map-coding png embeds it as a grey PNG instead);\n"
    "vertex data and indices are meshopt-coded (EXT_meshopt_compression; --no-compress\n"
    "for tools without it).  --exr also\n"
    "writes it as RIG.exr for pipelines; --layers writes RIG_layers.png (surface layers per texel).\n";

double msSince(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Prints "stage..." on stderr only if the stage runs longer than a second,
// then its duration when it ends.
class Progress {
public:
    explicit Progress(const char* stage) : stage_(stage), t0_(std::chrono::steady_clock::now())
    {
        watcher_ = std::thread([this] {
            std::unique_lock<std::mutex> lock(m_);
            if (!cv_.wait_for(lock, std::chrono::seconds(1), [this] { return done_; })) {
                std::fprintf(stderr, "strata-bake: %s...\n", stage_);
                announced_ = true;
            }
        });
    }
    ~Progress()
    {
        {
            std::lock_guard<std::mutex> lock(m_);
            done_ = true;
        }
        cv_.notify_all();
        watcher_.join();
        if (announced_)
            std::fprintf(stderr, "strata-bake: %s done in %.1f s\n", stage_, msSince(t0_) / 1000.0);
    }

private:
    const char* stage_;
    std::chrono::steady_clock::time_point t0_;
    std::mutex m_;
    std::condition_variable cv_;
    bool done_ = false;
    bool announced_ = false;
    std::thread watcher_;
};

// Files written by this run, removed again if a later step fails, so a
// failed bake leaves nothing behind.
// Every output is first written under a staging name beside its target and
// renamed into place only when the whole bake has succeeded, so a failed
// command never removes or truncates what an earlier one wrote.
struct Outputs {
    std::vector<std::string> written;  // final names
    bool committed = false;
    static std::string staged(const std::string& path)
    {
        const std::string dir = io::directoryOf(path);
        const size_t slash = path.find_last_of('/');
        const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
        return (dir.empty() ? std::string() : dir + "/") + ".strata-staging-" + name;
    }
    // Writes through `write(stagedPath)`; errors name the final path only.
    template <typename F>
    void write(const std::string& path, F&& write)
    {
        const std::string tmp = staged(path);
        Status st = write(tmp);
        if (!st) {
            std::remove(tmp.c_str());
            std::string msg = st.message();
            for (size_t at; (at = msg.find(tmp)) != std::string::npos;)
                msg.replace(at, tmp.size(), path);
            throw cli::Error(msg);
        }
        written.push_back(path);
    }
    void commit()
    {
        for (const std::string& p : written)
            if (std::rename(staged(p).c_str(), p.c_str()) != 0)
                throw cli::Error(p + ": cannot replace the file (" + std::strerror(errno) + ")");
        committed = true;
    }
    ~Outputs()
    {
        if (!committed)
            for (const std::string& p : written)
                std::remove(staged(p).c_str());
    }
};

std::vector<uint8_t> layerImage(const std::vector<uint16_t>& layers)
{
    // Paper Figure 6f: one layer blue, two green, three or more red.
    std::vector<uint8_t> rgb(layers.size() * 3, 0);
    for (size_t i = 0; i < layers.size(); ++i) {
        const uint16_t l = layers[i];
        uint8_t* p = &rgb[3 * i];
        if (l == 1) {
            p[2] = 160;
        } else if (l == 2) {
            p[1] = 200;
        } else if (l >= 3) {
            p[0] = 230;
        }
    }
    return rgb;
}

}  // namespace

int main(int argc, char** argv)
{
    return cli::run("strata-bake", [&]() -> int {
        std::string highPath, controlPath, outPath, reportPath, uvMode, skeletonPath, sizeArg = "auto";
        size_t controlFaces = 0;
        baker::BakeOptions options;
        bool asFloat = false;
        int pngBits = 0, errorFrom = -2, errorTo = -2;  // -2: around the recommended level
        bool writeExr = false, writeLayers = false;
        double tolerance = 1e-4;  // RMS over the diagonal: 0.01%
        bool schemeGiven = false;
        bool compress = true;
        std::string mapCoding = "vertex";
        double maxMemoryMB = 2048.0;
        options.threads = int(std::max(1u, std::thread::hardware_concurrency()));
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto value = [&] { return cli::flagValue(argc, argv, &i); };
            if (a == "-h" || a == "--help") {
                std::fputs(kUsage, stdout);
                return 0;
            } else if (a == "--version") {
                std::printf("strata-bake %s\n", cli::kVersion);
                return 0;
            } else if (a == "--tolerance") {
                const std::string v = value();
                tolerance = double(cli::parseFloat(a, v.size() && v.back() == '%' ? v.substr(0, v.size() - 1) : v));
                if (v.size() && v.back() == '%')
                    tolerance /= 100.0;
                if (!(tolerance >= 0.0 && tolerance < 1.0))
                    throw cli::Error("--tolerance expects a fraction of the diagonal (or a percentage, 0.01%), got \"" + v +
                                     "\"");
            } else if (a == "--max-memory") {
                maxMemoryMB = double(cli::parseInt(a, value(), 16, 1 << 24));
            } else if (a == "--no-compress") {
                compress = false;
            } else if (a == "--map-coding") {
                mapCoding = value();
                if (mapCoding != "vertex" && mapCoding != "png")
                    throw cli::Error("--map-coding expects vertex or png");
            } else if (a == "--exr") {
                writeExr = true;
            } else if (a == "--layers") {
                writeLayers = true;
            } else if (a == "--high") {
                highPath = value();
            } else if (a == "--control") {
                controlPath = value();
            } else if (a == "--skeleton") {
                skeletonPath = value();
            } else if (a == "--control-faces") {
                controlFaces = size_t(cli::parseInt(a, value(), 4, 10000000));
            } else if (a == "--uv") {
                uvMode = value();
                if (uvMode != "keep" && uvMode != "auto")
                    throw cli::Error("--uv expects keep or auto");
            } else if (a == "--size") {
                sizeArg = value();
                if (sizeArg != "auto")
                    options.size = cli::parseInt(a, sizeArg, 16, 8192);
            } else if (a == "--scheme") {
                if (!parseScheme(value(), &options.scheme))
                    throw cli::Error("--scheme expects linear or smooth");
                schemeGiven = true;
            } else if (a == "--float") {
                asFloat = true;
            } else if (a == "--png8") {
                pngBits = 8;
            } else if (a == "--png16") {
                pngBits = 16;
            } else if (a == "--overlap") {
                options.overlap = cli::parseChoice<baker::OverlapPolicy>(
                    a, value(), {{"max", baker::OverlapPolicy::Max}, {"nearest", baker::OverlapPolicy::Nearest}});
            } else if (a == "--threads") {
                options.threads = cli::parseInt(a, value(), 1, 256);
            } else if (a == "--error-levels") {
                const std::string v = value();
                const size_t colon = v.find(':');
                if (v == "none") {
                    errorFrom = errorTo = -1;
                } else if (colon == std::string::npos) {
                    errorFrom = 0;
                    errorTo = cli::parseInt(a, v, -1, kMaxLevel);
                } else {
                    errorFrom = cli::parseInt(a, v.substr(0, colon), 0, kMaxLevel);
                    errorTo = cli::parseInt(a, v.substr(colon + 1), errorFrom, kMaxLevel);
                }
            } else if (a == "-o" || a == "--output") {
                outPath = value();
            } else if (a == "--report") {
                reportPath = value();
            } else {
                throw cli::Error("unknown argument " + a + " (see --help)");
            }
        }
        if (highPath.empty() || controlPath.empty() || outPath.empty())
            throw cli::Error("--high, --control and -o are required (see --help)");
        if (std::filesystem::is_symlink(outPath))
            throw cli::Error(outPath + ": is a symbolic link; refusing to replace it (write to its target)");
        for (const std::string& input : {highPath, controlPath})
            if (input != "auto" && std::filesystem::exists(outPath) && std::filesystem::exists(input) &&
                std::filesystem::equivalent(outPath, input))
                throw cli::Error(outPath + ": the output would overwrite an input");
        const std::string ext = io::extensionOf(outPath);
        if (ext != ".glb" && ext != ".gltf")
            throw cli::Error(outPath + ": the rig must be a .glb or .gltf file");
        const std::string base = outPath.substr(0, outPath.size() - ext.size());
        const std::string stem = io::stemOf(outPath);

        nlohmann::json report;
        auto t0 = std::chrono::steady_clock::now();
        baker::TriangleMesh high;
        baker::HighMeshStats highStats;
        Status st = baker::loadHighMesh(highPath, &high, &highStats);
        if (!st)
            throw cli::Error(st.message());
        ControlMesh control;
        Rig controlRig;     // a glTF control keeps its whole document for the output
        Skeleton skeleton;  // carried through from a skinned glTF control rig
        if (controlPath == "auto") {
            if (controlFaces == 0)
                controlFaces = std::max<size_t>(200, high.faceCount() / 50);
            Progress p("simplifying the high-resolution mesh");
            if (!(st = baker::decimateToControlMesh(high, controlFaces, &control)))
                throw cli::Error(highPath + ": " + st.message());
            if (uvMode == "keep")
                throw cli::Error("--uv keep needs a control mesh with UVs; an automatic control mesh has none");
            uvMode = "auto";
        } else {
            if (!(st = baker::loadControlRig(controlPath, &controlRig)))
                throw cli::Error(st.message());
            for (const std::string& w : controlRig.warnings)
                std::fprintf(stderr, "strata-bake: warning: %s: %s\n", controlPath.c_str(), w.c_str());
            control = controlRig.mesh;
            skeleton = controlRig.skeleton;
            if (uvMode.empty()) {
                // Default: keep the control's UVs when they can carry a map
                // (no overlaps), else lay out an atlas in a new UV set.
                uvMode = control.hasUVs() ? "keep" : "auto";
                if (uvMode == "keep") {
                    ControlMesh probe = control;
                    std::string note;
                    baker::fitUVsToUnitSquare(&probe, &note);
                    if (!(st = baker::checkUVs(probe, 1024))) {
                        std::fprintf(stderr,
                                     "strata-bake: warning: %s: its UVs cannot carry the map (%s); generating an atlas "
                                     "in a new UV set (--uv keep insists)\n",
                                     controlPath.c_str(), st.message().c_str());
                        uvMode = "auto";
                    }
                }
            }
            if (uvMode == "keep" && !control.hasUVs())
                throw cli::Error(controlPath + ": the control mesh has no UVs (use --uv auto to generate them)");
        }
        if (!skeletonPath.empty()) {
            // The paper's joint file: its point-to-line binding becomes
            // standard skin weights, so the rig plays in any glTF viewer.
            if (!skeleton.empty())
                std::fprintf(stderr, "strata-bake: warning: %s: its skin is replaced by %s\n", controlPath.c_str(),
                             skeletonPath.c_str());
            if (!(st = io::loadJointFile(skeletonPath, &skeleton)))
                throw cli::Error(st.message());
            if (!(st = bindSkeletonWeights(&skeleton, control)))
                throw cli::Error(skeletonPath + ": " + st.message());
            controlRig.source.reset();  // the document's own skin is replaced: write the control mesh anew
        }
        const double loadMs = msSince(t0);

        // UVs, map size and recommended level.  Unless --size forces a size,
        // the map starts at the paper's texel ~ high-res edge rule and doubles
        // until the closed loop reaches --tolerance at a level around the
        // paper's, or stops improving: the smallest pair that reaches it.
        std::string sizeReason;
        const double typicalEdge = baker::medianEdgeLength(high);
        std::string atlasNote;
        baker::AtlasOptions atlas;
        atlas.gutter = 1;
        baker::ChartAtlasStats chartStats;
        const ControlMesh bare = control;
        auto layout = [&](int mapSize) {
            atlas.mapSize = mapSize;
            control = bare;
            Status s = baker::buildChartAtlas(&control, atlas, &chartStats);
            if (!s) {
                control = bare;
                baker::AtlasOptions triangles = atlas;
                triangles.gutter = 2;
                s = baker::buildTriangleAtlas(&control, triangles);
                chartStats = baker::ChartAtlasStats();
            }
            return s;
        };
        // Memory before work: the baker holds about 32 bytes per texel (map,
        // layers, owners, dilation) and 200 per high-res triangle (mesh,
        // mapping, index); the closed loop is chunked.
        auto checkMemory = [&](int mapSize) {
            const double needMB = (32.0 * double(mapSize) * double(mapSize) + 200.0 * double(high.faceCount())) /
                                  (1024.0 * 1024.0);
            if (needMB > maxMemoryMB)
                throw cli::Error(outPath + ": a " + std::to_string(mapSize) + "^2 map over " +
                                 std::to_string(high.faceCount()) + " triangles needs about " +
                                 std::to_string(long(needMB)) + " MB, over the " + std::to_string(long(maxMemoryMB)) +
                                 " MB budget (raise it with --max-memory MB)");
        };
        const bool forced = options.size > 0;
        int size = options.size;
        if (uvMode == "auto") {
            // A chart atlas (charts grown over the control mesh, projected on
            // their planes, packed); the per-triangle atlas only if a chart
            // would fold.
            if (!forced) {
                if (!(st = layout(512)))  // provisional layout to measure the UV area (scale-free)
                    throw cli::Error(st.message());
                size = baker::chooseMapSize(control, typicalEdge, options.maxSize, &sizeReason);
            }
        } else {
            std::string uvNote;
            if (baker::fitUVsToUnitSquare(&control, &uvNote))
                std::fprintf(stderr, "strata-bake: warning: %s: %s\n", controlPath.c_str(), uvNote.c_str());
            if (!forced)
                size = baker::chooseMapSize(control, typicalEdge, options.maxSize, &sizeReason);
            if (!(st = baker::checkUVs(control, std::max(size, 1024))))
                throw cli::Error(controlPath + ": " + st.message());
        }
        if (forced)
            sizeReason = "forced by --size";
        int paperLevel = 0;
        while (paperLevel < kMaxLevel && (control.faceCount() << (2 * paperLevel)) <= high.faceCount())
            ++paperLevel;
        int recommended = paperLevel;
        struct Trial {
            int size, level;
            double rms;  // the larger of both directions, over the diagonal
        };
        std::vector<Trial> trials;
        DisplacementMap map;
        std::vector<uint16_t> layers;
        baker::BakeReport rep;
        const int sizeCap = forced ? size : std::min(options.maxSize, 4096);
        // The previous size's result, kept so that stopping when doubling no
        // longer pays returns the smaller map.
        struct Snapshot {
            ControlMesh control;
            DisplacementMap map;
            std::vector<uint16_t> layers;
            baker::BakeReport rep;
            baker::ChartAtlasStats chartStats;
            int size = 0, level = 0;
            double best = 1e300;
        } previous;
        std::string schemeReason = schemeGiven ? "--scheme" : "";
        if (!schemeGiven && !forced && tolerance > 0.0) {
            // Which surface carries the map better for this pair, measured at
            // the first size and the paper's level: the paper's linear split
            // unless the Loop limit is clearly closer (loose cages).
            if (uvMode == "auto" && !(st = layout(size)))
                throw cli::Error(st.message());
            // The linear scheme first: when it already meets the tolerance
            // the smooth one is not tried (its bake costs several times more).
            double rms[2] = {0.0, -1.0};
            for (Scheme candidate : {Scheme::Linear, Scheme::Smooth}) {
                if (candidate == Scheme::Smooth && rms[0] <= tolerance)
                    break;
                baker::BakeOptions probe = options;
                probe.size = uvMode == "auto" ? atlas.mapSize : size;
                probe.scheme = candidate;
                DisplacementMap probeMap;
                baker::BakeReport probeReport;
                std::vector<baker::LevelError> errs;
                Progress p("choosing the subdivision scheme");
                if (!(st = baker::bake(&probeMap, nullptr, &probeReport, control, high, probe)) ||
                    !(st = baker::closedLoopError(&errs, control, probeMap, candidate, high, paperLevel, paperLevel,
                                                  options.threads)))
                    throw cli::Error(highPath + ": " + st.message());
                rms[int(candidate)] = std::max(errs[0].forwardRms, errs[0].backwardRms) / probeReport.diagonal;
            }
            options.scheme = rms[1] >= 0.0 && rms[1] * 1.25 < rms[0] ? Scheme::Smooth : Scheme::Linear;
            char buf[160];
            if (rms[1] < 0.0)
                std::snprintf(buf, sizeof(buf), "measured: linear %.4g%% RMS at level %d meets the tolerance",
                              100.0 * rms[0], paperLevel);
            else
                std::snprintf(buf, sizeof(buf), "measured: linear %.4g%%, smooth %.4g%% RMS at level %d", 100.0 * rms[0],
                              100.0 * rms[1], paperLevel);
            schemeReason = buf;
        }
        for (;;) {
            if (uvMode == "auto") {
                for (; size <= 8192; size *= 2) {
                    if ((st = layout(size)))
                        break;
                    if (forced)
                        throw cli::Error(st.message());
                    sizeReason += "; raised to fit the charts";
                }
                if (!st)
                    throw cli::Error(st.message());
            }
            options.size = size;
            checkMemory(size);
            {
                Progress p("baking");
                if (!(st = baker::bake(&map, &layers, &rep, control, high, options)))
                    throw cli::Error(highPath + ": " + st.message());
            }
            if (forced || tolerance <= 0.0)
                break;
            // The paper's level and the three below it (a loose tolerance is
            // met with fewer refined vertices, hence fewer stored values); a
            // finer level than the paper's rule rarely pays for its four
            // times the triangles.
            std::vector<baker::LevelError> errs;
            const int lo = std::max(0, paperLevel - 3), hi = paperLevel;
            {
                Progress p("measuring the map size against --tolerance");
                if (!(st = baker::closedLoopError(&errs, control, map, options.scheme, high, lo, hi, options.threads)))
                    throw cli::Error(st.message());
            }
            double best = 1e300;
            int met = -1, bestLevel = hi;
            for (const baker::LevelError& e : errs) {
                const double rms = std::max(e.forwardRms, e.backwardRms) / rep.diagonal;
                trials.push_back({size, e.level, rms});
                if (rms < best) {
                    best = rms;
                    bestLevel = e.level;
                }
                if (met < 0 && rms <= tolerance)
                    met = e.level;
            }
            if (met >= 0) {
                recommended = met;
                char buf[96];
                std::snprintf(buf, sizeof(buf), "; reaches --tolerance %.4g%% at level %d", 100.0 * tolerance, met);
                sizeReason += buf;
                break;
            }
            if (best > 0.9 * previous.best) {
                // Doubling no longer pays: resolution is not what limits the
                // error here.  The previous, smaller map, at its best level.
                control = std::move(previous.control);
                map = std::move(previous.map);
                layers = std::move(previous.layers);
                rep = previous.rep;
                chartStats = previous.chartStats;
                size = previous.size;
                recommended = previous.level;
                sizeReason += "; doubling the map no longer improved the error";
                break;
            }
            if (size * 2 > sizeCap) {
                recommended = bestLevel;
                sizeReason += "; at the size cap without reaching --tolerance";
                break;
            }
            previous.control = control;
            previous.map = std::move(map);
            previous.layers = std::move(layers);
            previous.rep = rep;
            previous.chartStats = chartStats;
            previous.size = size;
            previous.level = bestLevel;
            previous.best = best;
            size *= 2;
        }
        rep.sizeReason = sizeReason;
        if (uvMode == "auto") {
            char buf[160];
            if (chartStats.charts)
                std::snprintf(buf, sizeof(buf), "chart atlas: %zu charts, %.0f%% of texels inside charts, stretch <= %.2f",
                              chartStats.charts, 100.0 * chartStats.texelFill, chartStats.maxStretch);
            else
                std::snprintf(buf, sizeof(buf), "per-triangle atlas (a chart would fold)");
            atlasNote = buf;
        }

        // Outputs.
        t0 = std::chrono::steady_clock::now();
        std::error_code mkdirError;
        if (!io::directoryOf(outPath).empty())
            std::filesystem::create_directories(io::directoryOf(outPath), mkdirError);
        if (mkdirError)
            throw cli::Error(io::directoryOf(outPath) + ": cannot create the output folder (" + mkdirError.message() + ")");
        Outputs outputs;
        Rig rig = std::move(controlRig);
        rig.mesh = control;
        rig.skeleton = std::move(skeleton);
        rig.hasDisplacement = true;
        rig.displacement = DisplacementInfo();
        rig.displacement.scheme = options.scheme;
        rig.displacement.recommendedLevel = recommended;
        if (writeExr)
            outputs.write(base + ".exr", [&](const std::string& p) {
                return io::writeDisplacementExr(p, map, asFloat ? io::ExrPixelType::Float : io::ExrPixelType::Half);
            });
        if (pngBits) {
            std::vector<uint16_t> q(map.texels.size());  // paper eq. 12 at 2^n levels
            for (size_t i = 0; i < q.size(); ++i)
                q[i] = uint16_t(shared::strata_quantize(map.texels[i], rep.dmin, rep.dmax, float(1 << pngBits)));
            const std::string png = base + (pngBits == 8 ? ".png8.png" : ".png16.png");
            outputs.write(png, [&](const std::string& p) { return io::writePngGray(p, map.width, map.height, pngBits, q); });
            rig.displacement.quantized.uri = io::stemOf(png) + ".png";
            rig.displacement.quantized.bits = pngBits;
            rig.displacement.quantized.dmin = rep.dmin;
            rig.displacement.quantized.dmax = rep.dmax;
        }
        if (writeLayers)
            outputs.write(base + "_layers.png", [&](const std::string& p) {
                return io::writePngRgb(p, map.width, map.height, layerImage(layers));
            });
        std::vector<std::string> notes;
        // The map keeps the bits the error needs: a step q adds q / sqrt(12)
        // RMS, in quadrature with the rest, so q = E (the tolerance, or the
        // error the chosen size and level reach when that is larger) grows
        // the total by 4%.
        double achieved = tolerance;
        for (const Trial& t : trials)
            if (t.size == map.width && t.level == recommended)
                achieved = std::max(achieved, t.rms);
        io::RigWriteOptions writeOptions;
        writeOptions.maxQuantizationStep = tolerance > 0.0 ? achieved * rep.diagonal : 0.0;
        writeOptions.compress = compress;
        writeOptions.vertexDisplacements = mapCoding == "vertex";
        outputs.write(outPath, [&](const std::string& p) { return io::saveRig(p, rig, &map, &notes, &writeOptions); });
        for (const std::string& n : notes)
            std::fprintf(stderr, "strata-bake: warning: %s: %s\n", outPath.c_str(), n.c_str());
        const double writeMs = msSince(t0);

        // Closed loop: reconstruct from the rig just written, as the runtime
        // will, at the levels around the recommended one unless asked.
        if (errorFrom == -2) {
            errorFrom = std::max(0, recommended - 1);
            errorTo = std::min(kMaxLevel, recommended + 1);
        }
        std::vector<baker::LevelError> errors;
        double errorMs = 0.0;
        if (errorTo >= 0) {
            Rig written;
            DisplacementMap writtenMap;
            const std::string staged = Outputs::staged(outPath);
            DisplacementField field;
            if (!(st = io::loadRig(staged, &written)) || !(st = io::loadRigDisplacementMap(staged, written, &writtenMap)) ||
                (written.displacement.vertexLevel >= 0 &&
                 !(st = DisplacementField::create(&field, written.mesh, written.displacement.vertexLevel,
                                                  written.displacement.vertexValues))))
                throw cli::Error(outPath + ": the rig just written does not load back: " + st.message());
            t0 = std::chrono::steady_clock::now();
            Progress p("measuring the closed-loop error");
            if (!(st = baker::closedLoopError(&errors, written.mesh, writtenMap, options.scheme, high, errorFrom, errorTo,
                                              options.threads, size_t(1) << 20,
                                              written.displacement.vertexLevel >= 0 ? &field : nullptr)))
                throw cli::Error(st.message());
            errorMs = msSince(t0);
        }

        FILE* summary = reportPath == "-" ? stderr : stdout;  // stdout is the JSON then
        auto fileSize = [](const std::string& p) {
            std::vector<unsigned char> b;
            return io::readFile(Outputs::staged(p), &b).isOk() ? double(b.size()) : 0.0;
        };
        const double diag = rep.diagonal;
        std::fprintf(summary, "strata-bake: %s onto %s (%s scheme%s%s)\n", highPath.c_str(), controlPath.c_str(),
                     schemeName(options.scheme), schemeReason.empty() ? "" : ": ", schemeReason.c_str());
        std::fprintf(summary, "  high-res      %zu vertices, %zu triangles (median edge %.4g)\n", rep.highVertices,
                    rep.highTriangles, rep.typicalEdge);
        if (highStats.polygonsTriangulated || highStats.duplicateVertices || highStats.degenerateTriangles ||
            highStats.nonManifoldEdges)
            std::fprintf(summary, "  tolerated     %zu polygons triangulated, %zu duplicate vertices, %zu degenerate "
                        "triangles, %zu non-manifold edges\n",
                        highStats.polygonsTriangulated, highStats.duplicateVertices, highStats.degenerateTriangles,
                        highStats.nonManifoldEdges);
        std::fprintf(summary, "  control       %zu vertices, %zu triangles, UVs %s\n", control.positions.size(),
                    control.faceCount(), uvMode == "auto" ? ("generated, " + atlasNote).c_str() : "kept");
        std::fprintf(summary, "  map           %dx%d: %s\n", map.width, map.height, rep.sizeReason.c_str());
        if (!trials.empty()) {
            std::fprintf(summary, "  trade-off     (map, level: RMS / diagonal, the larger direction; tolerance %.4g%%)\n",
                         100.0 * tolerance);
            for (const Trial& t : trials)
                std::fprintf(summary, "                %5d, %d: %.4f%%%s\n", t.size, t.level, 100.0 * t.rms,
                             t.size == map.width && t.level == recommended ? "  <- chosen" : "");
        }
        std::fprintf(summary, "  mapping       %zu in a normal volume, %zu fell back to the nearest point (search |d| <= %.3g)\n",
                    rep.highVertices - rep.fallbackVertices, rep.fallbackVertices, rep.searchDistance);
        std::fprintf(summary, "  raster        %zu border triangles, %zu pieces, coverage %.2f%%, overlap %.3f%% of texels\n",
                    rep.raster.borderTriangles, rep.raster.pieces, 100.0 * rep.coverage, 100.0 * rep.overlapFraction);
        std::fprintf(summary, "  holes/gutters %zu texels measured by line intersection, the rest dilated\n",
                    rep.lineFilledTexels);
        std::fprintf(summary, "  distances     dmin %.4g, dmax %.4g (%.3g%% .. %.3g%% of the diagonal %.4g)\n", rep.dmin, rep.dmax,
                    100.0 * rep.dmin / diag, 100.0 * rep.dmax / diag, diag);
        std::fprintf(summary, "  time          load %.0f ms, mapping %.0f ms, raster %.0f ms, dilation %.0f ms, write %.0f ms, "
                    "closed loop %.0f ms\n",
                    loadMs, rep.times.mapping, rep.times.rasterize, rep.times.dilate, writeMs, errorMs);
        std::fprintf(summary, "  outputs      ");
        for (const std::string& p : outputs.written)
            std::fprintf(summary, " %s (%.0f KB)", p.c_str(), fileSize(p) / 1024.0);
        std::fprintf(summary, "\n");
        const double bound = std::sqrt(3.0) / 2.0 * rep.typicalEdge;
        if (!errors.empty()) {
            std::fprintf(summary, "  closed loop (distance / diagonal; paper bound sqrt(3)/2 edge = %.3g%%)\n", 100.0 * bound / diag);
            std::fprintf(summary, "    level | triangles | recon->high RMS   max   | high->recon RMS   max\n");
            for (const baker::LevelError& e : errors)
                std::fprintf(summary, "    %5d | %9zu | %9.4f%% %8.4f%% | %9.4f%% %8.4f%%\n", e.level, e.triangles,
                            100.0 * e.forwardRms / diag, 100.0 * e.forwardMax / diag, 100.0 * e.backwardRms / diag,
                            100.0 * e.backwardMax / diag);
        }

        if (!reportPath.empty()) {
            report["high"] = {{"path", highPath},
                              {"vertices", rep.highVertices},
                              {"triangles", rep.highTriangles},
                              {"medianEdge", rep.typicalEdge},
                              {"diagonal", diag},
                              {"polygonsTriangulated", highStats.polygonsTriangulated},
                              {"duplicateVertices", highStats.duplicateVertices},
                              {"degenerateTriangles", highStats.degenerateTriangles},
                              {"nonManifoldEdges", highStats.nonManifoldEdges}};
            report["control"] = {{"path", controlPath},
                                 {"vertices", control.positions.size()},
                                 {"triangles", control.faceCount()},
                                 {"uv", uvMode}};
            report["map"] = {{"size", map.width}, {"reason", rep.sizeReason}, {"dmin", rep.dmin}, {"dmax", rep.dmax},
                             {"coverage", rep.coverage}, {"overlapFraction", rep.overlapFraction},
                             {"multiLayerTexels", rep.raster.multiLayerTexels},
                             {"coveredTexels", rep.raster.coveredTexels},
                             {"lineFilledTexels", rep.lineFilledTexels}};
            report["mapping"] = {{"fallbacks", rep.fallbackVertices}, {"searchDistance", rep.searchDistance},
                                 {"borderTriangles", rep.raster.borderTriangles}, {"pieces", rep.raster.pieces}};
            nlohmann::json tradeOff = nlohmann::json::array();
            for (const Trial& t : trials)
                tradeOff.push_back({{"size", t.size}, {"level", t.level}, {"rms", t.rms}});
            report["tolerance"] = tolerance;
            report["tradeOff"] = tradeOff;
            report["scheme"] = schemeName(options.scheme);
            report["recommendedLevel"] = recommended;
            report["timeMs"] = {{"load", loadMs}, {"mapping", rep.times.mapping}, {"rasterize", rep.times.rasterize},
                                {"dilate", rep.times.dilate}, {"write", writeMs}, {"closedLoop", errorMs}};
            nlohmann::json files = nlohmann::json::object();
            for (const std::string& p : outputs.written)
                files[p] = fileSize(p);
            report["outputBytes"] = files;
            report["paperBound"] = {{"maxError", bound}, {"relative", bound / diag}};
            nlohmann::json levels = nlohmann::json::array();
            for (const baker::LevelError& e : errors)
                levels.push_back({{"level", e.level}, {"vertices", e.vertices}, {"triangles", e.triangles},
                                  {"forwardRms", e.forwardRms / diag}, {"forwardMax", e.forwardMax / diag},
                                  {"backwardRms", e.backwardRms / diag}, {"backwardMax", e.backwardMax / diag}});
            report["closedLoop"] = levels;
            const std::string text = report.dump(2) + "\n";
            if (reportPath == "-")
                std::fwrite(text.data(), 1, text.size(), stdout);
            else
                outputs.write(reportPath, [&](const std::string& p) { return io::writeFileAtomic(p, text.data(), text.size()); });
        }
        outputs.commit();
        return 0;
    });
}
