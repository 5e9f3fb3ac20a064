"""GLSL 4.30 sources. Lighting is computed in linear RGB and written gamma-encoded (sRGB) at the end.

Every geometry pass writes three outputs: 0 = colour, 1 = depth along the optical axis in metres
(float32), 2 = instance id (uint: zebra id + 1, 0 for everything else).
"""

COMMON = """
#version 430
uniform mat4 u_view_proj;
uniform mat4 u_light_view_proj;
uniform vec3 u_cam_pos;
uniform vec3 u_cam_fwd;
uniform vec3 u_light_dir;      // towards the light
uniform vec3 u_light_rgb;      // colour * intensity
uniform vec3 u_ambient_rgb;    // colour * intensity
uniform vec3 u_horizon_rgb;
uniform vec3 u_zenith_rgb;
uniform float u_haze;          // extinction per metre
uniform float u_exposure;
uniform sampler2DShadow u_shadow;
uniform int u_use_shadow;
"""

LIGHTING = """
float shadow_at(vec3 wpos, vec3 n) {
    if (u_use_shadow == 0) return 1.0;
    vec4 lp = u_light_view_proj * vec4(wpos + n * 0.05, 1.0);
    vec3 p = lp.xyz / lp.w * 0.5 + 0.5;
    if (p.x <= 0.0 || p.x >= 1.0 || p.y <= 0.0 || p.y >= 1.0 || p.z >= 1.0) return 1.0;
    float bias = 0.0015;
    vec2 texel = 1.0 / vec2(textureSize(u_shadow, 0));
    float s = 0.0;
    s += texture(u_shadow, vec3(p.xy + vec2(-0.5, -0.5) * texel, p.z - bias));
    s += texture(u_shadow, vec3(p.xy + vec2( 0.5, -0.5) * texel, p.z - bias));
    s += texture(u_shadow, vec3(p.xy + vec2(-0.5,  0.5) * texel, p.z - bias));
    s += texture(u_shadow, vec3(p.xy + vec2( 0.5,  0.5) * texel, p.z - bias));
    return s * 0.25;
}

vec3 shade(vec3 albedo, vec3 n, vec3 wpos) {
    float ndl = max(dot(n, u_light_dir), 0.0);
    float sh = ndl > 0.0 ? shadow_at(wpos, n) : 0.0;
    float sky = 0.6 + 0.4 * n.z;  // hemisphere ambient: more from the sky than from the ground
    return albedo * (u_light_rgb * ndl * sh + u_ambient_rgb * sky);
}

vec3 haze(vec3 c, vec3 wpos) {
    float d = length(wpos - u_cam_pos);
    float f = 1.0 - exp(-u_haze * d);
    return mix(c, u_horizon_rgb * clamp(length(u_ambient_rgb) * 1.6, 0.03, 1.0), f);
}

vec4 encode(vec3 linear) {
    vec3 c = 1.0 - exp(-linear * u_exposure);  // soft tone curve keeps highlights
    return vec4(pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
"""

OUTPUTS = """
layout(location = 0) out vec4 f_color;
layout(location = 1) out float f_depth;
layout(location = 2) out uint f_id;
"""

# What every lit surface (terrain, vegetation, zebras) writes: one function, so the three outputs agree everywhere.
SURFACE = LIGHTING + OUTPUTS + """
in vec3 v_wpos;
void write_surface(vec3 albedo, vec3 n, uint id) {
    f_color = encode(haze(shade(albedo, n, v_wpos), v_wpos));
    f_depth = dot(v_wpos - u_cam_pos, u_cam_fwd);
    f_id = id;
}
"""

TERRAIN_VS = COMMON + """
in vec3 in_pos;
in vec3 in_normal;
out vec3 v_wpos;
out vec3 v_normal;
void main() {
    v_wpos = in_pos;
    v_normal = in_normal;
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
}
"""

