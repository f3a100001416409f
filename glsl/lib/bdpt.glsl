// Bidirectional path tracing's physics, written once and driven two ways: BDPT's kernels
// (lib/bdpt_wave.glsl, lib/bdpt_pass.glsl) walk whole subpaths and combine every (s,t)
// strategy; MMLT's (lib/mmlt_wave.glsl) evaluate one strategy per sample. Subpath walks, the four kinds of connection and their MIS
// weights live here.
//
// MIS: power heuristic over every strategy of a path, computed recursively without
// storing whole paths (the dVCM/dVC quantities of Georgiev's "Implementing vertex
// connection and merging", 2012, restricted to connections). Every pdf is squared on
// the way in (mis()), so the stored quantities are already power-heuristic sums.
// N = light_paths() light subpaths run per pass (bdpt: width * height), so light tracing
// (t = 1) has N samples per pixel estimate: it divides its contribution by N and its
// MIS ratios carry N. MMLT keeps the same N so that its weights are bdpt's.
//
// Randomness comes only through the sampler interface, which the including kernel
// defines before this file (sampler_pcg.glsl or sampler_pss.glsl):
//   uint sample_u32(uint stream); float sample_1d(uint stream);
//   vec2 sample_2d(uint stream);  vec3 sample_3d(uint stream);
// with streams STREAM_CAMERA (camera walk), STREAM_LIGHT (light walk) and
// STREAM_CONNECT (the s = 1 light sample).
//
#ifndef BDPT_GLSL
#define BDPT_GLSL
#extension GL_EXT_control_flow_attributes : require
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "visibility.glsl"
#include "camera.glsl"
#include "media.glsl"

// Scattering vertices of the longest path that gets every strategy.
uint max_scatter() { return scene.max_depth; }
// Whether camera walks can go beyond max_scatter() (maxdepth -1: Russian roulette, and
// the BSDF-only weights of s = 0 and s = 1 there). A constant where the kernel is built
// for bounded walks (MMLT's: BDPT_BOUNDED_WALKS) or specialized for a bounded scene, so
// that their code is left out.
bool walks_unbounded() {
#ifdef BDPT_BOUNDED_WALKS
    return false;
#else
    return has_feature(FEATURE_UNBOUNDED);
#endif
}
// N, the light subpaths of a pass.
float light_paths() { return float(scene.width) * float(scene.height); }
// A pixel's area on the image plane at distance 1.
float pixel_area() {
    vec4 w = scene.cam_window;
    return (w.y - w.x) * (w.w - w.z) / light_paths();
}

float mis(float x) { return x * x; }

// Solid-angle pdf with which the camera samples direction w (unit, from the eye) for a
// given pixel: 1 / (pixel_area() cos^3(theta)).
float camera_pdf_w(vec3 w) {
    float c = dot(w, scene.cam_forward.xyz);
    return 1.0 / (pixel_area() * c * c * c);
}

// The pdf of the scene's importancesampling mode (wo where the walk came from, wi the
// other direction; n the shading normal on the side of the arriving path).
float material_pdf(BsdfParams b, vec3 n, vec3 wo, vec3 wi) {
    return bsdf_pdf(b, scene.sample_mode, n, wo, wi);
}

// A vertex of a subpath, with what later connections need: a surface's, or (in scenes
// with media) a scattering point in a medium (vertex_is_medium: material holds
// PATH_VERTEX_MEDIUM and the medium's code; n = ns = ng = w, so that the surfaces' side
// tests pass; no cosine there: vertex_cos).
struct PathVertex {
    vec3 p;
    uint material;
    vec3 n;          // unit geometric normal on the side the path arrived from
    float dvcm;      // MIS running sums at this vertex
    vec3 w;          // unit direction toward the previous vertex
    float dvc;
    vec3 beta;       // throughput up to (not including) this vertex's BSDF
    uint emitter;    // NO_EMITTER unless the surface emits
    vec3 ng;         // geometric normal as the surface has it (emission sides, and the
                     // material's outside for refraction)
    vec2 uv;         // texture coordinates
    vec3 ns;         // unit shading normal on n's side: the BSDF's frame (geometric
                     // normals convert densities and place rays)
    vec4 tex0;       // the material's texture values (Surface.tex0, tex1)
    vec4 tex1;
};

