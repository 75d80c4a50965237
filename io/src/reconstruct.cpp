#include "strata/io/reconstruct.h"

#include "strata/io/mesh_io.h"
#include "strata/normals.h"

#include <algorithm>
#include <cmath>

namespace strata {
namespace io {

namespace {

// Displaced positions and shading normals for control positions and normals.
Status evaluate(Reconstruction* rec, const glm::vec3* controlPositions, size_t controlCount)
{
    const size_t n = rec->plan->refinedVertexCount();
    rec->positions.resize(n);
    rec->normals.resize(n);
    Status st = rec->plan->evaluate(rec->positions.data(), nullptr, 0, n, controlPositions, rec->controlNormals.data(),
                                    controlCount);
    if (!st)
        return st;
    rec->plan->computeShadingNormals(rec->normals.data(), rec->positions.data());
    return Status::ok();
}

}  // namespace

Status reconstructPose(Reconstruction* rec, Animator* animator, const Rig& rig, const Pose& pose)
{
    Status st = animator->pose(pose.animation, pose.time, pose.method);
    if (!st)
        return st;
    rec->controlNormals = animator->normals();
    return evaluate(rec, animator->positions().data(), rig.mesh.positions.size());
}

Status reconstruct(Reconstruction* out, const Rig& rig, const DisplacementMap* map, Scheme scheme, int level,
                   float scale, const Pose* pose)
{
    Reconstruction rec;
    Status st = Plan::create(&rec.plan, rig.mesh, scheme, level);
    if (!st)
        return st;
    if (map && !(st = applyRigDisplacement(rec.plan.get(), rig, map, scale)))
        return st;
    const ControlMesh& cm = rig.mesh;
    if (pose && !rig.skeleton.empty()) {
        Animator animator;
        if (!(st = animator.init(rig.skeleton, rig.mesh)))
            return st;
        if (!(st = reconstructPose(&rec, &animator, rig, *pose)))
            return st;
        *out = std::move(rec);
        return Status::ok();
    }
    rec.controlNormals.resize(cm.positions.size());
    computeControlNormals(rec.controlNormals.data(), cm.positions.data(), cm.positions.size(), cm.triangles.data(),
                          cm.faceCount());
    if (!(st = evaluate(&rec, cm.positions.data(), cm.positions.size())))
        return st;
    *out = std::move(rec);
    return Status::ok();
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

Status writeReconstruction(const std::filesystem::path& pathFile, const Reconstruction& rec)
{
    const std::string path = pathFile.string();
    const Plan& plan = *rec.plan;
    MeshView view;
    view.positions = rec.positions.data();
    view.normals = rec.normals.data();
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
