#!/bin/sh
# Plots and the docs/benchmarks.md table from DIR/results.csv (written by build/bench/bench_frame; DIR is
# bench for the CI-sized sweep of `make bench`, bench/full for `make bench-full`):
#   DIR/pareto_SCENE.png  error against the ground truth vs frame time, one series per method (the trade)
#   DIR/fig3.png          FULL : BRSM frame-time ratio vs RSM size, per VAL count (Bischoff 2017 Fig. 3; street)
#   DIR/fig5.png          mean relative difference to FULL vs VAL count, per RSM size (Bischoff 2017 Fig. 5; street)
#   DIR/flicker.png       flicker (change beyond FULL's own) vs VAL count, per method (street)
# and the table between docs/benchmarks.md's markers for the CSV's sweep: <!-- bench:ci --> (ci) or
# <!-- bench:frame --> (full). Columns are found by their names in the CSV's header.
# Usage: tools/bench-plots.sh [DIR]
set -eu
dir=${1:-bench}
csv=$dir/results.csv
[ -f "$csv" ] || { echo "bench-plots: $csv missing (run build/bench/bench_frame)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# awk with the header's columns as variables: c["frame_ms"] is that column's number
col='NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }'
head -1 "$csv" | grep -q '^sweep,scene,' || { echo "bench-plots: $csv has the old columns; rerun the bench" >&2; exit 1; }
renderer=$(awk -F, "$col"' { print $c["renderer"]; exit }' "$csv")
sweep=$(awk -F, "$col"' { print $c["sweep"]; exit }' "$csv")
scenes=$(awk -F, "$col"' { print $c["scene"] }' "$csv" | awk '!seen[$0]++')
methods=$(awk -F, "$col"' { print $c["method"] }' "$csv" | awk '!seen[$0]++')
street_size=$(awk -F, "$col"' $c["scene"] == "street" { print $c["width"] "x" $c["height"]; exit }' "$csv")
min_vs=$(awk -F, "$col"' $c["method"] == "brsm" && (m == "" || $c["view_samples"] < m) { m = $c["view_samples"] } END { print m }' "$csv")
for sc in $scenes; do
  size=$(awk -F, -v s="$sc" "$col"' $c["scene"] == s { print $c["width"] "x" $c["height"]; exit }' "$csv")
  plot=""
  for m in $methods; do
    awk -F, -v s="$sc" -v m="$m" "$col"' $c["scene"] == s && $c["method"] == m && $c["rel_mae_reference"] != "" { print $c["frame_ms"], $c["rel_mae_reference"] }' "$csv" > "$tmp/p_${sc}_$m.dat"
    [ -s "$tmp/p_${sc}_$m.dat" ] && plot="$plot${plot:+, }\"$tmp/p_${sc}_$m.dat\" with points ps 1.3 title \"$m\""
  done
  [ -n "$plot" ] || continue
  gnuplot <<GP
set terminal pngcairo size 720,480 font ",10" noenhanced
set grid
set key top right
set output "$dir/pareto_$sc.png"
set title "$sc, $size, $sweep sweep: error vs ground truth against frame time\n$renderer"
set xlabel "frame time, ms (median)"; set ylabel "relative mean absolute error vs reference"
set logscale x
plot $plot
GP
done
vals=$(awk -F, "$col"' $c["scene"] == "street" && $c["method"] == "brsm" { print $c["vals"] }' "$csv" | sort -n | uniq | tr '\n' ' ')
rsms=$(awk -F, "$col"' $c["scene"] == "street" && $c["method"] == "brsm" && $c["rel_diff_full"] != "" { print $c["rsm"] }' "$csv" | sort -n | uniq | tr '\n' ' ')
for v in $vals; do
  awk -F, -v v="$v" -v vs="$min_vs" "$col"' $c["scene"] == "street" && $c["method"] == "brsm" && $c["vals"] == v && $c["view_samples"] == vs && $c["full_over_this"] != "" { print $c["rsm"], $c["full_over_this"] }' "$csv" > "$tmp/fig3_$v.dat"
done
for r in $rsms; do
  awk -F, -v r="$r" -v vs="$min_vs" "$col"' $c["scene"] == "street" && $c["method"] == "brsm" && $c["rsm"] == r && $c["view_samples"] == vs && $c["rel_diff_full"] != "" { print $c["vals"], $c["rel_diff_full"] }' "$csv" > "$tmp/fig5_$r.dat"
done
fl=""
vlo=$(echo $vals | awk '{ print $1 }'); vhi=$(echo $vals | awk '{ print $NF }')
for m in $methods; do
  # a method without VALs (gather): a level line across the VAL range
  awk -F, -v m="$m" -v lo="$vlo" -v hi="$vhi" "$col"' $c["scene"] == "street" && $c["method"] == m && $c["flicker"] != "" && m != "full" {
    if ($c["vals"] > 0) print $c["vals"], $c["flicker"]; else { print lo, $c["flicker"]; print hi, $c["flicker"] } }' "$csv" > "$tmp/flicker_$m.dat"
  [ -s "$tmp/flicker_$m.dat" ] && fl="$fl${fl:+, }\"$tmp/flicker_$m.dat\" with linespoints pt 7 title \"$m\""
