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
// Conventions (pbrt-v4's): wo points where the path came from (toward the camera on a
// camera subpath, toward the light on a light subpath, as `transport` says), wi the
// other direction; n is the unit shading normal. bsdf_eval returns f itself, not
// f * |cos(theta_i)|.
//
// The course's BRDFs (BSDF_PHONG, BSDF_GGX) are two-sided reflectors and take n flipped
// toward wo (dot(n, wo) >= 0; a slightly negative value from rounding is clamped to 0
// where a cosine is needed): f = 0 and pdf = 0 for wi with dot(n, wi) <= 0, and a sampled
// wi below the surface is a failed sample.
//
// The dielectric, thin dielectric and conductor BSDFs (pbrt-v4's; their Fresnel and
// microfacet terms are in microfacet.glsl) take wo and wi on either side of n. A
// dielectric's `eta` is the relative index of refraction of the side n points away from
// (material_bsdf makes it so from the material's index and which side n is on), so a
// closed mesh or sphere is a solid of glass. Transmission in radiance mode carries the
// 1/eta^2 of radiance crossing an interface; importance mode does not. Smooth ones (alpha
// below MICROFACET_SMOOTH_ALPHA) and the thin dielectric are delta distributions: eval
// and pdf are 0, and a sample's f and pdf are the lobe's weight and choice probability
// (flag BSDF_LOBE_DELTA). They sample their own distribution whatever the mode.
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
#include "microfacet.glsl"
#include "texture.glsl"
#include "features.glsl"

// One surface's BSDF parameters (the BSDF_* kinds and SAMPLE_* modes are in abi.h).
struct BsdfParams {
    uint kind;
    vec3 kd;
    vec3 ks;
    float shininess;
    float roughness;   // the course GGX's alpha
    vec2 alpha;        // dielectric, conductor: microfacet alphas along the tangent and bitangent
    vec3 eta;          // dielectric: x, relative to n's orientation; thin: x; conductor: per channel
    vec3 k;            // conductor absorption
    vec3 coat;         // coated: layer thickness, walk's maximum depth, samples
    vec3 base_eta;     // coated conductor: the conductor's eta and k relative to the coating,
    vec3 base_k;       //   and its microfacet alphas
    vec2 base_alpha;
    vec3 albedo;       // coated: the layer's single-scattering albedo (0: it only absorbs)
    float g;           //   and its Henyey-Greenstein g
    uint table;        // measured: the texel index of its tables (measured.glsl)
    vec3 tangent;      // hair: the fiber's direction (the surface's dp/du) and the offset h
    float h;           //   across it (hair.glsl; Surface.tex1 carries them)
};

// Coated conductors' code is in kernels only for scenes that have them.
bool bsdf_is_coated_conductor(BsdfParams b) {
    return has_feature(FEATURE_COATED_CONDUCTOR) && b.kind == BSDF_COATED_CONDUCTOR;
}

// Measured materials are a class of their own: a kernel that shades one class holds their
// tables' code only if it is theirs, and other kernels only for scenes that have them.
bool bsdf_is_measured(BsdfParams b) {
#if defined(SHADE_CLASS)
    return SHADE_CLASS == MATERIAL_CLASS_MEASURED;
#else
    return has_feature(FEATURE_MEASURED) && b.kind == BSDF_MEASURED;
#endif
}

// Hair is a class of its own, like measured materials.
bool bsdf_is_hair(BsdfParams b) {
#if defined(SHADE_CLASS)
    return SHADE_CLASS == MATERIAL_CLASS_HAIR;
#else
    return has_feature(FEATURE_HAIR) && b.kind == BSDF_HAIR;
#endif
}

// Diffuse transmission's code is in kernels only for scenes that have it.
bool bsdf_is_diffuse_transmission(BsdfParams b) {
    return has_feature(FEATURE_DIFFUSE_TRANSMISSION) && b.kind == BSDF_DIFFUSE_TRANSMISSION;
}

