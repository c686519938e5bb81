#!/bin/sh
# Plots and the README table from bench/results.csv (written by build/bench/bench_frame):
#   bench/pareto_SCENE.png  error against the ground truth vs frame time, per method (the trade)
#   bench/fig3.png          FULL : BRSM frame-time ratio vs RSM size, per VAL count (paper 000 Fig. 3; street)
#   bench/fig5.png          mean relative difference to FULL vs VAL count, per RSM size (paper 000 Fig. 5; street)
#   bench/flicker.png       flicker (BRSM minus FULL's own change) vs VAL count (street)
# and the table between the <!-- bench:frame --> markers of README.md.
set -eu
csv=bench/results.csv
[ -f "$csv" ] || { echo "bench-plots: $csv missing (run build/bench/bench_frame)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
renderer=$(awk -F, 'NR == 2 { print $14 }' "$csv")
scenes=$(awk -F, 'NR > 1 { print $1 }' "$csv" | awk '!seen[$0]++')
for sc in $scenes; do
  for m in brsm full gather; do
    awk -F, -v s="$sc" -v m="$m" 'NR > 1 && $1 == s && $2 == m && $9 != "" && $9 >= 0 { print $6, $9 }' "$csv" > "$tmp/p_${sc}_$m.dat"
  done
  gnuplot <<GP
set terminal pngcairo size 720,480 font ",10" noenhanced
set grid
set key top right
set output "bench/pareto_$sc.png"
set title "$sc, 320x180: error against the ground truth vs frame time ($renderer)"
set xlabel "frame time, ms (median)"; set ylabel "relative mean absolute error vs reference"
set logscale x
plot "$tmp/p_${sc}_brsm.dat" with points pt 7 title "LightSkin + BRSM", "$tmp/p_${sc}_full.dat" with points pt 5 ps 1.5 title "LightSkin FULL", "$tmp/p_${sc}_gather.dat" with points pt 9 ps 1.5 title "RSM gather (256 samples)"
GP
done
for v in 2048 4096 8192; do
  awk -F, -v v="$v" 'NR > 1 && $1 == "street" && $2 == "brsm" && $4 == v && $5 == 256 { print $3, $7 }' "$csv" > "$tmp/fig3_$v.dat"
done
for r in 256 512 1024; do
  awk -F, -v r="$r" 'NR > 1 && $1 == "street" && $2 == "brsm" && $3 == r && $5 == 256 { print $4, $8 }' "$csv" > "$tmp/fig5_$r.dat"
done
awk -F, 'NR > 1 && $1 == "street" && $2 == "brsm-flicker" { print $4, $13 }' "$csv" > "$tmp/flicker.dat"
gnuplot <<GP
set terminal pngcairo size 720,480 font ",10" noenhanced
set grid
set key top left
set output "bench/fig3.png"
set title "street: FULL : BRSM frame-time ratio vs RSM size (256 view samples; paper 000 Fig. 3)"
set xlabel "RSM side (texels)"; set ylabel "FULL time / BRSM time"
set logscale x 2
plot for [v in "2048 4096 8192"] "$tmp/fig3_".v.".dat" with linespoints title v." VALs"
set key top right
set output "bench/fig5.png"
set title "street: mean relative difference to FULL vs VAL count (paper 000 Fig. 5)"
set xlabel "VALs"; set ylabel "mean |BRSM - FULL| / mean FULL"
plot for [r in "256 512 1024"] "$tmp/fig5_".r.".dat" with linespoints title "RSM ".r."^2"
set output "bench/flicker.png"
set title "street: flicker, mean frame-to-frame change beyond FULL's, sun turning 0.25 deg a frame"
set xlabel "VALs"; set ylabel "flicker (fraction of the mean radiance)"
plot "$tmp/flicker.dat" with linespoints pt 7 title "LightSkin + BRSM, RSM 256^2"
GP
# the README table
table="$tmp/table.md"
{
  echo "| scene | RSM | method | VALs | view samples | frame ms | FULL : this | rel. diff to FULL | rel. MAE vs reference |"
  echo "|---|---|---|---|---|---|---|---|---|"
  awk -F, 'NR > 1 && ($2 == "full" || $2 == "brsm" || $2 == "gather") {
    printf "| %s | %s^2 | %s | %s | %s | %.0f | %.1f | %.4f | %s |\n", $1, $3, ($2 == "full" ? "FULL" : ($2 == "brsm" ? "BRSM" : "gather")), $4,
           ($5 == 0 ? "-" : $5), $6, $7, $8, ($9 < 0 ? "-" : sprintf("%.3f", $9)) }' "$csv"
} > "$table"
if grep -q '<!-- bench:frame -->' README.md; then
  awk -v t="$table" '
    /<!-- bench:frame -->/ { print; while ((getline line < t) > 0) print line; skip = 1; next }
    /<!-- \/bench:frame -->/ { skip = 0 }
    !skip { print }' README.md > "$tmp/README.md" && cp "$tmp/README.md" README.md
fi
echo "bench-plots: bench/pareto_*.png bench/fig3.png bench/fig5.png bench/flicker.png, README table"
