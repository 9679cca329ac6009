#!/usr/bin/env bash
# sirad: install every build and run dependency from Debian 12 packages.
# Used by the README's two commands, by .ci/run and by deploy/Dockerfile.
# Idempotent: packages already present are left alone; apt-get runs only when one is missing.
set -euo pipefail

# What building needs (deploy/Dockerfile's build stage: `install-deps.sh --build`).
build_packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git
  # OpenCL: ICD loader, headers, C++ bindings, the PoCL CPU driver, clinfo for diagnostics
  ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers pocl-opencl-icd clinfo
  # ZeroMQ, maths, images, random numbers, hashing
  libzmq3-dev cppzmq-dev libglm-dev libopenexr-dev openexr libpng-dev librandom123-dev libxxhash-dev
  # scene import, command line, logging, configuration, wire schema
  libtinygltf-dev libcli11-dev libfmt-dev libyaml-cpp-dev nlohmann-json3-dev
  # the farm's HTTP API and web page
  libcpp-httplib-dev
  libprotobuf-dev protobuf-compiler
  # ray casting for the independent reference solver (sirad reference)
  libembree-dev
  # the man pages, made from --help at build time
  help2man
)
# What the tests and benchmarks need besides.
test_packages=(
  # tests and benchmarks; docker-compose only validates deploy/docker-compose.yml (no engine);
  # iproute2 (ip, tc) runs the namespace cluster; gnuplot-nox draws bench/paper's figures
  libgtest-dev libgmock-dev libbenchmark-dev docker-compose iproute2 gnuplot-nox
  # the farm's API is tested with curl, a client this project did not write, and its web page
  # in headless Chromium
  curl chromium
  # the hostile-peer tests: a SIRAD/1 client in Python (pyzmq, protobuf from protoc --python_out)
  python3-zmq python3-protobuf
  # the installed systemd units are checked with systemd-analyze verify
  systemd
  # the image is built with podman on a debian:12 base made by mmdebstrap (deploy/image-check.sh)
  podman mmdebstrap
  # deploy/slurm/sirad.sbatch runs on a Slurm started by its test (deploy/slurm/check-slurm.sh)
  slurm-wlm munge
)

case "${1:-}" in
  --build) packages=("${build_packages[@]}") ;;
  "") packages=("${build_packages[@]}" "${test_packages[@]}") ;;
  *) echo "install-deps: unknown argument '$1' (none: everything; --build: what building needs)" >&2; exit 2 ;;
esac

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]})); then
  SUDO=""
  if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
  echo "install-deps: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi

# The web page's JavaScript (three.js for `sirad view`): web/package-lock.json's exact versions
# into web/node_modules, which the build embeds into sirad. Not with --build: rendering needs none.
if [[ -z "${1:-}" ]]; then
  root="$(cd "$(dirname "$0")/.." && pwd)"
  want=$(grep -o '"three": "[0-9.]*"' "$root/web/package.json" | grep -o '[0-9][0-9.]*')
  if ! grep -q "\"version\": \"$want\"" "$root/web/node_modules/three/package.json" 2>/dev/null; then
    if ! command -v npm >/dev/null; then  # Debian's npm, unless a Node.js of another source brings its own
      SUDO=""
      if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
      $SUDO apt-get update -qq
      DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends npm >&2
    fi
    echo "install-deps: npm ci in web/ (three.js)" >&2
    npm ci --prefix "$root/web" --no-audit --no-fund --loglevel=error >&2
  fi
fi
