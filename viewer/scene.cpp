#include "scene.h"

#include "strata/displacement_math.h"

#include "strata/baker/distance.h"
#include "strata/baker/mesh_input.h"
#include "strata/gl/shaders.h"
#include "strata/io/file.h"
#include "strata/io/mesh_io.h"
#include "strata/io/rig_io.h"
#include "strata/normals.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

namespace strata {
namespace viewer {

Scene::Scene() = default;

Scene::~Scene()
{
    if (lineProgram_) {
        glDeleteProgram(lineProgram_);
        glDeleteVertexArrays(1, &lineVao_);
        glDeleteBuffers(1, &lineBuffer_);
    }
}

Status Scene::open(const std::string& path)
{
    auto rig = std::make_unique<Rig>();
    Status st;
    if (io::extensionOf(path) == ".obj") {
        if (!(st = io::readObj(path, &rig->mesh)) || !(st = validateControlMesh(rig->mesh)))
            st = Status(st.code(), st.message().rfind(path, 0) == 0 ? st.message() : path + ": " + st.message());
    } else {
        st = io::loadRig(path, rig.get());
    }
    DisplacementMap map;
    if (st && rigNeedsMap(*rig))
        st = io::loadRigDisplacementMap(path, *rig, &map);
    if (!st) {
        lastError_ = st.message();
        return st;
    }
    io::SceneMaterials materials;
    std::vector<std::string> materialWarnings;
    if (st)
        st = io::loadSceneMaterials(*rig, &materials, &materialWarnings);
    if (!st) {
        lastError_ = st.message();
        return st;
    }
    for (const std::string& w : materialWarnings)
        rig->warnings.push_back(w);
    // Commit: the new model replaces the old one.
    rig_ = std::move(rig);
    materials_ = std::move(materials);
    path_ = path;
    map_ = std::move(map);
    haveMap_ = rig_->hasDisplacement;
    highPositions_.clear();
    highTriangles_.clear();
    animated_ = !rig_->skeleton.empty();
    if (!settings.schemeGiven)
        settings.scheme = haveMap_ ? rig_->displacement.scheme : Scheme::Linear;
    if (settings.level < 0)
        settings.level = haveMap_ ? rig_->displacement.recommendedLevel : 2;
    settings.level = std::min(settings.level, kMaxLevel);
    if (settings.animation >= int(rig_->skeleton.animations.size()))
        settings.animation = -1;
    lo_ = glm::vec3(1e30f);
    hi_ = glm::vec3(-1e30f);
    for (const glm::vec3& p : rig_->mesh.positions) {
        lo_ = glm::min(lo_, p);
        hi_ = glm::max(hi_, p);
    }
    radius_ = std::max(0.5f * glm::length(hi_ - lo_), 1e-6f);
    dMin_ = dMax_ = 0.0f;
    if (haveMap_ && !map_.texels.empty()) {
        const auto mm = std::minmax_element(map_.texels.begin(), map_.texels.end());
        dMin_ = shared::strata_decode_distance(*mm.first, map_.factor, map_.offset);
        dMax_ = shared::strata_decode_distance(*mm.second, map_.factor, map_.offset);
        if (dMin_ > dMax_)  // a negative factor
            std::swap(dMin_, dMax_);
    } else if (haveMap_ && !rig_->displacement.vertexValues.empty()) {
        const std::vector<float>& d = rig_->displacement.vertexValues;
        const auto mm = std::minmax_element(d.begin(), d.end());
        dMin_ = *mm.first;
        dMax_ = *mm.second;
    }
    description_ = io::stemOf(path) + ": " + std::to_string(rig_->mesh.vertexCount()) + " control vertices, " +
                   std::to_string(rig_->mesh.faceCount()) + " triangles" +
                   (haveMap_ ? ", " + std::to_string(map_.width) + "x" + std::to_string(map_.height) + " map" : "") +
                   (animated_ ? ", " + std::to_string(rig_->skeleton.skin.joints.size()) + " joints" : "");
    builtLevel_ = -1;
    lastError_.clear();
    frameModel();
    framePose_ = animated_;
    if ((st = rebuild()))
        buildLines();
    return st;
}

Status Scene::openHigh(const std::string& path)
{
    baker::TriangleMesh high;
    Status st = baker::loadHighMesh(path, &high, nullptr);
    if (!st) {
        lastError_ = st.message();
        return st;
    }
    highPositions_ = std::move(high.positions);
    highTriangles_ = std::move(high.triangles);
    computeErrors();
    return Status::ok();
}

void Scene::frameModel()
{
    // The bounding sphere fits the narrower of the two fields of view.
    camera.target = 0.5f * (lo_ + hi_);
    const float halfY = 0.5f * camera.fovY;
    const float halfX = std::atan(std::tan(halfY) * std::max(aspect_, 1e-3f));
    camera.distance = radius_ * 1.08f / std::sin(std::min(halfX, halfY));
}

float Scene::animationLength() const
{
    if (!rig_ || settings.animation < 0)
        return 0.0f;
    const Animation& a = rig_->skeleton.animations[size_t(settings.animation)];
    return a.end - a.start;
}

void Scene::setTiming(bool on)
{
    timing_ = on;
    if (surface_)
        surface_->setTiming(on);
}

const gl::GpuTimings& Scene::gpuTimings() const
{
    static const gl::GpuTimings none;
    return surface_ ? surface_->timings() : none;
}

Status Scene::rebuild()
{
    // The one sequence every front end uses (strata::Surface): the rig's
    // scheme with its displacement (another scheme is refused, and the view
    // stays on the last one that worked), the rig's values applied.
    SurfaceOptions options;
    options.level = settings.level;
    options.scheme = settings.scheme;
    options.schemeGiven = true;
    options.displace = haveMap_;
    std::unique_ptr<Surface> cpu;
    Status st = Surface::create(&cpu, *rig_, &map_, options);
    std::unique_ptr<gl::GpuSurface> surface;
    if (st)
        st = gl::GpuSurface::create(&surface, cpu->plan());
    if (st && haveMap_ && !map_.texels.empty())
        st = surface->setDisplacementMap(map_);
    // A rig with per-vertex displacements: the GPU gets the CPU's own values.
    if (st && haveMap_ && rig_->displacement.vertexLevel >= 0)
        st = surface->setDisplacements(cpu->plan().displacements().data(), cpu->plan().displacements().size());
    if (!st) {
        lastError_ = st.message();
        return st;
    }
    cpu_ = std::move(cpu);
    surface_ = std::move(surface);
    surface_->setTiming(timing_);
    builtMaterials_ = settings.materials;
    if (settings.materials && !(st = uploadMaterials())) {
        lastError_ = st.message();
        return st;
    }
    builtLevel_ = settings.level;
    builtScheme_ = settings.scheme;
    computeErrors();
    return Status::ok();
}

// Each part's refined faces with its material; the base colour UVs refined
// through the same faces as face-varying data.
Status Scene::uploadMaterials()
{
    if (rig_->parts.empty() || rig_->fileCorners.size() != rig_->mesh.triangles.size())
        return Status::ok();  // not from a glTF scene: flat grey
    FaceVaryingRefinement fv;
    Status st = refineFaceVarying(&fv, rig_->mesh, rig_->fileCorners.data(), rig_->sourceVertex.size(), settings.level);
    if (!st)
        return st;
    std::vector<glm::vec2> corners(fv.corners.size()), corners2(materials_.fileUVs2.empty() ? 0 : corners.size());
    std::vector<glm::vec4> colours(materials_.fileColours.empty() ? 0 : fv.corners.size());
    for (size_t c = 0; c < corners.size(); ++c) {
        glm::vec2 uv(0.0f), uv2(0.0f);
        glm::vec4 colour(0.0f);
        for (uint32_t k = fv.offsets[fv.corners[c]]; k < fv.offsets[fv.corners[c] + 1]; ++k) {
            uv += fv.weights[k] * materials_.fileUVs[fv.sources[k]];
            if (!corners2.empty())
                uv2 += fv.weights[k] * materials_.fileUVs2[fv.sources[k]];
            if (!colours.empty())
                colour += fv.weights[k] * materials_.fileColours[fv.sources[k]];
        }
        corners[c] = uv;
        if (!corners2.empty())
            corners2[c] = uv2;
        if (!colours.empty())
            colours[c] = colour;
    }
    std::vector<gl::SurfaceMaterial> mats;
    for (const io::MaterialInfo& m : materials_.materials) {
        gl::SurfaceMaterial g;
        g.baseColor = m.baseColor;
        g.alphaMode = int(m.alphaMode);
        g.alphaCutoff = m.alphaCutoff;
        g.emissive = m.emissive;
        g.wrapS = int(m.wrapS);
        g.wrapT = int(m.wrapT);
        g.secondWrapS = int(m.second.wrapS);
        g.secondWrapT = int(m.second.wrapT);
        // Image `index` (none: -1), read through UV channel `channel`.
        const auto texture = [&](int index, int channel) {
            gl::SurfaceTexture t;
            if (index < 0 || size_t(index) >= materials_.images.size() || materials_.images[size_t(index)].rgba.empty())
                return t;
            const io::ImageRGBA& im = materials_.images[size_t(index)];
            t.width = im.width;
            t.height = im.height;
            t.rgba = im.rgba.data();
            t.second = channel == 1;
            return t;
        };
        g.baseColorTexture = texture(m.image, 0);
        g.emissiveTexture = texture(m.emissiveImage, m.emissiveChannel);
        g.metallicRoughnessTexture = texture(m.metallicRoughnessImage, m.metallicRoughnessChannel);
        g.occlusionTexture = texture(m.occlusionImage, m.occlusionChannel);
        g.normalTexture = texture(m.normalImage, m.normalChannel);
        g.normalScale = m.normalScale;
        g.metallic = m.metallic;
        g.roughness = m.roughness;
        g.occlusionStrength = m.occlusionStrength;
        mats.push_back(g);
    }
    const size_t per = size_t(1) << (2 * settings.level);
    std::vector<gl::MaterialRange> ranges;
    for (size_t p = 0; p < rig_->parts.size(); ++p) {
        const RigPart& part = rig_->parts[p];
        if (part.faceCount)
            ranges.push_back(
                {size_t(part.firstFace) * per, size_t(part.faceCount) * per, materials_.partMaterial[p], part.flat});
    }
    return surface_->setMaterials(mats, ranges, corners, colours, corners2);
}

void Scene::computeErrors()
{
    if (!surface_ || highPositions_.empty())
        return;
    // Distance of the bind-pose reconstruction to the high-res mesh, on the
    // CPU by the surface the GPU one was built from (update() poses it again
    // every frame).
    std::vector<glm::vec3> positions(cpu_->vertexCount());
    if (!cpu_->setRestPose() || !cpu_->evaluate(positions.data(), nullptr, positions.size()))
        return;
    baker::TriangleIndex index;
    index.build(highPositions_.data(), highTriangles_.data(), highTriangles_.size() / 3);
    std::vector<float> errors(positions.size());
    errorMax_ = 0.0f;
    for (size_t v = 0; v < positions.size(); ++v) {
        errors[v] = float(index.nearest(glm::dvec3(positions[v])));
        errorMax_ = std::max(errorMax_, errors[v]);
    }
    surface_->setVertexErrors(errors.data());
}

void Scene::buildLines()
{
    if (!lineProgram_) {
        if (!gl::buildProgram(&lineProgram_, "lines",
                              {{GL_VERTEX_SHADER, gl::linesShaderSource(GL_VERTEX_SHADER)},
                               {GL_FRAGMENT_SHADER, gl::linesShaderSource(GL_FRAGMENT_SHADER)}}))
            return;
        glCreateVertexArrays(1, &lineVao_);
    }
    lines_.clear();
    // Ground grid under the model, 20 cells across its size.
    const float y = lo_.y, extent = 2.0f * radius_, step = extent / 10.0f;
    const glm::vec3 c = 0.5f * (lo_ + hi_);
    for (int i = -10; i <= 10; ++i) {
        const float o = float(i) * step;
        lines_.push_back({c.x + o, y, c.z - extent});
        lines_.push_back({c.x + o, y, c.z + extent});
        lines_.push_back({c.x - extent, y, c.z + o});
        lines_.push_back({c.x + extent, y, c.z + o});
    }
    gridFirst_ = 0;
    gridCount_ = int(lines_.size());
    // Control cage: one segment per unique edge, found once here; update()
    // re-fills the segments from the posed control vertices.
    cageFirst_ = int(lines_.size());
    std::set<std::pair<uint32_t, uint32_t>> edges;
    const std::vector<uint32_t>& t = rig_->mesh.triangles;
    for (size_t f = 0; f < t.size(); f += 3)
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = t[f + size_t(k)], b = t[f + size_t((k + 1) % 3)];
            edges.insert({std::min(a, b), std::max(a, b)});
        }
    cageEdges_.clear();
    for (const auto& e : edges) {
        cageEdges_.insert(cageEdges_.end(), {e.first, e.second});
        lines_.push_back(rig_->mesh.positions[e.first]);
        lines_.push_back(rig_->mesh.positions[e.second]);
    }
    cageCount_ = int(lines_.size()) - cageFirst_;
    if (lineBuffer_)
        glDeleteBuffers(1, &lineBuffer_);
    glCreateBuffers(1, &lineBuffer_);
    glNamedBufferStorage(lineBuffer_, GLsizeiptr(lines_.size() * sizeof(glm::vec3)), lines_.data(),
                         GL_DYNAMIC_STORAGE_BIT);
    glVertexArrayVertexBuffer(lineVao_, 0, lineBuffer_, 0, sizeof(glm::vec3));
    glVertexArrayAttribFormat(lineVao_, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(lineVao_, 0, 0);
    glEnableVertexArrayAttrib(lineVao_, 0);
}

void Scene::update(float dt)
{
    if (!rig_)
        return;
    settings.level = std::clamp(settings.level, 0, kMaxLevel);
    if (settings.level != builtLevel_ || settings.scheme != builtScheme_ || settings.materials != builtMaterials_) {
        if (!rebuild()) {
            // Stay on what works.
            settings.level = builtLevel_;
            settings.scheme = builtScheme_;
            if (!surface_)
                return;
        }
    }
    if (settings.animation >= 0 && settings.playing) {
        const float len = animationLength();
        settings.time = len > 0.0f ? std::fmod(settings.time + dt, len) : 0.0f;
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (animated_) {
        const float start =
            settings.animation >= 0 ? rig_->skeleton.animations[size_t(settings.animation)].start : 0.0f;
        // The paper's deformer needs a chain of joints: linear blend
        // skinning where the skin has none.
        cpu_->setSkinningMethod(settings.skinning);
        Status posed = cpu_->setAnimationTime(settings.animation, start + settings.time);
        if (!posed && settings.skinning == SkinningMethod::Segments) {
            cpu_->setSkinningMethod(SkinningMethod::Linear);
            posed = cpu_->setAnimationTime(settings.animation, start + settings.time);
        }
        // A pose refused (one that is not finite) leaves the last one drawn:
        // say so rather than play on as if it were this time's.
        if (!posed)
            lastError_ = path_ + ": " + posed.message();
    }
    // Unanimated: the surface stays in the bind pose it was made in (and that
    // computeErrors sets), so the frame re-poses nothing.
    const glm::vec3* positions = cpu_->controlPositions().data();
    const glm::vec3* normals = cpu_->controlNormals().data();
    cpuFrameMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (framePose_) {
        // A skinned mesh's bind space can be far from where its skeleton puts
        // it (CesiumMan stands up only once posed): frame the posed control
        // vertices, with the grid under their feet.
        framePose_ = false;
        lo_ = glm::vec3(1e30f);
        hi_ = glm::vec3(-1e30f);
        for (size_t v = 0; v < rig_->mesh.vertexCount(); ++v) {
            lo_ = glm::min(lo_, positions[v]);
            hi_ = glm::max(hi_, positions[v]);
        }
        const float pad = std::max(dMax_, -dMin_) * std::max(settings.scale, 0.0f);
        lo_ -= glm::vec3(pad);
        hi_ += glm::vec3(pad);
        radius_ = std::max(0.5f * glm::length(hi_ - lo_), 1e-6f);
        frameModel();
        buildLines();
    }
    surface_->setDisplacementScale(settings.displacement ? settings.scale : 0.0f);
    // The adaptive frame is evaluated in render(), once the view is known.
    if (!settings.adaptive) {
        Status st = surface_->update(positions, normals, rig_->mesh.vertexCount());
        if (!st)
            lastError_ = st.message();
    }
    if (settings.cage && lineBuffer_ && cageCount_ > 0) {
        // Posed cage edges.
        for (size_t k = 0; k < cageEdges_.size(); ++k)
            lines_[size_t(cageFirst_) + k] = positions[cageEdges_[k]];
        glNamedBufferSubData(lineBuffer_, GLintptr(size_t(cageFirst_) * sizeof(glm::vec3)),
                             GLsizeiptr(size_t(cageCount_) * sizeof(glm::vec3)), &lines_[size_t(cageFirst_)]);
    }
}

void Scene::render(int width, int height)
{
    glViewport(0, 0, width, height);
    glClearColor(0.16f, 0.17f, 0.19f, 1.0f);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    if (!surface_)
        return;
    glEnable(GL_DEPTH_TEST);
    const float aspect = float(width) / float(std::max(height, 1));
    if (aspect != aspect_) {
        aspect_ = aspect;
        if (!userCamera_)
            frameModel();
    }
    const glm::vec3 dir(std::cos(camera.pitch) * std::sin(camera.yaw), std::sin(camera.pitch),
                        std::cos(camera.pitch) * std::cos(camera.yaw));
    const glm::vec3 eye = camera.target + camera.distance * dir;
    const float nearPlane = std::max(camera.distance - 4.0f * radius_, camera.distance * 0.01f);
    const glm::mat4 viewProjection = glm::perspective(camera.fovY, aspect, nearPlane, camera.distance + 6.0f * radius_) *
                                     glm::lookAt(eye, camera.target, glm::vec3(0, 1, 0));
    gl::DrawParams p;
    p.viewProjection = viewProjection;
    p.eye = eye;
    p.colorMode = settings.colorMode;
    p.wireframe = settings.wireframe;
    // Without material ranges (false colour, --no-materials) the surface is
    // flat where every part is.
    p.flatShading = allPartsFlat(*rig_);
    if (settings.colorMode == gl::ColorMode::Displacement)
        p.colorRange = glm::vec2(dMin_ * settings.scale, dMax_ * settings.scale);
    else if (settings.colorMode == gl::ColorMode::Error)
        p.colorRange = glm::vec2(0.0f, std::max(errorMax_, 1e-12f));
    if (settings.adaptive)
        renderAdaptive(eye, height, &p);
    else
        surface_->draw(p);
    if (lineProgram_) {
        glUseProgram(lineProgram_);
        glUniformMatrix4fv(glGetUniformLocation(lineProgram_, "u_viewProjection"), 1, GL_FALSE,
                           glm::value_ptr(viewProjection));
        glBindVertexArray(lineVao_);
        if (settings.grid) {
            glUniform4f(glGetUniformLocation(lineProgram_, "u_color"), 0.42f, 0.44f, 0.48f, 1.0f);
            glDrawArrays(GL_LINES, gridFirst_, gridCount_);
        }
        if (settings.cage) {
            glUniform4f(glGetUniformLocation(lineProgram_, "u_color"), 1.0f, 0.55f, 0.1f, 1.0f);
            glDisable(GL_DEPTH_TEST);
            glDrawArrays(GL_LINES, cageFirst_, cageCount_);
            glEnable(GL_DEPTH_TEST);
        }
        glBindVertexArray(0);
        glUseProgram(0);
    }
    if (settings.colorMode == gl::ColorMode::Displacement ||
        (settings.colorMode == gl::ColorMode::Error && hasHigh()))
        drawColorScale(width, height);
}

// The adaptive frame's materials: each part's triangles (the frame lists
// them face by face), their base colour UVs at each corner's grid point,
// linear inside its control face as the plan refines UVs.
Status Scene::uploadAdaptiveMaterials(const AdaptiveFrame& frame)
{
    if (rig_->parts.empty() || rig_->fileCorners.size() != rig_->mesh.triangles.size())
        return Status::ok();  // not from a glTF scene: flat grey
    const std::vector<uint32_t>& faces = frame.triangleFaces();
    std::vector<glm::vec2> corners;
    frame.cornerUVs(&corners, materials_.fileUVs.data(), rig_->fileCorners.data());
    std::vector<glm::vec2> corners2;  // the second UV channel's
    if (!materials_.fileUVs2.empty())
        frame.cornerUVs(&corners2, materials_.fileUVs2.data(), rig_->fileCorners.data());
    // COLOR_0 interpolates as the UVs do: its red-green and blue-alpha halves
    // through the same call.
    std::vector<glm::vec4> colours;
    if (!materials_.fileColours.empty()) {
        std::vector<glm::vec2> rg(materials_.fileColours.size()), ba(rg.size()), half;
        for (size_t v = 0; v < rg.size(); ++v) {
            rg[v] = glm::vec2(materials_.fileColours[v].r, materials_.fileColours[v].g);
            ba[v] = glm::vec2(materials_.fileColours[v].b, materials_.fileColours[v].a);
        }
        frame.cornerUVs(&half, rg.data(), rig_->fileCorners.data());
        colours.resize(half.size());
        for (size_t c = 0; c < half.size(); ++c)
            colours[c] = glm::vec4(half[c], 0.0f, 0.0f);
        frame.cornerUVs(&half, ba.data(), rig_->fileCorners.data());
        for (size_t c = 0; c < half.size() && c < colours.size(); ++c)
            colours[c] = glm::vec4(colours[c].r, colours[c].g, half[c]);
    }
    std::vector<gl::MaterialRange> ranges;
    size_t t = 0;
    for (size_t p = 0; p < rig_->parts.size(); ++p) {
        const RigPart& part = rig_->parts[p];
        while (t < faces.size() && faces[t] < part.firstFace)
            ++t;
        const size_t first = t;
        while (t < faces.size() && faces[t] < size_t(part.firstFace) + part.faceCount)
            ++t;
        if (t > first)
            ranges.push_back({first, t - first, materials_.partMaterial[p], part.flat});
    }
    return surface_->setAdaptiveMaterials(ranges, corners, colours, corners2);
}

// The adaptive frame for this view: levels chosen for the current pose,
// the GPU frame set up again only when they change, evaluated and drawn.
void Scene::renderAdaptive(const glm::vec3& eye, int height, gl::DrawParams* p)
{
    ViewSpec view;
    view.eye = eye;
    view.target = camera.target;
    view.fovYDegrees = glm::degrees(camera.fovY);
    view.heightPx = float(std::max(height, 1));
    const auto t0 = std::chrono::steady_clock::now();
    Status st = cpu_->chooseFaceLevels(view, std::max(settings.pixelError, 0.01f));
    adaptiveChooseMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const AdaptiveFrame& frame = cpu_->adaptiveFrame();
    if (st && frame.quarterLevels() != drawnLevels_) {
        st = surface_->setAdaptive(frame);
        drawnLevels_ = frame.quarterLevels();
        if (st && builtMaterials_)
            st = uploadAdaptiveMaterials(frame);
    }
    if (st)
        st = surface_->updateAdaptive(cpu_->controlPositions().data(), cpu_->controlNormals().data(),
                                      cpu_->controlVertexCount());
    if (!st) {
        lastError_ = "adaptive: " + st.message();
        settings.adaptive = false;
        return;
    }
    adaptiveVertices_ = frame.vertexCount();
    adaptiveTriangles_ = frame.triangleCount();
    const std::vector<uint8_t>& quarters = frame.quarterLevels();
    adaptiveLevels_[0] = quarters.empty() ? 0 : *std::min_element(quarters.begin(), quarters.end());
    adaptiveLevels_[1] = quarters.empty() ? 0 : *std::max_element(quarters.begin(), quarters.end());
    if (settings.levelColours) {
        p->colorMode = gl::ColorMode::Error;
        p->colorRange = glm::vec2(0.0f, float(std::max(cpu_->level(), 1)));
    }
    surface_->drawAdaptive(*p);
}

// The false-colour ramp as a bar at the right edge, blue (low) at the bottom
// to red (high) at the top.  The ramp mirrors surface.frag.glsl's ramp().
void Scene::drawColorScale(int width, int height)
{
    auto ramp = [](float t) {
        auto c = [](float x) { return std::clamp(x, 0.0f, 1.0f); };
        return glm::vec3(c(1.5f - std::fabs(4.0f * t - 3.0f)), c(1.5f - std::fabs(4.0f * t - 2.0f)),
                         c(1.5f - std::fabs(4.0f * t - 1.0f)));
    };
    const int barW = std::max(6, width / 40), barH = height / 2, x = width - barW - std::max(8, width / 50);
    const int y0 = (height - barH) / 2, bands = 64;
    glEnable(GL_SCISSOR_TEST);
    glScissor(x - 2, y0 - 2, barW + 4, barH + 4);
    glClearColor(0.9f, 0.9f, 0.9f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    for (int b = 0; b < bands; ++b) {
        const int ya = y0 + barH * b / bands, yb = y0 + barH * (b + 1) / bands;
        const glm::vec3 c = ramp((float(b) + 0.5f) / float(bands));
        glScissor(x, ya, barW, yb - ya);
        glClearColor(c.r, c.g, c.b, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT);
    }
    glDisable(GL_SCISSOR_TEST);
}

}  // namespace viewer
}  // namespace strata
