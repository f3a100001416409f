// Pinhole camera. Pixel (0,0) is the top-left; u jitters uniformly over the pixel.
#ifndef CAMERA_GLSL
#define CAMERA_GLSL
vec3 camera_ray_direction(uvec2 pixel, vec2 u) {
    float tan_half = scene.cam_eye.w;
    float aspect = scene.cam_right.w;
    vec2 film = (vec2(pixel) + u) / vec2(scene.dims.xy);
    float sx = (2.0 * film.x - 1.0) * tan_half * aspect;
    float sy = (1.0 - 2.0 * film.y) * tan_half;
    return normalize(scene.cam_forward.xyz + sx * scene.cam_right.xyz + sy * scene.cam_up.xyz);
}
#endif
