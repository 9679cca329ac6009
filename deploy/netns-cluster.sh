#!/usr/bin/env bash
# sirad: a real TCP cluster on one machine, in network namespaces: one namespace per host
# (coordinator, node0..nodeN-1) on a bridge inside a "switch" namespace, optional `tc tbf`
# bandwidth limits on the node links. Runs one scene end to end and cleans up.
#   deploy/netns-cluster.sh BUILD_DIR NODES OUT [RATE | --profile FILE] -- SCENE [coordinator args]
# e.g. deploy/netns-cluster.sh build 3 /tmp/cornell 100mbit -- cornell --bundles 500
#      deploy/netns-cluster.sh build 4 /tmp/cornell --profile deploy/profiles/office-mixed.yaml -- cornell
# RATE: one tbf rate on every node's uplink. --profile: each node's up and down rates from the
# profile (nodes are named netns-node0, netns-node1, ...) as tbf on both ends of its link, and
# the coordinator emulates the rest of the profile (speed, latency, jitter, loss, disconnects).
# Every link runs CURVE: keys for the coordinator and each node are made in OUT.keys
# (deploy/make-keys.sh), the nodes' public keys form the coordinator's allow list.
# Needs root (ip netns, veth, tc). Exits 77 where namespaces are not allowed.
set -euo pipefail

[[ $# -ge 4 ]] || { echo "usage: netns-cluster.sh BUILD_DIR NODES OUT [RATE | --profile FILE] -- SCENE [coordinator args]" >&2; exit 2; }
build=$(realpath "$1"); nodes=$2; out=$3; rate=""; profile=""
shift 3
if [[ "$1" == "--profile" ]]; then profile=$(realpath "$2"); shift 2
elif [[ "$1" != "--" ]]; then rate=$1; shift; fi
declare -A up down
if [[ -n "$profile" ]]; then
  # index name speed slowdown latency_ms jitter_ms up_mbit down_mbit ...
  table=$("$build/sirad" profile "$profile" --nodes "$nodes" --name-prefix netns-node) || exit 2
  while read -r i _ _ _ _ _ u d _; do up[$i]=$u; down[$i]=$d; done < <(tail -n +2 <<< "$table")
fi
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
  if [[ -n "$profile" && "$1" != coord ]]; then
    local n=$((i - 1))
    if [[ "${up[$n]}" != 0 ]]; then
      ip netns exec "$ns" tc qdisc add dev eth0 root tbf rate "${up[$n]}mbit" burst 64kb latency 50ms
    fi
    if [[ "${down[$n]}" != 0 ]]; then
      ip netns exec "$p-sw" tc qdisc add dev "${p}s$i" root tbf rate "${down[$n]}mbit" burst 64kb latency 50ms
    fi
  fi
}
add_host coord 0
for ((i = 0; i < nodes; i++)); do add_host "node$i" $((i + 1)); done

keys="$out.keys"
names=(); for ((i = 0; i < nodes; i++)); do names+=("netns-node$i"); done
SIRAD="$build/sirad" "$(dirname "$0")/make-keys.sh" "$keys" "${names[@]}"

endpoint="tcp://$subnet.1:5555"
scene=$1; shift
ip netns exec "$p-coord" "$build/sirad-coordinator" "$scene" --listen "$endpoint" --min-nodes "$nodes" \
  --curve-secret "$keys/coordinator.key_secret" --allow "$keys/allow" \
  --out "$out" --timeout 300 --status-json "$out.status.json" ${profile:+--profile "$profile" --bandwidth-by-network} -q "$@" &
coordinator=$!
pids+=("$coordinator")
# Nodes join one at a time, so node i is the i-th to join (its index in the profile): the next
# starts once the coordinator's status lists the one before (or after 30 s).
status_file="$out.status.json"
for ((i = 0; i < nodes; i++)); do
  ip netns exec "$p-node$i" "$build/sirad-node" --connect "$endpoint" --name "netns-node$i" \
    --curve-secret "$keys/netns-node$i.key_secret" --server-key "$keys/coordinator.key" &
  pids+=("$!")
  for ((t = 0; t < 300; t++)); do
    [[ -f "$status_file" && $(grep -o '"name"' "$status_file" | wc -l) -gt $i ]] && break
    kill -0 "$coordinator" 2>/dev/null || break
    sleep 0.1
  done
done
status=0
wait "$coordinator" || status=$?
exit "$status"
