#!/usr/bin/env python3
"""Instruction counts of gimany's hot loops from optimised SPIR-V, and a GPU time estimate.

tools/gpu-estimate.sh compiles each shader as gimany.h does (it prepends "#version 430 core\\n"
and nothing else), with some uniforms fixed to the default frame's values (a uniform branch
costs a GPU one scalar branch, so only the side the frame takes is counted), optimises with
spirv-opt -O, disassembles, and calls this with the .spvasm files. Each loop is found by its
OpLoopMerge and named by the source line of its header (OpLine, kept by glslang -g). Per
iteration it counts, along the costliest path from the loop header to its continue block
(SIMT: a warp pays every branch some lane takes; the cheapest path is printed too):
  alu  FP32/INT lane ops (a vecN op is N; dot of vecN N; length N + 1 sfu; x / y 1 alu + 1 sfu)
  sfu  transcendental (sqrt, rsqrt, rcp, exp2, log2, sin, cos; pow = 2 sfu + 1 alu;
       atan/acos/asin 1 sfu + 12 alu, a polynomial)
  f64  double ops;  ld_g / ld_s / ld_t  loads from buffers, shared memory, textures;  st stores
Free: extracts, constructs, shuffles, phis, access chains (address arithmetic), branches.
Per loop it also simulates one warp's iteration for its latency (see latency())."""
import json, re, sys
from collections import defaultdict

SFU1 = {"Sqrt", "InverseSqrt", "Exp2", "Log2", "Exp", "Log", "Sin", "Cos", "Tan"}
POLY = {"Atan", "Atan2", "Acos", "Asin"}
ALU_N = {"FMin", "FMax", "UMin", "UMax", "SMin", "SMax", "NMin", "NMax", "FAbs", "SAbs", "FSign", "SSign",
         "Floor", "Ceil", "Fract", "Trunc", "Round", "RoundEven", "Fma", "Step", "FindUMsb", "FindILsb"}
ALU_2N = {"FClamp", "UClamp", "SClamp", "NClamp", "FMix", "SmoothStep"}
FREE = {"OpCompositeExtract", "OpCompositeConstruct", "OpVectorShuffle", "OpCopyObject", "OpPhi", "OpBitcast",
        "OpAccessChain", "OpInBoundsAccessChain", "OpLabel", "OpBranch", "OpBranchConditional", "OpSwitch",
        "OpLoopMerge", "OpSelectionMerge", "OpLine", "OpNoLine", "OpReturn", "OpReturnValue", "OpUndef",
        "OpControlBarrier", "OpMemoryBarrier", "OpVariable", "OpKill", "OpUnreachable", "OpImage",
        "OpSampledImage", "OpCompositeInsert"}
KEYS = ["alu", "sfu", "f64", "ld_g", "ld_s", "ld_t", "ld_u", "st", "atom"]


def parse(path):
    lines = open(path).read().splitlines()
    comps, is64, ptr_sc, typ, glsl = {}, {}, {}, {}, None
    blocks, order, cur, line = {}, [], None, 0
    for raw in lines:
        s = raw.strip()
        if not s or s.startswith(";"):
            continue
        m = re.match(r"(%\S+) = (Op\w+)\s*(.*)", s)
        res, op, rest = (m.group(1), m.group(2), m.group(3).split()) if m else (None, s.split()[0], s.split()[1:])
        if op == "OpExtInstImport" and "GLSL.std.450" in s:
            glsl = res
        elif op in ("OpTypeFloat", "OpTypeInt"):
            comps[res] = 1; is64[res] = rest[0] == "64"
        elif op == "OpTypeBool":
            comps[res] = 1; is64[res] = False
        elif op == "OpTypeVector":
            comps[res] = int(rest[1]); is64[res] = is64.get(rest[0], False)
        elif op == "OpTypeMatrix":
            comps[res] = comps[rest[0]] * int(rest[1]); is64[res] = is64.get(rest[0], False)
        elif op == "OpTypePointer":
            ptr_sc[res] = rest[0]
        if op == "OpLine":
            line = int(rest[1]); continue
        if res and rest and op not in ("OpTypePointer", "OpTypeVector", "OpTypeFloat", "OpTypeInt", "OpLabel"):
            typ[res] = rest[0]
        if op == "OpLabel":
            cur = res; order.append(res)
            blocks[res] = {"ins": [], "succ": [], "merge": None, "cont": None, "line": line}
            continue
        if cur is None:
            continue
        b = blocks[cur]
        if op == "OpLoopMerge":
            b["merge"], b["cont"], b["line"] = rest[0], rest[1], line
        elif op == "OpBranch":
            b["succ"] = [rest[0]]
        elif op == "OpBranchConditional":
            b["succ"] = rest[1:3]
        elif op == "OpSwitch":
            b["succ"] = [rest[1]] + rest[3::2]
        b["ins"].append((res, op, rest))
        if op in ("OpReturn", "OpReturnValue", "OpKill", "OpUnreachable", "OpBranch", "OpBranchConditional", "OpSwitch"):
            cur = None
    return blocks, order, comps, is64, ptr_sc, typ, glsl


