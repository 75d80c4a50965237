// The C API (strata/strata.h): a thin layer over strata::Surface, the one
// object the tools, Python and the viewer draw through, so a C program's
// numbers equal theirs bit for bit.  No exception crosses the boundary.
#include "strata/strata.h"

#include "strata/io/render_mesh.h"
#include "strata/io/rig_io.h"
#include "strata/rig.h"
#include "strata/surface.h"

#include <glm/mat4x4.hpp>

#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <vector>

using namespace strata;

struct StrataRig {
    Rig rig;
    DisplacementMap map;
};

struct StrataSurface {
    std::unique_ptr<Surface> surface;
    // Surface::evaluate keeps scratch between frames: concurrent evaluate
    // calls on one handle are serialised.
    mutable std::mutex frameMutex;
};

struct StrataRenderMesh {
    io::RenderMesh layout;
    std::vector<glm::vec3> positions, normals;  // the refined frame, before gather
    // An adaptive layout: the frame it was made for, at that version.
    const AdaptiveFrame* frame = nullptr;
    uint64_t version = 0;
};

namespace {

thread_local std::string lastError;

StrataStatus fail(StrataStatus code, const std::string& message)
{
    lastError = message;
    return code;
}

StrataStatus fromStatus(const Status& st)
{
    if (st)
        return STRATA_OK;
    switch (st.code()) {
    case StatusCode::InvalidArgument:
        return fail(STRATA_INVALID_ARGUMENT, st.message());
    case StatusCode::Unsupported:
        return fail(STRATA_UNSUPPORTED, st.message());
    case StatusCode::IoError:
        return fail(STRATA_IO_ERROR, st.message());
    default:
        return fail(STRATA_INVALID_DATA, st.message());
    }
}

// Runs body, turning any exception into a status and a message.
template <typename F>
StrataStatus guarded(F&& body)
{
    try {
        return body();
    } catch (const std::bad_alloc&) {
        return fail(STRATA_OUT_OF_MEMORY, "out of memory");
    } catch (const std::exception&) {
        return fail(STRATA_INVALID_DATA, "unexpected internal failure on this input");
    }
}

StrataStatus finishSurface(const Rig& rig, const DisplacementMap* map, const SurfaceOptions& options,
                           StrataSurface** out)
{
    auto s = std::make_unique<StrataSurface>();
    if (Status st = Surface::create(&s->surface, rig, map, options); !st)
        return fromStatus(st);
    *out = s.release();
    return STRATA_OK;
}

}  // namespace