// A vertex as a wavefront keeps it between stages (the path-vertex buffer, a walk):
// what a connection reads (its emitter is not kept, and of its geometric normal only
// the side). Its material texture values are kept beside it, in scenes that have them.
GpuPathVertex pack_vertex(PathVertex y) {
    GpuPathVertex v;
    bool front = dot(y.n, y.ng) > 0.0;
    v.p = vec4(y.p, uintBitsToFloat(y.material | (front ? PATH_VERTEX_FRONT : 0u)));
    v.n = vec4(y.n, y.dvcm);
    v.wi = vec4(y.w, y.dvc);
    v.beta = vec4(y.beta, y.uv.y);
    v.ns = vec4(y.ns, y.uv.x);
    return v;
}

PathVertex unpack_vertex(GpuPathVertex g) {
    PathVertex y;
    y.p = g.p.xyz;
    uint m = floatBitsToUint(g.p.w);
    y.material = m & ~PATH_VERTEX_FRONT;
    y.n = g.n.xyz;
    y.dvcm = g.n.w;
    y.w = g.wi.xyz;
    y.dvc = g.wi.w;
    y.beta = g.beta.xyz;
    y.emitter = NO_EMITTER;
    y.ng = (m & PATH_VERTEX_FRONT) != 0u ? y.n : -y.n;   // (only its side matters: emission is not read here)
    y.uv = vec2(g.ns.w, g.beta.w);
    y.ns = g.ns.xyz;
    // (Its texture values are kept beside it: the caller's.)
    y.tex0 = vec4(0.0);
    y.tex1 = vec4(0.0);
    return y;
}

bool vertex_is_medium(PathVertex v) { return has_feature(FEATURE_MEDIA) && (v.material & PATH_VERTEX_MEDIUM) != 0u; }

uint vertex_medium(PathVertex v) { return v.material & 0xFFFFu; }

// The geometric cosine a vertex gives a segment along dir in the MIS sums' density
// conversions and the geometry term: 1 in a medium (a volume density).
float vertex_cos(PathVertex v, vec3 dir) { return vertex_is_medium(v) ? 1.0 : abs(dot(v.n, dir)); }

// The cosine that multiplies the vertex's BSDF toward wi (shading_cosine): 1 in a medium.
float vertex_shading_cos(PathVertex v, vec3 wi, uint transport) {
    return vertex_is_medium(v) ? 1.0 : shading_cosine(v.n, v.ns, v.w, wi, transport);
}

// The normal a ray leaving the vertex along dir is offset along: none in a medium.
vec3 vertex_side(PathVertex v, vec3 dir) {
    if (vertex_is_medium(v)) return vec3(0.0);
    return dot(v.n, dir) > 0.0 ? v.n : -v.n;
}

// The medium a ray leaving the vertex along dir is in, `current` the medium of the walk
// that found it (the medium on both sides of a surface that bounds none).
uint vertex_medium_toward(PathVertex v, vec3 dir, uint current) {
    if (!has_feature(FEATURE_MEDIA) || vertex_is_medium(v)) return current;
    return medium_after(v.material, v.ng, dir, current);
}

// The shade class of a vertex: its material's, SHADE_CLASS_MEDIUM in a medium.
uint vertex_class(PathVertex v) {
    return vertex_is_medium(v) ? SHADE_CLASS_MEDIUM : material_class(materials[v.material].info.x);
}

// The phase function at a medium vertex asked as bsdf_ask asks a BSDF (wi given, or drawn
// when `draw`): the Henyey-Greenstein function of the vertex's medium, which is its own
// density both ways (the scattering coefficient is in the walk's throughput: the free
// flight's weight).
bool phase_ask(PathVertex x, bool draw, vec3 u, inout BsdfSample q, out float pdf_rev) {
    float g = medium_g(vertex_medium(x));
    if (draw) q.wi = hg_sample(x.w, g, u.xy);
    float p = hg_phase(x.w, q.wi, g);
    q.f = vec3(p);
    q.pdf = p;
    q.flags = 0u;
    pdf_rev = p;
    return p > 0.0;
}

