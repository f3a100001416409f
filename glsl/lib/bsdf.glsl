// The BSDFs (docs/scene-format.md, "Materials"): evaluation, sampling and the
// solid-angle pdf of each sampling mode. Include after sampling.glsl. Mirrored on the
// CPU by src/bsdf.rs, which the statistical tests exercise, and checked against that
// mirror on the device by glsl/bsdf_probe.comp; keep them in sync.
//
// A material reaches these functions as one BsdfParams (material_bsdf builds it from
// the material record), and the transport mode (TRANSPORT_RADIANCE on camera subpaths,
// TRANSPORT_IMPORTANCE on light subpaths) is an argument of evaluation and sampling:
// the BRDFs here are symmetric and ignore it; refraction will not.
//
// Conventions: wo toward the viewer, wi toward the light, n the unit shading normal,
// already flipped toward wo (dot(n, wo) >= 0; a slightly negative value from rounding is
// clamped to 0 where a cosine is needed). Surfaces are two-sided, nothing is transmitted:
// f = 0 and pdf = 0 for wi with dot(n, wi) <= 0, and a sampled wi below the surface is a
// failed sample. bsdf_eval returns f itself, not f * cos(theta_i).
//
// Degenerate parameters, the same rules in src/bsdf.rs:
// - avg(c) = max((c.r + c.g + c.b) / 3, 0), so negative colours never give negative
//   lobe probabilities.
// - Probability t of sampling the specular lobe in SAMPLE_BRDF mode, sum = avg(kd) + avg(ks):
//   Phong: t = sum > 0 ? avg(ks) / sum : 0 (all-black: cosine lobe).
//   GGX:   t = sum > 0 ? (avg(kd) > 0 ? max(0.25, avg(ks) / sum) : 1) : 0. The 0.25 floor
//          is there because Schlick's F reaches 1 at grazing angles even for ks = 0;
//          with kd == 0 the diffuse lobe is zero, so it is never sampled.
// - GGX alpha = max(roughness, BSDF_MIN_ALPHA) (1e-4) so D stays finite; f32 cannot
//   resolve such a sharp lobe anyway, so very small alphas are near-mirror approximations.
// - Phong exponent s = max(shininess, 0); max(0, r.wi)^s is 0 for r.wi <= 0 (pow(0, 0)
//   is undefined in GLSL).
#ifndef BSDF_GLSL
#define BSDF_GLSL
#include "bindings.glsl"
#include "sampling.glsl"

// One surface's BSDF parameters (the BSDF_* kinds and SAMPLE_* modes are in abi.h).
struct BsdfParams {
    uint kind;
    vec3 kd;
    vec3 ks;
    float shininess;
    float roughness;   // GGX alpha
};

BsdfParams material_bsdf(GpuMaterial m) {
    BsdfParams b;
    b.kind = m.info.x;
    b.kd = m.diffuse.xyz;
    b.ks = m.specular.xyz;
    b.shininess = m.roughness.x;
    b.roughness = m.roughness.y;
    return b;
}

// A sampled direction: wi, the BSDF value f(wo, wi), the pdf of the sampling mode (the
// full mixture's, as MIS needs) and the lobe it came from (BSDF_LOBE_*).
struct BsdfSample {
    vec3 wi;
    vec3 f;
    float pdf;
    uint flags;
};

const float BSDF_MIN_ALPHA = 1e-4;

float bsdf_avg(vec3 c) {
    return max((c.x + c.y + c.z) * (1.0 / 3.0), 0.0);
}

// Probability of picking the specular lobe in SAMPLE_BRDF mode (rules above).
float bsdf_specular_probability(BsdfParams b) {
    float d = bsdf_avg(b.kd);
    float s = bsdf_avg(b.ks);
    float sum = d + s;
    if (!(sum > 0.0)) return 0.0;
    if (b.kind == BSDF_GGX) return d > 0.0 ? max(0.25, s / sum) : 1.0;
    return s / sum;
}

float bsdf_ggx_alpha(float roughness) {
    return max(roughness, BSDF_MIN_ALPHA);
}

