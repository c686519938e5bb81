#!/usr/bin/env python3
"""The cost model of tools/gpu-estimate.sh: iterations of each hot loop at `make bench-gpu`'s frame
x instructions per iteration (tools/gpu-estimate.py) / (GPU lane rate x efficiency). Every
constant below is stated and justified in docs/gpu-estimate.md.
Usage: gpu-estimate-model.py COUNTS.json CANDIDATES.txt SHADER_DIR"""
import json, math, re, sys

counts = json.load(open(sys.argv[1]))
cand = {}
for ln in open(sys.argv[2]):
    f = ln.split()
    if f and f[0] == "candidates":
        cand[f[1]] = {k: float(v) for k, v in (x.split("=") for x in f[3:])}
sdir = sys.argv[3]

def loops(variant):
    return next(r["loops"] for p, r in counts.items() if p.endswith("/" + variant + ".spvasm"))

def line_of(shader, text, after=None):
    seen = after is None
    for i, l in enumerate(open(sdir + "/" + shader), 1):
        seen = seen or after in l
        if seen and text in l:
            return i
    raise SystemExit("not found in %s: %s" % (shader, text))

def loop(variant, shader, text, path="max", nth=None, after=None):
    """per-iteration counts of the loop whose header is the first line holding text; nth=None:
    the sum over every inlined copy of it"""
    ln = line_of(shader, text, after)
    found = [l[path] for l in loops(variant) if l["line"] == ln]
    if not found:
        raise SystemExit("no loop at %s:%d" % (shader, ln))
    found = found if nth is None else [found[nth]]
    return {k: sum(f[k] for f in found) for k in found[0]}

def lat(variant, shader, text, nth=0, after=None):
    ln = line_of(shader, text, after)
    found = [l for l in loops(variant) if l["line"] == ln]
    return {"critical_path": found[nth]["critical_path"], "in_order": found[nth]["in_order"]}

def lin(*terms):   # sum of (factor, counts)
    out = {}
    for a, c in terms:
        for k, v in c.items():
            out[k] = out.get(k, 0) + a * v
    return out

def slots(c):
    """warp issue slots per iteration: every instruction (a vecN op is N) issues once"""
    return c["alu"] + c["sfu"] + c["ld_g"] + c["ld_s"] + c["ld_t"] + c["st"] + c["atom"]

GPUS = [   # name, SMs, FP32 lanes per SM, boost GHz, DRAM GB/s, max warps per SM, shared KiB per SM
    ("H100 SXM", 132, 128, 1.98, 3350.0, 64, 228),
    ("RTX 3060", 28, 128, 1.777, 360.0, 48, 100),
]
# optimistic / pessimistic: issue efficiency of a scheduler with enough warps (register-bank and
# shared-memory bank conflicts, INT32 at half rate on GA10x), the latency of one warp's iteration
# (its critical path, or an in-order issue of the SPIR-V order), DRAM efficiency, per-dispatch gap
EFF = {"opt": {"issue": 0.9, "lat": "critical_path", "bw": 0.8, "launch_us": 3.0},
       "pess": {"issue": 0.7, "lat": "in_order", "bw": 0.5, "launch_us": 10.0}}
SFU_RATIO = 8   # 16 SFU lanes per SM against 128 FP32 lanes (CUDA guide, throughput table, cc 8.6 and 9.0)
SCENES = {"sponza-atrium": 24863, "street": 3330}
W, H, RSM, VALS, VS, N = 1920, 1080, 2048, 8192, 256, 16
PIX, TEX = W * H, RSM * RSM
SHADE_SHARED = 768 * 16 * 2 + 768 * 4 + 64 * 16 * 2 + 64   # lightskin_shade.comp's shared memory per group, bytes

def cycles(parts, w, e):
    """cycles for w warps on one scheduler to run their iterations: per loop, the larger of the
    issue slots of all w warps (and their SFU pipe time) and one warp's latency"""
    tot = 0.0
    for n, c, lat in parts:
        tot += n * max(w * slots(c) / EFF[e]["issue"], w * SFU_RATIO * c["sfu"], lat[EFF[e]["lat"]])
    return tot

def pass_ms(threads, parts, gpu, e, w):
    """threads spread over every scheduler, w warps resident on each"""
    _, sms, _, ghz, _, _, _ = gpu
    warps = threads / 32.0
    return warps / (4 * sms) / w * cycles(parts, w, e) / (ghz * 1e9) * 1e3

def mem(bytes_, gpu, e):
    return bytes_ / (gpu[4] * 1e9 * EFF[e]["bw"]) * 1e3

