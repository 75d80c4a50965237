// The GPU path against the CPU runtime: positions read back from the very
// vertex shader that draws (transform feedback) match Plan::evaluate to 1e-5
// of the bounding-box diagonal at levels 0..4, both schemes, in the rest
// pose and in animated frames.  Headless through EGL (llvmpipe in CI).
#include "strata/animation.h"
#include "strata/gl/context.h"
#include "strata/gl/evaluator.h"
#include "strata/gl/framebuffer.h"
#include "strata/gl/gpu_surface.h"
#include "strata/gl/shaders.h"
#include "strata/normals.h"
#include "strata/plan.h"
#include "strata/surface.h"
#include "test_rigs.h"

#include <random>
#include <set>

using strata::test::maxDistance;

#include <glm/gtc/matrix_transform.hpp>

using namespace strata;

namespace {

gl::HeadlessContext* context()
{
    static std::unique_ptr<gl::HeadlessContext> ctx;
    static Status status = gl::HeadlessContext::create(&ctx);
    EXPECT_TRUE(status.isOk()) << status.message();
    return ctx.get();
}

// The built-in example's rig (icosphere(1) + closed-form head map) with a
// two-joint skin that turns the upper half of the head.
struct ExampleRig {
    ControlMesh mesh;
    DisplacementMap map;
    Skeleton skeleton;
    float diagonal = 0.0f;
};

ExampleRig makeExampleRig()
{
    ExampleRig r;
    Rig example;
    test::makeExampleRig(&example, &r.map);
    r.mesh = example.mesh;
    Skeleton& s = r.skeleton;
    test::twoJointSkin(&s, r.mesh, "neck", "head", glm::vec3(0.0f), glm::vec3(0.0f, 0.5f, 0.0f),
                       [](const glm::vec3& p) { return glm::clamp(p.y + 0.5f, 0.0f, 1.0f); });
    Animation turn;
    turn.name = "turn";
    const glm::quat q0(1, 0, 0, 0), q1 = glm::angleAxis(glm::radians(50.0f), glm::normalize(glm::vec3(1, 1, 0)));
    turn.channels.push_back(test::rotationKeys(1, {0.0f, 1.0f}, {q0, q1}));
    s.animations.push_back(turn);
    EXPECT_TRUE(finalizeSkeleton(&s, r.mesh.vertexCount()).isOk());
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const glm::vec3& p : r.mesh.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    r.diagonal = glm::length(hi - lo);
    return r;
}

}  // namespace

TEST(Gpu, HeadlessContextIsOpenGL45Core)
{
    gl::HeadlessContext* ctx = context();
    ASSERT_NE(ctx, nullptr);
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    EXPECT_GE(major * 10 + minor, 45) << ctx->description();
}

TEST(Gpu, DisplacedPositionsMatchTheCpuAtLevels0To4RestAndAnimated)
{
    ASSERT_NE(context(), nullptr);
    const ExampleRig rig = makeExampleRig();
    Animator animator;
    ASSERT_TRUE(animator.init(rig.skeleton, rig.mesh).isOk());
    float worst[2] = {0.0f, 0.0f};
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        for (int level = 0; level <= 4; ++level) {
            std::unique_ptr<Plan> plan;
            ASSERT_TRUE(Plan::create(&plan, rig.mesh, scheme, level).isOk());
            ASSERT_TRUE(plan->setDisplacement(rig.map).isOk());
            std::unique_ptr<gl::GpuSurface> gpu;
            const Status st = gl::GpuSurface::create(&gpu, *plan);
            ASSERT_TRUE(st.isOk()) << st.message();
            ASSERT_TRUE(gpu->setDisplacementMap(rig.map).isOk());
            const size_t n = plan->refinedVertexCount();
            std::vector<glm::vec3> cpu(n), fromGpu;
            // Rest pose (animation -1), then two animated frames.
            for (float t : {-1.0f, 0.4f, 1.0f}) {
                ASSERT_TRUE(animator.pose(t < 0.0f ? -1 : 0, std::max(t, 0.0f)).isOk());
                const std::vector<glm::vec3>& cp = animator.positions();
                ASSERT_TRUE(plan->evaluate(cpu.data(), nullptr, 0, n, cp.data(), animator.normals().data(), cp.size())
                                .isOk());
                ASSERT_TRUE(gpu->update(cp.data(), animator.normals().data(), cp.size()).isOk());
                ASSERT_TRUE(gpu->readPositions(&fromGpu).isOk());
                ASSERT_EQ(fromGpu.size(), n);
                const float err = maxDistance(cpu, fromGpu) / rig.diagonal;
                EXPECT_LE(err, 1e-5f) << schemeName(scheme) << " level " << level << " t " << t;
                worst[int(scheme)] = std::max(worst[int(scheme)], err);
                if (t == 0.4f && level == 3) {
                    // Shading normals from the normal pass match the CPU's.
                    std::vector<glm::vec3> cpuNormals(n), gpuNormals;
                    plan->computeShadingNormals(cpuNormals.data(), cpu.data());
                    ASSERT_TRUE(gpu->readNormals(&gpuNormals).isOk());
                    EXPECT_LE(maxDistance(cpuNormals, gpuNormals), 1e-4f) << schemeName(scheme);
                }
            }
        }
    }
    std::printf("GPU vs CPU, largest difference / diagonal: linear %.2g, smooth %.2g (%s)\n", double(worst[0]),
                double(worst[1]), context()->description().c_str());
}

