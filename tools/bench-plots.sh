#!/bin/sh
# Plots and the README table from bench/results.csv (written by build/bench/bench_frame):
#   bench/pareto.png    error against the ground truth vs frame time, per method (the trade)
#   bench/fig3.png      FULL : BRSM frame-time ratio vs RSM size, per VAL count (paper 000 Fig. 3)
#   bench/fig5.png      mean relative difference to FULL vs VAL count, per RSM size (paper 000 Fig. 5)
#   bench/flicker.png   flicker (BRSM minus FULL's own change) vs VAL count
# and the table between the <!-- bench:frame --> markers of README.md.
set -eu
csv=bench/results.csv
[ -f "$csv" ] || { echo "bench-plots: $csv missing (run build/bench/bench_frame)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# per-series data files: "x y" lines
awk -F, 'NR > 1 && ($2 == "brsm" || $2 == "full" || $2 == "gather") && $9 != "" && $9 >= 0 { print $6, $9 > "'"$tmp"'/pareto_" $2 ".dat" }' "$csv"
touch "$tmp/pareto_gather.dat"
for v in 2048 4096 8192; do
  awk -F, -v v="$v" 'NR > 1 && $2 == "brsm" && $4 == v && $5 == 256 { print $3, $7 }' "$csv" > "$tmp/fig3_$v.dat"
done
for r in 256 512 1024; do
  awk -F, -v r="$r" 'NR > 1 && $2 == "brsm" && $3 == r && $5 == 256 { print $4, $8 }' "$csv" > "$tmp/fig5_$r.dat"
done
awk -F, 'NR > 1 && $2 == "brsm-flicker" { print $4, $13 }' "$csv" > "$tmp/flicker.dat"
renderer=$(awk -F, 'NR == 2 { print $14 }' "$csv")
gnuplot <<GP
set terminal pngcairo size 720,480 font ",10" noenhanced
set grid
set key top right
set output "bench/pareto.png"
set title "street, 320x180: error against the ground truth vs frame time ($renderer)"
set xlabel "frame time, ms (median)"; set ylabel "relative mean absolute error vs reference"
set logscale x
plot "$tmp/pareto_brsm.dat" with points pt 7 title "LightSkin + BRSM", "$tmp/pareto_full.dat" with points pt 5 ps 1.5 title "LightSkin FULL", "$tmp/pareto_gather.dat" with points pt 9 ps 1.5 title "RSM gather (256 samples)"
unset logscale
set output "bench/fig3.png"
set title "FULL : BRSM frame-time ratio vs RSM size (256 view samples; paper 000 Fig. 3)"
set xlabel "RSM side (texels)"; set ylabel "FULL time / BRSM time"
set logscale x 2
plot for [v in "2048 4096 8192"] "$tmp/fig3_".v.".dat" with linespoints title v." VALs"
set output "bench/fig5.png"
set title "mean relative difference to FULL vs VAL count (paper 000 Fig. 5)"
set xlabel "VALs"; set ylabel "mean |BRSM - FULL| / mean FULL"
plot for [r in "256 512 1024"] "$tmp/fig5_".r.".dat" with linespoints title "RSM ".r."^2"
set output "bench/flicker.png"
set title "flicker: mean frame-to-frame change beyond FULL's, sun turning 0.25 deg a frame"
set xlabel "VALs"; set ylabel "flicker (fraction of the mean radiance)"
plot "$tmp/flicker.dat" with linespoints pt 7 title "LightSkin + BRSM, RSM 256^2"
GP
# the README table
table="$tmp/table.md"
{
  echo "| RSM | method | VALs | view samples | frame ms | FULL : this | rel. diff to FULL | rel. MAE vs reference |"
  echo "|---|---|---|---|---|---|---|---|"
  awk -F, 'NR > 1 && ($2 == "full" || $2 == "brsm" || $2 == "gather") {
    printf "| %s^2 | %s | %s | %s | %.0f | %.1f | %.4f | %s |\n", $3, ($2 == "full" ? "FULL" : ($2 == "brsm" ? "BRSM" : "gather")), $4,
           ($5 == 0 ? "-" : $5), $6, $7, $8, ($9 < 0 ? "-" : sprintf("%.3f", $9)) }' "$csv"
} > "$table"
if grep -q '<!-- bench:frame -->' README.md; then
  awk -v t="$table" '
    /<!-- bench:frame -->/ { print; while ((getline line < t) > 0) print line; skip = 1; next }
    /<!-- \/bench:frame -->/ { skip = 0 }
    !skip { print }' README.md > "$tmp/README.md" && cp "$tmp/README.md" README.md
fi
echo "bench-plots: bench/pareto.png bench/fig3.png bench/fig5.png bench/flicker.png, README table"
