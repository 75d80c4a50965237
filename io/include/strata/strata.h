/* Strata C API (C99): load a rig, refine it, pose it, evaluate displaced
 * positions and normals into buffers the caller owns.  For engines that are
 * not C++ (P/Invoke, Rust, Zig, C).  Link Strata::c: libstrata.so, which
 * exports these functions and nothing else (pkg-config --libs strata).
 *
 *   StrataRig* rig;  StrataSurface* surface;
 *   if (strata_rig_load("hero.glb", &rig) != STRATA_OK) puts(strata_last_error());
 *   strata_surface_create(rig, -1, &surface);            // the rig's recommended level
 *   float* xyz = malloc(12 * strata_surface_vertex_count(surface));
 *   strata_surface_set_animation_time(surface, 0, 0.5f);  // or set_joint_matrices
 *   strata_surface_evaluate(surface, xyz, NULL);
 *   strata_surface_destroy(surface);  strata_rig_destroy(rig);
 *
 * Every function returns a status; on failure strata_last_error() (per
 * thread) holds the one-line message the tools print.  Handles are opaque;
 * a surface keeps no pointer into its rig (destroy them in any order).
 * Nothing here throws, aborts or prints.
 */
#ifndef STRATA_STRATA_H
#define STRATA_STRATA_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum StrataStatus {
    STRATA_OK = 0,
    STRATA_INVALID_ARGUMENT = 1,
    STRATA_INVALID_DATA = 2,
    STRATA_IO_ERROR = 3,
    STRATA_UNSUPPORTED = 4,
    STRATA_OUT_OF_MEMORY = 5
} StrataStatus;

typedef enum StrataScheme { STRATA_SCHEME_LINEAR = 0, STRATA_SCHEME_SMOOTH = 1 } StrataScheme;

typedef struct StrataRig StrataRig;
typedef struct StrataSurface StrataSurface;

/** The library version, "major.minor.patch". */
const char* strata_version(void);
/** The message of this thread's last failure ("" when none). */
const char* strata_last_error(void);

/* ---- Rigs ---- */

/** Loads a rig (.glb or .gltf; external files resolve inside its folder). */
StrataStatus strata_rig_load(const char* path, StrataRig** out);
/** Loads a rig from bytes (binary: nonzero for .glb); no file is read. */
StrataStatus strata_rig_load_memory(const void* data, size_t size, int binary, StrataRig** out);
void strata_rig_destroy(StrataRig* rig);

int strata_rig_recommended_level(const StrataRig* rig);
StrataScheme strata_rig_scheme(const StrataRig* rig);
size_t strata_rig_control_vertex_count(const StrataRig* rig);
/** Skin joints (0 for an unskinned rig); their matrices' order. */
size_t strata_rig_joint_count(const StrataRig* rig);
size_t strata_rig_animation_count(const StrataRig* rig);
/** Name of animation `index` (valid while the rig lives), or NULL. */
const char* strata_rig_animation_name(const StrataRig* rig, size_t index);
/** The glTF node of skin joint `joint` (-1 when out of range): an engine
 *  that animates the nodes itself poses with world(node) * inverse bind. */
int strata_rig_joint_node(const StrataRig* rig, size_t joint);
/** Joint `joint`'s inverse bind matrix: 16 floats, column-major. */
StrataStatus strata_rig_joint_inverse_bind(const StrataRig* rig, size_t joint, float* matrix);

/* ---- Surfaces: one refinement of a control mesh, evaluated per frame ---- */

/** A surface at `level` (0..6; negative: the rig's recommended level), in
 *  the rig's scheme, with its displacement, in the bind pose. */
StrataStatus strata_surface_create(const StrataRig* rig, int level, StrataSurface** out);

/** A surface from caller arrays, for engines with their own loaders:
 *  positions (3 floats per vertex), triangles (3 per face, counter-clockwise),
 *  uvs (2 floats per value) with uv_indices (3 per face), and a map of
 *  map_width * map_height texels, row 0 at v = 0, decoding to
 *  texel * map_factor + map_offset.  uvs, uv_indices and map_texels may all
 *  be NULL for no displacement.  Everything is copied. */
StrataStatus strata_surface_create_from_arrays(const float* positions, size_t vertex_count, const uint32_t* triangles,
                                               size_t triangle_count, const float* uvs, size_t uv_count,
                                               const uint32_t* uv_indices, const float* map_texels, int map_width,
                                               int map_height, float map_factor, float map_offset,
                                               StrataScheme scheme, int level, StrataSurface** out);
