// Exact ray-primitive intersections (CPU mirror: src/accel/geometry.rs) and the
// surface description at a hit.
#ifndef GEOMETRY_GLSL
#define GEOMETRY_GLSL
#include "bindings.glsl"
#include "sampling.glsl"
#include "texture.glsl"
#include "features.glsl"
#include "shading_map.glsl"

const float TRIANGLE_DET_REL_EPS_SQ = 1e-10;

struct Hit {
    float t;
    uint prim;   // < triangle count: a triangle; else a sphere (prim - triangle count)
    vec2 bary;   // triangles: barycentrics of v1, v2
};

// Moller-Trumbore, two-sided; d need not be unit length.
bool intersect_triangle(vec3 v0, vec3 v1, vec3 v2, vec3 o, vec3 d, float tmin, float tmax,
                        out float t, out vec2 bary) {
    vec3 e1 = v1 - v0;
    vec3 e2 = v2 - v0;
    vec3 p = cross(d, e2);
    float det = dot(e1, p);
    t = 0.0;
    bary = vec2(0.0);
    // Degenerate triangles and rays (nearly) parallel to the plane miss.
    float scale2 = dot(e1, e1) * dot(e2, e2) * dot(d, d);
    if (abs(det) < 1.17549435e-38 || det * det <= TRIANGLE_DET_REL_EPS_SQ * scale2) return false;
    float inv_det = 1.0 / det;
    vec3 s = o - v0;
    float u = dot(s, p) * inv_det;
    if (u < 0.0 || u > 1.0) return false;
    vec3 q = cross(s, e1);
    float v = dot(d, q) * inv_det;
    if (v < 0.0 || u + v > 1.0) return false;
    t = dot(e2, q) * inv_det;
    bary = vec2(u, v);
    return t > tmin && t < tmax;
}

vec3 sphere_to_object_point(GpuSphere s, vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(s.w2o0, h), dot(s.w2o1, h), dot(s.w2o2, h));
}
vec3 sphere_to_object_dir(GpuSphere s, vec3 d) {
    return vec3(dot(s.w2o0.xyz, d), dot(s.w2o1.xyz, d), dot(s.w2o2.xyz, d));
}
vec3 sphere_to_world_point(GpuSphere s, vec3 q) {
    vec4 h = vec4(q, 1.0);
    return vec3(dot(s.o2w0, h), dot(s.o2w1, h), dot(s.o2w2, h));
}
// Unnormalised world normal at object-space point q: (W^T) q, W = world-to-object;
// turned inward for an inward-facing sphere (every use of a sphere's normal is this).
vec3 sphere_normal_unnormalized(GpuSphere s, vec3 q) {
    vec3 n = q.x * s.w2o0.xyz + q.y * s.w2o1.xyz + q.z * s.w2o2.xyz;
    return s.info.z != 0u ? -n : n;
}

// The unit sphere in object space; t is the same parameter as in world space because
// the object-space direction is not renormalised.
bool intersect_sphere(GpuSphere s, vec3 o, vec3 d, float tmin, float tmax, out float t) {
    vec3 oo = sphere_to_object_point(s, o);
    vec3 dd = sphere_to_object_dir(s, d);
    float a = dot(dd, dd);
    t = 0.0;
    if (a < 1.17549435e-38) return false;
    float b = dot(oo, dd);
    float c = dot(oo, oo) - 1.0;
    // Discriminant from the closest point on the line (Ray Tracing Gems, ch. 7).
    vec3 l = oo - (b / a) * dd;
    float disc = a * (1.0 - dot(l, l));
    if (disc < 0.0) return false;
    float q = -b - (b >= 0.0 ? 1.0 : -1.0) * sqrt(disc);
    float t0 = q != 0.0 ? c / q : 0.0;
    float t1 = q / a;
    if (t0 > t1) { float tmp = t0; t0 = t1; t1 = tmp; }
    if (t0 > tmin && t0 < tmax) { t = t0; return true; }
    if (t1 > tmin && t1 < tmax) { t = t1; return true; }
    return false;
}