extern "C" {

const char* strata_version(void)
{
    return STRATA_VERSION;
}

const char* strata_last_error(void)
{
    return lastError.c_str();
}

StrataStatus strata_rig_load(const char* path, StrataRig** out)
{
    if (!path || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_rig_load: null argument");
    *out = nullptr;
    return guarded([&] {
        auto r = std::make_unique<StrataRig>();
        Status st = io::loadRig(path, &r->rig);
        if (st && rigNeedsMap(r->rig))
            st = io::loadRigDisplacementMap(path, r->rig, &r->map);
        if (!st)
            return fromStatus(st);
        *out = r.release();
        return STRATA_OK;
    });
}

StrataStatus strata_rig_load_memory(const void* data, size_t size, int binary, StrataRig** out)
{
    if (!data || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_rig_load_memory: null argument");
    *out = nullptr;
    return guarded([&] {
        auto r = std::make_unique<StrataRig>();
        const std::string name = binary ? "rig.glb (memory)" : "rig.gltf (memory)";
        Status st = io::loadRigFromMemory(static_cast<const unsigned char*>(data), size, binary != 0, name, &r->rig);
        if (st && rigNeedsMap(r->rig))
            st = io::loadRigDisplacementMap(name, r->rig, &r->map);
        if (!st)
            return fromStatus(st);
        *out = r.release();
        return STRATA_OK;
    });
}

void strata_rig_destroy(StrataRig* rig)
{
    delete rig;
}

int strata_rig_recommended_level(const StrataRig* rig)
{
    return rig && rig->rig.hasDisplacement ? rig->rig.displacement.recommendedLevel : 0;
}

StrataScheme strata_rig_scheme(const StrataRig* rig)
{
    return rig && rig->rig.displacement.scheme == Scheme::Smooth ? STRATA_SCHEME_SMOOTH : STRATA_SCHEME_LINEAR;
}

size_t strata_rig_control_vertex_count(const StrataRig* rig)
{
    return rig ? rig->rig.mesh.positions.size() : 0;
}

size_t strata_rig_joint_count(const StrataRig* rig)
{
    return rig ? rig->rig.skeleton.skin.joints.size() : 0;
}

size_t strata_rig_animation_count(const StrataRig* rig)
{
    return rig ? rig->rig.skeleton.animations.size() : 0;
}

const char* strata_rig_animation_name(const StrataRig* rig, size_t index)
{
    return rig && index < rig->rig.skeleton.animations.size() ? rig->rig.skeleton.animations[index].name.c_str()
                                                              : nullptr;
}

int strata_rig_joint_node(const StrataRig* rig, size_t joint)
{
    return rig && joint < rig->rig.skeleton.skin.joints.size() ? rig->rig.skeleton.skin.joints[joint] : -1;
}

StrataStatus strata_rig_joint_inverse_bind(const StrataRig* rig, size_t joint, float* matrix)
{
    if (!rig || !matrix)
        return fail(STRATA_INVALID_ARGUMENT, "strata_rig_joint_inverse_bind: null argument");
    const Skin& skin = rig->rig.skeleton.skin;
    if (joint >= skin.inverseBindMatrices.size())
        return fail(STRATA_INVALID_ARGUMENT, "strata_rig_joint_inverse_bind: joint " + std::to_string(joint) +
                                                 " of " + std::to_string(skin.inverseBindMatrices.size()));
    std::memcpy(matrix, &skin.inverseBindMatrices[joint][0][0], 16 * sizeof(float));
    return STRATA_OK;
}

StrataStatus strata_surface_create(const StrataRig* rig, int level, StrataSurface** out)
{
    if (!rig || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_create: null argument");
    *out = nullptr;
    return guarded([&] {
        SurfaceOptions options;
        options.level = level < 0 ? -1 : level;
        return finishSurface(rig->rig, &rig->map, options, out);
    });
}

StrataStatus strata_surface_create_from_arrays(const float* positions, size_t vertex_count, const uint32_t* triangles,
                                               size_t triangle_count, const float* uvs, size_t uv_count,
                                               const uint32_t* uv_indices, const float* map_texels, int map_width,
                                               int map_height, float map_factor, float map_offset,
                                               StrataScheme scheme, int level, StrataSurface** out)
{
    if (!positions || !triangles || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_create_from_arrays: null argument");
    *out = nullptr;
    const bool displaced = map_texels != nullptr;
    if (displaced && (!uvs || !uv_indices || map_width < 1 || map_height < 1 || map_width > kMaxDisplacementMapSize ||
                      map_height > kMaxDisplacementMapSize))
        return fail(STRATA_INVALID_ARGUMENT,
                    "strata_surface_create_from_arrays: a map needs UVs, UV indices and a size in 1..16384");
    if (vertex_count > (size_t(1) << 28) || triangle_count > (size_t(1) << 28) || uv_count > (size_t(1) << 28))
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_create_from_arrays: counts are out of range");
    return guarded([&] {
        Rig rig;
        ControlMesh& m = rig.mesh;
        m.positions.resize(vertex_count);
        std::memcpy(m.positions.data(), positions, vertex_count * sizeof(glm::vec3));
        m.triangles.assign(triangles, triangles + 3 * triangle_count);
        if (uvs && uv_indices) {
            m.uvs.resize(uv_count);
            std::memcpy(m.uvs.data(), uvs, uv_count * sizeof(glm::vec2));
            m.uvIndices.assign(uv_indices, uv_indices + 3 * triangle_count);
        }
        Status st = validateControlMesh(m);
        if (!st)
            return fromStatus(st);
        // The caller's own map, sampled in the scheme asked for.
        DisplacementMap map;
        if (displaced) {
            map.width = map_width;
            map.height = map_height;
            map.texels.assign(map_texels, map_texels + size_t(map_width) * size_t(map_height));
            map.factor = map_factor;
            map.offset = map_offset;
        }
        SurfaceOptions options;
        options.level = level;
        options.scheme = scheme == STRATA_SCHEME_SMOOTH ? Scheme::Smooth : Scheme::Linear;
        options.schemeGiven = true;
        return finishSurface(rig, displaced ? &map : nullptr, options, out);
    });
}

void strata_surface_destroy(StrataSurface* surface)
{
    delete surface;
}

size_t strata_surface_vertex_count(const StrataSurface* surface)
{
    return surface ? surface->surface->vertexCount() : 0;
}

size_t strata_surface_triangle_count(const StrataSurface* surface)
{
    return surface ? surface->surface->triangleCount() : 0;
}

StrataStatus strata_surface_triangles(const StrataSurface* surface, uint32_t* dst)
{
    if (!surface || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_triangles: null argument");
    const std::vector<uint32_t>& t = surface->surface->triangles();
    std::memcpy(dst, t.data(), t.size() * sizeof(uint32_t));
    return STRATA_OK;
}

StrataStatus strata_surface_set_bind_pose(StrataSurface* surface)
{
    if (!surface)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_set_bind_pose: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        return fromStatus(surface->surface->setRestPose());
    });
}

StrataStatus strata_surface_set_animation_time(StrataSurface* surface, int animation, float time)
{
    if (!surface)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_set_animation_time: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        return fromStatus(surface->surface->setAnimationTime(animation, time));
    });
}

StrataStatus strata_surface_set_joint_matrices(StrataSurface* surface, const float* matrices, size_t joint_count)
{
    if (!surface || !matrices)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_set_joint_matrices: null argument");
    return guarded([&] {
        std::vector<glm::mat4> skin(joint_count);
        if (joint_count)
            std::memcpy(&skin[0][0][0], matrices, joint_count * 16 * sizeof(float));
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        return fromStatus(surface->surface->setJointMatrices(skin.data(), joint_count));
    });
}

StrataStatus strata_surface_set_control_positions(StrataSurface* surface, const float* positions, size_t count)
{
    if (!surface || !positions)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_set_control_positions: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        return fromStatus(
            surface->surface->setControlPositions(reinterpret_cast<const glm::vec3*>(positions), count));
    });
}

