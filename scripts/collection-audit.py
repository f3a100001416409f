#!/usr/bin/env python3
"""Render the scenes of a local copy of the pbrt-v4 scene collection with stand-in assets.

The collection (mmp/pbrt-v4-scenes) keeps its geometry, textures, measured materials and
volumes in files too large to fetch on the project's machine; its .pbrt text is small.
This script copies a directory of the collection's text files, writes a stand-in for
every file a scene names that is not there (by its extension: an empty .pbrt include, a
one-quad PLY, a 2 x 2 grey image, the repository's tabulated GGX .bsdf, a flat .spd
spectrum), then renders every top-level scene (a file with WorldBegin) at a tiny size
with each integrator, and prints a Markdown table of what read and rendered and what
failed, with the first line of each error. It does not fetch anything.

    scripts/collection-audit.py COLLECTION_DIR [--out DIR] [--integrators pathtracer,bdpt,mmlt]
                                [--size 32x18] [--spp 1] [--timeout 900] [--only NAME ...]

Stand-ins keep the reader honest about everything but the asset's contents: the scene's
directives, parameters, transforms, materials, lights and media are all read as written.
A stand-in is written where pbrt-v4 looks for the file: relative to the directory of the
top-level scene file (its search directory), whichever file names it. Kinds it cannot
stand in for (NanoVDB volumes, lens files) are left missing and reported.
LIGHTPATH_BIN=path runs that binary instead of ./lp.
"""
import argparse
import gzip
import os
import re
import shutil
import struct
import subprocess
import sys
import time
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# A file named by a directive or a string parameter.
REF = re.compile(
    r'(?:\b(?:Include|Import)\s+"([^"]+)")'
    r'|(?:"string\s+(?:filename|normalmap|lensfile|bsdffile|mapname)"\s*\[?\s*"([^"]+)")'
    r'|(?:"spectrum\s+\w+"\s*\[?\s*"([^"]+\.spd)")'
)


