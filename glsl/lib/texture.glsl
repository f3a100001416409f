// Textures: image lookup (bilinear or point, wrapped; MIP levels), pbrt's 2D and 3D checkerboard, and
// textures made of textures (pbrt-v4's scale, mix and directionmix, as programs). CPU mirror:
// src/texture.rs (`texture_value`).
#ifndef TEXTURE_GLSL
#define TEXTURE_GLSL
#include "bindings.glsl"
#include "features.glsl"
#include "sampling.glsl"
#include "noise.glsl"

// The texel (x, y); black outside the image (x or y negative: wrap_texel's `black`).
// Float texels are three floats; an 8-bit image's one word of bytes, each read through
// its table (abi.h GpuTexture).
vec3 texel(GpuTexture t, int x, int y) {
    if (x < 0 || y < 0) return vec3(0.0);
    uint p = uint(y) * t.info.z + uint(x);
    uvec3 at = t.info.y + 3u * p + uvec3(0u, 1u, 2u);
    if (t.flags.w != 0u) {
        uint word = floatBitsToUint(texel(t.info.y + p));
        at = t.flags.w - 1u + (uvec3(word, word >> 8u, word >> 16u) & 255u);
    }
    return vec3(texel(at.x), texel(at.y), texel(at.z));
}

// The texel index of the (floored) coordinate i along a side of n texels: repeating,
// clamped, or (black) -1 outside the side.
int wrap_texel(float i, int n, bool repeat, bool black) {
    float fn = float(n);
    if (black && (i < 0.0 || i >= fn)) return -1;
    if (repeat) i -= fn * floor(i / fn);
    return clamp(int(i), 0, n - 1);
}

// The texture code a lookup holds is that of the FEATURE_* texture bits in `tf` (the
// scene's, or for the alpha test those of the alpha textures: alpha_texture_features), a
// constant at every call site.
bool has_texture_feature(uint tf, uint feature) { return (tf & feature) != 0u; }

// A texture's (s, t) at the surface coordinates uv and world point p (pbrt-v4's
// TextureMapping2D: uv, spherical, cylindrical, planar).
vec2 texture_st(GpuTexture t, vec2 uv, vec3 p, uint tf) {
    if (!has_texture_feature(tf, FEATURE_TEXTURE_PROJECTIONS) || t.flags.z == TEXTURE_MAP_UV) return t.mapping.xy * uv + t.mapping.zw;
    vec4 h = vec4(p, 1.0);
    vec3 q = vec3(dot(t.proj0, h), dot(t.proj1, h), dot(t.proj2, h));
    if (t.flags.z == TEXTURE_MAP_PLANAR || t.flags.z == TEXTURE_MAP_SOLID) return q.xy;
    if (t.flags.z == TEXTURE_MAP_CYLINDRICAL) return vec2((PI + atan(q.y, q.x)) * INV_TWO_PI, q.z);
    vec3 d = normalize(q);
    float phi = atan(d.y, d.x);
    if (phi < 0.0) phi += 2.0 * PI;
    return vec2(acos(clamp(d.z, -1.0, 1.0)) * INV_PI, phi * INV_TWO_PI);
}

// An image's MIP level below the next: level l's texture (its first float and size)
// becomes level l + 1's (levels one after another from info.y, each max(1, w >> l) x
// max(1, h >> l) texels of three floats or one word; src/mipmap.rs).
GpuTexture next_image_level(GpuTexture t) {
    t.info.y += (t.flags.w != 0u ? 1u : 3u) * t.info.z * t.info.w;
    t.info.zw = max(t.info.zw >> 1u, uvec2(1u));
    return t;
}

