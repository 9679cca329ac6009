#!/bin/bash
# sirad bench: packs what bench/gpu.sh runs into one folder for a machine that has a GPU and its
# OpenCL driver but none of sirad's libraries (the GPU machines lent to this project run another
# distribution and cannot fetch packages): the four programs, and every shared library they load
# but the C library's own (those are the machine's), into OUT/lib. The NVIDIA driver's OpenCL
# (libnvidia-opencl, its ICD file) stays the machine's; the ICD loader travels.
#   bench/gpu-pack.sh [BUILD] [OUT]     (default: ./build, ./.gpu; OUT is made afresh)
# Writes OUT and OUT.tar.xz (the device tool carries at most 64 MiB with the working tree, and
# Embree alone is 44 MB: the archive is about a quarter of the folder). There:
#   tar xJf .gpu.tar.xz && bench/gpu.sh .gpu
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
BUILD=${1:-$HERE/../build} OUT=${2:-$HERE/../.gpu}
progs=("$BUILD/sirad" "$BUILD/sirad-node" "$BUILD/sirad-coordinator" "$BUILD/bench/sirad_bench_bundle")
for p in "${progs[@]}"; do [ -x "$p" ] || { echo "bench/gpu-pack.sh: missing $p (build first)" >&2; exit 1; }; done
rm -rf "$OUT"
mkdir -p "$OUT/lib" "$OUT/bench" "$OUT/vendors"
cp "${progs[@]:0:3}" "$OUT/"
cp "${progs[3]}" "$OUT/bench/"
# The libraries, less glibc's (libc, libm, libpthread, libdl, librt, the loader): the machine's
# own glibc is newer, and one process cannot mix two.
ldd "${progs[@]}" | awk '$2 == "=>" && $3 ~ /^\// { print $3 }' | sort -u |
  grep -vE '/(libc|libm|libpthread|libdl|librt|libresolv|ld-linux-x86-64)\.so' |
  while read -r lib; do cp -L "$lib" "$OUT/lib/"; done
strip --strip-unneeded "$OUT"/sirad* "$OUT"/bench/* "$OUT"/lib/* 2>/dev/null || true
# The NVIDIA ICD by name (the loader finds libnvidia-opencl.so.1 on the machine's library path).
echo libnvidia-opencl.so.1 > "$OUT/vendors/nvidia.icd"
tar -C "$(dirname "$OUT")" -cJf "$OUT.tar.xz" "$(basename "$OUT")"
du -sh "$OUT" "$OUT.tar.xz"
