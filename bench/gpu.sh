#!/bin/bash
# sirad bench: the one-command GPU check (issue 37). Builds nothing: runs the programs of BUILD
# (default: ./build) on every OpenCL device it finds and prints CSV on stdout, in under 5 minutes
# on a machine of 16 cores and one GPU.
#   bench/gpu.sh [BUILD]
# BUILD holds sirad, sirad-node, sirad-coordinator and bench/sirad_bench_bundle; where BUILD/lib
# exists (bench/gpu-pack.sh makes such a folder: the programs and the libraries they need, for
# a machine that has none of them) it goes first on LD_LIBRARY_PATH.
# Rows: section,device,path,patches,grid,value,unit
#   bundle   sirad_bench_bundle on the Cornell box, both transfer paths: 20k patches at grids 256
#            to 2048, one bundle a launch and 16 (path wide-x16), then 100k and 1M patches at
#            their auto grids (engine alone, and a whole solver step): ms per bundle (median)
#            and crossings/s
#   solve    `sirad render cornell --patches 100000 --target-error 0.01` on the device (its own
#            path), at most SOLVE_SECONDS (default 60): bundles, seconds, the error estimate
#   cluster  a coordinator on loopback TCP with one node on the first GPU and one on the first
#            CPU device, after each of them alone, CLUSTER_SECONDS (default 25) each: bundles/s,
#            and the pair's share of the two alone (target 0.9). Skipped without both kinds.
# Sections can be left out: SECTIONS (default "bundle solve cluster"). QUICK=1 shrinks every
# size and time (for the test that keeps this script working: tests/CMakeLists.txt).
set -uo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
BUILD=$(cd "${1:-$HERE/../build}" && pwd) || { echo "bench/gpu.sh: no build folder ${1:-$HERE/../build}" >&2; exit 1; }
[ -d "$BUILD/lib" ] && export LD_LIBRARY_PATH="$BUILD/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# The packed ICD files (NVIDIA's by name) where the machine registers none of its own.
compgen -G "/etc/OpenCL/vendors/*.icd" >/dev/null || { [ -d "$BUILD/vendors" ] && export OCL_ICD_VENDORS="$BUILD/vendors"; }
SIRAD=$BUILD/sirad BENCH=$BUILD/bench/sirad_bench_bundle
[ -x "$BENCH" ] || BENCH=$BUILD/sirad_bench_bundle
for p in "$SIRAD" "$BUILD/sirad-node" "$BUILD/sirad-coordinator" "$BENCH"; do
  [ -x "$p" ] || { echo "bench/gpu.sh: missing $p (build first, or bench/gpu-pack.sh)" >&2; exit 1; }
done
SOLVE_SECONDS=${SOLVE_SECONDS:-60} CLUSTER_SECONDS=${CLUSTER_SECONDS:-25}
PATCHES=20000 GRIDS=256,512,1024,2048 AUTO=100000,1000000 SOLVE_PATCHES=100000 CLUSTER_PATCHES=100000
if [ -n "${QUICK:-}" ]; then
  PATCHES=2000 GRIDS=64,128 AUTO=5000 SOLVE_PATCHES=3000 CLUSTER_PATCHES=3000 SOLVE_SECONDS=2 CLUSTER_SECONDS=2
fi
WORK=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; rm -rf "$WORK"' EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$WORK/pocl-cache}

