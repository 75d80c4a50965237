// Shading: a key light, a fill light and a sky/ground hemisphere, enough to
// show displaced detail; or false colour of the displacement or of a
// per-vertex error.  A glTF material is lit by the same lights through
// glTF's metallic-roughness model (its specification's appendix B: GGX
// distribution, Smith visibility, Schlick Fresnel; Lambert diffuse), in
// linear light, the sky and ground as image-based light through an
// analytic split-sum fit, shown sRGB-coded.
in vec3 v_position;
in vec3 v_normal;
in float v_displacement;
in float v_error;
in vec2 v_materialUV;
in vec2 v_secondUV;  // the second UV channel's (the base colour's where there is none)
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
uniform int u_emissiveSecond;  // read through the second UV channel
uniform sampler2D u_emissiveTexture;
// Its metallic and roughness factors times its metallic-roughness texture
// (B and G, linear), and its occlusion texture (R, mixed in by strength).
uniform float u_metallic;
uniform float u_roughness;
uniform int u_hasMetallicRoughnessTexture;
uniform int u_metallicRoughnessSecond;
uniform sampler2D u_metallicRoughnessTexture;
uniform int u_hasOcclusionTexture;
uniform int u_occlusionSecond;
uniform float u_occlusionStrength;
uniform sampler2D u_occlusionTexture;
// Its tangent-space normal texture (glTF's: X along +u, Y along -v).
uniform int u_hasNormalTexture;
uniform int u_normalSecond;
uniform float u_normalScale;
uniform sampler2D u_normalTexture;

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

const float kPi = 3.14159265;
const vec3 kKey = vec3(0.5, 0.8, 0.6), kFill = vec3(-0.6, 0.2, -0.4);
const vec3 kSky = vec3(0.25, 0.28, 0.33), kGround = vec3(0.08, 0.07, 0.06);  // linear irradiance

// Light of radiance `radiance` from direction l off the material at normal
// n, seen from `view` (glTF's BRDF: Lambert plus GGX with Smith and Schlick).
vec3 directLight(vec3 l, vec3 radiance, vec3 n, vec3 view, vec3 diffuse, vec3 f0, float roughness)
{
    float nl = dot(n, l);
    if (nl <= 0.0)
        return vec3(0.0);
    vec3 h = normalize(l + view);
    float nv = max(dot(n, view), 1e-4), nh = max(dot(n, h), 0.0), vh = max(dot(view, h), 0.0);
    float a = roughness * roughness, a2 = a * a;
    float d = a2 / (kPi * pow(nh * nh * (a2 - 1.0) + 1.0, 2.0));
    float vis = 0.5 / (nl * sqrt(nv * nv * (1.0 - a2) + a2) + nv * sqrt(nl * nl * (1.0 - a2) + a2));
    vec3 f = f0 + (1.0 - f0) * pow(1.0 - vh, 5.0);
    return ((1.0 - f) * diffuse / kPi + f * d * vis) * radiance * nl;
}

// The normal n turned by the normal texture at `uv`, in the frame a glTF
// viewer derives per pixel for a mesh without TANGENT (three.js's, after
// Schueler): X and Y the gradients of u and -v across n, both over the
// longer, Z n.  The baker's transferNormals writes in this frame.
vec3 perturbNormal(vec3 n, vec2 uv)
{
    vec3 q0 = dFdx(v_position), q1 = dFdy(v_position);
    vec2 st0 = dFdx(uv), st1 = dFdy(uv);
    vec3 q1perp = cross(q1, n), q0perp = cross(n, q0);
    vec3 t = q1perp * st0.x + q0perp * st1.x, b = q1perp * st0.y + q0perp * st1.y;
    float longer = max(dot(t, t), dot(b, b));
    if (longer <= 0.0)
        return n;
    float scale = inversesqrt(longer);
    vec3 m = texture(u_normalTexture, uv).xyz * 2.0 - 1.0;
    m.xy *= u_normalScale;
    return normalize(m.x * scale * t - m.y * scale * b + m.z * n);
}

// The material lit by the key, the fill and the hemisphere, linear.
vec3 shadeMaterial(vec3 albedo, vec3 n, vec3 view)
{
    float metallic = u_metallic, roughness = u_roughness;
    if (u_hasMetallicRoughnessTexture != 0) {
        vec4 mr = texture(u_metallicRoughnessTexture, u_metallicRoughnessSecond != 0 ? v_secondUV : v_materialUV);
        roughness *= mr.g;
        metallic *= mr.b;
    }
    metallic = clamp(metallic, 0.0, 1.0);
    roughness = clamp(roughness, 0.03, 1.0);
    float occlusion = 1.0;
    if (u_hasOcclusionTexture != 0)
        occlusion += u_occlusionStrength *
                     (texture(u_occlusionTexture, u_occlusionSecond != 0 ? v_secondUV : v_materialUV).r - 1.0);
    vec3 f0 = mix(vec3(0.04), albedo, metallic), diffuse = albedo * (1.0 - metallic);
    vec3 lit = directLight(normalize(kKey), vec3(2.5), n, view, diffuse, f0, roughness) +
               directLight(normalize(kFill), vec3(0.63), n, view, diffuse, f0, roughness);
    // The hemisphere: diffuse irradiance by the normal, specular by the
    // reflected ray, weighted by Karis' analytic fit of the split sum.
    float nv = max(dot(n, view), 1e-4);
    vec4 r = roughness * vec4(-1.0, -0.0275, -0.572, 0.022) + vec4(1.0, 0.0425, 1.04, -0.04);
    float a004 = min(r.x * r.x, exp2(-9.28 * nv)) * r.x + r.y;
    vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
    vec3 reflected = mix(kGround, kSky, 0.5 + 0.5 * reflect(-view, n).y);
    lit += occlusion * (diffuse * mix(kGround, kSky, 0.5 + 0.5 * n.y) + (f0 * ab.x + ab.y) * reflected);
    return lit;
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
        alpha = u_alphaMode == 2 ? c.a : 1.0;
        if (u_hasNormalTexture != 0)
            n = perturbNormal(n, u_normalSecond != 0 ? v_secondUV : v_materialUV);
        emitted = u_emissive;
        if (u_hasEmissiveTexture != 0)
            emitted *= texture(u_emissiveTexture, u_emissiveSecond != 0 ? v_secondUV : v_materialUV).rgb;
        o_color = vec4(srgbEncode(shadeMaterial(c.rgb, n, view) + emitted), alpha);
        return;
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
