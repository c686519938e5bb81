#!/usr/bin/env bash
# Runs one libFuzzer target: replays tests/fuzz/corpus/NAME (committed inputs, crashers included),
# then fuzzes for SECONDS with new inputs kept in build/fuzz/corpus-NAME.
set -eu
bin=$1; secs=$2
name=$(basename "$bin")
seed=tests/fuzz/corpus/$name
work=$(dirname "$bin")/corpus-$name
mkdir -p "$work"
dirs=("$work"); [ -d "$seed" ] && dirs+=("$seed")
dict=(); [ -f "tests/fuzz/$name.dict" ] && dict=(-dict="tests/fuzz/$name.dict")   # keywords, nesting depth
echo "fuzz: $name for ${secs}s"
"$bin" "${dict[@]}" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -print_final_stats=0 "${dirs[@]}" >"$work.log" 2>&1 || {
  echo "fuzz: $name FAILED, log follows"; tail -n 60 "$work.log"; exit 1; }
