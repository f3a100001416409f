// Visibility by stack traversal of the CPU-built binary SAH BVH (`--accel bvh2`; CPU
// mirror: src/accel/bvh.rs).
// Node: two vec4: (min, left_or_first bits), (max, count bits); count 0 = internal
// node whose first child follows it and whose second child is left_or_first.
struct BvhNode { vec4 min_left; vec4 max_count; };

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer BvhNodeChunk { BvhNode at[]; };
layout(std430, set = 0, binding = BINDING_BVH_NODES) readonly buffer BvhNodeBuffer { BvhNode bvh_nodes[]; };
BvhNode bvh_node(uint i) {
    if (data_kinds[DATA_BVH_NODES].z == DATA_IN_BINDING) return bvh_nodes[i];
    uint j;
    uvec2 a = data_chunk(DATA_BVH_NODES, i, j);
    return BvhNodeChunk(a).at[j];
}
#include "trace_bvh_common.glsl"

#define BVH_STACK_SIZE 64
// Stack entries past the nodes' (FEATURE_INSTANCES): an instance waiting to be walked
// (BVH_INSTANCE_ENTRY + its index), and the end of the instance being walked.
#define BVH_INSTANCE_ENTRY 0x80000000u
#define BVH_INSTANCE_EXIT 0xffffffffu

// Entry distance of the ray into a node's box, or INF when it misses within [0, tmax].
float bvh_box_entry(BvhNode node, vec3 o, vec3 inv_d, float tmax) {
    vec3 t0 = (node.min_left.xyz - o) * inv_d;
    vec3 t1 = (node.max_count.xyz - o) * inv_d;
    vec3 tnear = min(t0, t1);
    vec3 tfar = max(t0, t1);
    float enter = max(max(tnear.x, tnear.y), max(tnear.z, 0.0));
    float leave = min(min(min(tfar.x, tfar.y), tfar.z) * BVH_SLAB_EXIT_SCALE, tmax);
    return enter <= leave ? enter : INF;
}

bool bvh_traverse(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit) {
    vec3 inv_d = bvh_safe_inverse(d);
    uint stack[BVH_STACK_SIZE];
    uint sp = 0u;
    uint node_index = 0u;
    float closest = tmax;
    bool found = false;
    hit.t = 0.0;
    hit.prim = 0u;
    hit.bary = vec2(0.0);
    // The instance being walked, the world ray to go back to, the hits' id shift.
    uint inst = NO_INSTANCE;
    vec3 world_o = o;
    vec3 world_d = d;
    uint id_shift = 0u;
    BvhNode root = bvh_node(0);
    // An empty scene is one empty leaf with an inverted box.
    if (root.min_left.x > root.max_count.x) return false;
    if (bvh_box_entry(root, o, inv_d, closest) == INF) return false;
    while (true) {
        BvhNode node = bvh_node(node_index);
        uint count = floatBitsToUint(node.max_count.w);
        uint first = floatBitsToUint(node.min_left.w);
        if (count > 0u) {
            for (uint i = 0u; i < count; ++i) {
                uint prim = bvh_prim(first + i);
                if (bvh_is_instance(prim, inst)) {
                    if (sp < BVH_STACK_SIZE) stack[sp++] = BVH_INSTANCE_ENTRY + (prim - scene.flat_triangle_count);
                    continue;
                }
                if (bvh_visit_prim(prim, o, d, closest, hit)) {
                    hit.prim += id_shift;
                    found = true;
                    if (any_hit) return true;
                }
            }
        } else {
            uint a = node_index + 1u;
            uint b = first;
            float ta = bvh_box_entry(bvh_node(a), o, inv_d, closest);
            float tb = bvh_box_entry(bvh_node(b), o, inv_d, closest);
            if (ta > tb) { float tt = ta; ta = tb; tb = tt; uint x = a; a = b; b = x; }
            if (ta != INF) {
                if (tb != INF && sp < BVH_STACK_SIZE) stack[sp++] = b;
                node_index = a;
                continue;
            }
        }
        // Pop the next node still worth visiting.
        bool next = false;
        while (sp > 0u) {
            uint candidate = stack[--sp];
            if (has_feature(FEATURE_INSTANCES) && candidate >= BVH_INSTANCE_ENTRY) {
                o = world_o;
                d = world_d;
                inst = NO_INSTANCE;
                id_shift = 0u;
                if (candidate != BVH_INSTANCE_EXIT) {
                    // (The exit takes the entry's place on the stack.)
                    inst = candidate - BVH_INSTANCE_ENTRY;
                    stack[sp++] = BVH_INSTANCE_EXIT;
                    bvh_ray_to_object(inst, o, d);
                    id_shift = instances[inst].info.y;
                    candidate = instances[inst].info.z;
                }
                inv_d = bvh_safe_inverse(d);
                if (inst == NO_INSTANCE) continue;
            }
            if (bvh_box_entry(bvh_node(candidate), o, inv_d, closest) != INF) {
                node_index = candidate;
                next = true;
                break;
            }
        }
        if (!next) break;
    }
    return found;
}
