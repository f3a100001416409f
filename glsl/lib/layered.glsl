// Coated diffuse and coated conductor: pbrt-v4's CoatedDiffuseBxDF and
// CoatedConductorBxDF (a LayeredBxDF of a dielectric interface over a Lambertian or a
// conductor base, two-sided, an absorbing layer of unit extinction and thickness
// b.coat.x between them, scattering where b.albedo > 0). f, its pdf and sampling are stochastic
// estimates by random walks between the interfaces, with random numbers a deterministic
// function of the directions (as pbrt's are), so that MMLT's paths are functions of
// their primary samples. Sampling reports the pdf estimate (which every MIS weight
// reads) with f scaled to keep the walk's ratio f/pdf (pbrt's pdfIsProportional,
// resolved here). The walks run in local frames, z the normal, inside one engine
// (coated_engine, at the end) that bsdf.glsl asks everything. Included by bsdf.glsl; CPU
// mirror: src/bsdf/coated.rs (coated_f, coated_pdf, coated_sample, straight-line).
#ifndef LAYERED_GLSL
#define LAYERED_GLSL

#define COAT_LOBE_R 1u
#define COAT_LOBE_T 2u

// PCG's RXS-M-XS (hash_pcg), seeded by hashing two directions' float bits without their
// lowest 10 mantissa bits (so that the device's and the CPU's rounding almost always
// seed alike).
uint coat_rng_seed(vec3 a, vec3 b) {
    uint h = 0x9e3779b9u;
    h = hash_pcg(h ^ (floatBitsToUint(a.x) >> 10u));
    h = hash_pcg(h ^ (floatBitsToUint(a.y) >> 10u));
    h = hash_pcg(h ^ (floatBitsToUint(a.z) >> 10u));
    h = hash_pcg(h ^ (floatBitsToUint(b.x) >> 10u));
    h = hash_pcg(h ^ (floatBitsToUint(b.y) >> 10u));
    h = hash_pcg(h ^ (floatBitsToUint(b.z) >> 10u));
    return h;
}

float coat_next(inout uint state) {
    state = state * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    uint x = (word >> 22u) ^ word;
    return float(x >> 8u) * (1.0 / 16777216.0);
}

vec2 coat_next2(inout uint state) {
    float x = coat_next(state);
    return vec2(x, coat_next(state));
}

vec3 coat_flip_z(vec3 v) { return vec3(v.xy, -v.z); }
bool coat_smooth(vec2 a) { return max(a.x, a.y) < MICROFACET_SMOOTH_ALPHA; }

struct LocalSample {
    vec3 wi;
    vec3 f;
    float pdf;
    uint flags;
};

// The interface's pdf restricted to `lobes`, for wo.z > 0.
float coat_interface_pdf_up(vec2 a, float eta, vec3 wo, vec3 wi, uint lobes) {
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
    float pr = (lobes & COAT_LOBE_R) != 0u ? R : 0.0;
    float pt = (lobes & COAT_LOBE_T) != 0u ? 1.0 - R : 0.0;
    if (!(pr + pt > 0.0)) return 0.0;
    if (is_reflection) return tr_d_visible(wo, wm, a) / (4.0 * abs(dot(wo, wm))) * pr / (pr + pt);
    float dwm_dwi = abs(dot(wi, wm)) / sqr(dot(wi, wm) + dot(wo, wm) / etap);
    return tr_d_visible(wo, wm, a) * dwm_dwi * pt / (pr + pt);
}

