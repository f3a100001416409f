#!/usr/bin/env python3
"""Writes the production-size benchmark scenes of issue 30 (docs/performance.md, "Scenes of
production size") into a directory; nothing of them is committed.

  scripts/large-scenes.py OUT [--scale S] [--only mesh,instances,textures]

- mesh/mesh.pbrt: one mesh of 20 million triangles (a rippled grid, binary PLY) under a
  constant environment light and a distant light.
- instances/instances.pbrt: 10,000 instances of one 100,000-triangle mesh (a bumpy
  sphere, binary PLY) on a 100 × 100 lattice, rotated, scaled (some mirrored, some
  non-uniformly): one billion instanced triangles, under an environment light.
- textures/textures.pbrt: 300 quads, each with its own 1k × 1k PNG texture (a distinct
  pattern per texture), under an environment light.

--scale multiplies every count (triangles, instances, textures; texture side by its
square root), for quick runs: --scale 0.01 writes a 200k-triangle mesh, 100 instances of
a 1,000-triangle mesh and 3 textures. Needs numpy. Deterministic: the same arguments
write the same bytes.
"""
import argparse
import math
import os
import struct
import zlib

import numpy as np


def write_ply(path, vertices, faces, uv=None):
    """A binary little-endian PLY of float32 vertices (and uv) and int32 triangles."""
    n, m = len(vertices), len(faces)
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {n}",
              "property float x", "property float y", "property float z"]
    if uv is not None:
        header += ["property float u", "property float v"]
    header += [f"element face {m}", "property list uchar int vertex_indices", "end_header"]
    cols = [vertices.astype("<f4")]
    if uv is not None:
        cols.append(uv.astype("<f4"))
    vdata = np.ascontiguousarray(np.concatenate(cols, axis=1))
    fdt = np.dtype([("n", "u1"), ("i", "<i4", 3)])
    fdata = np.empty(m, dtype=fdt)
    fdata["n"] = 3
    fdata["i"] = faces
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        f.write(vdata.tobytes())
        f.write(fdata.tobytes())


def grid_faces(nx, ny):
    """Two triangles per cell of an (nx + 1) × (ny + 1) vertex grid, row by row."""
    i = np.arange(ny, dtype=np.int64)[:, None] * (nx + 1) + np.arange(nx, dtype=np.int64)[None, :]
    i = i.ravel()
    a, b, c, d = i, i + 1, i + nx + 2, i + nx + 1
    return np.stack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)], 1).reshape(-1, 3).astype(np.int32)


def mesh_scene(out, scale):
    os.makedirs(out, exist_ok=True)
    # 2 n² triangles: n = 3163 gives 20,007,938.
    n = max(2, int(round(math.sqrt(20e6 * scale / 2))))
    t = np.linspace(0.0, 1.0, n + 1, dtype=np.float64)
    u, v = np.meshgrid(t, t)
    x, z = (u - 0.5) * 20.0, (v - 0.5) * 20.0
    y = 0.15 * np.sin(7.0 * x) * np.cos(5.0 * z) + 0.05 * np.sin(31.0 * x + 17.0 * z)
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    uv = np.stack([u.ravel(), v.ravel()], 1)
    faces = grid_faces(n, n)
    write_ply(os.path.join(out, "mesh.ply"), vertices, faces, uv)
    with open(os.path.join(out, "mesh.pbrt"), "w") as f:
        f.write(f"""# {len(faces)} triangles in one mesh (scripts/large-scenes.py)
LookAt 0 6 -14  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 256 "integer yresolution" 256 "string filename" "mesh.exr"
Sampler "independent" "integer pixelsamples" 16
WorldBegin
LightSource "infinite" "rgb L" [ 0.4 0.45 0.5 ]
LightSource "distant" "point3 from" [ 1 4 -2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 2 2 2 ]
Material "coateddiffuse" "rgb reflectance" [ 0.5 0.35 0.2 ] "float roughness" 0.1
Shape "plymesh" "string filename" "mesh.ply"
""")
    return len(faces)


def sphere_mesh(target):
    """A bumpy unit sphere of about `target` triangles (a latitude-longitude grid)."""
    nv = max(2, int(round(math.sqrt(target / 4))))
    nu = 2 * nv
    theta = np.linspace(0.0, math.pi, nv + 1)
    phi = np.linspace(0.0, 2.0 * math.pi, nu + 1)
    ph, th = np.meshgrid(phi, theta)
    r = 1.0 + 0.06 * np.sin(9.0 * ph) * np.sin(7.0 * th) ** 2
    vertices = np.stack([(r * np.sin(th) * np.cos(ph)).ravel(), (r * np.cos(th)).ravel(),
                         (r * np.sin(th) * np.sin(ph)).ravel()], 1)
    return vertices, grid_faces(nu, nv)


