#!/usr/bin/env bash
# Figures 1 to 5 of the paper from its model (model/model.h via `sirad model`), twice: with the
# paper's costs (T_i = 4.5 s, T_e = 0.05 s, T = 60 s, sigma_1 / C = 1) and with the costs
# measured here (T_i and T_e from a real 2-node sync run of the Cornell box at 10,000 patches on
# this machine, read back by `sirad model --from-run`), same T and contractions.
#   bench/paper/model.sh            -> out/fig{1..5}-{paper,measured}.{csv,png}, out/measured-costs.txt
source "$(dirname "$0")/common.sh"

# Measured costs: a sync run exchanging every bundle, so its idle time is the exchange barrier.
"$SIRAD" render cornell --nodes 2 --mode sync --exchange-every 1 --bundles 200 --patches 10000 --width 64 --height 64 \
  --out "$OUT/costs-run" --status-json "$OUT/costs-run.json" -q > /dev/null
"$SIRAD" model --from-run "$OUT/costs-run.json" | grep '^# from the run' > "$OUT/measured-costs.txt"
TI=$(sed -E 's/.*T_i = ([0-9.e+-]+) s.*/\1/' "$OUT/measured-costs.txt")
TE=$(sed -E 's/.*T_e = ([0-9.e+-]+) s.*/\1/' "$OUT/measured-costs.txt")
rm -f "$OUT"/costs-run.{exr,png,ply}
echo "measured: T_i = $TI s, T_e = $TE s" >&2

for costs in paper measured; do
  if [ $costs = paper ]; then C="--t-iteration 4.5 --t-exchange 0.05"; MAXI=13; else C="--t-iteration $TI --t-exchange $TE"; MAXI=200; fi
  M="$SIRAD model --time 60 --sigma 1 $C"
  for f in 1 2 3 4; do : > "$OUT/fig$f-$costs.csv"; done
  first=1
  for a in $CONTRACTIONS; do
    strip() { if [ $first = 1 ]; then cat; else tail -n +2; fi | grep -v '^#'; }
    $M --contraction $a --processors 8 --exchange-every 1 --sweep processors --max 32 | strip >> "$OUT/fig1-$costs.csv"
    $M --contraction $a --processors 8 --sweep period --max $MAXI | strip >> "$OUT/fig2-$costs.csv"
    $M --contraction $a --processors 8 --exchange-every 1 --sweep fraction --max 20 | strip >> "$OUT/fig3-$costs.csv"
    $M --contraction $a --exchange-every 1 --sweep processors --max 16 --time-to 0.1 | strip >> "$OUT/fig4-$costs.csv"
    first=0
  done
  # Figure 5: every setup of figures 1 to 3, effective samples against 1 / sd.
  cat "$OUT/fig1-$costs.csv" <(tail -n +2 "$OUT/fig2-$costs.csv") <(tail -n +2 "$OUT/fig3-$costs.csv") > "$OUT/fig5-$costs.csv"

  title="$costs costs (T_i = $(awk -F, 'NR==2{print $6}' "$OUT/fig1-$costs.csv") s, T_e = $(awk -F, 'NR==2{print $7}' "$OUT/fig1-$costs.csv") s, T = 60 s, sigma_1/C = 1)"
  plot_by_a() {  # $1 x column, $2 y column, rest: extra gnuplot lines
    local x=$1 y=$2 s=""
    for a in $CONTRACTIONS; do s="$s${s:+, }'\$IN' using (\$4==$a ? \$$x : 1/0):(\$4==$a ? \$$y : 1/0) with linespoints title 'a = $a'"; done
    echo "plot ${s//\$IN/$IN}"
  }
  IN="$OUT/fig1-$costs.csv"; { png "$OUT/fig1-$costs.png"; echo "set title 'Figure 1: predicted error against P (I = 1, S = 1), $title'"; echo "set xlabel 'processors P'; set ylabel 'relative error'; set logscale y"; plot_by_a 1 11; } | gnuplot
  IN="$OUT/fig2-$costs.csv"; { png "$OUT/fig2-$costs.png"; echo "set title 'Figure 2: predicted error against I (P = 8, S = 1), $title'"; echo "set xlabel 'exchange period I'; set ylabel 'relative error'; set logscale y"; plot_by_a 2 11; } | gnuplot
  IN="$OUT/fig3-$costs.csv"; { png "$OUT/fig3-$costs.png"; echo "set title 'Figure 3: predicted error against S (P = 8, I = 1), $title'"; echo "set xlabel 'fraction S'; set ylabel 'relative error'; set logscale y"; plot_by_a 3 11; } | gnuplot
  IN="$OUT/fig4-$costs.csv"; { png "$OUT/fig4-$costs.png"; echo "set title 'Figure 4: time to 10 % error against P (I = 1), $title'"; echo "set xlabel 'processors P'; set ylabel 'seconds'; set logscale y"; plot_by_a 1 15; } | gnuplot
  IN="$OUT/fig5-$costs.csv"; { png "$OUT/fig5-$costs.png"; echo "set title 'Figure 5: effective samples against 1 / sd, $title'"; echo "set xlabel '1 / sd'; set ylabel 'ln E'; set logscale x"; plot_by_a 14 12 | sed 's/\$14/(1\/$14)/g; s/linespoints/points/g'; } | gnuplot
done
ls "$OUT"/fig[1-5]-*.png
