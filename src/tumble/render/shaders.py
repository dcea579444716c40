"""GLSL 3.30 sources of the renderer's passes.

Lighting is done in linear colour and written out as sRGB. All passes share `COMMON`: one sun
(a directional light), a sky/ground hemisphere for ambient light, Blinn-Phong highlights, and
an optional sun shadow map.
"""

COMMON = """
uniform vec3 u_eye;        // camera position (world)
uniform vec3 u_up;         // world up (unit)
uniform vec3 u_light_dir;  // unit vector towards the sun (world)
uniform sampler2D u_shadow_map;
uniform mat4 u_light_vp;   // world -> sun clip space
uniform float u_shadow_on; // 1 when the shadow map is valid
uniform float u_dither;    // 1: add the output dither (off for GIFs, whose palette decides)

const vec3 SUN = vec3(1.00, 0.96, 0.90) * 1.25;
const vec3 SKY_ZENITH = vec3(0.30, 0.50, 0.80);
const vec3 SKY_HORIZON = vec3(0.84, 0.89, 0.95);
const vec3 SKY_BELOW = vec3(0.60, 0.64, 0.69);

vec3 to_linear(vec3 c) { return pow(c, vec3(2.2)); }
vec3 to_srgb(vec3 c) { return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)); }
// exposure tone curve 1 - exp(-k c): linear near black, rolls off highlights instead of clipping
vec3 tonemap(vec3 c) { return 1.0 - exp(-1.5 * c); }

// screen-space noise in [0, 1) from the pixel position: an integer hash (the "lowbias32" mixer's
// constants), the same for a pixel in every frame, so renders stay byte-identical
float pixel_noise(uint salt) {
    uvec2 p = uvec2(gl_FragCoord.xy);
    uint h = p.x * 0x8da6b343u ^ p.y * 0xd8163841u ^ salt * 0xcb1ab31fu;
    h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15; h *= 0x846ca68bu; h ^= h >> 16;
    return float(h >> 8) / 16777216.0;
}

// an sRGB colour about to be stored in 8 bits, plus triangular noise of +-1 step: a smooth
// gradient (the sky, a large sphere) then shows no bands, its mean still exact (no bias)
vec3 dither(vec3 c) {
    return c + u_dither * (pixel_noise(1u) + pixel_noise(2u) - 1.0) / 255.0;
}

// sky colour (sRGB) seen along a unit direction: horizon to zenith above, a haze below
vec3 sky_color(vec3 dir) {
    float h = dot(dir, u_up);
    vec3 c = h > 0.0 ? mix(SKY_HORIZON, SKY_ZENITH, pow(h, 0.55))
                     : mix(SKY_HORIZON, SKY_BELOW, pow(min(-h * 4.0, 1.0), 0.6));
    float sun = max(dot(dir, u_light_dir), 0.0);
    return c + vec3(1.0, 0.9, 0.7) * (0.25 * pow(sun, 300.0) + 0.08 * pow(sun, 12.0));
}

// fraction of sunlight reaching world point p with normal n (1 = lit), 3x3 PCF
float sun_visibility(vec3 p, vec3 n) {
    if (u_shadow_on < 0.5) return 1.0;
    vec4 c = u_light_vp * vec4(p + n * 0.002, 1.0);
    vec3 s = c.xyz / c.w * 0.5 + 0.5;
    if (s.x <= 0.0 || s.x >= 1.0 || s.y <= 0.0 || s.y >= 1.0 || s.z >= 1.0) return 1.0;
    vec2 texel = 1.0 / vec2(textureSize(u_shadow_map, 0));
    // slope-scaled bias: surfaces grazing the sun need more
    float bias = 0.0015 + 0.004 * (1.0 - max(dot(n, u_light_dir), 0.0));
    float lit = 0.0;
    for (int i = -1; i <= 1; i++) {
        for (int j = -1; j <= 1; j++) {
            float d = texture(u_shadow_map, s.xy + vec2(i, j) * texel).r;
            lit += (s.z - bias <= d) ? 1.0 : 0.0;
        }
    }
    return lit / 9.0;
}

// linear colour of a surface with linear albedo a at world point p, unit normal n
vec3 shade_linear(vec3 a, vec3 p, vec3 n, float shininess, float specular) {
    vec3 v = normalize(u_eye - p);
    float ndl = max(dot(n, u_light_dir), 0.0);
    float vis = ndl > 0.0 ? sun_visibility(p, n) : 0.0;
    // hemisphere ambient: sky from above, a warm bounce from the ground below
    float up = dot(n, u_up) * 0.5 + 0.5;
    vec3 ambient = mix(vec3(0.09, 0.08, 0.07), vec3(0.26, 0.29, 0.35), up);
    vec3 c = a * (SUN * ndl * vis + ambient);
    if (specular > 0.0 && ndl > 0.0) {
        vec3 h = normalize(u_light_dir + v);
        c += SUN * (specular * pow(max(dot(n, h), 0.0), shininess) * vis);
    }
    return c;
}

// the same with an sRGB albedo
vec3 shade(vec3 albedo, vec3 p, vec3 n, float shininess, float specular) {
    return shade_linear(to_linear(albedo), p, n, shininess, specular);
}
"""