// The BSDF of material m at a surface point whose material texture values are tex0 and
// tex1 (Surface.tex0, tex1: the surface looked them up), whose normal, as the caller will
// pass it, points to the material's outside (front) or inside (!front).
BsdfParams material_bsdf(GpuMaterial m, bool front, vec4 tex0, vec4 tex1) {
    BsdfParams b;
    b.kind = m.info.x;
    b.kd = m.diffuse.xyz;
    b.ks = m.specular.xyz;
    b.shininess = m.roughness.x;
    b.roughness = m.roughness.y;
    b.alpha = m.roughness.yz;
    b.eta = m.eta.xyz;
    if (b.kind == BSDF_DIELECTRIC && !front) b.eta.x = 1.0 / b.eta.x;
    b.k = m.k.xyz;
    b.coat = m.k.xyz;
    b.base_eta = m.specular.xyz;
    b.base_k = m.diffuse.xyz;
    b.base_alpha = m.base.xy;
    bool layered = b.kind == BSDF_COATED_DIFFUSE || b.kind == BSDF_COATED_CONDUCTOR;
    b.albedo = has_feature(FEATURE_LAYER_MEDIUM) && layered ? m.eta.yzw : vec3(0.0);
    b.g = m.k.w;
    b.table = floatBitsToUint(m.base.x);
    // (Hair: sigma_a in k, eta in eta.x, beta_m and beta_n in alpha, the scales' tilt in
    // shininess; its frame and offset are the surface's, in tex1.)
    b.tangent = tex1.xyz;
    b.h = tex1.w;
    if (has_feature(FEATURE_HAIR) && b.kind == BSDF_HAIR) return b;
    // Textures replace parameters (material_texture's slots; roughness remapped here).
    if (!has_feature(FEATURE_MATERIAL_TEXTURES)) return b;
    for (uint slot = 0u; slot < MATERIAL_TEXTURE_SLOTS; ++slot) {
        if (material_texture(m, slot) == NO_TEXTURE) continue;
        vec3 v = slot == 0u ? tex0.xyz : slot == 1u ? tex1.xyz : vec3(slot == 2u ? tex0.w : tex1.w);
        // (A roughness below 0 is 0; a reflectance or a transmittance is clamped to [0, 1],
        // as pbrt-v4's materials clamp theirs: a mix or a scale of textures can leave it.)
        float a = max(v.x, 0.0);
        if (slot != 0u && slot != 3u && (m.info.y & MATERIAL_REMAP_ROUGHNESS) != 0u) a = sqrt(a);
        if (slot == 0u && (bsdf_is_coated_conductor(b) || b.kind == BSDF_CONDUCTOR)) {
            // pbrt-v4's artist-friendly conductor: eta 1, k from the reflectance r (a
            // coated conductor's in the coating: both over its index).
            vec3 r = clamp(v, vec3(0.0), vec3(0.9999));
            vec3 k = 2.0 * sqrt(r) / sqrt(vec3(1.0) - r);
            if (b.kind == BSDF_CONDUCTOR) {
                b.eta = vec3(1.0);
                b.k = k;
            } else {
                b.base_eta = vec3(1.0 / b.eta.x);
                b.base_k = k / b.eta.x;
            }
        } else if (slot == 0u) {
            b.kd = clamp(v, vec3(0.0), vec3(1.0));
        } else if (slot == 1u && bsdf_is_diffuse_transmission(b)) {
            b.ks = clamp(v, vec3(0.0), vec3(1.0));
        } else if (slot == 1u) {
            b.roughness = a;
            b.alpha = vec2(a);
        } else if (slot == 2u) {
            b.base_alpha = vec2(a);
        } else {
            b.coat.x = v.x;
        }
    }
    return b;
}

// Shading normals. Every BSDF is evaluated about the shading normal ns (on the side of the
// geometric normal n), and is 0 for a direction w on different sides of the two: the test
// is symmetric in wo and wi, so camera and light subpaths see one BSDF, and light does not
// leak through a surface.
bool shading_side_agrees(vec3 n, vec3 ns, vec3 w) { return dot(n, w) * dot(ns, w) > 0.0; }

// The cosine that multiplies f(wo, wi) in a path's throughput toward wi: |ns.wi| for
// radiance; for importance, Veach's adjoint BSDF with shading normals (thesis, 5.3; pbrt's
// CorrectShadingNormal) turns it into |n.wi| |ns.wo| / |n.wo|. Without shading normals
// (ns = n) both are |n.wi|.
float shading_cosine(vec3 n, vec3 ns, vec3 wo, vec3 wi, uint transport) {
    if (transport == TRANSPORT_RADIANCE) return abs(dot(ns, wi));
    float den = abs(dot(n, wo));
    return den > 0.0 ? abs(dot(n, wi)) * (abs(dot(ns, wo)) / den) : 0.0;
}

bool bsdf_is_smooth(BsdfParams b) { return max(b.alpha.x, b.alpha.y) < MICROFACET_SMOOTH_ALPHA; }

