// strata-demo: the built-in example, end to end, with no input files.
//
// Generates the paper's demo: a detailed head-like "captured" mesh and an
// icosahedron control mesh.  Bakes the displacement map with the baker
// (normal-volume mapping, forward rasterisation), writes the control rig and
// map, reloads them as an engine would, reconstructs every level with the
// runtime and reports the error against the closed-form surface.  Everything
// lands in one output folder.
#include "cli.h"

#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/baker/bake.h"
#include "strata/io/mesh_io.h"
#include "strata/io/exr.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"

#include <glm/geometric.hpp>

#include <chrono>
#include <cmath>
#include <sys/stat.h>

using namespace strata;

namespace {

double msSince(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void makeDirectory(const std::string& dir)
{
    std::string partial;
    for (size_t i = 0; i <= dir.size(); ++i) {
        if (i == dir.size() || dir[i] == '/') {
            if (!partial.empty() && ::mkdir(partial.c_str(), 0755) != 0 && errno != EEXIST)
                throw cli::Error(partial + ": cannot create directory");
        }
        if (i < dir.size())
            partial += dir[i];
    }
}

}  // namespace

int main(int argc, char** argv)
{
    return cli::run("strata-demo", [&]() -> int {
        std::string outDir = "strata-out";
        int maxLevel = 5, mapSize = 1024;
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto value = [&] { return cli::flagValue(argc, argv, &i); };
            if (a == "--out" || a == "-o")
                outDir = value();
            else if (a == "--max-level")
                maxLevel = cli::parseInt(a, value(), 0, kMaxLevel);
            else if (a == "--size")
                mapSize = cli::parseInt(a, value(), 64, 8192);
            else if (a == "-h" || a == "--help") {
                std::puts("usage: strata-demo [--out DIR] [--max-level N] [--size MAP_SIZE] [--version]");
                return 0;
            } else if (a == "--version") {
                std::printf("strata-demo %s\n", cli::kVersion);
                return 0;
            } else
                throw cli::Error("unknown option " + a);
        }
        makeDirectory(outDir);

        auto t0 = std::chrono::steady_clock::now();
        // The "capture": the head surface sampled by an 81920-triangle mesh.
        const ControlMesh capture = examples::makeHead(6);
        baker::TriangleMesh high;
        high.positions = capture.positions;
        high.triangles = capture.triangles;
        io::MeshView highView;
        highView.positions = high.positions.data();
        highView.vertexCount = high.positions.size();
        highView.triangles = high.triangles.data();
        highView.faceCount = high.faceCount();
        Status st = io::writeMesh(outDir + "/head_highres.ply", highView);
        if (!st)
            throw cli::Error(st.message());

        Rig rig;
        rig.mesh = examples::makeIcosphere(1);
        baker::AtlasOptions atlas;
        atlas.mapSize = mapSize;
        atlas.gutter = 2;
        if (!(st = baker::buildTriangleAtlas(&rig.mesh, atlas)))
            throw cli::Error(st.message());
        DisplacementMap map;
        baker::BakeOptions options;
        options.size = mapSize;
        baker::BakeReport report;
        if (!(st = baker::bake(&map, nullptr, &report, rig.mesh, high, options)))
            throw cli::Error(st.message());
        const double bakeMs = msSince(t0);
        rig.hasDisplacement = true;
        rig.displacement.scheme = Scheme::Linear;
        rig.displacement.recommendedLevel = std::min(maxLevel, 5);  // the per-vertex samples are stored at this level
        // One self-contained, compact rig (the map stored as 16-bit samples
        // at the refined vertices of that level, the mesh meshopt-coded), and the
        // same map as EXR beside it for pipelines.
        const std::string rigPath = outDir + "/head.glb";
        io::RigWriteOptions writeOptions;
        writeOptions.compress = true;
        writeOptions.vertexDisplacements = true;
        if (!(st = io::writeDisplacementExr(outDir + "/head.exr", map)) ||
            !(st = io::saveRig(rigPath, rig, &map, nullptr, &writeOptions)))
            throw cli::Error(st.message());
        std::printf("built-in example: a %zu-triangle head-like capture baked onto a %zu-triangle icosahedron control "
                    "mesh, %dx%d map in %.0f ms (%zu border triangles, %zu vertices outside every normal volume)\n",
                    high.faceCount(), rig.mesh.faceCount(), map.width, map.height, bakeMs,
                    report.raster.borderTriangles, report.fallbackVertices);

        // Reload through the public loaders, exactly as an engine would.
        Rig loaded;
        DisplacementMap loadedMap;
        if (!(st = io::loadRig(rigPath, &loaded)) ||
            (rigNeedsMap(loaded) && !(st = io::loadRigDisplacementMap(rigPath, loaded, &loadedMap))))
            throw cli::Error(st.message());

        std::printf("\n level | vertices | triangles | reconstruct ms | radial RMS / diag | radial max / diag\n");
        std::printf("-------+----------+-----------+----------------+-------------------+------------------\n");
        const double diag = 2.0 * std::sqrt(3.0) * 1.2;  // the head fits in a 2.4-unit cube
        for (int level = 0; level <= maxLevel; ++level) {
            t0 = std::chrono::steady_clock::now();
            io::Reconstruction rec;
            if (!(st = io::reconstruct(&rec, loaded, &loadedMap, Scheme::Linear, level)))
                throw cli::Error(st.message());
            const double ms = msSince(t0);
            double sum = 0.0, worst = 0.0;
            for (const glm::vec3& x : rec.positions) {
                const float len = glm::length(x);
                const double e = std::fabs(double(len) - double(examples::headRadius(x / len)));
                sum += e * e;
                worst = std::max(worst, e);
            }
            const std::string meshPath = outDir + "/head_level" + std::to_string(level) + ".ply";
            if (!(st = io::writeReconstruction(meshPath, rec)))
                throw cli::Error(st.message());
            if (level == rig.displacement.recommendedLevel &&
                !(st = io::writeReconstruction(outDir + "/head_level" + std::to_string(level) + ".glb", rec)))
                throw cli::Error(st.message());
            std::printf(" %5d | %8zu | %9zu | %14.1f | %17.2e | %16.2e\n", level, rec.positions.size(),
                        rec.plan().refinedFaceCount(), ms, std::sqrt(sum / double(rec.positions.size())) / diag,
                        worst / diag);
        }
        std::printf("\nwrote %s/: head_highres.ply (the capture), head.glb (control rig), head.exr (displacement "
                    "map), head_level0..%d.ply, head_level%d.glb (the recommended level)\n",
                    outDir.c_str(), maxLevel, rig.displacement.recommendedLevel);
        return 0;
    });
}