SKY_VERTEX = """
#version 330
out vec2 v_ndc;
void main() {
    // one triangle that covers the screen
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    v_ndc = p;
    gl_Position = vec4(p, 0.0, 1.0);
}
"""

SKY_FRAGMENT = (
    """
#version 330
in vec2 v_ndc;
uniform mat4 u_inv_vp;
out vec4 f_color;
"""
    + COMMON
    + """
void main() {
    vec4 far_point = u_inv_vp * vec4(v_ndc, 1.0, 1.0);
    vec3 dir = normalize(far_point.xyz / far_point.w - u_eye);
    f_color = vec4(dither(sky_color(dir)), 1.0);
}
"""
)

# an infinite plane, ray cast per pixel over the full screen: exact at every distance,
# drawn only from its front (+normal) side, checkered, fading into the sky far away
PLANE_FRAGMENT = (
    """
#version 330
in vec2 v_ndc;
uniform mat4 u_inv_vp;
uniform mat4 u_vp;
uniform vec3 u_normal;
uniform float u_offset;
uniform vec3 u_tangent;
uniform vec3 u_bitangent;
uniform float u_cell;
uniform float u_fade;
// walls and ramps (planes not facing straight up) are cut to the inside of the other planes and
// to a box around the scene, so a container of planes shows as its far walls, not endless sheets
uniform float u_wall;
uniform vec4 u_others[8];   // the other planes: unit normal, offset
uniform int u_other_count;
uniform vec3 u_clip_min;
uniform vec3 u_clip_max;
uniform float u_glass;
uniform float u_sky_on_miss;
out vec4 f_color;
"""
    + COMMON
    + """
// integral of the unit square wave s(u) = +1 on [0, 1), -1 on [1, 2) (period 2): a triangle wave
float square_integral(float u) { return 1.0 - abs(1.0 - 2.0 * fract(u * 0.5)); }

// checker value in [0, 1], box-filtered over the pixel footprint w so it greys out far away
// instead of shimmering: the mean of s over [u - w/2, u + w/2] is (S(u + w/2) - S(u - w/2)) / w
float checker(vec2 uv) {
    vec2 w = max(fwidth(uv), vec2(1e-4));
    float sx = (square_integral(uv.x + 0.5 * w.x) - square_integral(uv.x - 0.5 * w.x)) / w.x;
    float sy = (square_integral(uv.y + 0.5 * w.y) - square_integral(uv.y - 0.5 * w.y)) / w.y;
    return 0.5 + 0.5 * sx * sy;
}

void main() {
    vec4 far_point = u_inv_vp * vec4(v_ndc, 1.0, 1.0);
    vec3 dir = normalize(far_point.xyz / far_point.w - u_eye);
    float denom = dot(u_normal, dir);
    float t = (u_offset - dot(u_normal, u_eye)) / denom;
    // the opaque pass draws a plane's front side only; the glass pass (walls seen from behind,
    // drawn last and blended) draws the back side as faint glass with darker edges
    if (t <= 0.0 || (u_glass < 0.5 ? denom >= -1e-6 : denom <= 1e-6)) {
        // the first level floor also paints the sky where it misses (one full-screen pass less)
        if (u_sky_on_miss < 0.5) discard;
        f_color = vec4(dither(sky_color(dir)), 1.0);
        gl_FragDepth = 1.0;
        return;
    }
    vec3 p = u_eye + t * dir;
    float rim = 1.0;
    if (u_wall > 0.5) {
        // distance inside the clip region: the nearest other plane or box face
        float inside = min(min(p.x - u_clip_min.x, u_clip_max.x - p.x),
                           min(min(p.y - u_clip_min.y, u_clip_max.y - p.y), min(p.z - u_clip_min.z, u_clip_max.z - p.z)));
        for (int i = 0; i < u_other_count; i++) {
            inside = min(inside, dot(u_others[i].xyz, p) - u_others[i].w);
        }
        if (inside < 0.0) discard;
        float w = 0.004 * t;  // edge line about a few pixels wide
        rim = mix(0.55, 1.0, smoothstep(w, 2.0 * w, inside));
        if (u_glass > 0.5) {
            float edge = 1.0 - smoothstep(w, 2.0 * w, inside);
            f_color = vec4(mix(vec3(0.80, 0.88, 0.95), vec3(0.30, 0.33, 0.36), edge), mix(0.10, 0.55, edge));
            vec4 clip_glass = u_vp * vec4(p, 1.0);
            gl_FragDepth = clip_glass.z / clip_glass.w * 0.5 + 0.5;
            return;
        }
    }
    vec2 uv = vec2(dot(p, u_tangent), dot(p, u_bitangent)) / u_cell;
    // the two checker colours, linear: sRGB (0.86, 0.86, 0.84) and (0.64, 0.66, 0.68)
    vec3 albedo = mix(vec3(0.717, 0.717, 0.682), vec3(0.375, 0.401, 0.428), checker(uv)) * (rim * rim);
    vec3 c = to_srgb(tonemap(shade_linear(albedo, p, u_normal, 24.0, 0.0)));
    float r = t / u_fade;
    float fog = 1.0 - exp(-r * r);
    if (fog > 0.002) c = mix(c, sky_color(dir), fog);
    f_color = vec4(dither(c), 1.0);
    vec4 clip = u_vp * vec4(p, 1.0);
    gl_FragDepth = min(clip.z / clip.w * 0.5 + 0.5, 0.9999999);
}
"""
)

