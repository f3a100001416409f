// Emitters: selection by power, position sampling and the matching pdfs.
// Area pdfs of ellipsoids use the exact Jacobian of the affine map:
// dA_world = |det M| * |M^-T q| dA_object for the unit-sphere point q.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL
#include "bindings.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "geometry.glsl"
#include "texture.glsl"
#include "features.glsl"

// Pick an emitter by power with a uniform 32-bit integer x: the first i with
// x < cdf[i] (the last emitter when none). cdf[i] is the end of emitter i's range of
// the 2^32 values, so it is picked with probability exactly (cdf[i] - cdf[i-1]) / 2^32,
// the pick pdf the host stores in radiance.w (an emitter too dim for one value of the
// range is never picked and has pdf 0, so no estimator counts on it).
uint pick_emitter(uint x) {
    uint lo = 0u;
    uint hi = scene.emitter_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) >> 1;
        if (x < emitter_cdf[mid]) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

float emitter_pick_pdf(uint e) { return emitters[e].radiance.w; }

// Point, spot, directional, goniometric and projection lights: positions or directions
// no ray can hit.
bool emitter_kind_is_delta(uint kind) {
    return kind == EMITTER_POINT || kind == EMITTER_SPOT || kind == EMITTER_DIRECTIONAL
           || (has_feature(FEATURE_PROFILE_LIGHTS) && (kind == EMITTER_GONIOMETRIC || kind == EMITTER_PROJECTION));
}

// pbrt-v4's invisible area light (GpuEmitter.info.w, EMITTER_HIDDEN: an area light whose
// shape has alpha 0): it emits as the area light it is, but its surface is cut out of
// every ray (the alpha test), so no ray finds it and only light sampling does. For MIS it
// is a delta light: the strategies that would hit it are not strategies.
bool emitter_is_hidden(GpuEmitter em) { return (em.info.w & 0xFFFFu) == EMITTER_HIDDEN; }

// Triangles and spheres: emitters with a surface a camera can see.
bool emitter_kind_has_surface(uint kind) { return kind == EMITTER_TRIANGLE || kind == EMITTER_SPHERE; }

// Directional lights and the environment: light from infinitely far away.
bool emitter_kind_is_at_infinity(uint kind) { return kind == EMITTER_DIRECTIONAL || kind == EMITTER_INFINITE; }

// ---- the environment lights -----------------------------------------------------
// pbrt-v4's infinite lights, each an emitter (the last of the table, in a row: from
// scene.environment, scene.environment_count of them; GpuEmitter in abi.h). Each is
// constant (pbrt-v4's uniform infinite light: uniform sampling over the sphere) or an
// image over the sphere (its image infinite light: a piecewise-constant distribution over
// the map, built by the host from the map's dilated values times the mapping's solid
// angle per pixel), and may be seen only through its portal. Their radiance adds. Light
// sampling picks one of them by power and draws a direction as that one does, but the
// estimate and every MIS weight treat them as one light: the radiance of all of them, and
// the density of all of them, sum_e pick_e pdf_e(dir) (environment_pdf; pbrt's
// InfiniteLightDensity does the same for its BDPT). CPU mirror of the mappings and the
// distribution: src/texture.rs.

vec3 env_to_local(GpuEmitter em, vec3 d) {
    return vec3(dot(d, em.p0.xyz), dot(d, em.p1.xyz), dot(d, em.p2.xyz));
}
vec3 env_to_world(GpuEmitter em, vec3 l) {
    return l.x * em.p0.xyz + l.y * em.p1.xyz + l.z * em.p2.xyz;
}

// The equal-area square (Clarberg; pbrt-v4's): the point of [0,1]^2 of the unit direction
// l, and back (src/texture.rs equal_area_sphere_to_square and _square_to_sphere).
vec2 equal_area_sphere_to_square(vec3 l) {
    vec3 a = abs(l);
    float r = sqrt(max(1.0 - a.z, 0.0));
    float big = max(a.x, a.y);
    float small = big == 0.0 ? 0.0 : min(a.x, a.y) / big;
    float phi = atan(small) * (2.0 * INV_PI);
    if (a.x < a.y) phi = 1.0 - phi;
    float v = phi * r;
    float u = r - v;
    if (l.z < 0.0) {
        float t = u;
        u = 1.0 - v;
        v = 1.0 - t;
    }
    u = l.x < 0.0 ? -u : u;
    v = l.y < 0.0 ? -v : v;
    return 0.5 * vec2(u + 1.0, v + 1.0);
}

vec3 equal_area_square_to_sphere(vec2 uv) {
    float u = 2.0 * uv.x - 1.0;
    float v = 2.0 * uv.y - 1.0;
    float signed_d = 1.0 - (abs(u) + abs(v));
    float r = 1.0 - abs(signed_d);
    float phi = (r == 0.0 ? 1.0 : (abs(v) - abs(u)) / r + 1.0) * (PI / 4.0);
    float z = signed_d < 0.0 ? -(1.0 - r * r) : 1.0 - r * r;
    float s = r * sqrt(max(2.0 - r * r, 0.0));
    float c = cos(phi);
    float sn = sin(phi);
    return vec3((u < 0.0 ? -c : c) * s, (v < 0.0 ? -sn : sn) * s, z);
}

// The map point (u right, v down from the top row) of the unit direction l in the map's
// frame, and back (src/texture.rs EnvMapping).
vec2 env_uv(uint mapping, vec3 l) {
    if (mapping == ENV_MAPPING_LATLONG) {
        return vec2(atan(l.x, -l.z) * (0.5 * INV_PI) + 0.5, acos(clamp(l.y, -1.0, 1.0)) * INV_PI);
    }
    return equal_area_sphere_to_square(l);
}

vec3 env_direction(uint mapping, vec2 uv) {
    if (mapping == ENV_MAPPING_LATLONG) {
        float theta = PI * uv.y;
        float phi = TWO_PI * (uv.x - 0.5);
        float s = sin(theta);
        return vec3(s * sin(phi), cos(theta), -s * cos(phi));
    }
    return equal_area_square_to_sphere(uv);
}

