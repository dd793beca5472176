#!/usr/bin/env bash
# Regenerates BENCHMARKS.md: every figure in it comes from one run of this script.
#
#   bash .ci/benchmarks.sh            # full set (generated 10k / 100k / 1M, Porto, Chelsea, Den Haag)
#   FRAMES=20 bash .ci/benchmarks.sh  # fewer frames per camera path
#
# Needs ../shared/data beside the repository (the project's real datasets) and a release build;
# writes its raw outputs under out/benchmarks/ and BENCHMARKS.md at the repository root.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
data="$root/../shared/data"
out="$root/out/benchmarks"
frames="${FRAMES:-30}"
size="${SIZE:-1280x720}"
mkdir -p "$out"
if [ -f /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ] && [ -z "${VK_ICD_FILENAMES:-}" ] \
  && ! command -v nvidia-smi >/dev/null 2>&1; then
  export VK_ICD_FILENAMES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
fi

if [ -n "${CITYWALK_BIN:-}" ]; then
  cw="$(realpath "$CITYWALK_BIN")" # a binary built elsewhere (for example copied to a GPU machine)
else
  cargo build --release -p citywalk --bin citywalk
  cw="$root/target/release/citywalk"
fi

echo "== machine" >&2
{
  echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//') ($(nproc) cores)"
  echo "memory: $(free -g | awk '/Mem:/ {print $2}') GiB"
  echo "os: $(. /etc/os-release && echo "$PRETTY_NAME")"
  echo "rustc: $(rustc --version)"
  echo "citywalk: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg) (other work on the machine inflates times)"
  if command -v nvidia-smi >/dev/null 2>&1; then
    echo "gpu: $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)"
  fi
} > "$out/machine.txt"

echo "== generated cities" >&2
for n in 10000 100000 1000000; do
  f="$out/generated-$n.geojson"
  [ -f "$f" ] || "$cw" generate --buildings "$n" --seed 1 -o "$f"
done

echo "== preprocessing" >&2
preprocess() { # name input...
  local name=$1; shift
  "$cw" preprocess "$@" -o "$out/$name.cwk" --json > "$out/preprocess-$name.json"
}
# The n log n check (time(100k) / time(10k)) compares two runs: each of those two cities is
# preprocessed three times and the fastest run kept, so a moment of other load on a shared
# machine does not decide it. Packages are byte-for-byte deterministic, so the kept run's
# package is the same as the others'.
preprocess_best_of_3() { # name input
  local name=$1 best="" t
  for _ in 1 2 3; do
    preprocess "$name" "$2"
    t=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["total_seconds"])' \
      "$out/preprocess-$name.json")
    if [ -z "$best" ] || python3 -c 'import sys; sys.exit(0 if float(sys.argv[1]) < float(sys.argv[2]) else 1)' "$t" "$best"; then
      best=$t
      cp "$out/preprocess-$name.json" "$out/preprocess-$name.best.json"
    fi
  done
  mv "$out/preprocess-$name.best.json" "$out/preprocess-$name.json"
}
preprocess_best_of_3 generated-10k "$out/generated-10000.geojson"
preprocess_best_of_3 generated-100k "$out/generated-100000.geojson"
preprocess generated-1m "$out/generated-1000000.geojson"
preprocess porto "$data/osm_porto_center/porto.osm.pbf"
preprocess chelsea "$root/scenes/data/chelsea.osm.pbf"
preprocess denhaag "$data/cityjson_denhaag/DenHaag_01.json"

echo "== occluders and cluster tree levels" >&2
"$cw" inspect occluders "$out/denhaag.cwk" --json > "$out/occluders-denhaag.json"
"$cw" inspect occluders "$out/chelsea.cwk" --json > "$out/occluders-chelsea.json"
# The quality / polygon trade-off on Den Haag (issue 3): level selection swept from the
# paper's benefit rule to the outline alone.
tradeoff() { "$cw" inspect occluders "$out/denhaag.cwk" --json "${@:2}" > "$out/occluders-denhaag-tradeoff-$1.json"; }
tradeoff paper --min-gain 0 --sloped-roof-step 0
tradeoff benefit-roof-samples --min-gain 0
tradeoff gain-0.004 --min-gain 0.004
tradeoff gain-0.032 --min-gain 0.032
tradeoff gain-0.1 --min-gain 0.1
tradeoff outline-only --min-gain 0 --sloped-roof-step 0 --benefit-threshold 1e9
tradeoff walls-0.015 --select-walls --sloped-roof-step 1 --min-gain 0.015
tradeoff walls-0.02 --select-walls --sloped-roof-step 1 --min-gain 0.02
tradeoff walls-0.05 --select-walls --sloped-roof-step 1 --min-gain 0.05
"$cw" inspect tree "$out/chelsea.cwk" --level 4 -o "$out/tree-chelsea.png" > "$out/tree-chelsea.txt"
"$cw" inspect tree "$out/porto.cwk" --level 4 -o "$out/tree-porto.png" > "$out/tree-porto.txt"

echo "== occlusion benchmark" >&2
modes="${MODES:-$("$cw" bench --list-modes)}"
# The oracle's frame time is what every mode's `oracle_ratio` divides by: always measure it.
if [[ ",$modes," != *",oracle,"* ]]; then modes="$modes,oracle"; fi
# The baseline a user would pick instead: the whole city decimated by meshoptimizer to the
# triangle count of the LOD cut (mode lod; issue 7, after Chang et al. §9).
baseline=""
for m in lod all; do
  if [[ ",$modes," == *",$m,"* ]]; then baseline="--baseline decimate:$m"; break; fi
done
# shellcheck disable=SC2086 # $baseline is empty or two words
bench_args=(bench generated-10k.cwk generated-100k.cwk chelsea.cwk porto.cwk denhaag.cwk
  --out bench --frames "$frames" --size "$size" --modes "$modes" --png-every 0 $baseline)
echo "citywalk ${bench_args[*]}" > "$out/bench-command.txt"
(cd "$out" && "$cw" "${bench_args[@]}")

echo "== the 1M city (issue 13: walk and street at 640x360, ready time and resident memory)" >&2
bench_1m_args=(bench generated-1m.cwk --out bench-1m --frames "${FRAMES_1M:-8}" --size 640x360
  --paths walk,street --modes brute,all,auto,oracle --png-every 0)
echo "citywalk ${bench_1m_args[*]}" > "$out/bench-1m-command.txt"
(cd "$out" && "$cw" "${bench_1m_args[@]}")

echo "== demo (the README's main command; issue 7: under two minutes)" >&2
demo_start=$(date +%s%N)
"$cw" demo --scene "$root/scenes/data/chelsea.osm.pbf" --out "$out/demo" > "$out/demo.txt"
echo $((($(date +%s%N) - demo_start) / 1000000)) > "$out/demo-ms.txt"

echo "== BENCHMARKS.md" >&2
python3 .ci/benchmarks_md.py "$out" > BENCHMARKS.md
echo "wrote BENCHMARKS.md" >&2
