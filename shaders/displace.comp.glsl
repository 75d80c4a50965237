// Displaced positions for the shading-normal pass: the vertex shader's own
// displacement (same function, same inputs), written once per vertex.
layout(local_size_x = 128) in;

layout(std430, binding = 5) readonly buffer Surface { vec4 surface[]; };
layout(std430, binding = 6) writeonly buffer Displaced { vec4 displaced[]; };
layout(std430, binding = 7) readonly buffer SampleUVs { vec2 sampleUVs[]; };

uniform uint u_vertexCount;

void main()
{
    uint v = gl_GlobalInvocationID.x;
    if (v >= u_vertexCount)
        return;
    float d = strata_vertex_displacement(v, sampleUVs[v]);
    displaced[v] = vec4(strata_displace(surface[2u * v].xyz, surface[2u * v + 1u].xyz, d), 1.0);
}