TEST(Gpu, HardwareFilteringStaysCloseAndScaleZeroIsTheBareSurface)
{
    ASSERT_NE(context(), nullptr);
    const ExampleRig rig = makeExampleRig();
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, rig.mesh, Scheme::Linear, 3).isOk());
    ASSERT_TRUE(plan->setDisplacement(rig.map).isOk());
    std::unique_ptr<gl::GpuSurface> gpu;
    ASSERT_TRUE(gl::GpuSurface::create(&gpu, *plan).isOk());
    ASSERT_TRUE(gpu->setDisplacementMap(rig.map).isOk());
    std::vector<glm::vec3> normals(rig.mesh.vertexCount()), cpu(plan->refinedVertexCount()), fromGpu;
    computeControlNormals(normals.data(), rig.mesh.positions.data(), normals.size(), rig.mesh.triangles.data(),
                          rig.mesh.faceCount());
    ASSERT_TRUE(gpu->update(rig.mesh.positions.data(), normals.data(), normals.size()).isOk());
    ASSERT_TRUE(plan->evaluate(cpu.data(), nullptr, 0, cpu.size(), rig.mesh.positions.data(), normals.data(),
                               normals.size())
                    .isOk());
    // The texture unit's bilinear weights have 8 fractional bits: close,
    // not identical.
    gpu->setSampleFilter(gl::SampleFilter::Hardware);
    ASSERT_TRUE(gpu->readPositions(&fromGpu).isOk());
    EXPECT_LE(maxDistance(cpu, fromGpu) / rig.diagonal, 1e-3f);
    // Scale 0: the undisplaced refined surface.
    gpu->setSampleFilter(gl::SampleFilter::Shared);
    gpu->setDisplacementScale(0.0f);
    plan->clearDisplacement();
    ASSERT_TRUE(plan->evaluate(cpu.data(), nullptr, 0, cpu.size(), rig.mesh.positions.data(), normals.data(),
                               normals.size())
                    .isOk());
    ASSERT_TRUE(gpu->readPositions(&fromGpu).isOk());
    EXPECT_LE(maxDistance(cpu, fromGpu) / rig.diagonal, 1e-6f);
    // Wrong control count: an error, not a crash.
    EXPECT_FALSE(gpu->update(rig.mesh.positions.data(), normals.data(), 3).isOk());
}