def cost_block(b, comps, is64, ptr_sc, typ, glsl):
    c = dict.fromkeys(KEYS, 0)
    for ins in b["ins"]:
        c = add(c, cost_ins(ins, comps, is64, ptr_sc, typ, glsl))
    return c


def cost_ins(ins, comps, is64, ptr_sc, typ, glsl):
    c = dict.fromkeys(KEYS, 0)
    res, op, rest = ins
    t = rest[0] if rest else None
    n = comps.get(t, 1)
    wide = is64.get(t, False)
    if op in FREE:
        return c
    if op == "OpLoad":
        # buffers (Uniform + BufferBlock in GL SPIR-V 1.0), shared memory, loose uniforms;
        # Function / Private / Input are registers
        sc = ptr_sc.get(typ.get(rest[1]), "?")
        if sc not in ("Function", "Private", "Input"):
            c[{"Uniform": "ld_g", "StorageBuffer": "ld_g", "Workgroup": "ld_s"}.get(sc, "ld_u")] += 1
        return c
    if op == "OpStore":
        sc = ptr_sc.get(typ.get(rest[0]), "?")
        if sc not in ("Function", "Private", "Output"):
            c["st"] += 1
        return c
    if op.startswith("OpAtomic"):
        c["atom"] += 1; return c
    if op.startswith("OpImage"):
        c["ld_t"] += 1; return c
    if op == "OpExtInst" and rest[1] == glsl:
        f = rest[2]
        if f in SFU1: c["sfu"] += n
        elif f == "Pow": c["sfu"] += 2 * n; c["alu"] += n
        elif f in POLY: c["sfu"] += n; c["alu"] += 12 * n
        elif f in ("Length", "Distance"):
            m = comps.get(typ.get(rest[3]), 1); c["alu"] += m + (m if f == "Distance" else 0); c["sfu"] += 1
        elif f == "Normalize": c["alu"] += 2 * n; c["sfu"] += 1
        elif f == "Cross": c["alu"] += 6
        elif f in ALU_2N: c["alu"] += 2 * n
        else: c["alu"] += n
        return c
    if op == "OpDot":
        n = comps.get(typ.get(rest[1]), 1)
    elif op == "OpMatrixTimesVector":
        n = comps.get(typ.get(rest[1]), 1)
    elif op in ("OpAny", "OpAll"):
        n = max(comps.get(typ.get(rest[1]), 1) - 1, 0)
    elif op.startswith(("OpFOrd", "OpFUnord", "OpIEqual", "OpINotEqual", "OpULess", "OpUGreater", "OpSLess", "OpSGreater")):
        wide = is64.get(typ.get(rest[1]), False)
    if op in ("OpFDiv", "OpFRem", "OpFMod"):
        c["f64" if wide else "alu"] += n; c["sfu"] += n
    elif op in ("OpUDiv", "OpSDiv", "OpUMod", "OpSMod", "OpSRem"):
        c["alu"] += 10 * n; c["sfu"] += n   # an integer divide: a reciprocal and corrections
    elif op in ("OpConvertUToF", "OpConvertSToF", "OpConvertFToU", "OpConvertFToS", "OpFConvert"):
        c["f64" if wide or is64.get(typ.get(rest[1]), False) else "alu"] += n
    else:
        c["f64" if wide else "alu"] += n
    return c


def add(a, b):
    return {k: a[k] + b[k] for k in KEYS}


# latencies in cycles (Volta..Hopper microbenchmarks, Jia et al. 2018/2019): FP32/INT ALU 4,
# SFU (MUFU) ~20, shared memory ~25, global / texture (L1 / L2 hit) ~100
LAT = {"alu": 4, "sfu": 20, "ld_s": 25, "ld_g": 100, "ld_t": 100, "atom": 100}


