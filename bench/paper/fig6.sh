#!/usr/bin/env bash
# Figure 6 of the paper, measured: the Cornell box (2,000 patches) on the virtual-time cluster
# (real bundles, virtual clocks; deploy/profiles/lan-1g.yaml for the links), 50, 100 and 200
# bundles in all shared by P = 1, 2, 4, 8 processors exchanging every I bundles; RMS error
# against the reference solution (mean over SEEDS seeds, default 8) and virtual time, with the
# model's prediction (its sd, from the scene's fitted a and sigma_1 / C) on the same axes.
# The paper's estimator (average rule, plain transport), and sirad's defaults beside it.
#   bench/paper/fig6.sh  -> out/fig6.csv (every run), out/fig6-summary.csv, out/fig6a-P{2,4,8}.png,
#                           out/fig6b.png, out/fig6-model-ratio.txt
source "$(dirname "$0")/common.sh"
SEEDS=${SEEDS:-8}
REF="$OUT/cornell-2000.ref.csv"
P6="$PAPER fig6 --scene cornell --patches 2000 --reference $REF --profile $ROOT/deploy/profiles/lan-1g.yaml"
$P6 --seeds "$SEEDS" --estimator paper > "$OUT/fig6.csv"
$P6 --seeds "$(( (SEEDS + 1) / 2 ))" --estimator sirad --periods 1,5,end | tail -n +2 >> "$OUT/fig6.csv"

# Per setting: mean error and its standard error over the seeds, mean virtual time, the model.
# I = end is plotted at I = total / P (one phase: no exchange before the end).
awk -F, 'NR > 1 {
  k = $1 "," $2 "," $3 "," $4; n[k]++; s[k] += $6; q[k] += $6 * $6; t[k] += $7; me[k] = $10; ms[k] = $11
} END {
  print "estimator,total,processors,period,i_plot,error,runs,error_se,virtual_s,model_error,model_sd,ratio"
  for (k in n) {
    split(k, f, ","); m = s[k] / n[k]; v = n[k] > 1 ? (q[k] - n[k] * m * m) / (n[k] - 1) : 0; if (v < 0) v = 0
    ip = f[4] == "end" ? f[2] / f[3] : f[4]
    printf "%s,%s,%.6f,%d,%.6f,%.6f,%.6f,%.6f,%.4f\n", k, ip, m, n[k], sqrt(v / n[k]), t[k] / n[k], me[k], ms[k], m / ms[k]
  }
}' "$OUT/fig6.csv" | (read -r h; echo "$h"; sort -t, -k1,1 -k2,2n -k3,3n -k5,5n) > "$OUT/fig6-summary.csv"

# How far the model's sd is from the measured RMS error (paper estimator, P >= 2).
awk -F, 'NR > 1 && $1 == "paper" && $3 >= 2 { print $12 }' "$OUT/fig6-summary.csv" | sort -g |
  awk '{ r[++n] = $1 } END { printf "measured RMS error / model sd over %d settings (paper estimator, P >= 2): min %.3f, median %.3f, max %.3f\n", n, r[1], r[int((n + 1) / 2)], r[n] }' \
  > "$OUT/fig6-model-ratio.txt"
cat "$OUT/fig6-model-ratio.txt"

# One file per curve (gnuplot breaks a line at every filtered-out row).
C="$OUT/curves"; mkdir -p "$C"
curve() { awk -F, "NR > 1 && ($2)" "$OUT/fig6-summary.csv" > "$C/$1.csv"; echo "$C/$1.csv"; }
for P in 2 4 8; do
  s=""
  for T in 50 100 200; do
    f=$(curve "paper-$T-$P" "\$1 == \"paper\" && \$2 == $T && \$3 == $P")
    g=$(curve "sirad-$T-$P" "\$1 == \"sirad\" && \$2 == $T && \$3 == $P")
    s="$s${s:+, }'$f' using 5:6:8 with yerrorlines title 'measured, $T bundles', '$f' using 5:11 with lines dashtype 2 title 'model sd, $T bundles'"
    s="$s, '$g' using 5:6 with linespoints pointtype 7 title 'sirad defaults, $T bundles'"
  done
  { png "$OUT/fig6a-P$P.png"; echo "set title 'Figure 6a: RMS error against the exchange period I, P = $P (Cornell box, 2000 patches; $SEEDS seeds)'"
    echo "set xlabel 'bundles between exchanges I (rightmost: only at the end)'; set ylabel 'relative RMS error'; set logscale xy"; echo "plot $s"; } | gnuplot
done
s=""
for T in 50 100 200; do
  f=$(curve "time-end-$T" "\$1 == \"paper\" && \$2 == $T && \$4 == \"end\"")
  g=$(curve "time-1-$T" "\$1 == \"paper\" && \$2 == $T && \$4 == \"1\"")
  s="$s${s:+, }'$f' using 3:9 with linespoints title '$T bundles, exchange at the end', '$g' using 3:9 with linespoints dashtype 2 title '$T bundles, I = 1'"
done
{ png "$OUT/fig6b.png"; echo "set title 'Figure 6b: virtual wall time against P (measured bundle time, 1 Gbit/s LAN profile)'"
  echo "set xlabel 'processors P'; set ylabel 'seconds'; set logscale xy"; echo "plot $s"; } | gnuplot
ls "$OUT"/fig6*.png
