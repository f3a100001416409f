#!/usr/bin/env python3
"""Reference CPU measurement: renders a CSE168 `.test` scene with Mitsuba 3's
`path` integrator on the `llvm_ad_rgb` variant (Dr.Jit's LLVM JIT) and prints
    seconds <wall time of the timed render>
    threads <Dr.Jit worker threads>
    samples_per_second <SIZE*SIZE*SPP / seconds>   (always the last line)
Used by `lightpath bench --mitsuba`; install the dependencies with
scripts/setup-mitsuba.sh.

Usage: mitsuba_bench.py SCENE.test SIZE SPP [--out image.exr|image.png]

The scene is translated, not reproduced exactly (good enough for a speed reference):
  - every material becomes a two-sided Lambertian `diffuse` with kd as reflectance;
    Phong/GGX specular lobes (specular, shininess, roughness, brdf) are ignored;
  - `emission` makes a one-sided area emitter (along the triangle's geometric normal /
    a sphere's outward normal), where lightpath's is two-sided;
  - a sphere under a non-uniform scale (an ellipsoid) is tessellated, since Mitsuba's
    `sphere` only accepts similarity transforms;
  - Mitsuba's Russian roulette caps the survival probability at 0.95; its path tracer
    always does MIS next-event estimation (nexteventestimation/importancesampling are
    ignored), and the scene's size/spp are replaced by the command line's.
"""
import glob
import os
import subprocess
import sys
import time

import numpy as np


def find_libllvm19():
    """The path of Debian's libllvm19 shared library, or None."""
    try:
        files = subprocess.run(["dpkg", "-L", "libllvm19"], capture_output=True,
                               text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        files = glob.glob("/usr/lib/*/libLLVM*19*.so*")
    libs = sorted(f for f in files if "/libLLVM" in f and ".so" in f)
    return libs[0] if libs else None


# Dr.Jit must see the library before mitsuba/drjit are imported: with bookworm's
# default LLVM 15 its JIT fails to compile Mitsuba's kernels.
if "DRJIT_LIBLLVM_PATH" not in os.environ:
    lib = find_libllvm19()
    if lib:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib

try:
    import drjit as dr
    import mitsuba as mi
except ImportError as e:
    sys.exit(f"mitsuba_bench: cannot import mitsuba ({e}); run scripts/setup-mitsuba.sh")


# ---- transforms (4x4, column vectors; the scene's commands do M <- M * T) ----

def translate(v):
    m = np.eye(4)
    m[:3, 3] = v
    return m


def scale(v):
    return np.diag([v[0], v[1], v[2], 1.0])


def rotate(axis, degrees):
    a = np.asarray(axis, float)
    n = np.linalg.norm(a)
    if n == 0:
        raise ValueError("the rotation axis must not be zero")
    x, y, z = a / n
    t = np.radians(degrees)
    c, s, k = np.cos(t), np.sin(t), 1 - np.cos(t)
    m = np.eye(4)  # Rodrigues' rotation formula
    m[:3, :3] = [[c + x * x * k, x * y * k - z * s, x * z * k + y * s],
                 [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
                 [z * x * k - y * s, z * y * k + x * s, c + z * z * k]]
    return m


def uv_sphere(n=32):
    """Unit-sphere triangle mesh (vertices, faces), faces wound outward."""
    th, ph = np.meshgrid(np.linspace(0, np.pi, n + 1), np.linspace(0, 2 * np.pi, 2 * n + 1),
                         indexing="ij")
    v = np.stack([np.sin(th) * np.cos(ph), np.cos(th), -np.sin(th) * np.sin(ph)], -1)
    idx = np.arange(v.shape[0] * v.shape[1]).reshape(v.shape[:2])
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                        np.stack([a, c, d], -1).reshape(-1, 3)])
    return v.reshape(-1, 3), f


# ---- the .test parser (see docs/scene-format.md) ----