StrataStatus strata_surface_displacements(const StrataSurface* surface, float* dst)
{
    if (!surface || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_displacements: null argument");
    const Surface& s = *surface->surface;
    const std::vector<float>& d = s.plan().displacements();
    const std::vector<uint32_t>& order = s.vertexOrder();
    const size_t n = s.vertexCount();
    for (size_t i = 0; i < n; ++i) {
        const size_t v = i < order.size() ? order[i] : i;
        dst[i] = v < d.size() ? d[v] : 0.0f;
    }
    return STRATA_OK;
}

StrataStatus strata_surface_evaluate(const StrataSurface* surface, float* positions, float* normals)
{
    if (!surface || !positions)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_evaluate: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        Surface& s = *surface->surface;
        return fromStatus(s.evaluate(reinterpret_cast<glm::vec3*>(positions), reinterpret_cast<glm::vec3*>(normals),
                                     s.vertexCount()));
    });
}

StrataStatus strata_surface_choose_levels(StrataSurface* surface, const float* eye, const float* target,
                                          float fov_y_degrees, float height_px, float pixel_error)
{
    if (!surface || !eye || !target)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_choose_levels: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        ViewSpec view;
        view.eye = glm::vec3(eye[0], eye[1], eye[2]);
        view.target = glm::vec3(target[0], target[1], target[2]);
        view.fovYDegrees = fov_y_degrees;
        view.heightPx = height_px;
        return fromStatus(surface->surface->chooseFaceLevels(view, pixel_error));
    });
}

// The adaptive frame is made on first use: reads take the frame's lock too.
size_t strata_surface_adaptive_vertex_count(const StrataSurface* surface)
{
    if (!surface)
        return 0;
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    return surface->surface->adaptiveFrame().vertexCount();
}

size_t strata_surface_adaptive_triangle_count(const StrataSurface* surface)
{
    if (!surface)
        return 0;
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    return surface->surface->adaptiveFrame().triangleCount();
}

StrataStatus strata_surface_bounds(const StrataSurface* surface, float* min, float* max)
{
    if (!surface || !min || !max)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_bounds: null argument");
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    glm::vec3 lo, hi;
    surface->surface->bounds(&lo, &hi);
    for (int k = 0; k < 3; ++k) {
        min[k] = lo[k];
        max[k] = hi[k];
    }
    return STRATA_OK;
}

