#!/usr/bin/env bash
# Render a scene on a Slurm cluster as seed-split parts and merge them into one image:
# a job array of TASKS renders (task i renders with seed FIRST_SEED + i - 1) and a merge
# job that runs once every task has succeeded (--dependency=afterok).
#
#   scripts/slurm-render.sh SCENE TASKS [render options...]
#   SBATCH_OPTS="--partition=gpu --gres=gpu:1 --time=04:00:00" \
#     OUTPUT=/shared/out/cornell.exr scripts/slurm-render.sh scenes/cornell-box.test 16 --spp 256
#
# Environment:
#   OUTPUT        the merged image (default: SCENE's name + "-merged.exr", here)
#   WORKDIR       where the parts and logs go (default: slurm-NAME-TIMESTAMP, here);
#                 it, the scene and the binary must be on a filesystem every node sees
#   LIGHTPATH_BIN the lightpath binary (default: built here with ./lp)
#   SBATCH_OPTS   extra sbatch options for both jobs (partition, GPUs, time limits...)
#   FIRST_SEED    the first task's seed (default 1; use another range to add parts later)
# Prints the two job ids; `squeue -u $USER` follows them.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ $# -lt 2 ]; then
  echo "usage: $0 SCENE TASKS [render options...]" >&2
  exit 2
fi
scene="$(realpath "$1")"
tasks="$2"
shift 2
case "$tasks" in
  '' | *[!0-9]* | 0) echo "TASKS must be a positive number, got '$tasks'" >&2; exit 2 ;;
esac
[ -f "$scene" ] || { echo "no scene file $scene" >&2; exit 2; }
name="$(basename "$scene" .test)"
work="$(realpath -m "${WORKDIR:-slurm-$name-$(date +%Y%m%d-%H%M%S)}")"
output="$(realpath -m "${OUTPUT:-$name-merged.exr}")"
first="${FIRST_SEED:-1}"
if [ -z "${LIGHTPATH_BIN:-}" ]; then
  "$root/lp" devices >/dev/null   # builds the binary (and installs what it needs)
  LIGHTPATH_BIN="${CARGO_TARGET_DIR:-$HOME/.cache/lightpath/target}/release/lightpath"
fi
bin="$(realpath "$LIGHTPATH_BIN")"
mkdir -p "$work"
read -r -a sbatch_opts <<<"${SBATCH_OPTS:-}"
# The render options, quoted for the job's shell.
opts="$(printf '%q ' "$@")"

array=$(sbatch --parsable "${sbatch_opts[@]}" --job-name="lightpath-$name" \
  --array="1-$tasks" --output="$work/render-%a.log" \
  --wrap="exec $(printf '%q' "$bin") render $(printf '%q' "$scene") -q \
    --seed \$(( $first + SLURM_ARRAY_TASK_ID - 1 )) \
    -o $(printf '%q' "$work")/part-\$SLURM_ARRAY_TASK_ID.exr $opts")
array="${array%%;*}"
merge=$(sbatch --parsable "${sbatch_opts[@]}" --job-name="lightpath-$name-merge" \
  --dependency="afterok:$array" --output="$work/merge.log" \
  --wrap="exec $(printf '%q' "$bin") merge $(printf '%q' "$output") $(printf '%q' "$work")/part-*.exr")
merge="${merge%%;*}"
echo "render array $array ($tasks tasks, seeds $first..$((first + tasks - 1))) -> $work"
echo "merge job $merge (after all of them) -> $output"
