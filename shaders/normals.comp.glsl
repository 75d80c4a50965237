// Shading normals of the displaced mesh: each vertex sums the area normals
// of its faces, read as fans of its one-ring (strata::buildVertexFans, whose
// CPU mirror computeFanNormals does the same operations): a face (v, a, b)
// is the ring step a -> b with normal cross(a - p, b - p), and consecutive
// faces share a ring vertex, so an interior vertex of valence k reads k
// positions and k indices (the per-face corner pairs this replaced read 2k
// of each).
layout(local_size_x = 128) in;

layout(std430, binding = 6) readonly buffer Displaced { vec4 displaced[]; };
layout(std430, binding = 9) readonly buffer FanOffsets { uint fanOffsets[]; };
layout(std430, binding = 10) readonly buffer FanEntries { uint fanEntries[]; };
layout(std430, binding = 11) writeonly buffer Normals { vec4 normals[]; };

uniform uint u_vertexCount;

const uint kFanStart = 0x80000000u, kFanClose = 0x40000000u, kFanIndexMask = 0x3fffffffu;

void main()
{
    uint v = gl_GlobalInvocationID.x;
    if (v >= u_vertexCount)
        return;
    vec3 p = displaced[v].xyz;
    vec3 sum = vec3(0.0), first = vec3(0.0), prev = vec3(0.0);
    for (uint k = fanOffsets[v]; k < fanOffsets[v + 1u]; ++k) {
        uint e = fanEntries[k];
        vec3 q = displaced[e & kFanIndexMask].xyz - p;
        if ((e & kFanStart) != 0u)
            first = q;
        else
            sum += cross(prev, q);
        if ((e & kFanClose) != 0u)
            sum += cross(q, first);
        prev = q;
    }
    float len = length(sum);
    normals[v] = vec4(len > 0.0 ? sum / len : vec3(0.0), 0.0);
}
