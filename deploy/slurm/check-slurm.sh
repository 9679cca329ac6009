#!/usr/bin/env bash
# sirad: runs deploy/slurm/sirad.sbatch on a real Slurm on this machine (the Deploy.SlurmRuns
# test): munged, slurmctld and slurmd started here with a configuration of their own (one node,
# 4 CPUs, proctrack/linuxproc, task/none, select/cons_tres; their own ports and folders), the
# programs installed from BUILD_DIR into a temporary prefix (cmake --install), then
#   sbatch --wait -n 3 sirad.sbatch cornell ...
# must end with the images in the submit directory, a status counting every bundle on 2 nodes,
# and no keys left behind. The daemons are stopped at the end. As root; exits 77 (skipped)
# where Slurm or munge is not installed or this is not root.
#   deploy/slurm/check-slurm.sh BUILD_DIR
set -euo pipefail
build=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
skip() { echo "check-slurm: skipped: $*" >&2; exit 77; }
fail() { echo "check-slurm: $*" >&2; for f in "$tmp"/*.log "$tmp"/submit/*.log; do [[ -f $f ]] && { echo "== $f" >&2; tail -20 "$f" >&2; }; done; exit 1; }
[[ $(id -u) -eq 0 ]] || skip "needs root (slurmd and munged run as root here)"
for p in munged slurmctld slurmd sbatch srun scontrol sinfo; do
  command -v $p >/dev/null || skip "$p is not installed (apt-get install slurm-wlm munge)"
done

tmp=$(mktemp -d /tmp/sirad-slurm.XXXXXX)
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for ((i = 0; i < 100; i++)); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
  rm -rf "$tmp"
}
trap cleanup EXIT
free_port() { /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

# The programs, as a farm machine installs them.
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null

# munge, on its own socket and key.
mkdir -m 700 "$tmp/munge"
dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge/munge.key"
munged --foreground --force --socket="$tmp/munge/socket" --key-file="$tmp/munge/munge.key" \
  --pid-file="$tmp/munge/pid" --seed-file="$tmp/munge/seed" --log-file="$tmp/munged.log" >"$tmp/munged.out" 2>&1 &
pids+=($!)

host=$(hostname -s)
mkdir -p "$tmp/state" "$tmp/spool" "$tmp/submit"
cat >"$tmp/slurm.conf" <<CONF
ClusterName=siradcheck
SlurmctldHost=$host
SlurmUser=root
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
AuthType=auth/munge
AuthInfo=socket=$tmp/munge/socket
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SlurmdParameters=config_overrides
NodeName=$host CPUs=4 State=UNKNOWN
PartitionName=check Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$tmp/slurm.conf
# munged is up when its socket is there.
for ((i = 0; i < 100; i++)); do [[ -S $tmp/munge/socket ]] && break; sleep 0.1; done
[[ -S $tmp/munge/socket ]] || fail "munged did not start"
slurmctld -D -i -f "$SLURM_CONF" >"$tmp/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" >"$tmp/slurmd.out" 2>&1 &
pids+=($!)
# Slurm is up when the node is idle (a minute at most).
for ((i = 0; i < 600; i++)); do
  [[ $(sinfo -h -n "$host" -o %t 2>/dev/null) == idle ]] && break
  for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null || fail "a daemon exited while starting"; done
  sleep 0.1
done
[[ $(sinfo -h -n "$host" -o %t 2>/dev/null) == idle ]] || fail "the Slurm node did not come up: $(sinfo 2>&1)"

cd "$tmp/submit"
SIRAD_BIN=$tmp/prefix/bin POCL_CACHE_DIR=${POCL_CACHE_DIR:-$tmp/pocl} timeout 600 \
  sbatch --wait -n 3 "$here/sirad.sbatch" cornell --patches 500 --bundles 96 --exchange-every 16 --width 32 --height 32 \
  >"$tmp/sbatch.out" 2>&1 || fail "sbatch failed: $(cat "$tmp/sbatch.out")"
job=$(sed -n 's/^Submitted batch job \([0-9]*\).*/\1/p' "$tmp/sbatch.out")
[[ -n $job ]] || fail "no job id: $(cat "$tmp/sbatch.out")"
for ext in exr png ply glb; do [[ -s cornell-$job.$ext ]] || fail "no cornell-$job.$ext in the submit directory"; done
status=sirad-$job.status.json
[[ -s $status ]] || fail "no $status"
/usr/bin/python3 - "$status" <<'PY' || fail "the status of the job is wrong: $(cat "$status")"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["bundles_done"] == 96, s["bundles_done"]
worked = [n for n in s["nodes"] if n["bundles"] > 0]
assert len(worked) == 2, s["nodes"]
PY
[[ ! -e .sirad-$job ]] || fail "the job's keys were left in .sirad-$job"
echo "== the job's log"; cat "sirad-$job.log"
# A flag the script owns is refused, in the job's log, and the job fails.
if sbatch --wait -n 2 "$here/sirad.sbatch" cornell --listen 'tcp://*:1' >"$tmp/refused.out" 2>&1; then
  fail "a job with --listen was not refused"
fi
refused=$(sed -n 's/^Submitted batch job \([0-9]*\).*/\1/p' "$tmp/refused.out")
grep -q -- "--listen is set by this script" "sirad-$refused.log" || fail "the refusal is not in the job's log: $(cat "sirad-$refused.log")"
# The farm as a Slurm job: its queue in a folder the submitter shares, a job submitted to it
# with the installed `sirad submit` runs on its 2 nodes, and scancel stops it cleanly.
SIRAD_BIN=$tmp/prefix/bin SIRAD_HTTP=127.0.0.1:0 POCL_CACHE_DIR=${POCL_CACHE_DIR:-$tmp/pocl} \
  sbatch -n 3 "$here/sirad.sbatch" --serve "$tmp/farm" >"$tmp/farm.out" 2>&1 || fail "sbatch --serve failed: $(cat "$tmp/farm.out")"
farm_job=$(sed -n 's/^Submitted batch job \([0-9]*\).*/\1/p' "$tmp/farm.out")
[[ -n $farm_job ]] || fail "no job id: $(cat "$tmp/farm.out")"
for ((i = 0; i < 3000; i++)); do [[ ! -s $tmp/farm/http ]] || break; sleep 0.1; done
[[ -s $tmp/farm/http ]] || fail "the farm job did not serve in 300 s: $(cat "sirad-$farm_job.log" 2>&1)"
"$tmp/prefix/bin/sirad" submit cornell --farm "$tmp/farm" --name slurmjob --patches 500 --bundles 64 --width 32 --height 32 \
  >/dev/null || fail "sirad submit to the Slurm farm failed"
for ((i = 0; i < 3000; i++)); do
  state=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["state"])' "$tmp/farm/jobs/1/job.json" 2>/dev/null || true)
  [[ $state != done && $state != failed ]] || break
  sleep 0.1
done
[[ $state == done ]] || fail "the farm's job ended '$state' (not done in 300 s): $(cat "sirad-$farm_job.log")"
[[ -s $tmp/farm/jobs/1/slurmjob.png ]] || fail "the farm's job wrote no image"
/usr/bin/python3 - "$tmp/farm/jobs/1/status.json" <<'PY' || fail "the farm job's status is wrong: $(cat "$tmp/farm/jobs/1/status.json")"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["bundles_done"] == 64, s["bundles_done"]
assert len([n for n in s["nodes"] if n["bundles"] > 0]) >= 1, s["nodes"]
PY
scancel "$farm_job"
for ((i = 0; i < 600; i++)); do [[ -n $(squeue -h -j "$farm_job" 2>/dev/null) ]] || break; sleep 0.1; done
[[ -z $(squeue -h -j "$farm_job" 2>/dev/null) ]] || fail "the farm job did not end in 60 s after scancel"
[[ ! -e .sirad-$farm_job ]] || fail "the farm job's keys were left in .sirad-$farm_job"
echo "check-slurm: ok: job $job ran a coordinator and 2 nodes, job $farm_job served a farm, under Slurm ($(sinfo -V))"
