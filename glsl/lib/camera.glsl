// The camera: a pinhole, or a thin lens (pbrt-v4's perspective camera with lensradius
// and focaldistance). The film is the rectangle scene.cam_window (x0, x1 along cam_right,
// y0, y1 along cam_up) on the plane at distance 1 ahead of the eye, so that a screen
// window or a crop window is only another rectangle. Film position (0,0) is its top-left
// corner, pixel (0,0) the top-left pixel. Mirrored on the CPU by `camera_ray` in
// src/gpu_scene.rs.
#ifndef CAMERA_GLSL
#define CAMERA_GLSL
#include "bindings.glsl"
#include "sampling.glsl"
#include "rng.glsl"
#include "features.glsl"

// pbrt-v4's realistic camera: a lens system (src/scene/lens.rs, whose LensSystem is the
// CPU mirror; the path tracers only, the host refuses it to BDPT and MMLT).
bool camera_is_realistic() { return has_feature(FEATURE_REALISTIC_CAMERA) && scene.lens != NO_TEXTURE; }

// A thin lens and a lens system draw two numbers per camera ray (and a thin lens per
// t = 1 connection); a pinhole none (so that pinhole renders keep the numbers they had).
bool camera_has_lens() { return scene.lens_radius > 0.0 || camera_is_realistic(); }

// The ray o + t d meets the sphere of signed radius `radius` centred on the axis at z =
// `center` on the cap that holds the interface's vertex, at t, with the unit normal n
// facing back along the ray (lens.rs intersect_interface).
bool lens_interface(vec3 o, vec3 d, float radius, float center, out float t, out vec3 n) {
    vec3 oc = o - vec3(0.0, 0.0, center);
    float a = dot(d, d);
    float b = 2.0 * dot(d, oc);
    float c = dot(oc, oc) - radius * radius;
    float disc = b * b - 4.0 * a * c;
    t = 0.0;
    n = vec3(0.0, 0.0, 1.0);
    if (disc < 0.0) return false;
    float root = sqrt(disc);
    float q = b < 0.0 ? -0.5 * (b - root) : -0.5 * (b + root);
    float t0 = q / a;
    float t1 = c / q;
    if (t0 > t1) {
        float s = t0;
        t0 = t1;
        t1 = s;
    }
    bool closer = (d.z > 0.0) != (radius < 0.0);
    t = closer ? t0 : t1;
    if (!(t >= 0.0)) return false;
    n = normalize(oc + t * d);
    if (dot(n, d) > 0.0) n = -n;
    return true;
}

// A realistic camera's ray through the film position `film` for the numbers u (the exit
// pupil's point): its weight cos^4 theta / (p d^2), 0 where the lens stops it (lens.rs
// LensSystem::camera_ray, in camera space; here taken on to the world).
float realistic_camera_ray(vec2 film, vec2 u, out vec3 o, out vec3 d) {
    uint base = scene.lens;
    vec2 half_film = vec2(texel(base), texel(base + 1u));
    float rear = texel(base + 2u);
    uint count = uint(texel(base + 3u));
    o = scene.cam_eye.xyz;
    d = scene.cam_forward.xyz;
    vec2 f = -half_film + 2.0 * half_film * film;
    vec3 p_film = vec3(-f.x, f.y, 0.0);
    float r = length(p_film.xy);
    uint interval = min(uint(r / length(half_film) * float(LENS_PUPIL_INTERVALS)), LENS_PUPIL_INTERVALS - 1u);
    uint pb = base + 4u + 4u * count + 4u * interval;
    vec4 b = vec4(texel(pb), texel(pb + 1u), texel(pb + 2u), texel(pb + 3u));
    if (!(b.x < b.z && b.y < b.w)) return 0.0;
    vec2 q = vec2(b.x + (b.z - b.x) * u.x, b.y + (b.w - b.y) * u.y);
    float pdf = 1.0 / ((b.z - b.x) * (b.w - b.y));
    float sn = r > 0.0 ? p_film.y / r : 0.0;
    float cs = r > 0.0 ? p_film.x / r : 1.0;
    vec3 dir = vec3(cs * q.x - sn * q.y, sn * q.x + cs * q.y, rear) - p_film;
    // Through the interfaces, rear to front, in lens space (z negated).
    vec3 lo = p_film * vec3(1.0, 1.0, -1.0);
    vec3 ld = dir * vec3(1.0, 1.0, -1.0);
    float z = 0.0;
    for (uint k = count; k > 0u; --k) {
        uint e = base + 4u + 4u * (k - 1u);
        float radius = texel(e);
        float aperture = texel(e + 3u);
        z -= texel(e + 1u);
        float t;
        vec3 n;
        if (radius == 0.0) {
            if (ld.z >= 0.0) return 0.0;
            t = (z - lo.z) / ld.z;
        } else if (!lens_interface(lo, ld, radius, z + radius, t, n)) {
            return 0.0;
        }
        lo += t * ld;
        if (dot(lo.xy, lo.xy) > aperture * aperture) return 0.0;
        if (radius != 0.0) {
            float eta = texel(e + 2u);
            float eta_i = eta != 0.0 ? eta : 1.0;
            float before = k > 1u ? texel(e - 2u) : 0.0;   // (the interface ahead's eta)
            float eta_t = before != 0.0 ? before : 1.0;
            float rel = eta_t / eta_i;
            vec3 wi = -normalize(ld);
            float cos_i = dot(n, wi);
            float sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (rel * rel);
            if (sin2_t >= 1.0) return 0.0;
            ld = -wi / rel + (cos_i / rel - sqrt(1.0 - sin2_t)) * n;
        }
    }
    // Back to camera space (x right, y up, z ahead), then to the world.
    vec3 co = lo * vec3(1.0, 1.0, -1.0);
    vec3 cd = normalize(ld * vec3(1.0, 1.0, -1.0));
    vec3 right = scene.cam_right.xyz;
    vec3 up = scene.cam_up.xyz;
    vec3 ahead = scene.cam_forward.xyz;
    o = scene.cam_eye.xyz + co.x * right + co.y * up + co.z * ahead;
    d = normalize(cd.x * right + cd.y * up + cd.z * ahead);
    float cos_theta = normalize(dir).z;
    float c2 = cos_theta * cos_theta;
    return c2 * c2 / (pdf * rear * rear);
}