StrataStatus strata_surface_adaptive_triangles(const StrataSurface* surface, uint32_t* dst)
{
    if (!surface || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_adaptive_triangles: null argument");
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    const std::vector<uint32_t>& t = surface->surface->adaptiveFrame().triangles();
    std::memcpy(dst, t.data(), t.size() * sizeof(uint32_t));
    return STRATA_OK;
}

StrataStatus strata_surface_adaptive_triangle_levels(const StrataSurface* surface, uint8_t* dst)
{
    if (!surface || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_adaptive_triangle_levels: null argument");
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    const AdaptiveFrame& frame = surface->surface->adaptiveFrame();
    for (size_t t = 0; t < frame.triangleCount(); ++t)
        dst[t] = uint8_t(frame.triangleLevel(t));
    return STRATA_OK;
}

StrataStatus strata_surface_adaptive_vertices(const StrataSurface* surface, uint32_t* dst)
{
    if (!surface || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_adaptive_vertices: null argument");
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    const std::vector<uint32_t>& v = surface->surface->adaptiveFrame().vertices();
    std::memcpy(dst, v.data(), v.size() * sizeof(uint32_t));
    return STRATA_OK;
}

StrataStatus strata_surface_evaluate_adaptive(StrataSurface* surface, float* positions, float* normals)
{
    if (!surface || !positions)
        return fail(STRATA_INVALID_ARGUMENT, "strata_surface_evaluate_adaptive: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        Surface& s = *surface->surface;
        return fromStatus(s.evaluateAdaptive(reinterpret_cast<glm::vec3*>(positions),
                                             reinterpret_cast<glm::vec3*>(normals), s.adaptiveFrame().vertexCount()));
    });
}

uint32_t strata_surface_adaptive_version(const StrataSurface* surface)
{
    if (!surface)
        return 0;
    std::lock_guard<std::mutex> lock(surface->frameMutex);
    return uint32_t(surface->surface->adaptiveFrame().topologyVersion());
}

StrataStatus strata_render_mesh_create_adaptive(const StrataRenderMesh* uniform, StrataSurface* surface,
                                                StrataRenderMesh** out)
{
    if (!uniform || !surface || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_create_adaptive: null argument");
    *out = nullptr;
    if (uniform->frame)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_create_adaptive: give the surface's own render mesh, "
                                             "not an adaptive one");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        Surface& s = *surface->surface;
        const AdaptiveFrame& frame = s.adaptiveFrame();
        auto m = std::make_unique<StrataRenderMesh>();
        if (Status st = io::buildAdaptiveRenderMesh(uniform->layout, s.plan(), frame, &m->layout); !st)
            return fail(fromStatus(st), "strata_render_mesh_create_adaptive: " + st.message());
        m->frame = &frame;
        m->version = frame.topologyVersion();
        *out = m.release();
        return STRATA_OK;
    });
}

StrataStatus strata_render_mesh_create(const StrataRig* rig, const StrataSurface* surface, StrataRenderMesh** out)
{
    if (!rig || !surface || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_create: null argument");
    *out = nullptr;
    return guarded([&] {
        auto m = std::make_unique<StrataRenderMesh>();
        if (Status st = io::buildRenderMesh(rig->rig, surface->surface->plan(), &m->layout); !st)
            return fromStatus(st);
        if (m->layout.refinedVertexCount != surface->surface->vertexCount())
            return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_create: the surface is not laid out in the "
                                                 "plan's vertex order");
        *out = m.release();
        return STRATA_OK;
    });
}

void strata_render_mesh_destroy(StrataRenderMesh* mesh)
{
    delete mesh;
}

size_t strata_render_mesh_vertex_count(const StrataRenderMesh* mesh)
{
    return mesh ? mesh->layout.vertexCount() : 0;
}

size_t strata_render_mesh_index_count(const StrataRenderMesh* mesh)
{
    return mesh ? mesh->layout.indices.size() : 0;
}

