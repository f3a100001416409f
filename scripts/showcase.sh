#!/usr/bin/env bash
# The showcase: the Phong Cornell box (the course's hw4/cornellBRDF.test, the original
# project's showcase), cornell-occlusion, cornell-slab, caustic (light focused through a
# glass sphere), glass-window (a room lit only through a pane of thin glass) and two
# scenes in media (pbrt/volumetric-caustic.pbrt: a glass ball in fog focusing a small
# light; pbrt/hazy-door.pbrt: light through a door ajar into a hazy room), each
# rendered by the path tracer, BDPT and MMLT for the same TIME seconds, composed into one
# labelled PNG grid (rows: scenes; columns: integrators) so that one sees at a glance
# that the three converge to one image and which is least noisy.
#
#   scripts/showcase.sh                        # 160x160, 30 s per image -> showcase.png
#   SIZE=96x96 TIME=5 OUTPUT=/tmp/grid.png scripts/showcase.sh
#
# Needs Python's Pillow for the grid (installed with pip --user when missing).
# LIGHTPATH_BIN=path runs that binary instead of ./lp.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SIZE="${SIZE:-160x160}"
TIME="${TIME:-30}"
OUTPUT="${OUTPUT:-showcase.png}"
WORK="${WORK:-/tmp/lightpath-showcase}"
mkdir -p "$WORK"
lp() { if [ -n "${LIGHTPATH_BIN:-}" ]; then "$LIGHTPATH_BIN" "$@"; else "$root/lp" "$@"; fi; }
python3 -c "import PIL" 2>/dev/null || pip install --user --quiet pillow

scenes=("$root/scenes/course/hw4/cornellBRDF.test" "$root/scenes/cornell-occlusion.test" "$root/scenes/cornell-slab.test"
        "$root/scenes/caustic.test" "$root/scenes/glass-window.test"
        "$root/scenes/pbrt/volumetric-caustic.pbrt" "$root/scenes/pbrt/hazy-door.pbrt")
integrators=(pathtracer bdpt mmlt)
args=()
for scene in "${scenes[@]}"; do
  name="$(basename "$scene")"; name="${name%.*}"
  for integrator in "${integrators[@]}"; do
    png="$WORK/$name-$integrator.png"
    log="$WORK/$name-$integrator.log"
    lp render "$scene" --integrator "$integrator" --size "$SIZE" --spp 1000000 \
      --time-limit "$TIME" --seed 1 -o "$png" 2>"$log"
    spp=$(grep -E " spp, " "$log" | sed -E 's/.* ([0-9]+) spp,.*/\1/')
    unit=spp; [ "$integrator" = mmlt ] && unit="mutations/px"
    args+=("$png" "$name" "$integrator, ${TIME} s: $spp $unit")
  done
done

python3 - "$OUTPUT" "${#integrators[@]}" "${args[@]}" <<'PY'
import sys
from PIL import Image, ImageDraw, ImageFont
out, cols, rest = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
cells = [(rest[i], rest[i + 1] + "\n" + rest[i + 2]) for i in range(0, len(rest), 3)]
images = [Image.open(p).convert("RGB") for p, _ in cells]
w, h = images[0].size
label = 32
rows = (len(images) + cols - 1) // cols
grid = Image.new("RGB", (cols * w, rows * (h + label)), "white")
draw = ImageDraw.Draw(grid)
try:
    font = ImageFont.load_default(size=11)
except TypeError:
    font = ImageFont.load_default()
for i, (img, (_, text)) in enumerate(zip(images, cells)):
    x, y = (i % cols) * w, (i // cols) * (h + label)
    grid.paste(img, (x, y + label))
    draw.multiline_text((x + 4, y + 2), text, fill="black", font=font, spacing=2)
grid.save(out)
print(f"wrote {out}: {rows} scenes x {cols} integrators, {w}x{h} each")
PY
