#!/usr/bin/env bash
# Measures, on whatever GL the EGL path finds (llvmpipe here), how many list entries (or, for a
# tile whose list overflows, cache-grid entries) the LightSkin shading pass examines per pixel
# and how many of them it offers to its 16 nearest: the "candidates" of tools/gpu-estimate.sh.
# It builds build/estimate/gimany-demo from a COPY of gimany.h, demo.c and lightskin_shade.comp
# (the repository's files are not touched) in which the shading pass writes
# (candidates, offers, listed, 1) instead of the radiance, at cache fraction 1/32 (bench_gpu's),
# then averages indirect.pfm over the receivers.
# Usage: tools/gpu-estimate-candidates.sh NAME SCENE WxH [CAMERA]   (prints one line)
set -eu
name=$1 scene=$2 size=$3 camera=${4:-}
root=$(cd "$(dirname "$0")/.." && pwd)
d=$root/build/estimate
mkdir -p "$d/shaders" "$d/out"
if [ ! -x "$d/gimany-demo" ]; then
  cp "$root"/shaders/* "$d/shaders/"
  s=$d/shaders/lightskin_shade.comp
  python3 - "$s" <<'PY'
import sys
p = sys.argv[1]; t = open(p).read()
def sub(a, b):
    global t
    assert t.count(a) == 1, a
    t = t.replace(a, b)
sub("uint found;\n", "uint found;\nuint cand_, offers_;\n")
sub("if (cache_cell[k].xyz != c) continue;   /* another cell", "++cand_;\n        if (cache_cell[k].xyz != c) continue;   /* another cell")
sub("found = min(found + 1u, n);", "found = min(found + 1u, n);\n    ++offers_;")
sub("uint e = list_order[j];", "uint e = list_order[j];\n                ++cand_;")
sub("    found = 0u;\n    for (int j", "    found = 0u;\n    cand_ = 0u; offers_ = 0u;\n    for (int j")
sub("imageStore(indirect, px, vec4(min(outc, vec3(max_value)), 1.0));",
    "imageStore(indirect, px, vec4(float(cand_), float(offers_), listed ? 1.0 : 0.0, 1.0));")
open(p, "w").write(t)
PY
  (cd "$root" && make -s build/embed-shaders build/ref/scene.o >/dev/null)
  (cd "$d" && "$root/build/embed-shaders" "$d/shaders_embedded.h" $(ls shaders/*.comp shaders/*.vert shaders/*.frag shaders/*.geom | LC_ALL=C sort))
  cp "$root/gimany.h" "$d/gimany.h"
  sed 's#scene_gimany_load(ctx, &r->s, 0.0f,#scene_gimany_load(ctx, \&r->s, 1.0f / 32.0f,#' "$root/examples/demo.c" > "$d/demo.c"
  grep -q '1.0f / 32.0f' "$d/demo.c"
  gcc -std=c99 -I"$d" -I"$root/examples" -I"$root/scene" -I"$root" -isystem /usr/include/stb -O2 "$d/demo.c" "$root/build/ref/scene.o" \
      -o "$d/gimany-demo" -lEGL -lGL -lm -lstdc++
fi
out=$d/out/$name
args=(--scene "$scene" --size "$size" --rsm 256 --vals 2048 --frames 1 --timing off --out "$out" --no-glossy)
[ -n "$camera" ] && args+=(--camera "$camera")
(cd "$root" && "$d/gimany-demo" "${args[@]}" > "$out.log" 2>&1) || { cat "$out.log"; exit 1; }
python3 - "$out/indirect.pfm" "$out/stats.json" "$name" "$size" <<'PY'
import sys, struct, json
f = open(sys.argv[1], "rb")
assert f.readline().strip() == b"PF"
w, h = map(int, f.readline().split()); scale = float(f.readline())
n = w * h; v = struct.unpack(("<" if scale < 0 else ">") + "%df" % (3 * n), f.read(12 * n))
rx = [(v[3*i], v[3*i+1], v[3*i+2]) for i in range(n) if v[3*i+2] > 0 or v[3*i] > 0]
st = json.load(open(sys.argv[2]))
caches = st.get("counts", {}).get("caches", "?")
c = sum(r[0] for r in rx) / max(len(rx), 1); o = sum(r[1] for r in rx) / max(len(rx), 1)
listed = sum(1 for r in rx if r[2] > 0) / max(len(rx), 1)
print("candidates %s %s caches=%s receivers=%d mean_candidates=%.1f mean_offers=%.1f listed_fraction=%.3f max_candidates=%d"
      % (sys.argv[3], sys.argv[4], caches, len(rx), c, o, listed, max(r[0] for r in rx) if rx else 0))
PY