// Whether every lobe of the BSDF is a delta distribution (no light sampling or
// connection can reach it).
bool bsdf_is_delta(BsdfParams b) {
    if (b.kind == BSDF_THIN_DIELECTRIC) return true;
    if (b.kind == BSDF_DIELECTRIC) return bsdf_is_smooth(b) || b.eta.x == 1.0;
    if (b.kind == BSDF_CONDUCTOR) return bsdf_is_smooth(b);
    // A smooth coating over a smooth conductor (pbrt-v4's LayeredBxDF flags it specular).
    if (bsdf_is_coated_conductor(b)) {
        return bsdf_is_smooth(b) && max(b.base_alpha.x, b.base_alpha.y) < MICROFACET_SMOOTH_ALPHA
            && !(max(b.albedo.x, max(b.albedo.y, b.albedo.z)) > 0.0);
    }
    return false;
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

// ---- the interface BSDFs: dielectric, thin dielectric and conductor (pbrt-v4's, in the
// local frame) --------------------------------------------------------------------------

// The local frame of n: its tangent and bitangent from build_onb (the anisotropic
// alphas are along them). flip is set when wo lies below n: the functions then work in
// the mirrored frame (z negated) with the inverse relative index, so that wo.z >= 0.
struct LocalFrame {
    vec3 t;
    vec3 b;
    vec3 n;
    bool flip;
};

LocalFrame local_frame(vec3 n, vec3 wo) {
    LocalFrame f;
    build_onb(n, f.t, f.b);
    f.n = n;
    f.flip = dot(n, wo) < 0.0;
    return f;
}

vec3 to_local(LocalFrame f, vec3 v) {
    vec3 l = vec3(dot(v, f.t), dot(v, f.b), dot(v, f.n));
    return f.flip ? vec3(l.xy, -l.z) : l;
}

vec3 from_local(LocalFrame f, vec3 l) {
    if (f.flip) l.z = -l.z;
    return l.x * f.t + l.y * f.b + l.z * f.n;
}

// The relative index in the (possibly mirrored) frame.
float local_eta(BsdfParams b, LocalFrame f) { return f.flip ? 1.0 / b.eta.x : b.eta.x; }

float sqr(float x) { return x * x; }

// Rough dielectric (Walter et al. 2007, pbrt-v4's DielectricBxDF) for local wo.z > 0.
vec3 dielectric_f(vec2 a, float eta, vec3 wo, vec3 wi, uint transport) {
    float cos_o = wo.z;
    float cos_i = wi.z;
    if (cos_i == 0.0 || !(cos_o > 0.0)) return vec3(0.0);
    bool is_reflection = cos_i > 0.0;
    float etap = is_reflection ? 1.0 : eta;
    vec3 wm = wi * etap + wo;
    if (dot(wm, wm) == 0.0) return vec3(0.0);
    wm = normalize(wm);
    if (wm.z < 0.0) wm = -wm;
    if (dot(wm, wi) * cos_i < 0.0 || dot(wm, wo) * cos_o < 0.0) return vec3(0.0);
    float F = fr_dielectric(dot(wo, wm), eta);
    if (is_reflection) return vec3(tr_d(wm, a) * tr_g(wo, wi, a) * F / abs(4.0 * cos_i * cos_o));
    float denom = sqr(dot(wi, wm) + dot(wo, wm) / etap) * cos_i * cos_o;
    float ft = tr_d(wm, a) * (1.0 - F) * tr_g(wo, wi, a) * abs(dot(wi, wm) * dot(wo, wm) / denom);
    if (transport == TRANSPORT_RADIANCE) ft /= sqr(etap);
    return vec3(ft);
}

float dielectric_pdf(vec2 a, float eta, vec3 wo, vec3 wi) {
    float cos_o = wo.z;
    float cos_i = wi.z;
    if (cos_i == 0.0 || !(cos_o > 0.0)) return 0.0;
    bool is_reflection = cos_i > 0.0;
    float etap = is_reflection ? 1.0 : eta;
    vec3 wm = wi * etap + wo;
    if (dot(wm, wm) == 0.0) return 0.0;
    wm = normalize(wm);
    if (wm.z < 0.0) wm = -wm;
    if (dot(wm, wi) * cos_i < 0.0 || dot(wm, wo) * cos_o < 0.0) return 0.0;
    float R = fr_dielectric(dot(wo, wm), eta);
    float T = 1.0 - R;
    if (is_reflection) return tr_d_visible(wo, wm, a) / (4.0 * abs(dot(wo, wm))) * R / (R + T);
    float dwm_dwi = abs(dot(wi, wm)) / sqr(dot(wi, wm) + dot(wo, wm) / etap);
    return tr_d_visible(wo, wm, a) * dwm_dwi * T / (R + T);
}

bool dielectric_sample(BsdfParams b, LocalFrame fr, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    float eta = local_eta(b, fr);
    vec3 wi;
    if (bsdf_is_smooth(b) || eta == 1.0) {
        float R = fr_dielectric(wo.z, eta);
        float T = 1.0 - R;
        if (u.x < R / (R + T)) {
            wi = vec3(-wo.x, -wo.y, wo.z);
            s.f = vec3(R / abs(wi.z));
            s.pdf = R / (R + T);
            s.flags = BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA;
        } else {
            float etap;
            if (!refract_dir(wo, vec3(0.0, 0.0, 1.0), eta, etap, wi) || wi.z == 0.0) return false;
            float ft = T / abs(wi.z);
            if (transport == TRANSPORT_RADIANCE) ft /= sqr(etap);
            s.f = vec3(ft);
            s.pdf = T / (R + T);
            s.flags = BSDF_LOBE_TRANSMISSION | BSDF_LOBE_DELTA;
        }
    } else {
        vec3 wm = tr_sample_wm(wo, u.yz, b.alpha);
        float R = fr_dielectric(dot(wo, wm), eta);
        float T = 1.0 - R;
        if (u.x < R / (R + T)) {
            wi = reflect(-wo, wm);
            if (!(wi.z > 0.0)) return false;
            s.flags = BSDF_LOBE_REFLECTION;
        } else {
            float etap;
            if (!refract_dir(wo, wm, eta, etap, wi) || !(wi.z < 0.0)) return false;
            s.flags = BSDF_LOBE_TRANSMISSION;
        }
        // f and pdf as eval and pdf give them (the same half vector, up to rounding).
        s.f = dielectric_f(b.alpha, eta, wo, wi, transport);
        s.pdf = dielectric_pdf(b.alpha, eta, wo, wi);
    }
    s.wi = from_local(fr, wi);
    return s.pdf > 0.0 && !isinf(s.pdf) && s.f != vec3(0.0);
}

// Thin dielectric (pbrt-v4's ThinDielectricBxDF): reflection and straight-through
// transmission, with the multiple-bounce sum inside the slab. Delta.
bool thin_dielectric_sample(BsdfParams b, LocalFrame fr, vec3 wo, vec3 u, out BsdfSample s) {
    float R = fr_dielectric(wo.z, b.eta.x);
    float T = 1.0 - R;
    if (R < 1.0) {
        R += T * T * R / (1.0 - R * R);
        T = 1.0 - R;
    }
    vec3 wi;
    if (u.x < R / (R + T)) {
        wi = vec3(-wo.x, -wo.y, wo.z);
        s.f = vec3(R / abs(wi.z));
        s.pdf = R / (R + T);
        s.flags = BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA;
    } else {
        wi = -wo;
        s.f = vec3(T / abs(wi.z));
        s.pdf = T / (R + T);
        s.flags = BSDF_LOBE_TRANSMISSION | BSDF_LOBE_DELTA;
    }
    s.wi = from_local(fr, wi);
    return s.pdf > 0.0 && s.f != vec3(0.0);
}

// Conductor (pbrt-v4's ConductorBxDF): a mirror, or Trowbridge-Reitz reflection, of
// complex index eta + i k and alphas a, in the local frame (wo.z > 0). The conductor
// material and a coated conductor's base (layered.glsl) call these.
vec3 conductor_local_f(vec2 a, vec3 eta, vec3 k, vec3 wo, vec3 wi) {
    if (!(wo.z > 0.0) || !(wi.z > 0.0)) return vec3(0.0);
    vec3 wm = wi + wo;
    if (dot(wm, wm) == 0.0) return vec3(0.0);
    wm = normalize(wm);
    vec3 F = fr_conductor(abs(dot(wo, wm)), eta, k);
    return tr_d(wm, a) * F * tr_g(wo, wi, a) / (4.0 * wi.z * wo.z);
}

float conductor_local_pdf(vec2 a, vec3 wo, vec3 wi) {
    if (!(wo.z > 0.0) || !(wi.z > 0.0)) return 0.0;
    vec3 wm = wi + wo;
    if (dot(wm, wm) == 0.0) return 0.0;
    wm = normalize(wm);
    if (wm.z < 0.0) wm = -wm;
    return tr_d_visible(wo, wm, a) / (4.0 * abs(dot(wo, wm)));
}

// A sample from wo (wo.z > 0) with u: wi, f, pdf and flags. False when there is none.
bool conductor_local_sample(vec2 a, vec3 eta, vec3 k, vec3 wo, vec2 u, out vec3 wi, out vec3 f, out float pdf,
                            out uint flags) {
    wi = vec3(0.0, 0.0, 1.0);
    f = vec3(0.0);
    pdf = 0.0;
    flags = 0u;
    if (!(wo.z > 0.0)) return false;
    if (max(a.x, a.y) < MICROFACET_SMOOTH_ALPHA) {
        wi = vec3(-wo.x, -wo.y, wo.z);
        f = fr_conductor(wi.z, eta, k) / wi.z;
        pdf = 1.0;
        flags = BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA;
    } else {
        vec3 wm = tr_sample_wm(wo, u, a);
        wi = reflect(-wo, wm);
        if (!(wi.z > 0.0)) return false;
        f = conductor_local_f(a, eta, k, wo, wi);
        pdf = conductor_local_pdf(a, wo, wi);
        flags = BSDF_LOBE_REFLECTION;
    }
    return pdf > 0.0 && !isinf(pdf) && f != vec3(0.0);
}

vec3 conductor_f(BsdfParams b, vec3 wo, vec3 wi) { return conductor_local_f(b.alpha, b.eta, b.k, wo, wi); }
float conductor_pdf(BsdfParams b, vec3 wo, vec3 wi) { return conductor_local_pdf(b.alpha, wo, wi); }

bool conductor_sample(BsdfParams b, LocalFrame fr, vec3 wo, vec3 u, out BsdfSample s) {
    vec3 wi;
    bool ok = conductor_local_sample(b.alpha, b.eta, b.k, wo, u.yz, wi, s.f, s.pdf, s.flags);
    s.wi = from_local(fr, wi);
    return ok;
}

// Diffuse transmission (pbrt-v4's DiffuseTransmissionBxDF), in the local frame of wo
// (wo.z > 0): R/pi toward wo's side, T/pi through to the other; sampled as cosine lobes
// on either side, chosen in proportion to max(R) and max(T).
vec2 diffuse_transmission_weights(BsdfParams b) {
    float pr = max(b.kd.x, max(b.kd.y, b.kd.z));
    float pt = max(b.ks.x, max(b.ks.y, b.ks.z));
    return vec2(max(pr, 0.0), max(pt, 0.0));
}

vec3 diffuse_transmission_f(BsdfParams b, vec3 wo, vec3 wi) {
    if (wi.z == 0.0) return vec3(0.0);
    return (wi.z > 0.0 ? b.kd : b.ks) * INV_PI;
}

float diffuse_transmission_pdf(BsdfParams b, vec3 wo, vec3 wi) {
    vec2 p = diffuse_transmission_weights(b);
    if (wi.z == 0.0 || !(p.x + p.y > 0.0)) return 0.0;
    return abs(wi.z) * INV_PI * (wi.z > 0.0 ? p.x : p.y) / (p.x + p.y);
}

bool diffuse_transmission_sample(BsdfParams b, LocalFrame fr, vec3 wo, vec3 u, out BsdfSample s) {
    vec2 p = diffuse_transmission_weights(b);
    if (!(p.x + p.y > 0.0)) return false;
    vec3 wi = sample_cosine_hemisphere(u.yz);
    bool reflect = u.x < p.x / (p.x + p.y);
    if (!reflect) wi.z = -wi.z;
    s.f = diffuse_transmission_f(b, wo, wi);
    s.pdf = diffuse_transmission_pdf(b, wo, wi);
    s.flags = reflect ? BSDF_LOBE_REFLECTION : BSDF_LOBE_TRANSMISSION;
    s.wi = from_local(fr, wi);
    return s.pdf > 0.0 && !isinf(s.pdf) && s.f != vec3(0.0);
}

#include "layered.glsl"
#include "measured.glsl"
#include "hair.glsl"

// ---- the hair BSDF (pbrt-v4's HairBxDF, hair.glsl) in the fiber's frame about n ---------
// (b.tangent made orthogonal to n; build_onb's where it cannot be). CPU mirror:
// src/hair.rs, Hair::eval_about, pdf_about, sample_about.

// f(a, w) and pdf(a -> w), or with `draw` a w sampled from a's lobes (u).
bool hair_bsdf_query(BsdfParams b, vec3 n, vec3 a, bool draw, vec3 u, inout vec3 w, out vec3 f, out float pdf) {
    vec3 x = b.tangent - n * dot(n, b.tangent);
    float l = length(x);
    vec3 y;
    if (l > 1e-6) {
        x /= l;
    } else {
        build_onb(n, x, y);
    }
    y = cross(n, x);
    vec3 lw = vec3(dot(w, x), dot(w, y), dot(w, n));
    bool ok = hair_query(b.k, b.eta.x, b.alpha.x, b.alpha.y, b.shininess, b.h, vec3(dot(a, x), dot(a, y), dot(a, n)),
                         draw, u, lw, f, pdf);
    if (draw) w = lw.x * x + lw.y * y + lw.z * n;
    return ok;
}

// The combined question of a connection or a sample (bsdf_eval_pdfs, bsdf_sample_rev):
// pass 0 f(wo, wi) and pdf(wo -> wi) (wi drawn with `draw`), pass 1 f(wi, wo) and
// pdf(wi -> wo), asked when the reverse density is wanted or for importance transport,
// whose f is the adjoint f(wi, wo) (src/hair.rs). One inlined copy of the model.
bool hair_bsdf_pair(BsdfParams b, vec3 n, vec3 wo, bool draw, vec3 u, uint transport, bool want_rev,
                    inout vec3 wi, out vec3 f, out float pdf_fwd, out float pdf_rev) {
    f = vec3(0.0);
    pdf_fwd = 0.0;
    pdf_rev = 0.0;
    bool adjoint = transport == TRANSPORT_IMPORTANCE;
    bool ok = false;
    [[dont_unroll]] for (uint k = 0u; k < (want_rev || adjoint ? 2u : 1u); ++k) {
        vec3 fk, to = k == 0u ? wi : wo;
        float pdf;
        bool found = hair_bsdf_query(b, n, k == 0u ? wo : wi, draw && k == 0u, u, to, fk, pdf);
        if (k == 0u) {
            ok = found || !draw;
            wi = to;
            pdf_fwd = pdf;
            if (!adjoint) f = fk;
            if (!ok) break;
        } else {
            pdf_rev = pdf;
            if (adjoint) f = fk;
        }
    }
    return ok;
}

// ---- the measured BSDF (pbrt-v4's MeasuredBxDF, measured.glsl) in n's local frame ------
// (mirrored when wo lies below n: it reflects on both sides). CPU mirror: src/measured.rs,
// MeasuredBsdf::eval_about, sample_about.

// measured_query about n: f(wo, wi) and pdf(wo -> wi) of a given wi, or with `draw` a
// sampled wi (u.yz).
bool measured_bsdf_query(BsdfParams b, vec3 n, vec3 wo, bool draw, vec3 u, inout vec3 wi, out vec3 f,
                         out float pdf) {
    LocalFrame fr = local_frame(n, wo);
    vec3 li = to_local(fr, wi);
    bool ok = measured_query(b.table, to_local(fr, wo), draw, u.yz, li, f, pdf);
    if (draw) wi = from_local(fr, li);
    return ok;
}

vec3 interface_eval(BsdfParams b, vec3 n, vec3 wo, vec3 wi, uint transport) {
    if (bsdf_is_delta(b)) return vec3(0.0);
    LocalFrame fr = local_frame(n, wo);
    vec3 lo = to_local(fr, wo);
    vec3 li = to_local(fr, wi);
    if (b.kind == BSDF_DIELECTRIC) return dielectric_f(b.alpha, local_eta(b, fr), lo, li, transport);
    if (bsdf_is_diffuse_transmission(b)) return diffuse_transmission_f(b, lo, li);
    return conductor_f(b, lo, li);
}

float interface_pdf(BsdfParams b, vec3 n, vec3 wo, vec3 wi) {
    if (bsdf_is_delta(b)) return 0.0;
    LocalFrame fr = local_frame(n, wo);
    vec3 lo = to_local(fr, wo);
    vec3 li = to_local(fr, wi);
    if (b.kind == BSDF_DIELECTRIC) return dielectric_pdf(b.alpha, local_eta(b, fr), lo, li);
    if (bsdf_is_diffuse_transmission(b)) return diffuse_transmission_pdf(b, lo, li);
    return conductor_pdf(b, lo, li);
}

bool interface_sample(BsdfParams b, vec3 n, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    s.wi = vec3(0.0, 0.0, 1.0);
    s.f = vec3(0.0);
    s.pdf = 0.0;
    s.flags = 0u;
    LocalFrame fr = local_frame(n, wo);
    vec3 lo = to_local(fr, wo);
    if (!(lo.z > 0.0)) return false;
    if (b.kind == BSDF_DIELECTRIC) return dielectric_sample(b, fr, lo, u, transport, s);
    if (b.kind == BSDF_THIN_DIELECTRIC) return thin_dielectric_sample(b, fr, lo, u, s);
    if (bsdf_is_diffuse_transmission(b)) return diffuse_transmission_sample(b, fr, lo, u, s);
    return conductor_sample(b, fr, lo, u, s);
}

// The material class of a BSDF kind (MATERIAL_CLASS_*): the wavefront path tracer
// shades each class in a kernel of its own.
uint material_class(uint kind) {
    if (has_feature(FEATURE_HAIR) && kind == BSDF_HAIR) return MATERIAL_CLASS_HAIR;
    if (has_feature(FEATURE_MEASURED) && kind == BSDF_MEASURED) return MATERIAL_CLASS_MEASURED;
    if (kind == BSDF_COATED_DIFFUSE || kind == BSDF_COATED_CONDUCTOR) return MATERIAL_CLASS_COATED;
    if (kind == BSDF_PHONG || kind == BSDF_GGX) return MATERIAL_CLASS_BASIC;
    return MATERIAL_CLASS_INTERFACE;
}

// A kernel that shades one material class defines SHADE_CLASS (a MATERIAL_CLASS_*): the
// tests below are then constants, and the other classes' code is left out of it.
// (Kernels for scenes without interface materials take every BSDF but hair, which
// transmits, for a course one.)
bool bsdf_is_course_brdf(BsdfParams b) {
#if defined(SHADE_CLASS) && SHADE_CLASS == MATERIAL_CLASS_BASIC
    return true;
#elif defined(SHADE_CLASS) && (SHADE_CLASS == MATERIAL_CLASS_INTERFACE || SHADE_CLASS == MATERIAL_CLASS_HAIR)
    return false;
#elif defined(SHADE_CLASS)
    return !has_feature(FEATURE_INTERFACES);
#else
    return (!has_feature(FEATURE_INTERFACES) && !bsdf_is_hair(b)) || b.kind == BSDF_PHONG || b.kind == BSDF_GGX;
#endif
}

// lightpath profile: PROFILE_X2_BSDF evaluates, samples and weighs every BSDF twice
// (the extra time is the BSDF's share of a pass; see src/profile.rs).
#ifdef PROFILE_X2_BSDF
#define analytic_eval analytic_eval_once
#define analytic_pdf analytic_pdf_once
#define analytic_sample analytic_sample_once
#endif

vec3 analytic_eval(BsdfParams b, vec3 n, vec3 wo, vec3 wi, uint transport) {
    if (!bsdf_is_course_brdf(b)) return interface_eval(b, n, wo, wi, transport);
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

float analytic_pdf(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi) {
    if (!bsdf_is_course_brdf(b)) return interface_pdf(b, n, wo, wi);
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
bool analytic_sample(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    if (!bsdf_is_course_brdf(b)) return interface_sample(b, n, wo, u, transport, s);
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
    s.pdf = analytic_pdf(b, mode, n, wo, s.wi);
    if (!(s.pdf > 0.0 && !isinf(s.pdf))) return false;
    s.f = analytic_eval(b, n, wo, s.wi, transport);
    return true;
}

#ifdef PROFILE_X2_BSDF
#undef analytic_eval
#undef analytic_pdf
#undef analytic_sample
// The second call's inputs differ by an ulp and its result is kept only in a case that
// never happens (a negative value), so the compiler must compute both.
vec3 analytic_eval(BsdfParams b, vec3 n, vec3 wo, vec3 wi, uint transport) {
    vec3 x = analytic_eval_once(b, n, wo, wi * 1.0000001, transport);
    vec3 y = analytic_eval_once(b, n, wo, wi, transport);
    return x.x == -1.0 ? x : y;
}
float analytic_pdf(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi) {
    float x = analytic_pdf_once(b, mode, n, wo, wi * 1.0000001);
    float y = analytic_pdf_once(b, mode, n, wo, wi);
    return x == -1.0 ? x : y;
}
bool analytic_sample(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    BsdfSample other;
    bool x = analytic_sample_once(b, mode, n, wo * 1.0000001, u, transport, other);
    bool y = analytic_sample_once(b, mode, n, wo, u, transport, s);
    if (x && other.pdf == -1.0) s = other;
    return y;
}
#endif

// The BSDFs as the integrators see them: f, the pdf of sampling mode `mode`, and a sample.
// Every BSDF but coated diffuse has closed forms (the analytic_* functions above); coated
// diffuse answers through its walk engine (layered.glsl). Neither calls the other, so
// that a kernel inlines the engine only where it asks the coated BSDF a question.
// (Its walk engine is large: kernels carry it only for scenes that have coated materials.)
bool bsdf_is_coated(BsdfParams b) {
#if defined(SHADE_CLASS)
    return SHADE_CLASS == MATERIAL_CLASS_COATED;
#else
    return has_feature(FEATURE_COATED) && (b.kind == BSDF_COATED_DIFFUSE || bsdf_is_coated_conductor(b));
#endif
}

// The closed-form BSDFs' answers to several questions (bsdf_eval_pdfs, bsdf_sample_rev).
vec3 analytic_eval_pdfs(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi, uint transport, bool want_fwd,
                        bool want_rev, out float pdf_fwd, out float pdf_rev) {
    pdf_fwd = 0.0;
    pdf_rev = 0.0;
    vec3 f = analytic_eval(b, n, wo, wi, transport);
    if (want_fwd) pdf_fwd = analytic_pdf(b, mode, n, wo, wi);
    if (want_rev) pdf_rev = analytic_pdf(b, mode, n, wi, wo);
    return f;
}

bool analytic_sample_rev(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, bool want_rev,
                         out BsdfSample s, out float pdf_rev) {
    pdf_rev = 0.0;
    if (!analytic_sample(b, mode, n, wo, u, transport, s)) return false;
    if (want_rev && (s.flags & BSDF_LOBE_DELTA) == 0u) pdf_rev = analytic_pdf(b, mode, n, s.wi, wo);
    return true;
}

// The BSDFs that answer through an engine rather than closed forms: hair (hair.glsl), the
// measured tables (measured.glsl), the coated walks (layered.glsl).
bool bsdf_is_engine(BsdfParams b) {
    return bsdf_is_hair(b) || bsdf_is_measured(b) || bsdf_is_coated(b);
}

// Every question to an engine BSDF, in one body (the one place each engine is called
// with several questions): with `draw` a sample into s (and with want_rev its density
// back), else f(wo, s.wi) into s.f, pdf(wo -> s.wi) into s.pdf (want_fwd) and the density
// back (want_rev). bsdf_sample, bsdf_eval_pdfs, bsdf_sample_rev and bsdf_ask ask it.
bool engine_ask(BsdfParams b, vec3 n, vec3 wo, bool draw, vec3 u, uint transport, bool want_fwd, bool want_rev,
                inout BsdfSample s, out float pdf_rev) {
    pdf_rev = 0.0;
    if (draw) s.wi = vec3(0.0);
    if (bsdf_is_hair(b)) {
        bool ok = hair_bsdf_pair(b, n, wo, draw, u, transport, want_rev, s.wi, s.f, s.pdf, pdf_rev);
        s.flags = dot(n, wo) * dot(n, s.wi) > 0.0 ? BSDF_LOBE_REFLECTION : BSDF_LOBE_TRANSMISSION;
        return !draw || (ok && !isinf(s.pdf) && s.f != vec3(0.0));
    }
    if (bsdf_is_measured(b)) {
        s.flags = BSDF_LOBE_REFLECTION;
        bool ok = true;
        [[dont_unroll]] for (uint k = 0u; k < (want_rev ? 2u : 1u); ++k) {
            // (k = 0: the sample, or f and pdf(wo -> wi); k = 1: pdf(wi -> wo).)
            vec3 f, to = k == 0u ? s.wi : wo;
            float pdf;
            bool found = measured_bsdf_query(b, n, k == 0u ? wo : s.wi, draw && k == 0u, u, to, f, pdf);
            if (k == 0u) {
                ok = !draw || (found && !isinf(pdf) && f != vec3(0.0));
                s.wi = to;
                s.f = f;
                s.pdf = pdf;
                if (!ok) break;
            } else {
                pdf_rev = pdf;
            }
        }
        return ok;
    }
    if (bsdf_is_coated(b)) {
        vec3 f;
        float pdf;
        uint q = draw ? COAT_Q_SAMPLE | (want_rev ? COAT_Q_PDF_REV : 0u)
                      : COAT_Q_F | (want_fwd ? COAT_Q_PDF : 0u) | (want_rev ? COAT_Q_PDF_REV : 0u);
        vec3 wi = draw ? wo : s.wi;
        BsdfSample t = s;
        bool ok = coated_engine(b, n, wo, wi, draw ? u : vec3(0.0), transport, q, f, pdf, pdf_rev, t);
        if (draw) {
            s = t;
            return ok;
        }
        s.f = f;
        s.pdf = pdf;
        return true;
    }
    return false;
}

vec3 bsdf_eval(BsdfParams b, vec3 n, vec3 wo, vec3 wi, uint transport) {
    if (bsdf_is_hair(b)) {
        // (Importance: the adjoint, f(wi, wo).)
        bool adjoint = transport == TRANSPORT_IMPORTANCE;
        vec3 f, w = adjoint ? wo : wi;
        float pdf;
        hair_bsdf_query(b, n, adjoint ? wi : wo, false, vec3(0.0), w, f, pdf);
        return f;
    }
    if (bsdf_is_measured(b)) {
        vec3 f;
        float pdf;
        measured_bsdf_query(b, n, wo, false, vec3(0.0), wi, f, pdf);
        return f;
    }
    if (!bsdf_is_coated(b)) return analytic_eval(b, n, wo, wi, transport);
    vec3 f;
    float pdf, pdf_rev;
    BsdfSample s;
    coated_engine(b, n, wo, wi, vec3(0.0), transport, COAT_Q_F, f, pdf, pdf_rev, s);
    return f;
}

float bsdf_pdf(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi) {
    if (bsdf_is_hair(b)) {
        vec3 f;
        float pdf;
        hair_bsdf_query(b, n, wo, false, vec3(0.0), wi, f, pdf);
        return pdf;
    }
    if (bsdf_is_measured(b)) {
        vec3 f;
        float pdf;
        measured_bsdf_query(b, n, wo, false, vec3(0.0), wi, f, pdf);
        return pdf;
    }
    if (!bsdf_is_coated(b)) return analytic_pdf(b, mode, n, wo, wi);
    vec3 f;
    float pdf, pdf_rev;
    BsdfSample s;
    coated_engine(b, n, wo, wi, vec3(0.0), TRANSPORT_RADIANCE, COAT_Q_PDF, f, pdf, pdf_rev, s);
    return pdf;
}

// u.x picks the lobe, u.yz place the direction. False when there is no sample (below
// the surface, or a pdf that is not a positive finite number).
bool bsdf_sample(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, out BsdfSample s) {
    if (!bsdf_is_engine(b)) return analytic_sample(b, mode, n, wo, u, transport, s);
    float pdf_rev;
    return engine_ask(b, n, wo, true, u, transport, false, false, s, pdf_rev);
}

// Several questions about one BSDF at once, for the integrators' connections: f(wo, wi)
// with pdf(wo -> wi) (want_fwd) and pdf(wi -> wo) (want_rev), as bsdf_eval and bsdf_pdf
// give them. A stochastic BSDF (coated diffuse) answers them in one walk engine, so that
// a kernel inlines it once per connection rather than once per question.
vec3 bsdf_eval_pdfs(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 wi, uint transport, bool want_fwd, bool want_rev,
                    out float pdf_fwd, out float pdf_rev) {
    if (bsdf_is_engine(b)) {
        BsdfSample s;
        s.wi = wi;
        engine_ask(b, n, wo, false, vec3(0.0), transport, want_fwd, want_rev, s, pdf_rev);
        pdf_fwd = s.pdf;
        return s.f;
    }
    return analytic_eval_pdfs(b, mode, n, wo, wi, transport, want_fwd, want_rev, pdf_fwd, pdf_rev);
}

// bsdf_sample, and with want_rev the pdf of the way back, pdf(s.wi -> wo) (0 after a
// delta lobe).
bool bsdf_sample_rev(BsdfParams b, uint mode, vec3 n, vec3 wo, vec3 u, uint transport, bool want_rev,
                     out BsdfSample s, out float pdf_rev) {
    if (bsdf_is_engine(b)) return engine_ask(b, n, wo, true, u, transport, false, want_rev, s, pdf_rev);
    return analytic_sample_rev(b, mode, n, wo, u, transport, want_rev, s, pdf_rev);
}

// bsdf_eval_pdfs and bsdf_sample_rev in one: with `draw` the sample (into s) and its
// density back, else f(wo, s.wi) into s.f and the densities pdf(wo -> s.wi) into s.pdf
// (want_fwd) and back (want_rev). For a kernel that asks a BSDF both questions (BDPT's
// and MMLT's shade stages): one call site holds one copy of an engine that answers both
// (engine_ask), where the two functions would inline two.
bool bsdf_ask(BsdfParams b, uint mode, vec3 n, vec3 wo, bool draw, vec3 u, uint transport, bool want_fwd,
              bool want_rev, inout BsdfSample s, out float pdf_rev) {
    if (bsdf_is_engine(b)) return engine_ask(b, n, wo, draw, u, transport, want_fwd, want_rev, s, pdf_rev);
    if (draw) return analytic_sample_rev(b, mode, n, wo, u, transport, want_rev, s, pdf_rev);
    s.f = analytic_eval_pdfs(b, mode, n, wo, s.wi, transport, want_fwd, want_rev, s.pdf, pdf_rev);
    return true;
}
#endif
