// bench_gpu: the GPU path's frame split into upload, stencils, shading
// normals and draw (each stage finished before the next and timed by the
// wall clock: llvmpipe's timestamp queries land a stage late; median of 7
// frames), plus the whole frame unsplit by wall clock with glFinish, next
// to the CPU path for the same frame (pose + FrameEvaluator, one core), at
// levels 0..5 (6 with --max 6).
//
//   bench_gpu [--size WxH] [--max-level N]
//   bench_gpu --adaptive [--level N] [--size WxH] [--frames N] [--json FILE]
//
// --adaptive: one displaced, animated character of about a million refined
// vertices (a 500-face geodesic head, the example's head map, two joints
// bending it; level 6), uniform against adaptive (1-pixel tolerance, the
// model filling 100%, 30% and 10% of the view's height), stage by stage, as
// JSON on stdout (and into FILE), then a moving view and pose over N frames
// (120), adaptive against uniform per frame.  tools/gpu/ packs this for a
// GPU machine.
//
// Headless through EGL: llvmpipe on a machine without a GPU, the vendor's
// driver where there is one (the context line says which).
#include "bench_common.h"
#include "procedural.h"
#include "strata/animation.h"
#include "strata/baker/atlas.h"
#include "strata/frame.h"
#include "strata/gl/context.h"
#include "strata/gl/framebuffer.h"
#include "strata/gl/gpu_surface.h"
#include "strata/io/rig_io.h"
#include "strata/normals.h"
#include "strata/surface.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include <map>
#include <tuple>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <sys/stat.h>

using namespace strata;