// pbrt-v4's stochastic alpha test. A uniform number in [0, 1) that is a fixed function of
// the ray (o, d) and the triangle (its first corner v0, the same under every backend's
// numbering): a cut-out is decided once per ray and triangle. CPU mirror: src/alpha.rs.
float alpha_hash(vec3 o, vec3 d, vec3 v0) {
    uvec3 a = floatBitsToUint(o);
    uvec3 b = floatBitsToUint(d);
    uvec3 c = floatBitsToUint(v0);
    uint h = hash_pcg(a.x);
    h = hash_pcg(h ^ a.y);
    h = hash_pcg(h ^ a.z);
    h = hash_pcg(h ^ b.x);
    h = hash_pcg(h ^ b.y);
    h = hash_pcg(h ^ b.z);
    h = hash_pcg(h ^ c.x);
    h = hash_pcg(h ^ c.y);
    h = hash_pcg(h ^ c.z);
    return float(h >> 8u) * (1.0 / 16777216.0);
}

// Whether the ray (o, d) that hits the triangle `tri` at barycentrics bary passes through
// it: its alpha a there (a constant or a float texture at the hit's uv and point) keeps
// the hit where a >= 1, cuts it where a <= 0, and otherwise cuts it when alpha_hash > a
// (pbrt-v4's GeometricPrimitive test). Every visibility backend asks here, for closest
// hits and shadow rays alike.
bool alpha_cut(GpuTriangle tri, vec2 bary, vec3 o, vec3 d) {
    if (!has_feature(FEATURE_ALPHA)) return false;
    uint ai = floatBitsToUint(tri.v2.w);
    if (ai == NO_ATTRIBUTES) return false;
    TriangleAttributes at = attribute_record(ai);
    float kind = at.n0.w;
    if (kind == float(ALPHA_NONE)) return false;
    float alpha = at.n1.w;
    if (kind == float(ALPHA_TEXTURE)) {
        vec4 uv01 = at.uv01;
        vec2 uv2 = at.uv2.xy;
        float b0 = 1.0 - bary.x - bary.y;
        vec2 uv = b0 * uv01.xy + bary.x * uv01.zw + bary.y * uv2;
        vec3 p = tri.v0.xyz + bary.x * (tri.v1.xyz - tri.v0.xyz) + bary.y * (tri.v2.xyz - tri.v0.xyz);
        vec3 ng = normalize(cross(tri.v1.xyz - tri.v0.xyz, tri.v2.xyz - tri.v0.xyz));
        // (pbrt-v4's alpha test looks its texture up without a footprint.)
        alpha = texture_value(floatBitsToUint(alpha), uv, p, ng, vec3(0.0), vec3(0.0), vec4(0.0), alpha_texture_features()).x;
    }
    if (alpha >= 1.0) return false;
    if (alpha <= 0.0) return true;
    return alpha_hash(o, d, tri.v0.xyz) > alpha;
}

struct Surface {
    vec3 p;       // position
    vec3 ng;      // unit geometric normal (not flipped)
    uint material;
    uint emitter; // NO_EMITTER if the primitive emits nothing
    uint prim;
    vec2 uv;      // texture coordinates
    vec3 ns;      // unit shading normal (interpolated from a mesh's normals; else ng), on
                  // ng's side (the parser winds meshes so)
    vec4 tex0;    // the material's texture values here (material_texture's slots: xyz slot
    vec4 tex1;    // 0, w slot 2; xyz slot 1, w slot 3), for material_bsdf; 0 without one
};

// pbrt's (u, v) of a point q on the unit sphere: u the azimuth about +z from +x over
// 2 pi, v from the -z pole (0) to the +z pole (1).
vec2 sphere_uv(vec3 q) {
    q = normalize(q);
    float phi = atan(q.y, q.x);
    if (phi < 0.0) phi += 2.0 * 3.14159265358979;
    return vec2(phi * (0.5 / 3.14159265358979), 1.0 - acos(clamp(q.z, -1.0, 1.0)) * (1.0 / 3.14159265358979));
}

// Instanced objects (FEATURE_INSTANCES). Triangle ids below scene.flat_triangle_count are
// the world's triangles (their records); the ids up to scene.triangle_count are the
// instances' triangles, instance after instance (GpuInstance.info.x its first). A
// surface of an instance is made of its triangle carried to the world: corners by the
// instance's transform, shading normals by its inverse transpose (each normalized, as the
// flattened twin's), the geometric normal flipped back under a mirroring transform.
#define NO_INSTANCE 0xffffffffu

// The instance whose triangle ids hold id: the last whose first id is at most id.
uint instance_of(uint id) {
    uint lo = 0u;
    uint hi = scene.instance_count;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) >> 1;
        if (instances[mid].info.x <= id) lo = mid;
        else hi = mid;
    }
    return lo;
}