# The devices as `sirad devices` lists them: "P:D  platform / device  (...)".
mapfile -t DEVICES < <("$SIRAD" devices 2>/dev/null | grep -E '^[0-9]+:[0-9]+ ')
[ ${#DEVICES[@]} -gt 0 ] || { echo "bench/gpu.sh: no OpenCL device ($SIRAD devices)" >&2; exit 1; }
is_cpu() { [[ "$1" =~ Portable\ Computing\ Language.*(pthread|cpu|CPU) || "$1" =~ CPU ]]; }
gpu="" cpu=""
echo "section,device,path,patches,grid,value,unit"
for line in "${DEVICES[@]}"; do
  id=${line%% *}
  name=$(echo "${line#* }" | sed 's/^ *//; s/  (.*//; s/,/;/g')
  echo "# device $id: $name" >&2
  if is_cpu "$line"; then [ -z "$cpu" ] && cpu=$id; else [ -z "$gpu" ] && gpu=$id; fi

  # bundle: both paths, CSV rows engine,grid,patches,ms_median,crossings_per_s,ms_min,cpu_ms.
  [[ " ${SECTIONS:-bundle solve cluster} " == *" bundle "* ]] && "$BENCH" --device "$id" --paths band,wide --batches 1,16 --patches $PATCHES --grids $GRIDS --bundles 32 \
      --reference-bundles 0 --error-bundles 0 --auto-patches $AUTO 2>"$WORK/bench.err" |
    awk -F, -v dev="$name" 'NF == 7 && $1 ~ /-(band|wide)(-x[0-9]+)?$/ {
        what = substr($1, 1, index($1, "-") - 1); path = substr($1, index($1, "-") + 1)
        printf "bundle,%s,%s,%s,%s,%s,ms_per_bundle_%s\n", dev, path, $3, $2, $4, what
        if ($5 > 0) printf "bundle,%s,%s,%s,%s,%s,crossings_per_s_%s\n", dev, path, $3, $2, $5, what }'
  grep -is "error" "$WORK/bench.err" >&2

  # solve: to 1 % (or the time limit) on this device's own path.
  [[ " ${SECTIONS:-bundle solve cluster} " == *" solve "* ]] || continue
  "$SIRAD" render cornell --patches $SOLVE_PATCHES --target-error 0.01 --time-limit "$SOLVE_SECONDS" --device "$id" \
      --width 64 --height 64 --out "$WORK/solve" >"$WORK/solve.out" 2>&1
  awk -v dev="$name" '/^patches [0-9]+, bundles/ {
      gsub(",", ""); for (i = 1; i < NF; ++i) { if ($i == "patches") p = $(i + 1); if ($i == "bundles") b = $(i + 1);
        if ($i == "grid") g = $(i + 1); if ($(i + 1) == "s") s = $i; if ($i == "estimate") e = $(i + 1) }
      printf "solve,%s,own,%s,%s,%s,bundles\nsolve,%s,own,%s,%s,%s,seconds\nsolve,%s,own,%s,%s,%s,error_estimate\n",
        dev, p, g, b, dev, p, g, s, dev, p, g, e }' "$WORK/solve.out"
  grep -q "^patches" "$WORK/solve.out" || tail -3 "$WORK/solve.out" >&2
done

# cluster: bundles/s of a run of $2 seconds on loopback port $1 with nodes on devices $3...
# (the coordinator's figure: its wall time includes meshing and the nodes' joining).
cluster_rate() {
  local port=$1 seconds=$2
  shift 2
  local out="$WORK/cluster-$port" ids=("$@") pids=()
  "$BUILD/sirad-coordinator" cornell --patches $CLUSTER_PATCHES --bundles 100000000 --time-limit "$seconds" \
      --listen "tcp://127.0.0.1:$port" --insecure --width 16 --height 16 --out "$out" >"$out.log" 2>&1 &
  local coordinator=$!
  for k in "${!ids[@]}"; do
    "$BUILD/sirad-node" --connect "tcp://127.0.0.1:$port" --insecure --device "${ids[$k]}" --name "n$k" >"$out.node$k.log" 2>&1 &
    pids+=($!)
  done
  wait $coordinator
  kill "${pids[@]}" 2>/dev/null
  wait "${pids[@]}" 2>/dev/null
  grep -q "^patches" "$out.log" || tail -n 3 "$out.log" "$out".node*.log >&2
  sed -n 's/^patches.* \([0-9.]*\) bundles\/s.*/\1/p' "$out.log" | tail -1
}
# CLUSTER_CPU_PAIR=1 runs the cluster with the CPU device in both places (to check this script
# on a machine without a GPU; its share is not the target's).
[ -z "$gpu" ] && [ -n "${CLUSTER_CPU_PAIR:-}" ] && gpu=$cpu
if [[ " ${SECTIONS:-bundle solve cluster} " != *" cluster "* ]]; then
  :
elif [ -n "$gpu" ] && [ -n "$cpu" ]; then
  base=$((20000 + RANDOM % 20000))  # loopback ports of no fixed number: another run may hold one
  # A short run first, so that no measured run pays for compiling the kernels (PoCL and the
  # NVIDIA driver cache them).
  cluster_rate $((base + 3)) 2 "$gpu" "$cpu" >/dev/null
  g=$(cluster_rate $base "$CLUSTER_SECONDS" "$gpu") c=$(cluster_rate $((base + 1)) "$CLUSTER_SECONDS" "$cpu")
  both=$(cluster_rate $((base + 2)) "$CLUSTER_SECONDS" "$gpu" "$cpu")
  echo "cluster,gpu $gpu alone,own,$CLUSTER_PATCHES,auto,$g,bundles_per_s"
  echo "cluster,cpu $cpu alone,own,$CLUSTER_PATCHES,auto,$c,bundles_per_s"
  echo "cluster,gpu $gpu + cpu $cpu,own,$CLUSTER_PATCHES,auto,$both,bundles_per_s"
  [ -n "$g" ] && [ -n "$c" ] && [ -n "$both" ] &&
    awk -v g="$g" -v c="$c" -v b="$both" -v p="$CLUSTER_PATCHES" \
      'BEGIN { if (g + c > 0) printf "cluster,share of the two alone,own,%s,auto,%.3f,ratio\n", p, b / (g + c) }'
else
  echo "# cluster: skipped (needs a GPU and a CPU OpenCL device; found gpu '${gpu}' cpu '${cpu}')" >&2
fi
