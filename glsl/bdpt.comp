// One pass of bidirectional path tracing (integrator `bdpt`). Each invocation owns one
// pixel: it traces a light subpath, connecting every light vertex to the camera (t = 1,
// splatted with float atomics to whichever pixel it lands on) and storing the vertices
// in its slice of the path-vertex buffer, then traces a camera subpath that, at each
// vertex, takes the emission it finds (s = 0), a fresh light sample (s = 1) and a
// connection to every stored light vertex (s >= 2).
//
// MIS: power heuristic over every strategy of a path, computed recursively without
// storing whole paths (the dVCM/dVC quantities of Georgiev's "Implementing vertex
// connection and merging", 2012, restricted to connections). Every pdf below is squared
// on the way in (mis()), so the stored quantities are already power-heuristic sums.
// N = width * height light subpaths run per pass, so light tracing (t = 1) has N samples
// per pixel estimate: it divides its contribution by N and its MIS ratios carry N.
//
// Films: film[pixel] (camera strategies, written only by the pixel's own invocation) and
// splat[] (t = 1 strategies, float atomics). The image is (film + splat) / spp.
// A contribution that comes out NaN or infinite is left out and counted in
// stats[STAT_NONFINITE] (per contribution, not per sample).
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bindings.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "camera.glsl"

layout(std430, set = 0, binding = BINDING_SPLAT) buffer SplatBuffer { float splat[]; };
layout(std430, set = 0, binding = BINDING_PATH_VERTICES) buffer PathVertexBuffer { GpuPathVertex light_vertices[]; };
// Debug output (--bdpt-strategies): per (s,t), a weighted and an unweighted film of
// vec4s, laid out [strategy][weighted 0 / unweighted 1][pixel].
layout(std430, set = 0, binding = BINDING_STRATEGIES) buffer StrategyBuffer { float strategy_film[]; };

uint rays_traced = 0u;
uint max_scatter;      // scattering vertices of the longest path
float light_paths;     // N
float pixel_area;      // a pixel's area on the image plane at distance 1
uint sample_mode;
uint nonfinite = 0u;

float mis(float x) { return x * x; }

bool closest(vec3 o, vec3 d, out Hit hit) { rays_traced++; return trace_closest(o, d, INF, hit); }

// Is the segment between two surface points a and b (normals na, nb on the sides the
// segment leaves from) unoccluded?
bool visible(vec3 a, vec3 na, vec3 b, vec3 nb) {
    rays_traced++;
    vec3 o = offset_ray_origin(a, na);
    vec3 target = offset_ray_origin(b, nb);
    vec3 to = target - o;
    float dist = length(to);
    if (!(dist > 0.0)) return true;
    return !trace_occluded(o, to / dist, dist);
}

// Solid-angle pdf with which the camera samples direction w (unit, from the eye) for a
// given pixel: 1 / (pixel_area cos^3(theta)).
float camera_pdf_w(vec3 w) {
    float c = dot(w, scene.cam_forward.xyz);
    return 1.0 / (pixel_area * c * c * c);
}

bool finite3(vec3 v) { return !any(isnan(v)) && !any(isinf(v)); }

// Strategy (s, t): s light vertices, t camera vertices (the camera itself included).
// Only the group of strategies [first, first + count) that the host asked for is
// recorded (scene.direct.w = first << 16 | count; 0: none), at group-relative indices:
// when all strategies do not fit one buffer, the host re-renders the same samples once
// per group.
void record_strategy(uint s, uint t, uint pixel, vec3 weighted, vec3 unweighted) {
    uint count = scene.direct.w & 0xffffu;
    if (count == 0u) return;
    uint n = s + t - 2u;
    uint strategy = n * (n + 3u) / 2u + s - (scene.direct.w >> 16);
    if (strategy >= count) return;   // (strategies before the group wrap around to large values)
    uint npix = scene.dims.x * scene.dims.y;
    uint i = ((strategy * 2u) * npix + pixel) * 4u;
    uint j = ((strategy * 2u + 1u) * npix + pixel) * 4u;
    for (uint c = 0u; c < 3u; ++c) {
        atomicAdd(strategy_film[i + c], weighted[c]);
        atomicAdd(strategy_film[j + c], unweighted[c]);
    }
}

