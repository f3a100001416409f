// pbrt-v4's hair BSDF (Chiang et al. 2016; docs/pbrt.md, "hair"), in the fiber's frame:
// x along the fiber, z the shading normal, y = z x x; sin(theta) = w.x, phi = atan(w.z, w.y).
// CPU mirror: src/hair.rs (the model, its terms and conventions are described there);
// keep them in sync. Included by bsdf.glsl, whose hair branch sets up the frame and the
// adjoint.
#ifndef HAIR_GLSL
#define HAIR_GLSL

const float HAIR_PI = 3.14159265358979;

float hair_safe_sqrt(float x) { return sqrt(max(x, 0.0)); }

// I0 by its series' first ten terms.
float hair_bessel_i0(float x) {
    float sum = 0.0;
    float term = 1.0;
    float q = 0.25 * x * x;
    for (int i = 0; i < 10; ++i) {
        if (i > 0) term *= q / float(i * i);
        sum += term;
    }
    return sum;
}

// The longitudinal lobe M_p of variance v.
float hair_longitudinal(float cos_i, float cos_o, float sin_i, float sin_o, float v) {
    float a = cos_i * cos_o / v;
    float b = sin_i * sin_o / v;
    if (v <= 0.1) {
        float log_i0 = a > 12.0 ? a + 0.5 * (-log(2.0 * HAIR_PI) + log(1.0 / a) + 1.0 / (8.0 * a))
                                : log(hair_bessel_i0(a));
        return exp(log_i0 - b - 1.0 / v + 0.69314718 + log(1.0 / (2.0 * v)));
    }
    return exp(-b) * hair_bessel_i0(a) / (sinh(1.0 / v) * 2.0 * v);
}

float hair_logistic_cdf(float x, float s) { return 1.0 / (1.0 + exp(-x / s)); }

// The exit azimuth of term p relative to the entry's.
float hair_phase(uint p, float gamma_o, float gamma_t) {
    return 2.0 * float(p) * gamma_t - 2.0 * gamma_o + float(p) * HAIR_PI;
}

// wo's elevation tilted by the scales for term p: (sin, |cos|). sin2k, cos2k: of 2^k alpha.
vec2 hair_tilted(float sin_o, float cos_o, vec3 sin2k, vec3 cos2k, uint p) {
    if (p == 3u) return vec2(sin_o, cos_o);
    uint k = p == 0u ? 1u : p == 1u ? 0u : 2u;
    float sg = p == 0u ? -1.0 : 1.0;
    return vec2(sin_o * cos2k[k] + sg * cos_o * sin2k[k], abs(cos_o * cos2k[k] - sg * sin_o * sin2k[k]));
}

