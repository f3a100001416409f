// pbrt-v4's measured material (RGL's tabulated BRDFs) on the device: f, the pdf and a
// sample, in the local frame (z the normal), from a material packed into the texel buffer
// at `base` (src/measured.rs, MeasuredBsdf::pack). CPU mirror and documentation:
// src/measured.rs, line for line.
#ifndef MEASURED_GLSL
#define MEASURED_GLSL
#include "plinear2d.glsl"

const float MEASURED_PI = 3.14159265358979323846;

float measured_theta_to_u(float theta) { return sqrt(max(theta * (2.0 / MEASURED_PI), 0.0)); }
float measured_u_to_theta(float u) { return u * u * (MEASURED_PI / 2.0); }
float measured_phi_to_u(float phi) { return (phi + MEASURED_PI) * (0.5 / MEASURED_PI); }
float measured_u_to_phi(float u) { return (2.0 * u - 1.0) * MEASURED_PI; }

// The elevation of a unit vector, accurate near the normal.
float measured_elevation(vec3 d) {
    float dist = sqrt(d.x * d.x + d.y * d.y + (d.z - 1.0) * (d.z - 1.0));
    return 2.0 * asin(clamp(0.5 * dist, -1.0, 1.0));
}

float measured_azimuth(vec3 d) { return d.x == 0.0 && d.y == 0.0 ? 0.0 : atan(d.y, d.x); }

Plinear measured_table(uint base, uint k) { return plinear_at(base, plin_word(base + 2u + k)); }

// h's warped coordinates seen from wo (azimuth phi_o).
vec2 measured_warp_h(uint base, vec3 h, float phi_o) {
    bool isotropic = plin_word(base) != 0u;
    float y = measured_phi_to_u(measured_azimuth(h) - (isotropic ? phi_o : 0.0));
    return vec2(measured_theta_to_u(measured_elevation(h)), y - floor(y));
}

// The reflectance at the luminance-space point u, times D / (4 sigma) with the file's
// jacobian flag, over cos(theta_i).
vec3 measured_value(uint base, vec2 u, vec2 u_h, vec2 params, vec3 wi) {
    Plinear rgb = measured_table(base, 4u);
    vec3 r;
    [[dont_unroll]] for (uint c = 0u; c < 3u; ++c) r[c] = plinear_eval(rgb, u, vec3(params, float(c)));
    vec3 f = max(r, vec3(0.0)) / abs(wi.z);
    if (plin_word(base + 1u) != 0u) {
        vec2 u_o = vec2(measured_theta_to_u(params.y), measured_phi_to_u(params.x));
        float sigma = plinear_eval(measured_table(base, 1u), u_o, vec3(0.0));
        f *= sigma > 0.0 ? plinear_eval(measured_table(base, 0u), u_h, vec3(0.0)) / (4.0 * sigma) : 0.0;
    }
    return f;
}

// The Jacobian from the warped square to wi: h's solid angle times 4 (wo . h).
float measured_to_solid_angle(vec2 u_h, float wo_dot_h) {
    float theta = measured_u_to_theta(u_h.x);
    return max(2.0 * MEASURED_PI * MEASURED_PI * u_h.x * sin(theta), 1e-6) * 4.0 * abs(wo_dot_h);
}

vec3 measured_eval(uint base, vec3 wo, vec3 wi) {
    if (wo.z * wi.z <= 0.0) return vec3(0.0);
    if (wo.z < 0.0) {
        wo = -wo;
        wi = -wi;
    }
    vec3 h = wo + wi;
    if (dot(h, h) == 0.0) return vec3(0.0);
    h = normalize(h);
    vec2 params = vec2(measured_azimuth(wo), measured_elevation(wo));
    vec2 u_h = measured_warp_h(base, h, params.x);
    float pdf;
    vec2 u = plinear_invert(measured_table(base, 2u), u_h, vec3(params, 0.0), pdf);
    return measured_value(base, u, u_h, params, wi);
}

float measured_pdf(uint base, vec3 wo, vec3 wi) {
    if (wo.z * wi.z <= 0.0) return 0.0;
    if (wo.z < 0.0) {
        wo = -wo;
        wi = -wi;
    }
    vec3 h = wo + wi;
    if (dot(h, h) == 0.0) return 0.0;
    h = normalize(h);
    vec2 params = vec2(measured_azimuth(wo), measured_elevation(wo));
    vec2 u_h = measured_warp_h(base, h, params.x);
    float vndf_pdf;
    vec2 u = plinear_invert(measured_table(base, 2u), u_h, vec3(params, 0.0), vndf_pdf);
    return vndf_pdf * plinear_eval(measured_table(base, 3u), u, vec3(params, 0.0))
         / measured_to_solid_angle(u_h, dot(wo, h));
}

// wi drawn for wo with the numbers u, its f and pdf; false for no sample.
bool measured_sample(uint base, vec3 wo, vec2 u, out vec3 wi, out vec3 f, out float pdf) {
    wi = vec3(0.0);
    f = vec3(0.0);
    pdf = 0.0;
    bool flip = wo.z <= 0.0;
    if (flip) wo = -wo;
    vec2 params = vec2(measured_azimuth(wo), measured_elevation(wo));
    float lum_pdf, vndf_pdf;
    vec2 u1 = plinear_sample(measured_table(base, 3u), u, vec3(params, 0.0), lum_pdf);
    vec2 u_h = plinear_sample(measured_table(base, 2u), u1, vec3(params, 0.0), vndf_pdf);
    bool isotropic = plin_word(base) != 0u;
    float phi = measured_u_to_phi(u_h.y) + (isotropic ? params.x : 0.0);
    float theta = measured_u_to_theta(u_h.x);
    vec3 h = vec3(sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
    wi = 2.0 * dot(wo, h) * h - wo;
    if (!(wi.z > 0.0)) return false;
    pdf = vndf_pdf * lum_pdf / measured_to_solid_angle(u_h, dot(wo, h));
    f = measured_value(base, u1, u_h, params, wi);
    if (!(pdf > 0.0)) return false;
    if (flip) wi = -wi;
    return true;
}
#endif
