// Strata runtime: uniform refinement plans and CPU reconstruction
// (paper sections 2.3 and 3.1; the smooth scheme follows Lee, Moreton and
// Hoppe's Displaced Subdivision Surfaces).
//
// A Plan is built once per (control topology, scheme, level).  It owns the
// OpenSubdiv stencil tables, the refined topology and UVs, and one sample
// location (control face, barycentrics, UV) and one displacement per refined
// vertex.  Per frame, evaluate() turns the current control positions and
// normals into displaced refined positions; it allocates nothing, is const,
// and may be called from several threads on disjoint vertex ranges.
#pragma once

#include "strata/control_mesh.h"
#include "strata/displacement_map.h"
#include "strata/status.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace strata {

class DisplacementField;

/// How the refined surface is placed before displacement.
enum class Scheme {
    /// The paper's 1-to-4 midpoint split: refined vertices lie on the flat
    /// control triangles and move along the barycentric interpolation of the
    /// control vertex normals (eq. 2).  OpenSubdiv Loop with every edge and
    /// vertex infinitely sharp; at most 3 weights per refined vertex.
    Linear,
    /// The Loop limit surface, displaced along the unit limit normal
    /// (Displaced Subdivision Surfaces).  Smaller displacements, smoother.
    Smooth,
};

const char* schemeName(Scheme scheme);
/// Parses "linear" or "smooth"; returns false for anything else.
bool parseScheme(const std::string& text, Scheme* out);

/// Highest uniform level a plan accepts (4^6 = 4096 triangles per control triangle).
constexpr int kMaxLevel = 6;

/// Where a refined vertex sits on the control mesh: control face and the
/// barycentric weights (b1, b2) of its 2nd and 3rd corner (b0 = 1 - b1 - b2),
/// which is also the (s, t) of OpenSubdiv's triangular ptex parameterisation.
struct SampleLocation {
    uint32_t face;  ///< kNoControlFace for a vertex no face uses
    glm::vec2 bary;
};

/// Slot of grid point (i, j) of a control face refined to R = 2^level per
/// edge (barycentrics b1 = i / R, b2 = j / R, b0 = 1 - b1 - b2) in a tile of
/// (R + 1)(R + 2) / 2 slots: row j = 0 first, i ascending within a row.
inline size_t tileSlot(uint32_t i, uint32_t j, uint32_t R)
{
    return size_t(j) * (R + 1) - size_t(j) * (j - 1) / 2 + i;
}

/// SampleLocation::face of a refined vertex that descends from a control
/// vertex no face references: it stays where its control vertex is and is
/// never displaced.
constexpr uint32_t kNoControlFace = 0xffffffffu;

/// Per-corner data refined linearly inside each control face, the way a
/// plan refines UVs (FVAR_LINEAR_ALL): material UVs of any set, colours, or
/// the file vertex each corner came from.  Each refined value is a weighted
/// sum of at most three control values of one face.
struct FaceVaryingRefinement {
    std::vector<uint32_t> corners;  ///< 3 per refined face (plan order): refined value index
    std::vector<uint32_t> offsets;  ///< refined value count + 1: CSR into sources and weights
    std::vector<uint32_t> sources;  ///< control value index per entry
    std::vector<float> weights;     ///< weight per entry
};

/// Refines per-corner values through mesh's topology at `level`.
/// \param cornerValues  3 per control face, each < valueCount
Status refineFaceVarying(FaceVaryingRefinement* out, const ControlMesh& mesh, const uint32_t* cornerValues,
                         size_t valueCount, int level);

class Plan {
public:
    /// Builds the plan: topology refiner, stencil tables (vertex and, with
    /// UVs, face-varying), refined topology, sample locations.
    /// \param out    receives the plan on success, untouched on failure
    /// \param mesh   the control mesh (validated here; the plan keeps no reference)
    /// \param level  0..kMaxLevel
    static Status create(std::unique_ptr<Plan>* out, const ControlMesh& mesh, Scheme scheme, int level);
    /// The same, where `sameTopology` is a plan of this control topology,
    /// scheme and level (other positions or UVs): it lends its smooth-scheme
    /// limit stencils, the costly part (OpenSubdiv's limit stencil table),
    /// which are copied instead of computed.  Ignored (null, or another
    /// topology, scheme or level) the plan is built as create() builds it.
    static Status create(std::unique_ptr<Plan>* out, const ControlMesh& mesh, Scheme scheme, int level,
                         const Plan* sameTopology);

    ~Plan();
    Plan(const Plan&) = delete;
    Plan& operator=(const Plan&) = delete;