namespace {

struct Case {
    std::string name;
    Rig rig;
    DisplacementMap map;
    bool haveMap = false;
};

void run(const Case& c, int width, int height, int maxLevel)
{
    const bool animated = !c.rig.skeleton.empty() && !c.rig.skeleton.animations.empty();
    std::printf("\n%s: %zu control vertices, %s; %dx%d 4x MSAA target\n", c.name.c_str(), c.rig.mesh.vertexCount(),
                animated ? ("animation \"" + c.rig.skeleton.animations[0].name + "\"").c_str() : "rest pose",
                width, height);
    std::printf("level | refined verts | upload ms | stencils ms | normals ms | draw ms | GPU frame ms (wall) |"
                " M verts/s | CPU frame ms | CPU/GPU\n");
    std::printf("------+---------------+-----------+-------------+------------+---------+---------------------+"
                "-----------+--------------+--------\n");
    gl::Framebuffer fb;
    if (!fb.create(width, height).isOk())
        return;
    float t = 0.0f;
    for (int level = 0; level <= maxLevel; ++level) {
        // The rig at this level as an engine holds it (its own scheme, its
        // displacements, the animator); the GPU evaluates its plan.
        std::unique_ptr<Surface> drawn;
        SurfaceOptions surfaceOptions;
        surfaceOptions.level = level;
        surfaceOptions.layout = FrameLayout::Tiles;  // the CPU frame below, as bench_runtime's
        surfaceOptions.displace = c.haveMap;          // the plain characters: their cage refined
        if (Status made = Surface::create(&drawn, c.rig, c.haveMap ? &c.map : nullptr, surfaceOptions); !made) {
            std::printf("%s\n", made.message().c_str());
            return;
        }
        const Plan* plan = &drawn->plan();
        std::unique_ptr<gl::GpuSurface> gpu;
        const Status st = gl::GpuSurface::create(&gpu, *plan);
        if (!st) {
            std::printf("%s\n", st.message().c_str());
            return;
        }
        if (c.haveMap)
            gpu->setDisplacementMap(c.map);
        const size_t n = plan->refinedVertexCount();
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (const glm::vec3& p : c.rig.mesh.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        const float r = 0.5f * glm::length(hi - lo);
        gl::DrawParams params;
        params.eye = 0.5f * (lo + hi) + glm::vec3(0.0f, 0.0f, 3.0f * r);
        params.viewProjection = glm::perspective(0.7f, float(width) / float(height), 0.1f * r, 10.0f * r) *
                                glm::lookAt(params.eye, 0.5f * (lo + hi), glm::vec3(0, 1, 0));
        auto pose = [&] {
            t += 1.0f / 60.0f;
            if (animated) {
                const Animation& a = c.rig.skeleton.animations[0];
                drawn->setAnimationTime(0, a.start + std::fmod(t, std::max(a.end - a.start, 1e-3f)));
            }
        };
        const size_t cn = c.rig.mesh.vertexCount();
        // GPU stages, each finished before the next.
        gpu->setTiming(true);
        fb.bind();
        std::vector<double> up, sten, nrm, drw, wall;
        for (int f = 0; f < 8; ++f) {
            pose();
            const double t0 = bench::nowMs();
            gpu->update(drawn->controlPositions().data(), drawn->controlNormals().data(), cn);
            glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
            glEnable(GL_DEPTH_TEST);
            gpu->draw(params);
            glFinish();
            const double t1 = bench::nowMs();
            if (f == 0)
                continue;  // first use compiles and pages in
            const gl::GpuTimings& g = gpu->timings();
            up.push_back(g.uploadMs);
            sten.push_back(g.stencilMs);
            nrm.push_back(g.normalsMs);
            drw.push_back(g.drawMs);
            wall.push_back(t1 - t0);
        }
        gpu->setTiming(false);
        // The whole frame without queries (they serialise the pipeline).
        const double frame = bench::medianMs(
            [&] {
                pose();
                gpu->update(drawn->controlPositions().data(), drawn->controlNormals().data(), cn);
                glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
                gpu->draw(params);
                glFinish();
            },
            7, 20.0);
        // The CPU path for the same frame: the surface's FrameEvaluator in
        // tile order, one core (its tables made before timing).
        std::vector<glm::vec3> out(n), shading(n);
        drawn->evaluate(out.data(), shading.data(), n, 1);
        const double cpu = bench::medianMs(
            [&] {
                pose();
                drawn->evaluate(out.data(), shading.data(), n, 1);
            },
            7, 20.0);
        (void)wall;
        std::printf("%5d | %13zu | %9.3f | %11.3f | %10.3f | %7.3f | %19.3f | %9.1f | %12.3f | %6.2f\n", level, n,
                    bench::median(up), bench::median(sten), bench::median(nrm), bench::median(drw), frame,
                    double(n) / frame / 1000.0, cpu, cpu / frame);
        std::fflush(stdout);
    }
}

// A geodesic sphere: each icosahedron face cut into f^2 triangles, welded,
// on the unit sphere (20 f^2 faces).
ControlMesh geodesicSphere(int f)
{
    const ControlMesh ico = examples::makeIcosphere(0);
    ControlMesh m;
    std::map<std::tuple<long, long, long>, uint32_t> welded;
    auto vertex = [&](glm::vec3 p) {
        p = glm::normalize(p);
        const auto key = std::make_tuple(std::lround(p.x * 1e5f), std::lround(p.y * 1e5f), std::lround(p.z * 1e5f));
        const auto it = welded.find(key);
        if (it != welded.end())
            return it->second;
        m.positions.push_back(p);
        return welded[key] = uint32_t(m.positions.size() - 1);
    };
    for (size_t t = 0; t < ico.faceCount(); ++t) {
        const glm::vec3 a = ico.positions[ico.triangles[3 * t]], b = ico.positions[ico.triangles[3 * t + 1]],
                        c = ico.positions[ico.triangles[3 * t + 2]];
        std::vector<uint32_t> id(size_t(f + 1) * size_t(f + 1));
        for (int i = 0; i <= f; ++i)
            for (int j = 0; i + j <= f; ++j)
                id[size_t(i) * size_t(f + 1) + size_t(j)] =
                    vertex(a + (b - a) * (float(i) / float(f)) + (c - a) * (float(j) / float(f)));
        auto at = [&](int i, int j) { return id[size_t(i) * size_t(f + 1) + size_t(j)]; };
        for (int i = 0; i < f; ++i)
            for (int j = 0; i + j < f; ++j) {
                m.triangles.insert(m.triangles.end(), {at(i, j), at(i + 1, j), at(i, j + 1)});
                if (i + j + 1 < f)
                    m.triangles.insert(m.triangles.end(), {at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
            }
    }
    return m;
}

// The displaced, animated million-vertex character of --adaptive.
bool makeBigCharacter(Rig* rig, DisplacementMap* map)
{
    rig->mesh = geodesicSphere(5);
    if (!baker::buildTriangleAtlas(&rig->mesh, {2048, 2}).isOk() ||
        !examples::bakeRadialSurface(map, rig->mesh, 2048, 2, examples::headRadius).isOk())
        return false;
    rig->hasDisplacement = true;
    rig->displacement.encoding = "exr";
    rig->displacement.width = rig->displacement.height = 2048;
    rig->displacement.recommendedLevel = 6;
    Skeleton& s = rig->skeleton;
    s.nodes.resize(2);
    s.nodes[0].name = "neck";
    s.nodes[1].name = "head";
    s.nodes[1].parent = 0;
    s.nodes[1].rest.translation = glm::vec3(0.0f, 0.3f, 0.0f);
    s.skin.joints = {0, 1};
    s.skin.inverseBindMatrices = {glm::mat4(1.0f), glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, -0.3f, 0.0f))};
    s.weights.influences = 4;
    for (const glm::vec3& p : rig->mesh.positions) {
        const float w = glm::clamp(p.y + 0.3f, 0.0f, 1.0f);
        s.weights.joints.insert(s.weights.joints.end(), {0, 1, 0, 0});
        s.weights.weights.insert(s.weights.weights.end(), {1.0f - w, w, 0.0f, 0.0f});
    }
    Animation nod;
    nod.name = "nod";
    AnimationChannel c;
    c.node = 1;
    c.path = AnimationPath::Rotation;
    c.times = {0.0f, 1.0f, 2.0f};
    for (const glm::quat& q : {glm::quat(1, 0, 0, 0), glm::angleAxis(0.5f, glm::vec3(1.0f, 0.0f, 0.0f)), glm::quat(1, 0, 0, 0)})
        c.values.insert(c.values.end(), {q.x, q.y, q.z, q.w});
    nod.channels.push_back(c);
    nod.end = 2.0f;
    s.animations.push_back(nod);
    return finalizeSkeleton(&s, rig->mesh.vertexCount()).isOk();
}

// The draw's camera for a view of a width x height target: near and far
// planes around the distance to the target.
gl::DrawParams drawParamsFor(const ViewSpec& view, int width, int height)
{
    const float distance = glm::length(view.eye - view.target);
    gl::DrawParams params;
    params.eye = view.eye;
    params.viewProjection = glm::perspective(glm::radians(view.fovYDegrees), float(width) / float(height),
                                             0.05f * distance, 10.0f * distance) *
                            glm::lookAt(view.eye, view.target, glm::vec3(0, 1, 0));
    return params;
}

// Uniform against adaptive on the GPU, stage by stage, as JSON rows.
int runAdaptive(int width, int height, int level, int movingFrames, const std::string& jsonPath,
                const std::string& device)
{
    Rig rig;
    DisplacementMap map;
    if (!makeBigCharacter(&rig, &map)) {
        std::fprintf(stderr, "bench_gpu: could not make the character\n");
        return 1;
    }
    rig.displacement.recommendedLevel = level;
    std::unique_ptr<Surface> surface;
    Status st = Surface::create(&surface, rig, &map);
    if (!st) {
        std::fprintf(stderr, "bench_gpu: %s\n", st.message().c_str());
        return 1;
    }
    std::unique_ptr<gl::GpuSurface> gpu;
    if (!(st = gl::GpuSurface::create(&gpu, surface->plan())) ||
        !(st = gpu->setDisplacements(surface->plan().displacements().data(), surface->vertexCount()))) {
        std::fprintf(stderr, "bench_gpu: %s\n", st.message().c_str());
        return 1;
    }
    gl::Framebuffer fb;
    if (!(st = fb.create(width, height))) {
        std::fprintf(stderr, "bench_gpu: %s\n", st.message().c_str());
        return 1;
    }
    const size_t cn = surface->controlVertexCount(), n = surface->vertexCount();
    std::printf("bench_gpu --adaptive: %zu control faces, level %d, %zu refined vertices; %dx%d 4x MSAA target; %s\n",
                rig.mesh.faceCount(), level, n, width, height, device.c_str());
    std::printf("mode     | fill | vertices  | triangles | choose ms | set ms | upload ms | stencils ms | normals ms | "
                "draw ms | GPU frame ms | CPU frame ms\n");
    bench::JsonRows rows;
    float t = 0.0f;
    auto pose = [&] {
        t += 1.0f / 60.0f;
        surface->setAnimationTime(0, std::fmod(t, 2.0f));
    };
    pose();
    // The posed model's bounding sphere, for the three fills.
    std::vector<glm::vec3> finePositions(n), shading(n);
    surface->evaluate(finePositions.data(), shading.data(), n, 1);
    glm::vec3 centre;
    float radius = 0.0f;
    bench::boundingSphere(finePositions, &centre, &radius);
    surface->faceLevelErrors();  // measured at load, not in a frame
    // One frame of the current pose, unfinished: the control vertices up,
    // the passes, and the draw, uniform or adaptive.
    auto drawFrame = [&](bool adaptive, const gl::DrawParams& params) {
        const glm::vec3* cp = surface->controlPositions().data();
        const glm::vec3* nn = surface->controlNormals().data();
        if (adaptive)
            gpu->updateAdaptive(cp, nn, cn);
        else
            gpu->update(cp, nn, cn);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST);
        if (adaptive)
            gpu->drawAdaptive(params);
        else
            gpu->draw(params);
    };

    // Once per run, outside the rows: the adaptive passes' programs are
    // compiled by the first setAdaptive (tens of milliseconds on a driver
    // that compiles late), and a GPU idling at low clocks takes a moment to
    // come up.  Half a second of uniform frames brings it up.
    double programsMs = 0.0;
    {
        const double p0 = bench::nowMs();
        surface->chooseFaceLevels(bench::viewFilling(centre, radius, 0.1f, float(height)), 1.0f);
        gpu->setAdaptive(surface->adaptiveFrame());
        glFinish();
        programsMs = bench::nowMs() - p0;
        fb.bind();
        glViewport(0, 0, width, height);
        const gl::DrawParams params =
            drawParamsFor(bench::viewFilling(centre, radius, 1.0f, float(height)), width, height);
        for (const double w0 = bench::nowMs(); bench::nowMs() - w0 < 500.0;) {
            drawFrame(false, params);
            glFinish();
        }
    }
    std::printf("(the adaptive programs built and a first frame set in %.1f ms, once; GPU warmed for 0.5 s)\n",
                programsMs);

    for (float fill : {1.0f, 0.3f, 0.1f}) {
        const ViewSpec view = bench::viewFilling(centre, radius, fill, float(height));
        const gl::DrawParams params = drawParamsFor(view, width, height);
        for (int adaptive = 0; adaptive < 2; ++adaptive) {
            double chooseMs = 0.0, setMs = 0.0;
            size_t vertices = n, triangles = surface->triangleCount();
            if (adaptive) {
                // This view's own choice, made fresh (as bench_runtime's):
                // levels set by hand first, so none of the last fill's are
                // held; and at the same pose run after run (the timed loops
                // below pose as many frames as their time allows).
                t = 0.0f;
                pose();
                const std::vector<uint8_t> zeros(rig.mesh.faceCount(), 0);
                surface->setFaceLevels(zeros.data(), zeros.size());
                const double c0 = bench::nowMs();
                surface->chooseFaceLevels(view, 1.0f);
                chooseMs = bench::nowMs() - c0;
                // A new frame's fans and uploads, finished (median of 5).
                std::vector<double> sets;
                for (int r = 0; r < 5; ++r) {
                    const double c1 = bench::nowMs();
                    gpu->setAdaptive(surface->adaptiveFrame());
                    glFinish();
                    sets.push_back(bench::nowMs() - c1);
                }
                setMs = bench::median(sets);
                vertices = surface->adaptiveFrame().vertexCount();
                triangles = surface->adaptiveFrame().triangleCount();
            }
            auto frame = [&] { drawFrame(adaptive != 0, params); };
            fb.bind();
            glViewport(0, 0, width, height);
            gpu->setTiming(true);
            std::vector<double> up, sten, nrm, drw;
            for (int f = 0; f < 6; ++f) {
                pose();
                frame();
                if (f == 0)
                    continue;
                const gl::GpuTimings& g = gpu->timings();
                up.push_back(g.uploadMs);
                sten.push_back(g.stencilMs);
                nrm.push_back(g.normalsMs);
                drw.push_back(g.drawMs);
            }
            gpu->setTiming(false);
            const double wall = bench::medianMs(
                [&] {
                    pose();
                    frame();
                    glFinish();
                },
                5, 20.0);
            std::vector<glm::vec3> cpuPositions(vertices), cpuNormals(vertices);
            const double cpu = bench::medianMs(
                [&] {
                    pose();
                    if (adaptive)
                        surface->evaluateAdaptive(cpuPositions.data(), cpuNormals.data(), vertices, 1);
                    else
                        surface->evaluate(cpuPositions.data(), cpuNormals.data(), vertices, 1);
                },
                5, 20.0);
            const char* mode = adaptive ? "adaptive" : "uniform";
            std::printf("%-8s | %3.0f%% | %9zu | %9zu | %9.3f | %6.3f | %9.3f | %11.3f | %10.3f | %7.3f | %12.3f | %12.3f\n",
                        mode, 100.0 * fill, vertices, triangles, chooseMs, setMs, bench::median(up),
                        bench::median(sten), bench::median(nrm), bench::median(drw), wall, cpu);
            std::fflush(stdout);
            rows.field("table", "gpu_adaptive")
                .field("device", device)
                .field("mode", mode)
                .field("fill", double(fill))
                .field("level", level)
                .field("vertices", double(vertices))
                .field("triangles", double(triangles))
                .field("choose_ms", chooseMs)
                .field("set_adaptive_ms", setMs)
                .field("upload_ms", bench::median(up))
                .field("stencils_displace_ms", bench::median(sten))
                .field("normals_ms", bench::median(nrm))
                .field("draw_ms", bench::median(drw))
                .field("gpu_frame_ms", wall)
                .field("cpu_frame_ms", cpu)
                .field("width", width)
                .field("height", height)
                .endRow();
        }

        // A moving view and pose, as bench_runtime's adaptive_moving: the
        // camera dollies 10% in and out and slides sideways, the rig plays
        // at 60 Hz.  An adaptive frame is its choice, a new frame set where
        // the levels changed, the passes and the draw, finished; a uniform
        // frame is its passes and draw, finished.  The pose, the same for
        // both, is left out.  Three runs, the median.
        std::vector<double> adaptiveRuns, uniformRuns;
        size_t sets = 0, drawn = 0;
        for (int run = 0; run < 3; ++run) {
            double adaptiveTotal = 0.0, uniformTotal = 0.0;
            sets = drawn = 0;
            for (int f = 0; f < movingFrames; ++f) {
                const ViewSpec v = bench::movingView(view, centre, radius, f, movingFrames);
                const gl::DrawParams p = drawParamsFor(v, width, height);
                surface->setAnimationTime(0, std::fmod(float(f) / 60.0f, 2.0f));
                const uint64_t topology = surface->adaptiveFrame().topologyVersion();
                double t0 = bench::nowMs();
                surface->chooseFaceLevels(v, 1.0f);
                if (surface->adaptiveFrame().topologyVersion() != topology) {
                    gpu->setAdaptive(surface->adaptiveFrame());
                    ++sets;
                }
                drawFrame(true, p);
                glFinish();
                double t1 = bench::nowMs();
                adaptiveTotal += t1 - t0;
                drawn += surface->adaptiveFrame().vertexCount();
                t0 = bench::nowMs();
                drawFrame(false, p);
                glFinish();
                t1 = bench::nowMs();
                uniformTotal += t1 - t0;
            }
            adaptiveRuns.push_back(adaptiveTotal / movingFrames);
            uniformRuns.push_back(uniformTotal / movingFrames);
        }
        const double movingAdaptive = bench::median(adaptiveRuns), movingUniform = bench::median(uniformRuns);
        std::printf("moving   | %3.0f%% | %d frames: adaptive %.3f ms a frame (%zu new frames set, %zu vertices on "
                    "average), uniform %.3f ms (%.2f)\n",
                    100.0 * fill, movingFrames, movingAdaptive, sets, drawn / size_t(movingFrames), movingUniform,
                    movingAdaptive / movingUniform);
        std::fflush(stdout);
        rows.field("table", "gpu_adaptive_moving")
            .field("device", device)
            .field("fill", double(fill))
            .field("level", level)
            .field("frames", movingFrames)
            .field("adaptive_ms_per_frame", movingAdaptive)
            .field("uniform_ms_per_frame", movingUniform)
            .field("frames_set", double(sets))
            .field("mean_vertices", double(drawn / size_t(movingFrames)))
            .field("width", width)
            .field("height", height)
            .endRow();
    }
    std::printf("%s\n", rows.text().c_str());
    if (!jsonPath.empty() && !rows.write(jsonPath)) {
        std::fprintf(stderr, "bench_gpu: cannot write %s\n", jsonPath.c_str());
        return 1;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    int width = 1280, height = 720, maxLevel = 5, adaptiveLevel = 6, movingFrames = 120;
    bool adaptive = false, sizeGiven = false;
    std::string jsonPath;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--size") && i + 1 < argc)
            sizeGiven = std::sscanf(argv[++i], "%dx%d", &width, &height) == 2;
        else if (!std::strcmp(argv[i], "--max-level") && i + 1 < argc)
            maxLevel = std::clamp(std::atoi(argv[++i]), 0, kMaxLevel);
        else if (!std::strcmp(argv[i], "--adaptive"))
            adaptive = true;
        else if (!std::strcmp(argv[i], "--level") && i + 1 < argc)
            adaptiveLevel = std::clamp(std::atoi(argv[++i]), 1, kMaxLevel);
        else if (!std::strcmp(argv[i], "--frames") && i + 1 < argc)
            movingFrames = std::clamp(std::atoi(argv[++i]), 1, 100000);
        else if (!std::strcmp(argv[i], "--json") && i + 1 < argc)
            jsonPath = argv[++i];
        else {
            std::fprintf(stderr, "usage: bench_gpu [--size WxH] [--max-level N]\n"
                                 "       bench_gpu --adaptive [--level N] [--size WxH] [--frames N] [--json FILE]\n");
            return 2;
        }
    }
    if (adaptive && !sizeGiven) {  // the view the level of detail is measured for
        width = 1920;
        height = 1080;
    }
    width = std::clamp(width, 16, 8192);
    height = std::clamp(height, 16, 8192);
    std::unique_ptr<gl::HeadlessContext> ctx;
    const Status st = gl::HeadlessContext::create(&ctx);
    if (!st) {
        std::fprintf(stderr, "bench_gpu: %s\n", st.message().c_str());
        return 1;
    }
    if (adaptive)
        return runAdaptive(width, height, adaptiveLevel, movingFrames, jsonPath, ctx->description());
    std::printf("bench_gpu: %s\n", ctx->description().c_str());

    Case example;
    example.name = "built-in example (icosphere(1) + head map 1024^2)";
    example.rig.mesh = examples::makeIcosphere(1);
    baker::buildTriangleAtlas(&example.rig.mesh, {1024, 2});
    examples::bakeRadialSurface(&example.map, example.rig.mesh, 1024, 2, examples::headRadius);
    example.haveMap = true;
    run(example, width, height, maxLevel);

    const std::string data = STRATA_SHARED_DATA;
    for (const char* name : {"Fox", "CesiumMan"}) {
        struct stat sb;
        const std::string path = data + "/" + name + ".glb";
        if (::stat(path.c_str(), &sb) != 0)
            continue;
        Case c;
        c.name = name;
        if (!io::loadRig(path, &c.rig).isOk())
            continue;
        run(c, width, height, maxLevel);
    }
    return 0;
}
