#!/usr/bin/env bash
# The GPU frame-time estimate of docs/gpu-estimate.md (and docs/benchmarks.md, "On a GPU"), from the cost model
# and instruction counts, until a GPU has been lent: compiles the hot shaders as gimany.h builds
# them (#include lines expanded, "#version 430 core\n" prepended, nothing else), with the
# uniforms that pick a branch for the whole dispatch fixed to the default frame's values,
# optimises (spirv-opt -O), counts the instructions per iteration of each hot loop
# (tools/gpu-estimate.py) and multiplies by the iteration counts of `make bench-gpu`'s frame
# (bench/src/bench_gpu.c). Derivation: docs/gpu-estimate.md.
# Usage: tools/gpu-estimate.sh [--measure]   (--measure re-measures the shading pass's candidates
# per pixel on this machine's GL with tools/gpu-estimate-candidates.sh, ~2 min on llvmpipe;
# without it the figures that script printed on 2026-11-24 are used, listed below)
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$root" && make -s build/embed-shaders >/dev/null)

# shader, variant, uniforms fixed as NAME=VALUE (a uniform branch costs a GPU one scalar branch)
variants=(
  "proxy_lights.comp diffuse mode=0u ism_size=0u with_glossy=0u per_cache_k=0u"
  "proxy_lights.comp glossy mode=0u ism_size=0u with_glossy=1u per_cache_k=0u"
  "proxy_lights.comp dark mode=1u ism_size=0u with_glossy=0u per_cache_k=0u"
  "importance_map.comp all"
  "lightskin_shade.comp diffuse flags=0u"
  "lightskin_shade.comp glossy flags=1u"
  "rsm.frag all"
  "gbuffer.frag all"
)
files=()
for v in "${variants[@]}"; do
  set -- $v
  shader=$1 name=$2; shift 2
  base=${shader%.*} stage=${shader##*.}
  src=$tmp/$base-$name.$stage
  "$root/build/embed-shaders" --expand "$root/shaders/$shader" > "$tmp/$base.glsl"   # its #include lines expanded
  python3 - "$tmp/$base.glsl" "$src" "$@" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
for kv in sys.argv[3:]:
    k, v = kv.split("=")
    t, n = re.subn(r"layout\(location = \d+\) uniform (\w+) %s;" % k, r"const \1 %s = %s;" % (k, v), t)
    assert n == 1, kv
# glslang 12 emits invalid SPIR-V (OpStore of a block struct into a Function struct) for a ?:
# between two buffers' structs; the if/else it means compiles (a uniform branch once inlined)
t = t.replace("Proxy p = is_glossy ? glossy[i] : diffuse[i];", "Proxy p; if (is_glossy) p = glossy[i]; else p = diffuse[i];")
open(sys.argv[2], "w").write("#version 430 core\n" + t)
PY
  glslangValidator -G -g --aml -S "$stage" -o "$tmp/$base-$name.spv" "$src" >/dev/null
  spirv-val "$tmp/$base-$name.spv"
  spirv-opt -O "$tmp/$base-$name.spv" -o "$tmp/$base-$name.o.spv"
  spirv-dis --raw-id "$tmp/$base-$name.o.spv" > "$tmp/$base-$name.spvasm"
  files+=("$tmp/$base-$name.spvasm")
done
python3 "$root/tools/gpu-estimate.py" "${files[@]}" > "$tmp/counts.json"

# the shading pass's list entries examined per pixel (candidates) and offered to the 16 nearest
if [ "${1:-}" = "--measure" ]; then
  "$root/tools/gpu-estimate-candidates.sh" street street 1920x1080 > "$tmp/cand.txt"
  "$root/tools/gpu-estimate-candidates.sh" sponza-atrium ../shared/scenes/sponza_lod4/sponza_lod4.glb 1920x1080 \
      -11,2.5,0.5,12,5,0,60 >> "$tmp/cand.txt"
else   # printed by the two commands above on 2026-11-24 (llvmpipe; the counts do not depend on the driver)
  cat > "$tmp/cand.txt" <<'C'
candidates street 1920x1080 caches=3330 receivers=1915453 mean_candidates=25.0 mean_offers=21.4 listed_fraction=1.000 max_candidates=666
candidates sponza-atrium 1920x1080 caches=24863 receivers=2058422 mean_candidates=50.7 mean_offers=24.8 listed_fraction=0.966 max_candidates=1361
C
fi
cat "$tmp/cand.txt"
python3 "$root/tools/gpu-estimate-model.py" "$tmp/counts.json" "$tmp/cand.txt" "$root/shaders"
