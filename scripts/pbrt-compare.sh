#!/usr/bin/env bash
# Renders pbrt-v4 scenes with lightpath and compares each with pbrt-v4's own image of it
# (docs/pbrt.md, "Side by side with pbrt-v4"): both images' means per channel, their
# ratio, and the relMSE of lightpath's image against pbrt-v4's.
#   scripts/pbrt-compare.sh BIN PBRT_DIR OUT [SPP] [INTEGRATOR] [SCENE...]
# BIN: a lightpath binary. PBRT_DIR: NAME.exr for each scene NAME.pbrt, rendered by a
# pbrt-v4 of your own, outside the repository (from the scene's directory:
# `pbrt --spp 1024 --outfile PBRT_DIR/NAME.exr NAME.pbrt`). OUT: lightpath's images.
# SPP: lightpath's samples per pixel (default 1024); INTEGRATOR: pathtracer (default),
# bdpt or mmlt. SCENE: .pbrt files (default: scenes/pbrt/compare/*.pbrt, the Cornell box
# and the every-feature box).
set -euo pipefail
bin=$(realpath "$1"); pbrt_dir=$(realpath "$2"); out=$(realpath -m "$3"); mkdir -p "$out"
spp=${4:-1024}; integ=${5:-pathtracer}
shift $(( $# < 5 ? $# : 5 ))
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/pbrt/compare/*.pbrt scenes/pbrt/cornell-box.pbrt scenes/pbrt/every-feature.pbrt)
printf '%-22s %-26s %-26s %-20s %s\n' scene "pbrt-v4 mean (R G B)" "lightpath mean" "lightpath / pbrt" relMSE
for s in "${scenes[@]}"; do
  n=$(basename "$s" .pbrt)
  ref="$pbrt_dir/$n.exr"
  if [ ! -f "$ref" ]; then echo "$n: no $ref"; continue; fi
  "$bin" render "$s" --spp "$spp" --integrator "$integ" -q -o "$out/$n.$integ.exr"
  "$bin" compare "$out/$n.$integ.exr" "$ref" | awk -v n="$n" '
    /^mean A:/ {a1=$3; a2=$4; a3=$5}
    /^mean B:/ {b1=$3; b2=$4; b3=$5}
    /^relMSE:/ {r=$2}
    END {printf "%-22s %8.4f %8.4f %8.4f %8.4f %8.4f %8.4f   %6.3f %6.3f %6.3f   %s\n",
         n, b1, b2, b3, a1, a2, a3, a1/b1, a2/b2, a3/b3, r}'
done