// GGX normal distribution (Walter et al. 2007, eq. 33) for cos(theta_h) = nh, a2 = alpha^2:
// a2 / (pi ((nh^2 (a2 - 1) + 1)^2), the bracket regrouped as nh^2 a2 + (1 - nh^2) so that
// a2 is not lost to cancellation when nh ~ 1.
float ggx_d(float nh, float a2) {
    float nh2 = nh * nh;
    float den = nh2 * a2 + max(1.0 - nh2, 0.0);
    return a2 / (PI * den * den);
}

// Smith G1(v) / (2 cos(theta_v)) for cos(theta_v) = c >= 0:
// G1 = 2 / (1 + sqrt(1 + a2 tan^2)) = 2c / (c + sqrt(c^2 + a2 (1 - c^2))), so the
// quotient 1 / (c + sqrt(c^2 + a2 (1 - c^2))) stays finite as c -> 0.
float ggx_g1_over_2cos(float c, float a2) {
    return 1.0 / (c + sqrt(c * c + a2 * max(1.0 - c * c, 0.0)));
}

// Schlick's Fresnel with F0 = ks; wh = dot(wi, h).
vec3 fresnel_schlick(vec3 ks, float wh) {
    float m = clamp(1.0 - wh, 0.0, 1.0);
    float m2 = m * m;
    return ks + (1.0 - ks) * (m2 * m2 * m);
}

// max(0, rw)^s without pow(0, 0).
float phong_lobe(float rw, float s) {
    return rw > 0.0 ? pow(rw, s) : 0.0;
}

// The GGX microfacet term F G D / (4 |n.wi| |n.wo|) for ci = dot(n, wi) > 0 and
// co = max(dot(n, wo), 0).
vec3 ggx_specular(vec3 ks, float roughness, vec3 n, vec3 wo, vec3 wi, float ci, float co) {
    vec3 hsum = wi + wo;
    float len2 = dot(hsum, hsum);
    if (!(len2 > 0.0)) return vec3(0.0);
    vec3 h = hsum * inversesqrt(len2);
    float nh = dot(n, h);
    if (!(nh > 0.0)) return vec3(0.0);
    float a = bsdf_ggx_alpha(roughness);
    float a2 = a * a;
    float dg = ggx_d(nh, a2) * ggx_g1_over_2cos(ci, a2) * ggx_g1_over_2cos(co, a2);
    return fresnel_schlick(ks, dot(wi, h)) * dg;
}

// Solid-angle pdf of wi when h is drawn from D(h) (n.h) and wi = reflect(-wo, h):
// D(h) (n.h) / (4 |h.wi|).
float ggx_specular_pdf(float roughness, vec3 n, vec3 wo, vec3 wi) {
    vec3 hsum = wi + wo;
    float len2 = dot(hsum, hsum);
    if (!(len2 > 0.0)) return 0.0;
    vec3 h = hsum * inversesqrt(len2);
    float nh = dot(n, h);
    float wh = dot(wi, h);
    if (!(nh > 0.0) || !(wh > 0.0)) return 0.0;
    float a = bsdf_ggx_alpha(roughness);
    return ggx_d(nh, a * a) * nh / (4.0 * wh);
}

// Solid-angle pdf of the normalised Phong lobe around r: (s + 1) / (2 pi) max(0, r.wi)^s.
float phong_specular_pdf(float shininess, vec3 n, vec3 wo, vec3 wi) {
    float s = max(shininess, 0.0);
    vec3 r = reflect(-wo, n);
    return (s + 1.0) * INV_TWO_PI * phong_lobe(dot(r, wi), s);
}

