// Visibility by VK_KHR_ray_query. The world's triangles are one BLAS instance (identity
// transform); each instance of an object (FEATURE_INSTANCES) an instance of the object's
// BLAS (opaque: its triangles have no alpha) under its transform;
// each sphere is an instance of a unit-cube AABB BLAS under the sphere's transform,
// whose custom index is the sphere's index, intersected exactly here in world space.
// With alpha cut-outs (FEATURE_ALPHA) the triangles are not opaque: each candidate is
// confirmed here unless alpha_cut cuts it.
#extension GL_EXT_ray_query : require

layout(set = 0, binding = BINDING_TLAS) uniform accelerationStructureEXT tlas;

uint rq_flags() { return has_feature(FEATURE_ALPHA) ? gl_RayFlagsNoneEXT : gl_RayFlagsOpaqueEXT; }

// The triangle record of primitive p of geometry g of a BLAS over the records from
// `first`: its geometries are that range cut where the triangle data's chunks begin
// (src/gpu/rayquery.rs), so geometry g > 0 starts at a chunk.
uint rq_record(uint first, uint g, uint p) {
    if (g == 0u) return first + p;
    uint s = data_kinds[DATA_TRIANGLES].z;
    return (((first >> s) + g) << s) + p;
}

// (any_hit: the first hit found ends the query.)
bool trace_ray(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit) {
    rayQueryEXT rq;
    uint flags = rq_flags() | (any_hit ? gl_RayFlagsTerminateOnFirstHitEXT : 0u);
    rayQueryInitializeEXT(rq, tlas, flags, 0xFF, o, 0.0, d, tmax);
    while (rayQueryProceedEXT(rq)) {
        if (has_feature(FEATURE_ALPHA) && rayQueryGetIntersectionTypeEXT(rq, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
            // (Only the world's triangles have alpha: their BLAS starts at record 0.)
            uint r = rq_record(0u, uint(rayQueryGetIntersectionGeometryIndexEXT(rq, false)),
                               uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, false)));
            if (!alpha_cut(triangle_record(r), rayQueryGetIntersectionBarycentricsEXT(rq, false), o, d)) {
                rayQueryConfirmIntersectionEXT(rq);
                if (any_hit) rayQueryTerminateEXT(rq);
            }
            continue;
        }
        if (rayQueryGetIntersectionTypeEXT(rq, false) == gl_RayQueryCandidateIntersectionAABBEXT) {
            // Generated hits skip the driver's distance check: test against the
            // closest hit committed so far (opaque triangles commit without asking).
            float committed = rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT
                ? rayQueryGetIntersectionTEXT(rq, true)
                : tmax;
            uint si = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(rq, false));
            float t;
            if (intersect_sphere(spheres[si], o, d, 0.0, committed, t)) {
                rayQueryGenerateIntersectionEXT(rq, t);
                if (any_hit) rayQueryTerminateEXT(rq);
            }
        }
    }
    hit.t = 0.0;
    hit.prim = 0u;
    hit.bary = vec2(0.0);
    uint kind = rayQueryGetIntersectionTypeEXT(rq, true);
    if (kind == gl_RayQueryCommittedIntersectionTriangleEXT) {
        hit.t = rayQueryGetIntersectionTEXT(rq, true);
        uint g = uint(rayQueryGetIntersectionGeometryIndexEXT(rq, true));
        uint p = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
        hit.prim = rq_record(0u, g, p);
        // An object's instance (FEATURE_INSTANCES) has custom index 1 + its index (its
        // object's records start at info.x - info.y, its triangle ids at info.x); the
        // world's triangles 0.
        if (has_feature(FEATURE_INSTANCES)) {
            uint c = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(rq, true));
            if (c != 0u) {
                uvec4 info = instances[c - 1u].info;
                hit.prim = rq_record(info.x - info.y, g, p) + info.y;
            }
        }
        hit.bary = rayQueryGetIntersectionBarycentricsEXT(rq, true);
        return true;
    }
    if (kind == gl_RayQueryCommittedIntersectionGeneratedEXT) {
        hit.t = rayQueryGetIntersectionTEXT(rq, true);
        hit.prim = scene.triangle_count + uint(rayQueryGetIntersectionInstanceCustomIndexEXT(rq, true));
        return true;
    }
    return false;
}
