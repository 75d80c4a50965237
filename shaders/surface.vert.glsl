// Draw pass: the displacement is sampled here, per refined vertex, at its
// canonical UV, and applied along the stencil pass's direction (paper eq. 2),
// exactly as the CPU runtime does.  Also used alone, with transform feedback,
// to read the displaced positions back.
layout(std430, binding = 5) readonly buffer Surface { vec4 surface[]; };
layout(std430, binding = 11) readonly buffer Normals { vec4 normals[]; };
// Corner mode (materials): gl_VertexID is a refined face corner.
layout(std430, binding = 7) readonly buffer SampleUVs { vec2 sampleUVs[]; };
layout(std430, binding = 8) readonly buffer Triangles { uint triangles[]; };
layout(std430, binding = 12) readonly buffer Errors { float errors[]; };
layout(std430, binding = 14) readonly buffer CornerUVs { vec2 cornerUVs[]; };
// Corner mode with u_hasColours: each corner's COLOR_0 (linear RGBA).
layout(std430, binding = 15) readonly buffer CornerColours { vec4 cornerColours[]; };
// Corner mode with u_hasSecondUVs: each corner's second UV channel (the
// textures of a material on another set or transform).
layout(std430, binding = 16) readonly buffer CornerUVs2 { vec2 cornerUVs2[]; };
uniform int u_corners;
uniform int u_hasColours;
uniform int u_hasSecondUVs;
#ifdef STRATA_ADAPTIVE_DRAW
// An adaptive frame (adaptive.h): gl_VertexID is a frame vertex, already
// displaced by the evaluator; frameVertices gives its refined vertex.
layout(std430, binding = 6) readonly buffer Displaced { vec4 displaced[]; };
layout(std430, binding = 13) readonly buffer FrameVertices { uint frameVertices[]; };
#endif

layout(location = 0) in vec2 a_uv;
layout(location = 1) in float a_error;

uniform mat4 u_viewProjection;
uniform int u_haveNormals;

out vec3 v_position;
out vec3 v_normal;
out float v_displacement;
out float v_error;
out vec2 v_materialUV;
out vec2 v_secondUV;
out vec4 v_vertexColour;

void main()
{
#ifdef STRATA_ADAPTIVE_DRAW
    // Corner mode (materials): gl_VertexID is a corner of the frame's
    // triangles, with its own material UV.
    uint slot = u_corners != 0 ? triangles[gl_VertexID] : uint(gl_VertexID), refined = frameVertices[slot];
    v_position = displaced[slot].xyz;
    v_normal = normals[slot].xyz;
    v_displacement = strata_vertex_displacement(refined, sampleUVs[refined]);
    v_error = 0.0;  // the fragment shader reads its triangle's level
    v_materialUV = u_corners != 0 ? cornerUVs[gl_VertexID] : vec2(0.0);
    v_secondUV = u_corners != 0 && u_hasSecondUVs != 0 ? cornerUVs2[gl_VertexID] : v_materialUV;
    v_vertexColour = u_corners != 0 && u_hasColours != 0 ? cornerColours[gl_VertexID] : vec4(1.0);
    gl_Position = u_viewProjection * vec4(v_position, 1.0);
    return;
#endif
    uint v = uint(gl_VertexID);
    vec2 uv = a_uv;
    float error = a_error;
    v_materialUV = vec2(0.0);
    v_secondUV = vec2(0.0);
    v_vertexColour = vec4(1.0);
    if (u_corners != 0) {
        v = triangles[gl_VertexID];
        uv = sampleUVs[v];
        error = errors[v];
        v_materialUV = cornerUVs[gl_VertexID];
        v_secondUV = u_hasSecondUVs != 0 ? cornerUVs2[gl_VertexID] : v_materialUV;
        if (u_hasColours != 0)
            v_vertexColour = cornerColours[gl_VertexID];
    }
    vec3 p = surface[2u * v].xyz;
    vec3 n = surface[2u * v + 1u].xyz;
    float d = strata_vertex_displacement(v, uv);
    v_position = strata_displace(p, n, d);
    v_normal = u_haveNormals != 0 ? normals[v].xyz : normalize(n);
    v_displacement = d;
    v_error = error;
    gl_Position = u_viewProjection * vec4(v_position, 1.0);
}
