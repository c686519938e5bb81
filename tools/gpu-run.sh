#!/bin/sh
# tools/gpu-run.sh: runs on a machine with a real GPU what tools/gpu-bundle.sh built here (carried
# as .gl): the GL runtime from the .gl/*.deb packages (glvnd; the vendor's driver is the
# machine's), then bench_gpu at game sizes (its table to $OUT/gpu_table.md), then every GL test
# against its CPU twin on the vendor's driver, 8 at a time, each bounded (one log, $OUT/gltests.log,
# and a line per test in $OUT/gltests.txt). $OUT: where the files go (default out/gpu).
# Usage: [DUMP_PROGRAMS=1] tools/gpu-run.sh [BENCH_BUDGET_S [TESTS_BUDGET_S [BENCH_ONLY]]]   (budget
# 0: that part skipped; BENCH_ONLY: bench_gpu's --only; DUMP_PROGRAMS: every program's driver
# binary into $OUT/programs.tar first, NVIDIA's with the assembly it compiled to)
set -u
OUT=${OUT:-out/gpu}
mkdir -p "$OUT"
bench_budget=${1:-200}
tests_budget=${2:-150}
bench_only=${3:-}
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
vendor=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f "$vendor" ] && export __EGL_VENDOR_LIBRARY_FILENAMES="$vendor"
export LD_LIBRARY_PATH="${LD_LIBRARY_PATH:+$LD_LIBRARY_PATH:}$PWD/.gl/lib"
nvidia-smi -L 2>&1 | head -2
ldd .gl/bin/bench_gpu | grep -i "not found"
# the tests find the scenes where a checkout beside ../shared does
mkdir -p ../shared/scenes/sponza_lod4
cp -r .gl/scenes/cornell_box ../shared/scenes/ 2>/dev/null
cp .gl/scenes/sponza_lod4.glb ../shared/scenes/sponza_lod4/ 2>/dev/null
if [ -n "${DUMP_PROGRAMS:-}" ]; then   # every program's driver binary, one tar ($OUT/programs.tar)
  mkdir -p /tmp/programs && .gl/bin/bench_gpu --only none --dump-programs /tmp/programs 2>&1 | tail -3
  tar -C /tmp -cf "$OUT/programs.tar" programs
fi
t0=$(date +%s)
if [ "$bench_budget" != 0 ]; then
  .gl/bin/bench_gpu --sponza ../shared/scenes/sponza_lod4/sponza_lod4.glb --budget-s "$bench_budget" \
    ${bench_only:+--only "$bench_only"} --out "$OUT/gpu_table.md" 2>"$OUT/bench_gpu.log"
  echo "bench_gpu: rc $? in $(( $(date +%s) - t0 )) s"
  cat "$OUT/gpu_table.md"
  tail -3 "$OUT/bench_gpu.log"
fi
[ "$tests_budget" = 0 ] && exit 0
t0=$(date +%s)
: >"$OUT/gltests.txt"
export PROXY_DEBUG=1   # gltest_proxy: each cache past the tolerances, on stderr
ls .gl/bin/gltest_* | timeout "$tests_budget" xargs -P 8 -I{} sh -c \
  'n=$(basename {}); s=$(date +%s); timeout '"$tests_budget"' {} >"$OUT/$n.log" 2>&1; r=$?;
   echo "$n rc $r $(( $(date +%s) - s )) s $(grep -c "\[  FAILED  \]" "$OUT/$n.log") failed-lines" >>"$OUT/gltests.txt"'
echo "gltests: $(( $(date +%s) - t0 )) s"
for f in "$OUT"/gltest_*.log; do echo "=== $f"; cat "$f"; done >"$OUT/gltests.log" 2>/dev/null
rm -f "$OUT"/gltest_*.log
sort "$OUT/gltests.txt"
grep -h "FAILED\|ERROR\|Failure\|failure" "$OUT/gltests.log" | head -40
