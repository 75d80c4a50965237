// Shading normals of the displaced mesh: each vertex gathers the area-
// weighted normals of its triangles (in face order, like the CPU runtime's
// Plan::computeShadingNormals), so level 3 and up shade smoothly.  Each
// incident face comes as its other two corners, counter-clockwise from the
// vertex: cross(b - p, c - p) is the face's doubled area normal, read from
// two positions.
layout(local_size_x = 128) in;

layout(std430, binding = 6) readonly buffer Displaced { vec4 displaced[]; };
layout(std430, binding = 9) readonly buffer AdjacencyOffsets { uint adjacencyOffsets[]; };
layout(std430, binding = 10) readonly buffer AdjacentEdges { uvec2 adjacentEdges[]; };
layout(std430, binding = 11) writeonly buffer Normals { vec4 normals[]; };

uniform uint u_vertexCount;

void main()
{
    uint v = gl_GlobalInvocationID.x;
    if (v >= u_vertexCount)
        return;
    vec3 p = displaced[v].xyz;
    vec3 sum = vec3(0.0);
    for (uint k = adjacencyOffsets[v]; k < adjacencyOffsets[v + 1u]; ++k) {
        uvec2 e = adjacentEdges[k];
        sum += cross(displaced[e.x].xyz - p, displaced[e.y].xyz - p);
    }
    float len = length(sum);
    normals[v] = vec4(len > 0.0 ? sum / len : vec3(0.0), 0.0);
}
