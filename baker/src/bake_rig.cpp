// The whole bake as one call (paper 2.1-2.3, 3.2): load, control mesh,
// atlas, map size and level from the tolerance, bake, rig, closed loop.
// strata-bake and the Python module parse their arguments into a
// BakeRequest and call bakeRig; nothing here prints.
#include "strata/baker/bake_rig.h"
#include "strata/baker/picture.h"
#include "strata/baker/skin_transfer.h"
#include "strata/surface.h"
#include "strata/baker/texture_transfer.h"
#include "strata/io/materials.h"

#include "cancel.h"
#include "elapsed.h"
#include "material_carry.h"

#include "strata/baker/atlas.h"
#include "strata/baker/bake.h"
#include "strata/baker/fit.h"
#include "strata/baker/mesh_input.h"
#include "strata/displacement_math.h"
#include "strata/segment_deformer.h"
#include "strata/vertex_displacements.h"
#include "strata/io/exr.h"
#include "strata/io/file.h"
#include "strata/io/joint_file.h"
#include "strata/io/png.h"
#include "strata/io/rig_io.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <mutex>
#include <new>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include <signal.h>
#include <unistd.h>

namespace strata {
namespace baker {

namespace {

// Any user-facing failure inside the bake; bakeRig turns it into a Status.
struct BakeError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

void appendf(std::string* out, const char* format, ...)
{
    char buffer[1024];
    va_list args;
    va_start(args, format);
    const int n = std::vsnprintf(buffer, sizeof(buffer), format, args);
    va_end(args);
    if (n > 0)
        out->append(buffer, size_t(std::min(n, int(sizeof(buffer)) - 1)));
}

Status cancelledStatus(const BakeRequest& request)
{
    return Status(StatusCode::Cancelled, request.output + ": the bake was cancelled; nothing was written");
}

// Reports a stage (seconds < 0) only if it runs longer than a second, then
// its duration when it ends.
class Progress {
public:
    Progress(const BakeProgress* report, const char* stage)
        : report_(report), stage_(stage), t0_(std::chrono::steady_clock::now())
    {
        if (cancelRequested())
            throw BakeCancelled();
        if (!report_ || !*report_)
            return;
        watcher_ = std::thread([this] {
            std::unique_lock<std::mutex> lock(m_);
            if (!cv_.wait_for(lock, std::chrono::seconds(1), [this] { return done_; })) {
                (*report_)(stage_, -1.0);
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
        if (watcher_.joinable())
            watcher_.join();
        if (announced_)
            (*report_)(stage_, msSince(t0_) / 1000.0);
    }

private:
    const BakeProgress* report_;
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
        return (dir.empty() ? std::string() : dir + "/") + ".strata-staging-" + std::to_string(::getpid()) + "-" + name;
    }
    // Removes the staging files of bakes into `dir` that no longer run (a
    // bake killed with SIGKILL leaves its own): the ones whose process id is
    // gone, and those of the old naming, which has none.  A bake that still
    // runs keeps its files.
    static void removeStale(const std::string& dir)
    {
        std::error_code ec;
        const std::string prefix = ".strata-staging-";
        for (std::filesystem::directory_iterator it(dir.empty() ? "." : dir, ec), end; !ec && it != end;
             it.increment(ec)) {
            const std::string name = it->path().filename().string();
            if (name.compare(0, prefix.size(), prefix) != 0 || !it->is_regular_file(ec))
                continue;
            char* rest = nullptr;
            const long pid = std::strtol(name.c_str() + prefix.size(), &rest, 10);
            const bool running = rest && *rest == '-' && pid > 0 && pid < 0x7fffffffL &&
                                 (::kill(pid_t(pid), 0) == 0 || errno == EPERM);
            if (!running)
                std::filesystem::remove(it->path(), ec);
        }
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
            throw BakeError(msg);
        }
        written.push_back(path);
    }
    void commit()
    {
        // All or nothing: every target is checked before any is replaced.
        if (cancelRequested())
            throw BakeCancelled();
        for (const std::string& p : written) {
            std::error_code ec;
            if (std::filesystem::is_directory(p, ec))
                throw BakeError(p + ": is a folder; no output was replaced");
        }
        for (const std::string& p : written)
            if (std::rename(staged(p).c_str(), p.c_str()) != 0)
                throw BakeError(p + ": cannot replace the file (" + std::strerror(errno) + ")");
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

// What the tries of --control auto's face-count search share, so that each
// later try redoes none of it: the capture as loaded, the scheme measured
// on a cage of about its face count, and the map size of the tries that met the tolerance (a
// coarser cage needs no finer map: its error is the cage's, and doubling
// the map up to the size cap only to find that out cost a failing try of
// the 100k scan 28 s).
struct SearchShared {
    TriangleMesh high;  // loaded by bakeRig before the first try
    HighMeshStats highStats;
    bool schemeKnown = false;
    Scheme scheme = Scheme::Linear;
    std::string schemeReason;
    size_t schemeFaces = 0;  // the cage it was measured on
    bool schemeDecisive = false;  // the limit surface came out over 4x farther than the linear one
    // A try reuses the measured scheme on a cage within a factor 1.5 of
    // that one's face count; further off it measures again (on CesiumMan
    // the smooth scheme won on 200 faces and the linear one on 800).  A
    // decisive loss holds within a factor 3 (on the 100k scan the limit
    // surface lost 13x on 1,998 faces and 39x on 748; its probe on 748
    // faces, at level 4, was most of a 10 s try).
    bool schemeFits(size_t faces) const
    {
        const size_t k = schemeDecisive ? 6 : 3;  // twice the factor
        return schemeKnown && k * faces >= 2 * schemeFaces && 2 * faces <= k * schemeFaces;
    }
    int sizeCap = 0;  // 0: none yet
    int mapSize = 0;  // the last try's
    std::unique_ptr<Simplifier> simplifier;  // of `high`: a smaller count continues the last one's collapses
};

// The part of the whole bake's progress that one bake covers: [base,
// base + span) of the fraction reported (a try of the face-count search is
// a part; a plain bake the whole).
struct FractionSpan {
    const BakeFraction* report = nullptr;
    double base = 0.0, span = 1.0;
    double last = 0.0;  // what was reported, so the fraction never goes back
    void at(double fraction)
    {
        const double f = std::clamp(base + span * fraction, last, 1.0);
        if (report && *report && f > last) {
            last = f;
            (*report)(f);
        }
    }
};

// The output path's checks, made before any work: not a symbolic link, not
// one of the inputs, a .glb or .gltf.
Status checkOutput(const BakeRequest& request)
{
    const std::string& out = request.output;
    std::error_code ec;
    if (std::filesystem::is_symlink(out, ec))
        return Status(StatusCode::InvalidArgument,
                      out + ": is a symbolic link; refusing to replace it (write to its target)");
    const std::string ext = io::extensionOf(out);
    if (ext != ".glb" && ext != ".gltf")
        return Status(StatusCode::InvalidArgument, out + ": the rig must be a .glb or .gltf file");
    // Every output against every input and every other output, by file
    // identity (device and inode, `..` and links resolved), before any
    // folder is made or any byte written.
    const std::string base = out.substr(0, out.size() - ext.size());
    std::vector<std::string> outputs = {out};
    if (!request.report.empty() && request.report != "-")
        outputs.push_back(request.report);
    if (request.exr)
        outputs.push_back(base + ".exr");
    if (request.layers)
        outputs.push_back(base + "_layers.png");
    if (request.pngBits)
        outputs.push_back(base + (request.pngBits == 8 ? ".png8.png" : ".png16.png"));
    for (size_t i = 0; i < outputs.size(); ++i) {
        for (const std::string& input : {request.high, request.control, request.skeleton})
            if (input != "auto" && io::sameFile(outputs[i], input))
                return Status(StatusCode::InvalidArgument,
                              outputs[i] + ": the output would overwrite the input " + input);
        for (size_t j = 0; j < i; ++j)
            if (io::sameFile(outputs[i], outputs[j]))
                return Status(StatusCode::InvalidArgument, outputs[i] + ": two outputs would be the same file");
        if (i > 0 && std::filesystem::is_symlink(outputs[i], ec))
            return Status(StatusCode::InvalidArgument,
                          outputs[i] + ": is a symbolic link; refusing to replace it (write to its target)");
        if (std::filesystem::is_directory(outputs[i], ec))
            return Status(StatusCode::InvalidArgument, outputs[i] + ": is a folder, not a file to write");
        // A folder on the way that is a file: refused now, not after the bake.
        for (std::filesystem::path up = std::filesystem::path(outputs[i]).parent_path(); !up.empty();
             up = up.parent_path()) {
            if (std::filesystem::exists(up, ec) && !std::filesystem::is_directory(up, ec))
                return Status(StatusCode::InvalidArgument, io::directoryOf(outputs[i]) +
                                                               ": cannot create the output folder (" + up.string() +
                                                               " is a file)");
            if (up == up.parent_path())
                break;
        }
    }
    return Status::ok();
}

}  // namespace

namespace {

// The size of a staged output, or 0.
double fileSize(const std::string& path)
{
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(Outputs::staged(path), ec);
    return ec ? 0.0 : double(bytes);
}

// Below this picture PSNR (dB) against its source, a character's rig is
// said not to look like it, in the summary's first line.
constexpr double kLooksAlikeDb = 12.0;

// Where the summary's time line goes until every phase has run.
constexpr const char* kTimePlaceholder = "  time          (measured when the bake ends)";

// An automatic cage's face count where nothing else sets it, and the
// face-count search's first try: a fiftieth of the capture's faces, at
// least 200, never past the capture (a cage has at least 4 faces).
size_t firstCageFaces(size_t captureFaces)
{
    return std::min(std::max<size_t>(200, captureFaces / 50), std::max<size_t>(captureFaces, 4));
}

// One bake: its state, shared by the phases that make() and deliver() call
// in turn.  make() bakes the rig in memory (load, prepare the cage and
// atlas, choose the scheme, search the map size, encode the rig and settle
// its level, measure the encoded rig, pose a character against its
// source); nothing is written.  deliver() then writes the files (staged),
// summarises, reports and commits.  The face-count search bakes its tries
// and delivers only the one it chooses.  Every user-facing failure is a
// BakeError.
class BakeJob {
public:
    BakeJob(const BakeRequest& r, const BakeProgress* stages, SearchShared* searchShared, FractionSpan* fractionSpan)
        : request(r), progress(stages), shared(searchShared), fraction(fractionSpan), uvMode(r.uv),
          controlFaces(r.controlFaces), options(r.options), errorFrom(r.errorFrom), errorTo(r.errorTo)
    {
    }
    BakeJob(const BakeJob&) = delete;  // `result` points into the job itself
    BakeJob& operator=(const BakeJob&) = delete;

    // Each phase and its share of a default bake's time (the 100k scan
    // onto an automatic cage: the scheme's probes and fits are the largest
    // part, the summary and report nothing).
    void make()
    {
        static const std::pair<void (BakeJob::*)(), double> phases[] = {
            {&BakeJob::loadInputs, 0.12},   {&BakeJob::prepare, 0.05},    {&BakeJob::chooseScheme, 0.38},
            {&BakeJob::searchMapSize, 0.15}, {&BakeJob::encodeRig, 0.14},  {&BakeJob::measureWritten, 0.08},
            {&BakeJob::measureFrames, 0.04}};
        const auto start = std::chrono::steady_clock::now();
        runPhases(phases, std::size(phases));
        bakeMs_ = msSince(start);
    }

    // Writes, summarises, reports and commits; `searchNote` (the
    // face-count search's lines) goes into the summary after its first
    // lines, and `searchReport` into the report.  `triesMs` is the wall
    // time the search spent outside this bake (loading the capture, the
    // other tries): the time line then adds up to the whole command.
    void deliver(BakeResult* out, const std::string& searchNote = std::string(),
                 const nlohmann::json& searchReport = nlohmann::json(), double triesMs = 0.0)
    {
        static const std::pair<void (BakeJob::*)(), double> phases[] = {{&BakeJob::writeOutputs, 0.01},
                                                                         {&BakeJob::summarize, 0.01},
                                                                         {&BakeJob::writeReport, 0.01},
                                                                         {&BakeJob::finish, 0.01}};
        searchNote_ = searchNote;
        searchReport_ = searchReport;
        const auto t0 = std::chrono::steady_clock::now();
        runPhases(phases, std::size(phases));
        // The summary's time line, now that every phase has run: its parts
        // add up to the bake's whole wall time.
        const double totalMs = triesMs + bakeMs_ + msSince(t0);
        const double partsMs =
            triesMs + loadMs + prepareMs + schemeMs + searchMs + encodeMs + errorMs + framesMs + writeMs;
        std::string line;
        appendf(&line, "  time          %.1f s in all: ", totalMs / 1000.0);
        if (triesMs > 0.0)
            appendf(&line, "the capture's load and the other cage tries %.0f ms, then the chosen cage's bake: ",
                    triesMs);
        appendf(&line,
                "load %.0f ms, atlas and capture index %.0f ms, scheme %.0f ms (cage "
                "fits %.0f ms of it), map size and level %.0f ms (its last bake: mapping %.0f ms, raster %.0f ms, "
                "dilation %.0f ms), encode %.0f ms, closed loop %.0f ms",
                loadMs, prepareMs, schemeMs, fitMs, searchMs, rep.times.mapping, rep.times.rasterize,
                rep.times.dilate, encodeMs, errorMs);
        if (framesMs > 0.0)
            appendf(&line, ", posed frames %.0f ms", framesMs);
        appendf(&line, ", write %.0f ms, summary, report and commit %.0f ms", writeMs,
                std::max(0.0, totalMs - partsMs));
        const size_t at = own_.summary.find(kTimePlaceholder);
        if (at != std::string::npos)
            own_.summary.replace(at, std::strlen(kTimePlaceholder), line);
        *out = std::move(own_);
    }

    // The encoded rig and its closed-loop RMS / diagonal at the level it
    // recommends (-1: not measured): what the face-count search compares.
    size_t rigBytes() const { return rigBytes_.size(); }
    double rms() const
    {
        for (const LevelError& e : errors)
            if (e.level == recommended)
                return e.rms() / rep.diagonal;
        return -1.0;
    }
    // make()'s wall time.
    double wallMs() const { return bakeMs_; }
    // Where the progress of the phases still to run goes (null: nowhere).
    void reportTo(FractionSpan* span) { fraction = span; }

    size_t cageFaces() const { return control.faceCount(); }
    // The level the rig recommends, and the paper's for this cage and capture.
    int recommendedLevel() const { return recommended; }
    int capturedLevel() const { return paperLevel; }

    // The stored values' closed-loop RMS / diagonal before they were
    // quantised (rms() where no values are stored per vertex).
    double rmsBeforeQuantisation() const { return stored.rms >= 0.0 ? stored.rms / rep.diagonal : rms(); }
    // A character's worst posed frame against its source, RMS / diagonal
    // (-1: not a character, or not measured).
    double posedRms() const
    {
        double worst = -1.0;
        for (const FrameError& f : frames)
            worst = std::max(worst, f.rms / rep.diagonal);
        return worst;
    }

    // Frees what only make() needs (the capture, its index, the fits, the
    // atlas charts, the map's texels), for a try the search keeps to
    // compare: its delivery then writes the rig alone (the search bakes
    // its tries without map images).
    void releaseInputs()
    {
        high = TriangleMesh();
        highIndex = TriangleIndex();
        loop_ = LoopCapture();
        for (Fitted& f : fitted)
            f.positions = std::vector<glm::vec3>();  // their stats stay for the summary
        chartCache = ChartCache();
        previous = Snapshot();
        written_ = Rig();
        writtenMap_ = DisplacementMap();
        writtenLoaded_ = false;
        bare = ControlMesh();
        map.texels = std::vector<float>();  // its size stays for the summary
        layers = std::vector<uint16_t>();
    }

private:
    struct Fitted {
        bool done = false;
        std::vector<glm::vec3> positions;
        FitStats stats;
    };
    struct Trial {
        int size, level;
        double rms;  // the larger of both directions, over the diagonal
    };
    // The previous size's result, kept so that stopping when doubling no
    // longer pays returns the smaller map.
    struct Snapshot {
        ControlMesh control;
        DisplacementMap map;
        std::vector<uint16_t> layers;
        BakeReport rep;
        ChartAtlasStats chartStats;
        int size = 0, level = 0;
        double best = 1e300;
    };
    // How the values stored per refined vertex were made.
    struct Stored {
        size_t measured = 0;
        const char* how = "sampled from the map";
        double rms = -1.0;  // the closed loop of the values before quantisation
        double step = 0.0;  // the quantisation step they were coded with
    };

    void loadInputs();
    void checkOneFrame() const;
    void prepare();
    void chooseScheme();
    void searchMapSize();
    void encodeRig();
    void writeOutputs();
    void loadWritten();
    void measureWritten();
    void measureFrames();
    void summarize();
    void writeReport();
    void finish();

    const std::vector<glm::vec3>& fittedPositions(Scheme scheme);
    void useFit(Scheme scheme, ControlMesh* mesh);
    Status layout(int mapSize);
    void checkMemory(int mapSize) const;
    const Trial* trialAt(int level) const;
    double quantizationStep(int level) const;
    Status refineStoredValues(const ControlMesh& mesh, int level, std::vector<float>* values, double* step);
    Status encodeAt(int level, std::string* bytes);
    void runPhases(const std::pair<void (BakeJob::*)(), double>* phases, size_t count);
    void loadCharacter();
    std::vector<glm::vec3> posedCapture() const;
    void carryCharacter();
    void carryColour();
    void settleLevel();

    // A failure's message, naming the rig where it does not yet.
    std::string namingOutput(const Status& st) const
    {
        return st.message().compare(0, request.output.size(), request.output) == 0
                   ? st.message()
                   : request.output + ": " + st.message();
    }
    std::string pngPath() const { return base + (request.pngBits == 8 ? ".png8.png" : ".png16.png"); }

    template <typename... Args>
    void warn(const char* format, Args... args)
    {
        std::string w;
        appendf(&w, format, args...);
        result->warnings.push_back(w);
    }

    // A capture of separate pieces (a robot's rigid parts, which pass
    // through each other at its joints): each cage face is labelled with the
    // piece its corners were taken from, and each piece's vertices map onto
    // its own faces (ShellLabels).  Mapped onto the nearest cage instead, a
    // piece where it passes through its neighbour rode on the neighbour's
    // cage when posed: on a 59-piece, 18-joint robot every cage of up to
    // 11,316 faces went 1.5-4x past the tolerance posed, and the rig was
    // the capture itself (1,746 KB).
    void labelShells(const std::vector<uint32_t>& originals)
    {
        size_t pieces = 0;
        std::vector<uint32_t> shells = captureShells(high, &pieces);
        if (pieces < 2 || originals.size() != control.positions.size())
            return;
        auto labels = std::make_shared<ShellLabels>();
        labels->controlFace.resize(control.faceCount());
        for (size_t f = 0; f < control.faceCount(); ++f) {
            const uint32_t v = originals[control.triangles[3 * f]];
            labels->controlFace[f] = v < shells.size() ? shells[v] : 0;
        }
        labels->highVertex = std::move(shells);
        options.shells = std::move(labels);
        pieces_ = pieces;
    }

    // A capture far from the origin against its size has lost, in 32-bit
    // floats (Strata's and glTF's), what no bake can give back: a scan left
    // in survey coordinates.  Said where the rounding alone is over a tenth
    // of the default tolerance.
    void warnIfFarFromTheOrigin()
    {
        if (high.positions.empty())
            return;
        glm::vec3 lo = high.positions[0], hi = lo;
        float farthest = 0.0f;
        for (const glm::vec3& p : high.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
            farthest = std::max({farthest, std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
        }
        const double diagonal = double(glm::length(hi - lo));
        const double step = double(std::nextafter(farthest, std::numeric_limits<float>::infinity()) - farthest);
        if (diagonal > 0.0 && step > 1e-5 * diagonal)
            warn("%s: its coordinates reach %.3g from the origin, %.3g times its size, where 32-bit floats (Strata's "
                 "and glTF's) are %.3g apart, %.2g%% of its diagonal: no bake comes closer to it than that; move it "
                 "to the origin first (a node's translation can carry it back)",
                 request.high.c_str(), double(farthest), double(farthest) / diagonal, step, 100.0 * step / diagonal);
    }

    const BakeRequest request;  // a copy: a search's tries outlive the request it made
    BakeResult own_;
    BakeResult* result = &own_;  // filled as the phases run; deliver() hands it over
    const BakeProgress* progress;
    SearchShared* shared;    // a face-count search's tries, or null
    FractionSpan* fraction;  // where this bake's progress goes, or null
    // What the bake resolves from the request: the UVs ("keep" or "auto"),
    // an automatic cage's face count, and the options as chosen (map size,
    // scheme).
    std::string uvMode;
    size_t controlFaces;
    BakeOptions options;
    int errorFrom, errorTo;  // the closed loop's levels (-2: around the recommended one, once chosen)
    std::string searchNote_;
    nlohmann::json searchReport_;
    double bakeMs_ = 0.0;  // make()'s wall time
    std::string base;  // the output path without its extension

    // The inputs.
    TriangleMesh high;
    HighMeshStats highStats;
    TriangleIndex highIndex;  // the capture indexed once: fits, measurements and closed loops query it
    LoopCapture loop_;        // highIndex and the closed loop's samples of the capture (loopCapture())
    const LoopCapture& loopCapture()
    {
        if (!loop_.index) {
            loop_.index = &highIndex;
            loop_.samples = loopSamples(high);
        }
        return loop_;
    }
    ControlMesh control;
    Rig controlRig;     // a glTF control keeps its whole document for the output
    Skeleton skeleton;  // carried through from a skinned glTF control rig
    // --control auto on a skinned glTF: the capture as a character (its
    // skeleton, animations, per-vertex weights), carried onto the cage.
    Rig highRig;
    bool character = false;
    io::SceneMaterials captureMaterials;  // a textured capture's materials and decoded images
    bool coloured = false;                // ... carried as one base colour texture in the cage's UVs
    std::vector<int> faceMaterial;        // ... per capture face, its material (glTF's default, the last, where none)
    size_t mainMaterial = 0;              // ... the one most of the capture's faces wear
    io::BaseColourTexture baseColour;
    std::string colourNote;
    ControlMesh bare;   // the control mesh that atlas layouts start from
    int paperLevel = 0;

    // Cage, atlas, scheme, map size and level.
    AtlasOptions atlas;
    ChartAtlasStats chartStats;
    ChartCache chartCache;  // the charts, made once per cage the layouts start from
    std::string atlasNote, sizeReason, schemeReason;
    size_t atlasVertices = 0;  // a generated atlas's vertices once split at its seams
    size_t pieces_ = 1;        // the capture's separate pieces, where the cage is labelled by them
    bool fitting = false, fitSkippedForMaps = false;
    Fitted fitted[2];
    FitOptions fitOptions;
    bool forced = false;
    int size = 0, sizeCap = 0, recommended = 0;
    std::vector<Trial> trials;
    DisplacementMap map;
    std::vector<uint16_t> layers;
    BakeReport rep;
    Snapshot previous;

    // The outputs.
    Outputs outputs;
    Rig rig;
    io::RigWriteOptions writeOptions;
    std::vector<std::string> notes;
    Stored stored;
    std::vector<LevelError> errors;
    // A character from --control auto: the rig against its source, posed.
    struct FrameError {
        int animation = 0;
        float time = 0.0f;
        double rms = 0.0, max = 0.0;  // the larger side of each, model units
        double psnr = 0.0;            // both drawn at one camera and pose (picture.h), dB
    };
    std::vector<FrameError> frames;
    SkinFitReport skinFit;  // the cage's skin weights fitted over the animations (poses 0: not fitted)
    double framesMs = 0.0;
    Rig written_;                  // the rig as written, read back (loadWritten)
    DisplacementMap writtenMap_;   // ... and its map, when map-coded
    bool writtenLoaded_ = false;
    nlohmann::json report;
    std::string rigBytes_;  // the rig file, encoded
    double loadMs = 0.0, prepareMs = 0.0, fitMs = 0.0, schemeMs = 0.0, searchMs = 0.0, encodeMs = 0.0, errorMs = 0.0,
           writeMs = 0.0;
    double done_ = 0.0;  // the fraction of the phases' weight run
};

void BakeJob::runPhases(const std::pair<void (BakeJob::*)(), double>* phases, size_t count)
{
    for (size_t i = 0; i < count; ++i) {
        (this->*phases[i].first)();
        done_ += phases[i].second;
        if (fraction)
            fraction->at(done_);
    }
}

void BakeJob::loadInputs()
{
    if (request.high.empty() || request.control.empty() || request.output.empty())
        throw BakeError("--high, --control and -o are required (see --help)");
    if (request.mapCoding != "vertex" && request.mapCoding != "png")
        throw BakeError("map coding must be vertex or png, not " + request.mapCoding);
    if (request.meshCoding != "plain" && request.meshCoding != "draco" && request.meshCoding != "meshopt")
        throw BakeError("mesh coding must be plain, meshopt or draco, not " + request.meshCoding);
    if (Status checked = checkOutput(request); !checked)
        throw BakeError(checked.message());
    const std::string ext = io::extensionOf(request.output);
    base = request.output.substr(0, request.output.size() - ext.size());

    const auto t0 = std::chrono::steady_clock::now();
    Status st;
    if (shared) {
        high = shared->high;
        highStats = shared->highStats;
    } else if (!(st = loadHighMesh(request.high, &high, &highStats, request.maxMemoryMB))) {
        throw BakeError(st.message());
    }
    warnIfFarFromTheOrigin();
    if (request.control == "auto") {
        if (controlFaces == 0)
            controlFaces = firstCageFaces(high.faceCount());
        loadCharacter();
        Progress p(progress, "simplifying the high-resolution mesh");
        // A character's capture is decimated in its poses too, so that the
        // cage keeps vertices where it bends.
        if (shared && !shared->simplifier)
            shared->simplifier = std::make_unique<Simplifier>(shared->high, posedCapture());
        std::vector<uint32_t> originals;
        if (!(st = shared ? shared->simplifier->simplify(controlFaces, &control, &originals)
                          : Simplifier(high, posedCapture()).simplify(controlFaces, &control, &originals)))
            throw BakeError(request.high + ": " + st.message());
        labelShells(originals);
        if (uvMode == "keep")
            throw BakeError("--uv keep needs a control mesh with UVs; an automatic control mesh has none");
        uvMode = "auto";
    } else {
        if (!(st = loadControlRig(request.control, &controlRig, request.maxMemoryMB)) ||
            !(st = io::checkEachMeshPlacedOnce(request.control, controlRig)))
            throw BakeError(st.message());
        for (const std::string& w : controlRig.warnings)
            warn("%s: %s", request.control.c_str(), w.c_str());
        if (!high.colours.empty())
            warn("%s: its vertex colours are not carried onto a given control mesh, which keeps its own materials "
                 "(--control auto re-bakes them into the rig's texture)",
                 request.high.c_str());
        control = controlRig.mesh;
        skeleton = controlRig.skeleton;
        checkOneFrame();
        if (uvMode.empty()) {
            // Default: keep the control's UVs when they can carry a map
            // (no overlaps), else lay out an atlas in a new UV set.
            uvMode = control.hasUVs() ? "keep" : "auto";
            if (uvMode == "keep") {
                ControlMesh probe = control;
                std::string note;
                fitUVsToUnitSquare(&probe, &note);
                if (!(st = checkUVs(probe, 1024))) {
                    warn("%s: its UVs cannot carry the map (%s); generating an atlas in a new UV set (--uv keep "
                         "insists)",
                         request.control.c_str(), st.message().c_str());
                    uvMode = "auto";
                }
            }
        }
        if (uvMode == "keep" && !control.hasUVs())
            throw BakeError(request.control + ": the control mesh has no UVs (use --uv auto to generate them)");
        // A closed capture over a control mesh left open (a wrist, a
        // neck): the capture's cap has nothing to be displaced from, so
        // the holes are closed with fans (a plain, unskinned mesh whose
        // UVs are laid out anew only; --keep-holes keeps them open).
        if (request.closeHoles && uvMode == "auto" && skeleton.empty() && request.skeleton.empty() &&
            !controlRig.source && countBoundaryEdges(control.triangles.data(), control.faceCount()) > 0 &&
            countBoundaryEdges(high.triangles.data(), high.faceCount()) == 0) {
            const size_t before = control.faceCount();
            if (const size_t loops = closeBoundaryLoops(&control))
                warn("%s: the capture is closed where the control mesh is open: %zu boundary loop%s closed with "
                     "%zu triangles (--keep-holes keeps them open)",
                     request.control.c_str(), loops, loops == 1 ? "" : "s", control.faceCount() - before);
        }
    }
    if (!request.skeleton.empty()) {
        // The paper's joint file: its point-to-line binding becomes
        // standard skin weights, so the rig plays in any glTF viewer.
        if (!skeleton.empty())
            warn("%s: its skin is replaced by %s", request.control.c_str(), request.skeleton.c_str());
        if (!(st = io::loadJointFile(request.skeleton, &skeleton)))
            throw BakeError(st.message());
        if (!(st = bindSkeletonWeights(&skeleton, control)))
            throw BakeError(request.skeleton + ": " + st.message());
        controlRig.source.reset();  // the document's own skin is replaced: write the control mesh anew
    }
    loadMs = msSince(t0);
}

// A character's capture posed at sampleSkinPoses' poses, pose-major (empty
// for a capture that is not one), for the decimation to weigh: at most
// 256 MB of positions (a million-vertex capture takes 22 of the poses,
// evenly spread).  A pose that throws the capture out of range (past it the
// runtime refuses the pose) is refused here, by name.
std::vector<glm::vec3> BakeJob::posedCapture() const
{
    std::vector<glm::vec3> posed;
    if (!character)
        return posed;
    std::vector<glm::mat4> skins;
    std::vector<std::pair<size_t, float>> times;
    sampleSkinPoses(highRig.skeleton, &skins, &times);
    const size_t nj = highRig.skeleton.skin.joints.size(), poses = nj ? skins.size() / nj : 0;
    const size_t room = std::max<size_t>(
        1, (size_t(256) << 20) / (sizeof(glm::vec3) * std::max<size_t>(1, high.positions.size())));
    if (poses > room) {
        std::vector<glm::mat4> kept;
        std::vector<std::pair<size_t, float>> keptTimes;
        for (size_t i = 0; i < room; ++i) {
            const size_t q = i * poses / room;
            kept.insert(kept.end(), skins.begin() + long(q * nj), skins.begin() + long((q + 1) * nj));
            keptTimes.push_back(times[q]);
        }
        skins.swap(kept);
        times.swap(keptTimes);
    }
    skinPositions(high.positions.data(), high.positions.size(), highRig.skeleton.weights, skins, nj, &posed,
                  options.threads);
    if (const size_t i = Surface::firstOutOfRange(posed.data(), posed.size()); i < posed.size()) {
        const glm::vec3& x = posed[i];
        const size_t pose = i / high.positions.size();
        const Animation& an = highRig.skeleton.animations[times[pose].first];
        char what[240];
        std::snprintf(what, sizeof(what),
                      "animation %zu (%s) at %.6g s poses vertex %zu at (%.6g, %.6g, %.6g), beyond +-%.0e or not "
                      "finite: the character cannot be played",
                      times[pose].first, an.name.c_str(), double(times[pose].second), i % high.positions.size(),
                      double(x.x), double(x.y), double(x.z), double(Surface::kLargestCoordinate));
        throw BakeError(request.high + ": " + what);
    }
    return posed;
}

// The rig written for a character against the character itself, posed as
// it moves: for every animation, at 10 evenly spaced times, the layered
// surface at the recommended level and the source's own mesh, each
// sampled by area and measured to the other, and both drawn (picture.h:
// textured, lit, smooth or flat as glTF draws each part) at one camera
// framing the source, compared by PSNR.
void BakeJob::measureFrames()
{
    if (!character)
        return;
    const auto t0 = std::chrono::steady_clock::now();
    Progress p(progress, "measuring the character's animations against its source");
    loadWritten();
    std::unique_ptr<Surface> layered, source;
    SurfaceOptions plain;
    plain.displace = false;
    plain.level = 0;
    Status st = Surface::create(&layered, written_, &writtenMap_);
    if (st)
        st = Surface::create(&source, highRig, nullptr, plain);
    if (!st)
        throw BakeError(request.output + ": the character rig does not pose against its source: " + st.message());
    std::vector<glm::vec3> a(layered->vertexCount()), b(source->vertexCount());
    std::vector<glm::vec3> na(a.size()), nb(b.size());
    TriangleIndex ia, ib;
    // Laid out for pictures once: the rig's parts and materials, the
    // source's (its materials and decoded images as loadCharacter read them,
    // which always hold glTF's default material; read here only if that failed).
    io::RenderMesh layoutA, layoutB;
    io::SceneMaterials materialsA, sourceMaterials;
    const io::SceneMaterials& materialsB = captureMaterials.materials.empty() ? sourceMaterials : captureMaterials;
    if (!(st = io::buildRenderMesh(written_, layered->plan(), &layoutA)) ||
        !(st = io::buildRenderMesh(highRig, source->plan(), &layoutB)) ||
        !(st = io::loadSceneMaterials(written_, &materialsA)) ||
        (captureMaterials.materials.empty() && !(st = io::loadSceneMaterials(highRig, &sourceMaterials))))
        throw BakeError(request.output + ": laying the character out for its pictures: " + st.message());
    // Normal textures drawn in the frame a viewer derives without TANGENT,
    // which the rig's is written in and a capture without TANGENTs reads
    // in; a capture's TANGENTs (not posed here) leave both pictures without
    // them, so that the two stay alike.
    const bool normalTextures = materialsB.fileTangents.empty();
    std::vector<uint8_t> pictureA, pictureB;
    for (size_t anim = 0; anim < highRig.skeleton.animations.size(); ++anim) {
        const Animation& an = highRig.skeleton.animations[anim];
        for (int k = 0; k < 10; ++k) {
            const float t = an.start + (an.end - an.start) * float(k) / 9.0f;
            if (!(st = layered->setAnimationTime(int(anim), t)) || !(st = source->setAnimationTime(int(anim), t)) ||
                !(st = layered->evaluate(a.data(), na.data(), a.size(), options.threads)) ||
                !(st = source->evaluate(b.data(), nb.data(), b.size(), options.threads)))
                throw BakeError(request.output + ": posing the character: " + st.message());
            ia.build(a.data(), layered->triangles().data(), layered->triangleCount(), options.threads);
            ib.build(b.data(), source->triangles().data(), source->triangleCount(), options.threads);
            const DistanceStats ab = sampleDistance(
                areaSamples(a.data(), layered->triangles().data(), layered->triangleCount(), a.size() + layered->triangleCount()),
                ib, options.threads);
            const DistanceStats ba = sampleDistance(
                areaSamples(b.data(), source->triangles().data(), source->triangleCount(), b.size() + source->triangleCount()),
                ia, options.threads);
            glm::vec3 lo, hi;
            source->bounds(&lo, &hi);  // undisplaced at level 0: the posed source's own box
            const PictureCamera camera = frameBox(lo, hi);
            renderPicture(pictureOf(layoutA, a, na, materialsA, normalTextures), camera, &pictureA);
            renderPicture(pictureOf(layoutB, b, nb, materialsB, normalTextures), camera, &pictureB);
            frames.push_back({int(anim), t, std::max(ab.rms, ba.rms), std::max(ab.max, ba.max),
                              picturePsnr(pictureA, pictureB)});
        }
    }
    framesMs = msSince(t0);
}

// --control auto on a glTF capture: a skinned, animated character keeps
// its skeleton, skin and animations on the cage (carryCharacter), in the
// capture's own space (its bind space: the nodes place it as they placed
// the capture).  What is not carried yet is named in one line.
void BakeJob::loadCharacter()
{
    const std::string ext = io::extensionOf(request.high);
    if (ext != ".glb" && ext != ".gltf") {
        coloured = !high.colours.empty();  // a PLY's or OBJ's vertex colours
        return;
    }
    // The capture read as a rig (its skeleton, materials).  Where the rig
    // reader refuses what the mesh reader took (two skins, for one), the
    // shape is baked as before and the one line says what is not carried.
    Status st = loadControlRig(request.high, &highRig, request.maxMemoryMB);
    if (!st) {
        warn("%s: --control auto carries its shape only, not its skin, animations or colour: %s", request.high.c_str(),
             st.message().c_str());
        highRig = Rig();
        return;
    }
    // The same scene reader welds both, and the vertices no triangle uses
    // are left out of both: the capture's vertices are the rig's.
    if (!(st = keepCaptureVertices(&highRig, highStats)))
        throw BakeError(request.high + ": " + st.message());
    if (highRig.mesh.positions.size() != high.positions.size())
        throw BakeError(request.high + ": the capture and its character do not weld to the same vertices");
    character = !highRig.skeleton.empty() && !highRig.skeleton.weights.weights.empty();
    // Not here: point and line primitives are named below, and a capture
    // has no layer to miss (strata-reconstruct's scene output, for one, is
    // written by Strata without one).
    for (const std::string& w : highRig.warnings)
        if (w.find("point or line primitives are kept in the file") == std::string::npos &&
            w.find("the displacement is gone") == std::string::npos)
            warn("%s: %s", request.high.c_str(), w.c_str());
    std::vector<std::string> warnings;
    if (highRig.source && io::loadSceneMaterials(highRig, &captureMaterials, &warnings)) {
        for (const std::string& w : warnings)
            warn("%s: %s", request.high.c_str(), w.c_str());
        // Any material or texture: the colour is carried (a capture of
        // glTF's default material alone has nothing to carry).
        coloured = captureMaterials.materials.size() > 1 || !captureMaterials.fileColours.empty();
    }
    if (!character && !highRig.skeleton.empty())
        warn("%s: --control auto does not carry its skin onto the automatic cage: no vertex carries a weight",
             request.high.c_str());
    const size_t flatParts = flatPartCount(highRig);
    if (flatParts > 0 && flatParts < highRig.parts.size())
        warn("%s: %zu of its %zu primitives are drawn flat (no NORMAL, or their faces' normals); the automatic cage "
             "is one mesh, drawn smooth",
             request.high.c_str(), flatParts, highRig.parts.size());
    if (coloured) {
        const io::SceneMaterials& sm = captureMaterials;
        faceMaterial.assign(high.faceCount(), int(sm.materials.size()) - 1);
        for (size_t p = 0; p < highRig.parts.size() && p < sm.partMaterial.size(); ++p)
            for (uint32_t f = 0; f < highRig.parts[p].faceCount; ++f)
                if (size_t(highRig.parts[p].firstFace + f) < faceMaterial.size())
                    faceMaterial[highRig.parts[p].firstFace + f] = sm.partMaterial[p];
        std::vector<size_t> uses(sm.materials.size(), 0);
        for (int m : faceMaterial)
            ++uses[size_t(m)];
        mainMaterial = size_t(std::max_element(uses.begin(), uses.end()) - uses.begin());
    }
    // What one material's re-baked textures and one skinned mesh cannot
    // carry is named.
    const bool mainIsTheFiles = coloured && mainMaterial + 1 < captureMaterials.materials.size();  // not the default
    const std::string left =
        io::featuresNotCarried(highRig, mainIsTheFiles ? int(mainMaterial) : -1, &captureMaterials);
    if (!left.empty())
        warn("%s: --control auto makes one skinned mesh of one material, its base colour, metallic, roughness, "
             "emissive and normals re-baked into textures, its alpha mode and sidedness the material most of the capture "
             "wears; not carried: %s",
             request.high.c_str(), left.c_str());
}

// The capture's skeleton on the cage: the same nodes, joints, inverse bind
// matrices and animations, each cage vertex weighted as the capture is at
// its nearest point.
void BakeJob::carryCharacter()
{
    Skeleton carried = highRig.skeleton;
    // A capture of separate pieces: each cage vertex weighted from its own.
    std::vector<uint32_t> vertexPiece, facePiece;
    SkinShells shells;
    if (const ShellLabels* labels = options.shells.get();
        labels && labels->controlFace.size() == control.faceCount() &&
        labels->highVertex.size() == high.positions.size()) {
        vertexPiece.assign(control.positions.size(), 0);
        for (size_t f = 0; f < control.faceCount(); ++f)
            for (int k = 0; k < 3; ++k)
                vertexPiece[control.triangles[3 * f + size_t(k)]] = labels->controlFace[f];
        facePiece.resize(high.faceCount());
        for (size_t f = 0; f < facePiece.size(); ++f)
            facePiece[f] = labels->highVertex[high.triangles[3 * f]];
        shells = {vertexPiece.data(), facePiece.data()};
    }
    Status st = transferSkinWeights(control, high, highIndex, highRig.skeleton.weights, &carried.weights,
                                    options.threads, shells);
    if (!st)
        throw BakeError(request.high + ": " + st.message());
    if (!(st = finalizeSkeleton(&carried, control.positions.size())))
        throw BakeError(request.high + ": " + st.message());
    // Then fitted over the animations, on the layered surface at the rig's
    // level or finer (level 3 at most, and under 32k points: the weights
    // follow the capture's weight field, not the displacement's detail).
    if (!carried.animations.empty()) {
        Progress p(progress, "fitting the skin weights over the animations");
        int level = std::min(3, std::max(recommended, 2));
        while (level > 1 && (control.faceCount() << (2 * level)) / 2 > (size_t(1) << 15))
            --level;
        std::unique_ptr<Plan> plan;
        if (!(st = Plan::create(&plan, control, options.scheme, level)) || !(st = plan->setDisplacement(map)) ||
            !(st = fitSkinWeights(*plan, control, high, highIndex, highRig.skeleton.weights, carried, &carried.weights,
                                  &skinFit, options.threads, shells)))
            throw BakeError(request.high + ": fitting the cage's skin weights: " + st.message());
    }
    rig.skeleton = std::move(carried);
}

// The capture's appearance re-baked onto the cage (material_carry.h): the
// rig's one material, and the summary's words for it.
void BakeJob::carryColour()
{
    const CaptureAppearance capture{captureMaterials,    high.colours, high.positions, high.triangles,
                                    highRig.fileCorners, faceMaterial, mainMaterial, highStats.drawnFlat};
    const Status st = carryAppearance(capture, control, map, options.scheme, recommended, highIndex,
                                      request.maxMemoryMB, options.threads, &baseColour, &colourNote);
    if (!st)
        throw BakeError(request.high + ": " + st.message());
    writeOptions.baseColour = &baseColour;
}

// The normal-volume mapping joins a control mesh to a capture in one frame:
// a control vertex many capture sizes away (a stray vertex, other units, a
// vertex two billion units out) makes every later stage (charts, map size,
// codecs) work on a meaningless extent, so it is refused here, by name.
void BakeJob::checkOneFrame() const
{
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (const glm::vec3& p : high.positions) {
        lo = glm::min(lo, glm::dvec3(p));
        hi = glm::max(hi, glm::dvec3(p));
    }
    const double diagonal = glm::length(hi - lo);
    if (!(diagonal > 0.0) || !std::isfinite(diagonal))
        throw BakeError(request.high + ": the high-resolution mesh has no extent (every vertex at one point)");
    constexpr double kReach = 4.0;  // capture diagonals
    for (size_t i = 0; i < control.positions.size(); ++i) {
        const glm::dvec3 p(control.positions[i]);
        const double away = glm::length(glm::max(glm::max(lo - p, p - hi), glm::dvec3(0.0)));
        if (away > kReach * diagonal) {
            char where[160];
            std::snprintf(where, sizeof(where), "control vertex %zu at (%.6g, %.6g, %.6g) lies %.3g diagonals of the capture from it",
                          i, p.x, p.y, p.z, away / diagonal);
            throw BakeError((request.control == "auto" ? request.high : request.control) + ": " + where +
                            ": the control mesh and the capture are not in one frame (a stray vertex, or other units?)");
        }
    }
}

void BakeJob::prepare()
{
    const auto t0 = std::chrono::steady_clock::now();
    Status st;
    // UVs, map size and recommended level.  Unless --size forces a size,
    // the map starts at the paper's texel ~ high-res edge rule and doubles
    // until the closed loop reaches --tolerance at a level around the
    // paper's, or stops improving: the smallest pair that reaches it.
    const double typicalEdge = medianEdgeLength(high);
    atlas.gutter = 1;
    atlas.threads = options.threads;
    // Charts grow into the pack's gaps, and the packer tries its eight
    // chart orders, only where the map is an output: a map that serves the
    // bake alone is sampled once per refined vertex and would gain nothing
    // from finer texels (without the orders every default rig of the paper
    // run came out byte for byte the same, nefertiti's within 0.1%, and
    // the 100k scan's layouts took half the time).
    atlas.growIntoGaps = request.exr || request.pngBits != 0 || request.layers;
    atlas.tryOrders = atlas.growIntoGaps;
    // So is one chart over the whole map where the charts miss the atlas
    // targets (a file's vertices and texels inside charts).
    atlas.wholeMap = atlas.growIntoGaps;
    bare = control;
    while (paperLevel < kMaxLevel && (control.faceCount() << (2 * paperLevel)) <= high.faceCount())
        ++paperLevel;
    // The capture indexed once: cage fitting, the stored values' fit and
    // their measurement all query it.
    highIndex.build(high.positions.data(), high.triangles.data(), high.faceCount(), options.threads);
    // A bare cage is fitted to the capture for the scheme it will carry
    // (Displaced Subdivision Surfaces 4.2).  A character's own vertices
    // (a glTF control, written back as it came) and a skinned cage (its
    // weights were bound to these positions) are never moved, nor is a
    // user's cage whose map is asked for as an image (--exr, --png8/16):
    // a pipeline applies that map to the cage it has.
    const bool mapForPipelines = request.exr || request.pngBits != 0;
    const bool fittable = request.fitCage && !controlRig.source && skeleton.empty();
    fitting = fittable && (request.control == "auto" || !mapForPipelines);
    fitSkippedForMaps = fittable && !fitting;
    fitOptions.level = std::clamp(paperLevel, 1, 3);
    fitOptions.threads = options.threads;
    forced = options.size > 0;
    size = options.size;
    if (uvMode == "auto") {
        // A chart atlas (charts grown over the control mesh, flattened,
        // packed); the per-triangle atlas only where the charts do not fit
        // the map.
        if (!forced) {
            if (!(st = layout(512)))  // provisional layout to measure the UV area (scale-free)
                throw BakeError(st.message());
            size = chooseMapSize(control, typicalEdge, options.maxSize, &sizeReason);
        }
    } else {
        std::string uvNote;
        if (fitUVsToUnitSquare(&control, &uvNote))
            warn("%s: %s", request.control.c_str(), uvNote.c_str());
        if (!forced)
            size = chooseMapSize(control, typicalEdge, options.maxSize, &sizeReason);
        if (!(st = checkUVs(control, std::max(size, 1024))))
            throw BakeError(request.control + ": " + st.message());
    }
    if (forced)
        sizeReason = "forced by --size";
    recommended = paperLevel;
    sizeCap = forced ? size : std::min(options.maxSize, 4096);
    if (!forced && shared && shared->sizeCap > 0) {
        sizeCap = std::min(sizeCap, shared->sizeCap);
        size = std::min(size, sizeCap);
    }
    prepareMs = msSince(t0);
}

void BakeJob::chooseScheme()
{
    Status st;
    schemeReason = request.schemeGiven ? "--scheme" : "";
    const auto schemeStart = std::chrono::steady_clock::now();
    if (!request.schemeGiven && shared && shared->schemeFits(control.faceCount())) {
        options.scheme = shared->scheme;
        schemeReason = shared->schemeReason;
    } else if (!request.schemeGiven && !forced && request.tolerance > 0.0) {
        // Which surface carries the map better for this pair, measured at
        // the paper's level and twice the first size (up to 512^2), so
        // that the map's resolution, which the smaller displacements of
        // the limit surface need less of, does not decide it: the paper's
        // linear split unless the Loop limit is clearly closer (loose
        // cages).
        const int probeSize = std::max(size, std::min(2 * size, std::min(512, sizeCap)));
        if (uvMode == "auto" && !(st = layout(probeSize)))
            throw BakeError(st.message());
        // The linear scheme first: when it meets the tolerance four times
        // over (a level lower would too) the smooth one is not tried (its
        // fit and bake cost several times more); otherwise the closer
        // surface may reach the tolerance a level earlier, with a quarter
        // of the stored values.  Nor is it tried on a dense cage (a
        // sixteenth of the capture's faces or more: the paper's level is 2
        // or less) that the linear scheme brings within the tolerance: the
        // limit surface's gain is between the control vertices of a loose
        // cage (on the 100k scan's 10k remesh it came 4% closer, short of
        // the 25% that would choose it, for 3.9 of the bake's 8.6 s).
        //
        // A fitted cage is the costly part of the smooth probe, so the
        // limit surface is first measured on the cage fitted for the linear
        // scheme: where it comes out more than 4 times farther than the
        // linear one, its own fit is not tried either (a fit took the
        // error of spot, the hand and the penguin down by a third to a
        // half; on the 100k scan's automatic cage the fitted limit surface
        // still lost 32x, after 3 s of fitting).
        auto measure = [&](Scheme candidate, bool ownFit) {
            BakeOptions probe = options;
            probe.size = uvMode == "auto" ? atlas.mapSize : probeSize;
            probe.scheme = candidate;
            DisplacementMap probeMap;
            BakeReport probeReport;
            std::vector<LevelError> errs;
            ControlMesh candidateMesh = control;
            useFit(ownFit ? candidate : Scheme::Linear, &candidateMesh);
            Progress p(progress, "choosing the subdivision scheme");
            if (!(st = bake(&probeMap, nullptr, &probeReport, candidateMesh, high, probe)) ||
                !(st = closedLoopError(&errs, candidateMesh, probeMap, candidate, high, paperLevel, paperLevel,
                                       options.threads, size_t(1) << 20, nullptr, &loopCapture())))
                throw BakeError(request.high + ": " + st.message());
            return errs[0].rms() / probeReport.diagonal;
        };
        double rms[2] = {measure(Scheme::Linear, true), -1.0};
        bool unfitted = false;
        if (!(rms[0] <= 0.25 * request.tolerance || (paperLevel <= 2 && rms[0] <= request.tolerance))) {
            if (fitting) {
                rms[1] = measure(Scheme::Smooth, false);
                unfitted = rms[1] > 4.0 * rms[0];
            }
            if (!unfitted)
                rms[1] = measure(Scheme::Smooth, true);
        }
        options.scheme = rms[1] >= 0.0 && rms[1] * 1.25 < rms[0] ? Scheme::Smooth : Scheme::Linear;
        char buf[200];
        if (rms[1] < 0.0)
            std::snprintf(buf, sizeof(buf), "measured: linear %.4g%% RMS at level %d meets the tolerance",
                          100.0 * rms[0], paperLevel);
        else if (unfitted)
            std::snprintf(buf, sizeof(buf), "measured: linear %.4g%%, smooth %.4g%% on the linear fit (not fitted "
                                            "for itself: over 4x farther) RMS at level %d",
                          100.0 * rms[0], 100.0 * rms[1], paperLevel);
        else
            std::snprintf(buf, sizeof(buf), "measured: linear %.4g%%, smooth %.4g%% RMS at level %d", 100.0 * rms[0],
                          100.0 * rms[1], paperLevel);
        schemeReason = buf;
        if (shared) {
            appendf(&schemeReason, " on a cage of %zu faces", control.faceCount());
            shared->scheme = options.scheme;
            shared->schemeReason = schemeReason;
            shared->schemeFaces = control.faceCount();
            shared->schemeDecisive = unfitted;
            shared->schemeKnown = true;
        }
    }
    useFit(options.scheme, &bare);
    useFit(options.scheme, &control);
    schemeMs = msSince(schemeStart);  // fits included
}

void BakeJob::searchMapSize()
{
    Status st;
    const auto searchStart = std::chrono::steady_clock::now();
    for (;;) {
        checkMemory(size);  // before the atlas, whose packing at a large size is work too
        if (uvMode == "auto") {
            for (; size <= 8192; size *= 2) {
                {
                    Progress p(progress, "laying out the atlas");
                    st = layout(size);
                }
                if (st.code() == StatusCode::Cancelled)
                    throw BakeCancelled();
                if (st)
                    break;
                if (forced)
                    throw BakeError(st.message());
                sizeReason += "; raised to fit the charts";
            }
            if (!st)
                throw BakeError(st.message());
        }
        options.size = size;
        checkMemory(size);
        {
            Progress p(progress, "baking");
            if (!(st = bake(&map, &layers, &rep, control, high, options)))
                throw BakeError(request.high + ": " + st.message());
        }
        if (forced || request.tolerance <= 0.0)
            break;
        // The paper's level and every level below it (a loose tolerance
        // is met with fewer refined vertices, hence fewer stored values;
        // the coarse levels cost little to measure); a finer level than
        // the paper's rule rarely pays for its four times the triangles.
        std::vector<LevelError> errs;
        const int lo = 0, hi = paperLevel;
        {
            Progress p(progress, "measuring the map size against --tolerance");
            if (!(st = closedLoopError(&errs, control, map, options.scheme, high, lo, hi, options.threads,
                                       size_t(1) << 20, nullptr, &loopCapture())))
                throw BakeError(st.message());
        }
        double best = 1e300;
        int met = -1, bestLevel = hi;
        for (const LevelError& e : errs) {
            const double rms = e.rms() / rep.diagonal;
            trials.push_back({size, e.level, rms});
            if (rms < best) {
                best = rms;
                bestLevel = e.level;
            }
            if (met < 0 && rms <= request.tolerance)
                met = e.level;
        }
        if (met >= 0) {
            recommended = met;
            char buf[96];
            std::snprintf(buf, sizeof(buf), "; reaches --tolerance %.4g%% at level %d", 100.0 * request.tolerance, met);
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
    searchMs = msSince(searchStart);
    rep.sizeReason = sizeReason;
    if (shared)
        shared->mapSize = size;
    if (uvMode == "auto") {
        // Either atlas gives each UV to one vertex of one chart (or
        // triangle): the UVs are the vertices a file with them holds.
        atlasVertices = control.uvs.size();
        char buf[240];
        if (chartStats.wholeMap)
            std::snprintf(buf, sizeof(buf),
                          "one chart over the whole map (the charts split over %.1fx the vertices or filled "
                          "under %.0f%% of the map), %.0f%% of texels inside it, L2 stretch %.2f",
                          SquareAtlasOptions().maxVertexRatio, 100.0 * kAtlasMinFill, 100.0 * chartStats.texelFill,
                          chartStats.stretch);
        else if (chartStats.charts)
            std::snprintf(buf, sizeof(buf),
                          "chart atlas: %zu charts, %.0f%% of texels inside charts, distortion <= %.2f",
                          chartStats.charts, 100.0 * chartStats.texelFill, chartStats.maxDistortion);
        else
            std::snprintf(buf, sizeof(buf), "per-triangle atlas (the charts did not fit the map)");
        atlasNote = buf;
        std::snprintf(buf, sizeof(buf), ", %zu vertices once split at its seams (%.2fx)", atlasVertices,
                      double(atlasVertices) / double(std::max<size_t>(1, control.positions.size())));
        atlasNote += buf;
    }
}

// The rig in memory: the control mesh, a character's skin and colour, the
// layer's record and the stored values, at the level the closed loop
// settles on.
void BakeJob::encodeRig()
{
    const auto t0 = std::chrono::steady_clock::now();
    rig = std::move(controlRig);
    rig.mesh = control;
    rig.skeleton = std::move(skeleton);
    if (character)
        carryCharacter();
    if (coloured)
        carryColour();
    rig.hasDisplacement = true;
    rig.displacement = DisplacementInfo();
    rig.displacement.scheme = options.scheme;
    rig.displacement.recommendedLevel = recommended;
    rig.displacement.flatShading = highStats.drawnFlat;
    if (request.pngBits) {
        // The quantised PNG (written beside the rig by writeOutputs), named
        // in the rig.
        rig.displacement.quantized.uri = io::stemOf(pngPath()) + ".png";
        rig.displacement.quantized.bits = request.pngBits;
        rig.displacement.quantized.dmin = rep.dmin;
        rig.displacement.quantized.dmax = rep.dmax;
    }
    writeOptions.compress = request.compress && request.meshCoding != "plain";
    writeOptions.draco = request.meshCoding == "draco";
    // A bare cage's positions are stored to four times the tolerance: the
    // stored values are measured and fitted on the decoded cage, so its
    // error along the normals is taken up by them (on the real pairs the
    // closed loop moved by under 1% against a quarter of it).  Where an
    // edge would collapse at that error, the writer takes a finer one.
    writeOptions.maxPositionError = request.tolerance > 0.0 ? 4.0 * request.tolerance * rep.diagonal : 0.0;
    writeOptions.vertexDisplacements = request.mapCoding == "vertex";
    // An atlas made only to bake through is left out of a vertex-coded
    // rig (nothing reads it there); outputs that are the map keep it.
    writeOptions.omitDisplacementUVs = uvMode == "auto" && !request.exr && !request.pngBits && !request.layers;
    // Stored values measured and fitted on the capture come 1.4-2.7x closer
    // than the map's samples (the real pairs and the 100k scan), so where
    // the map's trial one level coarser comes within 3x of the tolerance,
    // that level is encoded first and settleLevel goes finer only if it
    // misses.  Encoding the finer one first would be followed by the
    // coarser one anyway (settleLevel tries coarser levels within that 3x)
    // and costs four times as much (measured, fitted, quantised, each in
    // the closed loop): it was 40% of the scan's second automatic try.
    if (writeOptions.vertexDisplacements && !forced && request.tolerance > 0.0 && recommended > 0)
        if (const Trial* coarser = trialAt(recommended - 1); coarser && coarser->rms <= 3.0 * request.tolerance)
            --recommended;
    if (Status st = encodeAt(recommended, &rigBytes_); !st)
        throw BakeError(namingOutput(st));
    settleLevel();
    for (const std::string& n : notes)
        warn("%s: %s", request.output.c_str(), n.c_str());
    encodeMs = msSince(t0);
}

// The files, staged beside their targets until finish() commits them: the
// map images asked for, then the rig.
void BakeJob::writeOutputs()
{
    const auto t0 = std::chrono::steady_clock::now();
    std::error_code mkdirError;
    if (!io::directoryOf(request.output).empty())
        std::filesystem::create_directories(io::directoryOf(request.output), mkdirError);
    if (mkdirError)
        throw BakeError(io::directoryOf(request.output) + ": cannot create the output folder (" +
                        mkdirError.message() + ")");
    Outputs::removeStale(io::directoryOf(request.output));
    if (request.exr)
        outputs.write(base + ".exr", [&](const std::string& p) {
            return io::writeDisplacementExr(p, map, request.floatExr ? io::ExrPixelType::Float : io::ExrPixelType::Half,
                                            options.threads);
        });
    if (request.pngBits) {
        std::vector<uint16_t> q(map.texels.size());  // paper eq. 12 at 2^n levels
        for (size_t i = 0; i < q.size(); ++i)
            q[i] = uint16_t(shared::strata_quantize(map.texels[i], rep.dmin, rep.dmax, float(1 << request.pngBits)));
        outputs.write(pngPath(), [&](const std::string& p) {
            return io::writePngGray(p, map.width, map.height, request.pngBits, q);
        });
    }
    if (request.layers)
        outputs.write(base + "_layers.png", [&](const std::string& p) {
            return io::writePngRgb(p, map.width, map.height, layerImage(layers));
        });
    outputs.write(request.output, [&](const std::string& p) {
        return io::writeFileAtomic(p, rigBytes_.data(), rigBytes_.size());
    });
    writeMs = msSince(t0);
}

// The rig as encoded, read back as a loader reads the file and, map-coded,
// its map: loaded once for the measurements that read it back.
void BakeJob::loadWritten()
{
    if (writtenLoaded_)
        return;
    Status st = io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(rigBytes_.data()), rigBytes_.size(),
                                      io::extensionOf(request.output) == ".glb", request.output, &written_);
    if (st && written_.displacement.vertexLevel < 0)
        st = io::loadRigDisplacementMap(request.output, written_, &writtenMap_);
    if (!st)
        throw BakeError(request.output + ": the rig just encoded does not load back: " + st.message());
    writtenLoaded_ = true;
}

void BakeJob::measureWritten()
{
    Status st;
    // Closed loop: reconstruct from the rig as encoded, as the runtime
    // will, at the levels around the recommended one unless asked.
    if (errorFrom == -2) {
        errorFrom = std::max(0, recommended - 1);
        errorTo = std::min(kMaxLevel, recommended + 1);
    }
    if (errorTo >= 0) {
        loadWritten();
        const Rig& written = written_;
        DisplacementField field;
        if (written.displacement.vertexLevel >= 0 &&
            !(st = DisplacementField::create(&field, written.mesh, written.displacement.vertexLevel,
                                             written.displacement.vertexValues)))
            throw BakeError(request.output + ": the rig just encoded does not load back: " + st.message());
        const auto t0 = std::chrono::steady_clock::now();
        Progress p(progress, "measuring the closed-loop error");
        if (!(st = closedLoopError(&errors, written.mesh, writtenMap_, options.scheme, high, errorFrom, errorTo,
                                   options.threads, size_t(1) << 20,
                                   written.displacement.vertexLevel >= 0 ? &field : nullptr, &loopCapture())))
            throw BakeError(st.message());
        errorMs = msSince(t0);
    }
}

void BakeJob::summarize()
{
    {
        // A rig replaces the capture; one larger than the capture as a
        // plain glb (float positions, 16- or 32-bit indices, a little
        // JSON) has a control mesh about as dense as the capture, and
        // the user is told so rather than left to find out.
        // Like with like: a capture that is a glTF file is compared as the
        // file it is (textures, animations and skins included); a mesh file
        // as a plain glb of its triangles, plus whatever textures,
        // animations and skins the rig carries from its control.
        const size_t hv = rep.highVertices, hf = rep.highTriangles;
        const std::string highExt = io::extensionOf(request.high);
        const bool gltfCapture = highExt == ".glb" || highExt == ".gltf";
        const double extra = double(io::characterBytes(rig));
        std::error_code sizeError;
        const double highBytes = gltfCapture ? double(std::filesystem::file_size(request.high, sizeError)) : 0.0;
        const double plain = gltfCapture && !sizeError ? highBytes
                                         : 12.0 * double(hv) + 3.0 * double(hf) * (hv <= 65535 ? 2.0 : 4.0) + 600.0 +
                                               extra;
        const double rigBytes = fileSize(request.output);
        char what[160];
        if (gltfCapture && !sizeError)
            std::snprintf(what, sizeof(what), "as the file it is");
        else
            std::snprintf(what, sizeof(what), "as a plain glb (about %.1f KB: %zu vertices, %zu triangles%s)",
                          plain / 1024.0, hv, hf, extra > 0 ? ", with the rig's textures, animations and skins" : "");
        // What the rig is most made of: its images, its animations (keyed
        // as the capture keys them), or else its control mesh and layer.
        io::CharacterBytes kinds;
        if (rigBytes > plain) {
            loadWritten();
            kinds = io::characterBytesOf(written_);
        }
        const double images = double(kinds.images), animations = double(kinds.animations);
        const double mesh = rigBytes - images - animations - double(kinds.skins);
        std::string textures = "base colour";  // the re-baked ones, by name
        for (const auto& [image, name] : {std::pair{&baseColour.metallicRoughness, ", metallic-roughness"},
                                          std::pair{&baseColour.emissiveRGBA, ", emissive"},
                                          std::pair{&baseColour.normalRGBA, ", normal"}})
            if (!image->empty())
                textures += name;
        const bool several = textures.find(',') != std::string::npos;
        if (rigBytes > plain && coloured && images >= std::max(animations, mesh))
            warn("%s: the rig (%.1f KB) is larger than the capture %s (%.1f KB); most of it is the %dx%d %s "
                 "texture%s re-baked into the cage's UVs (%.1f KB)",
                 request.output.c_str(), rigBytes / 1024.0, what, plain / 1024.0, baseColour.width, baseColour.height,
                 textures.c_str(), several ? "s" : "", images / 1024.0);
        else if (rigBytes > plain && animations >= std::max(images, mesh))
            warn("%s: the rig (%.1f KB) is larger than the capture %s (%.1f KB); most of it is its animations "
                 "(%.1f KB), keyed as the capture keys them",
                 request.output.c_str(), rigBytes / 1024.0, what, plain / 1024.0, animations / 1024.0);
        else if (rigBytes > plain)
            warn("%s: the rig (%.1f KB) is larger than the capture %s (%.1f KB); its control mesh has %zu triangles, "
                 "and a coarser one (%s), or --mesh-coding meshopt or draco, makes a smaller rig",
                 request.output.c_str(), rigBytes / 1024.0, what, plain / 1024.0, control.faceCount(),
                 request.control == "auto" ? "--control-faces, or a looser --tolerance" : "--control auto");
    }
    if (writeOptions.compress && io::extensionOf(request.output) == ".glb")
        warn("%s: %s-coded, which Blender 3.4 (Debian's, without Draco) and gltfpack do not open; "
             "--mesh-coding plain writes a rig they do",
             request.output.c_str(), request.meshCoding == "draco" ? "Draco" : "meshopt");
    const double diag = rep.diagonal;
    // The promise first: the closed loop at the recommended level (area-
    // weighted both ways, the larger side) against --tolerance.
    std::string promise;
    bool metAtRest = false;
    for (const LevelError& e : errors)
        if (e.level == recommended && request.tolerance > 0.0 && diag > 0.0) {
            const double reached = std::max(e.forwardRms, e.backwardRms) / diag;
            char buf[200];
            if (reached > request.tolerance)
                std::snprintf(buf, sizeof(buf), "; MISSES --tolerance %.4g%%: %.4g%% RMS at level %d", 100.0 * request.tolerance,
                              100.0 * reached, recommended);
            else
                std::snprintf(buf, sizeof(buf), "; %.4g%% RMS at level %d, within --tolerance %.4g%%", 100.0 * reached,
                              recommended, 100.0 * request.tolerance);
            metAtRest = reached <= request.tolerance;
            promise = buf;
        }
    // A character's closed loop is its rest pose: how far it moves from its
    // source (the worst of the frames measured below) goes beside it.
    if (!frames.empty() && diag > 0.0) {
        const FrameError& worst = *std::max_element(frames.begin(), frames.end(),
                                                    [](const FrameError& a, const FrameError& b) { return a.rms < b.rms; });
        char buf[200];
        std::snprintf(buf, sizeof(buf), "; posed, %.4g%% RMS from the source at worst (animation %d at %.3g s)",
                      100.0 * worst.rms / diag, worst.animation, double(worst.time));
        promise += buf;
        // The tolerance is met at rest; what the poses add is the skin
        // carried to the cage (its weights blended on fewer vertices).  The
        // face-count search judges it, so this is a fixed --control-faces
        // or a search that reached its cap: said where it goes past, not
        // left to read (CesiumMan: 2.7x at 0.01%, 1,000 faces).
        if (metAtRest && worst.rms / diag > request.tolerance) {
            std::snprintf(buf, sizeof(buf),
                          ", %.2gx --tolerance: the skin carried to the cage (the tolerance is met at rest; more %s "
                          "carry it closer)",
                          worst.rms / diag / request.tolerance,
                          request.control == "auto" ? "--control-faces" : "control faces");
            promise += buf;
        }
        // The pictures as a last check: a rig posed in the wrong units, or
        // coloured through the wrong UVs, measured near its source in a
        // space of its own, but its pictures were 1-7 dB from the source's
        // (a rig that looks like its source: 19-36 dB).
        const FrameError& unlike = *std::min_element(
            frames.begin(), frames.end(), [](const FrameError& a, const FrameError& b) { return a.psnr < b.psnr; });
        if (unlike.psnr < kLooksAlikeDb) {
            std::snprintf(buf, sizeof(buf), "; DOES NOT LOOK LIKE ITS SOURCE: picture PSNR %.3g dB (animation %d at %.3g s)",
                          unlike.psnr, unlike.animation, double(unlike.time));
            promise += buf;
        }
    }
    appendf(&result->summary, "strata-bake: %s onto %s (%s scheme%s%s)%s\n", request.high.c_str(), request.control.c_str(),
                 schemeName(options.scheme), schemeReason.empty() ? "" : ": ", schemeReason.c_str(), promise.c_str());
    appendf(&result->summary, "  high-res      %zu vertices, %zu triangles (median edge %.4g)\n", rep.highVertices,
                rep.highTriangles, rep.typicalEdge);
    if (highStats.polygonsTriangulated || highStats.duplicateVertices || highStats.degenerateTriangles ||
        highStats.nonManifoldEdges || highStats.unreferencedVertices)
        appendf(&result->summary, "  tolerated     %zu polygons triangulated, %zu duplicate vertices, %zu degenerate "
                    "triangles, %zu non-manifold edges, %zu vertices no triangle uses (left out)\n",
                    highStats.polygonsTriangulated, highStats.duplicateVertices, highStats.degenerateTriangles,
                    highStats.nonManifoldEdges, highStats.unreferencedVertices);
    if (highStats.drawnFlat)
        appendf(&result->summary, "  shading       flat, as glTF draws the capture (no primitive has NORMAL)\n");
    result->summary += searchNote_;
    appendf(&result->summary, "  control       %zu vertices, %zu triangles, UVs %s", control.positions.size(),
            control.faceCount(), uvMode == "auto" ? ("generated, " + atlasNote).c_str() : "kept");
    if (options.shells)
        appendf(&result->summary, "; the capture's %zu separate pieces each mapped onto its own", pieces_);
    result->summary += "\n";
    if (character) {
        appendf(&result->summary,
                "  character     %zu joints, %zu animations and skin weights carried from the capture",
                rig.skeleton.skin.joints.size(), rig.skeleton.animations.size());
        if (skinFit.poses > 0)
            appendf(&result->summary,
                    ", the weights fitted over %zu poses (the layered surface moves %.3g%% of the diagonal from the "
                    "capture's motion, RMS; %.3g%% as carried)",
                    skinFit.poses, 100.0 * skinFit.after / rep.diagonal, 100.0 * skinFit.before / rep.diagonal);
        result->summary += "\n";
    }
    if (!colourNote.empty())
        appendf(&result->summary, "  colour        %s\n", colourNote.c_str());
    appendf(&result->summary, "  map           %dx%d: %s\n", map.width, map.height, rep.sizeReason.c_str());
    if (fitting) {
        const Fitted& f = fitted[int(options.scheme)];
        if (f.stats.maxMove > 0.0)
            appendf(&result->summary,
                    "  fitted        cage vertices moved by up to %.3g%% of the diagonal: the %s base surface's RMS "
                    "distance to the capture %.4f%% -> %.4f%% (--no-fit keeps them)\n",
                    100.0 * f.stats.maxMove / rep.diagonal, schemeName(options.scheme),
                    100.0 * f.stats.rmsBefore / rep.diagonal, 100.0 * f.stats.rmsAfter / rep.diagonal);
        else
            appendf(&result->summary, "  fitted        cage kept: moving it did not bring the %s base surface closer\n",
                    schemeName(options.scheme));
    } else if (fitSkippedForMaps) {
        appendf(&result->summary, "  fitted        cage kept as drawn: the map images (--exr, --png) are for the cage "
                                  "you have\n");
    }
    if (writeOptions.vertexDisplacements)
        appendf(&result->summary,
                "  stored        per refined vertex at level %d, %s (the closed loop chose; %zu of them "
                "measured), quantised in steps of %.3g%% of the diagonal%s\n",
                recommended, stored.how, stored.measured, 100.0 * stored.step / rep.diagonal,
                writeOptions.omitDisplacementUVs ? "; the atlas only served the bake and is not in the rig "
                                                   "(--exr keeps it)" : "");
    if (!trials.empty()) {
        appendf(&result->summary, "  trade-off     (map, level: RMS / diagonal, the larger direction; tolerance %.4g%%)\n",
                     100.0 * request.tolerance);
        for (const Trial& t : trials)
            appendf(&result->summary, "                %5d, %d: %.4f%%%s\n", t.size, t.level, 100.0 * t.rms,
                         t.size == map.width && t.level == recommended ? "  <- chosen" : "");
    }
    appendf(&result->summary, "  mapping       %zu in a normal volume, %zu fell back to the nearest point (search |d| <= %.3g)\n",
                rep.highVertices - rep.fallbackVertices, rep.fallbackVertices, rep.searchDistance);
    appendf(&result->summary, "  raster        %zu border triangles, %zu pieces, coverage %.2f%%, overlap %.3f%% of texels\n",
                rep.raster.borderTriangles, rep.raster.pieces, 100.0 * rep.coverage, 100.0 * rep.overlapFraction);
    appendf(&result->summary, "  holes/gutters %zu texels measured by line intersection, the rest dilated\n",
                rep.lineFilledTexels);
    appendf(&result->summary, "  distances     dmin %.4g, dmax %.4g (%.3g%% .. %.3g%% of the diagonal %.4g)\n", rep.dmin, rep.dmax,
                100.0 * rep.dmin / diag, 100.0 * rep.dmax / diag, diag);
    appendf(&result->summary, "%s\n", kTimePlaceholder);  // run() writes it once every phase has run
    appendf(&result->summary, "  outputs      ");
    for (const std::string& p : outputs.written)
        appendf(&result->summary, " %s (%.0f KB)", p.c_str(), fileSize(p) / 1024.0);
    appendf(&result->summary, "\n");
    const double bound = std::sqrt(3.0) / 2.0 * rep.typicalEdge;
    if (!errors.empty()) {
        appendf(&result->summary, "  closed loop (distance / diagonal; paper bound sqrt(3)/2 edge = %.3g%%)\n", 100.0 * bound / diag);
        appendf(&result->summary, "    level | triangles | recon->high RMS   max   | high->recon RMS   max\n");
        for (const LevelError& e : errors)
            appendf(&result->summary, "    %5d | %9zu | %9.4f%% %8.4f%% | %9.4f%% %8.4f%%\n", e.level, e.triangles,
                        100.0 * e.forwardRms / diag, 100.0 * e.forwardMax / diag, 100.0 * e.backwardRms / diag,
                        100.0 * e.backwardMax / diag);
    }
    if (!frames.empty()) {
        appendf(&result->summary,
                "  posed against the source (level %d, 10 times per animation; the larger side; distance / diagonal; "
                "both drawn at 256x256, one camera, textured and lit)\n",
                recommended);
        appendf(&result->summary,
                "    animation                | RMS mean  RMS worst | max worst | picture PSNR mean, worst\n");
        for (size_t anim = 0; anim < highRig.skeleton.animations.size(); ++anim) {
            double mean = 0.0, worstRms = 0.0, worstMax = 0.0, psnr = 0.0, worstPsnr = 1e300;
            int n = 0;
            for (const FrameError& f : frames)
                if (f.animation == int(anim)) {
                    mean += f.rms;
                    worstRms = std::max(worstRms, f.rms);
                    worstMax = std::max(worstMax, f.max);
                    psnr += f.psnr;
                    worstPsnr = std::min(worstPsnr, f.psnr);
                    ++n;
                }
            appendf(&result->summary, "    %-24.24s | %8.4f%% %8.4f%% | %8.4f%% | %5.1f dB, %5.1f dB\n",
                    highRig.skeleton.animations[anim].name.c_str(), 100.0 * mean / std::max(n, 1) / diag,
                    100.0 * worstRms / diag, 100.0 * worstMax / diag, psnr / std::max(n, 1), n ? worstPsnr : 0.0);
        }
    }
}

void BakeJob::writeReport()
{
    const double diag = rep.diagonal, bound = std::sqrt(3.0) / 2.0 * rep.typicalEdge;
    report["high"] = {{"path", request.high},
                      {"vertices", rep.highVertices},
                      {"triangles", rep.highTriangles},
                      {"medianEdge", rep.typicalEdge},
                      {"diagonal", diag},
                      {"polygonsTriangulated", highStats.polygonsTriangulated},
                      {"duplicateVertices", highStats.duplicateVertices},
                      {"degenerateTriangles", highStats.degenerateTriangles},
                      {"nonManifoldEdges", highStats.nonManifoldEdges},
                      {"unreferencedVertices", highStats.unreferencedVertices}};
    report["control"] = {{"path", request.control},
                         {"vertices", control.positions.size()},
                         {"triangles", control.faceCount()},
                         {"uv", uvMode},
                         {"pieces", options.shells ? pieces_ : size_t(1)}};
    if (uvMode == "auto") {
        report["atlas"] = {{"charts", chartStats.charts},  // 0: the per-triangle atlas
                           {"kind", chartStats.wholeMap ? "whole map" : chartStats.charts ? "charts" : "triangles"},
                           {"splitVertices", atlasVertices}};
        if (chartStats.charts) {
            report["atlas"]["texelFill"] = chartStats.texelFill;
            report["atlas"]["maxDistortion"] = chartStats.maxDistortion;
            if (chartStats.wholeMap)
                report["atlas"]["stretch"] = chartStats.stretch;
        }
    }
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
    if (!frames.empty()) {
        nlohmann::json list = nlohmann::json::array();
        for (const FrameError& f : frames)
            list.push_back({{"animation", f.animation},
                            {"time", f.time},
                            {"rms", f.rms / diag},
                            {"max", f.max / diag},
                            {"psnr", f.psnr}});
        report["posed"] = {{"level", recommended}, {"frames", list}, {"ms", framesMs}};
    }
    if (skinFit.poses > 0)
        report["skinFit"] = {{"poses", skinFit.poses},
                             {"points", skinFit.points},
                             {"before", skinFit.before / diag},
                             {"after", skinFit.after / diag}};
    report["tolerance"] = request.tolerance;
    report["tradeOff"] = tradeOff;
    report["scheme"] = schemeName(options.scheme);
    report["shading"] = highStats.drawnFlat ? "flat" : "smooth";
    report["recommendedLevel"] = recommended;
    report["timeMs"] = {{"load", loadMs}, {"mapping", rep.times.mapping}, {"rasterize", rep.times.rasterize},
                        {"dilate", rep.times.dilate}, {"fit", fitMs}, {"schemeChoice", schemeMs},
                        {"sizeSearch", searchMs}, {"write", encodeMs + writeMs}, {"encode", encodeMs},
                        {"closedLoop", errorMs}};
    if (fitting) {
        const Fitted& f = fitted[int(options.scheme)];
        report["fit"] = {{"moved", f.stats.maxMove > 0.0},
                         {"maxMove", f.stats.maxMove / rep.diagonal},
                         {"baseRmsBefore", f.stats.rmsBefore / rep.diagonal},
                         {"baseRmsAfter", f.stats.rmsAfter / rep.diagonal}};
    }
    report["storedValues"] = stored.how;
    if (writeOptions.vertexDisplacements)
        report["quantizationStep"] = stored.step;
    nlohmann::json files = nlohmann::json::object();
    for (const std::string& p : outputs.written)
        files[p] = fileSize(p);
    report["outputBytes"] = files;
    report["paperBound"] = {{"maxError", bound}, {"relative", bound / diag}};
    nlohmann::json levels = nlohmann::json::array();
    for (const LevelError& e : errors)
        levels.push_back({{"level", e.level}, {"vertices", e.vertices}, {"triangles", e.triangles},
                          {"forwardRms", e.forwardRms / diag}, {"forwardMax", e.forwardMax / diag},
                          {"backwardRms", e.backwardRms / diag}, {"backwardMax", e.backwardMax / diag}});
    report["closedLoop"] = levels;
    if (!searchReport_.is_null())
        report["cageFaces"] = searchReport_;
    const std::string text = report.dump(2) + "\n";
    result->report = text;
    if (!request.report.empty() && request.report != "-")
        outputs.write(request.report, [&](const std::string& p) { return io::writeFileAtomic(p, text.data(), text.size()); });
}

void BakeJob::finish()
{
    outputs.commit();
    result->written = outputs.written;
    result->recommendedLevel = recommended;
    result->scheme = options.scheme;
    for (const LevelError& e : errors)
        if (e.level == recommended)
            result->rms = e.rms() / rep.diagonal;
}

const std::vector<glm::vec3>& BakeJob::fittedPositions(Scheme scheme)
{
    Fitted& f = fitted[int(scheme)];
    if (!f.done) {
        Progress p(progress, "fitting the control mesh to the capture");
        const auto tf = std::chrono::steady_clock::now();
        ControlMesh moved = bare;
        fitOptions.scheme = scheme;
        Status st;
        if (!(st = fitControlMesh(&moved, high, highIndex, fitOptions, &f.stats)))
            throw BakeError(request.high + ": fitting the control mesh: " + st.message());
        f.positions = std::move(moved.positions);
        f.done = true;
        fitMs += msSince(tf);
    }
    return f.positions;
}

// Puts the cage fitted for `scheme` into `mesh` (the scheme probe's
// cage, then the chosen scheme's into `bare`, which later atlas
// layouts start from, and `control`); a no-op without fitting.
void BakeJob::useFit(Scheme scheme, ControlMesh* mesh)
{
    if (!fitting)
        return;
    mesh->positions = fittedPositions(scheme);
}

Status BakeJob::layout(int mapSize)
{
    atlas.mapSize = mapSize;
    control = bare;
    Status s = buildAtlas(&control, atlas, &chartStats, &chartCache);
    if (!s) {
        control = bare;
        AtlasOptions triangles = atlas;
        triangles.gutter = 2;
        s = buildTriangleAtlas(&control, triangles);
        chartStats = ChartAtlasStats();
    }
    return s;
}

// Memory before work: the baker holds about 32 bytes per texel (map,
// layers, owners, dilation) and 200 per high-res triangle (mesh,
// mapping, index); the closed loop is chunked.
void BakeJob::checkMemory(int mapSize) const
{
    const double needMB = (32.0 * double(mapSize) * double(mapSize) + 200.0 * double(high.faceCount())) /
                          (1024.0 * 1024.0);
    if (needMB > request.maxMemoryMB)
        throw BakeError(request.output + ": a " + std::to_string(mapSize) + "^2 map over " +
                         std::to_string(high.faceCount()) + " triangles needs about " +
                         std::to_string(long(needMB)) + " MB, over the " + std::to_string(long(request.maxMemoryMB)) +
                         " MB budget (raise it with --max-memory MB)");
}

// The map's trial of `level` at the chosen size, or null.
const BakeJob::Trial* BakeJob::trialAt(int level) const
{
    for (const Trial& t : trials)
        if (t.size == map.width && t.level == level)
            return &t;
    return nullptr;
}

// The map keeps the bits the error needs: a step q adds q / sqrt(12)
// RMS, in quadrature with the rest, so q = E (the tolerance, or the
// error the chosen size and level reach when that is larger) grows
// the total by 4%.
double BakeJob::quantizationStep(int level) const
{
    const Trial* t = trialAt(level);
    const double achieved = t ? std::max(request.tolerance, t->rms) : request.tolerance;
    return request.tolerance > 0.0 ? achieved * rep.diagonal : 0.0;
}

// Stored per vertex, each value is measured against the capture along its
// own direction where that agrees with the map (within 2% of the diagonal:
// farther is another layer of a fold), then fitted; the closed loop keeps
// the best, and the quantisation step spends what the tolerance leaves.
Status BakeJob::refineStoredValues(const ControlMesh& mesh, int level, std::vector<float>* values, double* step)
{
    // The closed-loop RMS (the larger direction) of candidate values.
    auto loopRms = [&](const std::vector<float>& candidate, double* rms) {
        DisplacementField field;
        std::vector<LevelError> e;
        Status s = DisplacementField::create(&field, mesh, level, candidate);
        if (s)
            s = closedLoopError(&e, mesh, map, options.scheme, high, level, level, options.threads,
                                size_t(1) << 20, &field, &loopCapture());
        if (s)
            *rms = e[0].rms();
        return s;
    };
    std::vector<float> onCapture = *values;
    Status s = measureVertexDisplacements(&onCapture, mesh, options.scheme, level, highIndex,
                                          0.02 * rep.diagonal, options.threads, &stored.measured);
    // Kept only where the closed loop says so (a capture with
    // parts close together can mislead the rays).
    double rms[2] = {0.0, 0.0};
    if (!s || !(s = loopRms(*values, &rms[0])) || !(s = loopRms(onCapture, &rms[1])))
        return s;
    stored.rms = std::min(rms[0], rms[1]);
    if (rms[1] < rms[0]) {
        *values = std::move(onCapture);
        stored.how = "measured along their directions on the capture";
    } else {
        stored.measured = 0;
    }
    // Then fitted to the capture in both directions, from the
    // better of the two; kept where the closed loop says so.
    std::vector<float> fittedValues = *values;
    double fittedRms = 0.0;
    if (!(s = fitVertexDisplacements(&fittedValues, mesh, options.scheme, level, high, highIndex, 3,
                                     options.threads)) ||
        !(s = loopRms(fittedValues, &fittedRms)))
        return s;
    if (fittedRms < std::min(rms[0], rms[1])) {
        stored.rms = fittedRms;
        *values = std::move(fittedValues);
        stored.how = rms[1] < rms[0] ? "measured along their directions on the capture, then "
                                      "least-squares fitted to it"
                                    : "sampled from the map, then least-squares fitted to the capture";
    }
    // The values take the bits the tolerance needs.  Where they come well
    // within it, a coarser step spends the rest: a step q adds about
    // q / sqrt(12) RMS in quadrature, so the step that would bring the
    // total to 90% of the tolerance is tried, kept where the closed loop of
    // the quantised values stays within 95% of it (else halfway, else the
    // rule's).  Where they miss it (a cage too coarse for it), the step is
    // the coarsest of three that adds at most a tenth to their own error in
    // the closed loop: twice, 1.4 times and once the step that estimate
    // gives for 7% (it overestimates: on spot a step adding 5% by it added
    // 2%), else the rule's, which follows the map's trial at the level.
    stored.step = *step;
    const double goal = request.tolerance * rep.diagonal;
    const bool within = stored.rms < 0.9 * goal, missed = stored.rms > goal;
    if (request.tolerance > 0.0 && (within || missed)) {
        const double planned = within ? 0.9 * goal : 1.07 * stored.rms;
        const double allowed = within ? 0.95 * goal : 1.1 * stored.rms;
        const double spend = std::sqrt(12.0 * (planned * planned - stored.rms * stored.rms));
        std::vector<double> candidates;
        if (within)
            candidates = {spend, std::sqrt(spend * *step)};
        else
            candidates = {2.0 * spend, std::sqrt(2.0) * spend, spend};
        for (double candidate : candidates) {
            if (within && !(candidate > *step))
                break;
            // The values as the rig will decode them.
            std::vector<int32_t> q;
            float factor = 0.0f, offset = 0.0f;
            if (!(s = quantizeDisplacements(*values, candidate, &q, &factor, &offset)))
                return s;
            std::vector<float> decoded(q.size());
            for (size_t i = 0; i < q.size(); ++i)
                decoded[i] = shared::strata_decode_distance(float(q[i]), factor, offset);
            double quantizedRms = 0.0;
            if (!(s = loopRms(decoded, &quantizedRms)))
                return s;
            if (quantizedRms <= allowed) {
                *step = stored.step = candidate;
                break;
            }
        }
    }
    return Status::ok();
}

Status BakeJob::encodeAt(int level, std::string* bytes)
{
    rig.displacement.recommendedLevel = level;
    writeOptions.maxQuantizationStep = quantizationStep(level);
    notes.clear();
    // The writer encodes the control mesh first; the stored values are then
    // measured and fitted on the mesh as the file numbers it (its coding may
    // move and renumber the cage), and handed back to be coded.
    io::RigWriter writer;
    Status st = writer.begin(request.output, rig, &map, writeOptions, &notes);
    if (st && writer.needsVertexValues()) {
        std::vector<float> values = writer.sampledValues();
        double step = writer.quantizationStep();
        if ((st = refineStoredValues(writer.fileMesh(), writer.vertexLevel(), &values, &step)))
            st = writer.setVertexValues(values, step);
    }
    return st ? writer.commit(bytes) : st;
}

void BakeJob::settleLevel()
{
    if (!writeOptions.vertexDisplacements || forced || !(request.tolerance > 0.0) || stored.rms < 0.0)
        return;
    // The map's trials chose the level from values sampled from the
    // map; the stored ones are measured and fitted on the capture and
    // often come much closer.  So the level is settled on them: a
    // coarser one is written too while theirs still reach the
    // tolerance, a finer one while they miss it.  Finer goes up to the
    // capture's density, and on a cage the user gave one level past
    // it where they miss by more than 2x, kept there only where it
    // comes at least 10% closer (the level is the only knob left; an
    // automatic cage has its face count).
    const int finest = request.control != "auto" ? std::min(kMaxLevel, paperLevel + 1) : paperLevel;
    const double goal = request.tolerance * rep.diagonal;
    const int first = recommended;
    const double firstRms = stored.rms;
    // Encodes `level`; it replaces the chosen rig where keep(its RMS, the
    // chosen one's) says so.
    auto tryLevel = [&](int level, const std::function<bool(double, double)>& keep) {
        if (!trialAt(level)) {  // its map trial sets the quantisation step
            std::vector<LevelError> e;
            Progress p(progress, "measuring another level against --tolerance");
            Status st;
            if (!(st = closedLoopError(&e, control, map, options.scheme, high, level, level, options.threads,
                                       size_t(1) << 20, nullptr, &loopCapture())))
                throw BakeError(st.message());
            trials.push_back({map.width, level, e[0].rms() / rep.diagonal});
        }
        const Stored kept = stored;
        const std::vector<std::string> keptNotes = notes;
        std::string bytes;
        if (Status st = encodeAt(level, &bytes); !st)
            throw BakeError(namingOutput(st));
        if (keep(stored.rms, kept.rms)) {
            rigBytes_ = std::move(bytes);
            return true;
        }
        stored = kept;
        notes = keptNotes;
        rig.displacement.recommendedLevel = recommended;
        return false;
    };
    // A coarser level is only tried where its map samples come within
    // 3x of the tolerance (the stored values came 1.4-2.1x closer
    // than the map's on the real pairs).
    auto withinReach = [&](int level) {
        const Trial* t = trialAt(level);
        return !t || t->rms <= 3.0 * request.tolerance;
    };
    if (stored.rms <= goal) {
        while (recommended > 0 && withinReach(recommended - 1) &&
               tryLevel(recommended - 1, [&](double rms, double) { return rms <= goal; }))
            --recommended;
    } else {
        // Past the capture's density only where the tolerance is
        // missed by more than 2x: each level quadruples the values, and
        // a near miss is better served by the smaller rig.
        while (recommended < finest && stored.rms > goal &&
               (recommended + 1 <= paperLevel || stored.rms > 2.0 * goal) &&
               tryLevel(recommended + 1, [&](double rms, double was) {
                   return rms <= goal || (recommended + 1 <= paperLevel ? rms < was : rms < 0.9 * was);
               }))
            ++recommended;
    }
    char buf[200];
    if (recommended != first)
        std::snprintf(buf, sizeof(buf), "; the stored values %s at level %d (%.4g%%; level %d's %.4g%%)%s",
                      stored.rms <= goal ? "reach --tolerance" : "come closest", recommended,
                      100.0 * stored.rms / rep.diagonal, first, 100.0 * firstRms / rep.diagonal,
                      recommended > paperLevel ? ", one level finer than the capture's density" : "");
    else
        std::snprintf(buf, sizeof(buf), "; the stored values %s at level %d (%.4g%%)",
                      stored.rms <= goal ? "reach --tolerance" : "come closest", recommended,
                      100.0 * stored.rms / rep.diagonal);
    rep.sizeReason = sizeReason += buf;
}

// Runs `body` (a job's phases), the bake's failures turned into a Status.
template <typename F>
Status guarded(const BakeRequest& request, F&& body)
{
    try {
        body();
        return Status::ok();
    } catch (const BakeCancelled&) {
        return cancelledStatus(request);
    } catch (const BakeError& e) {
        return Status(StatusCode::InvalidArgument, e.what());
    } catch (const std::bad_alloc&) {
        return Status(StatusCode::InvalidData, "out of memory");
    }
}

// One bake, delivered.
Status bakeOnce(const BakeRequest& request, BakeResult* result, const BakeProgress* progress,
                SearchShared* shared = nullptr, FractionSpan* fraction = nullptr)
{
    *result = BakeResult();
    CancelScope scope(request.cancel);
    return guarded(request, [&] {
        BakeJob job(request, progress, shared, fraction);
        job.make();
        job.deliver(result);
    });
}

}  // namespace

// An automatic control mesh's face count follows from the tolerance: the
// smallest rig (in practice the fewest faces) whose bake reaches it in the
// closed loop, and for a character in every pose measured as well, or the
// most accurate tried when none does.  The first try is
// at a fiftieth of the capture's faces (at least 200); each next one is
// predicted where the error before quantisation, a power of the face count
// through the tries nearest the tolerance (until two tries give it, 1 going
// up and 2 going down), crosses the tolerance, with 10% to spare, between
// 200 and a fifth of the capture, 1,000 faces or half the capture up to
// 2,000, whichever is more (all of a capture smaller than 1,000: a
// low-polygon character's joints need nearly all its faces to bend like
// it; half of one under 4,000, where a fifth or 1,000 faces missed by a
// hair and the capture itself was twice the rig), and, going up, at most twice the
// faces until two tries measure the power.  A try that met two levels or more below the
// paper's level is nearly all cage: the next takes a quarter of its faces.
// The search stops when the answer is settled: the fewest that met and the
// most that missed are within 15% of each other, the prediction saves
// under 15% of the faces that met, fewer faces saved under 10% of the
// bytes, or, none met, even the steepest power
// allowed (3) puts it past 1.5 times the fifth (the tolerance is out of
// reach of a cage).  Where none met, the capture itself is the last try
// (its layer is nothing, so it meets any tolerance its coding keeps), and
// only if that fails too is the closest tried chosen.  Each try is a whole bake in
// memory; the tries share the capture as loaded, the scheme measured on a
// cage of about their face count (within 1.5x) and the map size of those
// that met.  The chosen try is delivered: written, summarised and
// reported.  Only a request for map images (--exr, --png8/16, --layers),
// whose atlas and fit differ, bakes the chosen count again.
Status bakeRig(const BakeRequest& request, BakeResult* result, const BakeProgress* progress,
               const BakeFraction* fraction)
{
    if (!result)
        return Status(StatusCode::InvalidArgument, "bakeRig: no result");
    if (!request.output.empty())
        if (Status checked = checkOutput(request); !checked)
            return checked;
    FractionSpan whole;
    whole.report = fraction;
    if (request.control != "auto" || request.controlFaces != 0 || !(request.tolerance > 0.0) ||
        request.high.empty() || request.output.empty())
        return bakeOnce(request, result, progress, nullptr, &whole);
    const auto searchStart = std::chrono::steady_clock::now();
    *result = BakeResult();
    CancelScope scope(request.cancel);
    // The map images change the bake (the atlas grows into its gaps, the
    // packer tries its orders): the tries bake without them.
    const bool reusable = !request.exr && !request.layers && request.pngBits == 0;
    struct Try {
        size_t faces;  // the cage's (the decimation may stop a face short of the count asked)
        size_t asked;
        double rms, bytes;
        double posed;  // a character's worst posed frame, RMS / diagonal (-1: not a character)
        double beforeQuantisation;  // the closed loop's RMS / diagonal at rest, before quantisation
        int level, paperLevel;  // the level the rig recommends; the paper's for its cage
        std::unique_ptr<BakeJob> job;  // the choice's bake, its inputs released (the others' are freed)
        std::string failure;           // why the try's bake failed (rms < 0), empty otherwise
        // What the face count buys: the error before quantisation, or the
        // posed one where larger.
        double shape() const { return std::max(beforeQuantisation, posed); }
    };
    std::vector<Try> tries;
    SearchShared shared;
    // At rest and, for a character, in every pose measured: the promise is
    // the tolerance in the poses it plays (CesiumMan's 1,113 faces met
    // 0.01% at rest and went 2.2x past it posed, its weights blended
    // linearly over fewer vertices than the capture's; 2,000 faces stay
    // within it posed for 10% more bytes).
    auto meets = [&](const Try& t) { return t.rms >= 0.0 && t.rms <= request.tolerance && t.posed <= request.tolerance; };
    auto fewestThatMet = [&]() -> Try* {
        Try* met = nullptr;
        for (Try& t : tries)
            if (meets(t) && (!met || t.faces < met->faces))
                met = &t;
        return met;
    };
    // The smallest rig that met the tolerance (ties: the fewer faces; a
    // cage near the capture's own density can need so little of a map that
    // more faces cost fewer bytes), else the smallest error (else, none
    // measured, the first try).
    auto choice = [&]() -> Try* {
        Try* chosen = nullptr;
        for (Try& t : tries)
            if (meets(t) &&
                (!chosen || t.bytes < chosen->bytes || (t.bytes == chosen->bytes && t.faces < chosen->faces)))
                chosen = &t;
        if (!chosen)
            for (Try& t : tries)
                if (t.rms >= 0.0 && (!chosen || std::max(t.rms, t.posed) < std::max(chosen->rms, chosen->posed)))
                    chosen = &t;
        return chosen ? chosen : &tries.front();
    };
    auto attempt = [&](size_t faces) {
        BakeRequest r = request;
        r.controlFaces = faces;
        r.exr = r.layers = false;
        r.pngBits = 0;
        const std::string stage = "baking onto an automatic cage of " + std::to_string(faces) + " faces";
        const auto t0 = std::chrono::steady_clock::now();
        if (progress && *progress)
            (*progress)(stage.c_str(), -1.0);
        // Progress counts on three tries (two more than the first; a
        // request for map images bakes the chosen count again), or one
        // more than made, until the search stops.
        const double expected = double(std::max<size_t>(3, tries.size() + 1)) + (reusable ? 0.0 : 1.0);
        FractionSpan part = whole;
        part.base = whole.last;
        part.span = (1.0 - whole.last) / (expected - double(tries.size()));
        auto job = std::make_unique<BakeJob>(r, nullptr, &shared, &part);
        const Status st = guarded(request, [&] { job->make(); });
        whole.last = part.last;
        if (progress && *progress)
            (*progress)(stage.c_str(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        if (!st) {
            // Listed in the summary with its reason (the first try's failure
            // is the bake's).
            if (st.code() != StatusCode::Cancelled && !tries.empty())
                tries.push_back({faces, faces, -1.0, 0.0, -1.0, -1.0, 0, 0, nullptr, st.message()});
            return st;
        }
        const double rms = job->rms(), posed = job->posedRms(), before = job->rmsBeforeQuantisation();
        job->reportTo(nullptr);  // `part` ends here
        job->releaseInputs();
        tries.push_back({job->cageFaces(), faces, rms, double(job->rigBytes()), posed, before,
                         job->recommendedLevel(), job->capturedLevel(), std::move(job), std::string()});
        if (meets(tries.back()))
            shared.sizeCap = std::max(shared.sizeCap, shared.mapSize);
        // Only the choice can be delivered, and a try that is not the
        // choice never becomes it (a later try can only take its place):
        // the others' bakes are freed now, and every one where the chosen
        // count is baked again with the map images.
        const Try* kept = reusable ? choice() : nullptr;
        for (Try& t : tries)
            if (&t != kept)
                t.job.reset();
        return st;
    };
    // The capture, loaded once for every try (its face count sets the first).
    if (!loadHighMesh(request.high, &shared.high, &shared.highStats, request.maxMemoryMB))
        return bakeOnce(request, result, progress, nullptr, &whole);  // it reports the problem
    const size_t faces = shared.high.faceCount();
    const size_t first = firstCageFaces(faces);
    const size_t most =
        std::max({first, faces / 5, std::min<size_t>(faces, 1000), std::min<size_t>(faces / 2, 2000)});
    if (Status st = attempt(first); !st)
        return st;  // the first try failed (or the bake was cancelled): its message is the bake's
    for (int more = 0; more < 5; ++more) {
        const Try* met = fewestThatMet();
        // The most faces that missed, below the fewest that met.
        const Try* missed = nullptr;
        for (const Try& t : tries)
            if (!meets(t) && (!met || t.faces < met->faces) &&
                (!missed || t.faces > missed->faces))
                missed = &t;
        if (met && missed && double(met->faces) <= 1.15 * double(missed->faces))
            break;
        // Fewer faces stopped paying: the fewest that met saved under 10%
        // of the bytes of the next fewest that met.  Below there the level
        // rises (the capture's density caps it), so the stored values do
        // not fall with the faces, and each try costs more (the 100k scan's
        // cages: 43.2 KB at 1,998 faces, 33.2 at 1,404, 31.4 at 748, and a
        // try of 439 faces took 34 s to miss).
        if (met) {
            const Try* next = nullptr;
            for (const Try& t : tries)
                if (meets(t) && t.faces > met->faces && (!next || t.faces < next->faces))
                    next = &t;
            if (next && met->bytes > 0.9 * next->bytes)
                break;
        }
        // The power through the tries nearest the tolerance: the fewest that
        // met and the most that missed; none missed, the two fewest that
        // met; none met, the two most faces.
        // Fitted to the errors before quantisation: a try that meets the
        // tolerance spends what it leaves on coarser steps (up to 90% of
        // it), which says nothing of what fewer faces would reach (at 0.2%
        // nefertiti's 1,400 faces came to 0.163% quantised, 0.068% before).
        const Try* finer = met;
        const Try* coarser = missed;
        if (!met) {
            finer = missed;
            coarser = nullptr;
            for (const Try& t : tries)
                if (t.faces < missed->faces && t.shape() > 0.0 && (!coarser || t.faces > coarser->faces))
                    coarser = &t;
        } else if (!missed) {
            coarser = met;
            finer = nullptr;
            for (const Try& t : tries)
                if (t.faces > met->faces && t.shape() > 0.0 && (!finer || t.faces < finer->faces))
                    finer = &t;
        }
        // Unmeasured, the power is 1 going up (from one miss a steeper one
        // undershoots, and each step up is capped) and 2 going down from a
        // try that met: the error falls faster than the face count rises
        // where the level is capped by the capture's density (the 100k
        // scan's fell as the power 2.2 from 1,011 faces to 1,998, and the
        // power 1 sent the second try to 1,011, a miss, and a third).
        double power = met && !missed ? 2.0 : 1.0;
        bool measured = false;
        if (finer && coarser && coarser->faces < finer->faces && coarser->shape() > finer->shape() &&
            finer->shape() > 0.0) {
            // Going down from two tries that met, at least 1: there the
            // error before quantisation is mostly the level's sampling of
            // the capture, nearly flat in the face count (the 100k scan's
            // cages of 1,998 and 1,404 faces measured 0.5), and a flat power
            // sends the next try to a quarter of the faces, a cage too
            // coarse to follow the capture (a 37 s try that missed).
            power = std::clamp(std::log(coarser->shape() / finer->shape()) /
                                   std::log(double(finer->faces) / double(coarser->faces)),
                               met && !missed ? 1.0 : 0.5, 3.0);
            measured = true;
        }
        const Try& anchor = met ? *met : *missed;
        size_t next = 0;
        double reach = 0.0;  // the fewest faces the tolerance may need, for the out-of-reach test
        if (anchor.shape() > 0.0) {
            const double predicted = double(anchor.faces) * std::pow(anchor.shape() / request.tolerance, 1.0 / power) * 1.1;
            next = size_t(std::lround(predicted));
            // By the steepest power allowed: the error is no power law
            // across a change of level or scheme (CesiumMan's fell 3.2x
            // from 400 faces to 800 after 1.26x from 200 to 400).
            reach = double(anchor.faces) * std::pow(anchor.shape() / request.tolerance, 1.0 / 3.0) * 1.1;
        } else {
            next = met ? met->faces / 2 : 2 * anchor.faces;  // no error to predict from
        }
        // A try that met two levels or more below the paper's is nearly all
        // cage: the tolerance is loose for it, and its error at that level
        // says nothing of what a smaller cage one level finer reaches.  A
        // quarter of the faces holds as many refined vertices one level up,
        // and a stored value costs a byte or two where a cage vertex costs
        // twelve (the 100k scan at 0.1%: 1,998 faces at level 0, 27.6 KB).
        const bool cageBound = met && !missed && met->level + 2 <= met->paperLevel && met->faces / 4 >= 200;
        if (cageBound)
            next = met->faces / 4;
        if (met) {
            if (!cageBound && double(next) > 0.85 * double(met->faces))
                break;  // settled: the saving would be small
            next = std::max<size_t>(next, std::max<size_t>(200, met->faces / 4));
            if (missed && next <= missed->faces)
                next = size_t(std::lround(std::sqrt(double(met->faces) * double(missed->faces))));
            if (next >= met->faces || (missed && next <= missed->faces))
                break;
        } else {
            // The most faces tried, or a tolerance out of reach of them by
            // the prediction: the closest tried is chosen.
            if (anchor.asked >= most || reach > 1.5 * double(most))
                break;
            // Up at most 2x until two tries measure the power (from one
            // miss the power 1 overshot the penguin's count 8x), 4x after.
            const size_t step = (measured ? 4 : 2) * anchor.faces;
            next = std::clamp<size_t>(next, size_t(1.15 * double(anchor.faces)), std::min(most, step));
        }
        // A count asked before would bake the same cage again.
        if (std::any_of(tries.begin(), tries.end(), [&](const Try& t) { return t.asked == next; }))
            break;
        if (Status tried = attempt(next); tried.code() == StatusCode::Cancelled)
            return tried;
        else if (!tried)
            break;  // a failed extra try leaves the choice to the others
    }
    // No cage up to the cap met the tolerance: the capture itself, whose
    // layer is nothing, is the last cage that adds faces (spot's fifth, 1,171
    // faces, stops at 0.018%, the level held at the capture's density).
    if (!fewestThatMet() &&
        std::none_of(tries.begin(), tries.end(), [&](const Try& t) { return t.asked >= faces; }))
        if (Status tried = attempt(faces); tried.code() == StatusCode::Cancelled)
            return tried;
    Try* chosen = choice();
    // The search's wall time (outside the delivered bake, for its time line).
    const double searchMs = msSince(searchStart);
    // The search's lines for the summary and the report.
    char took[160];
    std::snprintf(took, sizeof(took), "%zu tr%s in %.1f s%s", tries.size(), tries.size() == 1 ? "y" : "ies",
                  searchMs / 1000.0,
                  reusable ? ", the chosen one delivered" : ", then the chosen count baked again with the map images");
    const bool posedTries = std::any_of(tries.begin(), tries.end(), [](const Try& t) { return t.posed >= 0.0; });
    std::string note = "  cage faces    from the tolerance, " + std::string(took) +
                       (posedTries ? " (closed-loop RMS / diagonal at rest, posed at worst, rig bytes):"
                                   : " (closed-loop RMS / diagonal, rig bytes):");
    nlohmann::json searchReport = nlohmann::json::array();
    for (const Try& t : tries) {
        appendf(&note, "\n                  %zu%s: ", t.faces, t.asked >= faces ? " (the capture itself)" : "");
        if (t.rms >= 0.0 && t.posed >= 0.0)
            appendf(&note, "%.4f%%, %.4f%%, %.1f KB%s", 100.0 * t.rms, 100.0 * t.posed, t.bytes / 1024.0,
                    &t == chosen ? "  <- chosen" : "");
        else if (t.rms >= 0.0)
            appendf(&note, "%.4f%%, %.1f KB%s", 100.0 * t.rms, t.bytes / 1024.0, &t == chosen ? "  <- chosen" : "");
        else if (!t.failure.empty())
            note += "failed: " + t.failure;
        else
            note += "not measured";
        searchReport.push_back({{"faces", t.faces},
                                {"asked", t.asked},
                                {"rms", t.rms},
                                {"rmsBeforeQuantisation", t.beforeQuantisation},
                                {"posedRms", t.posed},
                                {"bytes", t.bytes},
                                {"chosen", &t == chosen},
                                {"failure", t.failure}});
    }
    note += "\n";
    if (reusable)
        return guarded(request, [&] {
            chosen->job->deliver(result, note, searchReport, searchMs - chosen->job->wallMs());
            whole.at(1.0);
        });
    BakeRequest r = request;
    r.controlFaces = chosen->asked;
    FractionSpan last = whole;
    last.base = whole.last;
    last.span = 1.0 - whole.last;
    return guarded(request, [&] {
        BakeJob job(r, progress, &shared, &last);
        job.make();
        job.deliver(result, note, searchReport, searchMs);
        whole.at(1.0);
    });
}

}  // namespace baker
}  // namespace strata