# spheres: one camera-facing quad per sphere that covers its silhouette; the fragment shader
# intersects the view ray with the sphere and writes the true depth
SPHERE_VERTEX = """
#version 330
in vec2 in_corner;
in vec3 in_center;
in float in_radius;
in vec4 in_quat;
in vec3 in_color;
uniform mat4 u_view;
uniform mat4 u_proj;
out vec3 v_eye_pos;
flat out vec3 v_center;
flat out float v_radius;
flat out vec4 v_quat;
flat out vec3 v_color;
void main() {
    vec3 c = (u_view * vec4(in_center, 1.0)).xyz;
    float d = length(c);
    v_center = c;
    v_radius = in_radius;
    v_quat = in_quat;
    v_color = in_color;
    if (d <= in_radius * 1.0001) {  // the eye is inside: skip
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        v_eye_pos = c;
        return;
    }
    // the silhouette is a cone from the eye with sin(half angle) = r / d; at distance d along
    // the axis its cross-section has radius r d / sqrt(d^2 - r^2), circumscribed by the quad
    vec3 w = c / d;
    vec3 a = abs(w.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 u = normalize(cross(a, w));
    vec3 v = cross(w, u);
    float s = in_radius * d / sqrt(d * d - in_radius * in_radius);
    vec3 p = c + (in_corner.x * u + in_corner.y * v) * s;
    v_eye_pos = p;
    gl_Position = u_proj * vec4(p, 1.0);
}
"""

