# sirad bench/paper: what every figure script shares (sourced). BUILD (default: ./build of the
# repository) holds the built sirad and sirad_bench_paper; OUT (default: bench/paper/out) gets
# the CSV and PNG files.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
BUILD=${BUILD:-$ROOT/build}
OUT=${OUT:-$HERE/out}
SIRAD=$BUILD/sirad
PAPER=$BUILD/bench/sirad_bench_paper
mkdir -p "$OUT"
command -v gnuplot >/dev/null || { echo "bench/paper: needs gnuplot (apt-get install gnuplot-nox)" >&2; exit 1; }
[ -x "$SIRAD" ] && [ -x "$PAPER" ] || { echo "bench/paper: build first (README: cmake -S . -B build -G Ninja && ninja -C build)" >&2; exit 1; }
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$BUILD/pocl-cache}

# The paper's contractions for figures 1 to 4.
CONTRACTIONS="0.1 0.3 0.5 0.7 0.9"

# gnuplot's PNG terminal with the settings every figure uses; $1 the output file.
png() { printf 'set terminal pngcairo size 1100,650 font ",10" noenhanced\nset output "%s"\nset datafile separator ","\nset key outside right\nset grid\n' "$1"; }