void strata_surface_destroy(StrataSurface* surface);

size_t strata_surface_vertex_count(const StrataSurface* surface);
size_t strata_surface_triangle_count(const StrataSurface* surface);
/** Copies the refined triangles: 3 * triangle_count indices. */
StrataStatus strata_surface_triangles(const StrataSurface* surface, uint32_t* dst);

/** The bind pose: the control positions as stored (a new surface's pose). */
StrataStatus strata_surface_set_bind_pose(StrataSurface* surface);
/** Poses a rig's surface from its own animation (index) at `time` seconds
 *  (linear blend skinning).  animation -1: the skeleton's rest pose. */
StrataStatus strata_surface_set_animation_time(StrataSurface* surface, int animation, float time);
/** Poses from skin matrices the engine computed (world * inverse bind), 16
 *  floats each, column-major, one per joint in the rig's order. */
StrataStatus strata_surface_set_joint_matrices(StrataSurface* surface, const float* matrices, size_t joint_count);
/** Poses from control positions the engine deformed itself (3 floats each).
 *  Each pose call refuses (STRATA_INVALID_ARGUMENT, the message naming the
 *  control vertex and any joint) a pose with a coordinate that is not
 *  finite or lies beyond +-1e9, and keeps the last pose. */
StrataStatus strata_surface_set_control_positions(StrataSurface* surface, const float* positions, size_t count);

/** The displacement of each refined vertex along its normal, in model
 *  units, in strata_surface_evaluate's order (vertex_count floats; zeros
 *  for a surface without displacement): for false colour and statistics. */
StrataStatus strata_surface_displacements(const StrataSurface* surface, float* dst);

/** Displaced refined positions (3 floats per vertex) and, unless NULL,
 *  shading normals (3 floats per vertex) of the current pose: the
 *  render-ready frame of FrameEvaluator, whose tables the first call makes.
 *  Calls on one surface from several threads are serialised. */
StrataStatus strata_surface_evaluate(const StrataSurface* surface, float* positions, float* normals);

/** A box (min and max, 3 floats each) that holds the current pose's surface
 *  at every level, uniform and adaptive: for culling and picking without
 *  reading the frame (Surface::bounds). */
StrataStatus strata_surface_bounds(const StrataSurface* surface, float* min, float* max);

/* ---- Adaptive level of detail (strata/adaptive.h) ----
 * Each control face at the lowest level whose surface stays within
 * pixel_error pixels of the surface's level on screen, for one view of the
 * current pose; neighbours at different levels are stitched without cracks.
 *
 *   strata_surface_choose_levels(surface, eye, target, 45.0f, 1080.0f, 1.0f);
 *   size_t n = strata_surface_adaptive_vertex_count(surface);
 *   strata_surface_evaluate_adaptive(surface, xyz, normals);   // n vertices
 *   strata_surface_adaptive_triangles(surface, indices);        // 3 per triangle
 */

/** Levels for a camera at eye (3 floats) looking at target (3 floats) with a
 *  vertical field of view in degrees and a viewport height in pixels.  The
 *  errors per face are measured at the first call; calls that give the
 *  levels already drawn keep the frame. */
StrataStatus strata_surface_choose_levels(StrataSurface* surface, const float* eye, const float* target,
                                          float fov_y_degrees, float height_px, float pixel_error);
/** Vertices and triangles of the adaptive frame (0 before a choice). */
size_t strata_surface_adaptive_vertex_count(const StrataSurface* surface);
size_t strata_surface_adaptive_triangle_count(const StrataSurface* surface);
/** 3 indices per adaptive triangle, into the adaptive frame's vertices. */
StrataStatus strata_surface_adaptive_triangles(const StrataSurface* surface, uint32_t* dst);
/** Per adaptive triangle, the level it is drawn at (its quarter's): one
 *  byte each, strata_surface_adaptive_triangle_count of them. */
StrataStatus strata_surface_adaptive_triangle_levels(const StrataSurface* surface, uint8_t* dst);
/** Per adaptive vertex, its refined vertex (an index into
 *  strata_surface_evaluate's vertices): to place UVs or colours. */
StrataStatus strata_surface_adaptive_vertices(const StrataSurface* surface, uint32_t* dst);
/** Positions (3 floats per adaptive vertex) and, unless NULL, shading
 *  normals of the adaptive frame in the current pose. */