// Solid angle per unit of map area at uv. Within 1e-4 rad of a latitude-longitude map's
// poles it is taken as 0 (those directions, 3e-8 sr, are left to BSDF sampling): there
// the density 1/sin(theta) of a sampled direction grows without bound, and its square in
// the MIS sums overflows.
float env_jacobian(uint mapping, vec2 uv) {
    if (mapping != ENV_MAPPING_LATLONG) return 4.0 * PI;
    float s = sin(PI * uv.y);
    return s > 1e-4 ? 2.0 * PI * PI * s : 0.0;
}

// ---- piecewise-constant distributions over [0,1]^2 -------------------------------------
// A w x h grid (row 0 at v = 0) stored in texels as a marginal CDF over rows (h + 1
// entries from `marginal`) and a CDF per row (h rows of w + 1 from `conditional`); the
// CPU mirror and builder is src/texture.rs Distribution2D. Sampling and the density both
// read only the CDFs, so a sample's density is exactly the one it was drawn with.

// The last i in 0 .. n-1 with cdf[i] <= u, for the n + 1 CDF entries from texel(first).
uint distribution_find_interval(uint first, uint n, float u) {
    uint lo = 0u;
    uint hi = n - 1u;
    while (lo < hi) {
        uint mid = (lo + hi + 1u) >> 1;
        if (texel(first + mid) <= u) lo = mid; else hi = mid - 1u;
    }
    return lo;
}

// The distribution's density at uv (with respect to area).
float distribution_pdf(uint marginal, uint conditional, uint w, uint h, vec2 uv) {
    uint x = min(uint(uv.x * float(w)), w - 1u);
    uint y = min(uint(uv.y * float(h)), h - 1u);
    uint row = conditional + y * (w + 1u);
    float m = texel(marginal + y + 1u) - texel(marginal + y);
    return m * (texel(row + x + 1u) - texel(row + x)) * float(w * h);
}

// A point of [0,1]^2 for uniforms u, with its density (0 where a cell has none).
vec2 sample_distribution(uint marginal, uint conditional, uint w, uint h, vec2 u, out float pdf) {
    uint y = distribution_find_interval(marginal, h, u.y);
    float m0 = texel(marginal + y);
    float m1 = texel(marginal + y + 1u);
    uint row = conditional + y * (w + 1u);
    uint x = distribution_find_interval(row, w, u.x);
    float c0 = texel(row + x);
    float c1 = texel(row + x + 1u);
    float fy = m1 > m0 ? clamp((u.y - m0) / (m1 - m0), 0.0, 1.0) : 0.5;
    float fx = c1 > c0 ? clamp((u.x - c0) / (c1 - c0), 0.0, 1.0) : 0.5;
    pdf = (m1 - m0) * (c1 - c0) * float(w * h);
    return min(vec2((float(x) + fx) / float(w), (float(y) + fy) / float(h)), vec2(0.99999994));
}

// Environment emitter em's map distribution's density at uv (with respect to map area).
float env_map_pdf(GpuEmitter em, vec2 uv) {
    GpuTexture t = textures[em.info.y];
    return distribution_pdf(floatBitsToUint(em.p0.w), floatBitsToUint(em.p1.w), t.info.z, t.info.w, uv);
}

bool env_has_map(GpuEmitter em) {
    return has_feature(FEATURE_ENVIRONMENT_MAP) && em.info.y != NO_TEXTURE;
}

// Environment emitter em's portal: its corner p0 and edges e1 = p1 - p0, e3 = p3 - p0.
// Returns false when it has none.
bool env_portal(GpuEmitter em, out vec3 p0, out vec3 e1, out vec3 e3) {
    uint i = floatBitsToUint(em.p2.w);
    if (i == NO_TEXTURE) return false;
    p0 = vec3(texel(i), texel(i + 1u), texel(i + 2u));
    e1 = vec3(texel(i + 3u), texel(i + 4u), texel(i + 5u));
    e3 = vec3(texel(i + 6u), texel(i + 7u), texel(i + 8u));
    return true;
}

// Whether the point q of the portal's plane lies in the portal.
bool portal_contains(vec3 p0, vec3 e1, vec3 e3, vec3 q) {
    q -= p0;
    float a = dot(q, e1) / dot(e1, e1);
    float b = dot(q, e3) / dot(e3, e3);
    return a >= 0.0 && a <= 1.0 && b >= 0.0 && b <= 1.0;
}

// pbrt-v4's portal: whether the ray from p along dir crosses em's portal rectangle, going
// out through it (always true without a portal).
bool portal_passes(GpuEmitter em, vec3 p, vec3 dir) {
    vec3 p0;
    vec3 e1;
    vec3 e3;
    if (!env_portal(em, p0, e1, e3)) return true;
    vec3 n = cross(e3, e1);
    float dn = dot(dir, n);
    if (!(dn > 0.0)) return false;
    float t = dot(p0 - p, n) / dn;
    return t > 0.0 && portal_contains(p0, e1, e3, p + t * dir);
}

// Environment emitter em's radiance arriving along -dir (dir the unit direction of an
// escaping ray), portal aside.
vec3 environment_value(GpuEmitter em, vec3 dir) {
    vec3 L = em.radiance.xyz;
    if (!env_has_map(em)) return L;
    return L * texture_leaf(textures[em.info.y], env_uv(em.info.z, env_to_local(em, dir)), vec3(0.0), vec3(0.0),
                            vec3(0.0), vec4(0.0), spec_features & FEATURE_TEXTURE_PROJECTIONS);
}

// Environment emitter em's radiance arriving at p from the direction dir (zero where its
// portal hides it).
vec3 environment_radiance_of(GpuEmitter em, vec3 p, vec3 dir) {
    return portal_passes(em, p, dir) ? environment_value(em, dir) : vec3(0.0);
}