// Add one strategy's MIS-weighted contribution to the camera film's running sum L,
// unless it is NaN or infinite (then it is counted and left out, and the sample's other
// strategies still count).
void add_camera(inout vec3 L, uint s, uint t, uint pixel, vec3 unweighted, float weight) {
    vec3 v = unweighted * weight;
    if (!finite3(v) || !finite3(unweighted)) { nonfinite++; return; }
    L += v;
    record_strategy(s, t, pixel, v, unweighted);
}

void add_splat(uvec2 px, uint s, vec3 unweighted, float weight) {
    vec3 v = unweighted * weight;
    if (!finite3(v) || !finite3(unweighted)) { nonfinite++; return; }
    uint pixel = px.y * scene.dims.x + px.x;
    record_strategy(s, 1u, pixel, v, unweighted);
    if (v == vec3(0.0)) return;
    atomicAdd(splat[pixel * 4u + 0u], v.x);
    atomicAdd(splat[pixel * 4u + 1u], v.y);
    atomicAdd(splat[pixel * 4u + 2u], v.z);
}

// t = 1 from a light vertex on a surface: p, n (toward wi), material, wi toward the
// previous light vertex, beta and the vertex's dVCM/dVC. s = index of the vertex + 1.
void connect_to_camera(uint s, vec3 p, vec3 n, uint material, vec3 wi, vec3 beta, float dvcm, float dvc) {
    uvec2 px;
    vec3 to_eye;
    float dist;
    if (!camera_project(p, px, to_eye, dist)) return;
    float cos_y = dot(n, to_eye);
    if (!(cos_y > 0.0)) return;
    GpuMaterial m = materials[material];
    uint kind = uint(m.params.z);
    vec3 f = bsdf_eval(kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, to_eye, wi);
    if (f == vec3(0.0)) return;
    float pdf_cam_a = camera_pdf_w(-to_eye) * cos_y / (dist * dist);
    float pdf_rev = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, to_eye, wi);
    float w_light = mis(pdf_cam_a / light_paths) * (dvcm + dvc * mis(pdf_rev));
    float weight = 1.0 / (1.0 + w_light);
    rays_traced++;
    vec3 o = offset_ray_origin(p, n);
    if (trace_occluded(o, to_eye, length(scene.cam_eye.xyz - o))) return;
    add_splat(px, s, beta * f * (pdf_cam_a / light_paths), weight);
}

// s = 1, t = 1: a point on an area light seen by the camera. (Delta lights are not
// visible to the camera, as in the path tracer.)
void connect_light_point_to_camera(LightEmission le, uint e) {
    uvec2 px;
    vec3 to_eye;
    float dist;
    if (!camera_project(le.p, px, to_eye, dist)) return;
    vec3 Le = emitted_radiance(emitter_material(emitters[e]), le.n, to_eye);
    float cos_y = abs(dot(le.n, to_eye));
    if (Le == vec3(0.0) || !(cos_y > 0.0)) return;
    float pdf_cam_a = camera_pdf_w(-to_eye) * cos_y / (dist * dist);
    float ratio = pdf_cam_a / (light_paths * le.pdf_pos);   // camera hitting it (s = 0) vs this
    float weight = 1.0 / (1.0 + mis(ratio));
    rays_traced++;
    vec3 o = offset_ray_origin(le.p, dot(le.n, to_eye) > 0.0 ? le.n : -le.n);
    if (trace_occluded(o, to_eye, length(scene.cam_eye.xyz - o))) return;
    add_splat(px, 1u, Le * ratio, weight);
}