// Bilinear lookup of the image (or one MIP level) t at (x, y) in [0,1]^2 from its top-left
// corner (texel centres at half-integers), wrapped as flags.x says; with `point`, the
// texel whose centre is nearest (pbrt-v4's point filter: the weights 0 or 1, halves up).
vec3 image_lookup(GpuTexture t, vec2 at, bool point) {
    int w = int(t.info.z);
    int h = int(t.info.w);
    // Texel centres at half-integers.
    float x = at.x * float(w) - 0.5;
    float y = at.y * float(h) - 0.5;
    float fx = floor(x);
    float fy = floor(y);
    float ax = x - fx;
    float ay = y - fy;
    if (point) {
        ax = step(0.5, ax);
        ay = step(0.5, ay);
    }
    bool repeat_u = t.flags.x == TEXTURE_WRAP_REPEAT || t.flags.x == TEXTURE_WRAP_REPEAT_U;
    bool repeat_v = t.flags.x == TEXTURE_WRAP_REPEAT;
    bool black = t.flags.x == TEXTURE_WRAP_BLACK;
    int x0 = wrap_texel(fx, w, repeat_u, black);
    int x1 = wrap_texel(fx + 1.0, w, repeat_u, black);
    int y0 = wrap_texel(fy, h, repeat_v, black);
    int y1 = wrap_texel(fy + 1.0, h, repeat_v, black);
    vec3 top = mix(texel(t, x0, y0), texel(t, x1, y0), ax);
    vec3 bottom = mix(texel(t, x0, y1), texel(t, x1, y1), ax);
    return mix(top, bottom, ay);
}

// One MIP level t read by pbrt-v4's elliptically weighted average at st (in [0,1]^2 from
// the top-left corner) under the footprint (d0, d1) (in the same units): in texels, the
// ellipse q(x) = x^T M x <= 1 whose M is the inverse of the footprint's covariance plus
// one texel in each direction (A, B, C below, normalised by its determinant F), and every
// texel centre inside weighted by a Gaussian of q, exp(-2 q) - exp(-2), q quantised to
// 1/128 as pbrt-v4's table. Texels wrap as image_lookup's. CPU mirror: src/mipmap.rs
// ewa_level.
vec3 image_ewa_level(GpuTexture t, vec2 st, vec2 d0, vec2 d1) {
    int w = int(t.info.z);
    int h = int(t.info.w);
    vec2 res = vec2(t.info.zw);
    vec2 c = st * res - 0.5;
    d0 *= res;
    d1 *= res;
    float a = d0.y * d0.y + d1.y * d1.y + 1.0;
    float b = -2.0 * (d0.x * d0.y + d1.x * d1.y);
    float cc = d0.x * d0.x + d1.x * d1.x + 1.0;
    float inv_f = 1.0 / (a * cc - 0.25 * b * b);
    a *= inv_f;
    b *= inv_f;
    cc *= inv_f;
    // The ellipse's bounding box: half-widths sqrt(4 C / det) and sqrt(4 A / det).
    float det = 4.0 * a * cc - b * b;
    float hx = 2.0 * sqrt(max(det * cc, 0.0)) / det;
    float hy = 2.0 * sqrt(max(a * det, 0.0)) / det;
    int x0 = int(ceil(c.x - hx));
    int x1 = int(floor(c.x + hx));
    int y0 = int(ceil(c.y - hy));
    int y1 = int(floor(c.y + hy));
    bool repeat_u = t.flags.x == TEXTURE_WRAP_REPEAT || t.flags.x == TEXTURE_WRAP_REPEAT_U;
    bool repeat_v = t.flags.x == TEXTURE_WRAP_REPEAT;
    bool black = t.flags.x == TEXTURE_WRAP_BLACK;
    vec3 sum = vec3(0.0);
    float weights = 0.0;
    for (int y = y0; y <= y1; ++y) {
        float dy = float(y) - c.y;
        int ty = wrap_texel(float(y), h, repeat_v, black);
        for (int x = x0; x <= x1; ++x) {
            float dx = float(x) - c.x;
            float q = a * dx * dx + b * dx * dy + cc * dy * dy;
            if (q < 1.0) {
                float k = float(min(int(q * 128.0), 127)) / 127.0;
                float weight = exp(-2.0 * k) - exp(-2.0);
                sum += weight * texel(t, wrap_texel(float(x), w, repeat_u, black), ty);
                weights += weight;
            }
        }
    }
    return sum / weights;
}

// pbrt-v4's EWA footprint of image t (levels MIP levels): d0 made the longer axis and d1
// the shorter, stretched to at least 1/other.z of it (maxanisotropy); the level to read,
// lod = levels - 1 + log2 of the shorter's length (at least 0), or -1 where the shorter is
// zero (no footprint: bilinear at the base). CPU mirror: src/mipmap.rs ewa.
float image_ewa_lod(GpuTexture t, int levels, inout vec2 d0, inout vec2 d1) {
    if (dot(d0, d0) < dot(d1, d1)) {
        vec2 s = d0;
        d0 = d1;
        d1 = s;
    }
    float longer = length(d0);
    float shorter = length(d1);
    float most = t.other.z;
    if (shorter * most < longer && shorter > 0.0) {
        float k = longer / (shorter * most);
        d1 *= k;
        shorter *= k;
    }
    if (shorter == 0.0) return -1.0;
    return max(0.0, float(levels - 1) + log2(shorter));
}

