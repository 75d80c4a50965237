#include "strata/io/reconstruct.h"

#include "strata/io/mesh_io.h"

#include <algorithm>
#include <cmath>

namespace strata {
namespace io {

namespace {

Status evaluate(Reconstruction* rec)
{
    const size_t n = rec->surface->vertexCount();
    rec->positions.resize(n);
    rec->normals.resize(n);
    return rec->surface->evaluate(rec->positions.data(), rec->normals.data(), n);
}

}  // namespace

Status reconstructPose(Reconstruction* rec, const Pose& pose)
{
    if (!rec || !rec->surface)
        return Status(StatusCode::InvalidArgument, "reconstructPose: no reconstruction");
    rec->surface->setSkinningMethod(pose.method);
    Status st = rec->surface->setAnimationTime(pose.animation, pose.time);
    return st ? evaluate(rec) : st;
}

Status reconstruct(Reconstruction* out, const Rig& rig, const DisplacementMap* map, const SurfaceOptions& options,
                   const Pose* pose)
{
    Reconstruction rec;
    SurfaceOptions o = options;
    if (pose)
        o.method = pose->method;
    Status st = Surface::create(&rec.surface, rig, map, o);
    if (!st)
        return st;
    if (pose && !rig.skeleton.empty())
        st = reconstructPose(&rec, *pose);
    else
        st = evaluate(&rec);
    if (!st)
        return st;
    *out = std::move(rec);
    return Status::ok();
}

Status reconstruct(Reconstruction* out, const Rig& rig, const DisplacementMap* map, Scheme scheme, int level,
                   float scale, const Pose* pose)
{
    SurfaceOptions options;
    options.level = level;
    options.scheme = scheme;
    options.schemeGiven = true;
    options.displace = map != nullptr;
    options.scale = scale;
    return reconstruct(out, rig, map, options, pose);
}

Status reconstructView(AdaptiveView* out, Reconstruction& rec, const ViewSpec& view, float pixelError, bool measure)
{
    if (!out || !rec.surface)
        return Status(StatusCode::InvalidArgument, "reconstructView: no reconstruction");
    Surface& s = *rec.surface;
    if (Status st = s.chooseFaceLevels(view, pixelError); !st)
        return st;
    const AdaptiveFrame& frame = s.adaptiveFrame();
    AdaptiveView a;
    a.positions.resize(frame.vertexCount());
    a.normals.resize(frame.vertexCount());
    if (Status st = s.evaluateAdaptive(a.positions.data(), a.normals.data(), a.positions.size()); !st)
        return st;
    if (measure && rec.positions.size() == s.vertexCount())
        a.maxPixelError = frame.maxScreenDeviation(a.positions.data(), rec.positions.data(), view);
    a.facesPerLevel.assign(size_t(s.level()) + 1, 0);
    for (uint8_t l : frame.levels())
        ++a.facesPerLevel[l];
    a.splitFaces = frame.splitFaceCount();
    *out = std::move(a);
    return Status::ok();
}

Status writeAdaptiveView(const std::filesystem::path& path, Reconstruction& rec, const AdaptiveView& view, bool normals)
{
    if (!rec.surface)
        return Status(StatusCode::InvalidArgument, "writeAdaptiveView: no reconstruction");
    const AdaptiveFrame& frame = rec.surface->adaptiveFrame();
    if (view.positions.size() != frame.vertexCount())
        return Status(StatusCode::InvalidArgument, "writeAdaptiveView: the view is not the surface's current frame");
    MeshView mesh;
    mesh.positions = view.positions.data();
    mesh.normals = normals && view.normals.size() == view.positions.size() ? view.normals.data() : nullptr;
    mesh.vertexCount = view.positions.size();
    mesh.triangles = frame.triangles().data();
    mesh.faceCount = frame.triangleCount();
    // UVs per corner: its grid point in its control face's UV triangle,
    // as the plan refines UVs (linearly inside each face).
    const ControlMesh& control = rec.surface->controlMesh();
    std::vector<glm::vec2> uvs;
    std::vector<uint32_t> uvIndices;
    if (!control.uvIndices.empty()) {
        frame.cornerUVs(&uvs, control.uvs.data(), control.uvIndices.data());
        uvIndices.resize(uvs.size());
        for (size_t c = 0; c < uvs.size(); ++c)
            uvIndices[c] = uint32_t(c);
        mesh.uvs = uvs.data();
        mesh.uvCount = uvs.size();
        mesh.uvIndices = uvIndices.data();
    }
    return writeMesh(path, mesh);
}

double reconstructionPeakBytes(const Rig& rig, Scheme scheme, int level, const std::string& outputExt, bool scene,
                               double mapTexels)
{
    // Refined vertices: a triangle mesh's are about half its refined faces.
    const double vertices = double(rig.mesh.faceCount()) * std::pow(4.0, level) * 0.5 + double(rig.mesh.vertexCount());
    // Bytes per refined vertex, measured: the linear plan with the output
    // file staged in memory (binary PLY least; OBJ text; a glb mesh; a
    // scene with refined attributes and skin more; .gltf adds base64).
    double perVertex = outputExt == ".obj" ? 405.0 : outputExt == ".ply" || outputExt == ".stl" ? 275.0 : 341.0;
    if (scene)
        perVertex = 560.0;
    if (outputExt == ".gltf")
        perVertex += 80.0;
    // The smooth (Loop) plan's stencil tables peak while they are built,
    // above what the output adds.
    if (scheme != Scheme::Linear)
        perVertex = std::max(760.0, perVertex + 215.0);
    const double base = 16.0 * 1024.0 * 1024.0;  // the process, the rig, its document
    return base + perVertex * vertices + 8.0 * mapTexels;
}

Status writeReconstruction(const std::filesystem::path& pathFile, const Reconstruction& rec, bool normals)
{
    const std::string path = pathFile.string();
    const Plan& plan = rec.plan();
    MeshView view;
    view.positions = rec.positions.data();
    view.normals = normals ? rec.normals.data() : nullptr;
    view.vertexCount = rec.positions.size();
    view.triangles = plan.refinedTriangles().data();
    view.faceCount = plan.refinedFaceCount();
    std::vector<glm::vec2> uvs;
    std::vector<uint32_t> uvIndices;
    plan.refinedUVs(&uvs, &uvIndices);
    if (!uvs.empty()) {
        view.uvs = uvs.data();
        view.uvCount = uvs.size();
        view.uvIndices = uvIndices.data();
    }
    return writeMesh(path, view);
}

}  // namespace io
}  // namespace strata
