// Participating media (FEATURE_MEDIA): pbrt-v4's homogeneous medium and, with
// FEATURE_GRID_MEDIA, its uniformgrid and rgbgrid; the medium a ray is in (a medium code:
// MEDIUM_VACUUM or the GpuMedium's index + 1), and the two questions light transport asks
// of a medium along a ray: where a path's next event is (free-flight sampling, with the
// emission it passes: FreeFlight, sample_medium) and how much of a shadow ray's light gets
// through (medium_segment_transmittance). CPU mirror: src/media.rs.
//
// RGB media are chromatic: sigma_t differs per channel. A distance is drawn from the
// density of one channel picked uniformly, and weighed by the mean of the three channels'
// densities (the one-sample MIS of the three, the balance heuristic: pbrt-v4's hero
// wavelength with its spectral MIS, for three channels), so that every channel is
// estimated without bias and none is sampled from a density that ignores it. Grids draw
// tentative collisions from a majorant and decide real or null (below, grid_track).
#ifndef MEDIA_GLSL
#define MEDIA_GLSL
#extension GL_EXT_control_flow_attributes : require
#include "bindings.glsl"
#include "sampling.glsl"
#include "features.glsl"
#include "noise.glsl"

layout(std430, set = 0, binding = BINDING_MEDIA) readonly buffer MediumBuffer { GpuMedium media[]; };

// The medium a ray leaving a surface of material m along w is in: the outside medium of
// the material's interface where w is on the side of pbrt's geometric normal ng, the
// inside one otherwise; the medium it arrived in (current) where the material bounds none.
uint medium_after(uint m, vec3 ng, vec3 w, uint current) {
    if ((materials[m].info.y & MATERIAL_MEDIUM_INTERFACE) == 0u) return current;
    uint packed = floatBitsToUint(materials[m].emission.w);
    return dot(w, ng) > 0.0 ? packed >> 16 : packed & 0xFFFFu;
}

bool material_passes_through(uint m) {
    return (materials[m].info.y & MATERIAL_PASS_THROUGH) != 0u;
}

vec3 medium_sigma_t(uint code) {
    return media[code - 1u].sigma_a.xyz + media[code - 1u].sigma_s.xyz;
}

float medium_g(uint code) { return media[code - 1u].sigma_a.w; }

// exp(-sigma_t d) per channel, 1 where sigma_t is 0 (also at d = INF).
vec3 medium_transmittance(vec3 sigma_t, float d) {
    return vec3(sigma_t.x > 0.0 ? exp(-sigma_t.x * d) : 1.0,
                sigma_t.y > 0.0 ? exp(-sigma_t.y * d) : 1.0,
                sigma_t.z > 0.0 ? exp(-sigma_t.z * d) : 1.0);
}

// Grid media (FEATURE_GRID_MEDIA, pbrt-v4's uniformgrid and rgbgrid): the extinction is a
// density grid's trilinear value times sigma_a + sigma_s (or an RGB grid's sigma_a +
// sigma_s, grid_point), bounded in each cell of a coarse majorant
// grid by a constant. Distances are drawn from that majorant (one for the three channels:
// the largest's), cell by cell along the ray (a DDA), and each tentative collision is real
// or null: a free flight chooses (delta tracking, by its channel's extinction), a shadow
// ray's transmittance multiplies each channel by the null fraction 1 - sigma_t / majorant
// (ratio tracking). The numbers after a ray's first come from a small generator seeded by a
// hash (pbrt-v4's volpath seeds its tracking so, from two of the sampler's numbers), so
// that a flight is a function of its ray and its two numbers in every integrator.
// (A word of it: the NanoVDB grids' headers and brick tables hold integers.)
uint medium_grid_word(uint i) {
    return floatBitsToUint(grid_value(i));
}

bool medium_is_grid(uint code) {
    return has_feature(FEATURE_GRID_MEDIA) && media[code - 1u].info.x != MEDIUM_HOMOGENEOUS;
}

float medium_random(inout uint state) {
    state = hash_pcg(state);
    return float(state >> 8u) * (1.0 / 16777216.0);
}

// pbrt's SampledGrid lookup: the samples at the cells' centres of the unit cube, trilinear
// between them, zero outside.
float grid_sample(uint first, uvec3 res, ivec3 i) {
    if (any(lessThan(i, ivec3(0))) || any(greaterThanEqual(i, ivec3(res)))) return 0.0;
    return grid_value(first + (uint(i.z) * res.y + uint(i.y)) * res.x + uint(i.x));
}

