#!/usr/bin/env python3
"""Assembles BENCHMARKS.md from the raw outputs of .ci/benchmarks.sh (argument: its out folder).

Every number printed here is read from those files; nothing is typed in by hand.
"""
import json
import sys
from pathlib import Path

out = Path(sys.argv[1])


def load(name):
    return json.loads((out / name).read_text())


def mib(b):
    return b / (1024 * 1024)


print("# citywalk benchmarks\n")
print("Regenerate everything on this page with one command (release build, about 15 minutes on 2 cores):\n")
print("```sh\nbash .ci/setup.sh && bash .ci/benchmarks.sh\n```\n")
print("Raw outputs (JSON, CSV, PNG) are written to `out/benchmarks/`. On a software adapter")
print("(lavapipe) compare ratios within one run; absolute times mean something only on a real GPU.\n")
print("## Machine\n")
print("```")
print((out / "machine.txt").read_text().strip())
bench = load("bench/bench.json")
a = bench["adapter"]
print(f"adapter: {a['name']} ({a['backend']}, {a['device_type']})")
print("```\n")

print("## Preprocessing (`citywalk preprocess INPUT -o scene.cwk --json`)\n")
print("Generated cities: `citywalk generate --buildings N --seed 1`. Times in seconds, wall clock;")
print("generated 10k and 100k: the fastest of three runs (they give the n log n ratio below).\n")
rows = [
    ("generated 10k", "generated-10k"),
    ("generated 100k", "generated-100k"),
    ("generated 1M", "generated-1m"),
    ("Porto (OSM)", "porto"),
    ("Chelsea (OSM)", "chelsea"),
    ("Den Haag (CityJSON LoD2)", "denhaag"),
]
stages = ["blocks", "occluders", "cluster tree", "quadtree", "gpu scene", "package"]
print("| input | buildings loaded / found | load | " + " | ".join(stages)
      + " | write | total | buildings/s | package | peak memory |")
print("|---|---:|" + "---:|" * (len(stages) + 7))
totals = {}
for label, key in rows:
    p = out / f"preprocess-{key}.json"
    if not p.exists():
        continue
    j = json.loads(p.read_text())
    st = dict((s, t) for s, t in j["stage_seconds"])
    totals[key] = j["total_seconds"]
    rate = j["buildings_loaded"] / j["total_seconds"] if j["total_seconds"] > 0 else 0
    print(f"| {label} | {j['buildings_loaded']:,} / {j['buildings_found']:,} | {j['load_seconds']:.2f} | "
          + " | ".join(f"{st.get(s, 0.0):.2f}" for s in stages)
          + f" | {j['write_seconds']:.2f} | {j['total_seconds']:.2f} | {rate:,.0f} | "
          f"{mib(j['package_bytes']):.1f} MiB | {mib(j['peak_memory_bytes']):.0f} MiB |")
if "generated-10k" in totals and "generated-100k" in totals:
    print(f"\ntime(100k) / time(10k) = {totals['generated-100k'] / totals['generated-10k']:.1f} "
          "(target ≤ 12, n log n).")
print()

print("## Virtual occluders (`citywalk inspect occluders SCENE --json`)\n")
print("Occlusion-preserving quality after Germs & Jansen §4.1: silhouette pixels of the occluder ÷ of")
print("the building, from 16 viewpoints on a circle at half the building's height (CPU raster, 128 px).")
print("Polygons are planar faces as in the paper's Table 1 (a wall quad is one polygon, a roof polygon")
print("one), counted the same way on the source mesh and on the occluders; triangles beside them.")
print("Wall-oriented facades, levels chosen by silhouette gain per polygon (the defaults).\n")
print("| scene | buildings | with occluders | source polygons | occluder polygons | reduction | "
      "source triangles | occluder triangles | reduction | "
      "quality mean | min | p5 | p25 | p50 | buildings/s |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")


def occluder_row(label, j):
    s = j["summary"]
    return (f"| {label} | {s['buildings']} | {s['buildings_with_occluders']} | {s['source_polygons']:,} | "
            f"{s['occluder_polygons']:,} | {s['polygon_reduction']:.2f}× | {s['source_triangles']:,} | "
            f"{s['occluder_triangles']:,} | {s['triangle_reduction']:.2f}× | {100 * s['quality_mean']:.1f} % | "
            f"{100 * s['quality_min']:.1f} % | {100 * s['quality_p5']:.1f} % | {100 * s['quality_p25']:.1f} % | "
            f"{100 * s['quality_p50']:.1f} % | {j['buildings_per_second']:,.0f} |")


