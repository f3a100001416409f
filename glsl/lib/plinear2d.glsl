// The piecewise-bilinear 2D distribution conditioned on up to three parameters (the
// measured material's tables), read from the texel buffer as src/plinear2d.rs packs it
// (PiecewiseLinear2D::pack); that file is its CPU mirror, line for line, and its
// documentation. A table is named by `base` (the texel index its offsets count from) and
// `header` (its header's index relative to base).
#ifndef PLINEAR2D_GLSL
#define PLINEAR2D_GLSL
#extension GL_EXT_control_flow_attributes : require
#include "bindings.glsl"

uint plin_word(uint i) { return floatBitsToUint(texel(i)); }

struct Plinear {
    uint base;
    uvec2 size;      // W, H
    uint n;          // parameters
    uvec3 res;       // their value counts
    uvec3 stride;    // their strides in slices
    uint params;     // absolute texel indices
    uint data;
    uint marginal;
    uint conditional;
};

Plinear plinear_at(uint base, uint header) {
    uint h = base + header;
    Plinear t;
    t.base = base;
    t.size = uvec2(plin_word(h), plin_word(h + 1u));
    t.n = plin_word(h + 2u);
    t.res = uvec3(plin_word(h + 3u), plin_word(h + 4u), plin_word(h + 5u));
    t.stride = uvec3(plin_word(h + 6u), plin_word(h + 7u), plin_word(h + 8u));
    t.params = base + plin_word(h + 9u);
    t.data = base + plin_word(h + 10u);
    t.marginal = base + plin_word(h + 11u);
    t.conditional = base + plin_word(h + 12u);
    return t;
}

// The slices to blend at the parameter values p: the first slice and each parameter's
// weight of its upper neighbour (0 for a parameter of one value).
void plinear_slices(Plinear t, vec3 p, out uint first, out vec3 w1) {
    first = 0u;
    w1 = vec3(0.0);
    uint values = t.params;
    [[dont_unroll]] for (uint d = 0u; d < t.n; ++d) {
        uint res = t.res[d];
        if (res > 1u) {
            // The largest i in [0, res - 2] with value_i <= p (bisection).
            uint lo = 1u, len = res - 2u;
            [[dont_unroll]] while (len > 0u) {
                uint half_ = len / 2u;
                uint middle = lo + half_;
                if (texel(values + middle) <= p[d]) {
                    lo = middle + 1u;
                    len -= half_ + 1u;
                } else {
                    len = half_;
                }
            }
            uint i = min(lo - 1u, res - 2u);
            float v0 = texel(values + i), v1 = texel(values + i + 1u);
            w1[d] = clamp((p[d] - v0) / (v1 - v0), 0.0, 1.0);
            first += i * t.stride[d];
        }
        values += res;
    }
}

// The blend of element `offset` of each slice (of `len` elements) of the array at `array`.
float plinear_lookup(Plinear t, uint array, uint len, uint offset, uint first, vec3 w1) {
    float sum = 0.0;
    [[dont_unroll]] for (uint c = 0u; c < (1u << t.n); ++c) {
        float w = 1.0;
        uint slice = first;
        for (uint d = 0u; d < 3u; ++d) {
            if (d >= t.n) break;
            bool up = ((c >> d) & 1u) != 0u;
            w *= up ? w1[d] : 1.0 - w1[d];
            slice += up ? t.stride[d] : 0u;
        }
        if (w > 0.0) sum += w * texel(array + slice * len + offset);
    }
    return sum;
}

// Solves the integral of the linear density from a to b over [0, t] = u for t.
float plinear_solve(float a, float b, float u) {
    if (abs(a - b) <= 1e-4 * (a + b)) return a + b > 0.0 ? 2.0 * u / (a + b) : 0.0;
    return (a - sqrt(max(a * a - 2.0 * u * (a - b), 0.0))) / (a - b);
}

// pos's patch (column, row) and its place in it.
void plinear_patch(Plinear t, vec2 pos, out uvec2 cell, out vec2 f) {
    vec2 x = clamp(pos, vec2(0.0), vec2(1.0)) * vec2(t.size - 1u);
    cell = min(uvec2(floor(x)), t.size - 2u);
    f = x - vec2(cell);
}

float plinear_area_inv(Plinear t) { return float((t.size.x - 1u) * (t.size.y - 1u)); }

// The four data values of the patch at node i (i, i + 1, i + W, i + W + 1).
vec4 plinear_corners(Plinear t, uint i, uint first, vec3 w1) {
    uint n = t.size.x * t.size.y;
    vec4 v;
    [[dont_unroll]] for (uint k = 0u; k < 4u; ++k) {
        v[k] = plinear_lookup(t, t.data, n, i + (k & 1u) + (k >> 1u) * t.size.x, first, w1);
    }
    return v;
}

// The density at pos for parameters p (a table kept as it is: its value).
float plinear_eval(Plinear t, vec2 pos, vec3 p) {
    uint first;
    vec3 w1;
    plinear_slices(t, p, first, w1);
    uvec2 cell;
    vec2 f;
    plinear_patch(t, pos, cell, f);
    vec4 v = plinear_corners(t, cell.y * t.size.x + cell.x, first, w1);
    return ((1.0 - f.x) * (1.0 - f.y) * v.x + f.x * (1.0 - f.y) * v.y + (1.0 - f.x) * f.y * v.z
            + f.x * f.y * v.w) * plinear_area_inv(t);
}

