// Stencil pass: control positions (and normals) -> refined surface point and
// displacement direction, one invocation per refined vertex.  The same
// entries in the same order as Plan::evaluate on the CPU.
layout(local_size_x = 128) in;

layout(std430, binding = 0) readonly buffer ControlPositions { float controlPositions[]; };
layout(std430, binding = 1) readonly buffer ControlNormals { float controlNormals[]; };
layout(std430, binding = 2) readonly buffer StencilOffsets { uint stencilOffsets[]; };
layout(std430, binding = 3) readonly buffer StencilIndices { uint stencilIndices[]; };
layout(std430, binding = 4) readonly buffer StencilWeights { float stencilWeights[]; };
layout(std430, binding = 5) writeonly buffer Surface { vec4 surface[]; };  // per vertex: point, direction
#ifdef STRATA_ADAPTIVE
// An adaptive frame (adaptive.h): invocation k evaluates the plan's refined
// vertex frameVertices[k] into slot k.
layout(std430, binding = 13) readonly buffer FrameVertices { uint frameVertices[]; };
#endif

uniform uint u_vertexCount;

vec3 controlPosition(uint i)
{
    return vec3(controlPositions[3u * i], controlPositions[3u * i + 1u], controlPositions[3u * i + 2u]);
}

void main()
{
    uint slot = gl_GlobalInvocationID.x;
    if (slot >= u_vertexCount)
        return;
#ifdef STRATA_ADAPTIVE
    uint v = frameVertices[slot];
#else
    uint v = slot;
#endif
    uint begin = stencilOffsets[v], end = stencilOffsets[v + 1u];
#ifdef STRATA_SMOOTH
    // Limit position and its two tangents; the direction is the unit normal.
    vec3 p = vec3(0.0), du = vec3(0.0), dv = vec3(0.0);
    for (uint k = begin; k < end; ++k) {
        vec3 c = controlPosition(stencilIndices[k]);
        p += stencilWeights[3u * k] * c;
        du += stencilWeights[3u * k + 1u] * c;
        dv += stencilWeights[3u * k + 2u] * c;
    }
    vec3 n = strata_limit_normal(du, dv);
#else
    // Paper eq. 2: barycentric blend of positions and of unit control normals.
    vec3 p = vec3(0.0), n = vec3(0.0);
    for (uint k = begin; k < end; ++k) {
        uint i = stencilIndices[k];
        float w = stencilWeights[k];
        p += w * controlPosition(i);
        n += w * vec3(controlNormals[3u * i], controlNormals[3u * i + 1u], controlNormals[3u * i + 2u]);
    }
#endif
    surface[2u * slot] = vec4(p, 1.0);
    surface[2u * slot + 1u] = vec4(n, 0.0);
}
