#!/usr/bin/env bash
# Renders a fixed matrix of scenes × integrators × backends with a fixed seed and writes
# the SHA-256 of each image's pixels to DIR/hashes, so that a restructuring can show it
# changed no image (docs/testing.md, "Images before and after").
#   scripts/image-hashes.sh BIN DIR     (BIN: a lightpath binary)
# Needs Python 3; the EXR reader (OpenEXR, numpy) goes into a virtual environment under
# $CARGO_TARGET_DIR's parent (default ~/.cache/lightpath/venv-hashes).
set -euo pipefail
bin=$(realpath "$1"); out=$(realpath -m "$2"); mkdir -p "$out"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${LIGHTPATH_HASH_VENV:-$HOME/.cache/lightpath/venv-hashes}"
[ -x "$venv/bin/python" ] || { python3 -m venv "$venv" && "$venv/bin/pip" install -q OpenEXR numpy; }
cd "$root"
scenes="scenes/cornell-box.test scenes/course/hw4/cornellBRDF.test scenes/course/hw4/ggx.test scenes/course/hw2/sphere.test scenes/two-lights.test"
: > "$out/log"
for s in $scenes; do
  n=$(basename "$s" .test)
  for accel in cwbvh bvh2 rayquery; do
    for integ in pathtracer direct analyticdirect bdpt mmlt; do
      extra=()
      [ "$integ" = bdpt ] && extra=(--bdpt-strategies "$out/$n.$integ.$accel.st")
      [ "$integ" = mmlt ] && extra=(--mmlt-bootstrap 2000 --mmlt-chains 256 --mmlt-depths "$out/$n.$integ.$accel.d")
      "$bin" render "$s" --seed 7 --size 24x16 --spp 4 --max-depth 4 --integrator "$integ" \
        --accel "$accel" -q -o "$out/$n.$integ.$accel.exr" "${extra[@]}" 2>>"$out/log" \
        || echo "FAIL $n $integ $accel" >>"$out/log"
    done
  done
done
for integ in pathtracer bdpt mmlt; do
  "$bin" render scenes/course/hw4/cornellBRDF.test --seed 3 --size 16x16 --spp 2 --max-depth -1 \
    --integrator "$integ" --accel cwbvh -q -o "$out/unb.$integ.exr" --mmlt-bootstrap 1000 \
    --mmlt-chains 64 2>>"$out/log" || echo "FAIL unb $integ" >>"$out/log"
done
# Every material class, texture and light in one box (written here, with its two
# images), under each NEE mode, Russian roulette and unbounded depth.
f="$out/features"; mkdir -p "$f"
"$venv/bin/python" - "$f" <<'PY'
import math, os, struct, sys
d = sys.argv[1]
def pfm(name, w, h, fn):
    with open(os.path.join(d, name), "wb") as o:
        o.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        for y in range(h):
            for x in range(w):
                o.write(struct.pack("<3f", *fn(x, y)))
pfm("env.pfm", 32, 16, lambda x, y: (0.2 + 2.0 * (x == 5 and y == 10), 0.3 + 0.5 * y / 16, 0.5 + 0.3 * math.sin(x)))
pfm("rough.pfm", 8, 8, lambda x, y: ((x + y) % 4 * 0.1 + 0.02,) * 3)
PY
cat > "$f/features.test" <<'EOF'
size 24 16
camera 0 1 3.2 0 1 0 0 1 0 50
maxdepth 6
importancesampling brdf
brdf phong
diffuse 0.7 0.7 0.7
vertex -1 0 -1
vertex 1 0 -1
vertex 1 0 1
vertex -1 0 1
vertex -1 2 -1
vertex 1 2 -1
vertex 1 2 1
vertex -1 2 1
checkerboard 0.8 0.8 0.8 0.2 0.3 0.2 4 4
tri 0 2 1
tri 0 3 2
texture none
diffuse 0.6 0.2 0.2
tri 0 4 7
tri 0 7 3
brdf ggx
diffuse 0.2 0.6 0.2
specular 0.2 0.2 0.2
roughness 0.3
tri 1 2 6
tri 1 6 5
roughnesstexture rough.pfm linear
brdf phong
diffuse 0.5 0.5 0.5
specular 0.3 0.3 0.3
shininess 20
tri 0 1 5
tri 0 5 4
roughnesstexture none
brdf dielectric
ior 1.5
roughness 0
sphere -0.5 0.35 0 0.3
roughness 0.2
sphere 0.1 0.3 0.4 0.25
brdf conductor
roughness 0
sphere 0.5 0.3 -0.3 0.25
roughness 0.15 0.3
sphere 0.5 0.9 -0.5 0.2
brdf coateddiffuse
diffuse 0.2 0.4 0.7
roughness 0.1
sphere -0.3 1.1 -0.5 0.3
brdf thindielectric
vertex -0.9 0.1 0.7
vertex -0.4 0.1 0.7
vertex -0.4 0.8 0.7
tri 8 9 10
brdf phong
diffuse 0 0 0
emission 3 3 2.5
sphere 0.7 1.6 0.3 0.1
emission 0 0 0
quadLight -0.3 1.99 -0.3 0.6 0 0 0 0 0.6 4 4 4
point -0.6 1.5 0.5 0.5 0.4 0.3
spot 0.6 1.8 0.6 0 0 0 2 2 2 30 5
directional 1 1 1 0.1 0.1 0.1
envmap env.pfm 0.5
EOF
for v in "off off 6" "on off 6" "mis off 6" "mis on 6" "mis on -1"; do
  set -- $v
  sed "s/^maxdepth 6/maxdepth $3\nnexteventestimation $1\nrussianroulette $2/" "$f/features.test" > "$f/f-$1-$2-$3.test"
  for accel in cwbvh rayquery; do
    for integ in pathtracer bdpt mmlt; do
      if [ "$integ" != pathtracer ] && [ "$1" != mis ]; then continue; fi
      "$bin" render "$f/f-$1-$2-$3.test" --seed 5 --spp 4 --integrator "$integ" --accel "$accel" \
        --mmlt-bootstrap 2000 --mmlt-chains 256 -q -o "$f/f-$1-$2-$3.$integ.$accel.exr" 2>>"$out/log" \
        || echo "FAIL features $v $integ $accel" >>"$out/log"
    done
  done
done
"$venv/bin/python" - "$out" <<'PY' > "$out/hashes"
import glob, hashlib, os, sys
import numpy as np, OpenEXR
out = sys.argv[1]
for path in sorted(glob.glob(os.path.join(out, "**", "*.exr"), recursive=True)):
    with OpenEXR.File(path) as f:
        h = hashlib.sha256()
        for name, ch in sorted(f.channels().items()):
            h.update(name.encode())
            h.update(np.ascontiguousarray(ch.pixels).tobytes())
    print(h.hexdigest(), os.path.relpath(path, out))
PY
echo "$(wc -l < "$out/hashes") images hashed in $out/hashes" >&2
