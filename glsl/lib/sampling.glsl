// Warping of uniform samples to directions and points, plus the MIS weight.
// Mirrored on the CPU by `bsdf::sampling` in src/bsdf.rs; keep the two in sync.
#ifndef SAMPLING_GLSL
#define SAMPLING_GLSL

const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;
const float TWO_PI = 6.28318530717958647693;
const float INV_TWO_PI = 0.15915494309189533577;

// Right-handed orthonormal basis (t, b, n) around the unit vector n:
// Duff et al. 2017, "Building an Orthonormal Basis, Revisited", JCGT 6(1), listing 3.
// The sign is a select, not a branch; n.z == -0.0 counts as positive (GLSL has no copysign).
void build_onb(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// A direction given in the local frame (z along n) expressed in world space.
vec3 to_world(vec3 v, vec3 n) {
    vec3 t;
    vec3 b;
    build_onb(n, t, b);
    return v.x * t + v.y * b + v.z * n;
}

// PCG's RXS-M-XS output permutation of one step: a 32-bit hash (Jarzynski and Olano
// 2020). The coated diffuse walk seeds its numbers with it, the mix material its choice.
uint hash_pcg(uint x) {
    uint state = x * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Cosine-weighted hemisphere (z up), pdf cos(theta) / pi: Malley's method with the
// polar disk map. z > 0 for u in [0, 1)^2.
vec3 sample_cosine_hemisphere(vec2 u) {
    float r = sqrt(u.x);
    float phi = TWO_PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
}

// Uniform unit disk by Shirley and Chiu's concentric map (square rings to disk rings, so
// nearby numbers stay nearby: the thin lens's points for MMLT's small steps).
vec2 sample_uniform_disk_concentric(vec2 u) {
    vec2 o = 2.0 * u - 1.0;
    if (o.x == 0.0 && o.y == 0.0) return vec2(0.0);
    float r, theta;
    if (abs(o.x) > abs(o.y)) {
        r = o.x;
        theta = 0.25 * PI * (o.y / o.x);
    } else {
        r = o.y;
        theta = 0.5 * PI - 0.25 * PI * (o.x / o.y);
    }
    return r * vec2(cos(theta), sin(theta));
}

// Uniform hemisphere (z up), pdf 1 / (2 pi). z = 1 - u.x lies in (0, 1] for u.x in [0, 1).
vec3 sample_uniform_hemisphere(vec2 u) {
    float z = 1.0 - u.x;
    float r = sqrt(max(1.0 - z * z, 0.0));
    float phi = TWO_PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), z);
}

// Uniform unit sphere, pdf 1 / (4 pi).
vec3 sample_uniform_sphere(vec2 u) {
    float z = 1.0 - 2.0 * u.x;
    float r = sqrt(max(1.0 - z * z, 0.0));
    float phi = TWO_PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), z);
}

// Uniform barycentrics (b0, b1) of a triangle, the third being 1 - b0 - b1:
// the square-root parametrisation (pbrt 3rd ed., section 13.6.5).
vec2 sample_uniform_triangle(vec2 u) {
    float su = sqrt(u.x);
    return vec2(1.0 - su, u.y * su);
}

// Uniform over the cone of directions within acos(cos_max) of +z, pdf
// 1 / (2 pi (1 - cos_max)).
vec3 sample_uniform_cone(vec2 u, float cos_max) {
    float cos_t = (1.0 - u.x) + u.x * cos_max;
    float sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    float phi = TWO_PI * u.y;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// Veach's power heuristic (beta = 2): the MIS weight of the strategy with pdf a against
// one with pdf b, a^2 / (a^2 + b^2) written as 1 / (1 + (b/a)^2) so that no square
// overflows. a == 0 (or NaN) gives 0; an infinite a (a delta strategy) gives 1, or 1/2
// against another infinite b; an infinite b gives 0; b <= 0 (or NaN) gives 1.
float power_heuristic(float a, float b) {
    if (!(a > 0.0)) return 0.0;
    if (isinf(a)) return isinf(b) ? 0.5 : 1.0;
    if (!(b > 0.0)) return 1.0;
    float r = b / a;
    return 1.0 / (1.0 + r * r);
}

// The Henyey-Greenstein phase function between wo and wi, both pointing away from the
// scattering point (pbrt-v4's convention: for g > 0 light goes on forwards, wi near
// -wo); it is also the density of hg_sample. Used by coated layers (layered.glsl) and media
// (media.glsl). CPU mirror: bsdf/coated.rs `hg`.
float hg_phase(vec3 wo, vec3 wi, float g) {
    g = clamp(g, -0.99, 0.99);   // (at +-1 the function is a delta, as pbrt-v4 avoids)
    float d = 1.0 + g * g + 2.0 * g * dot(wo, wi);
    return (1.0 - g * g) / (4.0 * PI * d * sqrt(max(d, 0.0)));
}

// A direction from the phase function around wo: the cosine by inverting the
// distribution's CDF, the azimuth uniform.
vec3 hg_sample(vec3 wo, float g, vec2 u) {
    g = clamp(g, -0.99, 0.99);
    float c;
    if (abs(g) < 1e-3) {
        c = 1.0 - 2.0 * u.x;
    } else {
        float q = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
        c = -(1.0 + g * g - q * q) / (2.0 * g);
    }
    float sn = sqrt(max(1.0 - c * c, 0.0));
    float phi = 2.0 * PI * u.y;
    return to_world(vec3(sn * cos(phi), sn * sin(phi), c), wo);
}

#endif
