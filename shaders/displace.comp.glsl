// Displaced positions for the shading-normal pass: the vertex shader's own
// displacement (same function, same inputs), written once per vertex.
layout(local_size_x = 128) in;

layout(std430, binding = 5) readonly buffer Surface { vec4 surface[]; };
layout(std430, binding = 6) writeonly buffer Displaced { vec4 displaced[]; };
layout(std430, binding = 7) readonly buffer SampleUVs { vec2 sampleUVs[]; };

#ifdef STRATA_ADAPTIVE
layout(std430, binding = 13) readonly buffer FrameVertices { uint frameVertices[]; };
#endif

uniform uint u_vertexCount;

void main()
{
    uint slot = gl_GlobalInvocationID.x;
    if (slot >= u_vertexCount)
        return;
#ifdef STRATA_ADAPTIVE
    uint v = frameVertices[slot];  // the plan's refined vertex: its UV and displacement
#else
    uint v = slot;
#endif
    float d = strata_vertex_displacement(v, sampleUVs[v]);
    displaced[slot] = vec4(strata_displace(surface[2u * slot].xyz, surface[2u * slot + 1u].xyz, d), 1.0);
}
