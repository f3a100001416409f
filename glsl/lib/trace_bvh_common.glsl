// What the two storage-buffer BVH walks share: the primitive references of their
// leaves, the slab test's constants, the exact primitive tests and the visibility
// interface over the walk.

// Mirrors of src/accel/bvh.rs: SLAB_EXIT_SCALE = 1 + 2 gamma(3), MIN_DIR_COMPONENT.
const float BVH_SLAB_EXIT_SCALE = 1.0 + 2.0 * (3.0 * 5.9604645e-8) / (1.0 - 3.0 * 5.9604645e-8);
const float BVH_MIN_DIR_COMPONENT = 1e-30;

vec3 bvh_safe_inverse(vec3 d) {
    vec3 c = mix(d, mix(vec3(-BVH_MIN_DIR_COMPONENT), vec3(BVH_MIN_DIR_COMPONENT), greaterThanEqual(d, vec3(0.0))),
                 lessThan(abs(d), vec3(BVH_MIN_DIR_COMPONENT)));
    return 1.0 / c;
}

bool bvh_intersect_prim_once(uint prim, vec3 o, vec3 d, float tmax, out float t, out vec2 bary) {
    uint ntri = scene.triangle_count;
    bary = vec2(0.0);
    if (prim < ntri) {
        GpuTriangle tri = triangle_record(prim);
        return intersect_triangle(tri.v0.xyz, tri.v1.xyz, tri.v2.xyz, o, d, 0.0, tmax, t, bary)
            && !alpha_cut(tri, bary, o, d);
    }
    return intersect_sphere(spheres[prim - ntri], o, d, 0.0, tmax, t);
}


// The leaves' primitive test. lightpath profile's PROFILE_X2_PRIM variant does it twice
// (the second answer is kept only where tmax < 0, never), so the extra time is the
// primitive tests' share of a pass, apart from traversal.
bool bvh_intersect_prim(uint prim, vec3 o, vec3 d, float tmax, out float t, out vec2 bary) {
#ifdef PROFILE_X2_PRIM
    float t2;
    vec2 bary2;
    bool second = bvh_intersect_prim_once(prim, o * 1.0000001, d, tmax * 0.99999994, t2, bary2);
    bool first = bvh_intersect_prim_once(prim, o, d, tmax, t, bary);
    if (second && tmax < 0.0) {
        t = t2;
        bary = bary2;
        return true;
    }
    return first;
#else
    return bvh_intersect_prim_once(prim, o, d, tmax, t, bary);
#endif
}

// Tests a leaf's primitive against the closest hit so far (`closest`); a nearer hit
// becomes the closest and is recorded in `hit`.
bool bvh_visit_prim(uint prim, vec3 o, vec3 d, inout float closest, inout Hit hit) {
    float t;
    vec2 bary;
    if (!bvh_intersect_prim(prim, o, d, closest, t, bary)) return false;
    closest = t;
    hit.t = t;
    hit.prim = prim;
    hit.bary = bary;
    return true;
}

// Two levels (FEATURE_INSTANCES): the tree at node 0 holds the world's primitives and the
// instances, a leaf's reference scene.flat_triangle_count + k being instance k; each
// object's tree (its root GpuInstance.info.z) holds its triangles' records. A walk meeting
// an instance walks the object's tree with the ray carried to object space (o by the
// instance's world-to-object transform, d by its linear part, unnormalized: t is the same
// in both spaces), then goes on with the world ray; a hit's id is its record + info.y.
bool bvh_is_instance(uint prim, uint inst) {
    return has_feature(FEATURE_INSTANCES) && inst == NO_INSTANCE && prim >= scene.flat_triangle_count
        && prim < scene.triangle_count;
}

void bvh_ray_to_object(uint inst, inout vec3 o, inout vec3 d) {
    vec4 q = vec4(o, 1.0);
    o = vec3(dot(instances[inst].w2o0, q), dot(instances[inst].w2o1, q), dot(instances[inst].w2o2, q));
    d = vec3(dot(instances[inst].w2o0.xyz, d), dot(instances[inst].w2o1.xyz, d), dot(instances[inst].w2o2.xyz, d));
}

// Each walk (trace_bvh2.glsl, trace_cwbvh.glsl) defines its traversal; the kernels'
// visibility interface (trace.glsl) is the same over either.
bool bvh_traverse(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit);

bool trace_ray(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit) {
    return bvh_traverse(o, d, tmax, any_hit, hit);
}