// f(wo, wi) (divided by |wi.z|) and pdf(wo -> wi) of the fiber with absorption sigma_a,
// index eta, roughnesses beta_m and beta_n, scale tilt alpha (degrees) and offset h; with
// `draw`, wi drawn from wo's lobes first (u.x the term, then the azimuth; u.y the
// longitudinal angle; u.z its azimuth about the tilted mirror direction). False where the
// BSDF has no value (wo along the fiber, or a sample with no density).
bool hair_query(vec3 sigma_a, float eta, float beta_m, float beta_n, float alpha, float h, vec3 wo,
                bool draw, vec3 u, inout vec3 wi, out vec3 f, out float pdf) {
    f = vec3(0.0);
    pdf = 0.0;
    float sin_o = wo.x;
    float cos_o = hair_safe_sqrt(1.0 - sin_o * sin_o);
    float phi_o = atan(wo.z, wo.y);
    h = clamp(h, -1.0, 1.0);
    float gamma_o = asin(h);
    float sin_t = sin_o / eta;
    float cos_t = hair_safe_sqrt(1.0 - sin_t * sin_t);
    float etap = hair_safe_sqrt(eta * eta - sin_o * sin_o) / cos_o;
    float sin_gt = h / etap;
    float cos_gt = hair_safe_sqrt(1.0 - sin_gt * sin_gt);
    float gamma_t = asin(clamp(sin_gt, -1.0, 1.0));
    vec3 tr = exp(-sigma_a * (2.0 * cos_gt / cos_t));
    float fr = fr_dielectric(cos_o * hair_safe_sqrt(1.0 - h * h), eta);
    vec3 ap[4];
    ap[0] = vec3(fr);
    ap[1] = (1.0 - fr) * (1.0 - fr) * tr;
    ap[2] = ap[1] * tr * fr;
    vec3 rest = vec3(1.0) - tr * fr;
    ap[3] = mix(vec3(0.0), ap[2] * fr * tr / rest, greaterThan(rest, vec3(0.0)));
    vec4 share = vec4(dot(ap[0], vec3(1.0 / 3.0)), dot(ap[1], vec3(1.0 / 3.0)), dot(ap[2], vec3(1.0 / 3.0)),
                      dot(ap[3], vec3(1.0 / 3.0)));
    float total = share.x + share.y + share.z + share.w;
    share = total > 0.0 ? share / total : vec4(0.0);
    float bm = beta_m;
    float x = 0.726 * bm + 0.812 * bm * bm + 3.7 * pow(bm, 20.0);
    float v0 = x * x;
    vec4 v = vec4(v0, 0.25 * v0, 4.0 * v0, 4.0 * v0);
    float bn = beta_n;
    float s = 0.62665707 * (0.265 * bn + 1.194 * bn * bn + 5.372 * pow(bn, 22.0));
    float a = radians(alpha);
    vec3 sin2k = vec3(sin(a), 0.0, 0.0);
    vec3 cos2k = vec3(hair_safe_sqrt(1.0 - sin2k.x * sin2k.x), 0.0, 0.0);
    sin2k.y = 2.0 * cos2k.x * sin2k.x;
    cos2k.y = cos2k.x * cos2k.x - sin2k.x * sin2k.x;
    sin2k.z = 2.0 * cos2k.y * sin2k.y;
    cos2k.z = cos2k.y * cos2k.y - sin2k.y * sin2k.y;
    float trim = hair_logistic_cdf(HAIR_PI, s) - hair_logistic_cdf(-HAIR_PI, s);
    if (draw) {
        uint p = 3u;
        float uc = u.x;
        for (uint q = 0u; q < 3u; ++q) {
            if (uc < share[q]) {
                p = q;
                break;
            }
            uc -= share[q];
        }
        float sh = share[p];
        uc = sh > 0.0 ? clamp(uc / sh, 0.0, 0.99999994) : 0.0;
        vec2 po = hair_tilted(sin_o, cos_o, sin2k, cos2k, p);
        float vp = v[p];
        float cos_th = 1.0 + vp * log(max(u.y, 1e-5) + (1.0 - u.y) * exp(-2.0 / vp));
        float sin_th = hair_safe_sqrt(1.0 - cos_th * cos_th);
        float cos_phi = cos(2.0 * HAIR_PI * u.z);
        float sin_i = -cos_th * po.x + sin_th * cos_phi * po.y;
        float cos_i = hair_safe_sqrt(1.0 - sin_i * sin_i);
        float dphi;
        if (p < 3u) {
            float l = -s * log(1.0 / (uc * trim + hair_logistic_cdf(-HAIR_PI, s)) - 1.0);
            dphi = hair_phase(p, gamma_o, gamma_t) + clamp(l, -HAIR_PI, HAIR_PI);
        } else {
            dphi = 2.0 * HAIR_PI * uc;
        }
        float phi_i = phi_o + dphi;
        wi = vec3(sin_i, cos_i * cos(phi_i), cos_i * sin(phi_i));
    }
    float sin_i = wi.x;
    float cos_i = hair_safe_sqrt(1.0 - sin_i * sin_i);
    float dphi = atan(wi.z, wi.y) - phi_o;
    [[dont_unroll]] for (uint p = 0u; p < 4u; ++p) {
        vec2 po = hair_tilted(sin_o, cos_o, sin2k, cos2k, p);
        float m = hair_longitudinal(cos_i, po.y, sin_i, po.x, v[p]);
        float n = 1.0 / (2.0 * HAIR_PI);
        if (p < 3u) {
            float d = dphi - hair_phase(p, gamma_o, gamma_t);
            while (d > HAIR_PI) d -= 2.0 * HAIR_PI;
            while (d < -HAIR_PI) d += 2.0 * HAIR_PI;
            float e = exp(-abs(d) / s);
            n = e / (s * (1.0 + e) * (1.0 + e)) / trim;
        }
        f += m * n * ap[p];
        pdf += m * n * share[p];
    }
    float c = abs(wi.z);
    if (c > 0.0) f /= c;
    bool ok = cos_o > 0.0 && !isnan(pdf) && !isinf(pdf) && !any(isnan(f)) && !any(isinf(f));
    if (!ok) {
        f = vec3(0.0);
        pdf = 0.0;
    }
    return ok && pdf > 0.0;
}
#endif