StrataStatus strata_surface_evaluate_adaptive(StrataSurface* surface, float* positions, float* normals);
/** Changes whenever the adaptive frame's vertices and triangles do (a choice
 *  that keeps the levels drawn keeps it): what was laid out for the frame,
 *  an adaptive render mesh included, holds while it stays the same. */
uint32_t strata_surface_adaptive_version(const StrataSurface* surface);

/* ---- Render meshes: a surface laid out for drawing ----
 * One vertex per (refined vertex, refined corner value), so material UVs
 * and colours split where the glTF parts' do.  The first
 * strata_surface_vertex_count() vertices are the refined vertices in the
 * order strata_surface_evaluate writes them (and strata-reconstruct writes
 * .obj and .ply); copies at seams follow.  Each part (a glTF primitive) is
 * a contiguous range of the indices. */

typedef struct StrataRenderMesh StrataRenderMesh;
typedef struct StrataRenderPart {
    uint32_t first_index, index_count;
    int32_t mesh, primitive; /* glTF mesh and primitive; -1 when not from glTF */
    int32_t material;        /* glTF material; -1 for the default one */
} StrataRenderPart;

/** The layout of `surface`, a surface of `rig` (attributes come from the
 *  rig's glTF document; the handle keeps no pointer to either). */
StrataStatus strata_render_mesh_create(const StrataRig* rig, const StrataSurface* surface, StrataRenderMesh** out);
void strata_render_mesh_destroy(StrataRenderMesh* mesh);
size_t strata_render_mesh_vertex_count(const StrataRenderMesh* mesh);
size_t strata_render_mesh_index_count(const StrataRenderMesh* mesh);
/** Copies the triangles' indices (index_count values). */
StrataStatus strata_render_mesh_indices(const StrataRenderMesh* mesh, uint32_t* dst);
/** Copies each render vertex's refined vertex (vertex_count values). */
StrataStatus strata_render_mesh_refined_vertices(const StrataRenderMesh* mesh, uint32_t* dst);
size_t strata_render_mesh_part_count(const StrataRenderMesh* mesh);
StrataStatus strata_render_mesh_part(const StrataRenderMesh* mesh, size_t index, StrataRenderPart* out);
/** 1 when part `index` is drawn with face normals (flat shading): a glTF
 *  primitive without NORMAL, which glTF shades flat, in a plain file or in a
 *  rig baked from a capture drawn so; 0 when it is drawn with the surface's
 *  normals, or out of range. */
int strata_render_mesh_part_flat(const StrataRenderMesh* mesh, size_t index);
/** Refined per-corner attributes (TEXCOORD_n, COLOR_n, _CUSTOM). */
size_t strata_render_mesh_attribute_count(const StrataRenderMesh* mesh);
/** Name of attribute `index` (valid while the mesh lives), or NULL. */
const char* strata_render_mesh_attribute_name(const StrataRenderMesh* mesh, size_t index);
int strata_render_mesh_attribute_components(const StrataRenderMesh* mesh, size_t index);
/** Copies attribute `index`: components floats per render vertex. */
StrataStatus strata_render_mesh_attribute(const StrataRenderMesh* mesh, size_t index, float* dst);
/** The layout of `surface`'s current adaptive frame (after
 *  strata_surface_choose_levels), from `uniform`, the surface's own render
 *  mesh: the same parts (each a contiguous range of the indices) and
 *  attributes, each vertex with its grid point's value at the surface's
 *  level.  Its first vertices are the adaptive frame's, in its order; seam
 *  copies follow (strata_render_mesh_refined_vertices gives each one's
 *  adaptive vertex).  strata_render_mesh_evaluate fills it from the adaptive
 *  frame; it refuses once the frame's levels change (make another). */
StrataStatus strata_render_mesh_create_adaptive(const StrataRenderMesh* uniform, StrataSurface* surface,
                                                StrataRenderMesh** out);
/** strata_surface_evaluate (or, for an adaptive render mesh,
 *  strata_surface_evaluate_adaptive) into the render vertices: 3 floats each
 *  of positions and (unless NULL) normals per render vertex.  `surface` is
 *  the one the mesh was made for (its vertex count, or the adaptive frame's
 *  version, is checked). */
StrataStatus strata_render_mesh_evaluate(StrataRenderMesh* mesh, const StrataSurface* surface, float* positions,
                                         float* normals);

#ifdef __cplusplus
}
#endif

#endif /* STRATA_STRATA_H */