ARITY = {"size": 2, "output": 1, "camera": 10, "spp": 1, "gamma": 1, "maxverts": 1,
         "vertex": 3, "tri": 3, "sphere": 4, "translate": 3, "rotate": 4, "scale": 3,
         "pushTransform": 0, "popTransform": 0, "diffuse": 3, "specular": 3,
         "shininess": 1, "roughness": 1, "brdf": 1, "emission": 3, "ambient": 3,
         "attenuation": 3, "quadLight": 12, "point": 6, "directional": 6,
         "integrator": 1, "maxdepth": 1, "nexteventestimation": 1, "russianroulette": 1,
         "importancesampling": 1, "lightsamples": 1, "lightstratify": 1}
WORDS = ("output", "brdf", "integrator", "nexteventestimation", "russianroulette",
         "importancesampling", "lightstratify")


def parse(path):
    """Returns a dict: camera, maxdepth, rr, tris {material: [triangle(3x3)]},
    spheres [(matrix, material)], quads [(a, ab, ac, rgb)], points, directionals.
    A material is the tuple (kd, emission)."""
    s = {"camera": None, "maxdepth": 5, "rr": True, "tris": {}, "spheres": [],
         "quads": [], "points": [], "directionals": []}
    verts, M, stack = [], np.eye(4), []
    kd, emission = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    for ln, line in enumerate(open(path), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        cmd, args = words[0], words[1:]
        where = f"{path}:{ln}: {cmd}"
        if cmd not in ARITY:
            sys.exit(f"{where}: unknown command")
        if len(args) != ARITY[cmd]:
            sys.exit(f"{where}: expected {ARITY[cmd]} arguments, got {len(args)}")
        if cmd not in WORDS:
            try:
                args = [float(a) for a in args]
            except ValueError:
                sys.exit(f"{where}: cannot parse a number in {' '.join(args)}")
        if cmd == "vertex":
            verts.append(args)
        elif cmd == "tri":
            idx = [int(i) for i in args]
            if any(i < 0 or i >= len(verts) or i != a for i, a in zip(idx, args)):
                sys.exit(f"{where}: vertex index out of range ({len(verts)} declared)")
            p = np.array([verts[i] + [1.0] for i in idx]) @ M.T
            s["tris"].setdefault((kd, emission), []).append(p[:, :3])
        elif cmd == "sphere":
            s["spheres"].append((M @ translate(args[:3]) @ scale([args[3]] * 3),
                                 (kd, emission)))
        elif cmd == "translate":
            M = M @ translate(args)
        elif cmd == "scale":
            M = M @ scale(args)
        elif cmd == "rotate":
            try:
                M = M @ rotate(args[:3], args[3])
            except ValueError as e:
                sys.exit(f"{where}: {e}")
        elif cmd == "pushTransform":
            stack.append(M.copy())
        elif cmd == "popTransform":
            if not stack:
                sys.exit(f"{where}: no matching pushTransform")
            M = stack.pop()
        elif cmd == "diffuse":
            kd = tuple(args)
        elif cmd == "emission":
            emission = tuple(args)
        elif cmd == "quadLight":
            s["quads"].append((np.array(args[0:3]), np.array(args[3:6]),
                               np.array(args[6:9]), args[9:12]))
        elif cmd == "point":
            s["points"].append((args[:3], args[3:]))
        elif cmd == "directional":
            s["directionals"].append((args[:3], args[3:]))
        elif cmd == "camera":
            s["camera"] = (args[0:3], args[3:6], args[6:9], args[9])
        elif cmd == "maxdepth":
            s["maxdepth"] = int(args[0])
        elif cmd == "russianroulette":
            s["rr"] = args[0] == "on"
        # Everything else (size, spp, output, gamma, specular lobes, ...) does not
        # affect this benchmark.
    if s["camera"] is None:
        sys.exit(f"{path}: no camera")
    return s


# ---- building the Mitsuba scene ----

def bsdf(kd):
    return {"type": "twosided",
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(kd)}}}


def area(rgb):
    return {"type": "area", "radiance": {"type": "rgb", "value": list(rgb)}}


def mesh(name, vertices, faces, kd, emission):
    """An mi.Mesh built in memory from (n,3) vertex and (m,3) face arrays."""
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf(kd))
    if any(emission):
        props["emitter"] = mi.load_dict(area(emission))
    m = mi.Mesh(name, len(vertices), len(faces), has_vertex_normals=False,
                has_vertex_texcoords=False, props=props)
    params = mi.traverse(m)
    params["vertex_positions"] = mi.Float(np.ravel(vertices).astype(np.float32))
    params["faces"] = mi.UInt32(np.ravel(faces).astype(np.uint32))
    params.update()
    return m