// An image texture's texels at (s, t) where the footprint's (s, t) derivatives are dst0
// (along x) and dst1 (along y), read as other.x says (TEXTURE_FILTER_*); with MIP levels
// (other.y > 1, FEATURE_MIP_TEXTURES) at the level they pick, pbrt-v4's MIPMap::Filter:
// width = 2 max |d|, level = levels - 1 + log2(width); past the top level its one texel;
// else point or bilinear at floor(level) (0 below it), trilinear blending floor(level)
// and the next by level's fraction (bilinear at the base below level 1); EWA
// (MORE_FEATURE_EWA_TEXTURES) the ellipse at the two levels image_ewa_lod picks, a level
// past the top read as the top's one texel. The levels are walked to in one loop, each
// lookup at one call. A degenerate footprint (NaN, infinite, 2^60) reads as none. CPU mirror:
// src/mipmap.rs image_value.
vec3 image_value(GpuTexture t, vec2 st, vec2 dst0, vec2 dst1, uint tf) {
    if (t.flags.y == 0u) {
        st.y = 1.0 - st.y;
        // (The footprint turned with it: EWA's ellipse would be mirrored otherwise.)
        dst0.y = -dst0.y;
        dst1.y = -dst1.y;
    }
    // A footprint with a component NaN, infinite or of 2^60 or more (a degenerate
    // differential) is read as none: the level and the ellipse made from it would be
    // undefined. (Its exponent bits tested, which no float optimisation may fold.)
    uvec4 exponents = floatBitsToUint(vec4(dst0, dst1)) & 0x7f800000u;
    if (any(greaterThanEqual(exponents, uvec4((127u + 60u) << 23)))) {
        dst0 = vec2(0.0);
        dst1 = vec2(0.0);
    }
    bool point = t.other.x == float(TEXTURE_FILTER_POINT);
    bool ewa = false;
    int first = 0;
    int count = 1;
    float blend = 0.0;
    int levels = int(t.other.y);
    if (has_texture_feature(tf, FEATURE_MIP_TEXTURES) && levels > 1) {
        if (has_more_feature(MORE_FEATURE_EWA_TEXTURES) && t.other.x == float(TEXTURE_FILTER_EWA)) {
            float lod = image_ewa_lod(t, levels, dst0, dst1);
            if (lod >= 0.0) {
                ewa = true;
                first = int(floor(lod));
                blend = lod - float(first);
                count = 2;
                // (Past the top, both levels are the top's texel.)
                first = min(first, levels);
            }
        } else {
            float width = 2.0 * max(max(abs(dst0.x), abs(dst0.y)), max(abs(dst1.x), abs(dst1.y)));
            float level = float(levels - 1) + log2(max(width, 1e-8));
            if (level >= float(levels - 1)) {
                // The top level's one texel.
                first = levels - 1;
                point = true;
                st = vec2(0.5);
            } else {
                first = max(0, int(floor(level)));
                if (t.other.x == float(TEXTURE_FILTER_TRILINEAR) && first > 0) {
                    count = 2;
                    blend = level - float(first);
                }
            }
        }
    }
    vec3 v = vec3(0.0);
    for (int i = 0; i < first + count; ++i) {
        if (i >= first) {
            float weight = count == 1 ? 1.0 : i == first ? 1.0 - blend : blend;
            // (EWA's level past the top: the top's one texel. An image of no levels, as
            // an environment map's, has other.y zero.)
            v += weight * (ewa && i >= levels ? texel(t, 0, 0)
                           : ewa ? image_ewa_level(t, st, dst0, dst1) : image_lookup(t, st, point));
        }
        if (i < levels - 1) t = next_image_level(t);
    }
    return v;
}

