// bench_bake: bake time per stage and peak memory (baker issue).
//
// Rows: each real pair in ../shared/data (when present) and a generated
// 1.3M-triangle detailed sphere (icosphere level 8 with the built-in head
// relief) onto a 5120-triangle control mesh at 2048^2.  Each case runs in a
// child process so its peak resident memory is its own.  Threads: 1 and 2.
#include "bench_common.h"

#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/baker/bake.h"
#include "strata/baker/mesh_input.h"
#include "strata/io/exr.h"
#include "strata/io/mesh_io.h"

#include <glm/geometric.hpp>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <cmath>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

using namespace strata;

namespace {

// Where a child bake leaves its total for the parent's --json row.
std::string totalFile(pid_t pid)
{
    return "/tmp/strata_bench_bake_total_" + std::to_string(pid) + ".txt";
}

bench::JsonRows jsonRows;

struct Case {
    std::string name, high, control;  // empty paths: generated
    bool uvAuto;
};

int runCase(const Case& c, int threads, int size)
{
    const double t0 = bench::nowMs();
    baker::TriangleMesh high;
    ControlMesh control;
    if (c.control.empty()) {
        if (!baker::loadHighMesh(c.high, &high, nullptr).isOk())
            return 1;
        control = examples::makeIcosphere(4);
    } else {
        if (!baker::loadHighMesh(c.high, &high, nullptr).isOk() || !baker::loadControlMesh(c.control, &control).isOk())
            return 1;
    }
    const double loadMs = bench::nowMs() - t0;
    if (c.uvAuto || !control.hasUVs()) {
        baker::AtlasOptions atlas;
        atlas.mapSize = size;
        if (!baker::buildTriangleAtlas(&control, atlas).isOk())
            return 1;
    } else {
        baker::fitUVsToUnitSquare(&control, nullptr);
    }
    baker::BakeOptions options;
    options.size = size;
    options.threads = threads;
    DisplacementMap map;
    baker::BakeReport report;
    const Status st = baker::bake(&map, nullptr, &report, control, high, options);
    if (!st) {
        std::fprintf(stderr, "%s: %s\n", c.name.c_str(), st.message().c_str());
        return 1;
    }
    const double w0 = bench::nowMs();
    const std::string tmp = "/tmp/strata_bench_bake_" + std::to_string(::getpid()) + ".exr";
    if (!io::writeDisplacementExr(tmp, map, io::ExrPixelType::Half, threads).isOk())
        return 1;
    const double writeMs = bench::nowMs() - w0;
    std::remove(tmp.c_str());
    const double total = loadMs + report.times.mapping + report.times.rasterize + report.times.dilate + writeMs;
    if (FILE* f = std::fopen(totalFile(getpid()).c_str(), "w")) {  // for the parent's --json row
        std::fprintf(f, "%.3f\n", total);
        std::fclose(f);
    }
    std::printf("%-22s | %9zu | %7zu | %5d | %7d | %8.0f | %8.0f | %8.0f | %8.0f | %7.0f | %8.0f |", c.name.c_str(),
                report.highTriangles, report.controlTriangles, map.width, threads, loadMs, report.times.mapping,
                report.times.rasterize, report.times.dilate, writeMs, total);
    std::fflush(stdout);
    return 0;
}

// A 100k-triangle "scan": a latitude-longitude sphere (224 x 224 quads, two
// triangles each) carrying the built-in head relief.
ControlMesh makeScan100k()
{
    const int n = 224;
    ControlMesh m;
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j < n; ++j) {
            const float th = 3.14159265f * float(i) / float(n), ph = 6.2831853f * float(j) / float(n);
            glm::vec3 p(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
            m.positions.push_back(p * examples::headRadius(p));
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const uint32_t a = uint32_t(i * n + j), b = uint32_t(i * n + (j + 1) % n), c = a + uint32_t(n),
                           d = b + uint32_t(n);
            if (i > 0)
                m.triangles.insert(m.triangles.end(), {a, b, c});
            if (i + 1 < n)
                m.triangles.insert(m.triangles.end(), {b, d, c});
        }
    return m;
}

// The default command-line bake (closed loop included), timed as a child
// process: wall time and peak resident memory.
void runDefaultCliBake(const std::string& high, const std::string& control)
{
    const std::string out = "/tmp/strata_bench_default_" + std::to_string(::getpid()) + ".glb";
    const double t0 = bench::nowMs();
    const pid_t pid = fork();
    if (pid == 0) {
        const int null = ::open("/dev/null", O_WRONLY);
        ::dup2(null, 1);
        ::dup2(null, 2);
        execl(STRATA_BAKE_EXE, STRATA_BAKE_EXE, "--high", high.c_str(), "--control", control.c_str(), "-o", out.c_str(),
              static_cast<char*>(nullptr));
        _exit(127);
    }
    int status = 0;
    struct rusage usage;
    wait4(pid, &status, 0, &usage);
    const double ms = bench::nowMs() - t0;
    struct stat st;
    const double kb = ::stat(out.c_str(), &st) == 0 ? double(st.st_size) / 1024.0 : 0.0;
    std::remove(out.c_str());
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        std::printf("default CLI bake 100k / 10k: failed\n");
        return;
    }
    std::printf("default CLI bake (strata-bake --high scan --control remesh -o rig.glb, closed loop included)\n");
    std::printf("case                         | total ms | peak MB | rig KB | target\n");
    std::printf("scan 100k / remesh 10k       | %8.0f | %7.0f | %6.0f | < 10000 ms, < 1024 MB\n", ms,
                double(usage.ru_maxrss) / 1024.0, kb);
    jsonRows.field("case", "default CLI bake, scan 100k / remesh 10k")
        .field("threads", double(std::thread::hardware_concurrency()))
        .field("total_ms", ms)
        .field("peak_mb", double(usage.ru_maxrss) / 1024.0)
        .field("rig_kb", kb)
        .endRow();
}

}  // namespace

