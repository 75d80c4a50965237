// Strata baker: reading captured meshes and deriving control meshes.
#pragma once

#include "strata/baker/bake.h"
#include "strata/animation.h"
#include "strata/control_mesh.h"
#include "strata/rig.h"
#include "strata/status.h"

#include <memory>
#include <string>

namespace strata {
namespace baker {

/// What was tolerated while reading a high-resolution mesh.
struct HighMeshStats {
    size_t polygonsTriangulated = 0;
    size_t duplicateVertices = 0;   ///< vertices at the exact position of an earlier one
    size_t degenerateTriangles = 0; ///< zero area (skipped by the rasteriser)
    size_t nonManifoldEdges = 0;    ///< edges with more than two faces (harmless to the bake)
    size_t unreferencedVertices = 0; ///< used by no triangle: left out
    /// When any were left out: per vertex kept, its number in the file's mesh.
    std::vector<uint32_t> keptVertices;
    /// A glTF capture none of whose triangle primitives has NORMAL: glTF
    /// draws it with face normals, and its rig says so (DisplacementInfo::flatShading).
    bool drawnFlat = false;
};

/// Reads OBJ, PLY / STL / OFF (Strata's bounded readers, polygons
/// triangulated) or glTF / GLB.  Vertices no triangle uses are left out
/// (stats says how many, and which were kept).  Errors name the file.  A
/// file whose reading would take more than maxMemoryMB is refused before it
/// is read.
Status loadHighMesh(const std::string& path, TriangleMesh* out, HighMeshStats* stats, double maxMemoryMB = 2048.0);

/// Leaves out of a rig read from a capture (loadControlRig of the same
/// file) the vertices loadHighMesh left out of its mesh (`stats`), with
/// their skin weights, so that both number the same vertices.
Status keepCaptureVertices(Rig* rig, const HighMeshStats& stats);

/// Reads a control mesh: OBJ (with UVs when present) or glTF / GLB (a rig or
/// any triangle mesh).  A glTF's skin, skeleton and animations go to
/// `skeleton` (when non-null) so the baked rig carries them.  Errors name the file.
Status loadControlMesh(const std::string& path, ControlMesh* out, Skeleton* skeleton = nullptr);

/// The control mesh as a whole rig: from glTF with its source document
/// (so the baked rig keeps everything the file had), parts and skin; from
/// OBJ the mesh alone.  Warnings say what was tolerated.  Loading is
/// bounded by maxMemoryMB as loadHighMesh's is.
Status loadControlRig(const std::string& path, Rig* out, double maxMemoryMB = 2048.0);

/// Derives a control mesh from a high-resolution one by quadric decimation
/// down to about targetFaces triangles, as the paper suggests (section 2):
/// a capture of more than max(20,000, 10 x targetFaces) triangles is first
/// brought to that count by meshoptimizer's simplifier (held within 0.1% of
/// its size), then OpenMesh's Decimater (with normal-flip protection) takes
/// the last collapses.  No UVs.  A character's capture may come with its
/// vertices posed (`posed`: posed[q * vertexCount + v], from skinPositions
/// in skin_transfer.h): each collapse then costs its quadric error at rest
/// plus the mean over the poses and the largest of them
/// (deformation-sensitive decimation), so the cage keeps vertices where the
/// character bends.
Status decimateToControlMesh(const TriangleMesh& high, size_t targetFaces, ControlMesh* out,
                             std::vector<glm::vec3> posed = {});

/// decimateToControlMesh for several face counts of one capture (the tries
/// of --control auto's face-count search): a count at or below the last
/// one continues the same collapses, with the quadrics they accumulated, so
/// it costs the collapses between the two counts instead of a new
/// decimation of the whole capture (the same greedy order, so the same mesh
/// but where collapses of equal cost are taken in another order); a larger
/// count starts over.  `high` must outlive the simplifier.
class Simplifier {
public:
    /// `posed`: as decimateToControlMesh's.
    explicit Simplifier(const TriangleMesh& high, std::vector<glm::vec3> posed = {});
    ~Simplifier();
    Simplifier(const Simplifier&) = delete;
    Simplifier& operator=(const Simplifier&) = delete;
    /// `originals` (optional): per cage vertex, the capture vertex it is
    /// (collapses keep one end of each edge where it was).
    Status simplify(size_t targetFaces, ControlMesh* out, std::vector<uint32_t>* originals = nullptr);
    /// The capture's faces (duplicates aside) the last simplify could not
    /// join to the mesh it decimates (non-manifold: a fin on an edge two
    /// faces already share, a second fan at a vertex): their corners are
    /// kept through the collapses and every cage has them as they are.
    size_t refusedFaces() const;

private:
    struct State;  // OpenMesh's mesh and decimater (mesh_input.cpp)
    const TriangleMesh& high_;
    std::vector<glm::vec3> posed_;
    std::unique_ptr<State> state_;
};

/// Per vertex of the capture, its connected piece (0..*count-1), vertices
/// at one position joined: the shells of ShellLabels.
std::vector<uint32_t> captureShells(const TriangleMesh& high, size_t* count);

/// Number of edges used by exactly one triangle (0 for a closed mesh).
size_t countBoundaryEdges(const uint32_t* triangles, size_t faceCount);

/// Closes every boundary loop of `mesh` with a fan of triangles around a new
/// vertex at the loop's centroid, oriented like the faces beside it: a
/// control mesh left open (a neck, a wrist) where the capture is closed can
/// then carry the capture's cap.  UVs are dropped (the caller lays out new
/// ones).  Does nothing and returns 0 when a boundary vertex has more than
/// one boundary edge leaving it (the loops are ambiguous); else the number
/// of loops closed.
size_t closeBoundaryLoops(ControlMesh* mesh);

}  // namespace baker
}  // namespace strata
