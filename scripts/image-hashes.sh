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
