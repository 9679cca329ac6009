#!/usr/bin/env bash
# sirad: CURVE keys for a cluster in one folder (docker-compose's `keys` service, the namespace
# cluster): coordinator.key(_secret), one key pair per node name, and `allow`, the coordinator's
# allow list of the node keys. Keys already there are kept (a restarted cluster keeps its keys).
#   deploy/make-keys.sh DIR [NODE_NAME ...]      (default: one shared key pair named "node")
# The sirad binary: $SIRAD, else `sirad` on the PATH.
set -euo pipefail
[[ $# -ge 1 ]] || { echo "usage: make-keys.sh DIR [NODE_NAME ...]" >&2; exit 2; }
dir=$1; shift
names=("$@"); [[ ${#names[@]} -gt 0 ]] || names=(node)
sirad=${SIRAD:-sirad}
mkdir -p "$dir"
chmod 700 "$dir"
for name in coordinator "${names[@]}"; do
  [[ -f "$dir/$name.key_secret" ]] || "$sirad" keygen "$dir/$name" > /dev/null
done
# The allow list: each node's public key (from its certificate) and its name.
allow=$(for name in "${names[@]}"; do
  sed -n 's/^ *public-key = "\(.*\)"$/\1/p' "$dir/$name.key" | sed "s/\$/ $name/"
done)
printf '# sirad allow list: node public keys admitted by the coordinator\n%s\n' "$allow" > "$dir/allow.tmp"
mv "$dir/allow.tmp" "$dir/allow"
