// Visibility by stack traversal of the CPU-built SAH BVH (CPU mirror: src/accel/bvh.rs).
// Node: two vec4: (min, left_or_first bits), (max, count bits); count 0 = internal
// node whose first child follows it and whose second child is left_or_first.
struct BvhNode { vec4 min_left; vec4 max_count; };

layout(std430, set = 0, binding = BINDING_BVH_NODES) readonly buffer BvhNodeBuffer { BvhNode bvh_nodes[]; };
layout(std430, set = 0, binding = BINDING_BVH_PRIMS) readonly buffer BvhPrimBuffer { uint bvh_prims[]; };

#define BVH_STACK_SIZE 64
// Mirrors of src/accel/bvh.rs: SLAB_EXIT_SCALE = 1 + 2 gamma(3), MIN_DIR_COMPONENT.
const float BVH_SLAB_EXIT_SCALE = 1.0 + 2.0 * (3.0 * 5.9604645e-8) / (1.0 - 3.0 * 5.9604645e-8);
const float BVH_MIN_DIR_COMPONENT = 1e-30;

vec3 bvh_safe_inverse(vec3 d) {
    vec3 c = mix(d, mix(vec3(-BVH_MIN_DIR_COMPONENT), vec3(BVH_MIN_DIR_COMPONENT), greaterThanEqual(d, vec3(0.0))),
                 lessThan(abs(d), vec3(BVH_MIN_DIR_COMPONENT)));
    return 1.0 / c;
}

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

bool bvh_intersect_prim(uint prim, vec3 o, vec3 d, float tmax, out float t, out vec2 bary) {
    uint ntri = scene.dims.z;
    bary = vec2(0.0);
    if (prim < ntri) {
        GpuTriangle tri = triangles[prim];
        return intersect_triangle(tri.v0.xyz, tri.v1.xyz, tri.v2.xyz, o, d, 0.0, tmax, t, bary);
    }
    return intersect_sphere(spheres[prim - ntri], o, d, 0.0, tmax, t);
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
    BvhNode root = bvh_nodes[0];
    // An empty scene is one empty leaf with an inverted box.
    if (root.min_left.x > root.max_count.x) return false;
    if (bvh_box_entry(root, o, inv_d, closest) == INF) return false;
    while (true) {
        BvhNode node = bvh_nodes[node_index];
        uint count = floatBitsToUint(node.max_count.w);
        uint first = floatBitsToUint(node.min_left.w);
        if (count > 0u) {
            for (uint i = 0u; i < count; ++i) {
                uint prim = bvh_prims[first + i];
                float t;
                vec2 bary;
                if (bvh_intersect_prim(prim, o, d, closest, t, bary)) {
                    closest = t;
                    found = true;
                    hit.t = t;
                    hit.prim = prim;
                    hit.bary = bary;
                    if (any_hit) return true;
                }
            }
        } else {
            uint a = node_index + 1u;
            uint b = first;
            float ta = bvh_box_entry(bvh_nodes[a], o, inv_d, closest);
            float tb = bvh_box_entry(bvh_nodes[b], o, inv_d, closest);
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
            if (bvh_box_entry(bvh_nodes[candidate], o, inv_d, closest) != INF) {
                node_index = candidate;
                next = true;
                break;
            }
        }
        if (!next) break;
    }
    return found;
}

bool trace_closest(vec3 o, vec3 d, float tmax, out Hit hit) {
    return bvh_traverse(o, d, tmax, false, hit);
}

bool trace_occluded(vec3 o, vec3 d, float tmax) {
    Hit hit;
    return bvh_traverse(o, d, tmax, true, hit);
}