TERRAIN_FS = COMMON + SURFACE + """
in vec3 v_normal;
uniform sampler2D u_ground;      // ground colour (linear) over the terrain grid
uniform vec4 u_ground_xform;     // origin x, origin y, 1/size x, 1/size y
uniform vec3 u_ground_mean;      // beyond the terrain (the apron): the mean ground colour
uniform vec3 u_ground_tint;      // the step's ground look (messages.GroundLook): 1 = as authored
uniform float u_ground_desat;
float hash(vec2 p) { return fract(sin(dot(p, vec2(127.1, 311.7))) * 43758.5453); }
float vnoise(vec2 p) {
    vec2 i = floor(p); vec2 f = fract(p); vec2 u = f * f * (3.0 - 2.0 * f);
    return mix(mix(hash(i), hash(i + vec2(1, 0)), u.x), mix(hash(i + vec2(0, 1)), hash(i + vec2(1, 1)), u.x), u.y);
}
void main() {
    vec2 uv = (v_wpos.xy - u_ground_xform.xy) * u_ground_xform.zw;
    bool inside = all(greaterThanEqual(uv, vec2(0.0))) && all(lessThanEqual(uv, vec2(1.0)));
    vec3 albedo = inside ? texture(u_ground, uv).rgb : u_ground_mean;
    float d = vnoise(v_wpos.xy * 4.0) * 0.5 + vnoise(v_wpos.xy * 0.7) * 0.5;  // grass/soil detail
    albedo *= 0.82 + 0.36 * d;
    albedo = min(mix(albedo, vec3(dot(albedo, vec3(0.2126, 0.7152, 0.0722))), u_ground_desat) * u_ground_tint,
                 vec3(0.95));
    write_surface(albedo, normalize(v_normal), 0u);
}
"""

# A vegetation copy: per-instance position (map, m), yaw about +z (rad) and uniform scale of the prototype mesh.
INSTANCE = """
in vec3 i_pos;
in float i_yaw;
in float i_scale;
mat3 instance_yaw() {
    float c = cos(i_yaw), s = sin(i_yaw);
    return mat3(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
}
"""

VEG_VS = COMMON + INSTANCE + """
in vec3 in_pos;
in vec3 in_normal;
in vec3 in_color;
out vec3 v_wpos;
out vec3 v_normal;
out vec3 v_color;
void main() {
    mat3 r = instance_yaw();
    v_wpos = i_pos + r * (in_pos * i_scale);
    v_normal = r * in_normal;
    v_color = in_color;
    gl_Position = u_view_proj * vec4(v_wpos, 1.0);
}
"""

VEG_FS = COMMON + SURFACE + """
in vec3 v_normal;
in vec3 v_color;
void main() {
    vec3 n = normalize(v_normal);
    if (!gl_FrontFacing) n = -n;
    write_surface(v_color, n, 0u);
}
"""

# A posed zebra vertex: all zebras' vertices (x, y, z in map, m) packed in one buffer, ``u_verts`` per zebra.
POSED = """
layout(std430, binding = 0) buffer Posed { float posed[]; };
uniform int u_verts;             // vertices per zebra
vec3 posed_vertex() {
    int k = (gl_InstanceID * u_verts + gl_VertexID) * 3;
    return vec3(posed[k], posed[k + 1], posed[k + 2]);
}
"""

ZEBRA_VS = COMMON + POSED + """
in vec2 in_uv;
in uint i_id;
in float i_layer;
out vec3 v_wpos;
out vec2 v_uv;
flat out uint v_id;
flat out float v_layer;
void main() {
    v_wpos = posed_vertex();
    v_uv = in_uv;
    v_id = i_id;
    v_layer = i_layer;
    gl_Position = u_view_proj * vec4(v_wpos, 1.0);
}
"""

ZEBRA_FS = COMMON + SURFACE + """
in vec2 v_uv;
flat in uint v_id;
flat in float v_layer;
uniform sampler2DArray u_coats;
void main() {
    vec3 n = normalize(cross(dFdx(v_wpos), dFdy(v_wpos)));
    if (dot(n, u_cam_pos - v_wpos) < 0.0) n = -n;
    vec3 albedo = pow(texture(u_coats, vec3(v_uv, v_layer)).rgb, vec3(2.2));
    write_surface(albedo, n, v_id);
}
"""

