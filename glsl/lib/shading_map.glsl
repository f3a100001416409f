// Bump and normal maps: the shading normal of a material with a displacement texture
// (pbrt-v4's BumpMap) or a normal map (pbrt-v4's NormalMap), from the surface's shading
// geometry (pbrt-v4's: dp/du, dp/dv, dn/du, dn/dv). Called from surface_at only, so that
// every integrator and strategy sees one shading normal at a point; the BSDFs' shading
// normal rules and the adjoint correction (bsdf.glsl) apply to it as to any other.
// CPU mirror: src/shading_map.rs.
#ifndef SHADING_MAP_GLSL
#define SHADING_MAP_GLSL
#include "bindings.glsl"
#include "sampling.glsl"
#include "texture.glsl"

// pbrt-v4's shading geometry at a point: the partial derivatives of position and of the
// unit shading normal n along u and v. For meshes with normals, dp/du is made
// perpendicular to n and dp/dv is n x dp/du (as pbrt-v4's triangles make them).
struct ShadingGeometry {
    vec3 n;
    vec3 dpdu;
    vec3 dpdv;
    vec3 dndu;
    vec3 dndv;
};

// A triangle's: corners p0..p2 with texture coordinates uv0..uv2 and, when `normals`,
// shading normals n0..n2; n the shading normal at the point (the geometric one without
// normals).
ShadingGeometry triangle_shading_geometry(vec3 p0, vec3 p1, vec3 p2, vec2 uv0, vec2 uv1,
                                          vec2 uv2, bool normals, vec3 n0, vec3 n1, vec3 n2,
                                          vec3 n) {
    ShadingGeometry g;
    g.n = n;
    vec2 duv02 = uv0 - uv2;
    vec2 duv12 = uv1 - uv2;
    vec3 dp02 = p0 - p2;
    vec3 dp12 = p1 - p2;
    float det = duv02.x * duv12.y - duv02.y * duv12.x;
    bool degenerate = abs(det) < 1e-9;
    if (!degenerate) {
        float inv = 1.0 / det;
        g.dpdu = (duv12.y * dp02 - duv02.y * dp12) * inv;
        g.dpdv = (duv02.x * dp12 - duv12.x * dp02) * inv;
    }
    if (degenerate || dot(cross(g.dpdu, g.dpdv), cross(g.dpdu, g.dpdv)) == 0.0) {
        build_onb(normalize(cross(p1 - p0, p2 - p0)), g.dpdu, g.dpdv);
    }
    g.dndu = vec3(0.0);
    g.dndv = vec3(0.0);
    if (normals) {
        vec3 ts = cross(n, g.dpdu);
        if (dot(ts, ts) > 0.0) {
            g.dpdu = cross(ts, n);
            g.dpdv = ts;
        } else {
            build_onb(n, g.dpdu, g.dpdv);
        }
        if (abs(det) >= 1e-32) {
            vec3 dn1 = n0 - n2;
            vec3 dn2 = n1 - n2;
            float inv = 1.0 / det;
            g.dndu = (duv12.y * dn1 - duv02.y * dn2) * inv;
            g.dndv = (duv02.x * dn2 - duv12.x * dn1) * inv;
        }
    }
    return g;
}

// A sphere's (the unit sphere under the affine map with linear rows o2w0..o2w2 and
// inverse rows w2o0..w2o2): q the point on the unit sphere, n the unit normal there.
// pbrt's u = phi / 2 pi and v = 1 - theta / pi. dn/du and dn/dv are the derivatives of
// the unit world normal (exact under any affine map).
ShadingGeometry sphere_shading_geometry(vec3 o2w0, vec3 o2w1, vec3 o2w2, vec3 w2o0, vec3 w2o1,
                                        vec3 w2o2, vec3 q, vec3 n) {
    ShadingGeometry g;
    g.n = n;
    q = normalize(q);
    if (q.x == 0.0 && q.y == 0.0) q.x = 1e-5;
    float r_xy = length(q.xy);
    float cos_phi = q.x / r_xy;
    float sin_phi = q.y / r_xy;
    vec3 du = TWO_PI * vec3(-q.y, q.x, 0.0);
    vec3 dv = -PI * vec3(q.z * cos_phi, q.z * sin_phi, -r_xy);
    g.dpdu = vec3(dot(o2w0, du), dot(o2w1, du), dot(o2w2, du));
    g.dpdv = vec3(dot(o2w0, dv), dot(o2w1, dv), dot(o2w2, dv));
    // The world normal is N(q) / |N(q)| with N the inverse transpose: its derivative along
    // u is the part of N(dq/du) / |N(q)| across n (dq/du = du on the unit sphere).
    vec3 nq = q.x * w2o0 + q.y * w2o1 + q.z * w2o2;
    float inv_len = 1.0 / length(nq);
    vec3 nu = (du.x * w2o0 + du.y * w2o1 + du.z * w2o2) * inv_len;
    vec3 nv = (dv.x * w2o0 + dv.y * w2o1 + dv.z * w2o2) * inv_len;
    vec3 m = nq * inv_len;
    g.dndu = nu - m * dot(m, nu);
    g.dndv = nv - m * dot(m, nv);
    return g;
}

