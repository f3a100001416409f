// Visibility by traversal of the compressed 8-wide BVH (Ylitie, Karras & Laine 2017;
// `--accel cwbvh`; CPU mirror, line for line: src/accel/cwbvh.rs).
//
// Node (80 bytes, five uvec4):
//   a: p.xyz (float bits), bytes of w: scale exponents e.x, e.y, e.z, internal-child mask
//   b: first child node, first primitive reference, meta bytes of slots 0-3, 4-7
//   c, d, e: x, y, z planes: min of slots 0-3, 4-7, max of slots 0-3, 4-7 (a byte each)
// Plane q of an axis lies at p + q 2^(e-127); the builder makes every such plane, in real
// arithmetic, contain the children, and the box test below bounds its own rounding.
struct CwbvhNode { uvec4 a; uvec4 b; uvec4 c; uvec4 d; uvec4 e; };

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer CwbvhNodeChunk { CwbvhNode at[]; };
layout(std430, set = 0, binding = BINDING_BVH_NODES) readonly buffer BvhNodeBuffer { CwbvhNode bvh_nodes[]; };
CwbvhNode bvh_node(uint i) {
    if (data_kinds[DATA_BVH_NODES].z == DATA_IN_BINDING) return bvh_nodes[i];
    uint j;
    uvec2 a = data_chunk(DATA_BVH_NODES, i, j);
    return CwbvhNodeChunk(a).at[j];
}
#include "trace_bvh_common.glsl"

// Mirror of src/accel/cwbvh.rs STACK_SIZE (the builder caps the depth to it).
#define CWBVH_STACK_SIZE 32

// Mirror of src/accel/cwbvh.rs TRANSFORMED_RAY_SLACK: 5 eps.
const float CWBVH_SLACK = 5.0 * 5.9604645e-8;

// The children's hit mask: internal children set bit 24 + (slot ^ octant), leaves one
// bit per primitive at its offset from the node's first primitive reference.
// The transformed ray: plane q of an axis is met at t = q (2^e / d) + (p - o) / d, one
// fma per plane, near and far planes picked once per node by the sign of d; (p - o) / d
// is lowered (near) and raised (far) by CWBVH_SLACK of itself, which bounds its
// rounding, and the exit scale covers the rest (proof: src/accel/cwbvh.rs).
uint cwbvh_intersect_node(CwbvhNode node, vec3 o, vec3 inv_d, bvec3 neg, uint oct_inv4, float tmax) {
    vec3 p = uintBitsToFloat(node.a.xyz);
    uint ew = node.a.w;
    vec3 e = vec3(uintBitsToFloat((ew & 0xffu) << 23), uintBitsToFloat(((ew >> 8) & 0xffu) << 23),
                  uintBitsToFloat(((ew >> 16) & 0xffu) << 23));
    vec3 E = e * inv_d;
    vec3 P = (p - o) * inv_d;
    vec3 S = abs(P) * CWBVH_SLACK;
    vec3 p_near = P - S;
    vec3 p_far = P + S;
    uint hitmask = 0u;
    for (uint half_ = 0u; half_ < 2u; ++half_) {
        uint meta4 = half_ == 0u ? node.b.z : node.b.w;
        uint is_inner4 = (meta4 & (meta4 << 1)) & 0x10101010u;
        uint inner_mask4 = (is_inner4 >> 4) * 0xffu;
        uint bit_index4 = (meta4 ^ (oct_inv4 & inner_mask4)) & 0x1f1f1f1fu;
        uint child_bits4 = (meta4 >> 5) & 0x07070707u;
        uvec3 lo4 = half_ == 0u ? uvec3(node.c.x, node.d.x, node.e.x) : uvec3(node.c.y, node.d.y, node.e.y);
        uvec3 hi4 = half_ == 0u ? uvec3(node.c.z, node.d.z, node.e.z) : uvec3(node.c.w, node.d.w, node.e.w);
        uvec3 near4 = mix(lo4, hi4, neg);
        uvec3 far4 = mix(hi4, lo4, neg);
        for (uint j = 0u; j < 4u; ++j) {
            uint shift = 8u * j;
            vec3 tnear = fma(vec3((near4 >> shift) & 0xffu), E, p_near);
            vec3 tfar = fma(vec3((far4 >> shift) & 0xffu), E, p_far);
            float enter = max(max(tnear.x, tnear.y), max(tnear.z, 0.0));
            float leave = min(min(min(tfar.x, tfar.y), tfar.z) * BVH_SLAB_EXIT_SCALE, tmax);
            if (enter <= leave) {
                uint bits = (child_bits4 >> shift) & 7u;
                uint index = (bit_index4 >> shift) & 31u;
                hitmask |= bits << index;
            }
        }
    }
    return hitmask;
}