// The BSDF at a path vertex: its material, seen from the side of its normal n.
BsdfParams vertex_bsdf(PathVertex v) {
    return material_bsdf(materials[v.material], dot(v.n, v.ng) > 0.0, v.tex0, v.tex1);
}

#ifdef SHADE_CLASS
// A shade stage's (BDPT's, MMLT's: SHADE_CLASS defined) BSDF at x (SHADE_CLASS_MEDIUM:
// none, the phase function is asked by phase_ask) and its question (bsdf_ask's
// arguments).
BsdfParams class_bsdf(PathVertex x) {
#if SHADE_CLASS == SHADE_CLASS_MEDIUM
    BsdfParams b;
    b.kind = 0u;
    return b;
#else
    return vertex_bsdf(x);
#endif
}

bool class_ask(BsdfParams b, PathVertex x, bool draw, vec3 u, uint transport, bool want_fwd, bool want_rev,
               inout BsdfSample q, out float pdf_rev) {
#if SHADE_CLASS == SHADE_CLASS_MEDIUM
    return phase_ask(x, draw, u, q, pdf_rev);
#else
    return bsdf_ask(b, scene.sample_mode, x.ns, x.w, draw, u, transport, want_fwd, want_rev, q, pdf_rev);
#endif
}
#endif

// A subpath being walked: the next ray and the running throughput and MIS sums.
struct Walk {
    vec3 o;
    vec3 d;
    vec3 beta;
    float dvcm;
    float dvc;
    uint vertices;     // surface vertices found so far
    bool infinite;     // light walks from a directional light
    float prev_pdf_w;  // camera walks beyond max_scatter(): the last bounce's BSDF pdf,
    bool prev_delta;   // ... whether it was a delta lobe,
    vec3 prev_p;       // ... and the vertex it left from; light walks from a light at
                       // infinity, before their first vertex: where the light enters
                       // (LightEmission.enter: a portal's crossing)
    bool escaped;      // the last ray left the scene (toward the environment)
    uint medium;       // the medium code of the next ray (FEATURE_MEDIA)
};

PathVertex vertex_at(Walk w, Surface s, vec3 toward_prev) {
    PathVertex v;
    v.p = s.p;
    v.material = s.material;
    v.n = dot(s.ng, toward_prev) < 0.0 ? -s.ng : s.ng;
    v.ns = dot(s.ng, toward_prev) < 0.0 ? -s.ns : s.ns;
    v.w = toward_prev;
    v.beta = w.beta;
    v.dvcm = w.dvcm;
    v.dvc = w.dvc;
    v.emitter = s.emitter;
    v.ng = s.ng;
    v.uv = s.uv;
    v.tex0 = s.tex0;
    v.tex1 = s.tex1;
    return v;
}

// A scattering vertex of the walk in its medium at p.
PathVertex medium_vertex_at(Walk w, vec3 p, vec3 toward_prev) {
    PathVertex v;
    v.p = p;
    v.material = PATH_VERTEX_MEDIUM | w.medium;
    v.n = toward_prev;
    v.ns = toward_prev;
    v.ng = toward_prev;
    v.w = toward_prev;
    v.beta = w.beta;
    v.dvcm = w.dvcm;
    v.dvc = w.dvc;
    v.emitter = NO_EMITTER;
    v.uv = vec2(0.0);
    v.tex0 = vec4(0.0);
    v.tex1 = vec4(0.0);
    return v;
}

// The medium a light's subpath starts in: an area light's by its material's interface
// (the side it emits toward), another light's its own (GpuEmitter.info.w's high bits).
// (n: the point's normal, dir the direction the light leaves along).
uint light_medium(uint e, vec3 n, vec3 dir) {
    if (!has_feature(FEATURE_MEDIA)) return MEDIUM_VACUUM;
    GpuEmitter em = emitters[e];
    if (emitter_kind_has_surface(em.info.x)) return medium_after(emitter_material(em), n, dir, MEDIUM_VACUUM);
    return em.info.w >> 16;
}

// ---- light subpaths ---------------------------------------------------------------