def build(s, size, spp):
    eye, target, up, fovy = s["camera"]
    maxdepth = s["maxdepth"]
    d = {
        "type": "scene",
        # Mitsuba's max_depth counts path segments (1: emitters seen directly, 2: direct
        # lighting); lightpath's maxdepth counts scattering vertices, so add one.
        "integrator": {"type": "path", "max_depth": -1 if maxdepth < 0 else maxdepth + 1,
                       "rr_depth": 1 if s["rr"] else 1 << 30, "hide_emitters": False},
        "sensor": {
            "type": "perspective", "fov_axis": "y", "fov": fovy,
            "to_world": mi.ScalarTransform4f().look_at(origin=eye, target=target, up=up),
            "film": {"type": "hdrfilm", "width": size, "height": size,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
    }
    n = 0
    for (kd, emission), tris in s["tris"].items():
        v = np.concatenate(tris)  # 3 unshared vertices per triangle: flat shading
        d[f"mesh{n}"] = mesh(f"mesh{n}", v, np.arange(len(v)).reshape(-1, 3), kd, emission)
        n += 1
    for M, (kd, emission) in s["spheres"]:
        sv = np.linalg.svd(M[:3, :3], compute_uv=False)
        if np.allclose(sv, sv[0], rtol=1e-5):
            d[f"sphere{n}"] = {"type": "sphere", "to_world": mi.ScalarTransform4f(M.tolist()),
                               "bsdf": bsdf(kd)}
            if any(emission):
                d[f"sphere{n}"]["emitter"] = area(emission)
        else:  # ellipsoid: tessellate (winding flips if M mirrors)
            v, f = uv_sphere()
            v = np.c_[v, np.ones(len(v))] @ M.T
            f = f if np.linalg.det(M[:3, :3]) > 0 else f[:, ::-1]
            d[f"sphere{n}"] = mesh(f"sphere{n}", v[:, :3], f, kd, emission)
        n += 1
    for a, ab, ac, rgb in s["quads"]:
        # Corners a, a+ac, a+ab+ac, a+ab: the faces' normal is cross(ac, ab), the side
        # Mitsuba's area emitter emits on. The quad is black geometry on both sides.
        v = np.array([a, a + ac, a + ab + ac, a + ab])
        d[f"quad{n}"] = mesh(f"quad{n}", v, [[0, 1, 2], [0, 2, 3]], (0, 0, 0), rgb)
        n += 1
    for p, rgb in s["points"]:
        d[f"point{n}"] = {"type": "point", "position": p,
                          "intensity": {"type": "rgb", "value": rgb}}
        n += 1
    for direction, rgb in s["directionals"]:
        # The light arrives *from* `direction`; Mitsuba wants the propagation direction.
        d[f"dir{n}"] = {"type": "directional", "direction": [-x for x in direction],
                        "irradiance": {"type": "rgb", "value": rgb}}
        n += 1
    return mi.load_dict(d)


def main():
    argv = sys.argv[1:]
    out = None
    if "--out" in argv:
        i = argv.index("--out")
        out = argv[i + 1]
        del argv[i:i + 2]
    if len(argv) != 3:
        sys.exit(__doc__)
    path, size, spp = argv[0], int(argv[1]), int(argv[2])
    mi.set_variant("llvm_ad_rgb")
    scene = build(parse(path), size, spp)

    # Warm-up: compiles (or loads from Dr.Jit's kernel cache) the render kernel, which
    # does not depend on the sample count; not timed.
    dr.eval(mi.render(scene, spp=1, seed=1))
    dr.sync_thread()

    start = time.perf_counter()
    img = mi.render(scene, spp=spp, seed=2)
    dr.eval(img)
    dr.sync_thread()
    seconds = time.perf_counter() - start

    if out:
        mi.util.write_bitmap(out, img)
    print(f"seconds {seconds:.6f}")
    print(f"threads {dr.thread_count()}")
    print(f"samples_per_second {size * size * spp / seconds:.1f}")


if __name__ == "__main__":
    main()
