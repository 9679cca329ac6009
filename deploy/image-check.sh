#!/usr/bin/env bash
# sirad: builds the image (deploy/Dockerfile) with podman and runs what it holds (the
# Deploy.ImageRuns test). Without a container engine that can run it (podman run needs crun's
# setrlimit, refused on some hosts), the image's exported root file system is run in a chroot:
#   1. the programs start (--version: version, commit, OpenCL);
#   2. sirad render cornell --patches 500 --bundles 50 writes its images;
#   3. a coordinator and a node of the image, over TCP on loopback with CURVE keys made by the
#      image's sirad-make-keys, finish a run;
#   4. the image's farm (sirad-coordinator --serve) runs a job a node of the image takes,
#      submitted by the image's sirad submit, and hands out its image over HTTP;
#   5. deploy/docker-compose.yml's and docker-compose.farm.yml's commands pass --check-config
#      as the image's own programs (deploy/check-compose.py --root).
# The debian:12 base is made with mmdebstrap when podman has none. As root; exits 77 (skipped)
# where podman or mmdebstrap is missing or this is not root.
#   deploy/image-check.sh [TAG]        (default tag: sirad)
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
tag=${1:-sirad}
skip() { echo "image-check: skipped: $*" >&2; exit 77; }
fail() { echo "image-check: $*" >&2; exit 1; }
[[ $(id -u) -eq 0 ]] || skip "needs root (chroot, bind mounts)"
command -v podman >/dev/null || skip "podman is not installed (apt-get install podman)"
command -v mmdebstrap >/dev/null || skip "mmdebstrap is not installed (apt-get install mmdebstrap)"

work=$(mktemp -d /var/tmp/sirad-image.XXXXXX)
root=$work/root
mounted=()
container=""
cleanup() {
  local pids
  pids=$(jobs -p); [[ -z $pids ]] || kill -TERM $pids 2>/dev/null || true
  wait 2>/dev/null || true
  local busy=0
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do
    umount -R -l "${mounted[i]}" 2>/dev/null || true
    if mountpoint -q "${mounted[i]}"; then busy=1; fi
  done
  [[ -z $container ]] || podman rm -f "$container" >/dev/null 2>&1 || true
  # Never removes through a mount that is still there (the host's /dev, /proc, /sys).
  if ((busy)); then echo "image-check: $work still has mounts; left in place" >&2; else rm -rf --one-file-system "$work"; fi
}
trap cleanup EXIT

if ! podman image exists debian:12; then
  echo "image-check: making the debian:12 base with mmdebstrap" >&2
  mmdebstrap --variant=minbase bookworm "$work/base.tar" >&2
  podman import "$work/base.tar" debian:12 >/dev/null
  rm -f "$work/base.tar"
fi
commit=$(git -C "$repo" rev-parse --short=12 HEAD 2>/dev/null || echo unknown)
[[ -z $(git -C "$repo" status --porcelain --untracked-files=no 2>/dev/null) ]] || commit="$commit-dirty"
echo "image-check: building $tag (commit $commit)" >&2
podman build --isolation=chroot --network host --build-arg SIRAD_GIT_COMMIT="$commit" -t "$tag" \
  -f "$repo/deploy/Dockerfile" "$repo" >"$work/build.log" 2>&1 || { tail -40 "$work/build.log" >&2; fail "podman build failed"; }

container=$(podman create "$tag" true)
mkdir -p "$root"
podman export "$container" | tar -x -C "$root"
for fs in proc sys dev; do
  mkdir -p "$root/$fs"
  mount --rbind "/$fs" "$root/$fs"
  mounted+=("$root/$fs")
done
# The image's environment; run_in_image execs, so a job's $! is the program itself.
image_env=(env -i PATH=/usr/local/bin:/usr/bin:/bin POCL_CACHE_DIR=/var/cache/pocl HOME=/root)
in_image() { chroot "$root" "${image_env[@]}" "$@"; }

# 1. The programs start, with their libraries and the OpenCL driver.
for p in sirad sirad-node sirad-coordinator; do
  v=$(in_image "$p" --version) || fail "$p --version failed in the image"
  grep -q "^$p .* (git $commit)$" <<<"$(head -1 <<<"$v")" || fail "$p --version in the image: $(head -1 <<<"$v") (expected commit $commit)"
  grep -q "^OpenCL platform" <<<"$v" || fail "$p sees no OpenCL platform in the image: $v"
done

# 2. A render.
in_image sh -c 'cd /out && sirad render cornell --patches 500 --bundles 50 -q' || fail "sirad render failed in the image"
for ext in exr png ply glb; do [[ -s $root/out/cornell.$ext ]] || fail "the image's render wrote no cornell.$ext"; done