for label, key in [("Den Haag (LoD2 meshes)", "denhaag"), ("Chelsea (2.5D)", "chelsea")]:
    p = out / f"occluders-{key}.json"
    if p.exists():
        print(occluder_row(label, json.loads(p.read_text())))
for label, key in [("Den Haag", "denhaag")]:
    p = out / f"occluders-{key}.json"
    if p.exists():
        j = json.loads(p.read_text())
        h = j["summary"]["quality_histogram"]
        bins = ", ".join(f"{10 * i}–{10 * (i + 1)} %: {n}" for i, n in enumerate(h[:10]) if n)
        print(f"\n{label} quality distribution (buildings per 10 % bin): {bins}.")
        w = j.get("outline_walls")
        if w:
            target = j["summary"]["source_polygons"] / 5
            print(f"\n{label} outlines alone (one level, one wall per simplified footprint edge): "
                  f"{w['per_building']:,} walls building by building, {w['merged_blocks']:,} with adjacent "
                  f"buildings merged into {w['blocks']:,} blocks; 5× fewer polygons than the source means "
                  f"at most {target:,.0f}.")
tradeoff = [
    ("benefit rule, no roof samples (the paper's method)", "paper"),
    ("benefit rule, sloped roofs sampled every 2 m", "benefit-roof-samples"),
    ("silhouette gain ≥ 0.4 % per polygon", "gain-0.004"),
    ("silhouette gain ≥ 1.6 % per polygon (default)", None),
    ("silhouette gain ≥ 3.2 % per polygon", "gain-0.032"),
    ("silhouette gain ≥ 10 % per polygon", "gain-0.1"),
    ("lowest level only (outline)", "outline-only"),
    ("beyond the paper: single walls (roofs sampled every 1 m), gain ≥ 1.5 % per wall", "walls-0.015"),
    ("beyond the paper: single walls (roofs sampled every 1 m), gain ≥ 2 % per wall", "walls-0.02"),
    ("beyond the paper: single walls (roofs sampled every 1 m), gain ≥ 5 % per wall", "walls-0.05"),
]
rows = []
for label, key in tradeoff:
    p = out / (f"occluders-denhaag-tradeoff-{key}.json" if key else "occluders-denhaag.json")
    if p.exists():
        rows.append(occluder_row(label, json.loads(p.read_text())))