SPHERE_FRAGMENT = (
    """
#version 330
in vec3 v_eye_pos;
flat in vec3 v_center;
flat in float v_radius;
flat in vec4 v_quat;
flat in vec3 v_color;
uniform mat4 u_proj;
uniform mat4 u_inv_view;
uniform float u_coverage;  // 1 when drawing multisampled with alpha-to-coverage: smooth edges
out vec4 f_color;
"""
    + COMMON
    + """
vec3 rotate_inv(vec4 q, vec3 v) {  // rotate by the conjugate of unit quaternion q = (x, y, z, w)
    vec3 t = 2.0 * cross(-q.xyz, v);
    return v + q.w * t + cross(-q.xyz, t);
}
void main() {
    // ray x = t d from the eye: |t d - c|^2 = r^2  ->  t^2 - 2 t (d.c) + c.c - r^2 = 0
    vec3 d = normalize(v_eye_pos);
    float b = dot(d, v_center);
    // distance from the centre to the ray; the pixel's share of the disc (edge antialiasing)
    // is its distance inside the silhouette over the pixel's size there
    float miss = sqrt(max(dot(v_center, v_center) - b * b, 0.0));
    float alpha = clamp((v_radius - miss) / max(fwidth(miss), 1e-7) + 0.5, 0.0, 1.0);
    if (u_coverage < 0.5 ? miss > v_radius : alpha <= 0.0) discard;
    float t = b - sqrt(max(v_radius * v_radius - miss * miss, 0.0));
    vec3 hit = t * d;
    vec4 clip = u_proj * vec4(hit, 1.0);
    gl_FragDepth = clip.z / clip.w * 0.5 + 0.5;
    vec3 n = normalize(mat3(u_inv_view) * ((hit - v_center) / v_radius));
    vec3 p = (u_inv_view * vec4(hit, 1.0)).xyz;
    // a faint band around the body's x = 0 great circle shows the sphere rolling
    vec3 local = rotate_inv(v_quat, n);
    float band = smoothstep(0.07, 0.10, abs(local.x));
    vec3 albedo = v_color * mix(0.84, 1.0, band);
    f_color = vec4(dither(to_srgb(tonemap(shade(albedo, p, n, 48.0, 0.35)))), u_coverage < 0.5 ? 1.0 : alpha);
}
"""
)

# the rotation of a vector by a unit quaternion, shared by the vertex shaders of meshes
ROTATE = """
vec3 rotate(vec4 q, vec3 v) {  // rotate by unit quaternion q = (x, y, z, w)
    vec3 t = 2.0 * cross(q.xyz, v);
    return v + q.w * t + cross(q.xyz, t);
}
"""

BOX_VERTEX = (
    """
#version 330
in vec3 in_position;
in vec3 in_normal;
in vec3 in_center;
in vec4 in_quat;
in vec3 in_half;
in vec3 in_color;
uniform mat4 u_vp;
out vec3 v_world;
out vec3 v_normal;
out vec3 v_local;
flat out vec3 v_half;
flat out vec3 v_color;
"""
    + ROTATE
    + """
void main() {
    v_local = in_position * in_half;
    v_half = in_half;
    v_world = in_center + rotate(in_quat, v_local);
    v_normal = rotate(in_quat, in_normal);
    v_color = in_color;
    gl_Position = u_vp * vec4(v_world, 1.0);
}
"""
)

BOX_FRAGMENT = (
    """
#version 330
in vec3 v_world;
in vec3 v_normal;
in vec3 v_local;
flat in vec3 v_half;
flat in vec3 v_color;
out vec4 f_color;
"""
    + COMMON
    + """
void main() {
    // distance to the nearest edge within this face: the middle one of the three distances
    // to the faces (the smallest is ~0, the face the fragment lies on)
    vec3 e = v_half - abs(v_local);
    float edge = e.x + e.y + e.z - min(e.x, min(e.y, e.z)) - max(e.x, max(e.y, e.z));
    float width = 0.06 * min(v_half.x, min(v_half.y, v_half.z));
    float aa = fwidth(edge);
    float rim = smoothstep(width - aa, width + aa, edge);
    vec3 albedo = v_color * mix(0.72, 1.0, rim);
    vec3 n = normalize(v_normal);
    f_color = vec4(dither(to_srgb(tonemap(shade(albedo, v_world, n, 32.0, 0.12)))), 1.0);
}
"""
)