// (1 - ty) times the blend of element o0 of `array` plus ty times that of element o1
// (one lookup site for both).
float plinear_blend(Plinear t, uint array, uint len, uint o0, uint o1, float ty, uint first, vec3 w1) {
    vec2 x;
    [[dont_unroll]] for (uint k = 0u; k < 2u; ++k) x[k] = plinear_lookup(t, array, len, k == 0u ? o0 : o1, first, w1);
    return (1.0 - ty) * x.x + ty * x.y;
}

// A point drawn with the density from the uniform numbers u; its density in pdf. (Its
// two searches, the row on the marginal integrals and then the column on the rows'
// running integrals blended at ty, are one bisection loop, which ends by evaluating the
// integral at the index it found: each lookup has one call site.)
vec2 plinear_sample(Plinear t, vec2 u, vec3 p, out float pdf) {
    uint first;
    vec3 w1;
    plinear_slices(t, p, first, w1);
    uint w = t.size.x, h = t.size.y, n = w * h;
    u = clamp(u, vec2(1e-7), vec2(1.0 - 1e-7));
    uint row = 0u, col = 0u;
    float ty = 0.0;
    [[dont_unroll]] for (uint pass = 0u; pass < 2u; ++pass) {
        bool rows = pass == 0u;
        uint count = rows ? h : w;
        float target = rows ? u.y : u.x;
        // The largest k in [0, count - 2] whose running integral is below the target.
        uint lo = 1u, len = count - 2u, k;
        float c;
        [[dont_unroll]] for (;;) {
            bool last = len == 0u;
            k = last ? min(lo - 1u, count - 2u) : lo + len / 2u;
            c = plinear_blend(t, rows ? t.marginal : t.conditional, rows ? h : n, rows ? k : row * w + k,
                              rows ? k : (row + 1u) * w + k, rows ? 0.0 : ty, first, w1);
            if (last) break;
            if (c < target) {
                lo = k + 1u;
                len -= len / 2u + 1u;
            } else {
                len = len / 2u;
            }
        }
        if (rows) {
            row = k;
            u.y -= c;
            vec2 r;
            [[dont_unroll]] for (uint j = 0u; j < 2u; ++j) {
                r[j] = plinear_lookup(t, t.conditional, n, (row + j) * w + w - 1u, first, w1);
            }
            ty = clamp(plinear_solve(r.x, r.y, u.y), 0.0, 1.0);
            u.x *= (1.0 - ty) * r.x + ty * r.y;
        } else {
            col = k;
            u.x -= c;
        }
    }
    vec4 v = plinear_corners(t, row * w + col, first, w1);
    float c0 = (1.0 - ty) * v.x + ty * v.z;
    float c1 = (1.0 - ty) * v.y + ty * v.w;
    float s = clamp(plinear_solve(c0, c1, u.x), 0.0, 1.0);
    pdf = ((1.0 - s) * c0 + s * c1) * plinear_area_inv(t);
    return vec2((float(col) + s) / float(w - 1u), (float(row) + ty) / float(h - 1u));
}

// The uniform numbers that plinear_sample maps to pos; the density there in pdf. (Its
// nine lookups, the patch's corners, the rows' totals and running integrals and the
// marginal, in one loop.)
vec2 plinear_invert(Plinear t, vec2 pos, vec3 p, out float pdf) {
    uint first;
    vec3 w1;
    plinear_slices(t, p, first, w1);
    uint w = t.size.x, h = t.size.y, n = w * h;
    uvec2 cell;
    vec2 f;
    plinear_patch(t, pos, cell, f);
    uint i = cell.y * w + cell.x;
    vec4 v, q;
    float marginal = 0.0;
    [[dont_unroll]] for (uint k = 0u; k < 9u; ++k) {
        uint array = k < 4u ? t.data : k < 8u ? t.conditional : t.marginal;
        uint offset = k < 4u ? i + (k & 1u) + (k >> 1u) * w
                    : k < 6u ? (cell.y + k - 4u) * w + w - 1u
                    : k < 8u ? i + (k - 6u) * w
                    : cell.y;
        float x = plinear_lookup(t, array, k < 8u ? n : h, offset, first, w1);
        if (k < 4u) {
            v[k] = x;
        } else if (k < 8u) {
            q[k - 4u] = x;
        } else {
            marginal = x;
        }
    }
    float c0 = (1.0 - f.y) * v.x + f.y * v.z;
    float c1 = (1.0 - f.y) * v.y + f.y * v.w;
    float r0 = q.x, r1 = q.y;
    float before = (1.0 - f.y) * q.z + f.y * q.w;
    float row_total = (1.0 - f.y) * r0 + f.y * r1;
    float ux = row_total > 0.0 ? (f.x * (c0 + 0.5 * f.x * (c1 - c0)) + before) / row_total : 0.0;
    float uy = f.y * (r0 + 0.5 * f.y * (r1 - r0)) + marginal;
    pdf = ((1.0 - f.x) * c0 + f.x * c1) * plinear_area_inv(t);
    return vec2(ux, uy);
}
#endif