    Scheme scheme() const { return scheme_; }
    int level() const { return level_; }
    size_t controlVertexCount() const { return controlVertexCount_; }
    /// controlTopologyHash of the control mesh the plan was built from: a
    /// rig's displacements apply only to a plan of the same topology.
    uint64_t controlTopologyHash() const { return controlTopology_; }
    /// Whether `other` refines the same control topology (vertex count and
    /// triangles) with the same scheme to the same level: it has the same
    /// refined vertices, stencils and sample locations (create()'s
    /// sameTopology lends its limit stencils then).
    bool sameRefinement(const Plan& other) const;

    /// Refined topology: refinedVertexCount() vertices, 3 indices per face,
    /// counter-clockwise like the control mesh.  4^level faces per control face.
    size_t refinedVertexCount() const { return samples_.size(); }
    size_t refinedFaceCount() const { return triangles_.size() / 3; }
    const std::vector<uint32_t>& refinedTriangles() const { return triangles_; }
    /// The control mesh's triangles (3 vertex indices per face), as built.
    const std::vector<uint32_t>& controlTriangles() const { return controlTriangles_; }

    /// Whether the control mesh had UVs (sampleUVs() and refinedUVs() then
    /// make them).
    bool hasUVs() const { return !controlUVIndices_.empty(); }
    /// Refined face-varying UVs, made on demand (the plan keeps only the
    /// control UVs: evaluation needs none): values, and 3 indices into them
    /// per refined face.  Both empty without UVs.
    /// Linear (FVAR_LINEAR_ALL), bit-identical to OpenSubdiv's face-varying
    /// refinement; values are shared across a control edge whose two faces
    /// use the same UVs at its ends, so seams split them.
    void refinedUVs(std::vector<glm::vec2>* values, std::vector<uint32_t>* indices) const;

    /// Per refined vertex: its canonical location and UV.  A vertex on a UV
    /// seam has several face-varying UVs; the canonical one is the UV of its
    /// first corner in refined face order.  It is sampled once, so the
    /// reconstructed surface has no cracks along seams.
    const std::vector<SampleLocation>& sampleLocations() const { return samples_; }
    /// The canonical UVs, made on demand (refinedVertexCount() values, (0, 0)
    /// for a vertex no face uses; empty without UVs): what a map is sampled
    /// at, here or in a shader.
    void sampleUVs(std::vector<glm::vec2>* out) const;

    /// Samples the map once per refined vertex at its canonical UV (the
    /// barycentric samples never change under animation, paper 2.4), scaled by
    /// `scale`, into the plan's own displacements (a convenience for one
    /// character per plan; sampleDisplacements() + the evaluate() that takes
    /// displacements share one plan).  Needs a control mesh with UVs.
    Status setDisplacement(const DisplacementMap& map, float scale = 1.0f);
    /// Sets the displacements from per-vertex values stored at some level
    /// (a rig's "vertex" encoding): exact at that level and below.  field
    /// must have been made from the same control topology.
    Status setDisplacement(const DisplacementField& field, float scale = 1.0f);
    /// Sets the displacements directly, one per refined vertex (a rig that
    /// stores them per vertex: vertex_displacements.h), scaled by `scale`.
    /// Vertices no control face uses stay at zero.
    Status setDisplacements(const float* values, size_t count, float scale = 1.0f);
    /// Sets every displacement to zero (the bare refined surface).
    void clearDisplacement();
    /// refinedVertexCount() distances, in model units.
    const std::vector<float>& displacements() const { return displacements_; }

    /// evaluate() with the caller's displacements (refinedVertexCount()
    /// values, from sampleDisplacements()) instead of the plan's own: one
    /// plan, shared and never modified, serves every character that shares
    /// its control topology.
    Status evaluate(glm::vec3* dstPositions, glm::vec3* dstDirections, size_t begin, size_t end,
                    const float* displacements, const glm::vec3* controlPositions, const glm::vec3* controlNormals,
                    size_t controlCount) const;

    /// evaluate() of the listed refined vertices: dstPositions[k] (and
    /// dstDirections[k]) for vertex vertices[k], with the caller's
    /// displacements (refinedVertexCount() values).  The same expression
    /// as evaluate(), bit for bit: an adaptive frame (adaptive.h) pays only
    /// for the vertices it draws.
    Status evaluateVertices(glm::vec3* dstPositions, glm::vec3* dstDirections, const uint32_t* vertices, size_t count,
                            const float* displacements, const glm::vec3* controlPositions,
                            const glm::vec3* controlNormals, size_t controlCount) const;

    /// Each control face's refined vertices as its grid: refinedVertex of
    /// face f, slot tileSlot(i, j, 2^level) at out[f * slots + slot], slots =
    /// (R + 1)(R + 2) / 2.  Vertices on a control edge or corner appear in
    /// every tile that shares it.
    Status tileVertices(std::vector<uint32_t>* out) const;