def png(w, h, rgb):
    raw = b"".join(b"\0" + bytes(rgb) * w for _ in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def exr(w, h, value):
    def attr(name, kind, data):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data

    chans = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    header = (b"\x76\x2f\x31\x01" + struct.pack("<i", 2)
              + attr("channels", "chlist", chans)
              + attr("compression", "compression", b"\0")
              + attr("dataWindow", "box2i", struct.pack("<4i", 0, 0, w - 1, h - 1))
              + attr("displayWindow", "box2i", struct.pack("<4i", 0, 0, w - 1, h - 1))
              + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
              + attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    line = struct.pack("<f", value) * (3 * w)
    first = len(header) + 8 * h
    table = b"".join(struct.pack("<Q", first + y * (8 + len(line))) for y in range(h))
    lines = b"".join(struct.pack("<ii", y, len(line)) + line for y in range(h))
    return header + table + lines


def stand_in(path):
    """The bytes of a stand-in for `path`, or None where there is none."""
    name = path.lower()
    gz = name.endswith(".gz")
    if gz:
        name = name[:-3]
    if name.endswith(".pbrt"):
        data = b"# stand-in (collection-audit.py): the original file is not here\n"
    elif name.endswith(".ply"):
        # (Each mesh's quad a little apart from the others, by a hash of its name: a
        # scene of hundreds of meshes would otherwise be hundreds of coincident quads.)
        h = zlib.crc32(path.encode())
        dx, dy, dz = ((h >> s) % 1000 / 1000.0 - 0.5 for s in (0, 10, 20))
        verts = "".join(f"{x + dx:g} {y + dy:g} {dz:g} {u} {v}\n"
                        for x, y, u, v in ((-0.5, -0.5, 0, 0), (0.5, -0.5, 1, 0),
                                           (0.5, 0.5, 1, 1), (-0.5, 0.5, 0, 1)))
        data = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                b"property float z\nproperty float u\nproperty float v\nelement face 2\n"
                b"property list uchar int vertex_indices\nend_header\n"
                + verts.encode() + b"3 0 1 2\n3 0 2 3\n")
    elif name.endswith(".png"):
        data = png(2, 2, [128, 128, 128])
    elif name.endswith(".exr"):
        data = exr(2, 2, 0.5)
    elif name.endswith(".pfm"):
        data = b"PF\n2 2\n-1.0\n" + struct.pack("<f", 0.5) * 12
    elif name.endswith(".tga"):
        data = struct.pack("<BBBHHBHHHHBB", 0, 0, 2, 0, 0, 0, 0, 0, 2, 2, 24, 0) + bytes([128]) * 12
    elif name.endswith(".bsdf"):
        with open(os.path.join(ROOT, "scenes/pbrt/ggx.bsdf"), "rb") as f:
            data = f.read()
    elif name.endswith(".spd"):
        data = b"# stand-in: flat\n400 1\n700 1\n"
    else:
        return None
    return gzip.compress(data) if gz else data


def top_level(path):
    with open(path, errors="replace") as f:
        return "WorldBegin" in f.read()


def write_stand_ins(work):
    """Stand-ins for every missing file the scenes name, relative to each top-level
    scene's directory; returns (written, missing-without-stand-in)."""
    written, missing = [], []
    scenes = [os.path.join(d, f) for d, _, fs in os.walk(work) for f in fs
              if f.endswith(".pbrt") and top_level(os.path.join(d, f))]
    for scene in sorted(scenes):
        base = os.path.dirname(scene)
        todo, seen = [scene], set()
        while todo:
            f = todo.pop()
            if f in seen or not os.path.exists(f):
                continue
            seen.add(f)
            opener = gzip.open if f.endswith(".gz") else open
            try:
                with opener(f, "rt", errors="replace") as fh:
                    text = fh.read()
            except OSError:
                continue
            for m in REF.finditer(text):
                rel = next(g for g in m.groups() if g)
                target = rel if os.path.isabs(rel) else os.path.normpath(os.path.join(base, rel))
                if not os.path.exists(target):
                    data = stand_in(target)
                    if data is None:
                        missing.append(os.path.relpath(target, work))
                        continue
                    os.makedirs(os.path.dirname(target), exist_ok=True)
                    with open(target, "wb") as out:
                        out.write(data)
                    written.append(os.path.relpath(target, work))
                if m.group(1):
                    todo.append(target)
    return scenes, written, missing


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("collection")
    ap.add_argument("--out", default="/tmp/lightpath-collection-audit")
    ap.add_argument("--integrators", default="pathtracer,bdpt,mmlt")
    ap.add_argument("--size", default="32x18")
    ap.add_argument("--spp", default="1")
    ap.add_argument("--timeout", type=int, default=900)
    ap.add_argument("--only", nargs="*", default=[])
    args = ap.parse_args()
    work = os.path.join(args.out, "scenes")
    if os.path.exists(work):
        shutil.rmtree(work)
    shutil.copytree(args.collection, work)
    scenes, written, missing = write_stand_ins(work)
    lp = os.environ.get("LIGHTPATH_BIN") or os.path.join(ROOT, "lp")
    print(f"{len(scenes)} top-level scenes; {len(written)} stand-ins written; "
          f"{len(set(missing))} named files without a stand-in", file=sys.stderr)
    for m in sorted(set(missing)):
        print(f"  no stand-in: {m}", file=sys.stderr)
    integrators = args.integrators.split(",")
    print("| scene | " + " | ".join(integrators) + " |")
    print("|---|" + "---|" * len(integrators))
    for scene in scenes:
        rel = os.path.relpath(scene, work)
        if args.only and not any(o in rel for o in args.only):
            continue
        cells = []
        for integrator in integrators:
            out = os.path.join(args.out, rel.replace("/", "_") + f"-{integrator}.exr")
            t0 = time.time()
            try:
                r = subprocess.run([lp, "render", scene, "--integrator", integrator, "--size",
                                    args.size, "--spp", args.spp, "-q", "-o", out],
                                   capture_output=True, text=True, timeout=args.timeout)
                ok, err = r.returncode == 0, r.stderr
            except subprocess.TimeoutExpired:
                ok, err = False, f"timed out after {args.timeout} s"
            dt = time.time() - t0
            if ok:
                cells.append(f"ok ({dt:.0f} s)")
            else:
                lines = err.splitlines()
                i = next((k for k, l in enumerate(lines) if l.startswith("error")), 0)
                first = " ".join(l.strip() for l in lines[i:i + 2]) if lines else "failed"
                cells.append("**" + first.replace("|", "/")[:240] + "**")
            print(f"{rel} {integrator}: {cells[-1]}", file=sys.stderr, flush=True)
        print(f"| {rel} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
