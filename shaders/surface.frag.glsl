// Shading: a key light, a fill light and a sky/ground hemisphere, enough to
// show displaced detail; or false colour of the displacement or of a
// per-vertex error.
in vec3 v_position;
in vec3 v_normal;
in float v_displacement;
in float v_error;
in vec2 v_materialUV;
in vec2 v_emissiveUV;  // the base colour's UVs, or a second set's
in vec4 v_vertexColour;

uniform int u_colorMode;       // 0 shaded, 1 displacement, 2 error, 3 flat (wireframe)
uniform int u_flatShading;     // 1: lit by the triangle's own plane (a glTF primitive without normals)
uniform vec2 u_colorRange;     // value range mapped onto the colour ramp
uniform vec3 u_eye;
uniform vec3 u_baseColor;
// The primitive's material (shaded view): glTF's base colour, its factor
// times its texture (sRGB-coded, read linear) times COLOR_0, shown
// sRGB-coded; alpha mode OPAQUE (0), MASK (1) or BLEND (2).
uniform int u_material;
uniform vec4 u_materialColor;
uniform int u_hasTexture;
uniform sampler2D u_baseColorTexture;
uniform int u_alphaMode;
uniform float u_alphaCutoff;
// Its emissive colour (linear) times its emissive texture, added lit or not.
uniform vec3 u_emissive;
uniform int u_hasEmissiveTexture;
uniform sampler2D u_emissiveTexture;

out vec4 o_color;

#ifdef STRATA_ADAPTIVE_DRAW
// Each adaptive triangle's control face level, the "error" colour mode's value.
layout(std430, binding = 12) readonly buffer TriangleLevels { float triangleLevels[]; };
#endif

vec3 srgbEncode(vec3 c)
{
    c = clamp(c, 0.0, 1.0);
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

vec3 ramp(float t)
{
    // Blue -> cyan -> green -> yellow -> red, as the paper's Fig. 6 maps.
    t = clamp(t, 0.0, 1.0);
    return clamp(vec3(1.5 - abs(4.0 * t - 3.0), 1.5 - abs(4.0 * t - 2.0), 1.5 - abs(4.0 * t - 1.0)), 0.0, 1.0);
}

void main()
{
    if (u_colorMode == 3) {
        o_color = vec4(u_baseColor, 1.0);
        return;
    }
    vec3 n = u_flatShading != 0 ? normalize(cross(dFdx(v_position), dFdy(v_position))) : normalize(v_normal);
    vec3 view = normalize(u_eye - v_position);
    if (dot(n, view) < 0.0)
        n = -n;  // back faces of open meshes
    vec3 base = u_baseColor, emitted = vec3(0.0);
    float alpha = 1.0;
    if (u_colorMode == 0 && u_material != 0) {
        vec4 c = u_materialColor * v_vertexColour;
        if (u_hasTexture != 0)
            c *= texture(u_baseColorTexture, v_materialUV);
        if (u_alphaMode == 1 && c.a < u_alphaCutoff)
            discard;
        base = srgbEncode(c.rgb);
        alpha = u_alphaMode == 2 ? c.a : 1.0;
        emitted = u_emissive;
        if (u_hasEmissiveTexture != 0)
            emitted *= texture(u_emissiveTexture, v_emissiveUV).rgb;
        emitted = srgbEncode(emitted);
    }
    if (u_colorMode == 1)
        base = ramp((v_displacement - u_colorRange.x) / max(u_colorRange.y - u_colorRange.x, 1e-12));
    else if (u_colorMode == 2) {
#ifdef STRATA_ADAPTIVE_DRAW
        float value = triangleLevels[gl_PrimitiveID];
#else
        float value = v_error;
#endif
        base = ramp((value - u_colorRange.x) / max(u_colorRange.y - u_colorRange.x, 1e-12));
    }
    vec3 key = normalize(vec3(0.5, 0.8, 0.6));
    vec3 fill = normalize(vec3(-0.6, 0.2, -0.4));
    float diffuse = max(dot(n, key), 0.0) * 0.75 + max(dot(n, fill), 0.0) * 0.2;
    float hemi = 0.5 + 0.5 * n.y;
    vec3 ambient = mix(vec3(0.18, 0.16, 0.14), vec3(0.32, 0.36, 0.42), hemi);
    float specular = pow(max(dot(reflect(-key, n), view), 0.0), 40.0) * 0.25;
    o_color = vec4(min(base * (ambient + diffuse) + vec3(specular) + emitted, vec3(1.0)), alpha);
}