// One interface operation, wo on either side. With `do_sample`, samples wi from wo
// restricted to `lobes` (uc, u); otherwise takes the given wi. Returns wi, f and the pdf
// restricted to `lobes` (both zero for a smooth interface that is not sampled). The
// walks below call it from one place each, so that a kernel inlines it once per walk.
bool coat_iface(vec2 a, float eta, vec3 wo, vec3 wi, bool do_sample, float uc, vec2 u, uint t, uint lobes,
                out LocalSample s) {
    s.wi = wi;
    s.f = vec3(0.0);
    s.pdf = 0.0;
    s.flags = 0u;
    bool flip = wo.z < 0.0;
    if (flip) {
        wo = coat_flip_z(wo);
        wi = coat_flip_z(wi);
        eta = 1.0 / eta;
    }
    if (do_sample && (coat_smooth(a) || eta == 1.0)) {
        float R = fr_dielectric(wo.z, eta);
        float pr = (lobes & COAT_LOBE_R) != 0u ? R : 0.0;
        float pt = (lobes & COAT_LOBE_T) != 0u ? 1.0 - R : 0.0;
        if (!(pr + pt > 0.0)) return false;
        if (uc < pr / (pr + pt)) {
            s.wi = vec3(-wo.x, -wo.y, wo.z);
            s.f = vec3(R / abs(s.wi.z));
            s.pdf = pr / (pr + pt);
            s.flags = BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA;
        } else {
            float etap;
            if (!refract_dir(wo, vec3(0.0, 0.0, 1.0), eta, etap, wi) || wi.z == 0.0) return false;
            float ft = (1.0 - R) / abs(wi.z);
            if (t == TRANSPORT_RADIANCE) ft /= sqr(etap);
            s.wi = wi;
            s.f = vec3(ft);
            s.pdf = pt / (pr + pt);
            s.flags = BSDF_LOBE_TRANSMISSION | BSDF_LOBE_DELTA;
        }
        if (flip) s.wi = coat_flip_z(s.wi);
        return s.pdf > 0.0 && !isinf(s.pdf) && s.f != vec3(0.0);
    }
    if (coat_smooth(a)) return false;
    if (do_sample) {
        vec3 wm = tr_sample_wm(wo, u, a);
        float R = fr_dielectric(dot(wo, wm), eta);
        float pr = (lobes & COAT_LOBE_R) != 0u ? R : 0.0;
        float pt = (lobes & COAT_LOBE_T) != 0u ? 1.0 - R : 0.0;
        if (!(pr + pt > 0.0)) return false;
        if (uc < pr / (pr + pt)) {
            wi = reflect(-wo, wm);
            if (!(wi.z > 0.0)) return false;
            s.flags = BSDF_LOBE_REFLECTION;
        } else {
            float etap;
            if (!refract_dir(wo, wm, eta, etap, wi) || !(wi.z < 0.0)) return false;
            s.flags = BSDF_LOBE_TRANSMISSION;
        }
    }
    s.wi = flip ? coat_flip_z(wi) : wi;
    s.f = dielectric_f(a, eta, wo, wi, t);
    s.pdf = coat_interface_pdf_up(a, eta, wo, wi, lobes);
    return !do_sample || (s.pdf > 0.0 && !isinf(s.pdf) && s.f != vec3(0.0));
}

vec3 coat_diffuse_f(vec3 kd, vec3 wo, vec3 wi) { return wo.z * wi.z > 0.0 ? kd * INV_PI : vec3(0.0); }
float coat_diffuse_pdf(vec3 wo, vec3 wi) { return wo.z * wi.z > 0.0 ? abs(wi.z) * INV_PI : 0.0; }

bool coat_diffuse_sample(vec3 kd, vec3 wo, vec2 u, out LocalSample s) {
    s.wi = sample_cosine_hemisphere(u);
    if (wo.z < 0.0) s.wi.z = -s.wi.z;
    s.pdf = abs(s.wi.z) * INV_PI;
    s.f = kd * INV_PI;
    s.flags = BSDF_LOBE_REFLECTION;
    return s.pdf > 0.0;
}

// The base: Lambertian (coated diffuse) or a conductor (coated conductor: its eta and k
// relative to the coating), for wo on either side.
bool coat_base_smooth(BsdfParams b) { return bsdf_is_coated_conductor(b) && coat_smooth(b.base_alpha); }

