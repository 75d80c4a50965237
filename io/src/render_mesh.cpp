#include "strata/io/render_mesh.h"

#include "gltf_accessor.h"
#include "gltf_document.h"
#include "refined_attributes.h"

#include <algorithm>
#include <map>
#include <numeric>
#include <unordered_map>

namespace strata {
namespace io {

bool isRefinedAttribute(const std::string& name)
{
    return name.rfind("TEXCOORD_", 0) == 0 || name.rfind("COLOR_", 0) == 0 || (!name.empty() && name[0] == '_');
}

int attributeComponents(const tinygltf::Model& model, int accessor)
{
    if (accessor < 0 || size_t(accessor) >= model.accessors.size())
        return 0;
    return std::max(0, tinygltf::GetNumComponentsInType(uint32_t(model.accessors[size_t(accessor)].type)));
}

Status refinePartAttribute(const tinygltf::Model& model, const RigPart& part, const FaceVaryingRefinement& fv,
                           const uint32_t* cornerValue, size_t count, int accessor, const std::string& name,
                           int components, float* out, size_t stride)
{
    std::vector<float> src;
    if (components <= 0)
        return Status(StatusCode::InvalidData, name + " is not a vector attribute");
    if (Status st = readFloatAccessor(model, accessor, components, name, &src); !st)
        return st;
    if (src.size() != size_t(part.vertexCount) * size_t(components))
        return Status(StatusCode::InvalidData, name + " does not have one element per vertex");
    const size_t comps = size_t(components);
    for (size_t i = 0; i < count; ++i) {
        float* o = out + i * stride;
        for (size_t c = 0; c < comps; ++c)
            o[c] = 0.0f;
        for (uint32_t k = fv.offsets[cornerValue[i]]; k < fv.offsets[cornerValue[i] + 1]; ++k) {
            const uint32_t file = fv.sources[k];
            if (file < part.firstVertex || file >= part.firstVertex + part.vertexCount)
                continue;
            const float* s = &src[size_t(file - part.firstVertex) * comps];
            for (size_t c = 0; c < comps; ++c)
                o[c] += fv.weights[k] * s[c];
        }
    }
    return Status::ok();
}

namespace {

// One render vertex per (vertex, corner value): corner c uses vertex
// vertexOf[c] with value valueOf[c].  The first `n` render vertices are the
// vertices themselves, each with the value of its first corner (0 for a
// vertex of no corner, never drawn); the copies others need follow.  Fills
// rm's refinedVertex and indices, and the value of every render vertex.
void splitByCornerValue(size_t n, const std::vector<uint32_t>& vertexOf, const std::vector<uint32_t>& valueOf,
                        RenderMesh* rm, std::vector<uint32_t>* values)
{
    rm->refinedVertexCount = n;
    rm->refinedVertex.resize(n);
    std::iota(rm->refinedVertex.begin(), rm->refinedVertex.end(), 0u);
    rm->indices.resize(vertexOf.size());
    values->assign(n, ~0u);
    std::unordered_map<uint64_t, uint32_t> copies;
    for (size_t c = 0; c < vertexOf.size(); ++c) {
        const uint32_t v = vertexOf[c], u = valueOf[c];
        if ((*values)[v] == ~0u || (*values)[v] == u) {
            (*values)[v] = u;
            rm->indices[c] = v;
            continue;
        }
        auto it = copies.emplace((uint64_t(v) << 32) | u, uint32_t(rm->refinedVertex.size()));
        if (it.second) {
            rm->refinedVertex.push_back(v);
            values->push_back(u);
        }
        rm->indices[c] = it.first->second;
    }
    for (uint32_t& u : *values)
        if (u == ~0u)
            u = 0;
}

}  // namespace

void RenderMesh::gather(const glm::vec3* refined, glm::vec3* out) const
{
    const size_t n = refinedVertex.size();
    for (size_t i = 0; i < n; ++i)
        out[i] = refined[refinedVertex[i]];
}

namespace {

// The seam table of layout m (its refinedVertex and indices over plan's
// refined triangles, one control face every perFace triangles): a face's
// corners at one refined vertex share its values, so one render vertex per
// (vertex, face).
RenderMesh::Seams seamsOf(const RenderMesh& m, const Plan& plan)
{
    const std::vector<uint32_t>& tris = plan.refinedTriangles();
    const size_t n = plan.refinedVertexCount(), perFace = size_t(1) << (2 * plan.level());
    RenderMesh::Seams t;
    if (m.refinedVertex.size() <= n)
        return t;  // no seam copies
    std::vector<uint8_t> seam(n, 0);
    for (size_t r = n; r < m.refinedVertex.size(); ++r)
        seam[m.refinedVertex[r]] = 1;
    struct Entry {
        uint32_t vertex, face, render;
    };
    std::vector<Entry> entries;
    for (size_t c = 0; c < tris.size(); ++c)
        if (seam[tris[c]])
            entries.push_back({tris[c], uint32_t(c / (3 * perFace)), m.indices[c]});
    std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
        return a.vertex != b.vertex ? a.vertex < b.vertex : a.face < b.face;
    });
    t.offsets.assign(n + 1, 0);
    for (size_t k = 0; k < entries.size(); ++k) {
        const Entry& e = entries[k];
        if (k > 0 && entries[k - 1].vertex == e.vertex && entries[k - 1].face == e.face)
            continue;
        ++t.offsets[e.vertex + 1];
        t.faces.push_back(e.face);
        t.vertices.push_back(e.render);
    }
    for (size_t v = 0; v < n; ++v)
        t.offsets[v + 1] += t.offsets[v];
    return t;
}

}  // namespace

