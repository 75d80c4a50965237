// Displacement lookup shared by the vertex shader and the compute passes.
// Needs displacement_math.h (prepended when the program is built).
//
// u_filter 0: the CPU runtime's own formula (strata_bilinear_footprint over
// four texelFetch reads), so GPU and CPU agree to float round-off.
// u_filter 1: the texture unit's bilinear filter via textureLod (GL_LINEAR,
// level 0; no mipmaps: a displacement is a distance, and averaging it over a
// footprint would move the surface, not anti-alias it).  Faster on some
// hardware; its weights carry 8 fractional bits.

uniform sampler2D u_map;
uniform ivec2 u_mapSize;
uniform float u_factor;
uniform float u_offset;
uniform float u_scale;   // user scale; 0 disables displacement
uniform int u_filter;
uniform int u_perVertex;  // 1: the rig stores its displacements per refined vertex (already decoded)
layout(std430, binding = 15) readonly buffer VertexDisplacements { float vertexDisplacements[]; };

float strata_sample_displacement(vec2 uv)
{
    if (u_scale == 0.0)
        return 0.0;
    float t;
    if (u_filter == 1) {
        t = textureLod(u_map, uv, 0.0).r;
    } else {
        ivec2 t0;
        vec2 frac;
        strata_bilinear_footprint(uv, u_mapSize, t0, frac);
        ivec2 t1 = strata_far_texel(t0, u_mapSize);
        t = strata_bilinear(texelFetch(u_map, t0, 0).r, texelFetch(u_map, ivec2(t1.x, t0.y), 0).r,
                            texelFetch(u_map, ivec2(t0.x, t1.y), 0).r, texelFetch(u_map, t1, 0).r, frac);
    }
    return u_scale * strata_decode_distance(t, u_factor, u_offset);
}

// The displacement of refined vertex v: its own stored value (a rig with
// per-vertex displacements: the CPU's very numbers), else the map at uv.
float strata_vertex_displacement(uint v, vec2 uv)
{
    if (u_scale == 0.0)
        return 0.0;
    if (u_perVertex != 0)
        return u_scale * vertexDisplacements[v];
    return strata_sample_displacement(uv);
}