// The footprint's (s, t) derivatives along x (d0) and y (d1) for texture t at (uv, p) whose
// (s, t) is st: uv's (duv) scaled by the mapping; a plane's rows applied to dp/dx and
// dp/dy; for the spherical and cylindrical mappings the difference of (s, t) one footprint
// step away, the periodic coordinate the short way round. CPU mirror: src/texture.rs
// st_footprint.
void texture_st_footprint(GpuTexture t, vec2 uv, vec3 p, vec2 st, vec3 dpdx, vec3 dpdy, vec4 duv,
                          uint tf, out vec2 d0, out vec2 d1) {
    d0 = t.mapping.xy * duv.xy;
    d1 = t.mapping.xy * duv.zw;
    if (!has_texture_feature(tf, FEATURE_TEXTURE_PROJECTIONS) || t.flags.z == TEXTURE_MAP_UV) return;
    if (t.flags.z == TEXTURE_MAP_PLANAR) {
        d0 = vec2(dot(t.proj0.xyz, dpdx), dot(t.proj1.xyz, dpdx));
        d1 = vec2(dot(t.proj0.xyz, dpdy), dot(t.proj1.xyz, dpdy));
        return;
    }
    d0 = texture_st(t, uv, p + dpdx, tf) - st;
    d1 = texture_st(t, uv, p + dpdy, tf) - st;
    if (t.flags.z == TEXTURE_MAP_SPHERICAL) {
        d0.y -= floor(d0.y + 0.5);
        d1.y -= floor(d1.y + 0.5);
    } else {
        d0.x -= floor(d0.x + 0.5);
        d1.x -= floor(d1.x + 0.5);
    }
}

// The value of a texture not made of textures (an image, a checkerboard, a procedural
// texture) at the surface coordinates uv and world point p, whose pixel footprint is
// (dpdx, dpdy) (surface_footprint; zero: none) and in (u, v) duv (du/dx, dv/dx, du/dy,
// dv/dy: uv_footprint), with the code of the texture features tf (the environment map, an
// image, looks up through it without the procedural textures').
vec3 texture_leaf(GpuTexture t, vec2 uv, vec3 p, vec3 dpdx, vec3 dpdy, vec4 duv, uint tf) {
    bool noise = t.info.x == TEXTURE_NOISE;
    vec2 st = noise ? vec2(0.0) : texture_st(t, uv, p, tf);
    if (has_texture_feature(tf, FEATURE_PROCEDURAL_TEXTURES) && (noise || t.info.x == TEXTURE_DOTS)) {
        vec4 h = vec4(p, 1.0);
        vec3 q = vec3(dot(t.proj0, h), dot(t.proj1, h), dot(t.proj2, h));
        // The footprint in the texture's space (pbrt-v4's TextureMapping3D maps dp/dx too).
        vec3 qx = vec3(dot(t.proj0.xyz, dpdx), dot(t.proj1.xyz, dpdx), dot(t.proj2.xyz, dpdx));
        vec3 qy = vec3(dot(t.proj0.xyz, dpdy), dot(t.proj1.xyz, dpdy), dot(t.proj2.xyz, dpdy));
        return procedural_value(t, q, st, max(dot(qx, qx), dot(qy, qy)));
    }
    if (has_texture_feature(tf, FEATURE_BILERP_TEXTURES) && t.info.x == TEXTURE_BILERP) {
        uint i = t.info.y;
        vec3 v00 = vec3(texel(i), texel(i + 1u), texel(i + 2u));
        vec3 v01 = vec3(texel(i + 3u), texel(i + 4u), texel(i + 5u));
        vec3 v10 = vec3(texel(i + 6u), texel(i + 7u), texel(i + 8u));
        vec3 v11 = vec3(texel(i + 9u), texel(i + 10u), texel(i + 11u));
        return (1.0 - st.x) * (1.0 - st.y) * v00 + (1.0 - st.x) * st.y * v01
             + st.x * (1.0 - st.y) * v10 + st.x * st.y * v11;
    }
    if (t.info.x == TEXTURE_CHECKERBOARD) {
        float sum = floor(st.x) + floor(st.y);
        if (has_texture_feature(tf, FEATURE_TEXTURE_PROJECTIONS) && t.flags.z == TEXTURE_MAP_SOLID) {
            sum += floor(dot(t.proj2, vec4(p, 1.0)));
        }
        float parity = mod(sum, 2.0);
        return parity == 0.0 ? t.scale.xyz : t.other.xyz;
    }
    vec2 dst0 = vec2(0.0);
    vec2 dst1 = vec2(0.0);
    if (has_texture_feature(tf, FEATURE_MIP_TEXTURES) && t.other.y > 1.0) {
        texture_st_footprint(t, uv, p, st, dpdx, dpdy, duv, tf, dst0, dst1);
    }
    return t.scale.xyz * image_value(t, st, dst0, dst1, tf);
}