// A rig that stores its displacements per refined vertex: the GPU uses the
// CPU's very values (no map in between), in both schemes, and returns to
// the map when told to.
TEST(Gpu, PerVertexDisplacementsMatchTheCpu)
{
    ASSERT_NE(context(), nullptr);
    const ExampleRig rig = makeExampleRig();
    std::vector<glm::vec3> normals(rig.mesh.vertexCount());
    computeControlNormals(normals.data(), rig.mesh.positions.data(), normals.size(), rig.mesh.triangles.data(),
                          rig.mesh.faceCount());
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        std::unique_ptr<Plan> plan;
        ASSERT_TRUE(Plan::create(&plan, rig.mesh, scheme, 3).isOk());
        // Per-vertex values unlike anything the map holds.
        std::vector<float> values(plan->refinedVertexCount());
        for (size_t v = 0; v < values.size(); ++v)
            values[v] = 0.02f * std::sin(0.37f * float(v));
        ASSERT_TRUE(plan->setDisplacements(values.data(), values.size()).isOk());
        std::unique_ptr<gl::GpuSurface> gpu;
        ASSERT_TRUE(gl::GpuSurface::create(&gpu, *plan).isOk());
        ASSERT_TRUE(gpu->setDisplacementMap(rig.map).isOk());
        ASSERT_TRUE(gpu->setDisplacements(plan->displacements().data(), plan->displacements().size()).isOk());
        std::vector<glm::vec3> cpu(plan->refinedVertexCount()), fromGpu;
        ASSERT_TRUE(gpu->update(rig.mesh.positions.data(), normals.data(), normals.size()).isOk());
        ASSERT_TRUE(plan->evaluate(cpu.data(), nullptr, 0, cpu.size(), rig.mesh.positions.data(), normals.data(),
                                   normals.size())
                        .isOk());
        ASSERT_TRUE(gpu->readPositions(&fromGpu).isOk());
        EXPECT_LE(maxDistance(cpu, fromGpu) / rig.diagonal, 1e-6f) << schemeName(scheme);
        // Back to the map: the map's surface again.
        ASSERT_TRUE(gpu->setDisplacements(nullptr, 0).isOk());
        ASSERT_TRUE(plan->setDisplacement(rig.map).isOk());
        ASSERT_TRUE(plan->evaluate(cpu.data(), nullptr, 0, cpu.size(), rig.mesh.positions.data(), normals.data(),
                                   normals.size())
                        .isOk());
        ASSERT_TRUE(gpu->update(rig.mesh.positions.data(), normals.data(), normals.size()).isOk());
        ASSERT_TRUE(gpu->readPositions(&fromGpu).isOk());
        EXPECT_LE(maxDistance(cpu, fromGpu) / rig.diagonal, 1e-5f) << schemeName(scheme);
        EXPECT_FALSE(gpu->setDisplacements(values.data(), 3).isOk());
    }
}

// The embeddable evaluator alone (no drawing): its displaced positions and
// normals equal the CPU's, and an engine's own shader that starts with
// samplingPrelude() reads the rig's displacement exactly as the CPU
// sampled it, after bindSampling().
TEST(Gpu, EvaluatorBuffersAndAnEngineShaderMatchTheCpu)
{
    ASSERT_NE(context(), nullptr);
    const ExampleRig rig = makeExampleRig();
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, rig.mesh, Scheme::Linear, 3).isOk());
    ASSERT_TRUE(plan->setDisplacement(rig.map).isOk());
    std::unique_ptr<gl::Evaluator> eval;
    const Status st = gl::Evaluator::create(&eval, *plan);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_TRUE(eval->setDisplacementMap(rig.map).isOk());
    const size_t n = plan->refinedVertexCount();
    std::vector<glm::vec3> normals(rig.mesh.vertexCount()), cpu(n), cpuNormals(n), gpu, gpuNormals;
    computeControlNormals(normals.data(), rig.mesh.positions.data(), normals.size(), rig.mesh.triangles.data(),
                          rig.mesh.faceCount());
    ASSERT_TRUE(plan->evaluate(cpu.data(), nullptr, 0, n, rig.mesh.positions.data(), normals.data(), normals.size())
                    .isOk());
    plan->computeShadingNormals(cpuNormals.data(), cpu.data());
    ASSERT_TRUE(eval->update(rig.mesh.positions.data(), normals.data(), normals.size()).isOk());
    ASSERT_TRUE(eval->readPositions(&gpu).isOk());
    ASSERT_TRUE(eval->readNormals(&gpuNormals).isOk());
    EXPECT_LE(maxDistance(cpu, gpu) / rig.diagonal, 1e-5f);
    EXPECT_LE(maxDistance(cpuNormals, gpuNormals), 1e-4f);

    // An engine's compute shader: d for every refined vertex at its sample UV.
    const std::string source = gl::samplingPrelude() + R"(