CLOTH_VERTEX = """
#version 330
in vec3 in_position;
in vec3 in_normal;
uniform mat4 u_vp;
out vec3 v_world;
out vec3 v_normal;
void main() {
    v_world = in_position;
    v_normal = in_normal;
    gl_Position = u_vp * vec4(in_position, 1.0);
}
"""

CLOTH_FRAGMENT = (
    """
#version 330
in vec3 v_world;
in vec3 v_normal;
uniform vec3 u_front;
uniform vec3 u_back;
out vec4 f_color;
"""
    + COMMON
    + """
// the cloth's sun shadow, blurred: 5 x 5 taps two texels apart, looked up a centimetre towards
// the sun (a crumpled cloth shadows itself along every wrinkle; sharp, those edges are jagged blotches)
float cloth_sun_visibility(vec3 p) {
    if (u_shadow_on < 0.5) return 1.0;
    vec4 c = u_light_vp * vec4(p + u_light_dir * 0.01, 1.0);
    vec3 s = c.xyz / c.w * 0.5 + 0.5;
    if (s.x <= 0.0 || s.x >= 1.0 || s.y <= 0.0 || s.y >= 1.0 || s.z >= 1.0) return 1.0;
    vec2 texel = 2.0 / vec2(textureSize(u_shadow_map, 0));
    float lit = 0.0;
    for (int i = -2; i <= 2; i++) {
        for (int j = -2; j <= 2; j++) {
            lit += (s.z - 0.002 <= texture(u_shadow_map, s.xy + vec2(i, j) * texel).r) ? 1.0 : 0.0;
        }
    }
    return lit / 25.0;
}

void main() {
    // two-sided: the back face uses the flipped normal and a lighter tint
    vec3 n = normalize(v_normal);
    vec3 albedo = u_front;
    if (!gl_FrontFacing) { n = -n; albedo = u_back; }
    vec3 a = to_linear(albedo);
    float ndl = dot(n, u_light_dir);
    // fabric has a soft terminator ("wrap" lighting: (n.l + w) / (1 + w), w = 0.4), and thin
    // cloth in its own shadow still gets some light through: a wrinkle's far side is a shade, not a hole
    float diffuse = max((ndl + 0.4) / 1.4, 0.0);
    float vis = mix(0.45, 1.0, cloth_sun_visibility(v_world));
    float up = dot(n, u_up) * 0.5 + 0.5;
    vec3 ambient = mix(vec3(0.09, 0.08, 0.07), vec3(0.26, 0.29, 0.35), up);
    float through = 0.35 * max(-ndl, 0.0);
    vec3 c = a * (SUN * (diffuse * vis + through) + ambient);
    vec3 h = normalize(u_light_dir + normalize(u_eye - v_world));
    c += SUN * (0.05 * pow(max(dot(n, h), 0.0), 12.0) * vis * step(0.0, ndl));
    f_color = vec4(dither(to_srgb(tonemap(c))), 1.0);
}
"""
)

# convex hulls and static meshes: triangles in a body's frame, placed per instance
SOLID_VERTEX = (
    """
#version 330
in vec3 in_position;
in vec3 in_normal;
in vec3 in_center;
in vec4 in_quat;
in vec3 in_color;
uniform mat4 u_vp;
out vec3 v_world;
out vec3 v_normal;
flat out vec3 v_color;
"""
    + ROTATE
    + """
void main() {
    v_world = in_center + rotate(in_quat, in_position);
    v_normal = rotate(in_quat, in_normal);
    v_color = in_color;
    gl_Position = u_vp * vec4(v_world, 1.0);
}
"""
)