bool bvh_traverse(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit) {
    vec3 inv_d = bvh_safe_inverse(d);
    bvec3 neg = lessThan(inv_d, vec3(0.0));
    uint oct_inv4 = (d.x < 0.0 ? 0u : 0x04040404u) | (d.y < 0.0 ? 0u : 0x02020202u) |
                    (d.z < 0.0 ? 0u : 0x01010101u);
    uvec2 stack[CWBVH_STACK_SIZE];
    uint sp = 0u;
    // The root, as the one internal child of a virtual node (bit 31: slot 7 ^ 7).
    uvec2 node_group = uvec2(0u, 0x80000000u);
    uvec2 prim_group = uvec2(0u);
    float closest = tmax;
    bool found = false;
    hit.t = 0.0;
    hit.prim = 0u;
    hit.bary = vec2(0.0);
    // The instance being walked, the world ray to go back to, the hits' id shift. On
    // entering an instance the rest of the leaf and of the node wait on the stack under
    // the instance's end (an entry whose y is 0; a leaf's rest has only y's low 24 bits,
    // a node group some of its top 8).
    uint inst = NO_INSTANCE;
    vec3 world_o = o;
    vec3 world_d = d;
    uint id_shift = 0u;
    while (true) {
        while (prim_group.y != 0u) {
            uint bit = uint(findMSB(prim_group.y));
            prim_group.y &= ~(1u << bit);
            uint prim = bvh_prim(prim_group.x + bit);
            if (bvh_is_instance(prim, inst)) {
                // (The host checks that the two trees' depths fit the stack.)
                if (sp + 3u > CWBVH_STACK_SIZE) continue;
                if (prim_group.y != 0u) stack[sp++] = prim_group;
                if ((node_group.y & 0xff000000u) != 0u) stack[sp++] = node_group;
                stack[sp++] = uvec2(0u);
                inst = prim - scene.flat_triangle_count;
                bvh_ray_to_object(inst, o, d);
                inv_d = bvh_safe_inverse(d);
                neg = lessThan(inv_d, vec3(0.0));
                oct_inv4 = (d.x < 0.0 ? 0u : 0x04040404u) | (d.y < 0.0 ? 0u : 0x02020202u) |
                           (d.z < 0.0 ? 0u : 0x01010101u);
                id_shift = instances[inst].info.y;
                node_group = uvec2(instances[inst].info.z, 0x80000000u);
                prim_group = uvec2(0u);
                break;
            }
            if (bvh_visit_prim(prim, o, d, closest, hit)) {
                hit.prim += id_shift;
                found = true;
                if (any_hit) return true;
            }
        }
        if ((node_group.y & 0xff000000u) != 0u) {
            uint hits = node_group.y;
            uint bit = uint(findMSB(hits));
            node_group.y &= ~(1u << bit);
            if ((node_group.y & 0xff000000u) != 0u && sp < CWBVH_STACK_SIZE) stack[sp++] = node_group;
            uint slot = (bit - 24u) ^ (oct_inv4 & 0xffu);
            uint relative = bitCount(hits & ~(0xffffffffu << slot));
            CwbvhNode node = bvh_node(node_group.x + relative);
            uint hitmask = cwbvh_intersect_node(node, o, inv_d, neg, oct_inv4, closest);
            node_group = uvec2(node.b.x, (hitmask & 0xff000000u) | (node.a.w >> 24));
            prim_group = uvec2(node.b.y, hitmask & 0x00ffffffu);
        }
        if (prim_group.y == 0u && (node_group.y & 0xff000000u) == 0u) {
            if (sp == 0u) break;
            uvec2 g = stack[--sp];
            if (has_feature(FEATURE_INSTANCES) && (g.y & 0xff000000u) == 0u) {
                if (g.y == 0u) {
                    // The instance's end: the world ray again.
                    o = world_o;
                    d = world_d;
                    inv_d = bvh_safe_inverse(d);
                    neg = lessThan(inv_d, vec3(0.0));
                    oct_inv4 = (d.x < 0.0 ? 0u : 0x04040404u) | (d.y < 0.0 ? 0u : 0x02020202u) |
                               (d.z < 0.0 ? 0u : 0x01010101u);
                    inst = NO_INSTANCE;
                    id_shift = 0u;
                    node_group.y = 0u;
                } else {
                    prim_group = g;
                }
            } else {
                node_group = g;
            }
        }
    }
    return found;
}