StrataStatus strata_render_mesh_indices(const StrataRenderMesh* mesh, uint32_t* dst)
{
    if (!mesh || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_indices: null argument");
    std::memcpy(dst, mesh->layout.indices.data(), mesh->layout.indices.size() * sizeof(uint32_t));
    return STRATA_OK;
}

StrataStatus strata_render_mesh_refined_vertices(const StrataRenderMesh* mesh, uint32_t* dst)
{
    if (!mesh || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_refined_vertices: null argument");
    std::memcpy(dst, mesh->layout.refinedVertex.data(), mesh->layout.refinedVertex.size() * sizeof(uint32_t));
    return STRATA_OK;
}

size_t strata_render_mesh_part_count(const StrataRenderMesh* mesh)
{
    return mesh ? mesh->layout.parts.size() : 0;
}

StrataStatus strata_render_mesh_part(const StrataRenderMesh* mesh, size_t index, StrataRenderPart* out)
{
    if (!mesh || !out)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_part: null argument");
    if (index >= mesh->layout.parts.size())
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_part: part " + std::to_string(index) + " of " +
                                                 std::to_string(mesh->layout.parts.size()));
    const io::RenderPart& p = mesh->layout.parts[index];
    out->first_index = p.firstIndex;
    out->index_count = p.indexCount;
    out->mesh = p.mesh;
    out->primitive = p.primitive;
    out->material = p.material;
    return STRATA_OK;
}

int strata_render_mesh_part_flat(const StrataRenderMesh* mesh, size_t index)
{
    return mesh && index < mesh->layout.parts.size() && mesh->layout.parts[index].flat ? 1 : 0;
}

size_t strata_render_mesh_attribute_count(const StrataRenderMesh* mesh)
{
    return mesh ? mesh->layout.attributes.size() : 0;
}

const char* strata_render_mesh_attribute_name(const StrataRenderMesh* mesh, size_t index)
{
    return mesh && index < mesh->layout.attributes.size() ? mesh->layout.attributes[index].name.c_str() : nullptr;
}

int strata_render_mesh_attribute_components(const StrataRenderMesh* mesh, size_t index)
{
    return mesh && index < mesh->layout.attributes.size() ? mesh->layout.attributes[index].components : 0;
}

StrataStatus strata_render_mesh_attribute(const StrataRenderMesh* mesh, size_t index, float* dst)
{
    if (!mesh || !dst)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_attribute: null argument");
    if (index >= mesh->layout.attributes.size())
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_attribute: attribute " + std::to_string(index) +
                                                 " of " + std::to_string(mesh->layout.attributes.size()));
    const std::vector<float>& v = mesh->layout.attributes[index].values;
    std::memcpy(dst, v.data(), v.size() * sizeof(float));
    return STRATA_OK;
}

StrataStatus strata_render_mesh_evaluate(StrataRenderMesh* mesh, const StrataSurface* surface, float* positions,
                                         float* normals)
{
    if (!mesh || !surface || !positions)
        return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_evaluate: null argument");
    return guarded([&] {
        std::lock_guard<std::mutex> lock(surface->frameMutex);
        Surface& s = *surface->surface;
        if (mesh->frame) {
            const AdaptiveFrame& frame = s.adaptiveFrame();
            if (&frame != mesh->frame)
                return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_evaluate: the adaptive render mesh was made "
                                                     "for another surface");
            if (frame.topologyVersion() != mesh->version)
                return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_evaluate: the surface's adaptive levels "
                                                     "changed since this render mesh was made; make another");
        }
        const size_t n = mesh->frame ? s.adaptiveFrame().vertexCount() : s.vertexCount();
        if (n != mesh->layout.refinedVertexCount)
            return fail(STRATA_INVALID_ARGUMENT, "strata_render_mesh_evaluate: the surface has " + std::to_string(n) +
                                                     " vertices, the render mesh was made for " +
                                                     std::to_string(mesh->layout.refinedVertexCount));
        mesh->positions.resize(n);
        if (normals)
            mesh->normals.resize(n);
        glm::vec3* p = mesh->positions.data();
        glm::vec3* q = normals ? mesh->normals.data() : nullptr;
        if (Status st = mesh->frame ? s.evaluateAdaptive(p, q, n) : s.evaluate(p, q, n); !st)
            return fromStatus(st);
        mesh->layout.gather(mesh->positions.data(), reinterpret_cast<glm::vec3*>(positions));
        if (normals)
            mesh->layout.gather(mesh->normals.data(), reinterpret_cast<glm::vec3*>(normals));
        return STRATA_OK;
    });
}

}  // extern "C"