// Start a light subpath: pick a light by power (light stream), place a point and a
// direction on it. False when there is no light or it emits nothing this way.
bool light_walk_start(out Walk w, out LightEmission le, out uint e) {
    w.o = vec3(0.0);
    w.d = vec3(0.0, 0.0, 1.0);
    w.beta = vec3(0.0);
    w.dvcm = 0.0;
    w.dvc = 0.0;
    w.vertices = 0u;
    w.infinite = false;
    w.prev_pdf_w = 0.0;
    w.prev_delta = false;
    w.prev_p = vec3(0.0);
    w.escaped = false;
    w.medium = MEDIUM_VACUUM;
    e = 0u;
    if (scene.emitter_count == 0u) return false;
    e = pick_emitter(sample_u32(STREAM_LIGHT));
    vec2 u_pos = sample_2d(STREAM_LIGHT);
    vec3 u_dir = sample_3d(STREAM_LIGHT);
    if (!sample_light_emission(e, u_pos, u_dir, le)) return false;
    bool delta = emitter_kind_is_delta(le.kind);
    w.beta = le.Le * (le.cos_l / le.pdf_emit);
    w.dvcm = mis(le.pdf_pos / le.pdf_emit);
    // (No camera subpath can hit a delta or hidden light: no such strategy to weigh.)
    w.dvc = delta || le.hidden ? 0.0 : mis(le.cos_l / le.pdf_emit);
    w.infinite = emitter_kind_is_at_infinity(le.kind);
    if (w.infinite) w.prev_p = le.enter;
    w.o = delta ? le.p : offset_ray_origin(le.p, dot(le.n, le.dir) > 0.0 ? le.n : -le.n);
    w.d = le.dir;
    w.medium = light_medium(e, le.n, le.dir);
    return true;
}

// The next surface vertex of a light subpath (y_i, i = w.vertices after the call): the
// surface s at distance t along the walk's ray (a wavefront's trace stage found it).
// False when the surface is grazed (cos^2 in the MIS sums must not underflow to 0).
bool light_walk_vertex(inout Walk w, float t, Surface s, out PathVertex v) {
    vec3 wi = -w.d;
    float cos_in = abs(dot(s.ng, wi));
    if (!(cos_in > 1e-6)) return false;
    // (Light from infinity reaches no point before it enters: its portal.)
    if (w.vertices == 0u && w.infinite && dot(s.p - w.prev_p, w.d) < 0.0) return false;
    if (!(w.vertices == 0u && w.infinite)) w.dvcm *= mis(t * t);
    w.dvcm /= mis(cos_in);
    w.dvc /= mis(cos_in);
    w.vertices++;
    v = vertex_at(w, s, wi);
    return true;
}

// The next vertex of a light subpath in its medium, at distance t along its ray.
void light_walk_medium_vertex(inout Walk w, float t, out PathVertex v) {
    vec3 p = w.o + t * w.d;
    // (Light from infinity reaches no point before it enters: its portal.)
    if (w.vertices == 0u && w.infinite && dot(p - w.prev_p, w.d) < 0.0) w.beta = vec3(0.0);
    if (!(w.vertices == 0u && w.infinite)) w.dvcm *= mis(t * t);
    w.vertices++;
    v = medium_vertex_at(w, p, -w.d);
}

// Continue a subpath from its vertex v after its BSDF sample bs (and the density back,
// pdf_rev; the shade stages ask both where they ask the BSDF's other questions): the
// throughput, and (update_mis) the MIS sums, follow the new direction. (The sample's
// numbers are drawn from the walk's stream, camera or light; walk_survives then plays
// the roulette beyond the cap.)
//
// A delta lobe (SmallVCM's specular update; Georgiev 2012, tech. rep. eqs. 53-55): no
// connection can end at this vertex, so dVCM restarts at 0 and dVC keeps its sum, times
// cos^2 (the lobe's forward and reverse pdfs are equal and cancel).
bool walk_scatter_sampled(inout Walk w, PathVertex v, BsdfSample bs, float pdf_rev, uint transport, bool update_mis) {
    if (!shading_side_agrees(v.n, v.ns, bs.wi)) return false;
    bool delta = (bs.flags & BSDF_LOBE_DELTA) != 0u;
    float cos_out = vertex_cos(v, bs.wi);   // geometric: for the MIS sums' densities
    w.beta = v.beta * bs.f * (vertex_shading_cos(v, bs.wi, transport) / bs.pdf);
    if (w.beta == vec3(0.0)) return false;
    if (update_mis) {
        if (delta) {
            w.dvcm = 0.0;
            w.dvc *= mis(cos_out);
        } else {
            w.dvc = mis(cos_out / bs.pdf) * (v.dvc * mis(pdf_rev) + v.dvcm);
            w.dvcm = mis(1.0 / bs.pdf);
        }
    }
    w.prev_pdf_w = bs.pdf;
    w.prev_delta = delta;
    w.prev_p = v.p;
    w.o = offset_ray_origin(v.p, vertex_side(v, bs.wi));
    w.d = bs.wi;
    w.medium = vertex_medium_toward(v, bs.wi, w.medium);
    return true;
}

