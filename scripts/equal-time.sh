#!/usr/bin/env bash
# Equal-time comparison of the integrators on the showcase scenes.
# For each scene: a long BDPT reference render, then TRIALS renders per integrator, each
# stopped after TIME seconds of rendering (--time-limit; MMLT's includes its bootstrap
# and chain starts), and their relMSE against the reference (lightpath compare: mean of
# (a-b)^2 / (b^2 + 0.01)). Prints a Markdown table.
#
#   scripts/equal-time.sh                  # 128x128, 20 s, 3 trials, 2048-spp reference
#   SIZE=64x64 TIME=5 REF_SPP=512 scripts/equal-time.sh
#   INTEGRATORS=mmlt MMLT_OPTS="--mmlt-chains 1024" scripts/equal-time.sh
#   SCENES="pbrt/volumetric-caustic.pbrt pbrt/smoke-grid.pbrt" scripts/equal-time.sh
#
# Output files go to $OUT (default /tmp/lightpath-equal-time); an existing reference is
# reused. The path tracer uses the scene's settings (NEE with MIS, BRDF sampling, RR).
# LIGHTPATH_BIN=path runs that binary instead of ./lp.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SIZE="${SIZE:-128x128}"
TIME="${TIME:-20}"
TRIALS="${TRIALS:-3}"
REF_SPP="${REF_SPP:-2048}"
SCENES="${SCENES:-cornell-occlusion cornell-slab}"
INTEGRATORS="${INTEGRATORS:-pathtracer bdpt mmlt}"
MMLT_OPTS="${MMLT_OPTS:-}"
OUT="${OUT:-/tmp/lightpath-equal-time}"
mkdir -p "$OUT"
# LIGHTPATH_BIN: a lightpath binary to use instead of ./lp (which rebuilds first).
lp() { if [ -n "${LIGHTPATH_BIN:-}" ]; then "$LIGHTPATH_BIN" "$@"; else "$root/lp" "$@"; fi; }

echo "| scene | integrator | time limit (s) | spp (mutations per pixel) reached | Msamples/s | relMSE (mean of $TRIALS) |"
echo "|---|---|---|---|---|---|"
for scene in $SCENES; do
  # A name (scenes/NAME.test) or a path under scenes/ with its extension (pbrt/x.pbrt).
  case "$scene" in
    *.test|*.pbrt) file="$root/scenes/$scene" ;;
    *) file="$root/scenes/$scene.test" ;;
  esac
  scene="$(basename "${scene%.*}")"
  ref="$OUT/$scene-ref-$SIZE.exr"
  if [ ! -f "$ref" ]; then
    lp render "$file" --integrator bdpt --size "$SIZE" --spp "$REF_SPP" \
      --seed 4242 -o "$ref" 2>"$OUT/$scene-ref.log"
  fi
  for integrator in $INTEGRATORS; do
    sum=0; spp=0; rate=0
    opts=()
    if [ "$integrator" = mmlt ]; then read -r -a opts <<<"$MMLT_OPTS"; fi
    for trial in $(seq 1 "$TRIALS"); do
      img="$OUT/$scene-$integrator-$trial.exr"
      log="$OUT/$scene-$integrator-$trial.log"
      lp render "$file" --integrator "$integrator" --size "$SIZE" \
        --spp 1000000 --time-limit "$TIME" --seed "$trial" -o "$img" "${opts[@]}" 2>"$log"
      line=$(grep -E " spp, .* Msamples/s" "$log")
      spp=$(echo "$line" | sed -E 's/.* ([0-9]+) spp,.*/\1/')
      rate=$(echo "$line" | sed -E 's/.*, ([0-9.]+) Msamples\/s.*/\1/')
      rel=$(lp compare "$img" "$ref" | sed -n 's/^relMSE: //p')
      sum=$(python3 -c "print($sum + $rel)")
    done
    mean=$(python3 -c "print(f'{$sum / $TRIALS:.5f}')")
    echo "| $scene | $integrator | $TIME | $spp | $rate | $mean |"
  done
done