// Trace the light subpath, splatting t = 1 connections and storing vertices 1..stored
// at light_vertices[base + i - 1]. Returns the number stored.
uint light_subpath(uint base, inout Rng rng) {
    if (scene.counts.x == 0u) return 0u;
    uint e = pick_emitter(rng_block(rng).x);
    vec4 u = rng_to_unit(rng_block(rng));
    LightEmission le;
    if (!sample_light_emission(e, u.xy, vec3(u.z, rng_next2(rng)), le)) return 0u;
    bool delta = le.kind >= EMITTER_POINT;
    if (!delta) connect_light_point_to_camera(le, e);
    if (max_scatter == 0u) return 0u;

    vec3 beta = le.Le * (le.cos_l / le.pdf_emit);
    float dvcm = mis(le.pdf_pos / le.pdf_emit);
    float dvc = delta ? 0.0 : mis(le.cos_l / le.pdf_emit);
    bool infinite = le.kind == EMITTER_DIRECTIONAL;
    vec3 o = delta ? le.p : offset_ray_origin(le.p, dot(le.n, le.dir) > 0.0 ? le.n : -le.n);
    vec3 d = le.dir;
    uint stored = 0u;
    for (uint i = 1u; i <= max_scatter; ++i) {
        Hit hit;
        if (!closest(o, d, hit)) break;
        Surface s = surface_at(hit, o, d);
        vec3 wi = -d;   // toward the previous vertex
        float cos_in = abs(dot(s.ng, wi));
        // Grazing hits end the subpath: cos_in^2 (a MIS factor) must not underflow to 0.
        if (!(cos_in > 1e-6)) break;
        if (!(i == 1u && infinite)) dvcm *= mis(hit.t * hit.t);
        dvcm /= mis(cos_in);
        dvc /= mis(cos_in);
        vec3 n = dot(s.ng, wi) < 0.0 ? -s.ng : s.ng;
        // Vertices that a camera vertex can still connect to (s + t - 2 <= max_scatter
        // with t >= 2) are stored.
        if (i < max_scatter) {
            GpuPathVertex v;
            v.p = vec4(s.p, uintBitsToFloat(s.material));
            v.n = vec4(n, dvcm);
            v.wi = vec4(wi, dvc);
            v.beta = vec4(beta, 0.0);
            light_vertices[base + i - 1u] = v;
            stored = i;
        }
        connect_to_camera(i + 1u, s.p, n, s.material, wi, beta, dvcm, dvc);
        if (i == max_scatter) break;
        GpuMaterial m = materials[s.material];
        uint kind = uint(m.params.z);
        vec3 wn;
        float pdf_fwd;
        if (!bsdf_sample(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wi, rng_next3(rng), wn, pdf_fwd)) break;
        float pdf_rev = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wn, wi);
        vec3 f = bsdf_eval(kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wi, wn);
        float cos_out = dot(n, wn);
        beta *= f * (cos_out / pdf_fwd);
        if (beta == vec3(0.0)) break;
        dvc = mis(cos_out / pdf_fwd) * (dvc * mis(pdf_rev) + dvcm);
        dvcm = mis(1.0 / pdf_fwd);
        o = offset_ray_origin(s.p, n);
        d = wn;
    }
    return stored;
}