// Whether the camera walk is beyond the strategies' cap (maxdepth -1: Russian roulette,
// no MIS sums).
bool walk_beyond(Walk w, bool camera) { return walks_unbounded() && camera && w.vertices > max_scatter(); }

// The camera walk's Russian roulette beyond the cap, after the scattering.
bool walk_survives(inout Walk w, bool beyond) {
    if (beyond) {
        float survive = min(1.0, max(w.beta.x, max(w.beta.y, w.beta.z)));
        if (sample_1d(STREAM_CAMERA) >= survive) return false;
        w.beta /= survive;
    }
    return true;
}

// ---- camera subpaths --------------------------------------------------------------

// A camera subpath that starts with the camera's ray (o, d) (camera_walk_start, or a
// ray a wavefront stage drew before).
void camera_walk_from(vec3 o, vec3 d, out Walk w) {
    w.o = o;
    w.d = d;
    w.beta = vec3(1.0);
    w.dvcm = mis(light_paths() / camera_pdf_w(w.d));
    w.dvc = 0.0;
    w.vertices = 0u;
    w.infinite = false;
    w.prev_pdf_w = 0.0;
    w.prev_delta = false;
    w.prev_p = w.o;
    w.escaped = false;
    w.medium = has_feature(FEATURE_MEDIA) ? scene.camera_medium : MEDIUM_VACUUM;
}

// Start a camera subpath through the film position `film` in [0,1)^2 (whole image);
// a thin lens draws its point from the camera stream. (The lens point's area pdf is the
// same for every strategy, and no light subpath can hit the lens, so it cancels from
// the MIS weights as a pinhole's delta does.)
void camera_walk_start(vec2 film, out Walk w) {
    vec2 u_lens = vec2(0.0);
    if (camera_has_lens()) u_lens = sample_2d(STREAM_CAMERA);
    vec3 o, d;
    camera_ray(film, u_lens, o, d);
    camera_walk_from(o, d, w);
}

// The next surface vertex z_k of a camera subpath (k = w.vertices after the call;
// strategies there have t = k + 1): the surface s at distance t along the walk's ray. The
// MIS sums stop being updated past max_scatter(), where only s = 0 and s = 1 remain
// (bdpt's beyond-the-cap regime). False when the surface is grazed.
bool camera_walk_vertex(inout Walk w, float t, Surface s, out PathVertex v) {
    vec3 wo = -w.d;
    float cos_in = abs(dot(s.ng, wo));
    if (!(cos_in > 1e-6)) return false;
    w.vertices++;
    if (w.vertices - 1u <= max_scatter()) {
        w.dvcm *= mis(t * t) / mis(cos_in);
        w.dvc /= mis(cos_in);
    }
    v = vertex_at(w, s, wo);
    return true;
}

// The next vertex of a camera subpath in its medium, at distance t along its ray.
void camera_walk_medium_vertex(inout Walk w, float t, out PathVertex v) {
    w.vertices++;
    if (w.vertices - 1u <= max_scatter()) w.dvcm *= mis(t * t);
    v = medium_vertex_at(w, w.o + t * w.d, -w.d);
}

// ---- strategies: each returns its unweighted contribution and its MIS weight ------

// What a MIS weight asks of an emitter: the densities with which emitter e emits from
// the point p (geometric normal ng) in the unit direction dir, by area (x) and by
// direction (y) (emitter_emission_pdfs). The s = 0 and s = 1 strategies at a camera
// vertex each ask one; a kernel that has both asks them in one place (bdpt_hit.comp).
struct EmissionQuery {
    uint e;
    vec3 p;
    vec3 ng;
    vec3 dir;
};