def latency(ins, comps, is64, ptr_sc, typ, glsl):
    """One iteration of one warp: the longest dependency chain (critical path: perfect
    scheduling), and an in-order issue of the SPIR-V order (a warp issues in order and stalls
    on an operand not ready; the driver's reordering lies between the two). Values from earlier
    iterations (phis) count as ready."""
    ready, depth, t, cp = {}, {}, 0, 0
    for res, op, rest in ins:
        c = cost_ins((res, op, rest), comps, is64, ptr_sc, typ, glsl)
        slots = sum(c[k] for k in ("alu", "sfu", "f64", "ld_g", "ld_s", "ld_t", "st", "atom"))
        ops = [o for o in rest if o.startswith("%")]
        if op == "OpPhi":
            continue
        lat = 0
        if slots:
            lat = max(LAT[k] for k in LAT if c[k]) if any(c[k] for k in LAT) else 4
            if c["sfu"] and c["alu"]:
                lat += 4 * min(c["alu"], 3)
            elif c["alu"] and op in ("OpDot", "OpExtInst"):
                lat = 4 * min(c["alu"], 3)
        d0 = max([depth.get(o, 0) for o in ops] + [0])
        r0 = max([ready.get(o, 0) for o in ops] + [0])
        start = max(t, r0)
        t = start + slots
        if res:
            depth[res] = d0 + lat
            ready[res] = start + max(slots - 1, 0) + lat
            cp = max(cp, depth[res])
    return cp, max([t] + list(ready.values()))


def weight(c):   # warp issue slots, used only to pick the costliest path
    return c["alu"] + c["sfu"] * 8 + c["f64"] * 2 + c["ld_g"] * 4 + c["ld_s"] + c["ld_t"] * 4 + c["st"] + c["atom"] * 4


def loops(blocks, comps, is64, ptr_sc, typ, glsl):
    cost = {l: cost_block(b, comps, is64, ptr_sc, typ, glsl) for l, b in blocks.items()}
    heads = [l for l, b in blocks.items() if b["merge"]]
    bodies = {}
    for h in heads:
        merge, cont = blocks[h]["merge"], blocks[h]["cont"]
        body, stack = set(), [h]
        while stack:   # the blocks reachable from the header without its merge or the back edge
            x = stack.pop()
            if x in body or x == merge:
                continue
            body.add(x)
            if x != cont:
                stack.extend(s for s in blocks[x]["succ"] if s != h)
        bodies[h] = body
    out = []
    for h in heads:
        merge, cont, body = blocks[h]["merge"], blocks[h]["cont"], bodies[h]
        inner = [o for o in heads if o != h and o in body]
        own = body - set().union(*[bodies[o] for o in inner]) if inner else body
        every = dict.fromkeys(KEYS, 0)   # every block once: what a CPU that masks both sides of a branch runs
        for x in own:
            every = add(every, cost[x])
        # the costliest and the cheapest path header -> continue block over the body's DAG; a
        # nested loop is passed through its merge block (its iterations are not counted here)
        memo = {}
        def walk(x, pick):   # (counts, blocks) of the costliest / cheapest path from x to the continue block
            key = (x, pick)
            if key in memo:
                return memo[key]
            if x == cont:
                r = (cost[x], [x])
            else:
                best = None
                nxt = [s for s in blocks[x]["succ"] if s in body and s != h]
                if blocks[x]["merge"] and blocks[x]["cont"] and x != h:   # a nested loop: on from its merge
                    nxt = [blocks[x]["merge"]] if blocks[x]["merge"] in body else []
                for s in nxt:
                    r = walk(s, pick)
                    if r is not None and (best is None or (weight(r[0]) > weight(best[0])) == (pick == "max")):
                        best = r
                r = None if best is None else (add(cost[x], best[0]), [x] + best[1])
            memo[key] = r
            return r
        sys.setrecursionlimit(100000)
        hi, lo = walk(h, "max"), walk(h, "min")
        if hi is None:
            continue
        ins = [i for x in hi[1] for i in blocks[x]["ins"]]
        cp, seq = latency(ins, comps, is64, ptr_sc, typ, glsl)
        hi, lo = hi[0], lo[0]
        out.append({"line": blocks[h]["line"] - 1, "innermost": not inner, "max": hi, "min": lo, "every": every,
                    "critical_path": cp, "in_order": seq})
    return sorted(out, key=lambda r: r["line"])


def whole(blocks, order, comps, is64, ptr_sc, typ, glsl):
    """A shader without hot loops (fragment shaders): the costliest path through main, loops once."""
    tot = dict.fromkeys(KEYS, 0)
    for l in order:
        tot = add(tot, cost_block(blocks[l], comps, is64, ptr_sc, typ, glsl))
    return tot


if __name__ == "__main__":
    res = {}
    for p in sys.argv[1:]:
        parsed = parse(p)
        res[p] = {"loops": loops(parsed[0], *parsed[2:]), "all_blocks": whole(*parsed)}
    json.dump(res, sys.stdout, indent=1)