float grid_lookup(uint first, uvec3 res, vec3 p) {
    vec3 s = p * vec3(res) - 0.5;
    vec3 f = floor(s);
    ivec3 i = ivec3(f);
    vec3 t = s - f;
    float x00 = mix(grid_sample(first, res, i), grid_sample(first, res, i + ivec3(1, 0, 0)), t.x);
    float x10 = mix(grid_sample(first, res, i + ivec3(0, 1, 0)), grid_sample(first, res, i + ivec3(1, 1, 0)), t.x);
    float x01 = mix(grid_sample(first, res, i + ivec3(0, 0, 1)), grid_sample(first, res, i + ivec3(1, 0, 1)), t.x);
    float x11 = mix(grid_sample(first, res, i + ivec3(0, 1, 1)), grid_sample(first, res, i + ivec3(1, 1, 1)), t.x);
    return mix(mix(x00, x10, t.y), mix(x01, x11, t.y), t.z);
}

// The same of an RGB grid (three floats per sample).
vec3 grid_sample3(uint first, uvec3 res, ivec3 i) {
    if (any(lessThan(i, ivec3(0))) || any(greaterThanEqual(i, ivec3(res)))) return vec3(0.0);
    uint k = first + 3u * ((uint(i.z) * res.y + uint(i.y)) * res.x + uint(i.x));
    return vec3(grid_value(k), grid_value(k + 1u), grid_value(k + 2u));
}

vec3 grid_lookup3(uint first, uvec3 res, vec3 p) {
    vec3 s = p * vec3(res) - 0.5;
    vec3 f = floor(s);
    ivec3 i = ivec3(f);
    vec3 t = s - f;
    vec3 x00 = mix(grid_sample3(first, res, i), grid_sample3(first, res, i + ivec3(1, 0, 0)), t.x);
    vec3 x10 = mix(grid_sample3(first, res, i + ivec3(0, 1, 0)), grid_sample3(first, res, i + ivec3(1, 1, 0)), t.x);
    vec3 x01 = mix(grid_sample3(first, res, i + ivec3(0, 0, 1)), grid_sample3(first, res, i + ivec3(1, 0, 1)), t.x);
    vec3 x11 = mix(grid_sample3(first, res, i + ivec3(0, 1, 1)), grid_sample3(first, res, i + ivec3(1, 1, 1)), t.x);
    return mix(mix(x00, x10, t.y), mix(x01, x11, t.y), t.z);
}

// A NanoVDB grid's voxel at index ijk from its bricks (CPU mirror: src/nanovdb.rs's
// Bricks::value; the header at grid_value(h), abi.h): 0 outside them and where a brick's
// table entry is 0.
float bricks_value(uint h, ivec3 ijk) {
    ivec3 r = ijk - ivec3(medium_grid_word(h + 12u), medium_grid_word(h + 13u), medium_grid_word(h + 14u));
    uvec3 dims = uvec3(medium_grid_word(h + 15u), medium_grid_word(h + 16u), medium_grid_word(h + 17u));
    if (any(lessThan(r, ivec3(0))) || any(greaterThanEqual(uvec3(r) >> 3u, dims))) return 0.0;
    uvec3 b = uvec3(r) >> 3u;
    uint t = medium_grid_word(medium_grid_word(h + 18u) + (b.z * dims.y + b.y) * dims.x + b.x);
    if (t == 0u) return 0.0;
    uvec3 l = uvec3(r) & 7u;
    return grid_value(medium_grid_word(h + 19u) + (t - 1u) * 512u + l.x + 8u * l.y + 64u * l.z);
}

