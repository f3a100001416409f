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

// A thin lens draws two numbers per camera ray and per t = 1 connection; a pinhole none
// (so that pinhole renders keep the numbers they had).
bool camera_has_lens() { return scene.lens_radius > 0.0; }

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
// a film point meets at its point on the plane of focus.
void camera_ray(vec2 film, vec2 u_lens, out vec3 o, out vec3 d) {
    vec3 dir = camera_film_direction(film);
    if (!camera_has_lens()) {
        o = scene.cam_eye.xyz;
        d = normalize(dir);
        return;
    }
    vec3 focus = scene.cam_eye.xyz + scene.focal_distance * dir;
    o = camera_lens_point(u_lens);
    d = normalize(focus - o);
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
// pixel, two over a thin lens.
void camera_sample(uvec2 pixel, inout Rng rng, out vec3 o, out vec3 d) {
    vec2 u_pixel = rng_next2(rng);
    vec2 u_lens = vec2(0.0);
    if (camera_has_lens()) u_lens = rng_next2(rng);
    camera_ray(camera_pixel_film(pixel, u_pixel), u_lens, o, d);
}
#endif
