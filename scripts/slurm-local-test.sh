#!/usr/bin/env bash
# A real Slurm run on this one machine: installs Debian's Slurm (slurmctld, slurmd) and
# munge when missing, configures a one-node cluster, starts the daemons, renders a
# scene through scripts/slurm-render.sh as a 4-task job array with a dependent merge
# job, and checks the merged image (4 × the samples, seeds 1..4, statistically the
# scene). Needs root; not part of ./lp test. Works from a fresh clone.
#
#   scripts/slurm-local-test.sh            # SCENE=scenes/cornell-box.test, 4 tasks
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SCENE="${SCENE:-$root/scenes/cornell-box.test}"
TASKS="${TASKS:-4}"
SPP="${SPP:-16}"
if [ "$(id -u)" != 0 ]; then echo "run as root (it installs and starts daemons)" >&2; exit 2; fi

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurm-wlm munge >/dev/null
fi

# munge: the key and the daemon.
mkdir -p /run/munge /var/log/munge /var/lib/munge
[ -s /etc/munge/munge.key ] || dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
chown -R munge:munge /etc/munge /run/munge /var/log/munge /var/lib/munge
chmod 400 /etc/munge/munge.key
pgrep -x munged >/dev/null || runuser -u munge -- /usr/sbin/munged
munge -n | unmunge >/dev/null

# A one-node cluster.
host="$(hostname -s)"
cpus="$(nproc)"
mkdir -p /etc/slurm /var/spool/slurmctld /var/spool/slurmd /var/log/slurm
chown slurm:slurm /var/spool/slurmctld /var/log/slurm
cat > /etc/slurm/slurm.conf <<CONF
ClusterName=lightpath-local
SlurmctldHost=$host
AuthType=auth/munge
SlurmUser=slurm
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
NodeName=$host CPUs=$cpus State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
pgrep -x slurmctld >/dev/null || slurmctld
pgrep -x slurmd >/dev/null || slurmd
for _ in $(seq 60); do
  sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
  sleep 1
done
sinfo

# The render, through the same script a real cluster would use.
work="$(mktemp -d /tmp/lightpath-slurm.XXXXXX)"
"$root/lp" devices >/dev/null
bin="${CARGO_TARGET_DIR:-$HOME/.cache/lightpath/target}/release/lightpath"
LIGHTPATH_BIN="$bin" WORKDIR="$work/parts" OUTPUT="$work/merged.exr" \
  "$root/scripts/slurm-render.sh" "$SCENE" "$TASKS" --size 64x64 --spp "$SPP" | tee "$work/submit.txt"
merge_job="$(sed -n 's/^merge job \([0-9]*\).*/\1/p' "$work/submit.txt")"
for _ in $(seq 600); do
  squeue -h -j "$merge_job" 2>/dev/null | grep -q . || break
  sleep 1
done
squeue
ls -l "$work/parts"
cat "$work/parts/merge.log"
[ -f "$work/merged.exr" ] || { echo "FAILED: no merged image" >&2; exit 1; }

# Checks: the merged image has every task's samples and seed, and matches one render of
# as many samples within the noise.
"$bin" render "$SCENE" --size 64x64 --spp $((SPP * TASKS)) --seed 1000 -o "$work/single.exr" -q
"$bin" compare "$work/merged.exr" "$work/single.exr" | tee "$work/compare.txt"
grep -q "A: .* $((SPP * TASKS)) spp, seed $(seq -s, 1 "$TASKS")," "$work/compare.txt" ||
  { echo "FAILED: the merged image does not record $((SPP * TASKS)) spp and seeds 1..$TASKS" >&2; exit 1; }
python3 - "$work/compare.txt" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
a = [float(v) for v in re.search(r"mean A: (\S+) (\S+) (\S+)", t).groups()]
b = [float(v) for v in re.search(r"mean B: (\S+) (\S+) (\S+)", t).groups()]
worst = max(abs(x / y - 1) for x, y in zip(a, b))
print(f"merged vs single render: image means differ by at most {worst:.2%}")
sys.exit(0 if worst < 0.02 else 1)
PY
echo "OK: $TASKS Slurm tasks merged into $work/merged.exr"
