// bench_gpu: the GPU path's frame split into upload, stencils, shading
// normals and draw (each stage finished before the next and timed by the
// wall clock: llvmpipe's timestamp queries land a stage late; median of 7
// frames), plus the whole frame unsplit by wall clock with glFinish, next
// to the CPU path for the same frame (pose + FrameEvaluator, one core), at
// levels 0..5 (6 with --max 6).
//
//   bench_gpu [--size WxH] [--max-level N]
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

}  // namespace

int main(int argc, char** argv)
{
    int width = 1280, height = 720, maxLevel = 5;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--size") && i + 1 < argc)
            std::sscanf(argv[++i], "%dx%d", &width, &height);
        else if (!std::strcmp(argv[i], "--max-level") && i + 1 < argc)
            maxLevel = std::clamp(std::atoi(argv[++i]), 0, kMaxLevel);
    }
    std::unique_ptr<gl::HeadlessContext> ctx;
    const Status st = gl::HeadlessContext::create(&ctx);
    if (!st) {
        std::fprintf(stderr, "bench_gpu: %s\n", st.message().c_str());
        return 1;
    }
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