// The radiance of every infinite light arriving at p from the direction dir (the scene
// has one: scene.environment != NO_EMITTER).
// (Each of these loops is the one call site of what it calls: lavapipe's compile time
// grows with every inlined copy.)
vec3 environment_radiance(vec3 p, vec3 dir) {
    if (!has_feature(FEATURE_ENVIRONMENTS)) return environment_radiance_of(emitters[scene.environment], p, dir);
    vec3 L = vec3(0.0);
    for (uint k = 0u; k < scene.environment_count; ++k) {
        L += environment_radiance_of(emitters[scene.environment + k], p, dir);
    }
    return L;
}

// A light subpath's emission ray from the disk point o along -dir, of environment emitter
// em. With a portal it carries light only along lines through the portal, and only to
// the points past it (those whose rays toward the environment cross it: what the camera
// side sees), so enter is where the line crosses the portal: a first vertex before it
// carries nothing (light_walk_vertex), as what blocks the line outside the portal blocks
// the light. Without a portal, enter is o.
vec3 environment_emission(GpuEmitter em, vec3 o, vec3 dir, out vec3 enter) {
    enter = o;
    vec3 p0;
    vec3 e1;
    vec3 e3;
    if (env_portal(em, p0, e1, e3)) {
        vec3 n = cross(e3, e1);
        float dn = dot(dir, n);
        if (!(dn > 0.0)) return vec3(0.0);
        enter = o + (dot(p0 - o, n) / dn) * dir;
        if (!portal_contains(p0, e1, e3, enter)) return vec3(0.0);
    }
    return environment_value(em, dir);
}

// The solid-angle density with which sampling environment emitter em draws the direction
// dir (no pick).
float environment_direction_pdf(GpuEmitter em, vec3 dir) {
    if (!env_has_map(em)) return 0.25 * INV_PI;
    vec2 uv = env_uv(em.info.z, env_to_local(em, dir));
    float jac = env_jacobian(em.info.z, uv);
    return jac > 0.0 ? env_map_pdf(em, uv) / jac : 0.0;
}

// A direction toward environment emitter em for uniforms u, with its solid-angle density.
vec3 sample_environment_direction(GpuEmitter em, vec2 u, out float pdf) {
    if (!env_has_map(em)) {
        pdf = 0.25 * INV_PI;
        return sample_uniform_sphere(u);
    }
    GpuTexture t = textures[em.info.y];
    float pdf_uv;
    vec2 uv = sample_distribution(floatBitsToUint(em.p0.w), floatBitsToUint(em.p1.w), t.info.z, t.info.w, u, pdf_uv);
    float jac = env_jacobian(em.info.z, uv);
    pdf = jac > 0.0 ? pdf_uv / jac : 0.0;
    return env_to_world(em, env_direction(em.info.z, uv));
}

// The solid-angle pdf, picks included, with which light sampling draws dir from the
// infinite lights together (the scene has one).
float environment_pdf(vec3 dir) {
    if (!has_feature(FEATURE_ENVIRONMENTS)) {
        GpuEmitter em = emitters[scene.environment];
        return em.radiance.w * environment_direction_pdf(em, dir);
    }
    float pdf = 0.0;
    for (uint k = 0u; k < scene.environment_count; ++k) {
        GpuEmitter em = emitters[scene.environment + k];
        pdf += em.radiance.w * environment_direction_pdf(em, dir);
    }
    return pdf;
}

// What the infinite lights other than emitter e add to e's own light-sampling density
// of dir (picks included), so that a sample drawn from e counts for all of them together
// (nothing with a single infinite light).
float other_environments_pdf(uint e, vec3 dir) {
    float pdf = 0.0;
    if (!has_feature(FEATURE_ENVIRONMENTS)) return pdf;
    for (uint k = 0u; k < scene.environment_count; ++k) {
        uint o = scene.environment + k;
        if (o == e) continue;
        GpuEmitter em = emitters[o];
        pdf += em.radiance.w * environment_direction_pdf(em, dir);
    }
    return pdf;
}

