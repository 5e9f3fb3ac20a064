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
uniform float u_cloud_cover;   // 0 clear .. 1 overcast (messages.Weather)
uniform vec2 u_cloud_offset;   // the cloud field's offset, m
"""

# Procedural detail shared by the ground and the foliage: value noise, cellular (Worley) noise and a
# footprint-filtered fbm. ``fw`` is the pixel footprint in metres (fwidth of the world position): every
# octave finer than about two pixels fades out, so detail never aliases into sparkle.
NOISE = """
float hash(vec2 p) { return fract(sin(dot(p, vec2(127.1, 311.7))) * 43758.5453); }
vec2 hash2(vec2 p) {
    return fract(sin(vec2(dot(p, vec2(127.1, 311.7)), dot(p, vec2(269.5, 183.3)))) * 43758.5453);
}
float vnoise(vec2 p) {
    vec2 i = floor(p); vec2 f = fract(p); vec2 u = f * f * (3.0 - 2.0 * f);
    return mix(mix(hash(i), hash(i + vec2(1, 0)), u.x), mix(hash(i + vec2(0, 1)), hash(i + vec2(1, 1)), u.x), u.y);
}
float fade(float cell_m, float fw) { return clamp(cell_m / (fw * 2.5) - 1.0, 0.0, 1.0); }
float fbm(vec2 p, float cell_m, float fw, int octaves) {
    float s = 0.0, a = 0.5, c = cell_m;
    for (int i = 0; i < octaves; ++i) {
        s += a * (vnoise(p / c) - 0.5) * fade(c, fw);
        c *= 0.5; a *= 0.55;
    }
    return s;
}
// Nearest feature point of a jittered grid of cell ``cell_m``: x = distance / cell, y = the cell's random id.
vec2 worley(vec2 p, float cell_m) {
    vec2 q = p / cell_m; vec2 i = floor(q); vec2 f = fract(q);
    float best = 8.0, id = 0.0;
    for (int y = -1; y <= 1; ++y) for (int x = -1; x <= 1; ++x) {
        vec2 g = vec2(x, y); vec2 o = hash2(i + g);
        float d = length(g + o - f);
        if (d < best) { best = d; id = hash(i + g + 17.0); }
    }
    return vec2(best, id);
}
"""

SHADOW = """
// Soft shadows: eight taps of the hardware 2x2 comparison filter on a disc turned per pixel, so the penumbra is a
// smooth gradient of about three texels instead of a staircase.
float shadow_at(vec3 wpos, vec3 n) {
    if (u_use_shadow == 0) return 1.0;
    vec4 lp = u_light_view_proj * vec4(wpos + n * 0.05, 1.0);
    vec3 p = lp.xyz / lp.w * 0.5 + 0.5;
    if (p.x <= 0.0 || p.x >= 1.0 || p.y <= 0.0 || p.y >= 1.0 || p.z >= 1.0) return 1.0;
    float bias = 0.0015;
    vec2 texel = 1.0 / vec2(textureSize(u_shadow, 0));
    float a = hash(gl_FragCoord.xy) * 6.2831853;
    mat2 rot = mat2(cos(a), sin(a), -sin(a), cos(a)) * 1.6;
    const vec2 DISC[8] = vec2[8](vec2(-0.61, 0.31), vec2(0.12, -0.93), vec2(0.84, 0.42), vec2(-0.27, -0.36),
                                 vec2(0.37, 0.05), vec2(-0.88, -0.45), vec2(-0.05, 0.79), vec2(0.63, -0.57));
    float s = 0.0;
    for (int i = 0; i < 8; ++i) s += texture(u_shadow, vec3(p.xy + rot * DISC[i] * texel, p.z - bias));
    return s * 0.125;
}
"""

CLOUDS = """
// Clouds: a layer of fbm at CLOUD_Z metres, thresholded by the cover (0 clear .. 1 overcast). The ground sees the
// sun through it along the light direction (cloud shadows); the sky shows it.
const float CLOUD_Z = 1200.0;
float cloud_density(vec2 p) {
    if (u_cloud_cover <= 0.0) return 0.0;
    vec2 q = (p + u_cloud_offset) / 650.0;
    float n = (0.5 * vnoise(q) + 0.25 * vnoise(q * 2.03 + 3.1) + 0.125 * vnoise(q * 4.07 + 7.7)
               + 0.0625 * vnoise(q * 8.3 + 1.3)) / 0.9375;
    float thr = 0.5 + 0.6 * (0.5 - u_cloud_cover);
    return max(smoothstep(thr - 0.05, thr + 0.12, n), smoothstep(0.75, 1.0, u_cloud_cover));
}
float sun_through_clouds(vec3 wpos) {
    if (u_cloud_cover <= 0.0) return 1.0;
    vec2 p = wpos.xy + u_light_dir.xy * (CLOUD_Z - wpos.z) / max(u_light_dir.z, 0.05);
    return 1.0 - 0.9 * cloud_density(p);
}
"""

LIGHTING = NOISE + SHADOW + CLOUDS + """
// Shadowing below the surface's own detail (the gaps between grass tufts, the foot of a stone): 1 = none.
// A surface sets it before write_surface; the sun loses more of it than the sky does.
float g_cavity = 1.0;