vec3 instance_point(uint inst, vec3 p) {
    vec4 q = vec4(p, 1.0);
    return vec3(dot(instances[inst].o2w0, q), dot(instances[inst].o2w1, q), dot(instances[inst].o2w2, q));
}

// A normal to the world: the transpose of world-to-object's upper 3x3 times n, normalized.
vec3 instance_normal(uint inst, vec3 n) {
    vec3 m = n.x * instances[inst].w2o0.xyz + n.y * instances[inst].w2o1.xyz + n.z * instances[inst].w2o2.xyz;
    float l = length(m);
    return l > 0.0 ? m / l : vec3(0.0);
}

// The triangle of id `id` in the world (corners; the w fields as its record holds them)
// and the instance it is seen through (NO_INSTANCE: a world triangle).
GpuTriangle world_triangle(uint id, out uint inst) {
    inst = NO_INSTANCE;
    if (!has_feature(FEATURE_INSTANCES) || id < scene.flat_triangle_count) return triangle_record(id);
    inst = instance_of(id);
    GpuTriangle tri = triangle_record(id - instances[inst].info.y);
    tri.v0.xyz = instance_point(inst, tri.v0.xyz);
    tri.v1.xyz = instance_point(inst, tri.v1.xyz);
    tri.v2.xyz = instance_point(inst, tri.v2.xyz);
    return tri;
}

// The attribute record a, its shading normals carried to the world through inst.
TriangleAttributes world_attributes(uint a, uint inst) {
    TriangleAttributes at = attribute_record(a);
    if (has_feature(FEATURE_INSTANCES) && inst != NO_INSTANCE && at.uv2.z != 0.0) {
        at.n0.xyz = instance_normal(inst, at.n0.xyz);
        at.n1.xyz = instance_normal(inst, at.n1.xyz);
        at.n2.xyz = instance_normal(inst, at.n2.xyz);
    }
    return at;
}

// The unit geometric normal of a world triangle seen through inst.
vec3 world_triangle_normal(GpuTriangle tri, uint inst) {
    vec3 ng = normalize(cross(tri.v1.xyz - tri.v0.xyz, tri.v2.xyz - tri.v0.xyz));
    if (has_feature(FEATURE_INSTANCES) && inst != NO_INSTANCE && instances[inst].info.w != 0u) ng = -ng;
    return ng;
}

// The shading geometry of the primitive at s for its material's bump or normal map (s.ns
// as the primitive gives it).
ShadingGeometry map_geometry(Hit hit, Surface s) {
    uint ntri = scene.triangle_count;
    if (hit.prim < ntri) {
        uint inst;
        GpuTriangle tri = world_triangle(hit.prim, inst);
        uint a = floatBitsToUint(tri.v2.w);
        vec2 uv0 = vec2(0.0);
        vec2 uv1 = vec2(1.0, 0.0);
        vec2 uv2 = vec2(1.0);
        bool normals = false;
        vec3 n0 = vec3(0.0);
        vec3 n1 = vec3(0.0);
        vec3 n2 = vec3(0.0);
        if (a != NO_ATTRIBUTES) {
            TriangleAttributes at = world_attributes(a, inst);
            uv0 = at.uv01.xy;
            uv1 = at.uv01.zw;
            uv2 = at.uv2.xy;
            normals = at.uv2.z != 0.0;
            n0 = at.n0.xyz;
            n1 = at.n1.xyz;
            n2 = at.n2.xyz;
        }
        return triangle_shading_geometry(tri.v0.xyz, tri.v1.xyz, tri.v2.xyz, uv0, uv1, uv2,
                                         normals, n0, n1, n2, s.ns);
    }
    GpuSphere sp = spheres[hit.prim - ntri];
    return sphere_shading_geometry(sp.o2w0.xyz, sp.o2w1.xyz, sp.o2w2.xyz, sp.w2o0.xyz,
                                   sp.w2o1.xyz, sp.w2o2.xyz, sphere_to_object_point(sp, s.p),
                                   s.ns);
}