vec2 emission_pdfs(EmissionQuery q) {
    vec2 pdfs;
    emitter_emission_pdfs(q.e, q.p, q.ng, q.dir, pdfs.x, pdfs.y);
    return pdfs;
}

// s = 0: the camera subpath found emission, at its last vertex z (environment false), or
// in the environment when its last ray escaped (environment true; z is not read). The
// path has w.vertices - 1 scattering vertices in the first case, w.vertices in the
// second. (A camera ray that escapes at once has only this strategy: no light subpath
// reaches the camera from infinity.) In two halves: emission_found (the unweighted
// value, and whether its weight needs the emitter's densities: `ask`, the query q) and
// emission_weight (the MIS weight, given those densities).
bool emission_found(Walk w, PathVertex z, bool environment, out vec3 value, out EmissionQuery q, out bool ask) {
    value = vec3(0.0);
    ask = false;
    q.e = z.emitter;
    uint scatter = w.vertices - 1u;
    vec3 Le, beta;
    if (environment) {
        if (scene.environment == NO_EMITTER || !w.escaped) return false;
        q.e = scene.environment;
        Le = environment_radiance(w.o, w.d);
        q.p = w.o;
        q.ng = vec3(0.0);
        q.dir = -w.d;
        beta = w.beta;
        scatter = w.vertices;
    } else {
        if (q.e == NO_EMITTER) return false;
        Le = emitted_radiance(z.material, z.ng, z.w);
        q.p = z.p;
        q.ng = z.ng;
        q.dir = z.w;
        beta = z.beta;
    }
    if (Le == vec3(0.0)) return false;
    ask = !(environment && scatter == 0u) && scatter <= max_scatter();
    value = beta * Le;
    return true;
}

float emission_weight(Walk w, PathVertex z, bool environment, EmissionQuery q, vec2 pdfs) {
    uint scatter = environment ? w.vertices : w.vertices - 1u;
    if (environment && scatter == 0u) return 1.0;
    if (scatter <= max_scatter()) {
        float dvcm = environment ? w.dvcm : z.dvcm;
        float dvc = environment ? w.dvc : z.dvc;
        float w_cam = mis(pdfs.x) * dvcm + mis(pdfs.y) * dvc;
        return 1.0 / (1.0 + w_cam);
    }
    if (!walks_unbounded()) return 0.0;   // (never: bounded walks stay within max_scatter())
    if (w.prev_delta) return 1.0;
    float pdf_light = environment ? environment_pdf(w.d) : emitter_pdf_solid_angle(q.e, w.prev_p, q.p, q.ng);
    return power_heuristic(w.prev_pdf_w, pdf_light);
}

// s = 1 at the camera vertex z (the walk's last): a fresh sample on a light, picked
// and placed with the connection stream, in two halves: the light's (light_sample_draw:
// the emitter picked and its point, and the query of the densities with which it would
// emit toward z, for the MIS weight) and the BSDF's (below).
bool light_sample_draw(PathVertex z, out LightSample ls, out EmissionQuery q) {
    q.e = 0u;
    if (scene.emitter_count == 0u) return false;
    q.e = pick_emitter(sample_u32(STREAM_CONNECT));
    vec2 u = sample_2d(STREAM_CONNECT);
    if (!sample_emitter(q.e, z.p, u, ls) || !(ls.pdf > 0.0)) return false;
    q.p = ls.p;
    q.ng = ls.n;
    q.dir = -ls.wi;
    return true;
}

// The BSDF's half of the s = 1 strategy at z for the light sample ls, in three steps so
// that a kernel can ask the BSDF its question in one place for this and for the t = 1
// connection (bdpt_shade.glsl): light_sample_faces (can the BSDF send the light toward
// z.w; the shading cosine), the question (bsdf_eval_pdfs toward ls.wi, radiance, its
// forward pdf and, if light_sample_weighs_all, its reverse one), light_sample_end (the unweighted contribution, the MIS weight and the shadow ray
// (o, d, tmax)). False when it cannot contribute.
bool light_sample_faces(BsdfParams b, PathVertex z, LightSample ls, out float cos_s) {
    cos_s = 1.0;
    if (vertex_is_medium(z)) return true;
    return direct_light_faces(b, z.n, z.ns, z.w, ls.wi, cos_s);
}