// A spot light's falloff toward the unit direction w from it: pbrt-v4's smoothstep
// between the cone angle (0) and the start of the falloff (1).
float spot_falloff(GpuEmitter em, vec3 w) {
    float c = dot(em.p1.xyz, w);
    float lo = em.p1.w;
    float hi = em.p2.x;
    if (lo == hi) return c < lo ? 0.0 : 1.0;
    float t = clamp((c - lo) / (hi - lo), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// The solid-angle pdf of a spot light's emission: uniform over its cone.
float spot_cone_pdf(GpuEmitter em, vec3 w) {
    float cos_end = em.p1.w;
    return dot(em.p1.xyz, w) >= cos_end ? 1.0 / (TWO_PI * (1.0 - cos_end)) : 0.0;
}

// ---- goniometric and projection lights ------------------------------------------------
// pbrt-v4's GoniometricLight and ProjectionLight: point lights whose intensity an image
// sets per direction, at its nearest pixel (FEATURE_PROFILE_LIGHTS). The record (abi.h
// GpuEmitter): the map M from world directions to the light's image space. Goniometric:
// the direction M w (normalized) on the equal-area square, one value per pixel.
// Projection: the screen point (M w).xy / (M w).z on pbrt-v4's screen bounds (half
// extents (a, 1) for an image of aspect a > 1, else (1, 1/a); y down the image, fov
// folded into M), RGB per pixel, dark where (M w).z <= 0 or beyond the bounds. Light
// subpaths draw directions from the image's distribution (its texels follow the image),
// in proportion to intensity. CPU mirror: src/scene/mod.rs DeltaLight::profile_uv.

bool emitter_kind_is_profiled(uint kind) {
    return has_feature(FEATURE_PROFILE_LIGHTS) && (kind == EMITTER_GONIOMETRIC || kind == EMITTER_PROJECTION);
}

mat3 profile_map(GpuEmitter em) {
    return transpose(mat3(em.p1.xyz, em.p2.xyz, vec3(em.p0.w, em.p1.w, em.p2.w)));
}

uint profile_width(GpuEmitter em) { return em.info.z & 0xffffu; }
uint profile_height(GpuEmitter em) { return em.info.z >> 16; }
uint profile_channels(GpuEmitter em) { return em.info.x == EMITTER_GONIOMETRIC ? 1u : 3u; }
uint profile_marginal(GpuEmitter em) {
    return em.info.y + profile_width(em) * profile_height(em) * profile_channels(em);
}
uint profile_conditional(GpuEmitter em) { return profile_marginal(em) + profile_height(em) + 1u; }

vec2 projection_half_extent(GpuEmitter em) {
    float aspect = float(profile_width(em)) / float(profile_height(em));
    return aspect > 1.0 ? vec2(aspect, 1.0) : vec2(1.0, 1.0 / aspect);
}

// The image point uv toward the unit world direction w, and the solid angle of directions
// per unit of image area there (jac). False where the light is dark.
bool profile_uv(GpuEmitter em, vec3 w, out vec2 uv, out float jac) {
    mat3 m = profile_map(em);
    vec3 q = m * w;
    float det = abs(determinant(m));
    uv = vec2(0.0);
    jac = 0.0;
    if (em.info.x == EMITTER_GONIOMETRIC) {
        float len = length(q);
        uv = equal_area_sphere_to_square(q / len);
        jac = 4.0 * PI * len * len * len / det;
        return true;
    }
    if (!(q.z > 0.0)) return false;
    vec2 half_extent = projection_half_extent(em);
    uv = (q.xy / q.z + half_extent) / (2.0 * half_extent);
    jac = 4.0 * half_extent.x * half_extent.y * q.z * q.z * q.z / det;
    return all(greaterThanEqual(uv, vec2(0.0))) && all(lessThanEqual(uv, vec2(1.0)));
}

// The unit world direction of the image point uv, and the solid angle per unit of image
// area there.
vec3 profile_direction(GpuEmitter em, vec2 uv, out float jac) {
    mat3 m = profile_map(em);
    mat3 inv = inverse(m);
    float det = abs(determinant(m));
    vec3 v;
    if (em.info.x == EMITTER_GONIOMETRIC) {
        v = inv * equal_area_square_to_sphere(uv);
        jac = 4.0 * PI;
    } else {
        vec2 half_extent = projection_half_extent(em);
        v = inv * vec3((2.0 * uv - 1.0) * half_extent, 1.0);
        jac = 4.0 * half_extent.x * half_extent.y;
    }
    float len = length(v);
    // |M w| = 1 / |v| for w = v / |v|.
    jac /= len * len * len * det;
    return v / len;
}

// The intensity toward the unit world direction w.
vec3 profile_intensity(GpuEmitter em, vec3 w) {
    vec2 uv;
    float jac;
    if (!profile_uv(em, w, uv, jac)) return vec3(0.0);
    uint width = profile_width(em);
    uint height = profile_height(em);
    uint x = min(uint(uv.x * float(width)), width - 1u);
    uint y = min(uint(uv.y * float(height)), height - 1u);
    uint i = em.info.y + (y * width + x) * profile_channels(em);
    vec3 value = em.info.x == EMITTER_GONIOMETRIC ? vec3(texel(i)) : vec3(texel(i), texel(i + 1u), texel(i + 2u));
    return em.radiance.xyz * value;
}

// The solid-angle density with which light subpaths draw the direction w (no pick).
float profile_direction_pdf(GpuEmitter em, vec3 w) {
    vec2 uv;
    float jac;
    if (!profile_uv(em, w, uv, jac) || !(jac > 0.0)) return 0.0;
    return distribution_pdf(profile_marginal(em), profile_conditional(em), profile_width(em), profile_height(em), uv)
           / jac;
}

// A direction drawn from the image's distribution for uniforms u, with its solid-angle density.
vec3 sample_profile_direction(GpuEmitter em, vec2 u, out float pdf) {
    float pdf_uv;
    vec2 uv = sample_distribution(profile_marginal(em), profile_conditional(em), profile_width(em),
                                  profile_height(em), u, pdf_uv);
    float jac;
    vec3 w = profile_direction(em, uv, jac);
    pdf = jac > 0.0 ? pdf_uv / jac : 0.0;
    return w;
}

// Radiance leaving an emissive surface point with unit normal ng toward w.
vec3 emitted_radiance(uint material, vec3 ng, vec3 w) {
    GpuMaterial m = materials[material];
    if ((m.info.y & MATERIAL_TWO_SIDED_EMISSION) == 0u && dot(ng, w) <= 0.0) return vec3(0.0);
    return m.emission.xyz;
}

float sphere_area_pdf(GpuSphere sp, float det_abs, vec3 q) {
    return 1.0 / (4.0 * PI * det_abs * length(sphere_normal_unnormalized(sp, q)));
}

// Area-measure pdf (given the emitter was picked) of the point p on emitter e.
float emitter_area_pdf(uint e, vec3 p) {
    GpuEmitter em = emitters[e];
    if (em.info.x == EMITTER_TRIANGLE) return 1.0 / em.p0.w;
    GpuSphere sp = spheres[em.info.y];
    return sphere_area_pdf(sp, em.p1.x, sphere_to_object_point(sp, p));
}

// The material of an area emitter (triangle or sphere).
uint emitter_material(GpuEmitter em) {
    return em.info.x == EMITTER_TRIANGLE ? floatBitsToUint(triangle_record(em.info.y).v0.w)
                                         : spheres[em.info.y].info.x;
}

// A uniformly distributed point p, with unit normal n, on area emitter em (triangle or
// sphere). Returns its area pdf (given em was picked).
float sample_area_emitter_point(GpuEmitter em, vec2 u, out vec3 p, out vec3 n) {
    if (em.info.x == EMITTER_TRIANGLE) {
        vec2 b = sample_uniform_triangle(u);
        vec3 e1 = em.p1.xyz - em.p0.xyz;
        vec3 e2 = em.p2.xyz - em.p0.xyz;
        p = em.p0.xyz + b.x * e1 + b.y * e2;
        n = normalize(cross(e1, e2));
        return 1.0 / em.p0.w;
    }
    GpuSphere sp = spheres[em.info.y];
    vec3 q = sample_uniform_sphere(u);
    p = sphere_to_world_point(sp, q);
    n = normalize(sphere_normal_unnormalized(sp, q));
    return sphere_area_pdf(sp, em.p1.x, q);
}

struct LightSample {
    vec3 wi;      // unit direction from the reference point toward the light
    float dist;   // distance to the light point (INF for directional lights)
    vec3 L;       // radiance arriving along -wi (point lights: I / d^2; directional: E)
    float pdf;    // solid-angle pdf including the pick probability (delta: pick probability)
    bool delta;
    bool unhittable;  // no ray can find the light (delta, or hidden): MIS weighs it alone
    vec3 p;       // the sampled point (for occlusion tests), n its normal
    vec3 n;
};

#ifdef PROFILE_X2_LIGHT
// lightpath profile: every light sample is drawn twice (see the wrapper below).
#define sample_emitter sample_emitter_once
#endif
// Sample a point on emitter e as seen from ref. Returns false for no contribution.
bool sample_emitter(uint e, vec3 ref, vec2 u, out LightSample ls) {
    GpuEmitter em = emitters[e];
    float pick = em.radiance.w;
    ls.delta = false;
    ls.unhittable = emitter_kind_is_delta(em.info.x) || emitter_is_hidden(em);
    ls.n = vec3(0.0);
    ls.L = vec3(0.0);
    ls.pdf = 0.0;
    ls.dist = 0.0;
    ls.wi = vec3(0.0, 0.0, 1.0);
    ls.p = ref;
    if (em.info.x == EMITTER_POINT) {
        vec3 to = em.p0.xyz - ref;
        float d2 = dot(to, to);
        if (d2 == 0.0) return false;
        ls.dist = sqrt(d2);
        ls.wi = to / ls.dist;
        ls.L = em.radiance.xyz / d2;
        ls.pdf = pick;
        ls.delta = true;
        ls.p = em.p0.xyz;
        return true;
    }
    if (em.info.x == EMITTER_SPOT) {
        vec3 to = em.p0.xyz - ref;
        float d2 = dot(to, to);
        if (d2 == 0.0) return false;
        ls.dist = sqrt(d2);
        ls.wi = to / ls.dist;
        ls.L = em.radiance.xyz * (spot_falloff(em, -ls.wi) / d2);
        ls.pdf = pick;
        ls.delta = true;
        ls.p = em.p0.xyz;
        return ls.L != vec3(0.0);
    }
    if (emitter_kind_is_profiled(em.info.x)) {
        vec3 to = em.p0.xyz - ref;
        float d2 = dot(to, to);
        if (d2 == 0.0) return false;
        ls.dist = sqrt(d2);
        ls.wi = to / ls.dist;
        ls.L = profile_intensity(em, -ls.wi) / d2;
        ls.pdf = pick;
        ls.delta = true;
        ls.p = em.p0.xyz;
        return ls.L != vec3(0.0);
    }
    if (em.info.x == EMITTER_INFINITE) {
        // (With the other infinite lights as one light: see "the environment lights". One
        // loop, so that each function it calls is inlined once.)
        float pdf_dir;
        ls.wi = sample_environment_direction(em, u, pdf_dir);
        ls.dist = INF;
        ls.pdf = pick * pdf_dir;
        if (!has_feature(FEATURE_ENVIRONMENTS)) {
            ls.L = environment_radiance_of(em, ref, ls.wi);
        } else {
            for (uint k = 0u; k < scene.environment_count; ++k) {
                uint o = scene.environment + k;
                GpuEmitter eo = emitters[o];
                ls.L += environment_radiance_of(eo, ref, ls.wi);
                if (o != e) ls.pdf += eo.radiance.w * environment_direction_pdf(eo, ls.wi);
            }
        }
        return ls.pdf > 0.0 && ls.L != vec3(0.0);
    }
    if (em.info.x == EMITTER_DIRECTIONAL) {
        ls.wi = em.p0.xyz;
        ls.dist = INF;
        ls.L = em.radiance.xyz;
        ls.pdf = pick;
        ls.delta = true;
        return true;
    }
    float area_pdf = sample_area_emitter_point(em, u, ls.p, ls.n);
    uint material = emitter_material(em);
    vec3 to = ls.p - ref;
    float d2 = dot(to, to);
    if (d2 == 0.0) return false;
    ls.dist = sqrt(d2);
    ls.wi = to / ls.dist;
    float cos_l = abs(dot(ls.n, ls.wi));
    if (cos_l == 0.0) return false;
    ls.L = emitted_radiance(material, ls.n, -ls.wi);
    ls.pdf = pick * area_pdf * d2 / cos_l;
    return ls.L != vec3(0.0);
}

#ifdef PROFILE_X2_LIGHT
#undef sample_emitter
bool sample_emitter(uint e, vec3 ref, vec2 u, out LightSample ls) {
    LightSample other;
    bool b = sample_emitter_once(e, ref, u.yx, other);
    bool a = sample_emitter_once(e, ref, u, ls);
    if (b && other.pdf == -1.0) ls = other;
    return a;
}
#endif

// A light sample as the wavefronts keep it between their stages (pt_hit to pt_shade,
// bdpt_hit to bdpt_shade): four vec4s.
void pack_light_sample(LightSample ls, out vec4 wi, out vec4 le, out vec4 p, out vec4 n) {
    wi = vec4(ls.wi, ls.dist);
    le = vec4(ls.L, ls.pdf);
    p = vec4(ls.p, (ls.delta ? 1.0 : 0.0) + (ls.unhittable ? 2.0 : 0.0));
    n = vec4(ls.n, 0.0);
}

LightSample unpack_light_sample(vec4 wi, vec4 le, vec4 p, vec4 n) {
    LightSample ls;
    ls.wi = wi.xyz;
    ls.dist = wi.w;
    ls.L = le.xyz;
    ls.pdf = le.w;
    ls.p = p.xyz;
    ls.delta = p.w == 1.0 || p.w == 3.0;
    ls.unhittable = p.w >= 2.0;
    ls.n = n.xyz;
    return ls;
}

// The shadow ray of a light sample seen from p: its origin (p offset along n toward the
// light), unit direction and extent (INF for lights at infinity). Traced by
// light_sample_visible (visibility.glsl) or by a wavefront's shadow stage.
void light_sample_shadow_ray(vec3 p, vec3 n, LightSample ls, out vec3 o, out vec3 d, out float tmax) {
    vec3 side = dot(ls.wi, n) > 0.0 ? n : -n;
    if (ls.dist == INF) {
        o = offset_ray_origin(p, side);
        d = ls.wi;
        tmax = INF;
        return;
    }
    vec3 target = ls.delta ? ls.p : offset_ray_origin(ls.p, dot(ls.n, -ls.wi) > 0.0 ? ls.n : -ls.n);
    shadow_ray_to(p, side, target, o, d, tmax);
}

// Solid-angle pdf (pick included) with which sample_emitter would have produced the
// point p with normal ng on emitter e, seen from ref. For MIS of emitters hit by
// BSDF sampling.
float emitter_pdf_solid_angle(uint e, vec3 ref, vec3 p, vec3 ng) {
    vec3 to = p - ref;
    float d2 = dot(to, to);
    float cos_l = abs(dot(ng, to)) / sqrt(d2);
    if (cos_l == 0.0) return 0.0;
    return emitter_pick_pdf(e) * emitter_area_pdf(e, p) * d2 / cos_l;
}

// ---------------------------------------------------------------------------------------
// Next-event estimation and emitter hits, shared by the path tracer and BDPT (whose s = 1
// and s = 0 strategies these are).

// Whether the BSDF b at a surface vertex (unit geometric normal n on the side of wo,
// shading normal ns on n's side) can send light arriving from wi toward wo, and the
// shading cosine |ns.wi|: the checks before direct_light_bsdf evaluates it.
bool direct_light_faces(BsdfParams b, vec3 n, vec3 ns, vec3 wo, vec3 wi, out float cos_theta) {
    cos_theta = 0.0;
    if (!(dot(ns, wo) > 0.0) || !shading_side_agrees(n, ns, wi)) return false;
    // The course's BRDFs reflect only; the interface BSDFs may transmit toward the light.
    float c = dot(ns, wi);
    if (bsdf_is_course_brdf(b) && !(c > 0.0)) return false;
    cos_theta = abs(c);
    return true;
}

// The BSDF's half of a light sample ls (drawn by sample_emitter, with ls.pdf > 0) at a
// surface vertex (unit geometric normal n on the side of wo, shading normal ns on n's
// side): f toward the light, the shading cosine |ns.wi| and the pdfs as
// sample_direct_light gives them. False when it cannot contribute. (The wavefront path
// tracer draws the light sample in one stage and asks the material in another.)
bool direct_light_bsdf(BsdfParams b, vec3 n, vec3 ns, vec3 wo, uint mode, bool want_fwd, bool want_rev,
                       LightSample ls, out vec3 f, out float cos_theta, out float pdf_fwd, out float pdf_rev) {
    f = vec3(0.0);
    pdf_fwd = 0.0;
    pdf_rev = 0.0;
    if (!direct_light_faces(b, n, ns, wo, ls.wi, cos_theta)) return false;
    f = bsdf_eval_pdfs(b, mode, ns, wo, ls.wi, TRANSPORT_RADIANCE, want_fwd, want_rev, pdf_fwd, pdf_rev);
    return f != vec3(0.0);
}

// A light sample at a surface vertex (p, unit geometric normal n on the side of wo, shading
// normal ns on n's side) for the BSDF b: the sample, the BSDF value toward it and the
// shading cosine |ns.wi| (the light may lie behind a transmitting surface). False when it
// cannot contribute (no sample, below the surface, f = 0). The shadow ray is the caller's
// (light_sample_visible), and so is the weighting: the estimate is f L cos / ls.pdf, and
// the BSDF's pdfs toward the light (want_fwd) and back (want_rev) in sampling mode `mode`
// come with f (bsdf_eval_pdfs).
bool sample_direct_light(BsdfParams b, uint e, vec3 p, vec3 n, vec3 ns, vec3 wo, vec2 u, uint mode, bool want_fwd,
                         bool want_rev, out LightSample ls, out vec3 f, out float cos_theta, out float pdf_fwd,
                         out float pdf_rev) {
    f = vec3(0.0);
    cos_theta = 0.0;
    pdf_fwd = 0.0;
    pdf_rev = 0.0;
    if (!sample_emitter(e, p, u, ls) || !(ls.pdf > 0.0)) return false;
    return direct_light_bsdf(b, n, ns, wo, mode, want_fwd, want_rev, ls, f, cos_theta, pdf_fwd, pdf_rev);
}

// Power-heuristic weight of a light sample against BSDF sampling of the same direction
// (bsdf_pdf); delta lights cannot be hit by BSDF sampling.
float light_sample_mis_weight(LightSample ls, float bsdf_pdf) {
    return ls.unhittable ? 1.0 : power_heuristic(ls.pdf, bsdf_pdf);
}

// Power-heuristic weight of emission found by BSDF sampling (from prev_p, with solid-angle
// pdf prev_pdf) at the point p, normal ng, of emitter e, against light sampling.
float emitter_hit_mis_weight(uint e, vec3 prev_p, float prev_pdf, vec3 p, vec3 ng) {
    return power_heuristic(prev_pdf, emitter_pdf_solid_angle(e, prev_p, p, ng));
}
// ---------------------------------------------------------------------------------------
// Light subpaths (BDPT, MMLT): emission of a ray from an emitter, and the pdfs a vertex on
// an emitter would have had under that sampling. Conventions, used by the MIS weights:
//   pdf_pos:  pick * area pdf of the point (delta lights: pick; the environment: pick *
//             the solid-angle pdf of its direction). Light subpaths and light sampling
//             (sample_emitter) place points with the same density.
//   pdf_emit: pdf_pos * solid-angle pdf of the direction. Area lights emit cosine-weighted
//             around the normal (over both sides, each with probability 1/2, when
//             two-sided); point lights uniformly over the sphere; spot lights uniformly
//             over their cone; goniometric and projection lights by their images; the environment from a disk of the scene's bounding
//             radius facing a uniformly drawn direction, pdf_emit = pdf_pos / (pi R^2);
//             directional lights
//             from a disk of the scene's bounding radius, pdf_emit = pick / (pi R^2).
//   cos_l:    |cos| between the normal and the direction (1 for delta lights).

struct LightEmission {
    vec3 p;       // origin of the ray
    vec3 n;       // unit normal (area lights; zero for delta lights)
    vec3 dir;     // unit direction of the ray
    vec3 Le;      // area: radiance along dir; point: intensity; directional: radiance
    vec3 enter;   // lights at infinity: where the light enters (environment_emission)
    float pdf_pos;
    float pdf_emit;
    float cos_l;
    uint kind;
    bool hidden;  // emitter_is_hidden
};

float emission_direction_pdf(bool two_sided, float cos_l) {
    return cos_l * (two_sided ? 0.5 * INV_PI : INV_PI);
}

// Start a light subpath on emitter e. u_pos places the point, u_dir the direction
// (u_dir.x picks the side of a two-sided emitter).
bool sample_light_emission(uint e, vec2 u_pos, vec3 u_dir, out LightEmission le) {
    GpuEmitter em = emitters[e];
    float pick = em.radiance.w;
    le.kind = em.info.x;
    le.hidden = emitter_is_hidden(em);
    le.n = vec3(0.0);
    le.cos_l = 1.0;
    le.Le = em.radiance.xyz;
    le.pdf_pos = pick;
    le.enter = vec3(0.0);
    if (em.info.x == EMITTER_POINT) {
        le.p = em.p0.xyz;
        le.dir = sample_uniform_sphere(u_dir.yz);
        le.pdf_emit = pick * (0.25 * INV_PI);
        return pick > 0.0;
    }
    if (em.info.x == EMITTER_SPOT) {
        le.p = em.p0.xyz;
        le.dir = to_world(sample_uniform_cone(u_dir.yz, em.p1.w), em.p1.xyz);
        le.Le = em.radiance.xyz * spot_falloff(em, le.dir);
        le.pdf_emit = pick * spot_cone_pdf(em, le.dir);
        return le.pdf_emit > 0.0 && le.Le != vec3(0.0);
    }
    if (emitter_kind_is_profiled(em.info.x)) {
        le.p = em.p0.xyz;
        float pdf_dir;
        le.dir = sample_profile_direction(em, u_dir.yz, pdf_dir);
        le.Le = profile_intensity(em, le.dir);
        le.pdf_emit = pick * pdf_dir;
        return le.pdf_emit > 0.0 && le.Le != vec3(0.0);
    }
    if (em.info.x == EMITTER_INFINITE) {
        // A direction toward the environment, as light sampling draws it, and parallel
        // rays from a disk of the scene's bounding radius facing it (pbrt-v4's SampleLe).
        float r = scene.bounds.w;
        float pdf_dir;
        vec3 toward = sample_environment_direction(em, u_dir.yz, pdf_dir);
        vec3 t;
        vec3 b;
        build_onb(toward, t, b);
        float rad = r * sqrt(u_pos.x);
        float phi = TWO_PI * u_pos.y;
        le.dir = -toward;
        le.p = scene.bounds.xyz + r * toward + rad * (cos(phi) * t + sin(phi) * b);
        le.Le = environment_emission(em, le.p, toward, le.enter);
        // With other infinite lights, the vertex's densities are theirs together (as every
        // strategy's MIS weights take them: emitter_emission_pdfs), and the ray carries
        // this light's emission divided by its share of that density (the ray's own
        // density: an unbiased estimate of this light's part; the others' parts come from
        // their own rays).
        float own = pick * pdf_dir;
        if (!(own > 0.0)) return false;
        le.pdf_pos = own + other_environments_pdf(e, toward);
        le.Le *= le.pdf_pos / own;
        le.pdf_emit = le.pdf_pos / (PI * r * r);
        return le.Le != vec3(0.0);
    }
    if (em.info.x == EMITTER_DIRECTIONAL) {
        float r = scene.bounds.w;
        vec3 t;
        vec3 b;
        build_onb(em.p0.xyz, t, b);
        float rad = r * sqrt(u_pos.x);
        float phi = TWO_PI * u_pos.y;
        le.dir = -em.p0.xyz;
        le.p = scene.bounds.xyz + r * em.p0.xyz + rad * (cos(phi) * t + sin(phi) * b);
        le.enter = le.p;
        le.pdf_emit = pick / (PI * r * r);
        return pick > 0.0;
    }
    float area_pdf = sample_area_emitter_point(em, u_pos, le.p, le.n);
    uint material = emitter_material(em);
    bool two_sided = em.info.z != 0u;
    vec3 side = (two_sided && u_dir.x < 0.5) ? -le.n : le.n;
    vec3 local = sample_cosine_hemisphere(u_dir.yz);
    le.dir = to_world(local, side);
    le.cos_l = local.z;
    le.pdf_pos = pick * area_pdf;
    le.pdf_emit = le.pdf_pos * emission_direction_pdf(two_sided, le.cos_l);
    le.Le = emitted_radiance(material, le.n, le.dir);
    return le.pdf_emit > 0.0 && le.Le != vec3(0.0);
}

// pdf_pos and pdf_emit (conventions above) of the point p, normal ng, on emitter e
// emitting toward the unit direction w. Delta lights ignore p, ng and w.
void emitter_emission_pdfs(uint e, vec3 p, vec3 ng, vec3 w, out float pdf_pos, out float pdf_emit) {
    GpuEmitter em = emitters[e];
    float pick = em.radiance.w;
    pdf_pos = pick;
    if (em.info.x == EMITTER_POINT) {
        pdf_emit = pick * (0.25 * INV_PI);
    } else if (em.info.x == EMITTER_INFINITE) {
        // (All infinite lights together: see "the environment lights".)
        pdf_pos = environment_pdf(-w);
        pdf_emit = pdf_pos / (PI * scene.bounds.w * scene.bounds.w);
    } else if (em.info.x == EMITTER_SPOT) {
        pdf_emit = pick * spot_cone_pdf(em, w);
    } else if (emitter_kind_is_profiled(em.info.x)) {
        pdf_emit = pick * profile_direction_pdf(em, w);
    } else if (em.info.x == EMITTER_DIRECTIONAL) {
        pdf_emit = pick / (PI * scene.bounds.w * scene.bounds.w);
    } else {
        pdf_pos = pick * emitter_area_pdf(e, p);
        pdf_emit = pdf_pos * emission_direction_pdf(em.info.z != 0u, abs(dot(ng, w)));
    }
}
// ---------------------------------------------------------------------------------------
// Closed forms (analytic.comp, the `analyticdirect` oracle): the irradiance emitter e
// gives a point p with unit normal n, with no visibility, for the surface `prim` (which
// an emitter does not light itself). Polygonal emitters: Lambert's formula for the
// irradiance of a polygon, E = L/2 * sum_i theta_i * dot(n, gamma_i) (Arvo 1995); point,
// spot and directional lights; a constant environment, E = pi L; spheres: a sphere of
// radius r whose centre is at distance D, at angle theta from the normal, gives
// E = pi L (r/D)^2 cos theta to a point outside it if its outside emits (its visible
// cap is a disk of directions; in front of a constant environment it replaces that
// disk of the environment's radiance), and E = pi L to a point inside it if its inside
// emits (an inward-facing or two-sided sphere fills the hemisphere and hides the
// environment). Ellipsoids (non-uniformly scaled spheres) are left out.
// No horizon clipping: lights must lie entirely above the surfaces they light.

// Irradiance factor sum_i theta_i * dot(n, gamma_i) / 2 of the triangle (v0, v1, v2) at p.
float polygon_irradiance_factor(vec3 p, vec3 n, vec3 v0, vec3 v1, vec3 v2) {
    vec3 r[3] = vec3[3](normalize(v0 - p), normalize(v1 - p), normalize(v2 - p));
    float sum = 0.0;
    for (int i = 0; i < 3; ++i) {
        vec3 a = r[i];
        vec3 b = r[(i + 1) % 3];
        float theta = acos(clamp(dot(a, b), -1.0, 1.0));
        vec3 c = cross(a, b);
        float len = length(c);
        if (len > 0.0) sum += theta * dot(n, c / len);
    }
    return 0.5 * abs(sum);
}

vec3 emitter_unoccluded_irradiance(uint e, vec3 p, vec3 n, uint prim) {
    GpuEmitter em = emitters[e];
    if (em.info.x == EMITTER_TRIANGLE) {
        if (em.info.y == prim) return vec3(0.0);
        vec3 ne = cross(em.p1.xyz - em.p0.xyz, em.p2.xyz - em.p0.xyz);
        // One-sided emitters light only the half-space in front of them.
        if (em.info.z == 0u && dot(p - em.p0.xyz, ne) <= 0.0) return vec3(0.0);
        return em.radiance.xyz * polygon_irradiance_factor(p, n, em.p0.xyz, em.p1.xyz, em.p2.xyz);
    } else if (em.info.x == EMITTER_POINT) {
        vec3 to = em.p0.xyz - p;
        float d2 = dot(to, to);
        return em.radiance.xyz * max(0.0, dot(n, to) / sqrt(d2)) / d2;
    } else if (em.info.x == EMITTER_INFINITE) {
        // The whole hemisphere, unoccluded: E = pi L; through a portal, the portal's
        // polygon (lighting only the points behind it).
        vec3 p0;
        vec3 e1;
        vec3 e3;
        if (env_portal(em, p0, e1, e3)) {
            if (!(dot(p0 - p, cross(e3, e1)) > 0.0)) return vec3(0.0);
            return em.radiance.xyz * (polygon_irradiance_factor(p, n, p0, p0 + e1, p0 + e1 + e3)
                                      + polygon_irradiance_factor(p, n, p0, p0 + e1 + e3, p0 + e3));
        }
        return PI * em.radiance.xyz;
    } else if (em.info.x == EMITTER_SPOT) {
        vec3 to = em.p0.xyz - p;
        float d2 = dot(to, to);
        vec3 w = to / sqrt(d2);
        return em.radiance.xyz * spot_falloff(em, -w) * max(0.0, dot(n, w)) / d2;
    } else if (emitter_kind_is_profiled(em.info.x)) {
        vec3 to = em.p0.xyz - p;
        float d2 = dot(to, to);
        vec3 w = to / sqrt(d2);
        return profile_intensity(em, -w) * max(0.0, dot(n, w)) / d2;
    } else if (em.info.x == EMITTER_DIRECTIONAL) {
        return em.radiance.xyz * max(0.0, dot(n, em.p0.xyz));
    } else if (em.info.x == EMITTER_SPHERE) {
        GpuSphere sp = spheres[em.info.y];
        if (em.info.y + scene.triangle_count == prim) return vec3(0.0);
        vec3 to = vec3(sp.o2w0.w, sp.o2w1.w, sp.o2w2.w) - p;
        // (A uniform scale: every column of the object-to-world map has length r.)
        float r2 = dot(vec3(sp.o2w0.x, sp.o2w1.x, sp.o2w2.x), vec3(sp.o2w0.x, sp.o2w1.x, sp.o2w2.x));
        float d2 = dot(to, to);
        bool inside = d2 < r2;
        if (em.info.z == 0u && inside != (sp.info.z != 0u)) return vec3(0.0);   // its back faces p
        // (It hides the constant environment behind it: that part of the
        // hemisphere's E = pi L_env is replaced.)
        vec3 behind = vec3(0.0);
        for (uint k = 0u; k < scene.environment_count; ++k) behind += emitters[scene.environment + k].radiance.xyz;
        if (inside) return PI * (em.radiance.xyz - behind);
        return (em.radiance.xyz - behind) * (PI * r2 / d2) * max(0.0, dot(n, to) / sqrt(d2));
    }
    return vec3(0.0);
}
#endif