vec3 shade(vec3 albedo, vec3 n, vec3 wpos) {
    float ndl = max(dot(n, u_light_dir), 0.0);
    float sh = ndl > 0.0 ? shadow_at(wpos, n) * sun_through_clouds(wpos) : 0.0;
    // Hemisphere ambient, more from the sky; a cloudy sky is brighter and lights from all around.
    // Its light is whiter too: clouds scatter all colours alike.
    float sky = (0.6 + 0.4 * n.z) * mix(0.55, 1.0, g_cavity) * (1.0 + 1.3 * u_cloud_cover);
    vec3 ambient = mix(u_ambient_rgb, vec3(dot(u_ambient_rgb, vec3(0.3, 0.5, 0.2))), 0.7 * u_cloud_cover);
    return albedo * (u_light_rgb * ndl * sh * g_cavity + ambient * sky);
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
uniform sampler2D u_surface;     // surface weights over the same grid: grass, soil, rock, wet
uniform sampler2D u_contact;     // contact shadows (ambient occlusion under animals) over u_contact_xform
uniform vec4 u_contact_xform;    // origin x, origin y, 1/size x, 1/size y
uniform vec4 u_ground_xform;     // origin x, origin y, 1/size x, 1/size y
uniform vec3 u_ground_mean;      // beyond the terrain (the apron): the mean ground colour
uniform vec3 u_ground_tint;      // the step's ground look (messages.GroundLook): 1 = as authored
uniform float u_ground_desat;
uniform float u_detail;          // 0 = flat colours (the old look), 1 = full procedural detail

// Grass: clumps of tussocks (metres), tufts (decimetres) and blades (centimetres), each scale with dark gaps
// where soil and shade show through, multiplied so that the contrast of the coarse scales survives distance.
vec3 grass_detail(vec2 xy, float fw, out float h) {
    // The tussock grid is warped and comes and goes in patches, so from above it never reads as a regular tiling.
    vec2 warp = 0.9 * vec2(vnoise(xy * 0.37), vnoise(xy * 0.37 + 7.0));
    vec2 clump = worley(xy + warp, 1.7);
    vec2 big = worley(xy + 3.7 + 0.3 * warp, 0.45);
    vec2 small = worley(xy + 7.3, 0.16);
    float tussocky = smoothstep(-0.12, 0.18, fbm(xy + 31.0, 11.0, fw, 2));
    float c0 = (1.0 - smoothstep(0.2, 1.0, clump.x)) * fade(1.7, fw) * mix(0.35, 1.0, tussocky);
    float c1 = (1.0 - smoothstep(0.15, 0.95, big.x)) * fade(0.45, fw);
    float c2 = (1.0 - smoothstep(0.1, 0.9, small.x)) * fade(0.16, fw);
    float blades = (vnoise(vec2(xy.x * 90.0, xy.y * 9.0) + vnoise(xy * 23.0) * 4.0) - 0.5) * fade(0.03, fw);
    h = 0.5 * c0 + 0.3 * c1 + 0.2 * c2 + 0.2 * blades;
    float shade = (0.5 + 0.9 * c0 - 0.3 * fade(1.7, fw) * step(0.8, clump.y))
                * (0.62 + 0.7 * c1) * (0.75 + 0.5 * c2) * (1.0 + 0.6 * blades) * (1.0 + 1.1 * fbm(xy, 3.0, fw, 3));
    vec3 hue = mix(vec3(1.1, 1.0, 0.8), vec3(0.88, 1.06, 1.12), clump.y * 0.7 + big.y * 0.3);
    return hue * shade;
}

// Bare soil and sand: mottling, grain, pebbles and stones with a lit and a shaded side, fine cracks.
vec3 soil_detail(vec2 xy, float fw, vec3 l, out float h) {
    vec2 peb = worley(xy, 0.09);
    vec2 rock = worley(xy + 11.0, 0.8);
    float stone = (1.0 - smoothstep(0.25, 0.45, peb.x)) * step(0.55, peb.y) * fade(0.09, fw);
    float boulder = (1.0 - smoothstep(0.15, 0.3, rock.x)) * step(0.75, rock.y) * fade(0.8, fw);
    vec2 crack = worley(xy + 3.1, 0.6);
    float grain = fbm(xy, 0.05, fw, 3);
    float mottle = fbm(xy, 2.5, fw, 4);
    h = stone * 0.6 + boulder + grain;
    float lit = 0.5 + 0.5 * clamp(dot(normalize(vec2(0.3, 0.2) + l.xy), vec2(0.7, 0.7)), -1.0, 1.0);
    float shade = (1.0 + 1.4 * mottle) * (1.0 + 0.9 * grain) + (stone + boulder) * (0.45 * lit - 0.15)
                  - 0.3 * (1.0 - smoothstep(0.0, 0.08, crack.x)) * fade(0.6, fw);
    return vec3(shade) * mix(vec3(1.0), vec3(1.08, 0.98, 0.9), peb.y * stone);
}

vec3 rock_detail(vec2 xy, float fw, out float h) {
    vec2 c = worley(xy, 0.35);
    float edge = smoothstep(0.0, 0.18, c.x) * fade(0.35, fw);
    h = (1.0 - c.x) * 0.8;
    return vec3(0.75 + 0.45 * c.y) * mix(1.0, 0.55 + 0.45 * edge, fade(0.35, fw)) * (1.0 + fbm(xy, 0.2, fw, 3));
}

// Open water: the sky mirrored by Fresnel's law on a surface rippled at two scales, the sun's glint, and below it
// the bed fading into murky water with depth.
void write_water(vec3 bed, float depth, float fw) {
    vec2 xy = v_wpos.xy;
    float e = 0.05;
    float r0 = fbm(xy, 2.0, fw, 3) + 0.5 * fbm(xy * 1.7 + 5.0, 0.4, fw, 2);
    float rx = fbm(xy + vec2(e, 0.0), 2.0, fw, 3) + 0.5 * fbm((xy + vec2(e, 0.0)) * 1.7 + 5.0, 0.4, fw, 2);
    float ry = fbm(xy + vec2(0.0, e), 2.0, fw, 3) + 0.5 * fbm((xy + vec2(0.0, e)) * 1.7 + 5.0, 0.4, fw, 2);
    vec3 n = normalize(vec3(-(rx - r0) / e * 0.06, -(ry - r0) / e * 0.06, 1.0));
    vec3 v = normalize(u_cam_pos - v_wpos);
    float cosv = clamp(dot(n, v), 0.0, 1.0);
    float fres = 0.02 + 0.98 * pow(1.0 - cosv, 5.0);
    vec3 r = reflect(-v, n);
    float level = clamp(length(u_ambient_rgb) * 1.6, 0.03, 1.0);
    vec3 sky = mix(u_horizon_rgb, u_zenith_rgb, pow(clamp(r.z, 0.0, 1.0), 0.5)) * level;
    float murk = 1.0 - exp(-depth * 1.2);
    vec3 body = shade(mix(bed * 0.6, vec3(0.05, 0.06, 0.04), murk), vec3(0.0, 0.0, 1.0), v_wpos);
    float sun = u_use_shadow == 0 ? 1.0 : shadow_at(v_wpos, vec3(0.0, 0.0, 1.0));
    vec3 glint = u_light_rgb * pow(max(dot(r, u_light_dir), 0.0), 300.0) * 4.0 * sun;
    vec3 c = mix(body, sky, fres) + glint;
    f_color = encode(haze(c, v_wpos));
    f_depth = dot(v_wpos - u_cam_pos, u_cam_fwd);
    f_id = 0u;
}

void main() {
    vec2 uv = (v_wpos.xy - u_ground_xform.xy) * u_ground_xform.zw;
    bool inside = all(greaterThanEqual(uv, vec2(0.0))) && all(lessThanEqual(uv, vec2(1.0)));
    vec3 albedo = inside ? texture(u_ground, uv).rgb : u_ground_mean;
    vec4 surf = inside ? texture(u_surface, uv) : vec4(0.6, 0.4, 0.0, 0.0);
    surf /= max(surf.x + surf.y + surf.z + surf.w, 1e-3);
    // The footprint's geometric mean: on ground seen at a grazing angle a pixel is long in depth but narrow
    // across, and detail across the view stays visible.
    float fw = max(sqrt(length(dFdx(v_wpos.xy)) * length(dFdy(v_wpos.xy))), 1e-4);
    vec2 xy = v_wpos.xy;
    // Patches at metre scales: dry and green, worn and thick, so no terrain cell is one flat colour.
    float patches = fbm(xy, 6.0, fw, 4);
    float hg, hs, hr;
    vec3 g = grass_detail(xy, fw, hg);
    vec3 so = soil_detail(xy, fw, u_light_dir, hs);
    vec3 r = rock_detail(xy, fw, hr);
    vec3 wet = vec3(0.55 + 0.4 * fbm(xy, 0.4, fw, 3));
    vec3 detail = g * surf.x + so * surf.y + r * surf.z + wet * surf.w;
    detail *= 1.0 + 0.8 * patches;
    albedo *= mix(vec3(1.0), detail, u_detail);
    albedo = min(mix(albedo, vec3(dot(albedo, vec3(0.2126, 0.7152, 0.0722))), u_ground_desat) * u_ground_tint,
                 vec3(0.95));
    // Micro-relief: the detail's height field tilts the normal, so the sun models tufts and stones.
    float hgt = (hg * surf.x + hs * surf.y + hr * surf.z) * u_detail;
    g_cavity = mix(1.0, clamp(0.25 + 0.9 * (hg * surf.x + (0.6 + hs) * surf.y + hr * surf.z + 0.7 * surf.w), 0.0, 1.0),
                   u_detail);
    vec2 grad = vec2(dFdx(hgt), dFdy(hgt));
    vec3 n = normalize(v_normal);
    vec3 dpx = dFdx(v_wpos), dpy = dFdy(v_wpos);
    vec3 bump = normalize(n - 0.08 * (grad.x * normalize(dpx) / max(length(dpx), 1e-4)
                                     + grad.y * normalize(dpy) / max(length(dpy), 1e-4)) * 0.05);
    vec2 cuv = (xy - u_contact_xform.xy) * u_contact_xform.zw;
    float contact = all(greaterThanEqual(cuv, vec2(0.0))) && all(lessThanEqual(cuv, vec2(1.0)))
                    ? texture(u_contact, cuv).r : 1.0;
    albedo *= contact;
    float water = inside ? texture(u_ground, uv).a : -2.0;
    // Wet mud darkens the shore up to half a metre above the water line.
    albedo *= mix(1.0, 0.55, smoothstep(-0.5, 0.0, water));
    if (water > 0.0) {
        write_water(albedo, water, fw);
        return;
    }
    write_surface(albedo, mix(n, bump, u_detail), 0u);
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
out vec3 v_opos;
flat out float v_seed;
void main() {
    mat3 r = instance_yaw();
    v_wpos = i_pos + r * (in_pos * i_scale);
    v_normal = r * in_normal;
    v_color = in_color;
    v_opos = in_pos * i_scale;
    v_seed = fract(i_pos.x * 0.1307 + i_pos.y * 0.7131);
    gl_Position = u_view_proj * vec4(v_wpos, 1.0);
}
"""

# Plants: green parts read as leaves (clusters of leaves with dark gaps between them, each cluster facing its own way
# and coloured its own shade, self-shadowed inside the crown); the rest (bark, rock, props) gets grain and streaks.
VEG_FS = COMMON + SURFACE + """
in vec3 v_normal;
in vec3 v_color;
in vec3 v_opos;
flat in float v_seed;
uniform vec3 u_veg_tint;        // the step's plant colour (messages.GroundLook.vegetation_tint)
uniform float u_detail;         // 0 = flat vertex colours (the plain look)
void main() {
    vec3 n = normalize(v_normal);
    if (!gl_FrontFacing) n = -n;
    vec3 albedo = v_color * u_veg_tint;
    if (u_detail > 0.0) {
        float fw = max(length(fwidth(v_opos)), 1e-4);
        float leafy = smoothstep(0.0, 0.015, v_color.g - max(v_color.r, v_color.b));
        vec2 p = v_opos.xy + v_opos.z * vec2(0.61, -0.37) + v_seed * 97.0;
        vec2 cl = worley(p + 0.25 * vec2(vnoise(p * 3.1), vnoise(p * 2.7 + 9.0)), 0.26);
        vec2 lf = worley(p + 5.3, 0.09);
        // A ragged crown: where the surface turns away from the camera, the gaps between leaf clusters are holes.
        // All three outputs show what lies behind, so labels stay exact.
        float facing = abs(dot(n, normalize(u_cam_pos - v_wpos)));
        if (leafy > 0.5 && cl.x > 0.3 + 2.0 * facing && fade(0.26, fw) > 0.5) discard;
        float clump = 1.0 - smoothstep(0.3, 0.95, cl.x);
        float leaf = 1.0 - smoothstep(0.25, 0.9, lf.x);
        float gaps = mix(1.0, 0.22 + 0.78 * clump, fade(0.26, fw));
        float lshade = gaps * mix(1.0, 0.65 + 0.6 * leaf, fade(0.09, fw));
        vec3 hue = mix(vec3(0.8, 1.0, 0.85), vec3(1.2, 1.02, 0.8), cl.y);
        vec2 tilt = (hash2(vec2(cl.y * 37.0, v_seed * 11.0)) - 0.5) * 1.6 * fade(0.26, fw);
        float grain = (1.0 + 0.9 * fbm(vec2(v_opos.x + v_opos.y, v_opos.z * 0.2), 0.3, fw, 3))
                    * (1.0 + 0.5 * fbm(v_opos.xy * 1.3 + v_opos.z, 0.07, fw, 2));
        albedo = mix(albedo * grain, albedo * mix(vec3(1.0), hue, fade(0.26, fw)) * lshade, leafy);
        n = normalize(mix(n, normalize(n + vec3(tilt, 0.0)), leafy));
        g_cavity = mix(1.0, 0.3 + 0.7 * clump, leafy * fade(0.26, fw));
    }
    write_surface(albedo, n, 0u);
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
uniform float u_ground_z;       // ground height under the herd (dust on the lower body)
uniform float u_detail;         // 0 = the coat texture as it is (the plain look), 1 = as photographs show it
void main() {
    vec3 n = normalize(cross(dFdx(v_wpos), dFdy(v_wpos)));
    if (dot(n, u_cam_pos - v_wpos) < 0.0) n = -n;
    vec3 albedo = pow(texture(u_coats, vec3(v_uv, v_layer)).rgb, vec3(2.2));
    vec3 plain = albedo;
    // Coats as photographs show them: near-black stripes on near-white hair (contrast about the coat's mid-grey),
    // a darker belly and legs in their own shade, dust on the lower body that differs per animal, and a sheen
    // of short hair towards grazing light.
    float luma = dot(albedo, vec3(0.2126, 0.7152, 0.0722));
    albedo = clamp(mix(vec3(luma), albedo, 0.7) * (luma > 0.12 ? 1.35 : 0.45), 0.0, 0.9);
    float dust = fract(sin(float(v_id) * 12.9898) * 43758.5453);
    float low = clamp(1.0 - (v_wpos.z - u_ground_z) / 0.9, 0.0, 1.0);
    albedo = mix(albedo, vec3(0.32, 0.25, 0.17), low * dust * 0.45);
    albedo *= mix(0.7, 1.0, clamp(n.z * 0.5 + 0.5, 0.0, 1.0));
    float rim = pow(1.0 - abs(dot(n, normalize(u_cam_pos - v_wpos))), 3.0);
    albedo += rim * 0.06 * max(dot(n, u_light_dir), 0.0);
    write_surface(mix(plain, albedo, u_detail), n, v_id);
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

# The sky: a gradient from horizon to zenith, brighter round the sun (forward scattering), the sun's disk, and the
# cloud layer the ground's cloud shadows come from (lit from the sun's side, grey where thick, fading into haze
# towards the horizon); an overcast sky is a bright grey.
SKY_FS = COMMON + NOISE + CLOUDS + OUTPUTS + """
in vec2 v_ndc;
uniform mat4 u_inv_view_proj;
uniform vec3 u_sun_dir;
uniform float u_sun_visible;
void main() {
    vec4 far = u_inv_view_proj * vec4(v_ndc, 1.0, 1.0);
    vec3 dir = normalize(far.xyz / far.w - u_cam_pos);
    float up = clamp(dir.z, 0.0, 1.0);
    float level = clamp(length(u_ambient_rgb) * 1.6, 0.03, 1.0);
    vec3 sky = mix(u_horizon_rgb, u_zenith_rgb, pow(up, 0.5));
    float grey = dot(sky, vec3(0.3, 0.5, 0.2));
    sky = mix(sky, vec3(grey * 1.15), u_cloud_cover * 0.85);
    float mu = max(dot(dir, u_sun_dir), 0.0);
    float halo = (pow(mu, 64.0) * 0.4 + pow(mu, 6.0) * 0.12) * u_sun_visible;
    vec3 c = sky * level + u_light_rgb * halo;
    float disk = smoothstep(0.99993, 0.99997, mu) * u_sun_visible;
    float cover = 0.0;
    if (dir.z > 0.0 && u_cloud_cover > 0.0) {
        vec2 p = u_cam_pos.xy + dir.xy * (CLOUD_Z - u_cam_pos.z) / max(dir.z, 0.01);
        float d = cloud_density(p);
        float toward = cloud_density(p + u_light_dir.xy * 180.0);
        // Cloud droplets scatter all colours alike: lit by the sun's colour and the sky's brightness, not its blue.
        vec3 lit = u_light_rgb * (0.25 + 0.55 * (1.0 - toward)) + vec3(dot(u_ambient_rgb, vec3(0.3, 0.5, 0.2))) * 1.9;
        vec3 cloud = lit * mix(1.0, 0.55, d * toward) * (1.0 - 0.3 * u_cloud_cover);
        cover = d * smoothstep(0.0, 0.12, dir.z);
        c = mix(c, cloud, cover);
    }
    c += u_light_rgb * disk * 12.0 * (1.0 - cover);
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
