// Shading normals of the displaced mesh: each vertex gathers the area-
// weighted normals of its triangles (in face order, like the CPU runtime's
// Plan::computeShadingNormals), so level 3 and up shade smoothly.
layout(local_size_x = 128) in;

layout(std430, binding = 6) readonly buffer Displaced { vec4 displaced[]; };
layout(std430, binding = 8) readonly buffer Triangles { uint triangles[]; };
layout(std430, binding = 9) readonly buffer AdjacencyOffsets { uint adjacencyOffsets[]; };
layout(std430, binding = 10) readonly buffer AdjacentFaces { uint adjacentFaces[]; };
layout(std430, binding = 11) writeonly buffer Normals { vec4 normals[]; };

uniform uint u_vertexCount;

void main()
{
    uint v = gl_GlobalInvocationID.x;
    if (v >= u_vertexCount)
        return;
    vec3 sum = vec3(0.0);
    for (uint k = adjacencyOffsets[v]; k < adjacencyOffsets[v + 1u]; ++k) {
        uint f = adjacentFaces[k];
        vec3 a = displaced[triangles[3u * f]].xyz;
        vec3 b = displaced[triangles[3u * f + 1u]].xyz;
        vec3 c = displaced[triangles[3u * f + 2u]].xyz;
        sum += cross(b - a, c - a);
    }
    float len = length(sum);
    normals[v] = vec4(len > 0.0 ? sum / len : vec3(0.0), 0.0);
}