# the VAL loop of proxy_lights.comp's modes 0 and 1 (the first line holding it: mode 0's)
T_PROXY = "for (uint t = base < first ? first - base : 0u; t < count; ++t)"

# --- instructions per iteration. Both scenes are diffuse only (the street's materials are
# make_material's, diffuse; sponza_lod4.glb has no materials: the loader's grey 0.8), so the
# frame runs the diffuse variants (with_glossy = 0, flags = 0); the glossy ones are printed too.
proxy_g = loop("proxy_lights-glossy", "proxy_lights.comp", T_PROXY, nth=0)
proxy = loop("proxy_lights-diffuse", "proxy_lights.comp", T_PROXY, nth=0)
# mode 1: the form-factor positions of dark caches (no VAL lit them), a second pass over the VALs
# in every work group that holds one; pessimistic: every group does
T_DARK = "float f = den > 0.0 ? tile_nw[t].w * tile_pa[t].w * cos_l * cos_x / den : 0.0;"
dark_line = line_of("proxy_lights.comp", T_DARK)
dark = next(l for l in reversed(loops("proxy_lights-dark")) if l["line"] < dark_line and l["innermost"])
imp = loop("importance_map-all", "importance_map.comp", "for (uint k = 0u; k < n; ++k)")
sv = "lightskin_shade-diffuse"
# a list entry: scan_list is inlined at each of neighbours()'s four scans (the rings', the slabs'
# first and both sides), in the block's search and the fallback's; a search runs the rings' or
# the slabs' (the tile's choice, uniform in its work group), so one copy per search site counts
cand_it = lin((2, loop(sv, "lightskin_shade.comp", "for (uint j = j0; j < j1; ++j) {", nth=0)))
offer_it = loop(sv, "lightskin_shade.comp", "for (int j = MAX_N - 1; j > 0; --j)", nth=0)
ring_it = loop(sv, "lightskin_shade.comp", "for (uint r = 0u; r < RINGS; ++r) {", after="float slack")
best_it = loop(sv, "lightskin_shade.comp", "for (int j = 0; j < MAX_N; ++j) v = uint(j) == i ? b.d[j] : v;", nth=0)
interp_it = loop(sv, "lightskin_shade.comp", "for (int j = 0; j < MAX_N; ++j) {   /* constant indices")   # one copy: the diffuse set
pass_it = loop(sv, "lightskin_shade.comp", "for (int pass = 0; pass < 2; ++pass)")                  # its weight passes
plan_it = lin((1, loop(sv, "lightskin_shade.comp", "for (uint i = 0u; i < TILE; ++i) {")),
              (1, loop(sv, "lightskin_shade.comp", "        for (uint i = 0u; i < TILE; ++i)")))
rsm_frag = next(r["all_blocks"] for p, r in counts.items() if p.endswith("/rsm-all.spvasm"))
gb_frag = next(r["all_blocks"] for p, r in counts.items() if p.endswith("/gbuffer-all.spvasm"))

def show(name, c):
    print("  %-44s alu %4d  sfu %3d  ld_shared %2d  ld_global %2d  -> %d issue slots" %
          (name, c["alu"], c["sfu"], c["ld_s"], c["ld_g"], slots(c)))

print("\ninstructions per iteration (spirv-opt -O, costliest path; tools/gpu-estimate.py):")
show("proxy: cache x VAL (diffuse, the frame's)", proxy)
show("proxy: cache x VAL (diffuse + glossy)", proxy_g)
show("proxy, mode 1 (dark caches): cache x VAL", dark["max"])
show("importance: texel x view sample", imp)
show("shade: candidate (list entry)", cand_it)
show("shade: offer step (x15 per offer)", offer_it)
show("shade: neighbour (interp_light, diffuse)", lin((1, interp_it), (2, pass_it)))
show("shade: ring check (+16 best_at steps)", lin((1, ring_it), (16, best_it)))
show("rsm.frag (whole)", rsm_frag)
show("gbuffer.frag (whole)", gb_frag)

T_CAND = 'for (uint j = j0; j < j1; ++j) {'
T_OFFER = 'for (int j = MAX_N - 1; j > 0; --j)'
T_INTERP = 'for (int j = 0; j < MAX_N; ++j) {   /* constant indices'
T_PASS = 'for (int pass = 0; pass < 2; ++pass)'
T_BEST = 'for (int j = 0; j < MAX_N; ++j) v = uint(j) == i ? b.d[j] : v;'
T_PLAN1, T_PLAN2 = 'for (uint i = 0u; i < TILE; ++i) {', '        for (uint i = 0u; i < TILE; ++i)'
SH = "lightskin_shade.comp"