// Whether the s = 1 strategy weighs itself against every strategy (paths within
// max_scatter()) or, beyond it, against the camera subpath's BSDF sampling alone; the
// BSDF's reverse pdf is wanted only for the former.
bool light_sample_weighs_all(Walk w) { return w.vertices <= max_scatter(); }

bool light_sample_end(Walk w, PathVertex z, LightSample ls, vec2 pdfs, float cos_s, vec3 f, float pdf_dir,
                      float pdf_rev, out vec3 value, out float weight, out vec3 o, out vec3 d, out float tmax) {
    value = vec3(0.0);
    weight = 0.0;
    o = z.p;
    d = vec3(0.0, 0.0, 1.0);
    tmax = 0.0;
    if (f == vec3(0.0)) return false;
    float cos_z = vertex_cos(z, ls.wi);
    if (light_sample_weighs_all(w)) {
        float pdf_pos = pdfs.x;
        float pdf_emit = pdfs.y;
        float d2 = ls.dist == INF ? 1.0 : ls.dist * ls.dist;
        float w_light = ls.unhittable ? 0.0 : mis(pdf_dir / ls.pdf);
        float w_cam = mis(pdf_emit * cos_z / (pdf_pos * d2)) * (z.dvcm + z.dvc * mis(pdf_rev));
        weight = 1.0 / (w_light + 1.0 + w_cam);
    } else {
        if (walks_unbounded()) weight = light_sample_mis_weight(ls, pdf_dir);
    }
    light_sample_shadow_ray(z.p, vertex_is_medium(z) ? vec3(0.0) : z.n, ls, o, d, tmax);
    value = z.beta * f * ls.L * (cos_s / ls.pdf);
    return true;
}

// The lens numbers of a t = 1 strategy, from the connection stream (which no t = 1
// strategy uses otherwise); none for a pinhole.
vec2 camera_lens_numbers() {
    vec2 u = vec2(0.0);
    if (camera_has_lens()) u = sample_2d(STREAM_CONNECT);
    return u;
}

// t = 1 from the light vertex y: the camera (a point of its lens) sees it, in three
// steps as the s = 1 strategy (light_sample_faces): camera_connection_faces (the lens
// point `eye`, the pixel `px` it lands on, the direction and distance to the eye; false
// when the camera cannot see y), the question to the BSDF (bsdf_eval_pdfs toward the eye,
// importance, its reverse pdf),
// camera_connection_end (the contribution, its MIS weight and the shadow ray (o, d,
// tmax) for the caller to trace and count).
bool camera_connection_faces(PathVertex y, out vec3 eye, out uvec2 px, out vec3 to_eye, out float dist) {
    eye = camera_lens_point(camera_lens_numbers());
    if (!camera_project(y.p, eye, px, to_eye, dist)) return false;
    if (!(abs(dot(y.n, to_eye)) > 0.0)) return false;
    return dot(y.ns, y.w) > 0.0 && shading_side_agrees(y.n, y.ns, to_eye);
}

bool camera_connection_end(PathVertex y, vec3 eye, vec3 to_eye, float dist, vec3 f, float pdf_rev, out vec3 value,
                           out float weight, out vec3 o, out vec3 d, out float tmax) {
    value = vec3(0.0);
    weight = 0.0;
    o = y.p;
    d = vec3(0.0, 0.0, 1.0);
    tmax = 0.0;
    if (f == vec3(0.0)) return false;
    float cos_y = vertex_cos(y, to_eye);
    // The measurement's cosine at y is the geometric cos_y (in pdf_cam_a) times the
    // adjoint BSDF's shading correction (shading_cosine's importance form).
    if (!vertex_is_medium(y)) f *= abs(dot(y.ns, y.w)) / abs(dot(y.n, y.w));
    float pdf_cam_a = camera_pdf_w(-to_eye) * cos_y / (dist * dist);
    float w_light = mis(pdf_cam_a / light_paths()) * (y.dvcm + y.dvc * mis(pdf_rev));
    weight = 1.0 / (1.0 + w_light);
    shadow_ray_to(y.p, vertex_side(y, to_eye), eye, o, d, tmax);
    value = y.beta * f * (pdf_cam_a / light_paths());
    return true;
}