// A NanoVDB grid at p of the unit cube (CPU mirror: src/scene/mod.rs's SparseGrid::lookup):
// its index-space point, then pbrt-v4's trilinear filter (values at integer points; z
// first, then y, then x; a + w (b - a)).
float bricks_lookup(uint h, vec3 p) {
    vec4 q = vec4(p, 1.0);
    vec3 x = vec3(dot(vec4(grid_value(h), grid_value(h + 1u), grid_value(h + 2u), grid_value(h + 3u)), q),
                  dot(vec4(grid_value(h + 4u), grid_value(h + 5u), grid_value(h + 6u), grid_value(h + 7u)), q),
                  dot(vec4(grid_value(h + 8u), grid_value(h + 9u), grid_value(h + 10u), grid_value(h + 11u)), q));
    vec3 f = floor(x);
    ivec3 i = ivec3(f);
    vec3 w = x - f;
    float v[2];
    [[dont_unroll]] for (int a = 0; a < 2; ++a) {
        float z0 = bricks_value(h, i + ivec3(a, 0, 0));
        float z1 = bricks_value(h, i + ivec3(a, 0, 1));
        float z2 = bricks_value(h, i + ivec3(a, 1, 0));
        float z3 = bricks_value(h, i + ivec3(a, 1, 1));
        float y0 = z0 + w.z * (z1 - z0);
        float y1 = z2 + w.z * (z3 - z2);
        v[a] = y0 + w.y * (y1 - y0);
    }
    return v[0] + w.x * (v[1] - v[0]);
}

// pbrt-v4's procedural cloud's density at p in the medium's space (CPU mirror:
// src/media.rs's cloud_density): the point moved by two octaves of the noise's gradient
// (forward differences of 0.01, as pbrt-v4's DNoise) scaled by the wispiness, five octaves
// of noise there, thinning with height, plus a floor of density below y = 0.5; in [0, 1].
// (One noise call site: lavapipe inlines each.)
float cloud_density(uint table, vec3 p, float density, float wispiness, float frequency) {
    vec3 pp = frequency * p;
    float vomega = 0.05 * wispiness;
    float vlambda = 10.0;
    float d = 0.0;
    float omega = 0.5;
    float lambda = 1.0;
    float n0 = 0.0;
    vec3 grad = vec3(0.0);
    int first = wispiness > 0.0 ? 0 : 8;
    // Calls 0-7: the two perturbations (the noise at q, then at q + 0.01 along x, y, z);
    // 8-12: the octaves.
    [[dont_unroll]] for (int k = first; k < 13; ++k) {
        vec3 q;
        if (k < 8) {
            int a = k & 3;
            q = vlambda * pp + (a == 0 ? vec3(0.0) : 0.01 * vec3(a == 1, a == 2, a == 3));
        } else {
            q = lambda * pp;
        }
        float n = noise3(table, q);
        if (k < 8) {
            int a = k & 3;
            if (a == 0) n0 = n; else grad[a - 1] = (n - n0) / 0.01;
            if (a == 3) {
                pp += vomega * grad;
                vomega *= 0.5;
                vlambda *= 1.99;
            }
        } else {
            d += omega * n;
            omega *= 0.5;
            lambda *= 1.99;
        }
    }
    d = clamp((1.0 - p.y) * 4.5 * density * d, 0.0, 1.0);
    d += 2.0 * max(0.0, 0.5 - p.y);
    return clamp(d, 0.0, 1.0);
}

// pbrt-v4's BlackbodySpectrum (Planck's law over its peak) at `kelvin` as linear sRGB, from
// the table at texel(table) (CPU mirror and maker: src/media.rs's blackbody and
// blackbody_table): log2 of its first temperature, entries per unit of log2 T, their count,
// then RGB entries; linear between them in log2 T, falling as T^-4 above the last.
vec3 blackbody(uint table, float kelvin) {
    float lo = texel(table), per = texel(table + 1u), last = texel(table + 2u) - 1.0;
    float x = (log2(kelvin) - lo) * per;
    float tail = x > last ? exp2((last - x) / per * 4.0) : 1.0;
    x = clamp(x, 0.0, last);
    float f = floor(min(x, last - 1.0));
    uint i = table + 3u + 3u * uint(f);
    vec3 a = vec3(texel(i), texel(i + 1u), texel(i + 2u));
    vec3 b = vec3(texel(i + 3u), texel(i + 4u), texel(i + 5u));
    return tail * mix(a, b, x - f);
}