// The camera subpath with s = 0, s = 1 and s >= 2 strategies at each vertex. Returns
// the pixel's camera-film contribution.
//
// maxdepth -1: paths of up to max_scatter (BDPT_UNBOUNDED_DEPTH_CAP) scattering vertices
// get every strategy. Longer ones, which only the camera subpath reaches (light
// subpaths are stored, so bounded), go on with Russian roulette up to the path tracer's
// UNBOUNDED_DEPTH_CAP and combine the two strategies left to them, s = 0 and s = 1, by
// the power heuristic, as the path tracer does. Path length splits path space, so the
// two regimes add up to the whole, unbiased.
vec3 camera_subpath(uvec2 pixel, uint base, uint stored, inout Rng rng) {
    uint pixel_index = pixel.y * scene.dims.x + pixel.x;
    vec3 o = scene.cam_eye.xyz;
    vec3 d = camera_ray_direction(pixel, rng_next2(rng));
    vec3 L = vec3(0.0);
    vec3 beta = vec3(1.0);
    float dvcm = mis(light_paths / camera_pdf_w(d));
    float dvc = 0.0;
    bool unbounded = scene.counts.z != 0u;
    uint max_vertices = unbounded ? UNBOUNDED_DEPTH_CAP : max_scatter;
    float prev_pdf_w = 0.0;   // beyond max_scatter: the BSDF pdf of the last bounce
    vec3 prev_p = o;
    for (uint k = 1u; k <= max_vertices + 1u; ++k) {
        // The vertex z_k; strategies here have t = k + 1.
        Hit hit;
        if (!closest(o, d, hit)) break;
        Surface s = surface_at(hit, o, d);
        vec3 wo = -d;
        float cos_in = abs(dot(s.ng, wo));
        // Grazing hits end the subpath: cos_in^2 (a MIS factor) must not underflow to 0.
        if (!(cos_in > 1e-6)) break;
        // Paths through this vertex with every strategy: s = 0 here has k - 1 scattering
        // vertices, s = 1 has k, s >= 2 more.
        bool all_s0 = k - 1u <= max_scatter;
        bool all_s1 = k <= max_scatter;
        if (all_s0) {
            dvcm *= mis(hit.t * hit.t) / mis(cos_in);
            dvc /= mis(cos_in);
        }
        vec3 n = dot(s.ng, wo) < 0.0 ? -s.ng : s.ng;

        // s = 0: the camera subpath found an emitter.
        if (s.emitter != NO_EMITTER) {
            vec3 Le = emitted_radiance(s.material, s.ng, wo);
            if (Le != vec3(0.0)) {
                float weight;
                if (all_s0) {
                    float pdf_pos;
                    float pdf_emit;
                    emitter_emission_pdfs(s.emitter, s.p, s.ng, wo, pdf_pos, pdf_emit);
                    float w_cam = mis(pdf_pos) * dvcm + mis(pdf_emit) * dvc;
                    weight = 1.0 / (1.0 + w_cam);
                } else {
                    weight = power_heuristic(prev_pdf_w, emitter_pdf_solid_angle(s.emitter, prev_p, s.p, s.ng));
                }
                add_camera(L, 0u, k + 1u, pixel_index, beta * Le, weight);
            }
        }
        if (k > max_vertices) break;
        GpuMaterial m = materials[s.material];
        uint kind = uint(m.params.z);

        // s = 1: a fresh sample on a light.
        if (scene.counts.x > 0u) {
            uint e = pick_emitter(rng_block(rng).x);
            vec2 u = rng_next2(rng);
            LightSample ls;
            if (sample_emitter(e, s.p, u, ls) && ls.pdf > 0.0) {
                float cos_z = dot(n, ls.wi);
                vec3 f = cos_z > 0.0 ? bsdf_eval(kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wo, ls.wi) : vec3(0.0);
                if (f != vec3(0.0)) {
                    float pdf_dir = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wo, ls.wi);
                    float weight;
                    if (all_s1) {
                        float pdf_rev = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, ls.wi, wo);
                        float pdf_pos;
                        float pdf_emit;
                        emitter_emission_pdfs(e, ls.p, ls.n, -ls.wi, pdf_pos, pdf_emit);
                        float d2 = ls.dist == INF ? 1.0 : ls.dist * ls.dist;
                        float w_light = ls.delta ? 0.0 : mis(pdf_dir / ls.pdf);
                        float w_cam = mis(pdf_emit * cos_z / (pdf_pos * d2)) * (dvcm + dvc * mis(pdf_rev));
                        weight = 1.0 / (w_light + 1.0 + w_cam);
                    } else {
                        weight = ls.delta ? 1.0 : power_heuristic(ls.pdf, pdf_dir);
                    }
                    rays_traced++;
                    if (light_sample_visible(s.p, n, ls)) add_camera(L, 1u, k + 1u, pixel_index, beta * f * ls.L * (cos_z / ls.pdf), weight);
                }
            }
        }

        // s >= 2: connect to the stored light vertices y_1 .. y_j with j + k <= max_scatter.
        uint last = k < max_scatter ? min(stored, max_scatter - k) : 0u;
        for (uint j = 1u; j <= last; ++j) {
            GpuPathVertex y = light_vertices[base + j - 1u];
            vec3 to = y.p.xyz - s.p;
            float d2 = dot(to, to);
            if (!(d2 > 0.0)) continue;
            vec3 dir = to * inversesqrt(d2);
            float cos_z = dot(n, dir);
            float cos_y = -dot(y.n.xyz, dir);
            if (!(cos_z > 0.0) || !(cos_y > 0.0)) continue;
            GpuMaterial my = materials[floatBitsToUint(y.p.w)];
            uint kind_y = uint(my.params.z);
            vec3 f_z = bsdf_eval(kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wo, dir);
            vec3 f_y = bsdf_eval(kind_y, my.diffuse.xyz, my.specular.xyz, my.params.x, my.params.y, y.n.xyz, -dir, y.wi.xyz);
            vec3 c = beta * f_z * f_y * y.beta.xyz * (cos_z * cos_y / d2);
            if (c == vec3(0.0)) continue;
            float cam_dir = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wo, dir);
            float cam_rev = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, dir, wo);
            float light_dir = bsdf_pdf(sample_mode, kind_y, my.diffuse.xyz, my.specular.xyz, my.params.x, my.params.y, y.n.xyz, y.wi.xyz, -dir);
            float light_rev = bsdf_pdf(sample_mode, kind_y, my.diffuse.xyz, my.specular.xyz, my.params.x, my.params.y, y.n.xyz, -dir, y.wi.xyz);
            float w_light = mis(cam_dir * cos_y / d2) * (y.n.w + y.wi.w * mis(light_rev));
            float w_cam = mis(light_dir * cos_z / d2) * (dvcm + dvc * mis(cam_rev));
            float weight = 1.0 / (w_light + 1.0 + w_cam);
            if (!visible(s.p, n, y.p.xyz, y.n.xyz)) continue;
            add_camera(L, j + 1u, k + 1u, pixel_index, c, weight);
        }

        // Extend the camera subpath.
        vec3 wn;
        float pdf_fwd;
        if (!bsdf_sample(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wo, rng_next3(rng), wn, pdf_fwd)) break;
        float pdf_rev = bsdf_pdf(sample_mode, kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wn, wo);
        vec3 f = bsdf_eval(kind, m.diffuse.xyz, m.specular.xyz, m.params.x, m.params.y, n, wo, wn);
        float cos_out = dot(n, wn);
        beta *= f * (cos_out / pdf_fwd);
        if (beta == vec3(0.0)) break;
        if (k > max_scatter) {
            // Every path through the next vertex is longer than max_scatter: roulette.
            float survive = min(1.0, max(beta.x, max(beta.y, beta.z)));
            if (rng_next(rng) >= survive) break;
            beta /= survive;
        } else {
            dvc = mis(cos_out / pdf_fwd) * (dvc * mis(pdf_rev) + dvcm);
            dvcm = mis(1.0 / pdf_fwd);
        }
        prev_pdf_w = pdf_fwd;
        prev_p = s.p;
        o = offset_ray_origin(s.p, n);
        d = wn;
    }
    return L;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.pass.z);
    if (pixel.x >= scene.dims.x || pixel.y >= min(scene.dims.y, pass_params.pass.w)) return;
    uint index = pixel.y * scene.dims.x + pixel.x;
    max_scatter = scene.counts.y;
    light_paths = float(scene.dims.x) * float(scene.dims.y);
    float pixel_side = 2.0 * scene.cam_eye.w / float(scene.dims.y);
    pixel_area = pixel_side * pixel_side;
    sample_mode = scene.options.z;
    // This invocation's slice of the light-vertex buffer (which holds one band).
    uint stride = max(max_scatter, 2u) - 1u;
    uint base = ((pixel.y - pass_params.pass.z) * scene.dims.x + pixel.x) * stride;
    if (base + stride > uint(light_vertices.length())) {
        atomicAdd(stats[STAT_OUT_OF_RANGE], 1u);
        return;
    }
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < pass_params.pass.y; ++i) {
        Rng rng = rng_init(scene.direct.z, index, pass_params.pass.x + i);
        uint stored = light_subpath(base, rng);
        sum += camera_subpath(pixel, base, stored, rng);
    }
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
    film[index] += vec4(sum, float(rays_traced));
}