// The footprint of a pixel at the surface point p with unit geometric normal n: pbrt-v4's
// dp/dx and dp/dy, by which its textures filter (noise octaves, bump map steps): where the
// camera rays through the pixels beside p's own film point (one right, one down) meet p's
// tangent plane, less p, times 1/8 (pbrt-v4's max(1/8, 1/sqrt(spp)) at 64 samples per
// pixel or more: fixed here, so that a render converges to one image at any spp). A
// function of the point alone, so every subpath reaching it (camera or light; PT, BDPT,
// MMLT) meets the same texture: where the camera sees p directly it is pbrt-v4's
// camera-ray differential (a thin lens's taken at its centre); elsewhere pbrt-v4
// approximates with the image's smallest differential, and this takes the one of the film
// point p projects to (behind the camera, the film centre's angle about the ray to p).
// Zero (no footprint) where undefined. CPU mirror: src/gpu_scene.rs surface_footprint.
void surface_footprint(vec3 p, vec3 n, out vec3 dpdx, out vec3 dpdy) {
    vec3 to = p - scene.cam_eye.xyz;
    float z = dot(to, scene.cam_forward.xyz);
    float k = z > 0.0 ? z : length(to);
    float sx = (scene.cam_window.y - scene.cam_window.x) / float(scene.width);
    float sy = (scene.cam_window.w - scene.cam_window.z) / float(scene.height);
    vec3 rx = to + (k * sx) * scene.cam_right.xyz;
    vec3 ry = to - (k * sy) * scene.cam_up.xyz;
    float pn = dot(n, to);
    float ax = dot(n, rx);
    float ay = dot(n, ry);
    dpdx = ax != 0.0 ? 0.125 * ((pn / ax) * rx - to) : vec3(0.0);
    dpdy = ay != 0.0 ? 0.125 * ((pn / ay) * ry - to) : vec3(0.0);
    if (any(isinf(dpdx)) || any(isnan(dpdx)) || any(isinf(dpdy)) || any(isnan(dpdy))) {
        dpdx = vec3(0.0);
        dpdy = vec3(0.0);
    }
}

