// Fresnel equations and the anisotropic Trowbridge-Reitz (GGX) microfacet distribution
// of the dielectric and conductor BSDFs (bsdf.glsl), following pbrt-v4 (pbr-book 4th
// ed., 9.3-9.6): exact dielectric and complex (conductor) Fresnel, the height-correlated
// Smith masking-shadowing term, and visible-normal sampling (Heitz 2018). Directions
// are in the local shading frame (z along the normal). CPU mirror: src/bsdf.rs
// (`microfacet`); keep in sync.
#ifndef MICROFACET_GLSL
#define MICROFACET_GLSL
#include "sampling.glsl"

// Alphas below this (in both directions) make a surface a perfect specular one (a delta
// lobe), as pbrt-v4's EffectivelySmooth.
const float MICROFACET_SMOOTH_ALPHA = 1e-3;

// Unpolarized Fresnel reflectance of a dielectric interface for the cosine cos_i of the
// incident direction with the normal and the relative index of refraction eta (the
// far side's over the near side's); a negative cosine comes from the far side.
float fr_dielectric(float cos_i, float eta) {
    cos_i = clamp(cos_i, -1.0, 1.0);
    if (cos_i < 0.0) {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    float sin2_i = 1.0 - cos_i * cos_i;
    float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.0) return 1.0;   // total internal reflection
    float cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    float r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_parl * r_parl + r_perp * r_perp);
}

// Complex numbers as vec2(re, im).
vec2 c_mul(vec2 a, vec2 b) { return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }
vec2 c_div(vec2 a, vec2 b) {
    float d = b.x * b.x + b.y * b.y;
    return vec2(a.x * b.x + a.y * b.y, a.y * b.x - a.x * b.y) / d;
}
vec2 c_sqrt(vec2 z) {
    float n = length(z);
    if (n == 0.0) return vec2(0.0);
    float t1 = sqrt(0.5 * (n + abs(z.x)));
    float t2 = 0.5 * z.y / t1;
    return z.x >= 0.0 ? vec2(t1, t2) : vec2(abs(t2), z.y < 0.0 ? -t1 : t1);
}

// Fresnel reflectance of a conductor with complex index eta + i k, for cos_i in [0, 1].
float fr_complex(float cos_i, vec2 eta) {
    cos_i = clamp(cos_i, 0.0, 1.0);
    float sin2_i = 1.0 - cos_i * cos_i;
    vec2 sin2_t = c_div(vec2(sin2_i, 0.0), c_mul(eta, eta));
    vec2 cos_t = c_sqrt(vec2(1.0, 0.0) - sin2_t);
    vec2 ci = vec2(cos_i, 0.0);
    vec2 r_parl = c_div(cos_i * eta - cos_t, cos_i * eta + cos_t);
    vec2 r_perp = c_div(ci - c_mul(eta, cos_t), ci + c_mul(eta, cos_t));
    return 0.5 * (dot(r_parl, r_parl) + dot(r_perp, r_perp));
}

vec3 fr_conductor(float cos_i, vec3 eta, vec3 k) {
    return vec3(fr_complex(cos_i, vec2(eta.x, k.x)), fr_complex(cos_i, vec2(eta.y, k.y)),
                fr_complex(cos_i, vec2(eta.z, k.z)));
}

// The distribution D(wm) of microfacet normals for alphas a (x along the tangent).
float tr_d(vec3 wm, vec2 a) {
    float cos2 = wm.z * wm.z;
    if (!(cos2 > 0.0)) return 0.0;
    float e = (wm.x * wm.x / (a.x * a.x) + wm.y * wm.y / (a.y * a.y)) / cos2;
    float f = 1.0 + e;
    return 1.0 / (PI * a.x * a.y * cos2 * cos2 * f * f);
}

// Smith's Lambda(w): the masked microfacet area per visible area, minus nothing.
float tr_lambda(vec3 w, vec2 a) {
    float cos2 = w.z * w.z;
    if (!(cos2 > 0.0)) return INF;
    float alpha2_tan2 = (a.x * a.x * w.x * w.x + a.y * a.y * w.y * w.y) / cos2;
    return 0.5 * (sqrt(1.0 + alpha2_tan2) - 1.0);
}

float tr_g1(vec3 w, vec2 a) { return 1.0 / (1.0 + tr_lambda(w, a)); }

// Height-correlated masking-shadowing of the pair.
float tr_g(vec3 wo, vec3 wi, vec2 a) { return 1.0 / (1.0 + tr_lambda(wo, a) + tr_lambda(wi, a)); }

// The distribution of normals visible from w: G1(w) / |cos w| D(wm) |w . wm|.
float tr_d_visible(vec3 w, vec3 wm, vec2 a) {
    return tr_g1(w, a) / abs(w.z) * tr_d(wm, a) * abs(dot(w, wm));
}

// A microfacet normal drawn from the distribution visible from w (Heitz 2018).
vec3 tr_sample_wm(vec3 w, vec2 u, vec2 a) {
    vec3 wh = normalize(vec3(a.x * w.x, a.y * w.y, w.z));
    if (wh.z < 0.0) wh = -wh;
    vec3 t1 = wh.z < 0.99999 ? normalize(cross(vec3(0.0, 0.0, 1.0), wh)) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(wh, t1);
    // A uniform point on the disk (polar), its y warped to the visible half.
    float r = sqrt(u.x);
    float theta = TWO_PI * u.y;
    vec2 p = vec2(r * cos(theta), r * sin(theta));
    float h = sqrt(max(1.0 - p.x * p.x, 0.0));
    float s = 0.5 * (1.0 + wh.z);
    p.y = (1.0 - s) * h + s * p.y;
    float pz = sqrt(max(0.0, 1.0 - dot(p, p)));
    vec3 nh = p.x * t1 + p.y * t2 + pz * wh;
    return normalize(vec3(a.x * nh.x, a.y * nh.y, max(1e-6, nh.z)));
}

// Refraction of w about the normal n (both unit, w on either side) for the relative
// index eta of the side n points away from: false on total internal reflection. etap is
// the relative index actually crossed (eta, or 1/eta from the far side).
bool refract_dir(vec3 w, vec3 n, float eta, out float etap, out vec3 wt) {
    float cos_i = dot(n, w);
    wt = vec3(0.0);
    etap = eta;
    if (cos_i < 0.0) {
        etap = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    float sin2_t = max(0.0, 1.0 - cos_i * cos_i) / (etap * etap);
    if (sin2_t >= 1.0) return false;
    float cos_t = sqrt(1.0 - sin2_t);
    wt = -w / etap + (cos_i / etap - cos_t) * n;
    return true;
}
#endif