done
flicker_rsm=$(awk -F, "$col"' $c["scene"] == "street" && $c["method"] == "full" && $c["flicker"] != "" { print $c["rsm"]; exit }' "$csv")
gnuplot <<GP
set terminal pngcairo size 720,480 font ",10" noenhanced
set grid
set key top left
set output "$dir/fig3.png"
set title "street, $street_size, $sweep sweep: FULL : BRSM frame-time ratio vs RSM size\n($min_vs view samples; Bischoff 2017 Fig. 3)"
set xlabel "RSM side (texels)"; set ylabel "FULL time / BRSM time"
set logscale x 2
plot for [v in "$vals"] "$tmp/fig3_".v.".dat" with linespoints title v." VALs"
unset logscale x
set logscale x 2
set key top right
set output "$dir/fig5.png"
set title "street, $street_size, $sweep sweep: mean relative difference to FULL vs VALs\n(Bischoff 2017 Fig. 5)"
set xlabel "VALs"; set ylabel "mean |BRSM - FULL| / mean FULL"
plot for [r in "$rsms"] "$tmp/fig5_".r.".dat" with linespoints title "RSM ".r."^2"
set output "$dir/flicker.png"
set title "street, $street_size, $sweep sweep: flicker (frame-to-frame change beyond FULL's)\nsun turning 0.25 deg a frame, RSM ${flicker_rsm}^2"
set xlabel "VALs (a method without VALs: a level line)"; set ylabel "flicker (fraction of the mean radiance)"
plot $fl
GP
# the README table: the CSV's rows, pass times left to the CSV
table="$tmp/table.md"
{
  echo "| scene | frame | RSM | method | VALs | view samples | clusters / 2nd-bounce VPLs / bounces | frame ms | FULL : this | rel. diff to FULL | rel. MAE vs reference (its noise floor; its paths per pixel) | flicker | GPU MiB | passes over 10%, ms (timing 2) |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
  awk -F, "$col"' {
    n = split("rsm gbuffer view_samples importance cumsum select caches vals proxy shade vpls kmeans paraboloid second_bounce blur ism", pn, " ")
    sum = 0; for (k = 1; k <= n; ++k) sum += $c[pn[k] "_ms"]
    passes = ""; for (k = 1; k <= n; ++k) if ($c[pn[k] "_ms"] > 0.1 * sum) passes = passes (passes == "" ? "" : ", ") sprintf("%s %.0f", pn[k], $c[pn[k] "_ms"])
    printf "| %s | %sx%s | %s^2 | %s | %s | %s | %s / %s / %s | %.0f | %s | %s | %s | %s | %.1f | %s |\n",
           $c["scene"], $c["width"], $c["height"], $c["rsm"], $c["method"], $c["vals"], ($c["view_samples"] == 0 ? "-" : $c["view_samples"]),
           $c["clusters"], $c["second_bounce_vpls"], $c["bounces"], $c["frame_ms"],
           ($c["full_over_this"] == "" ? "-" : sprintf("%.1f", $c["full_over_this"])), ($c["rel_diff_full"] == "" ? "-" : sprintf("%.4f", $c["rel_diff_full"])),
           ($c["rel_mae_reference"] == "" ? "-" : sprintf("%.3f (%.3f; %d)", $c["rel_mae_reference"], $c["ref_noise_mae"], $c["ref_spp"])),
           ($c["flicker"] == "" ? "-" : sprintf("%.4f", $c["flicker"])), $c["gpu_mib"], passes }' "$csv"
} > "$table"
if [ "$sweep" = full ]; then marker=frame; else marker=$sweep; fi
tools/bench-table.sh "$marker" "$table"
echo "bench-plots: $dir/pareto_*.png $dir/fig3.png $dir/fig5.png $dir/flicker.png, README table ($sweep sweep)"