// s's material with its mixes resolved, then the shading normal of that material's bump
// or normal map (MATERIAL_BUMP_MAP / MATERIAL_NORMAL_MAP, texture in roughness.w), then
// the values of the material's own textures (material_texture's slots, into s.tex0 and
// s.tex1 for material_bsdf).
//
// pbrt-v4's mix material is not a surface but a choice between two materials, made at
// each point by a hash of its position (and the mix), so that every subpath reaching
// the point meets the same material: the second with probability `amount`. Nested
// mixes resolve in turn. pbrt-v4's BumpMap looks the displacement up three times (at
// (u, v), a step along u, one along v: half the pixel footprint's extent in each,
// bump_steps), its NormalMap once.
//
// Every texture lookup of a surface point is made here, at the loop's one call of
// texture_value (the mixes' amounts first, then the map's, then the material's), so that
// a kernel holds one copy of the texture code, and only the kernels that find surfaces
// hold it: the shade stages read the values (lavapipe's compile time grows faster than a
// kernel).
void resolve_material_and_map(Hit hit, inout Surface s) {
    s.tex0 = vec4(0.0);
    s.tex1 = vec4(0.0);
    // (Scenes with hair have FEATURE_MATERIAL_TEXTURES: the host sets it.)
    if (!has_feature(FEATURE_MIX) && !has_feature(FEATURE_SHADING_MAPS) && !has_feature(FEATURE_MATERIAL_TEXTURES)) return;
    uint m = s.material;
    uint depth = 0u;
    bool resolving = has_feature(FEATURE_MIX);
    bool mapped = false;
    bool hair = false;
    uint flags = 0u;
    uint tex = NO_TEXTURE;
    uint lookups = 0u;
    uint k = 0u;
    uint slot = 0u;
    uint slots = has_feature(FEATURE_MATERIAL_TEXTURES) ? MATERIAL_TEXTURE_SLOTS : 0u;
    ShadingGeometry g;
    vec3 c = vec3(0.0);
    vec3 h = vec3(0.0);
    // The pixel footprint at the point (surface_footprint), for the noise textures, the
    // bump map's steps and (in (u, v): uv_footprint, from the surface's dp/du, dp/dv) the
    // MIP levels.
    vec3 dpdx = vec3(0.0);
    vec3 dpdy = vec3(0.0);
    bool mip = has_feature(FEATURE_MIP_TEXTURES);
    if (has_texture_feature(spec_features, FEATURE_PROCEDURAL_TEXTURES) || has_feature(FEATURE_SHADING_MAPS) || mip) {
        surface_footprint(s.p, s.ng, dpdx, dpdy);
    }
    vec4 duv = vec4(0.0);
    if (mip) {
        g = map_geometry(hit, s);
        duv = uv_footprint(g, dpdx, dpdy);
    }
    vec2 delta = vec2(BUMP_DELTA);
    for (uint step = 0u; step < MAX_MATERIAL_MIX_DEPTH + 3u + MATERIAL_TEXTURE_SLOTS; ++step) {
        uint index = NO_TEXTURE;
        vec2 uv = s.uv;
        vec3 p = s.p;
        bool mixing = false;
        if (resolving) {
            uvec4 info = materials[m].info;
            mixing = depth < MAX_MATERIAL_MIX_DEPTH && (info.y & MATERIAL_MIX) != 0u;
            resolving = mixing;
            index = info.z;
        }
        if (!mixing) {
            if (!mapped) {
                // The material is resolved: its map's lookups follow.
                mapped = true;
                flags = materials[m].info.y;
                bool map = has_feature(FEATURE_SHADING_MAPS) && (flags & (MATERIAL_BUMP_MAP | MATERIAL_NORMAL_MAP)) != 0u;
                hair = has_feature(FEATURE_HAIR) && materials[m].info.x == BSDF_HAIR;
                // (With MIP textures g is the point's already.)
                if ((map || hair) && !mip) g = map_geometry(hit, s);
                if (map) {
                    tex = floatBitsToUint(materials[m].roughness.w);
                    lookups = (flags & MATERIAL_NORMAL_MAP) != 0u ? 1u : 3u;
                    if (lookups == 3u) delta = bump_steps(g, dpdx, dpdy);
                }
            }
            if (k < lookups) {
                float su = k == 1u ? delta.x : 0.0;
                float sv = k == 2u ? delta.y : 0.0;
                index = tex;
                uv = s.uv + vec2(su, sv);
                p = s.p + su * g.dpdu + sv * g.dpdv;
            } else if (slot < slots) {
                index = material_texture(materials[m], slot);
            } else {
                break;
            }
        }
        vec3 v = index == NO_TEXTURE ? vec3(0.0) : texture_value(index, uv, p, s.ng, dpdx, dpdy, duv, spec_features);
        if (mixing) {
            vec4 mix_params = materials[m].specular;
            float amount = index == NO_TEXTURE ? mix_params.z : v.x;
            uvec3 b = floatBitsToUint(s.p);
            uint hh = hash_pcg(hash_pcg(hash_pcg(hash_pcg(m) ^ b.x) ^ b.y) ^ b.z);
            float u = (float(hh >> 8u) + 0.5) * (1.0 / 16777216.0);
            m = floatBitsToUint(amount < u ? mix_params.x : mix_params.y);
            depth += 1u;
        } else if (k < lookups) {
            c = v;
            h[k] = v.x;
            k += 1u;
        } else {
            if (slot == 0u) s.tex0.xyz = v;
            else if (slot == 1u) s.tex1.xyz = v;
            else if (slot == 2u) s.tex0.w = v.x;
            else s.tex1.w = v.x;
            slot += 1u;
        }
    }
    s.material = m;
    // Hair's frame follows the fiber (dp/du), its offset across it is pbrt's -1 + 2v.
    if (hair) s.tex1 = vec4(g.dpdu, -1.0 + 2.0 * s.uv.y);
    if (lookups > 0u) {
        s.ns = (flags & MATERIAL_NORMAL_MAP) != 0u ? normal_mapped_normal(g, c, s.ng)
                                                   : bump_mapped_normal(g, h, s.ng, delta);
    }
}

// The emitter of primitive prim (NO_EMITTER if it emits nothing): Surface.emitter, for a
// stage that keeps the surface in memory rather than finding it again.
uint primitive_emitter(uint prim) {
    uint ntri = scene.triangle_count;
    if (prim >= ntri) return spheres[prim - ntri].info.y;
    // (An instance's triangles emit nothing: emitting shapes are flattened.)
    return has_feature(FEATURE_INSTANCES) && prim >= scene.flat_triangle_count ? NO_EMITTER : floatBitsToUint(triangle_record(prim).v1.w);
}