// Half vector in the local frame (z along n) with pdf D(h) cos(theta_h):
// tan^2(theta_h) = a2 u.x / (1 - u.x), written without cancellation as
// cos^2 = (1 - u.x) / (u.x a2 + 1 - u.x), sin^2 = u.x a2 / (u.x a2 + 1 - u.x).
vec3 sample_ggx_half(vec2 u, float a2) {
    float den = u.x * a2 + (1.0 - u.x);
    float cos_t = sqrt((1.0 - u.x) / den);
    float sin_t = sqrt(u.x * a2 / den);
    float phi = TWO_PI * u.y;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// Direction in the local frame (z along the lobe axis) with pdf (s+1)/(2 pi) cos^s.
vec3 sample_phong_lobe(vec2 u, float s) {
    float cos_t = pow(1.0 - u.x, 1.0 / (s + 1.0));
    float sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    float phi = TWO_PI * u.y;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// lightpath profile: PROFILE_X2_BSDF evaluates, samples and weighs every BSDF twice
// (the extra time is the BSDF's share of a pass; see src/profile.rs).
#ifdef PROFILE_X2_BSDF
#define bsdf_eval bsdf_eval_once
#define bsdf_pdf bsdf_pdf_once
#define bsdf_sample bsdf_sample_once
#endif

vec3 bsdf_eval(BsdfParams b, vec3 n, vec3 wo, vec3 wi, uint transport) {
    float ci = dot(n, wi);
    if (!(ci > 0.0)) return vec3(0.0);
    vec3 f = b.kd * INV_PI;
    if (b.kind == BSDF_GGX) {
        float co = max(dot(n, wo), 0.0);
        f += ggx_specular(b.ks, b.roughness, n, wo, wi, ci, co);
    } else {
        float s = max(b.shininess, 0.0);
        vec3 r = reflect(-wo, n);
        f += b.ks * ((s + 2.0) * INV_TWO_PI * phong_lobe(dot(r, wi), s));
    }
    return f;
}

float bsdf_pdf(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi) {
    float ci = dot(n, wi);
    if (!(ci > 0.0)) return 0.0;
    if (mode == SAMPLE_HEMISPHERE) return INV_TWO_PI;
    float p_cos = ci * INV_PI;
    if (mode == SAMPLE_COSINE) return p_cos;
    float t = bsdf_specular_probability(b);
    float p_spec = 0.0;
    if (t > 0.0) {
        p_spec = b.kind == BSDF_GGX ? ggx_specular_pdf(b.roughness, n, wo, wi)
                                    : phong_specular_pdf(b.shininess, n, wo, wi);
    }
    return t * p_spec + (1.0 - t) * p_cos;
}

// u.x picks the lobe (SAMPLE_BRDF only), u.yz place the direction. False when the
// direction falls below the surface or its pdf is not a positive finite number.
bool bsdf_sample(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    s.pdf = 0.0;
    s.f = vec3(0.0);
    s.flags = BSDF_LOBE_REFLECTION;
    if (mode == SAMPLE_HEMISPHERE) {
        s.wi = to_world(sample_uniform_hemisphere(u.yz), n);
    } else if (mode == SAMPLE_COSINE) {
        s.wi = to_world(sample_cosine_hemisphere(u.yz), n);
    } else if (u.x < bsdf_specular_probability(b)) {
        if (b.kind == BSDF_GGX) {
            float a = bsdf_ggx_alpha(b.roughness);
            vec3 h = to_world(sample_ggx_half(u.yz, a * a), n);
            s.wi = reflect(-wo, h);
        } else {
            vec3 r = reflect(-wo, n);
            s.wi = to_world(sample_phong_lobe(u.yz, max(b.shininess, 0.0)), r);
        }
    } else {
        s.wi = to_world(sample_cosine_hemisphere(u.yz), n);
    }
    if (!(dot(n, s.wi) > 0.0)) return false;
    s.pdf = bsdf_pdf(b, mode, n, wo, s.wi);
    if (!(s.pdf > 0.0 && !isinf(s.pdf))) return false;
    s.f = bsdf_eval(b, n, wo, s.wi, transport);
    return true;
}

#ifdef PROFILE_X2_BSDF
#undef bsdf_eval
#undef bsdf_pdf
#undef bsdf_sample
// The second call's inputs differ by an ulp and its result is kept only in a case that
// never happens (a negative value), so the compiler must compute both.
vec3 bsdf_eval(BsdfParams b, vec3 n, vec3 wo, vec3 wi, uint transport) {
    vec3 x = bsdf_eval_once(b, n, wo, wi * 1.0000001, transport);
    vec3 y = bsdf_eval_once(b, n, wo, wi, transport);
    return x.x == -1.0 ? x : y;
}
float bsdf_pdf(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi) {
    float x = bsdf_pdf_once(b, mode, n, wo, wi * 1.0000001);
    float y = bsdf_pdf_once(b, mode, n, wo, wi);
    return x == -1.0 ? x : y;
}
bool bsdf_sample(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    BsdfSample other;
    bool x = bsdf_sample_once(b, mode, n, wo * 1.0000001, u, transport, other);
    bool y = bsdf_sample_once(b, mode, n, wo, u, transport, s);
    if (x && other.pdf == -1.0) s = other;
    return y;
}
#endif

#endif
