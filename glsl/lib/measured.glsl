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

// The Jacobian from the warped square to wi: h's solid angle times 4 (wo . h).
float measured_to_solid_angle(vec2 u_h, float wo_dot_h) {
    float theta = measured_u_to_theta(u_h.x);
    return max(2.0 * MEASURED_PI * MEASURED_PI * u_h.x * sin(theta), 1e-6) * 4.0 * abs(wo_dot_h);
}

// Every question about the material in one body, so that a kernel inlines its tables'
// code once per call site: with `draw`, wi drawn for wo with the numbers u (false for no
// sample); else for the given wi. Either way f(wo, wi) and the density with which a draw
// gives wi. (The mirror's eval, pdf and sample, src/measured.rs.)
bool measured_query(uint base, vec3 wo, bool draw, vec2 u, inout vec3 wi, out vec3 f, out float pdf) {
    f = vec3(0.0);
    pdf = 0.0;
    if (!draw && wo.z * wi.z <= 0.0) return false;
    bool flip = draw ? wo.z <= 0.0 : wo.z < 0.0;
    if (flip) {
        wo = -wo;
        wi = -wi;
    }
    vec2 params = vec2(measured_azimuth(wo), measured_elevation(wo));
    bool isotropic = plin_word(base) != 0u;
    vec2 u1, u_h;
    float lum_pdf = 0.0, vndf_pdf = 0.0;
    vec3 h;
    if (draw) {
        // The luminance's table draws u1 from u, the VNDF's u_h from u1 (one call site).
        vec2 x = u;
        [[dont_unroll]] for (uint k = 0u; k < 2u; ++k) {
            float p;
            x = plinear_sample(measured_table(base, 3u - k), x, vec3(params, 0.0), p);
            if (k == 0u) {
                u1 = x;
                lum_pdf = p;
            } else {
                vndf_pdf = p;
            }
        }
        u_h = x;
        float phi = measured_u_to_phi(u_h.y) + (isotropic ? params.x : 0.0);
        float theta = measured_u_to_theta(u_h.x);
        h = vec3(sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
        wi = 2.0 * dot(wo, h) * h - wo;
        if (!(wi.z > 0.0)) {
            wi = vec3(0.0);
            return false;
        }
    } else {
        h = wo + wi;
        if (dot(h, h) == 0.0) return false;
        h = normalize(h);
        float y = measured_phi_to_u(measured_azimuth(h) - (isotropic ? params.x : 0.0));
        u_h = vec2(measured_theta_to_u(measured_elevation(h)), y - floor(y));
        u1 = plinear_invert(measured_table(base, 2u), u_h, vec3(params, 0.0), vndf_pdf);
    }
    // The tables' values (one call site): the luminance at u1 (its density, for a given
    // wi), the reflectance's three channels at u1 and, with the file's jacobian flag, the
    // NDF at u_h and sigma at wo.
    bool jacobian = plin_word(base + 1u) != 0u;
    vec3 r;
    float ndf = 0.0, sigma = 0.0;
    vec2 u_o = vec2(measured_theta_to_u(params.y), measured_phi_to_u(params.x));
    [[dont_unroll]] for (uint k = draw ? 1u : 0u; k < (jacobian ? 6u : 4u); ++k) {
        // k: 0 luminance, 1-3 reflectance, 4 sigma, 5 NDF.
        uint table = k == 0u ? 3u : k < 4u ? 4u : k == 4u ? 1u : 0u;
        vec2 pos = k < 4u ? u1 : k == 4u ? u_o : u_h;
        vec3 p = k < 4u ? vec3(params, float(max(k, 1u) - 1u)) : vec3(0.0);
        float x = plinear_eval(measured_table(base, table), pos, p);
        if (k == 0u) {
            lum_pdf = x;
        } else if (k < 4u) {
            r[k - 1u] = x;
        } else if (k == 4u) {
            sigma = x;
        } else {
            ndf = x;
        }
    }
    f = max(r, vec3(0.0)) / abs(wi.z);
    if (jacobian) f *= sigma > 0.0 ? ndf / (4.0 * sigma) : 0.0;
    pdf = vndf_pdf * lum_pdf / measured_to_solid_angle(u_h, dot(wo, h));
    if (flip) wi = -wi;
    return pdf > 0.0;
}

vec3 measured_eval(uint base, vec3 wo, vec3 wi) {
    vec3 f;
    float pdf;
    measured_query(base, wo, false, vec2(0.0), wi, f, pdf);
    return f;
}

float measured_pdf(uint base, vec3 wo, vec3 wi) {
    vec3 f;
    float pdf;
    measured_query(base, wo, false, vec2(0.0), wi, f, pdf);
    return pdf;
}

// wi drawn for wo with the numbers u, its f and pdf; false for no sample.
bool measured_sample(uint base, vec3 wo, vec2 u, out vec3 wi, out vec3 f, out float pdf) {
    wi = vec3(0.0);
    return measured_query(base, wo, true, u, wi, f, pdf);
}
#endif