SKY_VS = """
#version 430
out vec2 v_ndc;
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2) * 2.0 - 1.0;
    v_ndc = p;
    gl_Position = vec4(p, 1.0, 1.0);  // at the far plane: drawn only where nothing else is
}
"""

SKY_FS = COMMON + OUTPUTS + """
in vec2 v_ndc;
uniform mat4 u_inv_view_proj;
uniform vec3 u_sun_dir;
uniform float u_sun_visible;
void main() {
    vec4 far = u_inv_view_proj * vec4(v_ndc, 1.0, 1.0);
    vec3 dir = normalize(far.xyz / far.w - u_cam_pos);
    float up = clamp(dir.z, 0.0, 1.0);
    vec3 sky = mix(u_horizon_rgb, u_zenith_rgb, pow(up, 0.5));
    float glow = pow(max(dot(dir, u_sun_dir), 0.0), 64.0) * u_sun_visible;
    float level = clamp(length(u_ambient_rgb) * 1.6, 0.03, 1.0);
    vec3 c = sky * level + u_light_rgb * glow * 0.4;
    if (dir.z < 0.0) c = u_horizon_rgb * level * 0.6;
    f_color = vec4(pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
    f_depth = 0.0;
    f_id = 0u;
}
"""

DEPTH_VEG_VS = """
#version 430
uniform mat4 u_light_view_proj;
in vec3 in_pos;
""" + INSTANCE + """
void main() {
    gl_Position = u_light_view_proj * vec4(i_pos + instance_yaw() * (in_pos * i_scale), 1.0);
}
"""

DEPTH_ZEBRA_VS = """
#version 430
uniform mat4 u_light_view_proj;
""" + POSED + """
void main() {
    gl_Position = u_light_view_proj * vec4(posed_vertex(), 1.0);
}
"""

DEPTH_FS = """
#version 430
void main() { }
"""

FXAA_VS = SKY_VS.replace("gl_Position = vec4(p, 1.0, 1.0);  // at the far plane: drawn only where nothing else is",
                         "gl_Position = vec4(p, 0.0, 1.0);")

FXAA_FS = """
#version 430
in vec2 v_ndc;
uniform sampler2D u_src;
out vec4 f_color;
float luma(vec3 c) { return dot(c, vec3(0.299, 0.587, 0.114)); }
void main() {
    vec2 px = 1.0 / vec2(textureSize(u_src, 0));
    vec2 uv = v_ndc * 0.5 + 0.5;
    vec3 c = texture(u_src, uv).rgb;
    float lm = luma(c);
    float ln = luma(texture(u_src, uv + vec2(0.0, px.y)).rgb);
    float ls = luma(texture(u_src, uv - vec2(0.0, px.y)).rgb);
    float le = luma(texture(u_src, uv + vec2(px.x, 0.0)).rgb);
    float lw = luma(texture(u_src, uv - vec2(px.x, 0.0)).rgb);
    float lo = min(lm, min(min(ln, ls), min(le, lw)));
    float hi = max(lm, max(max(ln, ls), max(le, lw)));
    float range = hi - lo;
    if (range < max(0.04, hi * 0.1)) { f_color = vec4(c, 1.0); return; }
    // Blend across the edge: along the steeper luma gradient, by how much the centre stands out.
    bool horizontal = abs(ln + ls - 2.0 * lm) >= abs(le + lw - 2.0 * lm);
    vec2 step = horizontal ? vec2(0.0, px.y) : vec2(px.x, 0.0);
    float g1 = horizontal ? abs(ln - lm) : abs(le - lm);
    float g2 = horizontal ? abs(ls - lm) : abs(lw - lm);
    vec2 side = g1 >= g2 ? step : -step;
    float blend = clamp(abs((ln + ls + le + lw) * 0.25 - lm) / range, 0.0, 1.0);
    blend = blend * blend * 0.75;
    vec3 other = texture(u_src, uv + side * 0.5).rgb;
    f_color = vec4(mix(c, other, blend), 1.0);
}
"""