# capsules: impostors. Each capsule draws the back faces of its bounding box (half extents
# (r, r, a + r) in its frame) and the fragment shader casts the pixel's ray against the capsule in
# the capsule's frame (exact silhouette and depth at any size, a dozen triangles per capsule). The
# same program family draws the shadow pass, where the rays are parallel (the sun): then the ray
# origin, a point on the sun's side of the box, varies linearly over the box and is interpolated.
CAPSULE_VERTEX = (
    """
#version 330
in vec3 in_position;   // corner of the cube [-1, 1]^3
in vec3 in_center;
in vec4 in_quat;
in float in_radius;
in float in_half;
in vec3 in_color;
uniform mat4 u_clip;       // world -> clip of this pass
uniform vec3 u_eye;        // perspective pass: the eye (world)
uniform vec3 u_ray_dir;    // parallel pass (the sun's): the rays' direction (world), else zero
out vec3 v_local;
out vec3 v_origin;
flat out vec3 v_center;
flat out vec4 v_quat;
flat out float v_radius;
flat out float v_half;
flat out vec3 v_color;
"""
    + ROTATE
    + """
vec3 rotate_inv(vec4 q, vec3 v) { return rotate(vec4(-q.xyz, q.w), v); }
void main() {
    v_local = in_position * vec3(in_radius, in_radius, in_half + in_radius) * 1.01;
    v_center = in_center;
    v_quat = in_quat;
    v_radius = in_radius;
    v_half = in_half;
    v_color = in_color;
    if (dot(u_ray_dir, u_ray_dir) > 0.0) {
        v_origin = v_local - rotate_inv(in_quat, u_ray_dir) * 4.0 * (in_half + in_radius);
    } else {
        v_origin = rotate_inv(in_quat, u_eye - in_center);
    }
    gl_Position = u_clip * vec4(in_center + rotate(in_quat, v_local), 1.0);
}
"""
)

# distance along the unit ray o + t d to the capsule of half length a and radius r along z, or -1.
# Every point of the two end spheres lies inside the infinite cylinder, so the ray's entry into the
# cylinder, where |z| <= a, is the first hit; elsewhere it is the nearer entry into an end sphere
CAPSULE_RAY = """
float capsule_ray(vec3 o, vec3 d, float a, float r) {
    float A = dot(d.xy, d.xy);
    if (A > 1e-12) {
        float B = dot(o.xy, d.xy);
        float h = B * B - A * (dot(o.xy, o.xy) - r * r);
        if (h < 0.0) return -1.0;
        float t = (-B - sqrt(h)) / A;
        if (abs(o.z + t * d.z) <= a) return t;
    }
    float best = -1.0;
    for (int k = 0; k < 2; k++) {
        vec3 oc = o - vec3(0.0, 0.0, k == 0 ? a : -a);
        float b = dot(oc, d);
        float h = b * b - (dot(oc, oc) - r * r);
        if (h >= 0.0) {
            float t = -b - sqrt(h);
            if (t > 0.0 && (best < 0.0 || t < best)) best = t;
        }
    }
    return best;
}
"""

CAPSULE_FRAGMENT_HEAD = """
#version 330
in vec3 v_local;
in vec3 v_origin;
flat in vec3 v_center;
flat in vec4 v_quat;
flat in float v_radius;
flat in float v_half;
flat in vec3 v_color;
uniform mat4 u_clip;
"""

CAPSULE_HIT = (
    ROTATE
    + CAPSULE_RAY
    + """
// the ray's hit in the capsule's frame, its world point and the depth written; false on a miss
bool capsule_hit(out vec3 hit, out vec3 world) {
    vec3 d = normalize(v_local - v_origin);
    float t = capsule_ray(v_origin, d, v_half, v_radius);
    if (t < 0.0) return false;
    hit = v_origin + t * d;
    world = v_center + rotate(v_quat, hit);
    vec4 clip = u_clip * vec4(world, 1.0);
    gl_FragDepth = clip.z / clip.w * 0.5 + 0.5;
    return true;
}
"""
)