// A grid medium at p in its unit cube (CPU mirror: src/media.rs's grid_point): its
// extinction, absorption and scattering, and (where `emits`) its emitted radiance.
// uniformgrid: the density times the medium's coefficients, Le times the Le scale;
// rgbgrid: its grids (1 where not given) times the medium's scales; cloud: its density
// times the medium's coefficients, no emission.
void grid_point(GpuMedium m, vec3 p, bool emits, out vec3 sigma_t, out vec3 sigma_a, out vec3 sigma_s, out vec3 le) {
    le = vec3(0.0);
    if (has_feature(FEATURE_RGB_GRID_MEDIA) && m.info.x == MEDIUM_RGBGRID) {
        uvec3 res = m.density_res.xyz;
        sigma_a = m.sigma_a.xyz * (m.info.y == MEDIUM_NO_GRID ? vec3(1.0) : grid_lookup3(m.info.y, res, p));
        sigma_s = m.sigma_s.xyz * (m.density_res.w == MEDIUM_NO_GRID ? vec3(1.0) : grid_lookup3(m.density_res.w, res, p));
        sigma_t = sigma_a + sigma_s;
        if (emits) le = m.emission.xyz * grid_lookup3(m.info.z, m.le_res.xyz, p);
        return;
    }
    if (has_feature(FEATURE_NANOVDB_MEDIA) && m.info.x == MEDIUM_NANOVDB) {
        float d = bricks_lookup(m.info.y, p);
        sigma_t = d * (m.sigma_a.xyz + m.sigma_s.xyz);
        sigma_a = d * m.sigma_a.xyz;
        sigma_s = d * m.sigma_s.xyz;
        if (emits && m.info.z != MEDIUM_NO_GRID) {
            float kelvin = (bricks_lookup(m.info.z, p) - m.sigma_s.w) * m.emission.w;
            le = kelvin > 100.0 ? m.emission.xyz * blackbody(m.le_res.w, kelvin) : vec3(0.0);
        }
        return;
    }
    float density;
    if (has_feature(FEATURE_CLOUD_MEDIA) && m.info.x == MEDIUM_CLOUD) {
        vec3 pm = uintBitsToFloat(m.density_res.xyz) + p * uintBitsToFloat(m.le_res.xyz);
        density = cloud_density(m.info.y, pm, uintBitsToFloat(m.density_res.w), uintBitsToFloat(m.le_res.w),
                                uintBitsToFloat(m.info.z));
        emits = false;
    } else {
        density = grid_lookup(m.info.y, m.density_res.xyz, p);
    }
    sigma_t = density * (m.sigma_a.xyz + m.sigma_s.xyz);
    sigma_a = density * m.sigma_a.xyz;
    sigma_s = density * m.sigma_s.xyz;
    if (emits) {
        le = m.emission.xyz * grid_lookup(m.info.z, m.le_res.xyz, p);
        // A temperature: its blackbody above 100 K (pbrt-v4's rule), nothing below.
        if (has_feature(FEATURE_TEMPERATURE_MEDIA) && m.density_res.w != MEDIUM_NO_GRID) {
            float kelvin = (grid_lookup(m.density_res.w, m.density_res.xyz, p) - m.sigma_s.w) * m.emission.w;
            le *= kelvin > 100.0 ? blackbody(m.le_res.w, kelvin) : vec3(0.0);
        }
    }
}

// A ray's next event in a medium, drawn once for the whole ray through the media it
// crosses (pass-through boundaries between them), from one pair of numbers: a channel c
// (u.x) and an exponential tau ~ Exp(1) (u.y) that the ray spends segment by segment (in
// channel c's extinction in homogeneous media, in the majorant in grids); the ray
// collides where it is spent. Each channel's technique (c = 0, 1, 2) would draw the same
// events with its own probability; the flight keeps, per channel, the factors in which
// they differ (`depth`, as -log), and weighs its event by f / the mean of the three
// (the one-sample MIS of the channels, the balance heuristic: pbrt-v4's hero wavelength
// with its spectral MIS, for three channels). A homogeneous segment of length t adds
// sigma_t t; a null collision in a grid -log(1 - sigma_t / majorant). The medium's
// emission is estimated at every collision, real or null, and summed in `emitted`
// (relative to the throughput where the flight started).
struct FreeFlight {
    uint c;
    float tau;      // what is left of the current exponential
    vec3 depth;     // per channel, -log of the factors the channels' techniques differ by
    vec3 emitted;
    uint rng;       // the grids' generator
};

FreeFlight free_flight_start(vec2 u) {
    FreeFlight f;
    f.c = min(uint(u.x * 3.0), 2u);
    f.tau = -log(1.0 - u.y);
    f.depth = vec3(0.0);
    f.emitted = vec3(0.0);
    f.rng = hash_pcg(floatBitsToUint(u.x) ^ hash_pcg(floatBitsToUint(u.y)));
    return f;
}

