/* A complete engine-side program over Strata's C API (C99): load a rig,
 * make its surface at the recommended level, pose it, evaluate a frame into
 * the program's own buffers and write it as OBJ.
 *
 *   strata-example-engine-c RIG.glb OUT.obj [ANIMATION TIME]
 *
 * Built and run by the tests, which compare OUT.obj's vertices with
 * strata-reconstruct's (the same surface, bit for bit).  Link Strata::c
 * (the shared C library: libstrata_c.so). */
#include <strata/strata.h>

#include <stdio.h>
#include <stdlib.h>

static int fail(const char* what)
{
    fprintf(stderr, "error: %s: %s\n", what, strata_last_error());
    return 1;
}

int main(int argc, char** argv)
{
    StrataRig* rig = NULL;
    StrataSurface* surface = NULL;
    float *xyz = NULL, *normals = NULL;
    uint32_t* triangles = NULL;
    size_t n, m, i;
    FILE* out;
    int rc = 1;
    if (argc != 3 && argc != 5) {
        fprintf(stderr, "usage: %s RIG.glb OUT.obj [ANIMATION TIME]\n", argv[0]);
        return 2;
    }
    if (strata_rig_load(argv[1], &rig) != STRATA_OK)
        return fail(argv[1]);
    /* -1: the rig's recommended level, in the scheme it was baked in. */
    if (strata_surface_create(rig, -1, &surface) != STRATA_OK) {
        rc = fail("strata_surface_create");
        goto done;
    }
    if (argc == 5 && strata_surface_set_animation_time(surface, atoi(argv[3]), (float)atof(argv[4])) != STRATA_OK) {
        rc = fail("strata_surface_set_animation_time");
        goto done;
    }
    n = strata_surface_vertex_count(surface);
    m = strata_surface_triangle_count(surface);
    xyz = malloc(n * 3 * sizeof(float));
    normals = malloc(n * 3 * sizeof(float));
    triangles = malloc(m * 3 * sizeof(uint32_t));
    if (!xyz || !normals || !triangles) {
        fprintf(stderr, "error: out of memory\n");
        goto done;
    }
    if (strata_surface_evaluate(surface, xyz, normals) != STRATA_OK ||
        strata_surface_triangles(surface, triangles) != STRATA_OK) {
        rc = fail("strata_surface_evaluate");
        goto done;
    }
    out = fopen(argv[2], "w");
    if (!out) {
        fprintf(stderr, "error: cannot write %s\n", argv[2]);
        goto done;
    }
    for (i = 0; i < n; ++i)
        fprintf(out, "v %.9g %.9g %.9g\n", (double)xyz[3 * i], (double)xyz[3 * i + 1], (double)xyz[3 * i + 2]);
    for (i = 0; i < n; ++i)
        fprintf(out, "vn %.9g %.9g %.9g\n", (double)normals[3 * i], (double)normals[3 * i + 1],
                (double)normals[3 * i + 2]);
    for (i = 0; i < m; ++i)
        fprintf(out, "f %u//%u %u//%u %u//%u\n", triangles[3 * i] + 1, triangles[3 * i] + 1, triangles[3 * i + 1] + 1,
                triangles[3 * i + 1] + 1, triangles[3 * i + 2] + 1, triangles[3 * i + 2] + 1);
    rc = fclose(out) == 0 ? 0 : 1;
    fprintf(stderr, "level %d, %zu vertices, %zu triangles -> %s\n", strata_rig_recommended_level(rig), n, m, argv[2]);
done:
    free(xyz);
    free(normals);
    free(triangles);
    strata_surface_destroy(surface);
    strata_rig_destroy(rig);
    return rc;
}