layout(local_size_x = 64) in;
layout(std430, binding = 7) readonly buffer SampleUVs { vec2 sampleUVs[]; };
layout(std430, binding = 3) writeonly buffer Out { float outD[]; };
uniform uint u_count;
void main()
{
    uint v = gl_GlobalInvocationID.x;
    if (v < u_count)
        outD[v] = strata_vertex_displacement(v, sampleUVs[v]);
}
)";
    GLuint program = 0;
    const Status built = gl::buildProgram(&program, "engine shader", {{GL_COMPUTE_SHADER, source}});
    ASSERT_TRUE(built.isOk()) << built.message();
    GLuint out = 0;
    glCreateBuffers(1, &out);
    glNamedBufferStorage(out, GLsizeiptr(n * 4), nullptr, 0);
    eval->bindSampling(program);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, gl::kSampleUVs, eval->buffer(gl::kSampleUVs));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, out);
    glUseProgram(program);
    glUniform1ui(glGetUniformLocation(program, "u_count"), GLuint(n));
    glDispatchCompute(GLuint((n + 63) / 64), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<float> d(n);
    glGetNamedBufferSubData(out, 0, GLsizeiptr(n * 4), d.data());
    glUseProgram(0);
    glDeleteBuffers(1, &out);
    glDeleteProgram(program);
    float worst = 0.0f;
    for (size_t v = 0; v < n; ++v)
        worst = std::max(worst, std::fabs(d[v] - plan->displacements()[v]));
    EXPECT_LE(worst, 1e-6f * rig.diagonal);
}

// The adaptive frame on the GPU (Evaluator::setAdaptive/updateAdaptive):
// positions and shading normals of the frame's vertices match the CPU's
// AdaptiveFrame at random level mixes, both schemes, animated, and a new
// mix of levels reuses or grows the buffers.
TEST(Gpu, AdaptiveFramesMatchTheCpuAtRandomLevelMixes)
{
    ASSERT_NE(context(), nullptr);
    std::mt19937 rng(11);
    for (Scheme scheme : {Scheme::Linear, Scheme::Smooth}) {
        Rig rig;
        DisplacementMap map;
        test::makeBendingExampleRig(&rig, &map);
        rig.displacement.scheme = scheme;
        std::unique_ptr<Surface> s;
        ASSERT_TRUE(Surface::create(&s, rig, &map).isOk());
        std::unique_ptr<gl::Evaluator> gpu;
        Status st = gl::Evaluator::create(&gpu, s->plan());
        ASSERT_TRUE(st.isOk()) << st.message();
        ASSERT_TRUE(gpu->setDisplacements(s->plan().displacements().data(), s->vertexCount()).isOk());
        float diagonal = 0.0f;
        {
            glm::vec3 lo(1e30f), hi(-1e30f);
            for (const glm::vec3& p : rig.mesh.positions) {
                lo = glm::min(lo, p);
                hi = glm::max(hi, p);
            }
            diagonal = glm::length(hi - lo);
        }
        std::vector<uint8_t> levels(rig.mesh.faceCount()), quarters(4 * levels.size());
        for (int trial = 0; trial < 6; ++trial) {
            std::uniform_int_distribution<int> any(0, s->level()), quarter(1, s->level());
            for (uint8_t& l : levels)
                l = uint8_t(trial == 0 ? s->level() : any(rng));
            if (trial < 4) {
                ASSERT_TRUE(s->setFaceLevels(levels.data(), levels.size()).isOk());
            } else {  // each quarter of a face at its own level
                for (uint8_t& q : quarters)
                    q = uint8_t(quarter(rng));
                ASSERT_TRUE(s->setQuarterLevels(quarters.data(), quarters.size()).isOk());
            }
            ASSERT_TRUE(s->setAnimationTime(0, 0.3f * float(trial)).isOk());
            const AdaptiveFrame& frame = s->adaptiveFrame();
            std::vector<glm::vec3> p(frame.vertexCount()), n(p.size()), gp, gn;
            ASSERT_TRUE(s->evaluateAdaptive(p.data(), n.data(), p.size()).isOk());
            ASSERT_TRUE(gpu->setAdaptive(frame).isOk());
            ASSERT_TRUE(gpu->updateAdaptive(s->controlPositions().data(), s->controlNormals().data(),
                                            s->controlVertexCount())
                            .isOk());
            ASSERT_TRUE(gpu->readAdaptivePositions(&gp).isOk());
            ASSERT_TRUE(gpu->readAdaptiveNormals(&gn).isOk());
            ASSERT_EQ(gp.size(), p.size());
            const std::string label = std::string(schemeName(scheme)) + " trial " + std::to_string(trial);
            EXPECT_LE(maxDistance(p, gp) / diagonal, 1e-5f) << label;
            EXPECT_LE(maxDistance(n, gn), 1e-4f) << label;
            EXPECT_EQ(gpu->adaptiveTriangleCount(), frame.triangleCount()) << label;
            // The indirect command draws every triangle of the frame.
            GLuint command[5] = {};
            glGetNamedBufferSubData(gpu->adaptiveBuffer(gl::AdaptiveBuffer::Indirect), 0, sizeof(command), command);
            EXPECT_EQ(command[0], 3 * frame.triangleCount()) << label;
            EXPECT_EQ(command[1], 1u) << label;
        }
    }
}