vec3 coat_base_f(BsdfParams b, vec3 wo, vec3 wi) {
    if (!bsdf_is_coated_conductor(b)) return coat_diffuse_f(b.kd, wo, wi);
    if (coat_base_smooth(b)) return vec3(0.0);
    if (wo.z < 0.0) {
        wo = coat_flip_z(wo);
        wi = coat_flip_z(wi);
    }
    return conductor_local_f(b.base_alpha, b.base_eta, b.base_k, wo, wi);
}

float coat_base_pdf(BsdfParams b, vec3 wo, vec3 wi) {
    if (!bsdf_is_coated_conductor(b)) return coat_diffuse_pdf(wo, wi);
    if (coat_base_smooth(b)) return 0.0;
    if (wo.z < 0.0) {
        wo = coat_flip_z(wo);
        wi = coat_flip_z(wi);
    }
    return conductor_local_pdf(b.base_alpha, wo, wi);
}

bool coat_base_sample(BsdfParams b, vec3 wo, vec2 u, out LocalSample s) {
    if (!bsdf_is_coated_conductor(b)) return coat_diffuse_sample(b.kd, wo, u, s);
    bool flip = wo.z < 0.0;
    bool ok = conductor_local_sample(b.base_alpha, b.base_eta, b.base_k, flip ? coat_flip_z(wo) : wo, u, s.wi, s.f,
                                     s.pdf, s.flags);
    if (flip) s.wi = coat_flip_z(s.wi);
    return ok;
}

float coat_tr(float thickness, vec3 w) {
    return abs(thickness) <= 1.17549435e-38 ? 1.0 : exp(-abs(thickness / w.z));
}

uint coat_other(uint t) { return t == TRANSPORT_RADIANCE ? TRANSPORT_IMPORTANCE : TRANSPORT_RADIANCE; }


// The three walks (f, pdf, sampling followed by the pdf of what was sampled) as one state
// machine: each turn of its loop runs at most one interface operation (coat_iface), so a
// kernel that evaluates BSDFs at many places inlines the dielectric interface once per
// place rather than once per step of each walk. The stages follow, in order, the
// straight-line walks of the CPU mirror (src/bsdf/coated.rs), drawing the same random
// numbers in the same order.
#define COAT_F 0u
#define COAT_PDF 1u
#define COAT_SAMPLE 2u

#define CS_F_FIRST 1u      // result: f(wo, wi) of the interface
#define CS_F_BEGIN 2u      // the next of the `samples` walks
#define CS_F_WOS 3u        // result: wo's transmission into the layer
#define CS_F_WIS 4u        // result: wi's transmission into the layer
#define CS_F_STEP 5u       // the next bounce
#define CS_F_TOP 6u        // result: reflection at the interface from below
#define CS_F_EXIT_F 7u     // result: f of the exit through the interface towards wi
#define CS_F_EXIT_PDF 8u   // result: wi's transmission density of that exit
#define CS_P_FIRST 9u      // result: the interface's reflection pdf
#define CS_P_BEGIN 10u
#define CS_P_WOS 11u
#define CS_P_WIS 12u
#define CS_P_EXIT 13u      // result: the exit's pdf after the base's sample
#define CS_S_FIRST 14u     // result: the interface's sample from above
#define CS_S_STEP 15u
#define CS_S_NEXT 16u      // result: the sample at the base or the interface
#define CS_P_START 17u     // the pdf of wi given wo
#define CS_S_END 18u       // the walk has its sample
#define CS_Q_NEXT 19u      // the next query
#define CS_S_DONE 20u      // the sample is final
#define CS_F_BASE 21u      // result: the base's sample
#define CS_P_BASE 22u      // result: the base's sample
#define CS_FAIL 23u
#define CS_F_BASE_NEE 24u  // result: the base's f and pdf toward wis
#define CS_P_BASE_PDF 25u  // result: the base's pdf between wos and wis

#define COAT_OP_NONE 0u
#define COAT_OP_SAMPLE 1u
#define COAT_OP_EVAL 2u
#define COAT_OP_BASE 3u       // sampling the base
#define COAT_OP_BASE_EVAL 4u  // the base's f and pdf (r.f, r.pdf)