// The direction from the eye through the film position `film` in [0,1)^2, scaled so that
// its component along the view direction is 1.
vec3 camera_film_direction(vec2 film) {
    float sx = mix(scene.cam_window.x, scene.cam_window.y, film.x);
    float sy = mix(scene.cam_window.w, scene.cam_window.z, film.y);
    return scene.cam_forward.xyz + sx * scene.cam_right.xyz + sy * scene.cam_up.xyz;
}

// The point of the lens for the numbers u (uniform over its disk); the eye for a pinhole.
vec3 camera_lens_point(vec2 u) {
    if (!camera_has_lens()) return scene.cam_eye.xyz;
    vec2 d = scene.lens_radius * sample_uniform_disk_concentric(u);
    return scene.cam_eye.xyz + d.x * scene.cam_right.xyz + d.y * scene.cam_up.xyz;
}

// The ray through the film position `film` from the lens point for u_lens: every ray of
// a film point meets at its point on the plane of focus. Returns the ray's weight: 1,
// but for a realistic camera's (0: no ray).
float camera_ray(vec2 film, vec2 u_lens, out vec3 o, out vec3 d) {
    if (camera_is_realistic()) return realistic_camera_ray(film, u_lens, o, d);
    vec3 dir = camera_film_direction(film);
    if (!camera_has_lens()) {
        o = scene.cam_eye.xyz;
        d = normalize(dir);
        return 1.0;
    }
    vec3 focus = scene.cam_eye.xyz + scene.focal_distance * dir;
    o = camera_lens_point(u_lens);
    d = normalize(focus - o);
    return 1.0;
}

vec2 camera_pixel_film(uvec2 pixel, vec2 u) {
    return (vec2(pixel) + u) / vec2(uvec2(scene.width, scene.height));
}

// Where the point p, seen from the lens point `eye` (camera_lens_point), lands on the
// film. False when it is behind the camera or off the film. to_eye and dist: the unit
// direction from p to `eye` and the distance.
bool camera_project(vec3 p, vec3 eye, out uvec2 pixel, out vec3 to_eye, out float dist) {
    vec3 d = p - eye;
    dist = length(d);
    pixel = uvec2(0u);
    to_eye = vec3(0.0);
    if (!(dist > 0.0)) return false;
    vec3 w = d / dist;
    to_eye = -w;
    float c = dot(w, scene.cam_forward.xyz);
    if (!(c > 0.0)) return false;
    // The film point whose rays pass through p: through the eye for a pinhole, through
    // the point where this ray meets the plane of focus for a lens.
    vec3 q = camera_has_lens() ? eye + w * (scene.focal_distance / c) - scene.cam_eye.xyz : w;
    float cq = dot(q, scene.cam_forward.xyz);
    if (!(cq > 0.0)) return false;
    float sx = dot(q, scene.cam_right.xyz) / cq;
    float sy = dot(q, scene.cam_up.xyz) / cq;
    vec2 film = vec2((sx - scene.cam_window.x) / (scene.cam_window.y - scene.cam_window.x),
                     (scene.cam_window.w - sy) / (scene.cam_window.w - scene.cam_window.z));
    if (!(film.x >= 0.0 && film.x < 1.0 && film.y >= 0.0 && film.y < 1.0)) return false;
    pixel = min(uvec2(film * vec2(uvec2(scene.width, scene.height))), uvec2(scene.width, scene.height) - 1u);
    return true;
}
// A camera ray through the pixel for the path tracers: two numbers of rng over the
// pixel, two over a lens. Returns its weight (camera_ray).
float camera_sample(uvec2 pixel, inout Rng rng, out vec3 o, out vec3 d) {
    vec2 u_pixel = rng_next2(rng);
    vec2 u_lens = vec2(0.0);
    if (camera_has_lens()) u_lens = rng_next2(rng);
    return camera_ray(camera_pixel_film(pixel, u_pixel), u_lens, o, d);
}
#endif
