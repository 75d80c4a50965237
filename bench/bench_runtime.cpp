// bench_runtime: refinement + reconstruction cost per level (runtime-core issue).
//
// For a ~2k-triangle control mesh (a cube with 13x13 quads per side, 2028
// triangles) and for spot (../shared/data, when present), per level 0..6:
// refined vertices, one-time setup, per-evaluate time (positions, directions
// and displacement), million displaced vertices per second, shading-normal
// pass, table memory, and OpenSubdiv's own Osd::CpuEvaluator::EvalStencils on
// positions alone over the same stencil table, all on one core.
#include "bench_common.h"

#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/io/mesh_io.h"
#include "strata/frame.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "strata/baker/bake_rig.h"
#include "strata/io/rig_io.h"
#include "strata/surface.h"

#include <opensubdiv/osd/bufferDescriptor.h>
#include <opensubdiv/osd/cpuEvaluator.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <algorithm>
#include <filesystem>
#include <functional>
#include <sys/stat.h>
#include <unistd.h>

using namespace strata;

namespace {

// A cube [-1,1]^3 with n x n quads per side, each split into two triangles.
ControlMesh makeCube(int n)
{
    ControlMesh m;
    auto vertex = [&](glm::vec3 p) {
        for (size_t i = 0; i < m.positions.size(); ++i)
            if (m.positions[i] == p)
                return uint32_t(i);
        m.positions.push_back(p);
        return uint32_t(m.positions.size() - 1);
    };
    for (int axis = 0; axis < 3; ++axis)
        for (int sign = -1; sign <= 1; sign += 2) {
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    uint32_t q[4];
                    const int di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
                    for (int k = 0; k < 4; ++k) {
                        glm::vec3 p;
                        p[axis] = float(sign);
                        p[u] = -1.0f + 2.0f * float(i + di[k]) / float(n);
                        p[v] = -1.0f + 2.0f * float(j + dj[k]) / float(n);
                        q[k] = vertex(p);
                    }
                    if (sign > 0)
                        m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
                    else
                        m.triangles.insert(m.triangles.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
                }
        }
    return m;
}

bench::JsonRows jsonRows;

void runTable(const char* name, ControlMesh mesh, int maxLevel, Scheme scheme, int threads)
{
    if (!mesh.hasUVs() && !baker::buildTriangleAtlas(&mesh, {2048, 2}).isOk()) {
        std::printf("%s: atlas failed\n", name);
        return;
    }
    DisplacementMap map;
    map.width = map.height = 1024;
    map.texels.resize(size_t(1024) * 1024);
    for (size_t i = 0; i < map.texels.size(); ++i)
        map.texels[i] = 0.01f * std::sin(float(i % 1024) * 0.05f) * std::cos(float(i / 1024) * 0.07f);

    std::vector<glm::vec3> normals(mesh.positions.size());
    computeControlNormals(normals.data(), mesh.positions.data(), normals.size(), mesh.triangles.data(),
                          mesh.faceCount());
    std::printf("\n%s, %zu control triangles, scheme %s, one core\n", name, mesh.faceCount(), schemeName(scheme));
    std::printf("level | refined verts | setup ms, UVs / none | evaluate ms | M verts/s | shading normals ms | tables MB |"
                " Osd EvalStencils ms (xyz) | evaluate / Osd | frame ms, plan order | frame ms, tile order, 1 / %d"
                " threads | frame M verts/s | speed-up\n", threads);
    std::printf("------+---------------+----------------------+-------------+-----------+--------------------+-----------+"
                "---------------------------+----------------+---------------------+------------------------------"
                "----+-----------------+---------\n");
    for (int level = 0; level <= maxLevel; ++level) {
        // Setup (plan + sampling the map) three times: the median, and the
        // first, which also pays for the process's first touch of the memory.
        std::unique_ptr<Plan> plan;
        Status st;
        std::vector<double> setups;
        for (int run = 0; run < 3 && (run == 0 || st); ++run) {
            plan.reset();
            const double t0 = bench::nowMs();
            st = Plan::create(&plan, mesh, scheme, level);
            if (st)
                st = plan->setDisplacement(map);
            setups.push_back(bench::nowMs() - t0);
        }
        if (!st) {
            std::printf("%5d | error: %s\n", level, st.message().c_str());
            continue;
        }
        const double setupFirst = setups[0], setup = bench::median(setups);
        // The default rig's case: no UVs (its displacements are per vertex).
        double setupNoUVs = 0.0, bytesNoUVs = 0.0;
        {
            ControlMesh bare = mesh;
            bare.uvs.clear();
            bare.uvIndices.clear();
            std::vector<double> lean;
            for (int run = 0; run < 3; ++run) {
                const double u0 = bench::nowMs();
                std::unique_ptr<Plan> p;
                if (!Plan::create(&p, bare, scheme, level).isOk())
                    break;
                lean.push_back(bench::nowMs() - u0);
                bytesNoUVs = double(p->memoryBytes()) / double(p->refinedVertexCount());
            }
            setupNoUVs = bench::median(lean);
        }
        const size_t n = plan->refinedVertexCount();
        std::vector<glm::vec3> out(n), dir(n), shading(n);
        const double eval = bench::medianMs([&] {
            plan->evaluate(out.data(), dir.data(), 0, n, mesh.positions.data(), normals.data(), mesh.positions.size());
        });
        const double shade = bench::medianMs([&] { plan->computeShadingNormals(shading.data(), out.data()); });
        // The render-ready frame (positions + shading normals) through
        // FrameEvaluator: in the plan's vertex order on one thread, and in
        // tile order (what an engine draws: FrameEvaluator::triangles()) on
        // one thread and on `threads`.  Tables built before timing.
        FrameEvaluator planFrame(*plan), frame(*plan, FrameLayout::Tiles);
        planFrame.evaluate(out.data(), shading.data(), nullptr, mesh.positions.data(), normals.data(),
                           mesh.positions.size(), 1);
        const double frameSetup0 = bench::nowMs();
        frame.evaluate(out.data(), shading.data(), nullptr, mesh.positions.data(), normals.data(),
                       mesh.positions.size(), 1);
        const double frameSetup = bench::nowMs() - frameSetup0;  // its tables and one frame
        const double framePlan = bench::medianMs([&] {
            planFrame.evaluate(out.data(), shading.data(), nullptr, mesh.positions.data(), normals.data(),
                               mesh.positions.size(), 1);
        });
        const double frame1 = bench::medianMs([&] {
            frame.evaluate(out.data(), shading.data(), nullptr, mesh.positions.data(), normals.data(),
                           mesh.positions.size(), 1);
        });
        const double frameN = bench::medianMs([&] {
            frame.evaluate(out.data(), shading.data(), nullptr, mesh.positions.data(), normals.data(),
                           mesh.positions.size(), threads);
        });
        std::string osd = "-", ratio = "-";
        double osdMs = std::nan("");
        if (scheme == Scheme::Linear) {
            // OpenSubdiv's own CSR evaluator on the same stencils, zero weights dropped.
            Plan::FlatStencils flat;
            plan->flattenStencils(&flat);
            struct {
                std::vector<int> sizes, offsets, indices;
                std::vector<float> weights;
            } s;
            for (size_t v = 0; v < n; ++v) {
                s.offsets.push_back(int(s.indices.size()));
                for (uint32_t k = flat.offsets[v]; k < flat.offsets[v + 1]; ++k)
                    if (flat.weights[k] != 0.0f) {
                        s.indices.push_back(int(flat.indices[k]));
                        s.weights.push_back(flat.weights[k]);
                    }
                s.sizes.push_back(int(s.indices.size()) - s.offsets.back());
            }
            using OpenSubdiv::Osd::BufferDescriptor;
            const BufferDescriptor desc(0, 3, 3);
            const double t = bench::medianMs([&] {
                OpenSubdiv::Osd::CpuEvaluator::EvalStencils(&mesh.positions[0].x, desc, &out[0].x, desc, s.sizes.data(),
                                                             s.offsets.data(), s.indices.data(), s.weights.data(), 0,
                                                             int(n));
            });
            char buf[64];
            std::snprintf(buf, sizeof(buf), "%.3f", t);
            osd = buf;
            osdMs = t;
            std::snprintf(buf, sizeof(buf), "%.2fx", eval / t);
            ratio = buf;
        }
        std::printf("%5d | %13zu | %9.1f / %8.1f | %11.3f | %9.1f | %18.3f | %9.1f | %25s | %14s | %19.3f | %16.3f / %13.3f |"
                    " %15.1f | %7.2fx\n",
                    level, n, setup, setupNoUVs, eval, double(n) / eval / 1000.0, shade, double(plan->memoryBytes()) / 1048576.0,
                    osd.c_str(), ratio.c_str(), framePlan, frame1, frameN, double(n) / frame1 / 1000.0,
                    frame1 / frameN);
        jsonRows.field("scheme", schemeName(scheme))
            .field("mesh", name)
            .field("level", level)
            .field("vertices", double(n))
            .field("evaluate_ms", eval)
            .field("normals_ms", shade)
            .field("frame_mverts_per_s", double(n) / frame1 / 1000.0)
            .field("frame_ms_plan_order", framePlan)
            .field("frame_setup_ms", frameSetup)
            .field("frame_table_bytes_per_vertex", double(frame.bytes()) / double(n))
            .field("setup_ms", setup)
            .field("setup_first_ms", setupFirst)
            .field("table_bytes_per_vertex", double(plan->memoryBytes()) / double(n))
            .field("setup_no_uvs_ms", setupNoUVs)
            .field("table_bytes_per_vertex_no_uvs", bytesNoUVs)
            .field("osd_ms", osdMs)
            .field("threads", threads)
            .field("frame_ms_1_thread", frame1)
            .field("frame_ms_threads", frameN)
            .field("thread_speedup", frame1 / frameN)
            .endRow();
        std::fflush(stdout);
    }
}

// Medians of interleaved timed runs of several bodies (each run repeats its
// body for at least 10 ms): one body after another, 15 rounds.
void interleavedMs(const std::vector<std::function<void()>>& bodies, const std::vector<double*>& out)
{
    std::vector<std::vector<double>> per(bodies.size());
    for (const auto& b : bodies)
        b();
    for (int round = 0; round < 15; ++round)
        for (size_t k = 0; k < bodies.size(); ++k) {
            int calls = 0;
            const double t0 = bench::nowMs();
            double t = t0;
            do {
                bodies[k]();
                ++calls;
                t = bench::nowMs();
            } while (t - t0 < 10.0);
            per[k].push_back((t - t0) / calls);
        }
    for (size_t k = 0; k < bodies.size(); ++k)
        *out[k] = bench::median(per[k]);
}

// Adaptive against uniform level of detail (issue 32): per rig, three
// camera distances where the posed model's bounding sphere fills 100%, 30%
// and 10% of a 1080-pixel-tall view (45 degrees), at a 1-pixel tolerance.
// Uniform is the lowest single level whose measured deviation from the
// finest level is within the tolerance there; adaptive is the view-chosen
// levels.  Frame: positions and shading normals on one thread (uniform: the
// tiled FrameEvaluator of that level's own plan, the fastest uniform path).
void runAdaptive(const char* name, const Rig& rig, const DisplacementMap* map, int animation, float time)
{
    std::unique_ptr<Surface> fine;
    Status st = Surface::create(&fine, rig, map);
    if (st && animation >= 0)
        st = fine->setAnimationTime(animation, time);
    if (!st) {
        std::printf("%s: %s\n", name, st.message().c_str());
        return;
    }
    const int L = fine->level();
    std::vector<glm::vec3> finePositions(fine->vertexCount());
    if (!fine->plan()
             .evaluate(finePositions.data(), nullptr, 0, finePositions.size(), fine->controlPositions().data(),
                       fine->controlNormals().data(), fine->controlVertexCount())
             .isOk())
        return;
    glm::vec3 centre;
    float radius = 0.0f;
    bench::boundingSphere(finePositions, &centre, &radius);
    const double loadStart = bench::nowMs();
    fine->faceLevelErrors();
    const double loadMs = bench::nowMs() - loadStart;

    std::printf("\n%s: %zu control faces, finest level %d (%s, %zu vertices); errors measured at load in %.1f ms\n", name,
                rig.mesh.faceCount(), L, schemeName(fine->scheme()), fine->vertexCount(), loadMs);
    std::printf("fill | mode     | levels      | vertices | triangles | frame ms | choose ms | rebuild ms | max px error | vertices / uniform | frame / uniform\n");
    std::printf("-----|----------|-------------|----------|-----------|----------|-----------|------------|--------------|--------------------|----------------\n");
    const float pixelError = 1.0f;
    for (float fill : {1.0f, 0.3f, 0.1f}) {
        const ViewSpec view = bench::viewFilling(centre, radius, fill, 1080.0f);

        // Uniform: the lowest level within the tolerance everywhere.
        int uniformLevel = L;
        float uniformError = 0.0f;
        std::vector<uint8_t> levels(rig.mesh.faceCount());
        for (int l = 0; l <= L; ++l) {
            std::fill(levels.begin(), levels.end(), uint8_t(l));
            fine->setFaceLevels(levels.data(), levels.size());
            std::vector<glm::vec3> p(fine->adaptiveFrame().vertexCount());
            fine->evaluateAdaptive(p.data(), nullptr, p.size());
            const float e = fine->adaptiveFrame().maxScreenDeviation(p.data(), finePositions.data(), view);
            if (e <= pixelError || l == L) {
                uniformLevel = l;
                uniformError = e;
                break;
            }
        }
        SurfaceOptions o;
        o.level = uniformLevel;
        std::unique_ptr<Surface> uniform;
        if (!Surface::create(&uniform, rig, map, o).isOk() ||
            (animation >= 0 && !uniform->setAnimationTime(animation, time).isOk()))
            return;
        std::vector<glm::vec3> up(uniform->vertexCount()), un(up.size());
        // A choice per frame of a view that moves (a hair each time: the same
        // view again keeps the frame without choosing).  In full: a chooser
        // of the bench's own, made as the Surface makes its own (the rest
        // pose's errors), asked with no previous levels, so none stand.
        // Kept: the Surface's choice, whose last levels stand.  An animated
        // rig's pose moves too (a millisecond a frame): the skinning is
        // timed alone and taken off.
        std::unique_ptr<Surface> rest;
        LevelChooser chooser;
        if (!Surface::create(&rest, rig, map).isOk() || !rest->setRestPose().isOk() ||
            !chooser
                 .init(rest->plan(), nullptr, rest->controlPositions().data(), rest->controlNormals().data(),
                       rest->controlVertexCount())
                 .isOk())
            return;
        std::vector<uint8_t> scratchLevels(4 * rig.mesh.faceCount());
        int nudge = 0;
        auto choose = [&](bool full) {
            ViewSpec moved = view;
            moved.eye.x += float(nudge++ % 2) * 1e-6f * radius;
            if (!full) {
                fine->chooseFaceLevels(moved, pixelError);
                return;
            }
            const std::vector<glm::mat4>& skin = fine->skinMatrices();
            chooser.choose(scratchLevels.data(), moved, pixelError, fine->controlPositions().data(),
                           fine->controlVertexCount(), skin.empty() ? 1.0f : skinScale(&skin[0][0][0], skin.size()),
                           fine->controlNormals().data(), nullptr);
        };
        const double stillPoseMs = bench::medianMs([&] { choose(true); }, 5, 20.0);
        double chooseMs = stillPoseMs, keptMs = bench::medianMs([&] { choose(false); }, 5, 20.0);
        if (animation >= 0) {
            int step = 0;
            auto pose = [&] { fine->setAnimationTime(animation, time + float(step++ % 2) * 1e-3f); };
            const double poseMs = bench::medianMs(pose, 5, 20.0);
            const double fullMs = bench::medianMs(
                [&] {
                    pose();
                    choose(true);
                },
                5, 20.0);
            const double keptPoseMs = bench::medianMs(
                [&] {
                    pose();
                    choose(false);
                },
                5, 20.0);
            chooseMs = std::max(0.0, fullMs - poseMs);
            keptMs = std::max(0.0, keptPoseMs - poseMs);
            fine->setAnimationTime(animation, time);
        }
        // This view's own choice, made fresh: levels set by hand first, so
        // none of the timing's levels are held.
        fine->setFaceLevels(levels.data(), levels.size());
        fine->chooseFaceLevels(view, pixelError);
        const AdaptiveFrame& frame = fine->adaptiveFrame();
        // A change of levels rebuilds the frame's topology (setQuarterLevels).
        const std::vector<uint8_t> chosen = frame.quarterLevels();
        const double rebuildMs = bench::medianMs([&] { fine->setQuarterLevels(chosen.data(), chosen.size()); }, 5, 20.0);
        std::vector<glm::vec3> ap(frame.vertexCount()), an(ap.size());
        // The uniform frame a level down (where it exists): a vertex costs
        // more in smaller tiles (more of them on a border), and an adaptive
        // frame's tiles are mostly that size or smaller.
        std::unique_ptr<Surface> below;
        o.level = uniformLevel - 1;
        if (uniformLevel > 0 && (!Surface::create(&below, rig, map, o).isOk() ||
                                 (animation >= 0 && !below->setAnimationTime(animation, time).isOk())))
            return;
        std::vector<glm::vec3> bp(below ? below->vertexCount() : 0), bn(bp.size());
        // Interleaved runs, so a slow spell of this shared machine falls on both.
        double uniformMs = 0.0, adaptiveMs = 0.0, uniformPositionsMs = 0.0, positionsMs = 0.0, belowMs = 0.0;
        interleavedMs({[&] { uniform->evaluate(up.data(), un.data(), up.size()); },
                       [&] { fine->evaluateAdaptive(ap.data(), an.data(), ap.size()); },
                       [&] { uniform->evaluate(up.data(), nullptr, up.size()); },
                       [&] { fine->evaluateAdaptive(ap.data(), nullptr, ap.size()); },
                       [&] {
                           if (below)
                               below->evaluate(bp.data(), bn.data(), bp.size());
                       }},
                      {&uniformMs, &adaptiveMs, &uniformPositionsMs, &positionsMs, &belowMs});
        const auto nsPerVertex = [](double ms, size_t n) { return n ? 1e6 * ms / double(n) : 0.0; };
        const float adaptiveError = frame.maxScreenDeviation(ap.data(), finePositions.data(), view);
        // Between the finest vertices too (a lattice 4x finer): a stitched
        // triangle's edges cross the finest triangles there.
        const float adaptiveErrorBetween = frame.maxScreenDeviation(ap.data(), finePositions.data(), view, 4);
        int lmin = L, lmax = 0;
        for (uint8_t l : frame.quarterLevels()) {
            lmin = std::min(lmin, int(l));
            lmax = std::max(lmax, int(l));
        }
        char range[32];
        std::snprintf(range, sizeof(range), "%d..%d", lmin, lmax);
        std::printf("%3.0f%% | uniform  | %-11d | %8zu | %9zu | %8.3f | %9s | %10s | %12.3f | %18s | %15s\n", 100.0 * fill,
                    uniformLevel, uniform->vertexCount(), uniform->triangleCount(), uniformMs, "-", "-",
                    double(uniformError), "1", "1");
        std::printf("%3.0f%% | adaptive | %-11s | %8zu | %9zu | %8.3f | %9.3f | %10.3f | %12.3f | %18.3f | %15.3f\n",
                    100.0 * fill, range, frame.vertexCount(), frame.triangleCount(), adaptiveMs, chooseMs, rebuildMs,
                    double(adaptiveError), double(frame.vertexCount()) / double(uniform->vertexCount()),
                    adaptiveMs / uniformMs);
        std::printf("     | positions alone: uniform %.3f ms, adaptive %.3f ms (%.3f)\n", uniformPositionsMs, positionsMs,
                    positionsMs / uniformPositionsMs);
        std::printf("     | max px error between the finest vertices too (a 4x finer lattice): %.3f\n", adaptiveErrorBetween);
        std::printf("     | a choice in full with the pose still (the view alone moving): %.3f ms; the last levels kept: %.3f ms\n",
                    stillPoseMs, keptMs);
        std::printf("     | frame per vertex: adaptive %.2f ns, uniform level %d %.2f ns", nsPerVertex(adaptiveMs, ap.size()),
                    uniformLevel, nsPerVertex(uniformMs, up.size()));
        if (below)
            std::printf(", uniform level %d %.2f ns", uniformLevel - 1, nsPerVertex(belowMs, bp.size()));
        std::printf("\n");
        std::fflush(stdout);
        for (int adaptive = 0; adaptive < 2; ++adaptive) {
            jsonRows.field("table", "adaptive")
                .field("mode", adaptive ? "adaptive" : "uniform")
                .field("mesh", name)
                .field("fill", double(fill))
                .field("pixel_tolerance", double(pixelError))
                .field("finest_level", L)
                .field("level_min", adaptive ? lmin : uniformLevel)
                .field("level_max", adaptive ? lmax : uniformLevel)
                .field("vertices", double(adaptive ? frame.vertexCount() : uniform->vertexCount()))
                .field("triangles", double(adaptive ? frame.triangleCount() : uniform->triangleCount()))
                .field("frame_ms", adaptive ? adaptiveMs : uniformMs)
                .field("choose_ms", adaptive ? chooseMs : 0.0)
                .field("choose_still_pose_ms", adaptive ? stillPoseMs : 0.0)
                .field("kept_choice_ms", adaptive ? keptMs : 0.0)
                .field("rebuild_ms", adaptive ? rebuildMs : 0.0)
                .field("max_pixel_error", double(adaptive ? adaptiveError : uniformError))
                .field("max_pixel_error_4x", double(adaptive ? adaptiveErrorBetween : uniformError))
                .field("positions_ms", adaptive ? positionsMs : uniformPositionsMs)
                .field("ns_per_vertex", adaptive ? nsPerVertex(adaptiveMs, ap.size()) : nsPerVertex(uniformMs, up.size()))
                .field("uniform_level_below_ns_per_vertex", nsPerVertex(belowMs, bp.size()))
                .field("uniform_frame_ms", uniformMs)
                .field("load_errors_ms", loadMs)
                .endRow();
        }

        // A moving view (and pose): 120 frames of the camera dollying 10% in
        // and out and sliding sideways, an animated rig playing at 60 Hz.
        // Per frame, adaptive is the choice (and the rebuild where the levels
        // change) and the frame; uniform is its frame.  The skinning, the
        // same for both, is left out.  Three runs, the median.
        const int frames = 120;
        std::vector<double> adaptiveRuns, uniformRuns;
        size_t full = 0, kept = 0, repaired = 0, rebuilds = 0, drawn = 0;
        std::vector<glm::vec3> mp(fine->vertexCount()), mn(mp.size());
        for (int run = 0; run < 3; ++run) {
            double adaptiveTotal = 0.0, uniformTotal = 0.0;
            const LevelChooser* lc = fine->levelChooser();
            const size_t fullBefore = lc->fullChoices(), keptBefore = lc->keptChoices(), repairedBefore = lc->repairedChoices();
            size_t changes = 0, vertices = 0;
            for (int f = 0; f < frames; ++f) {
                const ViewSpec v = bench::movingView(view, centre, radius, f, frames);
                if (animation >= 0) {
                    fine->setAnimationTime(animation, time + float(f) / 60.0f);
                    uniform->setAnimationTime(animation, time + float(f) / 60.0f);
                }
                const uint64_t topology = fine->adaptiveFrame().topologyVersion();
                double t0 = bench::nowMs();
                fine->chooseFaceLevels(v, pixelError);
                fine->evaluateAdaptive(mp.data(), mn.data(), fine->adaptiveFrame().vertexCount());
                double t1 = bench::nowMs();
                adaptiveTotal += t1 - t0;
                changes += fine->adaptiveFrame().topologyVersion() != topology;
                vertices += fine->adaptiveFrame().vertexCount();
                t0 = bench::nowMs();
                uniform->evaluate(up.data(), un.data(), up.size());
                t1 = bench::nowMs();
                uniformTotal += t1 - t0;
            }
            adaptiveRuns.push_back(adaptiveTotal / frames);
            uniformRuns.push_back(uniformTotal / frames);
            full = lc->fullChoices() - fullBefore;
            kept = lc->keptChoices() - keptBefore;
            repaired = lc->repairedChoices() - repairedBefore;
            rebuilds = changes;
            drawn = vertices / size_t(frames);
        }
        if (animation >= 0)  // the next fill's uniform level is measured in this pose
            fine->setAnimationTime(animation, time);
        const double movingAdaptiveMs = bench::median(adaptiveRuns), movingUniformMs = bench::median(uniformRuns);
        std::printf("     | moving, %d frames: adaptive %.3f ms a frame (choice and frame; %zu choices in full, %zu kept, %zu "
                    "repaired, %zu rebuilds, %zu vertices on average), uniform %.3f ms (%.2f)\n",
                    frames, movingAdaptiveMs, full, kept, repaired, rebuilds, drawn, movingUniformMs,
                    movingAdaptiveMs / movingUniformMs);
        std::fflush(stdout);
        jsonRows.field("table", "adaptive_moving")
            .field("mesh", name)
            .field("fill", double(fill))
            .field("frames", frames)
            .field("adaptive_ms_per_frame", movingAdaptiveMs)
            .field("uniform_ms_per_frame", movingUniformMs)
            .field("full_choices", double(full))
            .field("kept_choices", double(kept))
            .field("repaired_choices", double(repaired))
            .field("rebuilds", double(rebuilds))
            .field("mean_vertices", double(drawn))
            .endRow();
    }
}

// A rig baked by strata-bake's pipeline into a scratch folder, loaded back.
bool bakeForBench(const std::string& high, const std::string& stem, Rig* rig, DisplacementMap* map,
                  size_t controlFaces = 0)
{
    const std::string dir = (std::filesystem::temp_directory_path() / ("strata_bench_runtime_" + std::to_string(::getpid()))).string();
    std::filesystem::create_directories(dir);
    baker::BakeRequest request;
    request.high = high;
    request.control = "auto";
    request.controlFaces = controlFaces;
    request.output = dir + "/" + stem + ".glb";
    baker::BakeResult result;
    const Status st = baker::bakeRig(request, &result);
    bool ok = st.isOk() && io::loadRig(request.output, rig).isOk() &&
              (!rigNeedsMap(*rig) || io::loadRigDisplacementMap(request.output, *rig, map).isOk());
    if (!st)
        std::printf("%s: bake failed: %s\n", stem.c_str(), st.message().c_str());
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    return ok;
}

void runAdaptiveTables()
{
    std::printf("\nAdaptive against uniform level of detail, 1-pixel tolerance, 1080-pixel-tall view (one thread)\n");
    {
        Rig rig;
        DisplacementMap map;
        rig.mesh = examples::makeIcosphere(1);
        if (baker::buildTriangleAtlas(&rig.mesh, {1024, 2}).isOk() &&
            examples::bakeRadialSurface(&map, rig.mesh, 1024, 2, examples::headRadius).isOk()) {
            rig.hasDisplacement = true;
            rig.displacement.encoding = "exr";
            rig.displacement.width = rig.displacement.height = 1024;
            rig.displacement.recommendedLevel = 5;
            runAdaptive("example", rig, &map, -1, 0.0f);
        }
    }
    const std::string data = STRATA_SHARED_DATA;
    Rig rig;
    DisplacementMap map;
    // CesiumMan on 1,113 faces, its rig at level 2: the default search's
    // cage until it met the tolerance in every pose, where it now takes
    // 2,000 faces at level 0 and leaves a view nothing to choose.
    if (bakeForBench(data + "/CesiumMan.glb", "cesium", &rig, &map, 1113))
        runAdaptive("CesiumMan", rig, &map, 0, 1.0f);
    Rig scan;
    DisplacementMap scanMap;
    if (bakeForBench(data + "/nefertiti-lowres.obj", "nefertiti", &scan, &scanMap))
        runAdaptive("nefertiti", scan, &scanMap, -1, 0.0f);
}

}  // namespace