    /// Per-frame reconstruction of refined vertices [begin, end):
    ///   dstPositions[i - begin] = surface(i) + d_i * direction(i)   (eq. 2)
    /// \param dstPositions    end - begin positions (caller-owned)
    /// \param dstDirections   optional (nullptr to skip): end - begin displacement
    ///                        directions (unnormalised in the linear scheme, unit in smooth)
    /// \param controlPositions, controlNormals  controlCount values each; the
    ///                        normals from computeControlNormals() (unused by Smooth,
    ///                        which may pass nullptr)
    /// Allocates nothing; thread-safe on disjoint ranges.
    Status evaluate(glm::vec3* dstPositions, glm::vec3* dstDirections, size_t begin, size_t end,
                    const glm::vec3* controlPositions, const glm::vec3* controlNormals, size_t controlCount) const;

    /// Shading normals of a reconstructed (displaced) refined mesh: the
    /// area-weighted sum of the incident refined face normals, normalised.
    /// \param dst        refinedVertexCount() normals (caller-owned)
    /// \param positions  refinedVertexCount() displaced positions from evaluate()
    void computeShadingNormals(glm::vec3* dst, const glm::vec3* positions) const;

    /// Bytes held by the plan's tables (stencils, topology, UVs, samples).
    size_t memoryBytes() const;
    /// Number of stencil weights per refined vertex, summed (for reports).
    size_t stencilWeightCount() const;

    /// The stencils evaluate() applies, as flat arrays for a GPU: refined
    /// vertex v reads entries [offsets[v], offsets[v + 1]) of indices, with
    /// weightsPerEntry floats per entry (linear: 1, the weight of position
    /// and normal, three entries per vertex including zero-weight padding;
    /// smooth: 3, the limit position, d/ds and d/dt weights).  Same entries
    /// in the same order as the CPU loop, so a GPU sums the same terms.
    struct FlatStencils {
        std::vector<uint32_t> offsets, indices;
        std::vector<float> weights;
        int weightsPerEntry = 1;
    };
    void flattenStencils(FlatStencils* out) const;

private:
    Plan() = default;
    Status build(const ControlMesh& mesh, const Plan* sameTopology);
    // The parts of build(), sharing one sharp refiner and each refined
    // vertex's first face and corner (Build, in plan.cpp).
    struct Build;
    Status buildTopology(Build& b);
    Status buildLinear(Build& b);
    Status buildUVs(Build& b);
    Status buildLimit(const ControlMesh& mesh);
    Status checkEvaluate(const glm::vec3* dstPositions, const float* displacements, const glm::vec3* controlPositions,
                         const glm::vec3* controlNormals, size_t controlCount) const;
    template <typename VertexAt>
    void evaluateEach(glm::vec3* dstPositions, glm::vec3* dstDirections, size_t count, const VertexAt& vertexAt,
                      const float* d, const glm::vec3* controlPositions, const glm::vec3* controlNormals) const;

    Scheme scheme_ = Scheme::Linear;
    int level_ = 0;
    size_t controlVertexCount_ = 0;
    uint64_t controlTopology_ = 0;

    std::vector<uint32_t> triangles_;
    std::vector<glm::vec2> controlUVs_;  // the control mesh's UVs, for refinedUVs()
    std::vector<uint32_t> controlUVIndices_;
    std::vector<SampleLocation> samples_;
    std::vector<float> displacements_;

    // Linear scheme: samples_ are the stencils (barycentrics in their control
    // face); isolated_ lists the vertices no face uses (they keep their
    // control vertex's number).
    std::vector<uint32_t> controlTriangles_;
    std::vector<uint32_t> isolated_;
    std::vector<uint32_t> childCorners_;  // each corner of a face's 4^level children: grid point i | j << 16

    // Smooth scheme: limit stencils (position, d/ds, d/dt), CSR per refined vertex.
    std::vector<uint32_t> limitOffsets_;  // refinedVertexCount() + 1
    std::vector<uint32_t> limitIndices_;
    std::vector<float> limitWeights_;     // 3 per entry: position, du, dv
};

/// The displacement of every refined vertex of `plan`, sampled once from a
/// map at its canonical UV (needs a control mesh with UVs) or taken from a
/// per-vertex field, scaled by `scale`: the per-character state that goes
/// with a shared plan.  Vertices no face uses get 0.
/// \param dst  plan.refinedVertexCount() values (caller-owned)
Status sampleDisplacements(float* dst, const Plan& plan, const DisplacementMap& map, float scale = 1.0f);
Status sampleDisplacements(float* dst, const Plan& plan, const DisplacementField& field, float scale = 1.0f);

}  // namespace strata