# 3. A coordinator and a node over TCP with CURVE. The node is started once the coordinator
# has bound (its endpoint file), and the coordinator ends the run by itself.
in_image sirad-make-keys /keys node >/dev/null || fail "sirad-make-keys failed in the image"
chroot "$root" "${image_env[@]}" sirad-coordinator cornell --listen 'tcp://127.0.0.1:0' --endpoint-file /out/endpoint --patches 500 \
  --bundles 64 --exchange-every 16 --min-nodes 1 --timeout 300 --out /out/cluster --status-json /out/status.json -q \
  --curve-secret /keys/coordinator.key_secret --allow /keys/allow >"$work/coordinator.log" 2>&1 &
coordinator=$!
for ((i = 0; i < 600; i++)); do
  [[ ! -s $root/out/endpoint ]] || break
  kill -0 $coordinator 2>/dev/null || { cat "$work/coordinator.log" >&2; fail "the image's coordinator exited before binding"; }
  sleep 0.1
done
[[ -s $root/out/endpoint ]] || fail "the image's coordinator did not bind in 60 s"
endpoint=$(cat "$root/out/endpoint")
chroot "$root" "${image_env[@]}" sirad-node --connect "$endpoint" --curve-secret /keys/node.key_secret --server-key /keys/coordinator.key \
  >"$work/node.log" 2>&1 &
node=$!
timeout 300 tail --pid=$coordinator -f /dev/null || { cat "$work/coordinator.log" "$work/node.log" >&2; fail "the run did not end in 300 s"; }
wait $coordinator || { cat "$work/coordinator.log" "$work/node.log" >&2; fail "the image's coordinator failed"; }
kill -TERM $node 2>/dev/null || true
wait $node 2>/dev/null || true
[[ -s $root/out/cluster.exr ]] || fail "the image's cluster run wrote no cluster.exr"
grep -q '"bundles_done":64,' "$root/out/status.json" || fail "the cluster run's status does not count 64 bundles: $(cat "$root/out/status.json")"

# 4. The farm (docker-compose.farm.yml's service) with a node: a job submitted by the image's
# `sirad submit` runs, and its image is handed out by the farm's API.
chroot "$root" "${image_env[@]}" sirad-coordinator --serve /farm --listen 'tcp://127.0.0.1:0' --endpoint-file /out/farm-endpoint \
  --http 127.0.0.1:0 --curve-secret /keys/coordinator.key_secret --allow /keys/allow >"$work/farm.log" 2>&1 &
farm=$!
for ((i = 0; i < 600; i++)); do
  [[ ! -s $root/out/farm-endpoint || ! -s $root/farm/http ]] || break
  kill -0 $farm 2>/dev/null || { cat "$work/farm.log" >&2; fail "the image's farm exited before binding"; }
  sleep 0.1
done
[[ -s $root/farm/http ]] || fail "the image's farm did not bind in 60 s"
chroot "$root" "${image_env[@]}" sirad-node --connect "$(cat "$root/out/farm-endpoint")" --curve-secret /keys/node.key_secret \
  --server-key /keys/coordinator.key >"$work/farm-node.log" 2>&1 &
farm_node=$!
in_image sirad submit cornell --farm /farm --name imagejob --patches 500 --bundles 64 --width 64 --height 64 >/dev/null \
  || fail "sirad submit failed in the image"
for ((i = 0; i < 1500; i++)); do
  state=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["state"])' "$root/farm/jobs/1/job.json" 2>/dev/null || true)
  [[ $state != done && $state != failed ]] || break
  sleep 0.2
done
[[ $state == done ]] || { cat "$work/farm.log" "$work/farm-node.log" >&2; fail "the image's farm job ended '$state' (not done in 300 s)"; }
curl -sf -o "$work/farm.png" "$(cat "$root/farm/http")/api/jobs/1/files/imagejob.png" || fail "the farm's API did not hand out the job's image"
[[ $(head -c 4 "$work/farm.png" | od -An -c | tr -d ' ') == 211PNG ]] || fail "the farm's job image is not a PNG"
kill -TERM $farm_node $farm 2>/dev/null || true
wait $farm || { cat "$work/farm.log" >&2; fail "the image's farm did not stop cleanly on SIGTERM"; }
wait $farm_node 2>/dev/null || true

# 5. The compose files' commands, as the image's programs.
for compose in docker-compose.yml docker-compose.farm.yml; do
  /usr/bin/python3 "$repo/deploy/check-compose.py" --root "$root" "$repo/deploy/$compose" >"$work/compose.log" 2>&1 \
    || { cat "$work/compose.log" >&2; fail "$compose: its commands failed as the image's programs"; }
done
echo "image-check: ok: $tag ($commit) renders, runs a coordinator and a node over TCP, serves a farm job, and takes the compose commands"
