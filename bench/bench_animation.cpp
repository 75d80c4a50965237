// bench_animation: the layered frame against skinning the equivalent
// high-resolution mesh directly (animation issue).
//
// For Fox and CesiumMan (../shared/data), per level 0..5, on one core:
// animation sampling (+ world and skin matrices), control-vertex skinning,
// control normals, refinement + displacement (Plan::evaluate), the total,
// and refined vertices per second, and the frame with shading normals of
// the displaced mesh (what a renderer draws).  Beside it, in the same run, linear blend
// skinning of a mesh with as many vertices as the refined level and 4
// influences per vertex (positions, and positions + normals), which is what
// an engine would do with the captured mesh.  Stored size: the layered rig
// (control glb with skin and animations + an uncompressed half-float map
// with one texel per refined vertex, an upper bound) against that mesh as a
// skinned glb (position, normal, UV, 4 joints, 4 weights, 32-bit indices)
// carrying the same skeleton and animations.
#include "bench_common.h"

#include "strata/animation.h"
#include "strata/io/rig_io.h"
#include "strata/frame.h"
#include "strata/surface.h"
#include "strata/plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <sys/stat.h>

using namespace strata;

namespace {

bench::JsonRows jsonRows;

void run(const std::string& name, const std::string& path)
{
    Rig rig;
    Status st = io::loadRig(path, &rig);
    if (!st || rig.skeleton.empty() || rig.skeleton.animations.empty()) {
        std::printf("%s: %s\n", name.c_str(), st ? "no skin or animation" : st.message().c_str());
        return;
    }
    const std::string tmp = "/tmp/strata_bench_anim_" + name + ".glb";
    io::saveRig(tmp, rig);
    struct stat sb;
    const double rigBytes = ::stat(tmp.c_str(), &sb) == 0 ? double(sb.st_size) : 0.0;
    std::remove(tmp.c_str());

    Animator animator;
    animator.init(rig.skeleton, rig.mesh);
    const float duration = rig.skeleton.animations[0].end - rig.skeleton.animations[0].start;
    float t = 0.0f;
    auto nextTime = [&] {
        t += 1.0f / 60.0f;
        if (t > duration)
            t = 0.0f;
        return rig.skeleton.animations[0].start + t;
    };
    std::printf("\n%s: %zu control vertices, %zu triangles, %zu joints, animation \"%s\"; one core, median of 7 runs\n",
                name.c_str(), rig.mesh.positions.size(), rig.mesh.faceCount(), rig.skeleton.skin.joints.size(),
                rig.skeleton.animations[0].name.c_str());
    std::printf("level | refined verts | sample ms | skin ms | eq.6 ms | normals ms | evaluate ms | frame ms | M verts/s |"
                " LBS pos ms | LBS pos+nrm ms | frame/LBS pos | layered KB | high-res KB | size ratio | frame+shading ms |"
                " frame+shading/LBS pos+nrm\n");
    std::printf("------+---------------+-----------+---------+---------+------------+-------------+----------+-----------+"
                "------------+----------------+---------------+------------+-------------+-----------\n");
    for (int level = 0; level <= 5; ++level) {
        // The rig at this level through strata::Surface, as an engine holds
        // it (its own scheme and displacements); the stage columns time the
        // surface's plan on the animator's control mesh.  One core, in tile
        // order (the order an engine draws, with Surface::triangles(); its
        // tables built before timing).
        SurfaceOptions surfaceOptions;
        surfaceOptions.level = level;
        surfaceOptions.displace = rig.hasDisplacement && !rigNeedsMap(rig);  // a map-coded rig: the bare cage
        surfaceOptions.layout = FrameLayout::Tiles;
        std::unique_ptr<Surface> surface;
        if (!Surface::create(&surface, rig, nullptr, surfaceOptions))
            return;
        const Plan* plan = &surface->plan();
        const size_t n = plan->refinedVertexCount();
        std::vector<glm::vec3> out(n);
        const double sample = bench::medianMs([&] { animator.sample(0, nextTime()); });
        const double skin = bench::medianMs([&] { animator.skin(SkinningMethod::Linear); });
        // The paper's eq. 6 deformer in place of skin weights (not in "frame").
        const double segments = animator.segmentStatus().isOk()
                                    ? bench::medianMs([&] { animator.skin(SkinningMethod::Segments); })
                                    : std::nan("");
        const double normals = bench::medianMs([&] { animator.updateNormals(); });
        const double eval = bench::medianMs([&] {
            plan->evaluate(out.data(), nullptr, 0, n, animator.positions().data(), animator.normals().data(),
                           animator.positions().size());
        });
        const double frame = bench::medianMs([&] {
            animator.pose(0, nextTime());
            plan->evaluate(out.data(), nullptr, 0, n, animator.positions().data(), animator.normals().data(),
                           animator.positions().size());
        });
        // What a renderer draws: the same frame plus shading normals of the
        // displaced mesh (the comparison an engine developer makes), through
        // the surface.
        std::vector<glm::vec3> shading(n);
        if (!surface->evaluate(out.data(), shading.data(), n, 1))
            return;
        const double frameShaded = bench::medianMs([&] {
            surface->setAnimationTime(0, nextTime());
            surface->evaluate(out.data(), shading.data(), n, 1);
        });

        // The engine's alternative: an n-vertex mesh, 4 influences each.
        const size_t joints = rig.skeleton.skin.joints.size();
        std::mt19937 rng(7);
        VertexWeights w;
        w.influences = 4;
        w.joints.resize(4 * n);
        w.weights.resize(4 * n);
        std::vector<glm::vec3> rest(n), normalsIn(n), dst(n), dstN(n);
        for (size_t v = 0; v < n; ++v) {
            rest[v] = out[v];
            normalsIn[v] = glm::vec3(0.0f, 0.0f, 1.0f);
            float sum = 0.0f;
            for (int k = 0; k < 4; ++k) {
                w.joints[4 * v + size_t(k)] = uint16_t(rng() % joints);
                w.weights[4 * v + size_t(k)] = float(rng() % 1000 + 1);
                sum += w.weights[4 * v + size_t(k)];
            }
            for (int k = 0; k < 4; ++k)
                w.weights[4 * v + size_t(k)] /= sum;
        }
        const glm::mat4* skinMatrices = animator.skinMatrices().data();
        const double lbs = bench::medianMs([&] { skinLinear(dst.data(), rest.data(), n, w, skinMatrices); });
        const double lbsN = bench::medianMs([&] {
            for (size_t v = 0; v < n; ++v) {
                glm::mat4 m(0.0f);
                for (int k = 0; k < 4; ++k)
                    m += w.weights[4 * v + size_t(k)] * skinMatrices[w.joints[4 * v + size_t(k)]];
                dst[v] = glm::vec3(m * glm::vec4(rest[v], 1.0f));
                dstN[v] = glm::normalize(glm::mat3(m) * normalsIn[v]);
            }
        });
        // Both files carry the same skeleton and animations: the rig's bytes
        // beyond its control geometry are counted on both sides.
        auto geometryBytes = [](double vertices, double faces) { return vertices * (12 + 12 + 8 + 8 + 16) + faces * 12; };
        const double shared =
            std::max(0.0, rigBytes - geometryBytes(double(rig.sourceVertex.size()), double(rig.mesh.faceCount())));
        const double layeredKB = (rigBytes + 2.0 * double(n)) / 1024.0;
        const double highKB = (geometryBytes(double(n), double(plan->refinedFaceCount())) + shared) / 1024.0;
        std::printf("%5d | %13zu | %9.4f | %7.4f | %7.4f | %10.4f | %11.4f | %8.4f | %9.1f | %10.4f | %14.4f | %13.2f | "
                    "%10.1f | %11.1f | %9.1fx | %16.4f | %25.2f\n",
                    level, n, sample, skin, segments, normals, eval, frame, double(n) / frame / 1000.0, lbs, lbsN, frame / lbs,
                    layeredKB, highKB, highKB / layeredKB, frameShaded, frameShaded / lbsN);
        jsonRows.field("rig", name)
            .field("level", level)
            .field("vertices", double(n))
            .field("frame_ms", frameShaded)
            .field("frame_positions_ms", frame)
            .field("lbs_pos_ms", lbs)
            .field("lbs_pos_nrm_ms", lbsN)
            .endRow();
        std::fflush(stdout);
    }
}

}  // namespace

int main(int argc, char** argv)
{
    std::string jsonPath;
    for (int i = 1; i < argc; ++i) {
        if (std::string(argv[i]) == "--json" && i + 1 < argc) {
            jsonPath = argv[++i];
        } else {
            std::fprintf(stderr, "usage: bench_animation [--json FILE]\n");
            return 2;
        }
    }
    const std::string data = STRATA_SHARED_DATA;
    struct stat sb;
    bool any = false;
    for (const char* name : {"Fox", "CesiumMan"}) {
        const std::string path = data + "/" + name + ".glb";
        if (::stat(path.c_str(), &sb) == 0) {
            run(name, path);
            any = true;
        }
    }
    if (!any)
        std::printf("bench_animation: %s holds neither Fox.glb nor CesiumMan.glb; nothing to measure\n", data.c_str());
    if (!jsonPath.empty() && !jsonRows.write(jsonPath)) {
        std::fprintf(stderr, "bench_animation: cannot write %s\n", jsonPath.c_str());
        return 1;
    }
    return 0;
}
