// Pinhole camera: rays through pixels, and (for light tracing) points back to pixels.
// Pixel (0,0) is the top-left; u jitters uniformly over the pixel.
#ifndef CAMERA_GLSL
#define CAMERA_GLSL
#include "bindings.glsl"
// The ray through the film position `film` in [0,1)^2 ((0,0) the top-left corner).
vec3 camera_ray_direction_film(vec2 film) {
    float tan_half = scene.cam_eye.w;
    float aspect = scene.cam_right.w;
    float sx = (2.0 * film.x - 1.0) * tan_half * aspect;
    float sy = (1.0 - 2.0 * film.y) * tan_half;
    return normalize(scene.cam_forward.xyz + sx * scene.cam_right.xyz + sy * scene.cam_up.xyz);
}

vec3 camera_ray_direction(uvec2 pixel, vec2 u) {
    return camera_ray_direction_film((vec2(pixel) + u) / vec2(uvec2(scene.width, scene.height)));
}

// Where the point p lands on the film. False when it is behind the camera or off the film.
bool camera_project(vec3 p, out uvec2 pixel, out vec3 to_eye, out float dist) {
    vec3 d = p - scene.cam_eye.xyz;
    dist = length(d);
    pixel = uvec2(0u);
    to_eye = vec3(0.0);
    if (!(dist > 0.0)) return false;
    vec3 w = d / dist;
    to_eye = -w;
    float c = dot(w, scene.cam_forward.xyz);
    if (!(c > 0.0)) return false;
    float tan_half = scene.cam_eye.w;
    float sx = dot(w, scene.cam_right.xyz) / (c * tan_half * scene.cam_right.w);
    float sy = dot(w, scene.cam_up.xyz) / (c * tan_half);
    vec2 film = vec2(0.5 * (sx + 1.0), 0.5 * (1.0 - sy));
    if (!(film.x >= 0.0 && film.x < 1.0 && film.y >= 0.0 && film.y < 1.0)) return false;
    pixel = min(uvec2(film * vec2(uvec2(scene.width, scene.height))), uvec2(scene.width, scene.height) - 1u);
    return true;
}
#endif
