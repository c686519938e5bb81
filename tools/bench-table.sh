#!/bin/sh
# tools/bench-table.sh NAME FILE: replaces what lies between docs/benchmarks.md's <!-- bench:NAME --> and
# <!-- /bench:NAME --> lines with FILE's contents (the tables `make bench`, `make bench-full` and
# `make bench-gpu` write). Without the markers it says so and leaves docs/benchmarks.md alone.
set -eu
name=$1
file=$2
if ! grep -q "<!-- bench:$name -->" docs/benchmarks.md; then
  echo "bench-table: docs/benchmarks.md has no <!-- bench:$name --> markers; table not written" >&2
  exit 0
fi
tmp=$(mktemp)
awk -v t="$file" -v op="<!-- bench:$name -->" -v cl="<!-- /bench:$name -->" '
  $0 == op { print; while ((getline line < t) > 0) print line; skip = 1; next }
  $0 == cl { skip = 0 }
  !skip { print }' docs/benchmarks.md > "$tmp" && cp "$tmp" docs/benchmarks.md
rm -f "$tmp"
echo "bench-table: docs/benchmarks.md's bench:$name table from $file"