def shade_parts(sc):
    """per pixel: candidates, 15 insertion steps per offer, 8 ring checks (the bound: RINGS) of
    16 best_at steps, 16 neighbours (interp_light + its 2 weight passes); plan_tile's two
    64-step loops run by one invocation for the tile: 1/64 of them per pixel, a whole warp's slot"""
    m = cand[sc]
    return [(m["mean_candidates"], cand_it, lat(sv, SH, T_CAND)),
            (m["mean_offers"] * (N - 1), offer_it, lat(sv, SH, T_OFFER)),
            (8, ring_it, lat(sv, SH, "for (uint r = 0u; r < RINGS; ++r) {", after="float slack")),
            (8 * N, best_it, lat(sv, SH, T_BEST)),
            (N, lin((1, loop(sv, SH, T_INTERP, nth=0)), (2, loop(sv, SH, T_PASS, nth=0))), lat(sv, SH, T_INTERP, 0)),
            (1.0, lin((1, loop(sv, SH, T_PLAN1)), (1, loop(sv, SH, T_PLAN2))), lat(sv, SH, T_PLAN1))]

def shade_per_pixel(sc):
    return sum(n * slots(c) for n, c, _ in shade_parts(sc))

PL = lat("proxy_lights-diffuse", "proxy_lights.comp", T_PROXY)
IL = lat("importance_map-all", "importance_map.comp", "for (uint k = 0u; k < n; ++k)")
print("  latency of one iteration of one warp, critical path / in-order (cycles): proxy %d / %d, importance %d / %d"
      % (PL["critical_path"], PL["in_order"], IL["critical_path"], IL["in_order"]))

def proxy_lanes(caches, vals):
    """gimany.h's gim__proxy_lanes: doubled up to 16 while caches x lanes stays <= 2^17 and every
    lane keeps 512 VALs"""
    l = 1
    while l < 16 and caches * l * 2 <= 1 << 17 and vals >= l * 2 * 512:
        l *= 2
    return l