CAPSULE_FRAGMENT = (
    CAPSULE_FRAGMENT_HEAD
    + """
uniform float u_alpha;   // 1: opaque; the joint overlay's hidden parts are drawn faint
out vec4 f_color;
"""
    + COMMON
    + CAPSULE_HIT
    + """
void main() {
    vec3 hit, p;
    if (!capsule_hit(hit, p)) discard;
    vec3 n = rotate(v_quat, (hit - vec3(0.0, 0.0, clamp(hit.z, -v_half, v_half))) / v_radius);
    f_color = vec4(dither(to_srgb(tonemap(shade(v_color, p, normalize(n), 32.0, 0.15)))), u_alpha);
}
"""
)

SHADOW_CAPSULE_FRAGMENT = (
    CAPSULE_FRAGMENT_HEAD
    + CAPSULE_HIT
    + """
void main() {
    vec3 hit, p;
    if (!capsule_hit(hit, p)) discard;
}
"""
)

SOLID_FRAGMENT = (
    """
#version 330
in vec3 v_world;
in vec3 v_normal;
flat in vec3 v_color;
uniform float u_alpha;   // 1: opaque; the joint overlay's hidden parts are drawn faint
out vec4 f_color;
"""
    + COMMON
    + """
void main() {
    // two-sided: an open mesh (terrain) seen from below is lit as its underside
    vec3 n = normalize(v_normal);
    if (!gl_FrontFacing) n = -n;
    f_color = vec4(dither(to_srgb(tonemap(shade(v_color, v_world, n, 32.0, 0.15)))), u_alpha);
}
"""
)

SHADOW_SOLID_VERTEX = (
    """
#version 330
in vec3 in_position;
in vec3 in_center;
in vec4 in_quat;
uniform mat4 u_light_vp;
"""
    + ROTATE
    + """
void main() {
    gl_Position = u_light_vp * vec4(in_center + rotate(in_quat, in_position), 1.0);
}
"""
)

# sun shadow map passes: depth only
SHADOW_SPHERE_VERTEX = """
#version 330
in vec2 in_corner;
in vec3 in_center;
in float in_radius;
uniform mat4 u_light_vp;
uniform vec3 u_light_right;
uniform vec3 u_light_up;
out vec2 v_corner;
flat out float v_radius;
flat out vec3 v_center;
void main() {
    // orthographic sun: a quad of half-size r facing the sun covers the sphere's shadow
    vec3 p = in_center + (in_corner.x * u_light_right + in_corner.y * u_light_up) * in_radius;
    v_corner = in_corner;
    v_radius = in_radius;
    v_center = in_center;
    gl_Position = u_light_vp * vec4(p, 1.0);
}
"""

SHADOW_SPHERE_FRAGMENT = """
#version 330
in vec2 v_corner;
flat in float v_radius;
flat in vec3 v_center;
uniform mat4 u_light_vp;
uniform vec3 u_light_dir;
void main() {
    float q = dot(v_corner, v_corner);
    if (q > 1.0) discard;
    // the sphere's surface nearest the sun along this texel's ray (orthographic: only the
    // distance along the sun direction matters for depth)
    vec4 c = u_light_vp * vec4(v_center + u_light_dir * v_radius * sqrt(1.0 - q), 1.0);
    gl_FragDepth = c.z / c.w * 0.5 + 0.5;
}
"""

SHADOW_MESH_VERTEX = """
#version 330
in vec3 in_position;
uniform mat4 u_light_vp;
void main() {
    gl_Position = u_light_vp * vec4(in_position, 1.0);
}
"""

SHADOW_BOX_VERTEX = (
    """
#version 330
in vec3 in_position;
in vec3 in_center;
in vec4 in_quat;
in vec3 in_half;
uniform mat4 u_light_vp;
"""
    + ROTATE
    + """
void main() {
    gl_Position = u_light_vp * vec4(in_center + rotate(in_quat, in_position * in_half), 1.0);
}
"""
)

EMPTY_FRAGMENT = """
#version 330
void main() {}
"""
