#!/usr/bin/env bash
# sirad: a real TCP cluster on one machine, in network namespaces: one namespace per host
# (coordinator, node0..nodeN-1) on a bridge inside a "switch" namespace, optional `tc tbf`
# bandwidth limits on the node links. Runs one scene end to end and cleans up.
#   deploy/netns-cluster.sh BUILD_DIR NODES OUT [RATE] -- [sirad-coordinator args after SCENE...]
# e.g. deploy/netns-cluster.sh build 3 /tmp/cornell 100mbit -- cornell --bundles 500
# Needs root (ip netns, veth, tc). Exits 77 where namespaces are not allowed.
set -euo pipefail

[[ $# -ge 4 ]] || { echo "usage: netns-cluster.sh BUILD_DIR NODES OUT [RATE] -- SCENE [coordinator args]" >&2; exit 2; }
build=$(realpath "$1"); nodes=$2; out=$3; rate=""
shift 3
if [[ "$1" != "--" ]]; then rate=$1; shift; fi
[[ "${1:-}" == "--" ]] && shift
[[ $# -ge 1 ]] || { echo "netns-cluster: no scene given" >&2; exit 2; }

p="sd$$"                     # names must fit 15 characters: sd<pid>[hs]<i>
subnet=10.77.$(( $$ % 200 + 20 ))
pids=()

cleanup() {
  for pid in "${pids[@]:-}"; do [[ -n "$pid" ]] && kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  for ns in $(ip netns list 2>/dev/null | awk '{print $1}' | grep "^$p-" || true); do ip netns del "$ns" 2>/dev/null || true; done
}
trap cleanup EXIT

if ! ip netns add "$p-sw" 2>/dev/null; then
  echo "netns-cluster: network namespaces are not allowed here (ip netns add failed); skipping" >&2
  exit 77
fi
ip -n "$p-sw" link add br0 type bridge
ip -n "$p-sw" link set br0 up

# One host namespace per machine, its eth0 on the switch's bridge.
add_host() {  # name index
  local ns="$p-$1" i=$2
  ip netns add "$ns"
  ip link add "${p}h$i" type veth peer name "${p}s$i"
  ip link set "${p}h$i" netns "$ns"
  ip link set "${p}s$i" netns "$p-sw"
  ip -n "$p-sw" link set "${p}s$i" master br0 up
  ip -n "$ns" link set "${p}h$i" name eth0
  ip -n "$ns" addr add "$subnet.$((i + 1))/24" dev eth0
  ip -n "$ns" link set eth0 up
  ip -n "$ns" link set lo up
  if [[ -n "$rate" && "$1" != coord ]]; then
    ip netns exec "$ns" tc qdisc add dev eth0 root tbf rate "$rate" burst 64kb latency 50ms
  fi
}
add_host coord 0
for ((i = 0; i < nodes; i++)); do add_host "node$i" $((i + 1)); done

endpoint="tcp://$subnet.1:5555"
scene=$1; shift
ip netns exec "$p-coord" "$build/sirad-coordinator" "$scene" --listen "$endpoint" --min-nodes "$nodes" \
  --out "$out" --timeout 300 "$@" &
coordinator=$!
pids+=("$coordinator")
for ((i = 0; i < nodes; i++)); do
  ip netns exec "$p-node$i" "$build/sirad-node" --connect "$endpoint" --name "netns-node$i" &
  pids+=("$!")
done
status=0
wait "$coordinator" || status=$?
exit "$status"
