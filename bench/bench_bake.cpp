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
#include <cstring>
#include <string>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

using namespace strata;

namespace {

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
    if (!io::writeDisplacementExr(tmp, map).isOk())
        return 1;
    const double writeMs = bench::nowMs() - w0;
    std::remove(tmp.c_str());
    const double total = loadMs + report.times.mapping + report.times.rasterize + report.times.dilate + writeMs;
    std::printf("%-22s | %9zu | %7zu | %5d | %7d | %8.0f | %8.0f | %8.0f | %8.0f | %7.0f | %8.0f |", c.name.c_str(),
                report.highTriangles, report.controlTriangles, map.width, threads, loadMs, report.times.mapping,
                report.times.rasterize, report.times.dilate, writeMs, total);
    std::fflush(stdout);
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    const std::string data = STRATA_SHARED_DATA;
    bool onlyGenerated = argc > 1 && std::strcmp(argv[1], "--generated-only") == 0;
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
            const int size = c.name.find("1.3M") != std::string::npos ? 2048 : 1024;
            std::fflush(stdout);
            const pid_t pid = fork();
            if (pid == 0)
                _exit(runCase(c, threads, size));
            int status = 0;
            struct rusage usage;
            wait4(pid, &status, 0, &usage);
            if (WIFEXITED(status) && WEXITSTATUS(status) == 0)
                std::printf(" %6.0f\n", double(usage.ru_maxrss) / 1024.0);
            else
                std::printf(" %s failed\n", c.name.c_str());
            std::fflush(stdout);
        }
    std::remove(generated.c_str());
    std::remove(quarter.c_str());
    return 0;
}