// The value of texture `index` at the surface coordinates uv and world point p, where the
// surface's unit geometric normal is ng (read by a direction mix alone; either side) and
// the pixel footprint (dpdx, dpdy) (zero: none; the procedural textures read it).
// A texture made of textures runs its program (abi.h TEXTURE_GRAPH): its records in
// order, each into a register, leaves looked up here at one call site. tf: the texture
// features compiled in (has_texture_feature).
vec3 texture_value(uint index, vec2 uv, vec3 p, vec3 ng, vec3 dpdx, vec3 dpdy, vec4 duv, uint tf) {
    if (!has_texture_feature(tf, FEATURE_TEXTURE_GRAPHS)) return texture_leaf(textures[index], uv, p, dpdx, dpdy, duv, tf);
    GpuTexture t = textures[index];
    uint first = index, count = 1u;
    if (t.info.x == TEXTURE_GRAPH) {
        first = t.info.y;
        count = min(t.info.z, uint(MAX_TEXTURE_PROGRAM));
    }
    vec3 regs[MAX_TEXTURE_PROGRAM];
    vec3 v = vec3(0.0);
    for (uint i = 0u; i < count; ++i) {
        GpuTexture n = textures[first + i];
        if (n.info.x == TEXTURE_SCALE || n.info.x == TEXTURE_MIX || n.info.x == TEXTURE_DIRECTION_MIX) {
            vec3 a = n.flags.x == NO_TEXTURE ? n.scale.xyz : regs[n.flags.x];
            vec3 b = n.flags.y == NO_TEXTURE ? n.other.xyz : regs[n.flags.y];
            // (A direction mix is a mix whose amount, tex2's weight, is 1 - |ng . dir|.)
            float amount = n.info.x == TEXTURE_DIRECTION_MIX ? 1.0 - abs(dot(ng, n.mapping.xyz))
                         : n.flags.z == NO_TEXTURE ? n.mapping.x : regs[n.flags.z].x;
            v = n.info.x == TEXTURE_SCALE ? a * b.x : (1.0 - amount) * a + amount * b;
        } else {
            v = texture_leaf(n, uv, p, dpdx, dpdy, duv, tf);
        }
        regs[i] = v;
    }
    return v;
}

// The texture features of the scene's alpha textures (abi.h's FEATURE_ALPHA_*): the
// alpha test, inlined in every traversal, holds only their code.
uint alpha_texture_features() {
    return (has_feature(FEATURE_ALPHA_TEXTURE_PROJECTIONS) ? FEATURE_TEXTURE_PROJECTIONS : 0u)
         | (has_feature(FEATURE_ALPHA_TEXTURE_GRAPHS) ? FEATURE_TEXTURE_GRAPHS : 0u)
         | (has_feature(FEATURE_ALPHA_PROCEDURAL_TEXTURES) ? FEATURE_PROCEDURAL_TEXTURES : 0u)
         | (has_feature(FEATURE_ALPHA_BILERP_TEXTURES) ? FEATURE_BILERP_TEXTURES : 0u);
}

// The texture of slot `slot` (< MATERIAL_TEXTURE_SLOTS) of material m, or NO_TEXTURE: 0 the
// diffuse reflectance (a conductor's or a coated conductor's: its reflectance), 1 the
// roughness (first channel; diffuse transmission: the transmittance), 2 a coated
// conductor's conductor roughness, 3 a coated layer's thickness. Surfaces look them up
// (geometry.glsl's resolve_material_and_map), material_bsdf reads the values.
uint material_texture(GpuMaterial m, uint slot) {
    uint kind = m.info.x;
    bool coated = has_feature(FEATURE_COATED) && (kind == BSDF_COATED_DIFFUSE || kind == BSDF_COATED_CONDUCTOR);
    return slot == 0u ? m.info.z
         : slot == 1u ? m.info.w
         : slot == 2u ? (has_feature(FEATURE_COATED_CONDUCTOR) && kind == BSDF_COATED_CONDUCTOR ? floatBitsToUint(m.base.z) : NO_TEXTURE)
         : (coated ? floatBitsToUint(m.base.w) : NO_TEXTURE);
}
#endif
