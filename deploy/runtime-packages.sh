#!/usr/bin/env bash
# sirad: the Debian packages that the given programs need at run time (deploy/Dockerfile's
# runtime stage installs these and nothing else): the package of every shared library ldd
# resolves, plus the OpenCL drivers the ICD loader opens at run time (PoCL), which no ldd shows.
#   deploy/runtime-packages.sh PROGRAM...
# Fails, naming it, on a library ldd cannot find or no package owns.
set -euo pipefail
declare -A pkgs=([pocl-opencl-icd]=1 [ocl-icd-libopencl1]=1 [clinfo]=1)
for prog in "$@"; do
  while read -r lib; do
    [[ -n $lib ]] || continue
    if [[ $lib == "not found:"* ]]; then echo "runtime-packages: $prog: ${lib#not found: } not found" >&2; exit 1; fi
    real=$(readlink -f "$lib")
    owner=$(dpkg -S "$lib" 2>/dev/null || dpkg -S "$real" 2>/dev/null || dpkg -S "/usr$real" 2>/dev/null || true)
    [[ -n $owner ]] || { echo "runtime-packages: $prog: no package owns $lib" >&2; exit 1; }
    pkgs[${owner%%:*}]=1
  done < <(ldd "$prog" | awk '/=> not found/ {print "not found: " $1; next} /=> \// {print $3} /^\t\/lib/ {print $1}')
done
printf '%s\n' "${!pkgs[@]}" | sort