// A grid segment [0, len) of the ray (o, d): the majorant cells it crosses (a DDA over
// the unit cube's MEDIUM_MAJORANT_RES^3 cells), the tentative collisions in them. scatter:
// delta tracking, a collision is real with probability sigma_t[c] / majorant (true, t
// and weight sigma_s / the channels' mean extinction, both times exp(-depth)); else every
// collision is null (ratio tracking: exp(-depth) is then the transmittance).
bool grid_track(inout FreeFlight f, uint code, vec3 o, vec3 d, float len, bool scatter, out float t_hit,
                out vec3 weight) {
    t_hit = len;
    weight = vec3(1.0);
    GpuMedium m = media[code - 1u];
    vec3 uo = vec3(dot(m.unit_x, vec4(o, 1.0)), dot(m.unit_y, vec4(o, 1.0)), dot(m.unit_z, vec4(o, 1.0)));
    vec3 ud = vec3(dot(m.unit_x.xyz, d), dot(m.unit_y.xyz, d), dot(m.unit_z.xyz, d));
    // The segment's part in the unit cube.
    float t = 0.0;
    float t1 = len;
    for (int a = 0; a < 3; ++a) {
        if (ud[a] != 0.0) {
            float ta = -uo[a] / ud[a];
            float tb = (1.0 - uo[a]) / ud[a];
            t = max(t, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        } else if (uo[a] < 0.0 || uo[a] > 1.0) {
            t1 = -1.0;
        }
    }
    if (!(t < t1)) return false;
    const float R = float(MEDIUM_MAJORANT_RES);
    ivec3 cell = clamp(ivec3(floor((uo + t * ud) * R)), ivec3(0), ivec3(MEDIUM_MAJORANT_RES - 1));
    ivec3 stp = ivec3(0);
    vec3 next = vec3(INF);
    vec3 delta = vec3(INF);
    for (int a = 0; a < 3; ++a) {
        if (ud[a] > 0.0) {
            stp[a] = 1;
            next[a] = ((float(cell[a]) + 1.0) / R - uo[a]) / ud[a];
            delta[a] = 1.0 / (R * ud[a]);
        } else if (ud[a] < 0.0) {
            stp[a] = -1;
            next[a] = (float(cell[a]) / R - uo[a]) / ud[a];
            delta[a] = -1.0 / (R * ud[a]);
        }
    }
    bool emits = scatter && m.emission.xyz != vec3(0.0);
    [[dont_unroll]] while (t < t1) {
        float end = min(min(next.x, min(next.y, next.z)), t1);
        float maj = grid_value(m.info.w + (uint(cell.z) * uint(MEDIUM_MAJORANT_RES) + uint(cell.y)) * uint(MEDIUM_MAJORANT_RES) + uint(cell.x));
        [[dont_unroll]] while (maj > 0.0 && f.tau < maj * (end - t)) {
            t += f.tau / maj;
            vec3 p = uo + t * ud;
            vec3 sigma_t, sigma_a, sigma_s, le;
            grid_point(m, p, emits, sigma_t, sigma_a, sigma_s, le);
            vec3 a = exp(-f.depth);
            float mean_a = dot(a, vec3(1.0 / 3.0));
            if (emits) f.emitted += a * sigma_a * le / (maj * mean_a);
            if (scatter && medium_random(f.rng) * maj < sigma_t[f.c]) {
                t_hit = t;
                weight = a * sigma_s / dot(a * sigma_t, vec3(1.0 / 3.0));
                return true;
            }
            f.depth -= log(max(vec3(1.0) - sigma_t / maj, vec3(0.0)));
            // (A flight's weights are ratios: its factors can be kept near 1.)
            if (scatter) f.depth -= min(f.depth.x, min(f.depth.y, f.depth.z));
            else if (all(isinf(f.depth))) return false;
            f.tau = -log(1.0 - medium_random(f.rng));
        }
        if (maj > 0.0) f.tau -= maj * (end - t);
        t = end;
        if (next.x <= next.y && next.x <= next.z) {
            cell.x += stp.x;
            next.x += delta.x;
        } else if (next.y <= next.z) {
            cell.y += stp.y;
            next.y += delta.y;
        } else {
            cell.z += stp.z;
            next.z += delta.z;
        }
        if (any(lessThan(cell, ivec3(0))) || any(greaterThanEqual(cell, ivec3(MEDIUM_MAJORANT_RES)))) break;
    }
    return false;
}

// A segment of the ray (o, d) of length len (INF: none ends it) in the medium `code`:
// true when the flight ends in it, at t (from the segment's start), weight
// sigma_s / the channels' mean extinction, times the flight's factors; else the segment's
// optical depth is spent.
bool free_flight_segment(inout FreeFlight f, uint code, vec3 o, vec3 d, float len, out float t, out vec3 weight) {
    t = len;
    weight = vec3(1.0);
    if (code == MEDIUM_VACUUM) return false;
    if (medium_is_grid(code)) return grid_track(f, code, o, d, len, true, t, weight);
    vec3 sigma_t = medium_sigma_t(code);
    float sc = sigma_t[f.c];
    if (sc > 0.0 && f.tau < sc * len) {
        t = f.tau / sc;
        vec3 tr = exp(-(f.depth + sigma_t * t));
        float pdf = dot(sigma_t * tr, vec3(1.0 / 3.0));
        weight = media[code - 1u].sigma_s.xyz * tr / pdf;
        f.emitted += media[code - 1u].sigma_a.xyz * media[code - 1u].emission.xyz * tr / pdf;
        return true;
    }
    // (A clear channel spends nothing, even along an endless segment.)
    vec3 spent = vec3(sigma_t.x > 0.0 ? sigma_t.x * len : 0.0, sigma_t.y > 0.0 ? sigma_t.y * len : 0.0,
                      sigma_t.z > 0.0 ? sigma_t.z * len : 0.0);
    f.tau -= spent[f.c];
    f.depth += spent;
    return false;
}

// The weight of a flight that reached the end of its ray: its factors over their mean.
vec3 free_flight_through(FreeFlight f) {
    vec3 tr = exp(-f.depth);
    float p = dot(tr, vec3(1.0 / 3.0));
    return p > 0.0 ? tr / p : vec3(0.0);
}

// A path's next event along one ray (o, d) in the medium `code` (the path tracer's and
// BDPT's, which draw a new flight at each boundary), tmax the distance to the surface it
// meets (INF: none): scattered, a scattering vertex at t with weight sigma_s Tr / p(t);
// else the surface is reached with weight Tr / P(reaching it). emitted: the medium's
// emission along the ray before the event (to be multiplied by the throughput before it).
struct MediumEvent {
    bool scattered;
    float t;
    vec3 weight;
    vec3 emitted;
};

MediumEvent sample_medium(uint code, vec3 o, vec3 d, float tmax, vec2 u) {
    FreeFlight f = free_flight_start(u);
    MediumEvent ev;
    ev.scattered = free_flight_segment(f, code, o, d, tmax, ev.t, ev.weight);
    if (!ev.scattered) ev.weight = free_flight_through(f);
    ev.emitted = f.emitted;
    return ev;
}

// The transmittance of a shadow ray's segment (o, d) of length len in the medium `code`:
// exact in a homogeneous medium, ratio-tracked in a grid with the generator `rng` (seeded
// by the caller from a hash of the ray: medium_ray_seed).
vec3 medium_segment_transmittance(uint code, vec3 o, vec3 d, float len, inout uint rng) {
    if (code == MEDIUM_VACUUM) return vec3(1.0);
    if (medium_is_grid(code)) {
        FreeFlight f;
        f.c = 0u;
        f.tau = -log(1.0 - medium_random(rng));
        f.depth = vec3(0.0);
        f.emitted = vec3(0.0);
        f.rng = rng;
        float t;
        vec3 w;
        grid_track(f, code, o, d, len, false, t, w);
        rng = f.rng;
        return exp(-f.depth);
    }
    return medium_transmittance(medium_sigma_t(code), len);
}

uint medium_ray_seed(vec3 o, vec3 d) {
    uvec3 a = floatBitsToUint(o), b = floatBitsToUint(d);
    return hash_pcg(a.x ^ hash_pcg(a.y ^ hash_pcg(a.z ^ hash_pcg(b.x ^ hash_pcg(b.y ^ hash_pcg(b.z))))));
}
#endif
