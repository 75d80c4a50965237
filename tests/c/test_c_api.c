/* The C API from a C99 program.  With a rig and the C++ path's numbers
 * (written by CApi.MatchesTheCppPathBitForBit), checks them bit for bit;
 * alone, checks what needs no file: a closed-form surface from arrays and
 * the error path.  Exit 0 when everything holds. */
#include "strata/strata.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;
#define CHECK(cond)                                                          \
    do {                                                                     \
        if (!(cond)) {                                                       \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
            ++failures;                                                      \
        }                                                                    \
    } while (0)

/* A unit square displaced by a constant map: every refined vertex moves by
 * exactly 0.25 along +z (the square's normal), whatever the level. */
static void closedForm(void)
{
    const float positions[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t triangles[] = {0, 1, 2, 0, 2, 3};
    const float uvs[] = {0, 0, 1, 0, 1, 1, 0, 1};
    const float texels[] = {0.5f, 0.5f, 0.5f, 0.5f};
    StrataSurface* s = NULL;
    CHECK(strata_surface_create_from_arrays(positions, 4, triangles, 2, uvs, 4, triangles, texels, 2, 2, 0.5f, 0.0f,
                                            STRATA_SCHEME_LINEAR, 3, &s) == STRATA_OK);
    if (!s)
        return;
    const size_t n = strata_surface_vertex_count(s);
    CHECK(strata_surface_triangle_count(s) == 2 * 64);
    float* p = (float*)malloc(n * 3 * sizeof(float));
    float* nrm = (float*)malloc(n * 3 * sizeof(float));
    uint32_t* t = (uint32_t*)malloc(strata_surface_triangle_count(s) * 3 * sizeof(uint32_t));
    CHECK(strata_surface_evaluate(s, p, nrm) == STRATA_OK);
    CHECK(strata_surface_triangles(s, t) == STRATA_OK);
    for (size_t i = 0; i < n; ++i) {
        CHECK(fabsf(p[3 * i + 2] - 0.25f) < 1e-6f);
        CHECK(p[3 * i] >= -1e-6f && p[3 * i] <= 1.0f + 1e-6f);
        CHECK(fabsf(nrm[3 * i + 2] - 1.0f) < 1e-5f);
    }
    for (size_t i = 0; i < 3 * strata_surface_triangle_count(s); ++i)
        CHECK(t[i] < n);
    /* Adaptive: a flat plane displaced by a constant is flat at every level,
     * so any view draws it at level 0: its 4 corners, 2 triangles, z = 0.25. */
    {
        const float eye[3] = {0.5f, 0.5f, 3.0f}, target[3] = {0.5f, 0.5f, 0.0f};
        CHECK(strata_surface_adaptive_vertex_count(s) == 0);
        CHECK(strata_surface_choose_levels(s, eye, target, 45.0f, 1080.0f, 1.0f) == STRATA_OK);
        CHECK(strata_surface_adaptive_vertex_count(s) == 4);
        CHECK(strata_surface_adaptive_triangle_count(s) == 2);
        float ap[12], an[12];
        uint32_t at[6], av[4];
        CHECK(strata_surface_evaluate_adaptive(s, ap, an) == STRATA_OK);
        CHECK(strata_surface_adaptive_triangles(s, at) == STRATA_OK);
        CHECK(strata_surface_adaptive_vertices(s, av) == STRATA_OK);
        for (int i = 0; i < 4; ++i) {
            CHECK(fabsf(ap[3 * i + 2] - 0.25f) < 1e-6f);
            CHECK(fabsf(an[3 * i + 2] - 1.0f) < 1e-5f);
            CHECK(av[i] < n);
            CHECK(fabsf(ap[3 * i] - p[3 * av[i]]) < 1e-6f && fabsf(ap[3 * i + 1] - p[3 * av[i] + 1]) < 1e-6f);
        }
        for (int i = 0; i < 6; ++i)
            CHECK(at[i] < 4);
        uint8_t levels[2] = {9, 9};
        CHECK(strata_surface_adaptive_triangle_levels(s, levels) == STRATA_OK);
        CHECK(levels[0] == 0 && levels[1] == 0);
        CHECK(strata_surface_adaptive_triangle_levels(s, NULL) == STRATA_INVALID_ARGUMENT);
        /* A camera on its target is refused with a message. */
        CHECK(strata_surface_choose_levels(s, eye, eye, 45.0f, 1080.0f, 1.0f) == STRATA_INVALID_ARGUMENT);
        CHECK(strstr(strata_last_error(), "not a view") != NULL);
    }
    /* The engine deforms the control mesh itself: lifted by 1, the surface follows. */
    const float lifted[] = {0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    CHECK(strata_surface_set_control_positions(s, lifted, 4) == STRATA_OK);
    CHECK(strata_surface_evaluate(s, p, NULL) == STRATA_OK);
    CHECK(fabsf(p[2] - 1.25f) < 1e-6f);
    /* Wrong counts are refused with a message. */
    CHECK(strata_surface_set_control_positions(s, lifted, 3) == STRATA_INVALID_ARGUMENT);
    CHECK(strstr(strata_last_error(), "3 control positions") != NULL);
    /* A pose that is not finite is refused, naming the vertex; the last pose stays. */
    float broken[12];
    memcpy(broken, lifted, sizeof(broken));
    broken[7] = NAN;
    CHECK(strata_surface_set_control_positions(s, broken, 4) == STRATA_INVALID_ARGUMENT);
    CHECK(strstr(strata_last_error(), "control vertex 2") != NULL);
    CHECK(strata_surface_evaluate(s, p, NULL) == STRATA_OK);
    CHECK(fabsf(p[2] - 1.25f) < 1e-6f);
    CHECK(strata_surface_set_animation_time(s, 0, 0.0f) == STRATA_INVALID_ARGUMENT);
    free(p);
    free(nrm);
    free(t);
    strata_surface_destroy(s);
}

static void errors(void)
{
    StrataRig* rig = (StrataRig*)1;
    CHECK(strata_rig_load("no/such/rig.glb", &rig) != STRATA_OK);
    CHECK(rig == NULL);
    CHECK(strstr(strata_last_error(), "no/such/rig.glb") != NULL);
    CHECK(strata_rig_load_memory("not a glb", 9, 1, &rig) == STRATA_INVALID_DATA);
    CHECK(strata_surface_create(NULL, 0, NULL) == STRATA_INVALID_ARGUMENT);
    CHECK(strlen(strata_version()) >= 5);
}

/* Compares n floats from the C API with the next n of the expected file, bit for bit. */
static int sameBits(const float* got, FILE* expected, size_t n)
{
    float* want = (float*)malloc(n * sizeof(float));
    const int ok = fread(want, sizeof(float), n, expected) == n && memcmp(got, want, n * sizeof(float)) == 0;
    free(want);
    return ok;
}

/* The adaptive layout of a view: the adaptive frame's vertices first, every
 * vertex where its adaptive vertex is; refused once the levels change. */
static void adaptiveRenderMesh(const StrataRenderMesh* uniform, StrataSurface* s, const float* posed, uint32_t count)
{
    float lo[3] = {posed[0], posed[1], posed[2]}, hi[3] = {posed[0], posed[1], posed[2]};
    for (uint32_t i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k) {
            lo[k] = fminf(lo[k], posed[3 * i + k]);
            hi[k] = fmaxf(hi[k], posed[3 * i + k]);
        }
    /* The surface's own box holds the pose's every vertex. */
    float box[6];
    CHECK(strata_surface_bounds(s, box, box + 3) == STRATA_OK);
    for (int k = 0; k < 3; ++k)
        CHECK(box[k] <= lo[k] && hi[k] <= box[3 + k]);
    CHECK(strata_surface_bounds(s, NULL, box) == STRATA_INVALID_ARGUMENT);
    const float size = fmaxf(hi[0] - lo[0], fmaxf(hi[1] - lo[1], hi[2] - lo[2]));
    const float target[3] = {0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), 0.5f * (lo[2] + hi[2])};
    const float far[3] = {target[0], target[1], target[2] + 8.0f * size};
    CHECK(strata_surface_choose_levels(s, far, target, 40.0f, 1080.0f, 1.0f) == STRATA_OK);
    const uint32_t version = strata_surface_adaptive_version(s);
    const size_t frame = strata_surface_adaptive_vertex_count(s);
    StrataRenderMesh* a = NULL;
    CHECK(strata_render_mesh_create_adaptive(uniform, s, &a) == STRATA_OK);
    if (!a)
        return;
    StrataRenderMesh* none = NULL;
    CHECK(strata_render_mesh_create_adaptive(a, s, &none) == STRATA_INVALID_ARGUMENT && none == NULL);
    const size_t n = strata_render_mesh_vertex_count(a);
    CHECK(n >= frame && frame > 0);
    CHECK(strata_render_mesh_index_count(a) == 3 * strata_surface_adaptive_triangle_count(s));
    CHECK(strata_render_mesh_attribute_count(a) == strata_render_mesh_attribute_count(uniform));
    CHECK(strata_render_mesh_part_count(a) == strata_render_mesh_part_count(uniform));
    uint32_t* of = (uint32_t*)malloc(n * sizeof(uint32_t));
    float* xyz = (float*)malloc(n * 3 * sizeof(float));
    float* own = (float*)malloc(frame * 3 * sizeof(float));
    CHECK(strata_render_mesh_refined_vertices(a, of) == STRATA_OK);
    CHECK(strata_render_mesh_evaluate(a, s, xyz, NULL) == STRATA_OK);
    CHECK(strata_surface_evaluate_adaptive(s, own, NULL) == STRATA_OK);
    for (size_t i = 0; i < n; ++i) {
        CHECK(of[i] < frame && (i >= frame || of[i] == i));
        CHECK(memcmp(xyz + 3 * i, own + 3 * (size_t)of[i], 3 * sizeof(float)) == 0);
    }
    /* Closer, at a tenth of the tolerance: other levels, and the old layout is refused. */
    const float near[3] = {target[0], target[1], target[2] + 1.5f * size};
    CHECK(strata_surface_choose_levels(s, near, target, 40.0f, 1080.0f, 0.1f) == STRATA_OK);
    CHECK(strata_surface_adaptive_version(s) != version);
    CHECK(strata_render_mesh_evaluate(a, s, xyz, NULL) == STRATA_INVALID_ARGUMENT);
    CHECK(strstr(strata_last_error(), "levels changed") != NULL);
    free(of);
    free(xyz);
    free(own);
    strata_render_mesh_destroy(a);
}

/* The render mesh of a posed surface: the refined vertices first, in
 * strata_surface_evaluate's order; every vertex placed where its refined
 * vertex is; the parts cover the indices; joints name their nodes. */
static void renderMesh(const StrataRig* rig, StrataSurface* s, const float* posed, uint32_t count)
{
    StrataRenderMesh* m = NULL;
    CHECK(strata_render_mesh_create(rig, s, &m) == STRATA_OK);
    if (!m)
        return;
    const size_t n = strata_render_mesh_vertex_count(m), indices = strata_render_mesh_index_count(m);
    CHECK(n >= count);
    CHECK(indices == 3 * strata_surface_triangle_count(s));
    uint32_t* refined = (uint32_t*)malloc(n * sizeof(uint32_t));
    uint32_t* idx = (uint32_t*)malloc(indices * sizeof(uint32_t));
    float* xyz = (float*)malloc(n * 3 * sizeof(float));
    CHECK(strata_render_mesh_refined_vertices(m, refined) == STRATA_OK);
    CHECK(strata_render_mesh_indices(m, idx) == STRATA_OK);
    CHECK(strata_render_mesh_evaluate(m, s, xyz, NULL) == STRATA_OK);
    for (size_t i = 0; i < n; ++i) {
        CHECK(refined[i] < count);
        if (i < count)
            CHECK(refined[i] == i);
        CHECK(memcmp(xyz + 3 * i, posed + 3 * (size_t)refined[i], 3 * sizeof(float)) == 0);
    }
    for (size_t i = 0; i < indices; ++i)
        CHECK(idx[i] < n);
    size_t covered = 0;
    for (size_t k = 0; k < strata_render_mesh_part_count(m); ++k) {
        StrataRenderPart part;
        CHECK(strata_render_mesh_part(m, k, &part) == STRATA_OK);
        CHECK(part.first_index == covered);
        covered += part.index_count;
        CHECK(part.mesh >= 0 && part.primitive >= 0);
        /* A control mesh has no NORMAL, but this rig's layer does not say
         * its capture was drawn flat: the surface is drawn smooth. */
        CHECK(strata_render_mesh_part_flat(m, k) == 0);
    }
    CHECK(covered == indices);
    StrataRenderPart none;
    CHECK(strata_render_mesh_part(m, 99, &none) == STRATA_INVALID_ARGUMENT);
    CHECK(strata_render_mesh_part_flat(m, 99) == 0);
    CHECK(strata_render_mesh_part_flat(NULL, 0) == 0);
    float* d = (float*)malloc(count * sizeof(float));
    CHECK(strata_surface_displacements(s, d) == STRATA_OK);
    for (uint32_t i = 0; i < count; ++i)
        CHECK(isfinite(d[i]));
    float ibm[16];
    for (size_t j = 0; j < strata_rig_joint_count(rig); ++j) {
        CHECK(strata_rig_joint_node(rig, j) >= 0);
        CHECK(strata_rig_joint_inverse_bind(rig, j, ibm) == STRATA_OK);
        CHECK(isfinite(ibm[0]) && ibm[15] != 0.0f);
    }
    CHECK(strata_rig_joint_node(rig, 99) == -1);
    CHECK(strata_rig_joint_inverse_bind(rig, 99, ibm) == STRATA_INVALID_ARGUMENT);
    adaptiveRenderMesh(m, s, posed, count);
    free(d);
    free(refined);
    free(idx);
    free(xyz);
    strata_render_mesh_destroy(m);
}

static void againstCpp(const char* rigPath, const char* expectedPath)
{
    FILE* expected = fopen(expectedPath, "rb");
    CHECK(expected != NULL);
    if (!expected)
        return;
    uint32_t level = 0, count = 0;
    CHECK(fread(&level, 4, 1, expected) == 1 && fread(&count, 4, 1, expected) == 1);
    /* From the file, and from its bytes. */
    StrataRig* rig = NULL;
    CHECK(strata_rig_load(rigPath, &rig) == STRATA_OK);
    if (!rig) {
        fprintf(stderr, "%s\n", strata_last_error());
        fclose(expected);
        return;
    }
    CHECK(strata_rig_joint_count(rig) == 2);
    CHECK(strata_rig_animation_count(rig) == 1);
    StrataSurface* s = NULL;
    CHECK(strata_surface_create(rig, (int)level, &s) == STRATA_OK);
    CHECK(s && strata_surface_vertex_count(s) == count);
    if (s) {
        float* p = (float*)malloc(count * 3 * sizeof(float));
        float* nrm = (float*)malloc(count * 3 * sizeof(float));
        float* bind = (float*)malloc(count * 3 * sizeof(float));
        CHECK(strata_surface_evaluate(s, p, nrm) == STRATA_OK); /* bind pose */
        memcpy(bind, p, count * 3 * sizeof(float));
        CHECK(sameBits(p, expected, 3 * count));
        CHECK(sameBits(nrm, expected, 3 * count));
        CHECK(strata_surface_set_animation_time(s, 0, 0.5f) == STRATA_OK); /* posed */
        CHECK(strata_surface_evaluate(s, p, nrm) == STRATA_OK);
        CHECK(sameBits(p, expected, 3 * count));
        CHECK(sameBits(nrm, expected, 3 * count));
        renderMesh(rig, s, p, count);
        CHECK(strata_surface_set_bind_pose(s) == STRATA_OK); /* back to the bind pose, bit for bit */
        CHECK(strata_surface_evaluate(s, p, NULL) == STRATA_OK);
        CHECK(memcmp(p, bind, count * 3 * sizeof(float)) == 0);
        free(bind);
        free(p);
        free(nrm);
        strata_surface_destroy(s);
    }
    FILE* f = fopen(rigPath, "rb");
    if (f) {
        fseek(f, 0, SEEK_END);
        const long size = ftell(f);
        fseek(f, 0, SEEK_SET);
        char* bytes = (char*)malloc((size_t)size);
        CHECK(fread(bytes, 1, (size_t)size, f) == (size_t)size);
        StrataRig* fromBytes = NULL;
        CHECK(strata_rig_load_memory(bytes, (size_t)size, 1, &fromBytes) == STRATA_OK);
        CHECK(strata_rig_control_vertex_count(fromBytes) == strata_rig_control_vertex_count(rig));
        strata_rig_destroy(fromBytes);
        free(bytes);
        fclose(f);
    }
    strata_rig_destroy(rig);
    fclose(expected);
}

int main(int argc, char** argv)
{
    closedForm();
    errors();
    if (argc == 3)
        againstCpp(argv[1], argv[2]);
    if (failures)
        fprintf(stderr, "%d checks failed\n", failures);
    return failures ? 1 : 0;
}