Status buildRenderMesh(const Rig& rig, const Plan& plan, RenderMesh* out)
{
    RenderMesh rm;
    const size_t n = plan.refinedVertexCount();
    const std::vector<uint32_t>& tris = plan.refinedTriangles();
    const bool fromGltf = rig.source && !rig.parts.empty() && rig.fileCorners.size() == rig.mesh.triangles.size();
    if (!fromGltf) {
        rm.refinedVertexCount = n;
        rm.refinedVertex.resize(n);
        std::iota(rm.refinedVertex.begin(), rm.refinedVertex.end(), 0u);
        rm.indices = tris;
        RenderPart part;
        part.indexCount = uint32_t(tris.size());
        rm.parts.push_back(part);
        *out = std::move(rm);
        return Status::ok();
    }
    FaceVaryingRefinement fv;
    if (Status st = refineFaceVarying(&fv, rig.mesh, rig.fileCorners.data(), rig.sourceVertex.size(), plan.level());
        !st)
        return st;
    const size_t perFace = size_t(1) << (2 * plan.level());
    if (fv.corners.size() != tris.size())
        return Status(StatusCode::InvalidData, "the face-varying refinement does not match the plan");
    // Each refined vertex first takes the corner value of its first corner;
    // a corner with another value gets (or finds) a copy.
    std::vector<uint32_t> cornerValue;
    splitByCornerValue(n, tris, fv.corners, &rm, &cornerValue);

    // Parts, and which render vertices each part's triangles use.
    const tinygltf::Model& model = rig.source->model;
    std::map<std::string, size_t> attributeOf;
    std::vector<uint32_t> partOf(rm.refinedVertex.size(), ~0u);
    size_t covered = 0;
    for (size_t p = 0; p < rig.parts.size(); ++p) {
        const RigPart& part = rig.parts[p];
        RenderPart rp;
        rp.firstIndex = uint32_t(size_t(part.firstFace) * perFace * 3);
        rp.indexCount = uint32_t(size_t(part.faceCount) * perFace * 3);
        rp.mesh = part.mesh;
        rp.primitive = part.primitive;
        rp.material = part.material;
        rp.flat = part.flat;
        covered += part.faceCount;
        if (size_t(rp.firstIndex) + rp.indexCount > rm.indices.size())
            return Status(StatusCode::InvalidData, part.name + ": its faces lie outside the control mesh");
        for (size_t i = rp.firstIndex; i < size_t(rp.firstIndex) + rp.indexCount; ++i)
            if (partOf[rm.indices[i]] == ~0u)
                partOf[rm.indices[i]] = uint32_t(p);
        rm.parts.push_back(rp);
        const tinygltf::Primitive& prim = model.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
        for (const auto& [name, accessor] : prim.attributes)
            if (isRefinedAttribute(name) && !attributeOf.count(name)) {
                const int comps = attributeComponents(model, accessor);
                if (comps <= 0)
                    return Status(StatusCode::InvalidData, part.name + ": " + name + " has no valid accessor");
                attributeOf[name] = rm.attributes.size();
                RenderAttribute a;
                a.name = name;
                a.components = comps;
                // A part without the attribute reads 0, or white for a
                // vertex colour (glTF draws a primitive without COLOR_0 so).
                a.values.assign(rm.refinedVertex.size() * size_t(comps), name.rfind("COLOR_", 0) == 0 ? 1.0f : 0.0f);
                rm.attributes.push_back(std::move(a));
            }
    }
    if (covered != rig.mesh.faceCount())
        return Status(StatusCode::InvalidData, "the rig's parts do not cover its control mesh");
    // The render vertices each part uses (one pass), and their corner values.
    std::vector<std::vector<uint32_t>> used(rig.parts.size()), usedValues(rig.parts.size());
    for (size_t i = 0; i < partOf.size(); ++i)
        if (partOf[i] != ~0u) {
            used[partOf[i]].push_back(uint32_t(i));
            usedValues[partOf[i]].push_back(cornerValue[i]);
        }
    // Each attribute, part by part, over those vertices.
    for (size_t p = 0; p < rig.parts.size(); ++p) {
        const RigPart& part = rig.parts[p];
        const std::vector<uint32_t>& mine = used[p];
        const std::vector<uint32_t>& values = usedValues[p];
        if (mine.empty())
            continue;
        const tinygltf::Primitive& prim = model.meshes[size_t(part.mesh)].primitives[size_t(part.primitive)];
        for (const auto& [name, accessor] : prim.attributes) {
            if (!isRefinedAttribute(name))
                continue;
            RenderAttribute& a = rm.attributes[attributeOf[name]];
            if (attributeComponents(model, accessor) != a.components)
                return Status(StatusCode::InvalidData, part.name + ": " + name + " has " +
                                                           std::to_string(attributeComponents(model, accessor)) +
                                                           " components, another part's has " +
                                                           std::to_string(a.components));
            const size_t comps = size_t(a.components);
            std::vector<float> refined(mine.size() * comps);
            if (Status st = refinePartAttribute(model, part, fv, values.data(), values.size(), accessor, name,
                                                a.components, refined.data(), comps);
                !st)
                return Status(st.code(), part.name + ": " + st.message());
            for (size_t k = 0; k < mine.size(); ++k)
                for (size_t c = 0; c < comps; ++c)
                    a.values[size_t(mine[k]) * comps + c] = refined[k * comps + c];
        }
    }
    rm.seams = seamsOf(rm, plan);
    *out = std::move(rm);
    return Status::ok();
}

