#!/usr/bin/env python3
"""BDPT (or MMLT) against the path tracer on every project and course scene, at small size.

For each scene, SEEDS independent renders per integrator; the image mean of each render
(per channel) gives a mean and a standard error per integrator, and the table reports,
for the channel with the largest |z|, the relative difference of the means and its
z-score (difference / combined standard error; with few seeds the standard errors are
rough, so |z| up to ~3 is noise). Exits non-zero when some |z| exceeds 4.
The path tracer runs with NEE + MIS; scenes with `maxdepth -1` run at MAXDEPTH for both
(BDPT caps -1 at 32 vertices and the path tracer at 1024, so they would differ slightly).

    scripts/bdpt-vs-pt.py                       # 64 pixels wide, 4 seeds
    WIDTH=48 SEEDS=6 PT_SPP=512 BDPT_SPP=128 scripts/bdpt-vs-pt.py
    ONLY=slab,two-lights SEEDS=12 scripts/bdpt-vs-pt.py   # scenes whose path has one of these
    INTEGRATOR=mmlt SEEDS=6 scripts/bdpt-vs-pt.py          # MMLT (BDPT_SPP mutations per
                                                           # pixel, MMLT_OPTS) instead of BDPT

Needs a release build (./lp builds one); uses $CARGO_TARGET_DIR like ./lp.
"""
import math
import os
import pathlib
import re
import subprocess
import sys
import tempfile

root = pathlib.Path(__file__).resolve().parent.parent
target = pathlib.Path(
    os.environ.get("CARGO_TARGET_DIR", pathlib.Path.home() / ".cache/lightpath/target")
)
binary = target / "release" / "lightpath"
WIDTH = int(os.environ.get("WIDTH", "64"))
SEEDS = int(os.environ.get("SEEDS", "4"))
PT_SPP = int(os.environ.get("PT_SPP", "256"))
BDPT_SPP = int(os.environ.get("BDPT_SPP", "64"))
MAXDEPTH = int(os.environ.get("MAXDEPTH", "8"))
ONLY = [w for w in os.environ.get("ONLY", "").split(",") if w]
OTHER = os.environ.get("INTEGRATOR", "bdpt")
OTHER_OPTS = os.environ.get(
    "MMLT_OPTS", "--mmlt-chains 512 --mmlt-bootstrap 8192" if OTHER == "mmlt" else ""
).split()


def scenes():
    out = sorted((root / "scenes").glob("*.test"))
    out += sorted((root / "scenes" / "course").rglob("*.test"))
    return [p for p in out if not ONLY or any(w in str(p) for w in ONLY)]


def setting(text, name):
    m = re.search(rf"^\s*{name}\s+(.+)$", text, re.M)
    return m.group(1).split() if m else None


def image_mean(path):
    out = subprocess.run(
        [binary, "compare", path, path], check=True, capture_output=True, text=True
    ).stdout
    m = re.search(r"mean A: (\S+) (\S+) (\S+)", out)
    return [float(v) for v in m.groups()]


def stats(values):
    n = len(values)
    mean = sum(values) / n
    var = sum((v - mean) ** 2 for v in values) / (n - 1)
    return mean, math.sqrt(var / n)


def main():
    if not binary.exists():
        sys.exit(f"{binary} not found: build with ./lp (or cargo build --release) first")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for scene in scenes():
            text = scene.read_text()
            size = setting(text, "size") or ["640", "480"]
            w, h = int(size[0]), int(size[1])
            height = max(1, round(WIDTH * h / w))
            depth = setting(text, "maxdepth")
            depth = int(depth[0]) if depth else 5
            if depth < 0:
                depth = MAXDEPTH
            # A copy with NEE + MIS for the path tracer (course scenes include no files).
            copy = tmp / scene.name
            copy.write_text(text + "\nnexteventestimation mis\n")
            means = {}
            for integrator, spp in (("pathtracer", PT_SPP), (OTHER, BDPT_SPP)):
                per_seed = []
                for seed in range(SEEDS):
                    img = tmp / f"{integrator}-{seed}.exr"
                    extra = OTHER_OPTS if integrator == OTHER else []
                    subprocess.run(
                        [binary, "render", copy, "-o", img, "-q", "--integrator", integrator,
                         "--size", f"{WIDTH}x{height}", "--spp", str(spp),
                         "--max-depth", str(depth), "--seed", str(seed + 1)] + extra,
                        check=True,
                    )
                    per_seed.append(image_mean(img))
                means[integrator] = [stats([m[c] for m in per_seed]) for c in range(3)]
            worst = None
            for c in range(3):
                (a, sa), (b, sb) = means[OTHER][c], means["pathtracer"][c]
                se = math.sqrt(sa * sa + sb * sb)
                z = (a - b) / se if se > 0 else 0.0
                rel = (a - b) / b if b != 0 else 0.0
                if worst is None or abs(z) > abs(worst[0]):
                    worst = (z, rel, a, b, "rgb"[c])
            name = scene.relative_to(root)
            rows.append((str(name), depth, worst))
            print(f"{name}: done", file=sys.stderr)
    o = OTHER.upper()
    print(f"| scene | maxdepth | channel | PT mean | {o} mean | {o}/PT − 1 | z |")
    print("|---|---|---|---|---|---|---|")
    for name, depth, (z, rel, a, b, channel) in rows:
        print(f"| {name} | {depth} | {channel} | {b:.4f} | {a:.4f} | {rel:+.2%} | {z:+.2f} |")
    bad = [r for r in rows if abs(r[2][0]) > 4.0]
    if bad:
        print(f"\n{len(bad)} scene(s) differ by more than 4 standard errors", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
