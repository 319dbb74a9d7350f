#!/usr/bin/env bash
# Run a command starved of CPU, the way docs/ros.md "Starvation and stalls" measured ceco run (issue 17).
#
#   tools/cpu_starved.sh QUOTA_US NLOOPS NICE -- COMMAND...
#   tools/cpu_starved.sh 50000 2 -10 -- ceco run --scenario sc03 --strategy all --out /tmp/starved
#
# COMMAND and its children run in a cgroup-v1 `cpu` group capped at QUOTA_US of CPU time per 100 ms
# (50000: half a CPU), beside NLOOPS busy loops at nice NICE in the same group (-10: each loop weighs
# about 9 times a nice-0 process), so the run's processes get a few per cent of a CPU while the rest
# of the machine is left alone. Needs root and /sys/fs/cgroup/cpu (cgroup v1); the group is removed
# at the end. Exit status: COMMAND's.
set -euo pipefail
if [ $# -lt 5 ] || [ "$4" != "--" ]; then
  echo "usage: $0 QUOTA_US NLOOPS NICE -- COMMAND..." >&2
  exit 2
fi
quota=$1 nloops=$2 nice=$3
shift 4
root=/sys/fs/cgroup/cpu
[ -w "$root" ] || { echo "cpu_starved: $root not writable (needs root and cgroup v1)" >&2; exit 2; }
cg=$root/ceco_starved_$$
mkdir "$cg"
loops=()
cleanup() {
  [ ${#loops[@]} -eq 0 ] || kill "${loops[@]}" 2>/dev/null || true
  wait "${loops[@]}" 2>/dev/null || true
  echo $$ > "$root/cgroup.procs"
  rmdir "$cg" 2>/dev/null || true
}
trap cleanup EXIT
echo 100000 > "$cg/cpu.cfs_period_us"
echo "$quota" > "$cg/cpu.cfs_quota_us"
echo $$ > "$cg/cgroup.procs"
for _ in $(seq "$nloops"); do
  nice -n "$nice" bash -c 'while :; do :; done' &
  loops+=($!)
done
set +e
"$@"
rc=$?
exit $rc