// s = 1, t = 1: the point a light subpath started from, seen by the camera, and the
// shadow ray that decides it. (Delta and hidden lights are not visible to the camera, as
// in the path tracer.)
bool light_point_seen(LightEmission le, uint e, out uvec2 px, out vec3 value, out float weight, out vec3 o,
                      out vec3 d, out float tmax) {
    value = vec3(0.0);
    weight = 0.0;
    px = uvec2(0u);
    o = le.p;
    d = vec3(0.0, 0.0, 1.0);
    tmax = 0.0;
    if (!emitter_kind_has_surface(le.kind) || le.hidden) return false;
    vec3 to_eye;
    float dist;
    vec3 eye = camera_lens_point(camera_lens_numbers());
    if (!camera_project(le.p, eye, px, to_eye, dist)) return false;
    vec3 Le = emitted_radiance(emitter_material(emitters[e]), le.n, to_eye);
    float cos_y = abs(dot(le.n, to_eye));
    if (Le == vec3(0.0) || !(cos_y > 0.0)) return false;
    float pdf_cam_a = camera_pdf_w(-to_eye) * cos_y / (dist * dist);
    float ratio = pdf_cam_a / (light_paths() * le.pdf_pos);   // camera hitting it (s = 0) vs this
    weight = 1.0 / (1.0 + mis(ratio));
    shadow_ray_to(le.p, dot(le.n, to_eye) > 0.0 ? le.n : -le.n, eye, o, d, tmax);
    value = Le * ratio;
    return true;
}

// s >= 2, t >= 2: connect the camera vertex z to the light vertex y, in three steps as
// the other connections: connection_faces (the unit direction dir from z to y and the
// squared distance d2; false when the segment cannot carry light), the questions to both
// vertices' BSDFs (BDPT's and MMLT's shade stages, each by its class), connection_end (the contribution,
// its MIS weight and the shadow ray (o, d, tmax) between the two points).
bool connection_faces(PathVertex z, PathVertex y, out vec3 dir, out float d2) {
    vec3 to = y.p - z.p;
    d2 = dot(to, to);
    dir = vec3(0.0, 0.0, 1.0);
    if (!(d2 > 0.0)) return false;
    dir = to * inversesqrt(d2);
    // (Either vertex may transmit: the cosines' signs say which side the segment leaves.)
    if (!(vertex_cos(z, dir) > 0.0) || !(vertex_cos(y, dir) > 0.0)) return false;
    if (!(dot(z.ns, z.w) > 0.0) || !(dot(y.ns, y.w) > 0.0)) return false;
    return shading_side_agrees(z.n, z.ns, dir) && shading_side_agrees(y.n, y.ns, -dir);
}

// f_z, cam_dir, cam_rev: z's BSDF toward y (radiance) and its pdfs; f_y, light_dir,
// light_rev: y's toward z (importance).
bool connection_end(PathVertex z, PathVertex y, vec3 dir, float d2, vec3 f_z, float cam_dir, float cam_rev,
                    vec3 f_y, float light_dir, float light_rev, out vec3 value, out float weight, out vec3 o,
                    out vec3 d, out float tmax) {
    value = vec3(0.0);
    weight = 0.0;
    o = z.p;
    d = dir;
    tmax = 0.0;
    float cos_z = vertex_cos(z, dir);
    float cos_y = vertex_cos(y, -dir);
    float g = vertex_shading_cos(z, dir, TRANSPORT_RADIANCE) * vertex_shading_cos(y, -dir, TRANSPORT_IMPORTANCE) / d2;
    vec3 c = z.beta * f_z * f_y * y.beta * g;
    if (c == vec3(0.0)) return false;
    // The densities convert with the geometric cosines.
    float w_light = mis(cam_dir * cos_y / d2) * (y.dvcm + y.dvc * mis(light_rev));
    float w_cam = mis(light_dir * cos_z / d2) * (z.dvcm + z.dvc * mis(cam_rev));
    weight = 1.0 / (w_light + 1.0 + w_cam);
    shadow_ray_to(z.p, vertex_side(z, dir), offset_ray_origin(y.p, vertex_side(y, -dir)), o, d, tmax);
    value = c;
    return true;
}

#endif
