// Mesh input and control-mesh derivation.  The only OpenMesh translation
// unit (its Decimater templates are heavy to compile).
#include <OpenMesh/Core/IO/MeshIO.hh>  // before the kernel headers, as OpenMesh requires

#include "strata/baker/mesh_input.h"

#include "strata/io/file.h"
#include "strata/io/mesh_io.h"
#include "strata/io/rig_io.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cstring>

namespace strata {
namespace baker {
namespace {

using OMesh = OpenMesh::TriMesh_ArrayKernelT<>;

void countTolerated(const TriangleMesh& m, HighMeshStats* s)
{
    std::vector<glm::vec3> sorted = m.positions;
    std::sort(sorted.begin(), sorted.end(), [](const glm::vec3& a, const glm::vec3& b) {
        return a.x != b.x ? a.x < b.x : a.y != b.y ? a.y < b.y : a.z < b.z;
    });
    for (size_t i = 1; i < sorted.size(); ++i)
        s->duplicateVertices += sorted[i] == sorted[i - 1];
    for (size_t f = 0; f < m.faceCount(); ++f) {
        const glm::vec3 n = glm::cross(m.positions[m.triangles[3 * f + 1]] - m.positions[m.triangles[3 * f]],
                                       m.positions[m.triangles[3 * f + 2]] - m.positions[m.triangles[3 * f]]);
        s->degenerateTriangles += !(glm::dot(n, n) > 0.0f);
    }
    s->nonManifoldEdges = computeTopologyStats(m.triangles.data(), m.faceCount()).nonManifoldEdges;
}

// Binary little-endian PLY with float x/y/z vertices and a uchar/int face
// list: what scanners and most tools write.  Read directly (OpenMesh builds
// a halfedge structure first, ~10x slower on million-triangle scans); any
// other PLY layout returns false and goes to OpenMesh.
bool readBinaryPlyFast(const std::vector<unsigned char>& bytes, TriangleMesh* mesh, size_t* polygons, std::string* error)
{
    const std::string head(reinterpret_cast<const char*>(bytes.data()), std::min<size_t>(bytes.size(), 4096));
    const size_t end = head.find("end_header\n");
    if (head.rfind("ply\n", 0) != 0 || end == std::string::npos ||
        head.find("format binary_little_endian 1.0") == std::string::npos)
        return false;
    size_t nv = 0, nf = 0;
    std::vector<std::string> vprops;
    std::string faceList;
    bool inVertex = false, inFace = false;
    size_t pos = 0;
    while (pos < end) {
        const size_t eol = head.find('\n', pos);
        const std::string line = head.substr(pos, eol - pos);
        pos = eol + 1;
        char name[64] = {0}, type[64] = {0}, t2[64] = {0}, t3[64] = {0};
        unsigned long count = 0;
        if (std::sscanf(line.c_str(), "element %63s %lu", name, &count) == 2) {
            inVertex = std::strcmp(name, "vertex") == 0;
            inFace = std::strcmp(name, "face") == 0;
            if (!inVertex && !inFace)
                return false;
            (inVertex ? nv : nf) = size_t(count);
        } else if (std::sscanf(line.c_str(), "property list %63s %63s %63s", t2, t3, name) == 3) {
            if (!inFace)
                return false;
            faceList = std::string(t2) + " " + t3;
        } else if (std::sscanf(line.c_str(), "property %63s %63s", type, name) == 2) {
            if (!inVertex)
                return false;
            vprops.push_back(std::string(type) + " " + name);
        }
    }
    if (vprops.size() < 3 || vprops[0] != "float x" || vprops[1] != "float y" || vprops[2] != "float z")
        return false;
    for (const std::string& p : vprops)
        if (p.rfind("float ", 0) != 0)
            return false;
    const bool intIndex = faceList == "uchar int" || faceList == "uchar uint";
    if (!intIndex)
        return false;
    const size_t stride = vprops.size() * 4;
    const unsigned char* p = bytes.data() + end + 11;
    const unsigned char* last = bytes.data() + bytes.size();
    if (size_t(last - p) / stride < nv) {
        *error = "vertex data is truncated";
        return true;
    }
    mesh->positions.resize(nv);
    for (size_t i = 0; i < nv; ++i, p += stride)
        std::memcpy(&mesh->positions[i], p, 12);
    mesh->triangles.reserve(nf * 3);
    for (size_t f = 0; f < nf; ++f) {
        if (p >= last) {
            *error = "face data is truncated";
            return true;
        }
        const unsigned n = *p++;
        if (size_t(last - p) < size_t(n) * 4) {
            *error = "face data is truncated";
            return true;
        }
        uint32_t idx[256];
        std::memcpy(idx, p, size_t(n) * 4);
        p += size_t(n) * 4;
        for (unsigned k = 0; k < n; ++k)
            if (idx[k] >= nv) {
                *error = "face " + std::to_string(f) + " references vertex " + std::to_string(idx[k]) + " of " +
                         std::to_string(nv);
                return true;
            }
        *polygons += n > 3;
        for (unsigned k = 1; k + 1 < n; ++k)
            mesh->triangles.insert(mesh->triangles.end(), {idx[0], idx[k], idx[k + 1]});
    }
    return true;
}

}  // namespace

Status loadHighMesh(const std::string& path, TriangleMesh* out, HighMeshStats* stats)
{
    const std::string ext = io::extensionOf(path);
    TriangleMesh mesh;
    HighMeshStats s;
    Status st;
    if (ext == ".obj") {
        ControlMesh cm;
        io::ObjReadInfo info;
        if (!(st = io::readObj(path, &cm, &info)))
            return st;
        mesh.positions = std::move(cm.positions);
        mesh.triangles = std::move(cm.triangles);
        s.polygonsTriangulated = info.triangulated;
    } else if (ext == ".glb" || ext == ".gltf") {
        if (!(st = io::loadGltfTriangles(path, &mesh.positions, &mesh.triangles)))
            return st;
    } else if (ext == ".ply" || ext == ".stl" || ext == ".off") {
        std::vector<unsigned char> probe;
        if (!(st = io::readFile(path, &probe)))
            return st;
        std::string error;
        if (ext == ".ply" && readBinaryPlyFast(probe, &mesh, &s.polygonsTriangulated, &error)) {
            if (!error.empty())
                return Status(StatusCode::InvalidData, path + ": " + error);
            if (!(st = checkHighMesh(mesh)))
                return Status(st.code(), path + ": " + st.message());
            countTolerated(mesh, &s);
            *out = std::move(mesh);
            if (stats)
                *stats = s;
            return Status::ok();
        }
        probe = std::vector<unsigned char>();
        OMesh om;
        OpenMesh::IO::Options opt;
        omerr().disable();  // OpenMesh reports through its own streams; errors become Status here
        omout().disable();
        const bool ok = OpenMesh::IO::read_mesh(om, path, opt);
        omerr().enable();
        omout().enable();
        if (!ok || om.n_faces() == 0)
            return Status(StatusCode::InvalidData, path + ": cannot read a triangle mesh from this " + ext + " file");
        for (auto v : om.vertices()) {
            const auto p = om.point(v);
            mesh.positions.emplace_back(p[0], p[1], p[2]);
        }
        for (auto f : om.faces()) {
            std::vector<uint32_t> corners;
            for (auto v : om.fv_range(f))
                corners.push_back(uint32_t(v.idx()));
            s.polygonsTriangulated += corners.size() > 3;
            for (size_t k = 1; k + 1 < corners.size(); ++k)
                mesh.triangles.insert(mesh.triangles.end(), {corners[0], corners[k], corners[k + 1]});
        }
    } else {
        return Status(StatusCode::InvalidArgument,
                      path + ": unknown mesh format \"" + ext + "\" (use .obj, .ply, .stl, .off, .glb or .gltf)");
    }
    if (!(st = checkHighMesh(mesh)))
        return Status(st.code(), path + ": " + st.message());
    countTolerated(mesh, &s);
    *out = std::move(mesh);
    if (stats)
        *stats = s;
    return Status::ok();
}

Status loadControlRig(const std::string& path, Rig* out)
{
    const std::string ext = io::extensionOf(path);
    Status st;
    Rig rig;
    if (ext == ".obj") {
        io::ObjReadInfo info;
        if (!(st = io::readObj(path, &rig.mesh, &info)))
            return st;
        if (info.degenerate)
            rig.warnings.push_back(std::to_string(info.degenerate) + " triangles repeat a vertex (zero area) and are left out");
    } else if (ext == ".glb" || ext == ".gltf") {
        if (!(st = io::loadRig(path, &rig)))
            return st;
    } else {
        return Status(StatusCode::InvalidArgument,
                      path + ": unknown control mesh format \"" + ext + "\" (use .obj, .glb or .gltf)");
    }
    if (!(st = validateControlMesh(rig.mesh)))
        return Status(st.code(), path + ": not a usable control mesh: " + st.message());
    *out = std::move(rig);
    return Status::ok();
}

Status loadControlMesh(const std::string& path, ControlMesh* out, Skeleton* skeleton)
{
    Rig rig;
    Status st = loadControlRig(path, &rig);
    if (!st)
        return st;
    *out = std::move(rig.mesh);
    if (skeleton)
        *skeleton = std::move(rig.skeleton);
    return Status::ok();
}

Status decimateToControlMesh(const TriangleMesh& high, size_t targetFaces, ControlMesh* out)
{
    if (targetFaces < 4)
        return Status(StatusCode::InvalidArgument, "--control-faces must be at least 4");
    OMesh om;
    // Deleting (isolated vertices, collapsed elements) needs status flags.
    om.request_vertex_status();
    om.request_edge_status();
    om.request_face_status();
    std::vector<OMesh::VertexHandle> vh;
    vh.reserve(high.positions.size());
    for (const glm::vec3& p : high.positions)
        vh.push_back(om.add_vertex(OMesh::Point(p.x, p.y, p.z)));
    omerr().disable();  // complex (non-manifold) faces are refused by OpenMesh and simply not added
    for (size_t f = 0; f < high.faceCount(); ++f)
        om.add_face(vh[high.triangles[3 * f]], vh[high.triangles[3 * f + 1]], vh[high.triangles[3 * f + 2]]);
    omerr().enable();
    om.delete_isolated_vertices();
    om.garbage_collection();
    if (om.n_faces() == 0)
        return Status(StatusCode::InvalidData, "the high-resolution mesh has no manifold faces to simplify");
    using Decimater = OpenMesh::Decimater::DecimaterT<OMesh>;
    Decimater decimater(om);
    OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
    OpenMesh::Decimater::ModNormalFlippingT<OMesh>::Handle flipping;
    decimater.add(quadric);
    decimater.add(flipping);
    decimater.module(flipping).set_max_normal_deviation(60.0);
    if (!decimater.initialize())
        return Status(StatusCode::InvalidData, "OpenMesh's decimater could not be initialised");
    decimater.decimate_to_faces(0, targetFaces);
    om.garbage_collection();

    ControlMesh cm;
    for (auto v : om.vertices()) {
        const auto p = om.point(v);
        cm.positions.emplace_back(p[0], p[1], p[2]);
    }
    for (auto f : om.faces())
        for (auto v : om.fv_range(f))
            cm.triangles.push_back(uint32_t(v.idx()));
    Status st = validateControlMesh(cm);
    if (!st)
        return Status(st.code(), "the simplified control mesh is unusable: " + st.message());
    *out = std::move(cm);
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