Status buildAdaptiveRenderMesh(const RenderMesh& uniform, const Plan& plan, const AdaptiveFrame& frame,
                               RenderMesh* out)
{
    const std::vector<uint32_t>& tris = plan.refinedTriangles();
    const size_t n = plan.refinedVertexCount(), perFace = size_t(1) << (2 * plan.level());
    const size_t faces = plan.controlTriangles().size() / 3;
    if (uniform.refinedVertexCount != n || uniform.indices.size() != tris.size() || tris.size() != 3 * perFace * faces)
        return Status(StatusCode::InvalidArgument, "the render mesh was not made for this surface's plan");
    // A refined vertex with seam copies takes, in each control face, the
    // render vertex that face's triangles use; any other is its own render
    // vertex.  (A layout made by hand without its table gets one here.)
    RenderMesh::Seams made;
    const RenderMesh::Seams* seams = &uniform.seams;
    if (uniform.refinedVertex.size() > n && seams->offsets.size() != n + 1) {
        made = seamsOf(uniform, plan);
        seams = &made;
    }
    const bool anySeam = !seams->offsets.empty();

    const std::vector<uint32_t>& vertices = frame.vertices();
    const std::vector<uint32_t>& triangles = frame.triangles();
    const std::vector<uint32_t>& triangleFaces = frame.triangleFaces();
    // Per corner, uniform's render vertex of its refined vertex in its face.
    std::vector<uint32_t> cornerSource(triangles.size());
    for (size_t c = 0; c < triangles.size(); ++c) {
        const uint32_t a = triangles[c], v = vertices[a];
        uint32_t r = v;
        if (anySeam && seams->offsets[v + 1] > seams->offsets[v]) {
            const uint32_t face = triangleFaces[c / 3];
            uint32_t e = seams->offsets[v];
            while (e < seams->offsets[v + 1] && seams->faces[e] != face)
                ++e;
            if (e == seams->offsets[v + 1])
                return Status(StatusCode::InvalidData, "adaptive vertex " + std::to_string(a) +
                                                           " lies outside its triangle's control face");
            r = seams->vertices[e];
        }
        cornerSource[c] = r;
    }
    RenderMesh rm;
    std::vector<uint32_t> source;  // per render vertex: uniform's render vertex
    splitByCornerValue(vertices.size(), triangles, cornerSource, &rm, &source);

    // Parts: the frame lists its triangles control face by control face,
    // so each part's faces give one range of them.
    if (!std::is_sorted(triangleFaces.begin(), triangleFaces.end()))
        return Status(StatusCode::InvalidData, "the adaptive frame's triangles are not in control face order");
    for (const RenderPart& part : uniform.parts) {
        const size_t firstFace = part.firstIndex / (3 * perFace), endFace = firstFace + part.indexCount / (3 * perFace);
        const auto first = std::lower_bound(triangleFaces.begin(), triangleFaces.end(), uint32_t(firstFace));
        const auto end = std::lower_bound(first, triangleFaces.end(), uint32_t(endFace));
        RenderPart p = part;
        p.firstIndex = uint32_t(3 * size_t(first - triangleFaces.begin()));
        p.indexCount = uint32_t(3 * size_t(end - first));
        rm.parts.push_back(p);
    }
    for (const RenderAttribute& a : uniform.attributes) {
        RenderAttribute b;
        b.name = a.name;
        b.components = a.components;
        const size_t comps = size_t(a.components);
        b.values.resize(source.size() * comps);
        for (size_t k = 0; k < source.size(); ++k)
            for (size_t i = 0; i < comps; ++i)
                b.values[k * comps + i] = a.values[size_t(source[k]) * comps + i];
        rm.attributes.push_back(std::move(b));
    }
    *out = std::move(rm);
    return Status::ok();
}

}  // namespace io
}  // namespace strata