def instances_scene(out, scale):
    os.makedirs(out, exist_ok=True)
    vertices, faces = sphere_mesh(100_000 * math.sqrt(scale))
    write_ply(os.path.join(out, "object.ply"), vertices, faces)
    side = max(1, int(round(100 * math.sqrt(scale))))
    rng = np.random.default_rng(30)
    lines = [f"""# {side * side} instances of a {len(faces)}-triangle mesh: {side * side * len(faces)} instanced triangles (scripts/large-scenes.py)
LookAt 0 {1.2 * side} {-1.6 * side}  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 256 "integer yresolution" 256 "string filename" "instances.exr"
Sampler "independent" "integer pixelsamples" 16
WorldBegin
LightSource "infinite" "rgb L" [ 0.8 0.85 0.9 ]
ObjectBegin "object"
Material "diffuse" "rgb reflectance" [ 0.6 0.5 0.4 ]
Shape "plymesh" "string filename" "object.ply"
ObjectEnd
Material "diffuse" "rgb reflectance" [ 0.3 0.3 0.3 ]
Shape "bilinearmesh" "point3 P" [ -{side} -1 -{side}  {side} -1 -{side}  -{side} -1 {side}  {side} -1 {side} ]
"""]
    for i in range(side):
        for j in range(side):
            angle = float(rng.uniform(0.0, 360.0))
            s = rng.uniform(0.6, 1.0, 3)
            kind = (i * side + j) % 4
            if kind == 0:
                s[:] = s[0]  # uniform
            elif kind == 1:
                s[0] = -s[0]  # mirrored
            x, z = 2.0 * i - side + 1.0, 2.0 * j - side + 1.0
            lines.append(
                f"AttributeBegin Translate {x:.3f} 0 {z:.3f} Rotate {angle:.2f} 0 1 0 "
                f"Scale {s[0]:.3f} {s[1]:.3f} {s[2]:.3f} ObjectInstance \"object\" AttributeEnd\n")
    with open(os.path.join(out, "instances.pbrt"), "w") as f:
        f.writelines(lines)
    return side * side * len(faces)


def write_png(path, rgb):
    """An 8-bit RGB PNG (stdlib zlib)."""
    h, w, _ = rgb.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, w * 3)], axis=1).tobytes()

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def textures_scene(out, scale):
    os.makedirs(os.path.join(out, "tex"), exist_ok=True)
    count = max(1, int(round(300 * scale)))
    size = max(16, int(round(1024 * min(1.0, math.sqrt(scale) * 10))))
    t = np.linspace(0.0, 1.0, size, endpoint=False)
    u, v = np.meshgrid(t, t)
    side = int(math.ceil(math.sqrt(count)))
    lines = [f"""# {count} quads, each with its own {size} x {size} texture (scripts/large-scenes.py)
LookAt {side} {side} {-1.5 * side}  {side} {side} 0  0 1 0
Camera "perspective" "float fov" 50
Film "rgb" "integer xresolution" 256 "integer yresolution" 256 "string filename" "textures.exr"
Sampler "independent" "integer pixelsamples" 16
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
"""]
    for k in range(count):
        fx, fy = 2 + k % 17, 3 + (k * 7) % 13
        r = 0.5 + 0.5 * np.sin(2 * math.pi * (fx * u + 0.1 * k))
        g = 0.5 + 0.5 * np.cos(2 * math.pi * (fy * v + 0.05 * k))
        b = ((np.floor(u * (4 + k % 9)) + np.floor(v * (4 + k % 5))) % 2) * 0.8 + 0.1
        rgb = (np.stack([r, g, b], 2) * 255.0 + 0.5).astype(np.uint8)
        name = f"tex/t{k:03d}.png"
        write_png(os.path.join(out, name), rgb)
        x, y = 2.0 * (k % side), 2.0 * (k // side)
        lines.append(
            f"Texture \"t{k}\" \"spectrum\" \"imagemap\" \"string filename\" \"{name}\"\n"
            f"Material \"diffuse\" \"texture reflectance\" \"t{k}\"\n"
            f"Shape \"bilinearmesh\" \"point3 P\" [ {x} {y} 0  {x + 1.8} {y} 0  {x} {y + 1.8} 0  {x + 1.8} {y + 1.8} 0 ] "
            f"\"point2 uv\" [ 0 0  1 0  0 1  1 1 ]\n")
    with open(os.path.join(out, "textures.pbrt"), "w") as f:
        f.writelines(lines)
    return count


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out")
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--only", default="mesh,instances,textures")
    a = p.parse_args()
    for what in a.only.split(","):
        if what == "mesh":
            n = mesh_scene(os.path.join(a.out, "mesh"), a.scale)
            print(f"mesh: {n} triangles")
        elif what == "instances":
            n = instances_scene(os.path.join(a.out, "instances"), a.scale)
            print(f"instances: {n} instanced triangles")
        elif what == "textures":
            n = textures_scene(os.path.join(a.out, "textures"), a.scale)
            print(f"textures: {n} textures")
        else:
            raise SystemExit(f"--only: unknown scene {what!r} (mesh, instances, textures)")


if __name__ == "__main__":
    main()