// The adaptive draw (GpuSurface::drawAdaptive, one glDrawElementsIndirect)
// covers the same pixels as the uniform finest draw, and its level false
// colour shows several levels when the faces have several.
TEST(Gpu, AdaptiveDrawCoversWhatTheUniformDrawCovers)
{
    ASSERT_NE(context(), nullptr);
    Rig rig;
    DisplacementMap map;
    std::unique_ptr<Surface> s = test::bendingSurfaceAt(0.5f, &rig, &map);
    ASSERT_TRUE(s);
    std::unique_ptr<gl::GpuSurface> gpu;
    ASSERT_TRUE(gl::GpuSurface::create(&gpu, s->plan()).isOk());
    ASSERT_TRUE(gpu->setDisplacements(s->plan().displacements().data(), s->vertexCount()).isOk());
    ViewSpec view;
    view.eye = glm::vec3(0.4f, 0.3f, 4.0f);
    view.heightPx = 256.0f;
    ASSERT_TRUE(s->chooseFaceLevels(view, 1.0f).isOk());
    ASSERT_TRUE(gpu->setAdaptive(s->adaptiveFrame()).isOk());
    gl::Framebuffer fb;
    ASSERT_TRUE(fb.create(256, 256, 1).isOk());
    gl::DrawParams params;
    params.eye = view.eye;
    params.viewProjection = glm::perspective(glm::radians(view.fovYDegrees), 1.0f, 0.1f, 100.0f) *
                            glm::lookAt(view.eye, view.target, glm::vec3(0, 1, 0));
    auto render = [&](bool adaptive, gl::ColorMode mode, std::vector<uint8_t>* rgb) {
        fb.bind();
        glViewport(0, 0, 256, 256);
        glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST);
        params.colorMode = mode;
        params.colorRange = glm::vec2(0.0f, float(s->level()));
        const glm::vec3* cp = s->controlPositions().data();
        const glm::vec3* cn = s->controlNormals().data();
        if (adaptive) {
            ASSERT_TRUE(gpu->updateAdaptive(cp, cn, s->controlVertexCount()).isOk());
            gpu->drawAdaptive(params);
        } else {
            ASSERT_TRUE(gpu->update(cp, cn, s->controlVertexCount()).isOk());
            gpu->draw(params);
        }
        fb.readRGB(rgb);
        ASSERT_EQ(glGetError(), GLenum(GL_NO_ERROR));
    };
    std::vector<uint8_t> uniform, adaptive, levels;
    render(false, gl::ColorMode::Shaded, &uniform);
    render(true, gl::ColorMode::Shaded, &adaptive);
    render(true, gl::ColorMode::Error, &levels);
    size_t covered[2] = {0, 0}, differ = 0;
    std::set<uint32_t> colours;
    for (size_t i = 0; i < uniform.size(); i += 3) {
        const bool u = uniform[i] | uniform[i + 1] | uniform[i + 2], a = adaptive[i] | adaptive[i + 1] | adaptive[i + 2];
        covered[0] += u;
        covered[1] += a;
        differ += u != a;
        if (levels[i] | levels[i + 1] | levels[i + 2])
            colours.insert(uint32_t(levels[i]) << 16 | uint32_t(levels[i + 1]) << 8 | levels[i + 2]);
    }
    EXPECT_GT(covered[0], size_t(256 * 256 / 10));
    // Within the 1-pixel tolerance the silhouettes differ by at most a
    // pixel along the outline.
    EXPECT_LT(differ, covered[0] / 20) << covered[0] << " " << covered[1];
    std::set<int> faceLevels(s->adaptiveFrame().levels().begin(), s->adaptiveFrame().levels().end());
    EXPECT_GT(faceLevels.size(), 1u);
    EXPECT_GT(colours.size(), 1u);
}