def proxy_ms(caches, vals, gpu, e, lanes=None):
    """one thread per cache and lane, 64 per work group, each lane over vals / lanes VALs (mode
    1, the dark caches, in lane 0 over all of them): the busiest scheduler holds w warps"""
    _, sms, _, ghz, _, maxw, _ = gpu
    lanes = proxy_lanes(caches, vals) if lanes is None else lanes
    groups = math.ceil(caches / 64) * lanes
    per_sm = min(math.ceil(groups / sms), maxw // 2)
    # groups beyond what is resident start as others finish: a fraction of a round, not a whole
    rounds = max(1.0, groups / (per_sm * sms))
    w = math.ceil(2 * per_sm / 4)
    parts = [(math.ceil(vals / lanes), proxy, PL)]
    t = rounds * cycles(parts, w, e)
    if e == "pess":   # mode 1 in every group of lane 0
        g0 = math.ceil(caches / 64)
        p0 = min(math.ceil(g0 / sms), maxw // 2)
        t += max(1.0, g0 / (p0 * sms)) * cycles([(vals, dark["max"], dark)], math.ceil(2 * p0 / 4), e)
    return t / (ghz * 1e9) * 1e3, groups, 2 * groups, w

rows = []
for gpu in GPUS:
    w_shade = min(gpu[6] * 1024 // SHADE_SHARED * 2, gpu[5]) / 4.0
    for sc, caches in SCENES.items():
        r = {}
        for e in ("opt", "pess"):
            t = {}
            t["proxy"], groups, warps, w = proxy_ms(caches, VALS, gpu, e)
            one_lane = proxy_ms(caches, VALS, gpu, e, 1)[0]   # the pass before 2026-11-28
            w_imp = gpu[5] / 4.0 if e == "opt" else 8.0
            t["importance"] = max(pass_ms(TEX, [(VS, imp, IL)], gpu, e, w_imp), mem(TEX * (3 * 16 + 4), gpu, e))
            t["shade"] = pass_ms(PIX, shade_parts(sc), gpu, e, w_shade)
            frag = lambda c: {"critical_path": 0, "in_order": 0}
            t["rsm + G-buffer"] = (max(pass_ms(TEX, [(1, rsm_frag, frag(0))], gpu, e, 8), mem(TEX * (3 * 16 + 4), gpu, e)) +
                                   max(pass_ms(PIX, [(1, gb_frag, frag(0))], gpu, e, 8), mem(PIX * (4 + 8 + 16), gpu, e)))
            t["scan + select + rest"] = mem(TEX * (4 + 8) * 2, gpu, e) + 14 * EFF[e]["launch_us"] * 1e-3
            t["frame"] = sum(t.values())
            t["FULL proxy"] = proxy_ms(caches, TEX, gpu, e)[0]
            r[e] = t
            r[e + " one lane"] = one_lane
        rows.append((gpu[0], sc, caches, groups, warps, w, r))

print("\nbench-gpu frame (1920x1080, RSM 2048^2, 8,192 VALs, 256 view samples), LightSkin + BRSM, ms, optimistic .. pessimistic:")
keys = ["proxy", "importance", "shade", "rsm + G-buffer", "scan + select + rest", "frame", "FULL proxy"]
print("| GPU | scene (caches) | " + " | ".join(keys) + " |")
print("|---|---|" + "---|" * len(keys))
for g, sc, caches, groups, warps, w, r in rows:
    print("| %s | %s (%s) | " % (g, sc, format(caches, ",")) +
          " | ".join("%.2f .. %.2f" % (r["opt"][k], r["pess"][k]) if r["opt"][k] < 100 else
                     "%.0f .. %.0f" % (r["opt"][k], r["pess"][k]) for k in keys) + " |")
print("\nproxy occupancy: " + "; ".join("%s %s: %d groups of 64, %d warps, busiest scheduler %d warp(s)" %
                                        (g, sc, groups, warps, w) for g, sc, caches, groups, warps, w, r in rows))
print("proxy lanes: " + "; ".join("%s %s: %d lanes, %.2f .. %.2f ms (one lane: %.2f .. %.2f)" %
                                   (g, sc, proxy_lanes(caches, VALS), r["opt"]["proxy"], r["pess"]["proxy"],
                                    r["opt one lane"], r["pess one lane"]) for g, sc, caches, groups, warps, w, r in rows))
print("shading: %d bytes of shared memory per 8x8 tile -> %s warps per scheduler; lane slots per pixel: %s" %
      (SHADE_SHARED, ", ".join("%s %.1f" % (g[0], min(g[6] * 1024 // SHADE_SHARED * 2, g[5]) / 4.0) for g in GPUS),
       ", ".join("%s %.0f" % (sc, shade_per_pixel(sc)) for sc in SCENES)))

# --- llvmpipe check: the demo (street, 3,330 caches x 2,048 VALs; 640x360), 2 cores x 8 lanes
# (LLVM 15, 256 bits), both sides of every branch (masking): every block of the loop body once
ghz = 3.0
def cpu_ms(lane_ops):
    return lane_ops / (2 * 8 * ghz * 1e9) * 1e3
def ops(c, sfu=4):
    return c["alu"] + sfu * c["sfu"] + c["ld_s"] + c["ld_g"] + c["ld_t"] + c["st"]
pe = loop("proxy_lights-diffuse", "proxy_lights.comp", T_PROXY, path="every", nth=0)
ce = lin((2, loop(sv, "lightskin_shade.comp", "for (uint j = j0; j < j1; ++j) {", path="every", nth=0)))
oe = loop(sv, "lightskin_shade.comp", "for (int j = MAX_N - 1; j > 0; --j)", path="every", nth=0)
ie = lin((1, loop(sv, "lightskin_shade.comp", "for (int j = 0; j < MAX_N; ++j) {   /* constant indices", path="every")),
         (2, loop(sv, "lightskin_shade.comp", "for (int pass = 0; pass < 2; ++pass)", path="every")))
pred_proxy = cpu_ms(3330 * 2048 * ops(pe))
c640 = 32.5   # tools/gpu-estimate-candidates.sh street street 640x360: mean_candidates=32.5
pred_shade = cpu_ms(640 * 360 * (c640 * (ops(ce) + (N - 1) * ops(oe)) + N * ops(ie)))
print("\nllvmpipe check (the demo: street, 3,330 caches x 2,048 VALs, 640x360; 2 cores x 8 lanes x %.1f GHz, "
      "every block of the body, sfu = 4 ops):" % ghz)
pred_dark = pred_proxy + cpu_ms(3330 * 2048 * ops(dark["every"]))
print("  proxy: %d lane ops per iteration -> %.0f ms at efficiency 1 (%.0f ms with mode 1's pass in every group); "
      "measured 365.0 ms -> efficiency %.2f .. %.2f" % (ops(pe), pred_proxy, pred_dark, pred_proxy / 365.0, pred_dark / 365.0))
print("  shade: %.0f lane ops per pixel -> %.0f ms at efficiency 1; measured 283.0 ms -> efficiency %.2f"
      % (c640 * (ops(ce) + (N - 1) * ops(oe)) + N * ops(ie), pred_shade, pred_shade / 283.0))