// Queries of coated_engine, answered in this order.
#define COAT_Q_F 1u          // f(wo, wi)
#define COAT_Q_PDF 2u        // pdf(wo -> wi)
#define COAT_Q_SAMPLE 4u     // a sample from wo with u; wi becomes its direction
#define COAT_Q_PDF_REV 8u    // pdf(wi -> wo) (none after a delta sample)

// Answers `queries` about the coated BSDF b at a point with shading normal n (world
// directions, as bsdf.glsl's): f for `transport`, the pdf estimates both ways, and a
// sample (its f scaled so that f/pdf is the walk's estimate while pdf is the estimate
// every MIS weight reads). False when a sample was asked for and there is none.
bool coated_engine(BsdfParams b, vec3 n, vec3 wo_w, vec3 wi_w, vec3 u3, uint t, uint queries,
                   out vec3 f_out, out float pdf_out, out float pdf_rev_out, out BsdfSample smp) {
    vec2 a = b.alpha;
    float eta = b.eta.x;
    // (pbrt keeps the thickness above 0 so that the walk alternates between the layers.)
    float thick = max(b.coat.x, 1.17549435e-38);
    uint max_depth = uint(max(b.coat.y, 0.0));
    uint samples = uint(max(b.coat.z, 1.0));
    bool top_smooth = coat_smooth(a);
    bool base_smooth = coat_base_smooth(b);
    bool medium = has_feature(FEATURE_LAYER_MEDIUM) && max(b.albedo.x, max(b.albedo.y, b.albedo.z)) > 0.0;
    // The exit towards wi after a base bounce or a scattering event: the layer's length
    // still to cross, the density of the strategy that made w, and whether it was delta.
    float exit_len = thick, exit_own = 0.0;
    bool exit_one = false;
    f_out = vec3(0.0);
    pdf_out = 0.0;
    pdf_rev_out = 0.0;
    smp.wi = wi_w;
    smp.f = vec3(0.0);
    smp.pdf = 0.0;
    smp.flags = 0u;

    // The operation of the next turn and its result.
    uint op = COAT_OP_NONE;
    bool op_draw = true;
    vec3 op_wo = wo_w, op_wi = wi_w;
    float op_uc = 0.0;
    vec2 op_u = vec2(0.0);
    uint op_t = t, op_lobes = COAT_LOBE_R | COAT_LOBE_T;
    LocalSample r;
    r.wi = wi_w;
    r.f = vec3(0.0);
    r.pdf = 0.0;
    r.flags = 0u;
    bool r_ok = false;

    // The query under way, in its local frame (wo, wi), and the walks' state.
    uint query = 0u, mode = COAT_F;
    LocalFrame fr = local_frame(n, wo_w);
    vec3 wo = wo_w, wi = wi_w;
    LocalSample res = r;
    uint rng = 0u;
    uint stage = CS_Q_NEXT;
    uint s = 0u, depth = 0u;
    vec3 f = vec3(0.0), beta = vec3(0.0), w = vec3(0.0), f_exit = vec3(0.0);
    float z = thick, sum = 0.0, pdf = 0.0, base_pdf = 0.0;
    LocalSample wos = r, wis = r;
    bool ok_o = false, specular = false, flip = false, ok = false;

    while (stage != CS_FAIL) {
        // A sampling operation draws its three numbers here (but the first of a sampling
        // query, which has the caller's).
        if (op != COAT_OP_NONE) {
            if (op != COAT_OP_EVAL && op != COAT_OP_BASE_EVAL && op_draw) {
                op_uc = coat_next(rng);
                op_u = coat_next2(rng);
            }
            if (op == COAT_OP_BASE) {
                r_ok = coat_base_sample(b, op_wo, op_u, r);
            } else if (op == COAT_OP_BASE_EVAL) {
                r.f = coat_base_f(b, op_wo, op_wi);
                r.pdf = coat_base_pdf(b, op_wo, op_wi);
                r_ok = true;
            } else {
                r_ok = coat_iface(a, eta, op_wo, op_wi, op == COAT_OP_SAMPLE, op_uc, op_u, op_t, op_lobes, r);
            }
        }
        op = COAT_OP_NONE;
        op_draw = true;
        op_t = t;
        op_lobes = COAT_LOBE_R | COAT_LOBE_T;

        // f: the interface's own reflection, then `samples` walks that enter through wo's
        // side and leave through wi's, adding wi's transmission at each visit of the base
        // (and, for a rough interface, the exit towards wi after each base bounce) by MIS.
        if (stage == CS_Q_NEXT) {
            query = (queries & COAT_Q_F) != 0u ? COAT_Q_F
                  : (queries & COAT_Q_PDF) != 0u ? COAT_Q_PDF
                  : (queries & COAT_Q_SAMPLE) != 0u ? COAT_Q_SAMPLE
                  : (queries & COAT_Q_PDF_REV) != 0u ? COAT_Q_PDF_REV : 0u;
            if (query == 0u) {
                ok = true;
                break;
            }
            queries &= ~query;
            mode = query == COAT_Q_F ? COAT_F : query == COAT_Q_SAMPLE ? COAT_SAMPLE : COAT_PDF;
            bool rev = query == COAT_Q_PDF_REV;
            fr = local_frame(n, rev ? wi_w : wo_w);
            wo = to_local(fr, rev ? wi_w : wo_w);
            wi = to_local(fr, rev ? wo_w : wi_w);
            s = 0u;
            sum = 0.0;
            if (mode == COAT_SAMPLE) {
                if (!(wo.z > 0.0)) break;
                flip = wo.z < 0.0;
                if (flip) wo = -wo;
                op = COAT_OP_SAMPLE;
                op_wo = wo;
                op_uc = u3.x;
                op_u = u3.yz;
                op_draw = false;
                stage = CS_S_FIRST;
            } else {
                if (wo.z < 0.0) {
                    wo = -wo;
                    wi = -wi;
                }
                if (mode == COAT_PDF) {
                    stage = CS_P_START;
                } else if (!(wi.z > 0.0) || !(wo.z > 0.0)) {
                    stage = CS_Q_NEXT;   // f = 0
                } else {
                    rng = coat_rng_seed(wo, wi);
                    op = COAT_OP_EVAL;
                    op_wo = wo;
                    op_wi = wi;
                    stage = CS_F_FIRST;
                }
            }
        } else if (stage == CS_F_FIRST) {
            f = float(samples) * r.f;
            stage = CS_F_BEGIN;
        } else if (stage == CS_F_BEGIN) {
            if (s == samples) {
                f_out = f / float(samples);
                stage = CS_Q_NEXT;
                continue;
            }
            op = COAT_OP_SAMPLE;
            op_wo = wo;
            op_lobes = COAT_LOBE_T;
            stage = CS_F_WOS;
        } else if (stage == CS_F_WOS) {
            if (!r_ok) {
                ++s;
                stage = CS_F_BEGIN;
            } else {
                wos = r;
                op = COAT_OP_SAMPLE;
                op_wo = wi;
                op_t = coat_other(t);
                op_lobes = COAT_LOBE_T;
                stage = CS_F_WIS;
            }
        } else if (stage == CS_F_WIS) {
            if (!r_ok) {
                ++s;
                stage = CS_F_BEGIN;
            } else {
                wis = r;
                beta = wos.f * abs(wos.wi.z) / wos.pdf;
                z = thick;
                w = wos.wi;
                depth = 0u;
                stage = CS_F_STEP;
            }
        } else if (stage == CS_F_STEP) {
            float m = max(beta.x, max(beta.y, beta.z));
            bool stop = depth >= max_depth;
            if (!stop && depth > 3u && m < 0.25) {
                float q = max(0.0, 1.0 - m);
                if (coat_next(rng) < q) stop = true;
                else beta /= 1.0 - q;
            }
            bool at_interface = !stop;
            if (stop) {
                ++s;
                stage = CS_F_BEGIN;
            } else if (medium) {
                // The scattering layer: a free flight of unit extinction along w.
                float dz = -log(1.0 - coat_next(rng)) * abs(w.z);
                float zp = w.z > 0.0 ? z + dz : z - dz;
                if (zp == z) {
                    // (A flight too short to leave the boundary, as pbrt-v4 skips it.)
                    at_interface = false;
                    ++depth;
                } else if (0.0 < zp && zp < thick) {
                    // A scattering event: light arriving along the presampled exit
                    // direction, then the phase function's new direction (and light
                    // leaving along it through the interface towards wi).
                    at_interface = false;
                    float ph = hg_phase(-w, -wis.wi, b.g);
                    float wt = top_smooth ? 1.0 : power_heuristic(wis.pdf, ph);
                    vec3 nee = vec3(ph * wt * coat_tr(zp - thick, wis.wi));
                    if (top_smooth && base_smooth) {
                        // Between a smooth coat and a smooth conductor light also reaches
                        // the exit along -wis.wi by mirror reflections (see coated.rs).
                        vec3 up = -wis.wi;
                        vec3 v = vec3(up.xy, -up.z);
                        vec3 fb = fr_conductor(abs(up.z), b.base_eta, b.base_k);
                        float rr = fr_dielectric(abs(up.z), 1.0 / eta);
                        float tl = coat_tr(thick, up);
                        nee = (vec3(ph * coat_tr(zp - thick, up)) + hg_phase(-w, v, b.g) * coat_tr(zp, v) * fb * tl)
                            / (vec3(1.0) - rr * fb * tl * tl);
                    }
                    f += beta * b.albedo * nee * wis.f / wis.pdf;
                    vec3 wp = hg_sample(-w, b.g, coat_next2(rng));
                    float p = hg_phase(-w, wp, b.g);
                    if (p > 0.0 && wp.z != 0.0) {
                        beta *= b.albedo;
                        w = wp;
                        z = zp;
                    }
                    if (p > 0.0 && wp.z > 0.0 && !top_smooth) {
                        exit_len = thick - zp;
                        exit_own = p;
                        exit_one = false;
                        op = COAT_OP_EVAL;
                        op_wo = -w;
                        op_wi = wi;
                        stage = CS_F_EXIT_F;
                    } else {
                        ++depth;
                    }
                } else {
                    z = clamp(zp, 0.0, thick);
                }
            } else {
                z = z == thick ? 0.0 : thick;
                beta *= coat_tr(thick, w);
            }
            if (at_interface) {
                if (z == thick) {
                    op = COAT_OP_SAMPLE;
                    op_wo = -w;
                    op_lobes = COAT_LOBE_R;
                    stage = CS_F_TOP;
                } else {
                    op = COAT_OP_BASE_EVAL;
                    op_wo = -w;
                    op_wi = -wis.wi;
                    stage = CS_F_BASE_NEE;
                }
            }
        } else if (stage == CS_F_BASE_NEE) {
            float wt = top_smooth ? 1.0 : power_heuristic(wis.pdf, r.pdf);
            f += beta * r.f * abs(wis.wi.z) * wt * coat_tr(thick, wis.wi) * wis.f / wis.pdf;
            op = COAT_OP_BASE;
            op_wo = -w;
            stage = CS_F_BASE;
        } else if (stage == CS_F_BASE) {
            if (!r_ok) {
                ++s;
                stage = CS_F_BEGIN;
            } else {
                beta *= r.f * abs(r.wi.z) / r.pdf;
                w = r.wi;
                base_pdf = r.pdf;
                if (top_smooth) {
                    ++depth;
                    stage = CS_F_STEP;
                } else {
                    exit_len = thick;
                    exit_own = base_pdf;
                    exit_one = base_smooth;
                    op = COAT_OP_EVAL;
                    op_wo = -w;
                    op_wi = wi;
                    stage = CS_F_EXIT_F;
                }
            }
        } else if (stage == CS_F_TOP) {
            if (!r_ok) {
                ++s;
                stage = CS_F_BEGIN;
            } else {
                beta *= r.f * abs(r.wi.z) / r.pdf;
                w = r.wi;
                ++depth;
                stage = CS_F_STEP;
            }
        } else if (stage == CS_F_EXIT_F) {
            f_exit = r.f;
            if (f_exit == vec3(0.0)) {
                ++depth;
                stage = CS_F_STEP;
            } else {
                // wis's density (see coated.rs)
                op = COAT_OP_EVAL;
                op_wo = wi;
                op_wi = -w;
                op_lobes = COAT_LOBE_T;
                stage = CS_F_EXIT_PDF;
            }
        } else if (stage == CS_F_EXIT_PDF) {
            // (exit_own: the density of the base's or the phase function's strategy that
            // made w; a smooth base's delta sample is the only strategy.)
            f += beta * coat_tr(exit_len, w) * f_exit * (exit_one ? 1.0 : power_heuristic(exit_own, r.pdf));
            ++depth;
            stage = CS_F_STEP;

        // pdf: the interface's reflection, then `samples` estimates of the density of
        // paths through the layer (a mixture with the uniform density, as pbrt's).
        } else if (stage == CS_P_START) {
            rng = coat_rng_seed(wi, wo);
            if (wo.z * wi.z > 0.0) {
                op = COAT_OP_EVAL;
                op_wo = wo;
                op_wi = wi;
                op_lobes = COAT_LOBE_R;
                stage = CS_P_FIRST;
            } else {
                s = samples;
                stage = CS_P_BEGIN;
            }
        } else if (stage == CS_P_FIRST) {
            sum = float(samples) * r.pdf;
            stage = CS_P_BEGIN;
        } else if (stage == CS_P_BEGIN) {
            if (s == samples) {
                float p = 0.1 / (4.0 * PI) + 0.9 * sum / float(samples);
                stage = CS_Q_NEXT;
                if (query == COAT_Q_PDF) pdf_out = p;
                else if (query == COAT_Q_PDF_REV) pdf_rev_out = p;
                else {
                    res.f *= p / res.pdf;
                    res.pdf = p;
                    if (any(isinf(res.f)) || any(isnan(res.f)) || res.f == vec3(0.0)) break;
                    stage = CS_S_DONE;
                }
            } else {
                op = COAT_OP_SAMPLE;
                op_wo = wo;
                op_t = TRANSPORT_RADIANCE;
                op_lobes = COAT_LOBE_T;
                stage = CS_P_WOS;
            }
        } else if (stage == CS_P_WOS) {
            ok_o = r_ok;
            wos = r;
            op = COAT_OP_SAMPLE;
            op_wo = wi;
            op_t = TRANSPORT_IMPORTANCE;
            op_lobes = COAT_LOBE_T;
            stage = CS_P_WIS;
        } else if (stage == CS_P_WIS) {
            ++s;
            stage = CS_P_BEGIN;
            if (ok_o && r_ok) {
                wis = r;
                op = COAT_OP_BASE_EVAL;
                op_wo = -wos.wi;
                op_wi = -wis.wi;
                stage = CS_P_BASE_PDF;
            }
        } else if (stage == CS_P_BASE_PDF) {
            stage = CS_P_BEGIN;
            base_pdf = r.pdf;   // (the base's density between wos and wis)
            if (top_smooth) {
                sum += base_pdf;
            } else {
                op = COAT_OP_BASE;
                op_wo = -wos.wi;
                stage = CS_P_BASE;
            }
        } else if (stage == CS_P_BASE) {
            stage = CS_P_BEGIN;
            if (r_ok) {
                float r_pdf = base_pdf;
                sum += power_heuristic(wis.pdf, r_pdf) * r_pdf;
                base_pdf = r.pdf;
                op = COAT_OP_EVAL;
                op_wo = -r.wi;
                op_wi = wi;
                stage = CS_P_EXIT;
            }
        } else if (stage == CS_P_EXIT) {
            sum += (base_smooth ? 1.0 : power_heuristic(base_pdf, r.pdf)) * r.pdf;
            stage = CS_P_BEGIN;

        // Sampling: the interface from above; a reflection is the sample, a transmission
        // walks between the base and the interface until it leaves through the interface.
        } else if (stage == CS_S_FIRST) {
            if (!r_ok) {
                stage = CS_FAIL;
            } else if ((r.flags & BSDF_LOBE_REFLECTION) != 0u) {
                res = r;
                stage = CS_S_END;
            } else {
                w = r.wi;
                specular = (r.flags & BSDF_LOBE_DELTA) != 0u;
                rng = coat_rng_seed(wo, u3);
                f = r.f * abs(r.wi.z);
                pdf = r.pdf;
                z = thick;
                depth = 0u;
                stage = CS_S_STEP;
            }
        } else if (stage == CS_S_STEP) {
            float rr = max(f.x, max(f.y, f.z)) / pdf;
            bool stop = depth >= max_depth;
            if (!stop && depth > 3u && rr < 0.25) {
                float q = max(0.0, 1.0 - rr);
                if (coat_next(rng) < q) stop = true;
                else pdf *= 1.0 - q;
            }
            bool at_interface = !(stop || w.z == 0.0);
            if (!at_interface) {
                stage = CS_FAIL;
            } else if (medium) {
                float dz = -log(1.0 - coat_next(rng)) * abs(w.z);
                float zp = w.z > 0.0 ? z + dz : z - dz;
                if (zp == z) {
                    at_interface = false;
                    stage = CS_FAIL;
                } else if (0.0 < zp && zp < thick) {
                    at_interface = false;
                    vec3 wp = hg_sample(-w, b.g, coat_next2(rng));
                    float p = hg_phase(-w, wp, b.g);
                    if (!(p > 0.0) || wp.z == 0.0) {
                        stage = CS_FAIL;
                    } else {
                        f *= b.albedo;   // (and p in f and pdf alike: left out, see coated.rs)
                        specular = false;
                        w = wp;
                        z = zp;
                        ++depth;
                    }
                } else {
                    z = clamp(zp, 0.0, thick);
                }
            } else {
                z = z == thick ? 0.0 : thick;
                f *= coat_tr(thick, w);
            }
            if (at_interface) {
                op = z == 0.0 ? COAT_OP_BASE : COAT_OP_SAMPLE;
                op_wo = -w;
                stage = CS_S_NEXT;
            }
        } else if (stage == CS_S_NEXT) {
            if (!r_ok) {
                stage = CS_FAIL;
            } else {
                f *= r.f;
                pdf *= r.pdf;
                specular = specular && (r.flags & BSDF_LOBE_DELTA) != 0u;
                w = r.wi;
                if ((r.flags & BSDF_LOBE_TRANSMISSION) != 0u) {
                    res.flags = wo.z * w.z > 0.0 ? BSDF_LOBE_REFLECTION : BSDF_LOBE_TRANSMISSION;
                    if (specular) res.flags |= BSDF_LOBE_DELTA;
                    res.wi = w;
                    res.f = f;
                    res.pdf = pdf;
                    stage = CS_S_END;
                } else {
                    f *= abs(r.wi.z);
                    ++depth;
                    stage = CS_S_STEP;
                }
            }
        }


        // The walk's sample: a delta one is final; otherwise the pdf estimate of its
        // direction replaces the walk's density (keeping f/pdf).
        if (stage == CS_S_END) {
            if ((res.flags & BSDF_LOBE_DELTA) != 0u) {
                stage = CS_S_DONE;
            } else {
                wi = res.wi;
                s = 0u;
                sum = 0.0;
                stage = CS_P_START;
            }
        }
        if (stage == CS_S_DONE) {
            if (flip) res.wi = -res.wi;
            smp.wi = from_local(fr, res.wi);
            smp.f = res.f;
            smp.pdf = res.pdf;
            smp.flags = res.flags;
            wi_w = smp.wi;
            if ((res.flags & BSDF_LOBE_DELTA) != 0u) queries &= ~COAT_Q_PDF_REV;
            stage = CS_Q_NEXT;
        }
    }
    return ok;
}
#endif