int main(int argc, char** argv)
{
    int maxLevel = kMaxLevel, maxSmooth = 5;
    int threads = int(std::max(2u, std::thread::hardware_concurrency()));
    std::string jsonPath;
    bool adaptiveOnly = false, adaptive = true;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--max-level") && i + 1 < argc)
            maxLevel = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--max-smooth-level") && i + 1 < argc)
            maxSmooth = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--json") && i + 1 < argc)
            jsonPath = argv[++i];
        else if (!std::strcmp(argv[i], "--adaptive-only"))
            adaptiveOnly = true;
        else if (!std::strcmp(argv[i], "--no-adaptive"))
            adaptive = false;
        else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = std::max(1, std::atoi(argv[++i]));
        else {
            std::fprintf(stderr, "usage: bench_runtime [--max-level N] [--max-smooth-level N] [--threads N] [--adaptive-only | --no-adaptive]\n"
                                 "                     [--json FILE]\n");
            return 2;
        }
    }
    std::printf("bench_runtime: median of 7 runs per cell (setup: of 3, the first in the JSON); evaluate = positions + "
                "directions + displacement\n");
    if (adaptiveOnly) {
        runAdaptiveTables();
        if (!jsonPath.empty() && !jsonRows.write(jsonPath)) {
            std::fprintf(stderr, "bench_runtime: cannot write %s\n", jsonPath.c_str());
            return 1;
        }
        return 0;
    }
    const ControlMesh cube = makeCube(13);
    runTable("cube 13x13 per side", cube, maxLevel, Scheme::Linear, threads);
    ControlMesh spot;
    const std::string spotPath = std::string(STRATA_SHARED_DATA) + "/spot_control_mesh.obj";
    struct stat st;
    const bool haveSpot = ::stat(spotPath.c_str(), &st) == 0 && io::readObj(spotPath, &spot).isOk();
    if (haveSpot)
        runTable("spot", spot, maxLevel, Scheme::Linear, threads);
    else
        std::printf("\nspot: %s not found, skipped\n", spotPath.c_str());
    runTable("cube 13x13 per side", cube, std::min(maxLevel, maxSmooth), Scheme::Smooth, threads);
    if (haveSpot)
        runTable("spot", spot, std::min(maxLevel, maxSmooth), Scheme::Smooth, threads);
    if (adaptive)
        runAdaptiveTables();
    if (!jsonPath.empty() && !jsonRows.write(jsonPath)) {
        std::fprintf(stderr, "bench_runtime: cannot write %s\n", jsonPath.c_str());
        return 1;
    }
    return 0;
}