Surface surface_at(Hit hit, vec3 o, vec3 d) {
    Surface s;
    s.prim = hit.prim;
    uint ntri = scene.triangle_count;
    if (hit.prim < ntri) {
        uint inst;
        GpuTriangle tri = world_triangle(hit.prim, inst);
        vec3 e1 = tri.v1.xyz - tri.v0.xyz;
        vec3 e2 = tri.v2.xyz - tri.v0.xyz;
        s.p = tri.v0.xyz + hit.bary.x * e1 + hit.bary.y * e2;
        s.ng = normalize(cross(e1, e2));
        if (has_feature(FEATURE_INSTANCES) && inst != NO_INSTANCE && instances[inst].info.w != 0u) s.ng = -s.ng;
        s.material = floatBitsToUint(tri.v0.w);
        s.emitter = floatBitsToUint(tri.v1.w);
        uint a = floatBitsToUint(tri.v2.w);
        float b0 = 1.0 - hit.bary.x - hit.bary.y;
        s.ns = s.ng;
        if (a == NO_ATTRIBUTES) {
            // pbrt's default (0,0), (1,0), (1,1).
            s.uv = vec2(hit.bary.x + hit.bary.y, hit.bary.y);
        } else {
            TriangleAttributes at = world_attributes(a, inst);
            s.uv = b0 * at.uv01.xy + hit.bary.x * at.uv01.zw + hit.bary.y * at.uv2.xy;
            if (at.uv2.z != 0.0) {
                vec3 ns = b0 * at.n0.xyz + hit.bary.x * at.n1.xyz + hit.bary.y * at.n2.xyz;
                float l = length(ns);
                if (l > 0.0) s.ns = ns / l;
            }
        }
    } else {
        GpuSphere sp = spheres[hit.prim - ntri];
        s.p = o + hit.t * d;
        vec3 q = sphere_to_object_point(sp, s.p);
        s.ng = normalize(sphere_normal_unnormalized(sp, q));
        s.material = sp.info.x;
        s.emitter = sp.info.y;
        s.uv = sphere_uv(q);
        s.ns = s.ng;
    }
    resolve_material_and_map(hit, s);
    return s;
}

// The material of the primitive a ray (o, d) hit, as the primitive holds it (a mix
// unresolved), and its unit geometric normal ng as surface_at gives it: what a shadow ray
// through media asks of the surfaces it crosses.
uint primitive_material(Hit hit, vec3 o, vec3 d, out vec3 ng) {
    if (hit.prim < scene.triangle_count) {
        uint inst;
        GpuTriangle tri = world_triangle(hit.prim, inst);
        ng = world_triangle_normal(tri, inst);
        return floatBitsToUint(tri.v0.w);
    }
    GpuSphere sp = spheres[hit.prim - scene.triangle_count];
    ng = normalize(sphere_normal_unnormalized(sp, sphere_to_object_point(sp, o + hit.t * d)));
    return sp.info.x;
}

// Move a ray origin off a surface by a few ULPs along the normal, robust at any scale
// (Wachter & Binder, Ray Tracing Gems ch. 6).
vec3 offset_ray_origin(vec3 p, vec3 n) {
    const float origin = 1.0 / 32.0;
    const float float_scale = 1.0 / 65536.0;
    const float int_scale = 256.0;
    ivec3 of_i = ivec3(int_scale * n);
    vec3 p_i = vec3(
        intBitsToFloat(floatBitsToInt(p.x) + ((p.x < 0.0) ? -of_i.x : of_i.x)),
        intBitsToFloat(floatBitsToInt(p.y) + ((p.y < 0.0) ? -of_i.y : of_i.y)),
        intBitsToFloat(floatBitsToInt(p.z) + ((p.z < 0.0) ? -of_i.z : of_i.z)));
    return vec3(abs(p.x) < origin ? p.x + float_scale * n.x : p_i.x,
                abs(p.y) < origin ? p.y + float_scale * n.y : p_i.y,
                abs(p.z) < origin ? p.z + float_scale * n.z : p_i.z);
}

// A shadow ray stops this fraction of its length short of its target (pbrt-v4's
// ShadowEpsilon). Offsetting the target off its surface is not enough: the offset is a
// few ULPs of the target's coordinates (an absolute 2^-16 where a coordinate is near 0),
// while the ray's intersection with that surface, computed from a distant origin, errs in
// proportion to the distance. A floor at y = 0 seen from 500 units away then occludes
// its own points, and BDPT's connections to it came out dark (issue 26).
const float SHADOW_EPSILON = 1e-4;

// The shadow ray from the surface point p (offset along n, the normal on the side the
// ray leaves) to `target` (already off its own surface, or a point in space): origin,
// unit direction and extent. Every visibility test between two points is built here.
void shadow_ray_to(vec3 p, vec3 n, vec3 target, out vec3 o, out vec3 d, out float tmax) {
    o = offset_ray_origin(p, n);
    vec3 to = target - o;
    float dist = length(to);
    d = dist > 0.0 ? to / dist : n;
    tmax = dist * (1.0 - SHADOW_EPSILON);
}
#endif
