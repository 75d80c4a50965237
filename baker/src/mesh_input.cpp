// Mesh input and control-mesh derivation.  The only OpenMesh translation
// unit (its Decimater templates are heavy to compile); OpenMesh only
// decimates here, it never parses files.
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
#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <filesystem>
#include <limits>

namespace strata {
namespace baker {
namespace {

using OMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// Per vertex, the lowest-numbered vertex at its position (itself when it is
// the first there): equal positions as equal bit patterns (+0 for -0),
// sorted as integers by a stable 96-bit radix sort, 16 bits a pass, so each
// run of equal positions starts at its lowest vertex.
std::vector<uint32_t> firstAtPosition(const std::vector<glm::vec3>& positions)
{
    struct Key {
        std::array<uint32_t, 3> bits;
        uint32_t vertex;
    };
    const size_t count = positions.size();
    std::vector<Key> keys(count), scratch(count);
    for (size_t i = 0; i < count; ++i) {
        for (int c = 0; c < 3; ++c) {
            const float v = positions[i][c] + 0.0f;
            std::memcpy(&keys[i].bits[size_t(c)], &v, 4);
        }
        keys[i].vertex = uint32_t(i);
    }
    for (int pass = 0; pass < 6; ++pass) {  // least significant digit first: z low, z high, y low, ...
        const size_t word = size_t(2 - pass / 2);
        const int shift = 16 * (pass % 2);
        std::vector<uint32_t> bucket(65537, 0);
        for (const Key& k : keys)
            ++bucket[((k.bits[word] >> shift) & 0xffffu) + 1];
        for (size_t d = 0; d < 65536; ++d)
            bucket[d + 1] += bucket[d];
        for (const Key& k : keys)
            scratch[bucket[(k.bits[word] >> shift) & 0xffffu]++] = k;
        keys.swap(scratch);
    }
    std::vector<uint32_t> first(count);
    for (size_t i = 0; i < count; ++i)
        first[keys[i].vertex] = i > 0 && keys[i].bits == keys[i - 1].bits ? first[keys[i - 1].vertex] : keys[i].vertex;
    return first;
}

// Renumbers each face's corners to the first vertex at their position
// (firstAtPosition's `first`) and leaves out the faces two of whose corners
// become one, with their UV corners when `uvIndices` is not null; returns
// how many faces were left out.
size_t weldFaces(const std::vector<uint32_t>& first, std::vector<uint32_t>* triangles,
                 std::vector<uint32_t>* uvIndices = nullptr)
{
    std::vector<uint32_t>& t = *triangles;
    const size_t nf = t.size() / 3;
    size_t kept = 0;
    for (size_t f = 0; f < nf; ++f) {
        const uint32_t a = first[t[3 * f]], b = first[t[3 * f + 1]], c = first[t[3 * f + 2]];
        if (a == b || b == c || c == a)
            continue;
        t[3 * kept] = a;
        t[3 * kept + 1] = b;
        t[3 * kept + 2] = c;
        if (uvIndices)
            std::copy_n(&(*uvIndices)[3 * f], 3, &(*uvIndices)[3 * kept]);
        ++kept;
    }
    t.resize(3 * kept);
    if (uvIndices)
        uvIndices->resize(3 * kept);
    return nf - kept;
}

void countTolerated(const TriangleMesh& m, HighMeshStats* s)
{
    // The mesh holds no NaN: equal bits are equal positions.
    const std::vector<uint32_t> first = firstAtPosition(m.positions);
    for (size_t v = 0; v < first.size(); ++v)
        s->duplicateVertices += first[v] != v;
    for (size_t f = 0; f < m.faceCount(); ++f) {
        const glm::vec3 n = glm::cross(m.positions[m.triangles[3 * f + 1]] - m.positions[m.triangles[3 * f]],
                                       m.positions[m.triangles[3 * f + 2]] - m.positions[m.triangles[3 * f]]);
        s->degenerateTriangles += !(glm::dot(n, n) > 0.0f);
    }
    s->nonManifoldEdges = computeTopologyStats(m.triangles.data(), m.faceCount()).nonManifoldEdges;
}

}  // namespace

namespace {

// A mesh read from text or binary takes a few times its file's bytes
// while it is parsed and welded (an OBJ line of ~30 bytes becomes 12 of
// position, a PLY's binary records about their own size, plus the index):
// a file past a quarter of the budget is refused before it is read.
Status checkReadBudget(const std::string& path, double maxMemoryMB)
{
    std::error_code ec;
    const uintmax_t bytes = std::filesystem::file_size(path, ec);
    const double need = 4.0 * double(bytes), budget = maxMemoryMB * 1024.0 * 1024.0;
    if (ec || need <= budget)
        return Status::ok();  // the reader reports a missing file
    return Status(StatusCode::InvalidArgument, path + ": reading its " + std::to_string(bytes) + " bytes needs about " +
                                                   std::to_string(long(need / (1024.0 * 1024.0))) + " MB, over the " +
                                                   std::to_string(long(maxMemoryMB)) +
                                                   " MB budget (raise it with --max-memory MB)");
}

// Leaves out the vertices no triangle uses, renumbering the rest in order;
// returns how many, and (kept, when not null and any were left out) the
// old number of each vertex kept.  In a capture such a vertex is no
// surface, yet the mapping, the fit and the capture's size would take it
// for one (a hole cut into a scan leaves its vertices floating over it, and
// the cage was fitted towards them).  A control mesh's glTF vertices are its
// triangles' corners, so such a vertex could not be written: the rig would
// number its layer for one mesh and hold another.  Indices must be in range.
template <typename Mesh>
size_t dropUnreferencedVertices(Mesh* mesh, std::vector<uint32_t>* kept = nullptr)
{
    std::vector<uint32_t> renumbered(mesh->positions.size(), ~0u);
    for (uint32_t v : mesh->triangles)
        renumbered[v] = 0;
    uint32_t next = 0;
    for (size_t v = 0; v < renumbered.size(); ++v)
        if (renumbered[v] == 0) {
            renumbered[v] = next;
            mesh->positions[next++] = mesh->positions[v];
        }
    const size_t dropped = mesh->positions.size() - next;
    if (dropped == 0)
        return 0;
    mesh->positions.resize(next);
    for (uint32_t& v : mesh->triangles)
        v = renumbered[v];
    if (kept) {
        kept->clear();
        for (size_t v = 0; v < renumbered.size(); ++v)
            if (renumbered[v] != ~0u)
                kept->push_back(uint32_t(v));
    }
    return dropped;
}

}  // namespace

Status loadHighMesh(const std::string& path, TriangleMesh* out, HighMeshStats* stats, double maxMemoryMB)
{
    const std::string ext = io::extensionOf(path);
    TriangleMesh mesh;
    HighMeshStats s;
    Status st;
    if (!(st = checkReadBudget(path, maxMemoryMB)))
        return st;
    if (ext == ".obj") {
        ControlMesh cm;
        io::ObjReadInfo info;
        if (!(st = io::readObj(path, &cm, &info)))
            return st;
        mesh.positions = std::move(cm.positions);
        mesh.triangles = std::move(cm.triangles);
        mesh.colours = std::move(info.colours);
        s.polygonsTriangulated = info.triangulated;
    } else if (ext == ".glb" || ext == ".gltf") {
        io::LoadOptions options;
        options.maxMemoryMB = maxMemoryMB;
        if (!(st = io::loadGltfTriangles(path, &mesh.positions, &mesh.triangles, options, &s.drawnFlat)))
            return st;
    } else if (ext == ".ply" || ext == ".stl" || ext == ".off") {
        // Strata's own bounded reader: untrusted bytes never reach OpenMesh.
        io::PolygonMesh pm;
        if (!(st = io::readPolygonMesh(path, &pm)))
            return st;
        mesh.positions = std::move(pm.positions);
        mesh.triangles = std::move(pm.triangles);
        mesh.colours = std::move(pm.colours);
        s.polygonsTriangulated = pm.polygonsTriangulated;
    } else {
        return Status(StatusCode::InvalidArgument,
                      path + ": unknown mesh format \"" + ext + "\" (use .obj, .ply, .stl, .off, .glb or .gltf)");
    }
    if (!(st = checkHighMesh(mesh)))
        return Status(st.code(), path + ": " + st.message());
    s.unreferencedVertices = dropUnreferencedVertices(&mesh, &s.keptVertices);
    if (s.unreferencedVertices > 0 && !mesh.colours.empty()) {
        for (size_t v = 0; v < s.keptVertices.size(); ++v)
            mesh.colours[v] = mesh.colours[s.keptVertices[v]];
        mesh.colours.resize(s.keptVertices.size());
    }
    countTolerated(mesh, &s);
    *out = std::move(mesh);
    if (stats)
        *stats = s;
    return Status::ok();
}

Status keepCaptureVertices(Rig* rig, const HighMeshStats& stats)
{
    if (stats.keptVertices.empty())
        return Status::ok();
    const size_t before = rig->mesh.positions.size();
    std::vector<uint32_t> kept;
    if (dropUnreferencedVertices(&rig->mesh, &kept) != stats.unreferencedVertices || kept != stats.keptVertices)
        return Status(StatusCode::InvalidData, "the capture and its character do not leave out the same unused vertices");
    VertexWeights& w = rig->skeleton.weights;
    const size_t k = size_t(std::max(0, w.influences));
    if (k > 0 && w.joints.size() == before * k && w.weights.size() == before * k) {
        for (size_t v = 0; v < kept.size(); ++v) {
            std::copy_n(&w.joints[k * kept[v]], k, &w.joints[k * v]);
            std::copy_n(&w.weights[k * kept[v]], k, &w.weights[k * v]);
        }
        w.joints.resize(k * kept.size());
        w.weights.resize(k * kept.size());
    }
    return Status::ok();
}

Status loadControlRig(const std::string& path, Rig* out, double maxMemoryMB)
{
    const std::string ext = io::extensionOf(path);
    Status st;
    Rig rig;
    if (!(st = checkReadBudget(path, maxMemoryMB)))
        return st;
    if (ext == ".obj") {
        io::ObjReadInfo info;
        if (!(st = io::readObj(path, &rig.mesh, &info)))
            return st;
        if (info.degenerate)
            rig.warnings.push_back(std::to_string(info.degenerate) + " triangles repeat a vertex (zero area) and are left out");
    } else if (ext == ".glb" || ext == ".gltf") {
        io::LoadOptions options;
        options.maxMemoryMB = maxMemoryMB;
        if (!(st = io::loadControlForBake(path, &rig, options)))
            return st;
    } else {
        return Status(StatusCode::InvalidArgument,
                      path + ": unknown control mesh format \"" + ext + "\" (use .obj, .glb or .gltf)");
    }
    if (!(st = validateControlMesh(rig.mesh)))
        return Status(st.code(), path + ": not a usable control mesh: " + st.message());
    // An OBJ's vertices at one position become one, as a glTF control's do
    // in the scene reader: a mesh split at its UV or normal seams (a glTF
    // converted to OBJ, a triangle soup) is cracked there, and every crack
    // was taken for a hole and capped (spot's cage as a soup: 372 "holes"
    // closed with 1,116 triangles, 0.37% RMS).  The UVs stay per corner.
    // (A glTF's vertices stay: the rig is written as its source document.)
    if (ext == ".obj") {
        ControlMesh& m = rig.mesh;
        const std::vector<uint32_t> first = firstAtPosition(m.positions);
        if (const size_t collapsed = weldFaces(first, &m.triangles, m.hasUVs() ? &m.uvIndices : nullptr)) {
            rig.warnings.push_back(std::to_string(collapsed) +
                                   " triangles with two corners at one place (zero area) are left out");
            if (!(st = validateControlMesh(m)))
                return Status(st.code(), path + ": not a usable control mesh: " + st.message());
        }
        const size_t before = m.positions.size();
        const size_t dropped = dropUnreferencedVertices(&m);
        size_t coincident = 0;
        for (size_t v = 0; v < before; ++v)
            coincident += first[v] != v;
        if (coincident)
            rig.warnings.push_back(std::to_string(coincident) + " vertices at the place of another (a mesh split at "
                                   "its seams) are one with it");
        if (dropped > coincident)
            rig.warnings.push_back(std::to_string(dropped - coincident) +
                                   (dropped - coincident == 1 ? " vertex" : " vertices") + " no triangle uses left out");
    }
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

namespace {

// OpenMesh reports through its own log streams (omlog, omout, omerr):
// silenced while it works, so only Strata's one-line messages reach users.
struct QuietOpenMesh {
    QuietOpenMesh()
    {
        omlog().disable();
        omout().disable();
        omerr().disable();
    }
    ~QuietOpenMesh()
    {
        omlog().enable();
        omout().enable();
        omerr().enable();
    }
};

// Faces turned against their neighbours (an exporter's flipped patch) are
// turned back: two faces agree across an edge they run opposite ways.  Each
// connected piece (across edges of two faces) is walked breadth-first from
// its first face, then keeps the turn most of its faces had.  OpenMesh
// refuses a face that meets its neighbour the wrong way round, so such a
// patch's rim was cut open in the cage (spot with a patch of 526 faces
// turned: 40 faces refused, and even the capture itself missed 0.01%).
// Returns how many faces turned.
size_t orientConsistently(std::vector<uint32_t>* triangles)
{
    std::vector<uint32_t>& t = *triangles;
    const size_t nf = t.size() / 3;
    const EdgeGroups edges = groupEdges(t.data(), nf);
    std::vector<uint32_t> edgeOf(t.size());
    for (size_t e = 0; e < edges.edgeCount(); ++e)
        for (uint32_t k = 0; k < edges.faceCountOf(e); ++k)
            edgeOf[edges.cornersOf(e)[k]] = uint32_t(e);
    std::vector<int8_t> turn(nf, -1);  // -1: not reached; else 1 to turn
    std::vector<uint32_t> piece, queue;
    size_t turned = 0;
    for (size_t seed = 0; seed < nf; ++seed) {
        if (turn[seed] >= 0)
            continue;
        piece.clear();
        queue.assign(1, uint32_t(seed));
        turn[seed] = 0;
        for (size_t q = 0; q < queue.size(); ++q) {
            const uint32_t f = queue[q];
            piece.push_back(f);
            for (uint32_t c = 3 * f; c < 3 * f + 3; ++c) {
                const size_t e = edgeOf[c];
                if (edges.faceCountOf(e) != 2)
                    continue;
                const uint32_t o = edges.cornersOf(e)[0] == c ? edges.cornersOf(e)[1] : edges.cornersOf(e)[0];
                const uint32_t g = o / 3;
                if (g == f || turn[g] >= 0)
                    continue;
                // Corners c and o start their edge; the same start is the same way round.
                turn[g] = int8_t(turn[f] ^ int8_t(t[c] == t[o]));
                queue.push_back(g);
            }
        }
        size_t against = 0;
        for (uint32_t f : piece)
            against += size_t(turn[f]);
        const int8_t flipAll = int8_t(2 * against > piece.size());
        for (uint32_t f : piece)
            if (turn[f] ^ flipAll) {
                std::swap(t[3 * size_t(f) + 1], t[3 * size_t(f) + 2]);
                ++turned;
            }
    }
    return turned;
}

// The capture's triangles as the decimation starts from them.  Vertices at
// one position (a capture's UV or normal seams) become one: kept apart, a
// seam is a boundary the decimation must keep whole, and the cage carries
// it as a crack of coincident vertices (which a glTF tool then welds).
// Triangles that collapse in the welding are dropped.
std::vector<uint32_t> weldedTriangles(const TriangleMesh& high)
{
    std::vector<uint32_t> welded = high.triangles;
    weldFaces(firstAtPosition(high.positions), &welded);
    orientConsistently(&welded);
    return welded;
}

// `welded` (weldedTriangles of `high`) simplified by meshoptimizer towards
// `faces` triangles while its error stays within 0.1% of the capture's
// size; `welded` itself when it is already that few.
std::vector<uint32_t> preSimplified(const TriangleMesh& high, const std::vector<uint32_t>& welded, size_t faces)
{
    if (welded.size() / 3 <= faces)
        return welded;
    std::vector<uint32_t> out(welded.size());
    out.resize(meshopt_simplify(out.data(), welded.data(), welded.size(), &high.positions[0].x, high.positions.size(),
                                sizeof(glm::vec3), 3 * faces, 1e-3f, 0, nullptr));
    return out;
}

}  // namespace

// Quadric error summed over a character's poses (Mohr and Gleicher's
// deformation-sensitive decimation): each vertex keeps one quadric of its
// faces' planes at rest and one per pose, and a collapse onto v1 costs
// the rest quadric's error at v1 plus the mean of the posed ones at v1's
// posed places, plus the largest of those.  A joint's faces, flat at rest,
// fold when posed, so the cage keeps vertices where the character bends
// (its skin is carried per cage vertex, and a face that spans a bend cannot
// follow it); the largest keeps a joint that folds in a few poses only (a
// run's stride), which the mean over every animation dilutes.  With it,
// posed RMS mean / worst: CesiumMan 0.0285 / 0.0321% -> 0.0251 / 0.0272%,
// the 60k-triangle stand-in 0.0370 / 0.0393% -> 0.0359 / 0.0379%; rest
// plus the largest alone lost on the stand-in (0.0378 / 0.0406%).
template <class MeshT>
class ModPosedQuadricT : public OpenMesh::Decimater::ModBaseT<MeshT> {
public:
    DECIMATING_MODULE(ModPosedQuadricT, MeshT, PosedQuadric);

    explicit ModPosedQuadricT(MeshT& mesh) : Base(mesh, false) {}

    // The capture posed (posed[q * count + c], capture vertex c in pose q)
    // and the capture vertex of each mesh vertex.  Poses past what 256 MB
    // of places and quadrics hold are thinned evenly.
    void setPoses(const std::vector<glm::vec3>& posed, size_t count, std::vector<uint32_t> original)
    {
        const size_t given = count ? posed.size() / count : 0;
        const size_t perPose = (sizeof(OpenMesh::Vec3d) + sizeof(OpenMesh::Geometry::Quadricd)) *
                               std::max<size_t>(1, original.size());
        poses_ = std::min(given, std::max<size_t>(1, (size_t(256) << 20) / perPose) - 1);
        at_.assign((poses_ + 1) * original.size(), OpenMesh::Vec3d(0.0));
        for (size_t v = 0; v < original.size(); ++v) {
            const auto p = Base::mesh().point(typename MeshT::VertexHandle(int(v)));
            at_[v * (poses_ + 1)] = OpenMesh::Vec3d(p[0], p[1], p[2]);
            for (size_t q = 0; q < poses_; ++q) {
                const glm::vec3& x = posed[q * given / poses_ * count + original[v]];
                at_[v * (poses_ + 1) + q + 1] = OpenMesh::Vec3d(x.x, x.y, x.z);
            }
        }
    }

    // An open capture's rims (scan holes, an open neck): each boundary edge
    // adds the plane through it square to its face, weighted by `weight`
    // times its length squared, to both its vertices (Garland and
    // Heckbert's boundary constraint), so collapses keep the rim where it
    // runs instead of cutting across the hole with chords that the cage's
    // faces then span over no capture at all.  0: none.
    void setBoundaryWeight(double weight) { boundaryWeight_ = weight; }

    void initialize() override
    {
        const size_t stride = poses_ + 1;
        quadrics_.assign(stride * Base::mesh().n_vertices(), OpenMesh::Geometry::Quadricd());
        if (boundaryWeight_ > 0.0)
            for (auto h : Base::mesh().halfedges()) {
                if (!Base::mesh().is_boundary(h))
                    continue;
                const auto inside = Base::mesh().opposite_halfedge_handle(h);
                const size_t a = size_t(Base::mesh().from_vertex_handle(h).idx()),
                             b = size_t(Base::mesh().to_vertex_handle(h).idx()),
                             c = size_t(Base::mesh().to_vertex_handle(Base::mesh().next_halfedge_handle(inside)).idx());
                for (size_t q = 0; q < stride; ++q) {
                    const OpenMesh::Vec3d &pa = at_[a * stride + q], &pb = at_[b * stride + q],
                                          &pc = at_[c * stride + q];
                    const OpenMesh::Vec3d e = pb - pa, face = e % (pc - pa);
                    OpenMesh::Vec3d m = e % face;
                    const double length = m.norm();
                    if (!(length > 0.0))
                        continue;
                    m /= length;
                    OpenMesh::Geometry::Quadricd quadric(m[0], m[1], m[2], -(pa | m));
                    quadric *= boundaryWeight_ * e.sqrnorm() * (q == 0 ? 1.0 : 1.0 / double(poses_));
                    quadrics_[a * stride + q] += quadric;
                    quadrics_[b * stride + q] += quadric;
                }
            }
        for (auto f : Base::mesh().faces()) {
            size_t v[3], k = 0;
            for (auto vh : Base::mesh().fv_range(f))
                v[k++] = size_t(vh.idx());
            for (size_t q = 0; q < stride; ++q) {
                const OpenMesh::Vec3d &a = at_[v[0] * stride + q], &b = at_[v[1] * stride + q],
                                      &c = at_[v[2] * stride + q];
                OpenMesh::Vec3d n = (b - a) % (c - a);
                double area = n.norm();
                if (!(area > FLT_MIN))
                    continue;
                n /= area;
                area *= q == 0 ? 0.5 : 0.5 / double(poses_);
                OpenMesh::Geometry::Quadricd quadric(n[0], n[1], n[2], -(a | n));
                quadric *= area;
                for (size_t corner : v)
                    quadrics_[corner * stride + q] += quadric;
            }
        }
    }

    float collapse_priority(const CollapseInfo& ci) override
    {
        const size_t stride = poses_ + 1, v0 = size_t(ci.v0.idx()), v1 = size_t(ci.v1.idx());
        double error = 0.0, largest = 0.0;
        for (size_t q = 0; q < stride; ++q) {
            OpenMesh::Geometry::Quadricd quadric = quadrics_[v0 * stride + q];
            quadric += quadrics_[v1 * stride + q];
            const double e = quadric(at_[v1 * stride + q]);
            error += e;
            if (q > 0)  // a pose's quadrics are weighted by 1 / poses (their sum is the mean)
                largest = std::max(largest, e * double(poses_));
        }
        return float(error + largest);
    }

    void postprocess_collapse(const CollapseInfo& ci) override
    {
        const size_t stride = poses_ + 1, v0 = size_t(ci.v0.idx()), v1 = size_t(ci.v1.idx());
        for (size_t q = 0; q < stride; ++q)
            quadrics_[v1 * stride + q] += quadrics_[v0 * stride + q];
    }

private:
    size_t poses_ = 0;
    double boundaryWeight_ = 0.0;
    std::vector<OpenMesh::Vec3d> at_;                              // per vertex: rest, then each pose
    std::vector<OpenMesh::Geometry::Quadricd> quadrics_;           // the same layout
};

// A character of many separate pieces (a robot's bolts, fingers, plates)
// keeps each piece at kPieceFloorFaces faces or more (or all it had): the
// quadrics see a bolt as a speck of error and collapse it to a
// tetrahedron, which no displacement draws back as a ball (the map's few
// texels over its four corners drew cones, half its radius out).  A piece
// that reaches its floor has its vertices locked, so no collapse whose
// priority was queued before can take it lower.
template <class MeshT>
class ModPieceFloorT : public OpenMesh::Decimater::ModBaseT<MeshT> {
public:
    DECIMATING_MODULE(ModPieceFloorT, MeshT, PieceFloor);

    explicit ModPieceFloorT(MeshT& mesh) : Base(mesh, true) {}

    // Per mesh vertex (its index), its piece.
    void setPieces(std::vector<uint32_t> piece, size_t floor)
    {
        piece_ = std::move(piece);
        floor_ = floor;
    }

    void initialize() override
    {
        MeshT& mesh = Base::mesh();
        size_t count = 0;
        for (uint32_t p : piece_)
            count = std::max<size_t>(count, size_t(p) + 1);
        faces_.assign(count, 0);
        members_.assign(count, {});
        for (auto f : mesh.faces())
            ++faces_[piece_[size_t(mesh.fv_begin(f)->idx())]];
        for (auto v : mesh.vertices())
            members_[piece_[size_t(v.idx())]].push_back(v);
        least_.resize(count);
        for (size_t p = 0; p < count; ++p) {
            least_[p] = std::min(faces_[p], floor_);
            lockAtFloor(p);
        }
    }

    float collapse_priority(const CollapseInfo& ci) override
    {
        const size_t p = piece_[size_t(ci.v0.idx())];
        return faces_[p] >= least_[p] + removed(ci) ? float(Base::LEGAL_COLLAPSE) : float(Base::ILLEGAL_COLLAPSE);
    }

    void postprocess_collapse(const CollapseInfo& ci) override
    {
        const size_t p = piece_[size_t(ci.v1.idx())];
        faces_[p] -= std::min(faces_[p], removed(ci));
        lockAtFloor(p);
    }

private:
    static size_t removed(const CollapseInfo& ci) { return size_t(ci.fl.is_valid()) + size_t(ci.fr.is_valid()); }

    // A collapse of a closed piece takes two faces: under its floor + 2, none may.
    void lockAtFloor(size_t p)
    {
        if (faces_[p] >= least_[p] + 2)
            return;
        for (auto v : members_[p])
            Base::mesh().status(v).set_locked(true);
        members_[p].clear();
    }

    size_t floor_ = 0;
    std::vector<uint32_t> piece_;                                   // per mesh vertex
    std::vector<size_t> faces_, least_;                             // per piece: its live faces, its floor
    std::vector<std::vector<typename MeshT::VertexHandle>> members_;  // per piece, until locked
};

// ModPieceFloorT's floor.  The robot stand-in (59 pieces, 28 of them taken
// to 4 faces by the default search's 2,257-face cage): see docs/RESULTS.md.
constexpr size_t kPieceFloorFaces = 12;

// The rims' weight against the faces' (ModPosedQuadricT::setBoundaryWeight).
// Nefertiti with ten holes cut (3% of its diagonal across) on 1,400 faces:
// recon -> capture RMS 0.121% with none (max 2.6%: cage faces over the
// holes), 0.014% at 1, 0.0131% at 10, 0.0148% at 100, 0.0155% at 1000; at
// the default 0.01% its automatic rig went 155 -> 53 KB (10,723 -> 1,996
// faces), the intact bust's being 56 KB.
constexpr double kBoundaryWeight = 10.0;

struct Simplifier::State {
    using Decimater = OpenMesh::Decimater::DecimaterT<OMesh>;
    OMesh om;
    std::unique_ptr<Decimater> decimater;
    OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
    ModPosedQuadricT<OMesh>::Handle posedQuadric;  // a character's, instead of `quadric`
    OpenMesh::Decimater::ModNormalFlippingT<OMesh>::Handle flipping;
    ModPieceFloorT<OMesh>::Handle pieceFloor;  // a capture of more than one piece
    size_t faces = 0;  // the live faces after the last simplify
    std::vector<uint32_t> refused;  // the capture's faces OpenMesh could not join, 3 corners each
    OpenMesh::VPropHandleT<uint32_t> original;  // the capture vertex of each mesh vertex
};

Simplifier::Simplifier(const TriangleMesh& high, std::vector<glm::vec3> posed)
    : high_(high), posed_(std::move(posed))
{
}
Simplifier::~Simplifier() = default;

Status Simplifier::simplify(size_t targetFaces, ControlMesh* out, std::vector<uint32_t>* originals)
{
    QuietOpenMesh quiet;
    if (targetFaces < 4)
        return Status(StatusCode::InvalidArgument, "--control-faces must be at least 4");
    if (!state_ || targetFaces > state_->faces + refusedFaces()) {
        // The mesh OpenMesh decimates, from a capture's welded faces.
        const auto meshOf = [&](const std::vector<uint32_t>& start) {
            auto state = std::make_unique<State>();
            OMesh& om = state->om;
            // Deleting (isolated vertices, collapsed elements) needs status flags.
            om.request_vertex_status();
            om.request_edge_status();
            om.request_face_status();
            std::vector<OMesh::VertexHandle> vh(high_.positions.size());
            OpenMesh::VPropHandleT<uint32_t> original;  // the capture vertex of each mesh vertex
            om.add_property(original);
            for (uint32_t v : start)
                if (!vh[v].is_valid()) {
                    const glm::vec3& p = high_.positions[v];
                    vh[v] = om.add_vertex(OMesh::Point(p.x, p.y, p.z));
                    om.property(original, vh[v]) = v;
                }
            // A face on the corners of an earlier one (a duplicate, either way
            // round) is no more surface.  A face OpenMesh cannot join to the
            // rest (a fin on an edge two faces already share, a second fan at a
            // vertex) is kept aside: its corners are locked against collapses,
            // and it joins every cage as it is (the runtime refines any
            // topology).  Given corners of its own instead, it would be a crack
            // of coincident vertices, which the rig's glTF welds: a rig that
            // does not load back.  Spot with 50 fins: 0.073% RMS on the capture
            // itself without them, 0.0000% with them.
            std::vector<std::array<uint32_t, 3>> sorted(start.size() / 3);
            std::vector<uint32_t> order(sorted.size());
            for (uint32_t f = 0; f < order.size(); ++f) {
                sorted[f] = {start[3 * f], start[3 * f + 1], start[3 * f + 2]};
                std::sort(sorted[f].begin(), sorted[f].end());
                order[f] = f;
            }
            std::stable_sort(order.begin(), order.end(),
                             [&](uint32_t a, uint32_t b) { return sorted[a] < sorted[b]; });
            std::vector<uint8_t> repeated(sorted.size(), 0);
            for (size_t i = 1; i < order.size(); ++i)
                repeated[order[i]] = sorted[order[i]] == sorted[order[i - 1]];
            for (size_t f = 0; f < start.size() / 3; ++f)
                if (!repeated[f] &&
                    !om.add_face(vh[start[3 * f]], vh[start[3 * f + 1]], vh[start[3 * f + 2]]).is_valid())
                    state->refused.insert(state->refused.end(), &start[3 * f], &start[3 * f] + 3);
            om.delete_isolated_vertices();
            om.garbage_collection();
            if (!state->refused.empty()) {
                std::vector<uint8_t> corner(high_.positions.size(), 0);
                for (uint32_t v : state->refused)
                    corner[v] = 1;
                for (auto v : om.vertices())
                    if (corner[om.property(original, v)])
                        om.status(v).set_locked(true);
            }
            state->original = original;
            return state;
        };
        // A large capture first goes most of the way with meshoptimizer's
        // quadric simplifier (topology kept, no flips), held to a tenth of
        // a percent of its size: ten times the faces asked for, at least
        // 20,000.  OpenMesh's decimater then takes the last collapses, with
        // quadrics of a surface that close to the capture, in a fifth of the
        // time the whole capture took (single-threaded, it was a third of
        // an automatic bake of a 100k-triangle scan).  Where its collapses
        // leave a face OpenMesh cannot join that the capture did not have
        // (a sliver along a crease, three faces on an edge: the robot's
        // hands), the cage would not be closed: meshoptimizer is then held
        // to four times as many faces, and past the capture's own count
        // the whole capture is decimated (a million-triangle scan is not
        // taken whole to OpenMesh for one sliver).  The start with the
        // fewest such faces is kept, the first of equals.
        const std::vector<uint32_t> welded = weldedTriangles(high_);
        size_t preFaces = std::max<size_t>(20000, 10 * targetFaces);
        auto state = meshOf(preSimplified(high_, welded, preFaces));
        const size_t weldedFaces = welded.size() / 3;
        while (!state->refused.empty() && preFaces < weldedFaces) {
            preFaces = preFaces > weldedFaces / 4 ? std::numeric_limits<size_t>::max() : 4 * preFaces;
            auto next = meshOf(preSimplified(high_, welded, preFaces));
            if (next->refused.size() < state->refused.size())
                state = std::move(next);
        }
        OMesh& om = state->om;
        const OpenMesh::VPropHandleT<uint32_t> original = state->original;
        if (om.n_faces() == 0)
            return Status(StatusCode::InvalidData, "the high-resolution mesh has no manifold faces to simplify");
        state->decimater = std::make_unique<State::Decimater>(om);
        State::Decimater& decimater = *state->decimater;
        const size_t poses = posed_.size() / std::max<size_t>(1, high_.positions.size());
        const bool posed = poses > 0 && posed_.size() == poses * high_.positions.size();
        bool open = false;
        for (auto e : om.edges())
            open = open || om.is_boundary(e);
        // An open capture (a scan with holes, a character open at the neck)
        // holds its rims (kBoundaryWeight); a closed static one takes
        // OpenMesh's own quadrics (the same face quadrics, the same cages).
        if (posed || open) {
            std::vector<uint32_t> kept;
            for (auto v : om.vertices())
                kept.push_back(om.property(original, v));
            decimater.add(state->posedQuadric);
            decimater.module(state->posedQuadric)
                .setPoses(posed ? posed_ : std::vector<glm::vec3>(), high_.positions.size(), std::move(kept));
            if (open)
                decimater.module(state->posedQuadric).setBoundaryWeight(kBoundaryWeight);
        } else {
            decimater.add(state->quadric);
        }
        decimater.add(state->flipping);
        decimater.module(state->flipping).set_max_normal_deviation(60.0);
        // A character's pieces only: a scan's specks of debris are no parts
        // to keep.
        size_t pieces = 0;
        const std::vector<uint32_t> shells = posed ? captureShells(high_, &pieces) : std::vector<uint32_t>();
        if (pieces > 1) {
            std::vector<uint32_t> piece(om.n_vertices());
            for (auto v : om.vertices())
                piece[size_t(v.idx())] = shells[om.property(original, v)];
            decimater.add(state->pieceFloor);
            decimater.module(state->pieceFloor).setPieces(std::move(piece), kPieceFloorFaces);
        }
        if (!decimater.initialize())
            return Status(StatusCode::InvalidData, "OpenMesh's decimater could not be initialised");
        state->faces = om.n_faces();
        state_ = std::move(state);
    }
    // The decimater counts the faces it starts from with the deleted ones
    // (n_faces() before a garbage collection): those are added to the target.
    // The faces kept aside count towards the target.
    const size_t refused = refusedFaces();
    const size_t decimated = std::max<size_t>(4, targetFaces > refused ? targetFaces - refused : 0);
    state_->decimater->decimate_to_faces(0, decimated + (state_->om.n_faces() - state_->faces));
    // The mesh the decimater works on keeps its deleted elements (a later,
    // smaller count continues from it); a copy is compacted and read.
    OMesh om = state_->om;
    om.garbage_collection();
    state_->faces = om.n_faces();

    ControlMesh cm;
    std::vector<uint32_t> from;
    for (auto v : om.vertices()) {
        const auto p = om.point(v);
        cm.positions.emplace_back(p[0], p[1], p[2]);
        from.push_back(om.property(state_->original, v));
    }
    for (auto f : om.faces())
        for (auto v : om.fv_range(f))
            cm.triangles.push_back(uint32_t(v.idx()));
    // The faces kept aside, on their locked corners (or corners of their own).
    if (!state_->refused.empty()) {
        std::vector<int64_t> at(high_.positions.size(), -1);
        for (auto v : om.vertices())
            at[om.property(state_->original, v)] = v.idx();
        for (uint32_t c : state_->refused) {
            if (at[c] < 0) {
                at[c] = int64_t(cm.positions.size());
                cm.positions.push_back(high_.positions[c]);
                from.push_back(c);
            }
            cm.triangles.push_back(uint32_t(at[c]));
        }
    }
    Status st = validateControlMesh(cm);
    if (!st)
        return Status(st.code(), "the simplified control mesh is unusable: " + st.message());
    *out = std::move(cm);
    if (originals)
        *originals = std::move(from);
    return Status::ok();
}

std::vector<uint32_t> captureShells(const TriangleMesh& high, size_t* count)
{
    const std::vector<uint32_t> first = firstAtPosition(high.positions);
    std::vector<uint32_t> parent(high.positions.size());
    for (uint32_t v = 0; v < parent.size(); ++v)
        parent[v] = first[v];
    auto root = [&](uint32_t v) {
        while (parent[v] != v)
            v = parent[v] = parent[parent[v]];
        return v;
    };
    for (size_t t = 0; t + 2 < high.triangles.size(); t += 3) {
        for (int k = 1; k < 3; ++k) {
            const uint32_t a = root(high.triangles[t]), b = root(high.triangles[t + size_t(k)]);
            if (a != b)
                parent[std::max(a, b)] = std::min(a, b);
        }
    }
    std::vector<uint32_t> shell(parent.size()), label(parent.size(), UINT32_MAX);
    size_t n = 0;
    for (uint32_t v = 0; v < parent.size(); ++v) {
        const uint32_t r = root(v);
        if (label[r] == UINT32_MAX)
            label[r] = uint32_t(n++);
        shell[v] = label[r];
    }
    if (count)
        *count = n;
    return shell;
}

size_t Simplifier::refusedFaces() const
{
    return state_ ? state_->refused.size() / 3 : 0;
}

Status decimateToControlMesh(const TriangleMesh& high, size_t targetFaces, ControlMesh* out,
                             std::vector<glm::vec3> posed)
{
    return Simplifier(high, std::move(posed)).simplify(targetFaces, out);
}

size_t countBoundaryEdges(const uint32_t* triangles, size_t faceCount)
{
    const EdgeGroups edges = groupEdges(triangles, faceCount);
    size_t boundary = 0;
    for (size_t e = 0; e < edges.edgeCount(); ++e)
        boundary += edges.faceCountOf(e) == 1;
    return boundary;
}

size_t closeBoundaryLoops(ControlMesh* mesh)
{
    // Directed boundary edges a -> b, as their one face has them.
    const EdgeGroups edges = groupEdges(mesh->triangles.data(), mesh->faceCount());
    std::vector<std::pair<uint32_t, uint32_t>> boundary;  // (a, b)
    for (size_t e = 0; e < edges.edgeCount(); ++e)
        if (edges.faceCountOf(e) == 1) {
            const uint32_t c = edges.cornersOf(e)[0];
            boundary.push_back({mesh->triangles[c], mesh->triangles[c / 3 * 3 + (c % 3 + 1) % 3]});
        }
    if (boundary.empty())
        return 0;
    std::sort(boundary.begin(), boundary.end());
    for (size_t i = 1; i < boundary.size(); ++i)
        if (boundary[i].first == boundary[i - 1].first)
            return 0;  // two boundary edges leave one vertex: ambiguous loops
    auto next = [&](uint32_t a) -> int64_t {
        const auto it = std::lower_bound(boundary.begin(), boundary.end(), std::make_pair(a, 0u));
        return it != boundary.end() && it->first == a ? int64_t(it->second) : -1;
    };
    std::vector<uint8_t> used(boundary.size(), 0);
    std::vector<std::vector<uint32_t>> loops;
    for (size_t i = 0; i < boundary.size(); ++i) {
        if (used[i])
            continue;
        std::vector<uint32_t> loop;
        uint32_t a = boundary[i].first;
        for (size_t guard = 0; guard <= boundary.size(); ++guard) {
            const auto it = std::lower_bound(boundary.begin(), boundary.end(), std::make_pair(a, 0u));
            if (it == boundary.end() || it->first != a)
                return 0;  // the chain ends at a vertex no boundary edge leaves: no closed loop
            const size_t k = size_t(it - boundary.begin());
            if (used[k])
                break;
            used[k] = 1;
            loop.push_back(a);
            const int64_t b = next(a);
            if (b < 0)
                return 0;
            a = uint32_t(b);
        }
        if (a != boundary[i].first || loop.size() < 3)
            return 0;  // not a closed loop
        loops.push_back(std::move(loop));
    }
    for (const std::vector<uint32_t>& loop : loops) {
        glm::dvec3 centre(0.0);
        for (uint32_t v : loop)
            centre += glm::dvec3(mesh->positions[v]);
        const uint32_t c = uint32_t(mesh->positions.size());
        mesh->positions.push_back(glm::vec3(centre / double(loop.size())));
        // The loop runs as its faces have it; the cap runs the other way.
        for (size_t i = 0; i < loop.size(); ++i) {
            const uint32_t a = loop[i], b = loop[(i + 1) % loop.size()];
            mesh->triangles.insert(mesh->triangles.end(), {b, a, c});
        }
    }
    mesh->uvs.clear();
    mesh->uvIndices.clear();
    return loops.size();
}

}  // namespace baker
}  // namespace strata