// The pixel footprint in (u, v): (du/dx, dv/dx, du/dy, dv/dy), the least-squares
// solutions of dp/dx = du/dx dp/du + dv/dx dp/dv and likewise for y (pbrt-v4's
// ComputeDifferentials, clamped to 1e8 as its); zero where dp/du, dp/dv are degenerate.
// (pbrt-v4 solves with the surface's geometric dp/du; this with the shading geometry's,
// the same but on meshes with normals.) CPU mirror: src/shading_map.rs uv_footprint.
vec4 uv_footprint(ShadingGeometry g, vec3 dpdx, vec3 dpdy) {
    float a00 = dot(g.dpdu, g.dpdu);
    float a01 = dot(g.dpdu, g.dpdv);
    float a11 = dot(g.dpdv, g.dpdv);
    float det = a00 * a11 - a01 * a01;
    float inv = det != 0.0 && !isinf(1.0 / det) ? 1.0 / det : 0.0;
    vec2 bx = vec2(dot(g.dpdu, dpdx), dot(g.dpdv, dpdx));
    vec2 by = vec2(dot(g.dpdu, dpdy), dot(g.dpdv, dpdy));
    vec2 ddx = clamp(vec2(a11 * bx.x - a01 * bx.y, a00 * bx.y - a01 * bx.x) * inv, -1e8, 1e8);
    vec2 ddy = clamp(vec2(a11 * by.x - a01 * by.y, a00 * by.y - a01 * by.x) * inv, -1e8, 1e8);
    return vec4(ddx, ddy);
}

// pbrt-v4's steps in u and v for a bump map's differences: half the footprint's extent
// in u and in v, (|du/dx| + |du/dy|) / 2 and likewise (uv_footprint); BUMP_DELTA where
// that is 0 (no footprint).
vec2 bump_steps(ShadingGeometry g, vec3 dpdx, vec3 dpdy) {
    vec4 d = uv_footprint(g, dpdx, dpdy);
    vec2 steps = 0.5 * (abs(d.xy) + abs(d.zw));
    return vec2(steps.x > 0.0 ? steps.x : BUMP_DELTA, steps.y > 0.0 ? steps.y : BUMP_DELTA);
}

// pbrt-v4's BumpMap: the displacement texture's values h = (d at (uv, p), d a step
// delta.x along u, d a step delta.y along v; bump_steps) move the surface along n; the
// shading normal is the displaced surface's, cross(dp/du, dp/dv), on ng's side.
// Unchanged where that is degenerate.
vec3 bump_mapped_normal(ShadingGeometry g, vec3 h, vec3 ng, vec2 delta) {
    vec3 dpdu = g.dpdu + (h.y - h.x) / delta.x * g.n + h.x * g.dndu;
    vec3 dpdv = g.dpdv + (h.z - h.x) / delta.y * g.n + h.x * g.dndv;
    vec3 ns = cross(dpdu, dpdv);
    float l = length(ns);
    if (!(l > 0.0) || isinf(l)) return g.n;
    ns /= l;
    return dot(ns, ng) < 0.0 ? -ns : ns;
}

// pbrt-v4's NormalMap: the texture's RGB c gives the normal 2c - 1 in the frame
// (x = dp/du, y = n x dp/du, z = n); on ng's side.
vec3 normal_mapped_normal(ShadingGeometry g, vec3 c, vec3 ng) {
    c = 2.0 * c - 1.0;
    float l = length(c);
    if (!(l > 0.0)) return g.n;
    c /= l;
    vec3 x = normalize(g.dpdu);
    vec3 ns = normalize(c.x * x + c.y * cross(g.n, x) + c.z * g.n);
    return dot(ns, ng) < 0.0 ? -ns : ns;
}

#endif