if rows:
    print("\n**Den Haag trade-off** (`--min-gain`, `--sloped-roof-step`, `--benefit-threshold`):\n")
    print("| level selection | buildings | with occluders | source polygons | occluder polygons | reduction | "
          "source triangles | occluder triangles | reduction | "
          "quality mean | min | p5 | p25 | p50 | buildings/s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    print("\n".join(rows))
print()

print("## Cluster tree: polygons and triangles per level (`citywalk inspect tree SCENE.cwk`)\n")
print("Polygons (planar faces) and triangles drawn when the whole city is shown at one level of the")
print("package's legibility tree, against the input (Chang et al. report 285,039 → 131,409 polygons")
print("at ε = 100, τ = 2).\n")
for label, key in [("Chelsea", "chelsea"), ("Porto", "porto")]:
    p = out / f"tree-{key}.txt"
    if p.exists():
        lines = [l.replace(str(out.resolve()), "out/benchmarks") for l in p.read_text().splitlines()]
        print(f"**{label}** ({lines[0]}): " + lines[1] + "\n")
        print("```")
        print("\n".join(lines[2:]))
        print("```\n")

print("## Occlusion benchmark (`citywalk bench`)\n")
command = out / "bench-command.txt"
if command.exists():
    print("Run in `out/benchmarks/` (the packages made above):\n")
    print("```sh\n" + command.read_text().strip() + "\n```\n")
modes = sorted({e["mode"] for e in bench["entries"]})
print(f"Modes measured: {', '.join(modes)}. Every frame of every mode is checked against the exact")
print("ID-buffer oracle; *false culls* must be 0. Frame time is CPU wall time around recording,")
print("submission and GPU completion: median over the path, and its tail as p95, p99 (nearest rank)")
print("and max; speed-up is brute force's median ÷ the mode's, same scene and path, same run.")
print("`oracle` draws exactly the buildings the oracle sees in one plain pass (finding them is not")
print("timed): the fastest any culling could be; *÷ oracle* is the mode's median ÷ the oracle's.")
print("*CPU ms* is the engine's own thread CPU time per frame (selection, recording and submission,")
print("not the wait for the GPU): median / p99 / max. Pixel error after Chang et al. §9 (share of")
print("pixels whose grey level differs / whose colour differs by more than 40 in a channel).\n")
print("On a software adapter (device type Cpu, lavapipe) the tables quote no absolute frame or GPU")
print("times: frame cost is the speed-up over brute force and the ratio to the oracle in the same")
print("run, the tail is p95, p99 and max ÷ the mode's own median, GPU phases are shares of the")
print("frame's timestamped GPU time (on lavapipe compute-pass timestamps are not credible: the cull")
print("reads ~0.005 ms). CPU ms is the engine's own work on the CPU and is printed on every adapter.")
print("Absolute frame milliseconds are printed for real GPUs only; `bench.json` and `frames.csv`")
print("keep them always.\n")

def times(ratio):
    """A ratio as `2.50×`, or `–` where bench.json has none (null: no brute or oracle run)."""
    return "–" if ratio is None else f"{ratio:.2f}×"


# The runtime's targets (issue 6), read from the same entries: at street level >= 99 % culled
# and drawn <= 1.5 x the exactly visible set; frame cost vs brute >= 20x (street) and >= 10x
# (flyover) -- the last two mean something only on a real GPU.
entries = {(e["scene"], e["path"], e["mode"]): e for e in bench["entries"]}
best = next((m for m in ("all", "occluders") if m in modes), None)
if best:
    print(f"**Targets of the runtime, mode `{best}`** (street level: culled ≥ 99 %, drawn ≤ 1.5 × visible;")
    print("speed-up ≥ 20× street and ≥ 10× flyover, judged on a real GPU only). `walk` is the")
    print("walkthrough (3 m per frame): the two-phase cull draws last frame's visible set first (the")
    print("part of it the occluders' own pyramid does not hide: the occluder gate), and `street`")
    print("spreads its frames over the whole route, hundreds of metres apart in the large cities, so")
    print("that each of its frames is nearly a cold start:\n")
    print("| scene | path | culled | drawn ÷ visible | speed-up | ÷ oracle | flyover speed-up | dive speed-up |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")

    def speed(scene, path):
        e = entries.get((scene, path, best))
        return f"{e['speedup_vs_brute']:.2f}×" if e and e.get("speedup_vs_brute") else "–"

    for scene in sorted({e["scene"] for e in bench["entries"]}):
        for path in ("street", "walk"):
            st = entries.get((scene, path, best))
            if not st:
                continue
            ratio = st["drawn_mean"] / st["visible_mean"] if st["visible_mean"] else float("nan")
            print(f"| {scene} | {path} | {100 * st['culled_fraction_mean']:.1f} % | {ratio:.2f} "
                  f"| {speed(scene, path)} | {times(st.get('oracle_ratio'))} "
                  f"| {speed(scene, 'flyover')} | {speed(scene, 'dive')} |")
    print()


def bench_tables(bench):
    """The benchmark's tables from bench.json. On a software adapter (device type Cpu) no
    absolute frame or GPU time is printed: frame cost as the speed-up over brute force and the
    ratio to the oracle (same scene, path and run), the tail (p95, p99, max) as multiples of the
    mode's median, and GPU phases as shares of the frame's timestamped GPU time. CPU ms (the
    engine's thread CPU time) is printed on every adapter."""
    software = bench["adapter"]["device_type"] == "Cpu"
    a = bench["adapter"]
    print(f"Adapter: {a['name']} ({a['backend']}, {a['device_type']}); "
          f"{bench['size'][0]}×{bench['size'][1]} pixels.\n")
    cols = ["scene", "path", "mode", "frames", "false culls", "visible", "drawn", "clusters",
            "culled", "triangles", "draw calls"]
    if software:
        cols += ["frame p95 / p99 / max ÷ median"]
    else:
        cols += ["frame ms (median)", "p95", "p99", "max", "GPU ms (median)"]
    cols += ["CPU ms (median / p99 / max)", "speed-up vs brute", "÷ oracle", "pixel error (grey / colour)"]
    print("| " + " | ".join(cols) + " |")
    print("|---|---|---|" + "---:|" * (len(cols) - 3))
    for e in bench["entries"]:
        row = [e["scene"], e["path"], e["mode"], str(e["frames"]), str(e["false_culls"]),
               f"{e['visible_mean']:.1f}", f"{e['drawn_mean']:.1f}", f"{e['clusters_mean']:.1f}",
               f"{100 * e['culled_fraction_mean']:.1f} %", f"{e['triangles_mean']:.0f}",
               f"{e['draw_calls_mean']:.1f}"]
        median = e["frame_ms_median"]
        tail = [e["frame_ms_p95"], e["frame_ms_p99"], e["frame_ms_max"]]
        if software:
            row += [" / ".join(f"{t / median:.2f}" for t in tail) if median > 0 else "–"]
        else:
            gpu = e.get("gpu_ms_median")
            row += [f"{median:.2f}"] + [f"{t:.2f}" for t in tail] + ["n/a" if gpu is None else f"{gpu:.2f}"]
        row += [f"{e['cpu_ms_median']:.2f} / {e['cpu_ms_p99']:.2f} / {e['cpu_ms_max']:.2f}",
                times(e.get("speedup_vs_brute")), times(e.get("oracle_ratio")),
                f"{100 * e['pixel_error_mean']:.2f} % / {100 * e['pixel_error_colour_mean']:.2f} %"]
        print("| " + " | ".join(row) + " |")
    timed = [e for e in bench["entries"] if e.get("gpu_phase_ms_median")]
    if timed:
        phases = []
        for e in timed:
            for name in e["gpu_phase_ms_median"]:
                if name not in phases:
                    phases.append(name)
        if software:
            print("\nGPU time per phase from timestamp queries, as a share of the frame's timestamped"
                  " GPU time (medians):\n")
        else:
            print("\nGPU time per phase from timestamp queries (median ms):\n")
        print("| scene | path | mode | " + " | ".join(phases) + " |")
        print("|---|---|---|" + "---:|" * len(phases))
        for e in timed:
            ms = e["gpu_phase_ms_median"]
            total = sum(ms.values())

            def cell(name):
                if name not in ms:
                    return "–"
                if software:
                    return f"{100 * ms[name] / total:.0f} %" if total > 0 else "–"
                return f"{ms[name]:.3f}"

            print(f"| {e['scene']} | {e['path']} | {e['mode']} | " + " | ".join(cell(p) for p in phases) + " |")
    if any(e["mode"] == "decimated" for e in bench["entries"]):
        print("\n`decimated`: the whole city decimated with meshoptimizer to a triangle budget and drawn"
              " unculled (the baseline a user would pick instead); its false culls are visible buildings"
              " with no triangles left and do not fail the benchmark.")


bench_tables(bench)

bench_1m = out / "bench-1m/bench.json"
if bench_1m.exists():
    big = json.loads(bench_1m.read_text())
    print("\n## The generated 1M city (`citywalk bench`)\n")
    command = out / "bench-1m-command.txt"
    if command.exists():
        print("Run in `out/benchmarks/`:\n")
        print("```sh\n" + command.read_text().strip() + "\n```\n")
    for s in big["scenes"]:
        print(f"Package `{s['scene']}`: {s['buildings']:,} buildings, ready to draw in "
              f"{s['ready_s']:.1f} s, {s['resident_mib']:,.0f} MiB resident then "
              f"({s['gpu_allocated_mib']:,.0f} MiB of it allocated through Vulkan); the whole "
              f"run peaked at {big['peak_resident_mib']:,.0f} MiB resident.\n")
    bench_tables(big)

# The hand-written sections (the 1M city, memory, one-off comparisons), kept across regenerations.
notes = Path(__file__).with_name("benchmarks_notes.md")
if notes.exists():
    text = notes.read_text()
    if text.startswith("<!--"):
        text = text[text.index("-->") + 3:]
    print("\n" + text.strip())

demo = out / "demo-ms.txt"
if demo.exists():
    print("\n## The main job (`citywalk demo`)\n")
    print(f"`citywalk demo` (preprocess the bundled Chelsea extract, street walk and flyover in mode `all`"
          f" against `brute`, PNG frames and the summary) took {int(demo.read_text()) / 1000:.1f} s of wall"
          " time on this machine, release build (target: under two minutes).")
