#!/usr/bin/env bash
# Beyond the paper: the heterogeneous 16-node farm of deploy/profiles/hetero-16.yaml (speeds
# 0.25x to 4x, links 10 Mbit/s to 1 Gbit/s) on the virtual-time cluster, the Cornell box at
# 2,000 patches with sirad's default estimator: virtual time until the run's own error estimate
# reaches 2 %, for sync against async, balanced grants or not, star against ring, and I = 8,
# 32 and auto (SEEDS seeds, default 3); the error measured against the reference at that point
# beside it.
#   bench/paper/hetero.sh  -> out/hetero.csv (every run), out/hetero-summary.csv, out/hetero.png
source "$(dirname "$0")/common.sh"
SEEDS=${SEEDS:-3}
H="$PAPER hetero --scene cornell --patches 2000 --reference $OUT/cornell-2000.ref.csv --profile $ROOT/deploy/profiles/hetero-16.yaml --target 0.02 --seeds $SEEDS --periods 8,32,auto"
$H --topologies star --balance on,off > "$OUT/hetero.csv"
$H --topologies ring --balance on | tail -n +2 >> "$OUT/hetero.csv"
awk -F, 'NR > 1 {
  k = $1 "," $2 "," $3 "," $4; n[k]++; t[k] += $8; b[k] += $9; e[k] += $11; u[k] += $13; c[k] = $5
} END {
  print "mode,topology,balance,period,chosen,runs,virtual_s,bundles,error,utilisation"
  for (k in n) printf "%s,%s,%d,%.4f,%.1f,%.5f,%.4f\n", k, c[k], n[k], t[k] / n[k], b[k] / n[k], e[k] / n[k], u[k] / n[k]
}' "$OUT/hetero.csv" | (read -r h; echo "$h"; sort) > "$OUT/hetero-summary.csv"
column -s, -t "$OUT/hetero-summary.csv"
{ png "$OUT/hetero.png"; echo "set title 'hetero-16: virtual time to 2 % error (Cornell box, 2000 patches, sirad defaults; mean of $SEEDS seeds)'"
  echo "set style data histogram; set style fill solid 0.8 border -1; set boxwidth 0.8; set ylabel 'virtual seconds'; set yrange [0:*]; set xtics rotate by -30"
  echo "plot '$OUT/hetero-summary.csv' using 7:xtic(strcol(1).' '.strcol(2).' bal '.strcol(3).' I='.strcol(4).(strcol(4) eq 'auto' ? '('.strcol(5).')' : '')) title 'time to 2 %'"; } | gnuplot
ls "$OUT"/hetero.png