int main(int argc, char** argv)
{
    const std::string data = STRATA_SHARED_DATA;
    bool onlyGenerated = false;
    std::string jsonPath, onlyCase;
    int onlyThreads = 0;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--generated-only")) {
            onlyGenerated = true;
        } else if (!std::strcmp(argv[i], "--json") && i + 1 < argc) {
            jsonPath = argv[++i];
        } else if (!std::strcmp(argv[i], "--case") && i + 1 < argc) {
            onlyCase = argv[++i];  // a substring of the case names; skips the default CLI bake (for profiling)
        } else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) {
            onlyThreads = std::atoi(argv[++i]);
        } else {
            std::fprintf(stderr, "usage: bench_bake [--generated-only] [--case NAME] [--threads N] [--json FILE]\n");
            return 2;
        }
    }
    std::vector<Case> cases;
    struct stat st;
    if (!onlyGenerated && ::stat((data + "/spot_triangulated.obj").c_str(), &st) == 0) {
        cases.push_back({"spot", data + "/spot_triangulated.obj", data + "/spot_control_mesh.obj", true});
        cases.push_back({"penguin", data + "/penguin_hr.obj", data + "/penguin_control_mesh.obj", false});
        cases.push_back({"hand", data + "/hand_closed.obj", data + "/hand_lowres.obj", false});
    }
    // The generated scans are written once as binary PLY and loaded like real
    // ones; two sizes (4x apart in triangles and texels) show the scaling.
    const std::string generated = "/tmp/strata_bench_generated_1m.ply";
    const std::string quarter = "/tmp/strata_bench_generated_330k.ply";
    for (int level : {7, 8}) {
        ControlMesh sphere = examples::makeIcosphere(level);
        for (glm::vec3& p : sphere.positions)
            p *= examples::headRadius(p);
        io::MeshView view;
        view.positions = sphere.positions.data();
        view.vertexCount = sphere.positions.size();
        view.triangles = sphere.triangles.data();
        view.faceCount = sphere.faceCount();
        if (!io::writeMesh(level == 8 ? generated : quarter, view).isOk())
            return 1;
    }
    cases.push_back({"generated 330k / 5120", quarter, "", true});
    cases.push_back({"generated 1.3M / 5120", generated, "", true});
    std::printf("bench_bake: linear scheme; ms per stage (dilation includes hole filling); peak RSS per child process\n");
    std::printf("case                   | high tris | control |  map  | threads |  load ms | mapping  |  raster  | "
                "dilation | write  | total ms | peak MB\n");
    std::printf("-----------------------+-----------+---------+-------+---------+----------+----------+----------+--"
                "--------+--------+----------+--------\n");
    for (const Case& c : cases)
        for (int threads : {1, 2}) {
            if ((!onlyCase.empty() && c.name.find(onlyCase) == std::string::npos) ||
                (onlyThreads > 0 && threads != onlyThreads))
                continue;
            const int size = c.name.find("1.3M") != std::string::npos ? 2048 : 1024;
            std::fflush(stdout);
            const pid_t pid = fork();
            if (pid == 0)
                _exit(runCase(c, threads, size));
            int status = 0;
            struct rusage usage;
            wait4(pid, &status, 0, &usage);
            if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
                std::printf(" %6.0f\n", double(usage.ru_maxrss) / 1024.0);
                double total = std::nan("");
                if (FILE* f = std::fopen(totalFile(pid).c_str(), "r")) {
                    if (std::fscanf(f, "%lf", &total) != 1)
                        total = std::nan("");
                    std::fclose(f);
                }
                std::remove(totalFile(pid).c_str());
                jsonRows.field("case", c.name)
                    .field("threads", threads)
                    .field("total_ms", total)
                    .field("peak_mb", double(usage.ru_maxrss) / 1024.0)
                    .endRow();
            } else
                std::printf(" %s failed\n", c.name.c_str());
            std::fflush(stdout);
        }
    if (!std::getenv("STRATA_BENCH_KEEP")) {
        std::remove(generated.c_str());
        std::remove(quarter.c_str());
    }
    if (!onlyCase.empty())
        return jsonPath.empty() || jsonRows.write(jsonPath) ? 0 : 1;

    // The scan and its 10k remesh, written once; the remesh is made here by
    // quadric decimation (as --control auto would) outside the timing.
    const std::string scanPath = "/tmp/strata_bench_scan_100k.ply", remeshPath = "/tmp/strata_bench_remesh_10k.obj";
    const ControlMesh scan = makeScan100k();
    baker::TriangleMesh scanMesh;
    scanMesh.positions = scan.positions;
    scanMesh.triangles = scan.triangles;
    ControlMesh remesh;
    if (!baker::decimateToControlMesh(scanMesh, 10000, &remesh).isOk())
        return 1;
    for (const auto& [path, mesh] : {std::make_pair(scanPath, &scan), std::make_pair(remeshPath, static_cast<const ControlMesh*>(&remesh))}) {
        io::MeshView view;
        view.positions = mesh->positions.data();
        view.vertexCount = mesh->positions.size();
        view.triangles = mesh->triangles.data();
        view.faceCount = mesh->faceCount();
        if (!io::writeMesh(path, view).isOk())
            return 1;
    }
    std::printf("\nscan: %zu triangles; remesh: %zu triangles\n", scan.faceCount(), remesh.faceCount());
    runDefaultCliBake(scanPath, remeshPath);
    if (!std::getenv("STRATA_BENCH_KEEP")) {
        std::remove(scanPath.c_str());
        std::remove(remeshPath.c_str());
    }
    if (!jsonPath.empty() && !jsonRows.write(jsonPath)) {
        std::fprintf(stderr, "bench_bake: cannot write %s\n", jsonPath.c_str());
        return 1;
    }
    return 0;
}
