#!/usr/bin/env bash
# The benchmark on a lent GPU machine (issue 13: "on a real GPU when one is lent, run the
# benchmark there with one prepared script and record the device"), as run on 2026-12-04
# (results in .ci/device/h200-2026-12-04/, notes in BENCHMARKS.md). About six minutes on an
# H200 machine of 16 cores; nothing there can be fetched, so everything travels with the tree:
#
#   echo /.devrun/ >> .git/info/exclude          # once; and the Vulkan loader in .gl/ as the
#   mkdir -p .devrun                              # device tool's README says
#   strip -o .devrun/citywalk target/release/citywalk; git rev-parse --short HEAD > .devrun/commit
#   cp ../shared/data/osm_porto_center/porto.osm.pbf ../shared/data/cityjson_denhaag/DenHaag_01.json .devrun/
#   device run: bash .ci/device/bench.sh   (carry .gl and .devrun; timeout 590 s)
#
# Results go to $OUT/results.tar.gz after every step, so a run cut off still returns them.
set -u
repo=$(pwd)
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
cw="$repo/.devrun/citywalk"; chmod +x "$cw"
W=/tmp/cw; mkdir -p "$W/res"; cd "$W"
R="$W/res"
log() { echo "[$(date +%T) +${SECONDS}s] $*" | tee -a "$R/progress.txt"; }
pack() { tar czf "$OUT/results.tar.gz" -C "$W" res 2>/dev/null; cp "$R/progress.txt" "$OUT/" 2>/dev/null; }
{
  echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//') ($(nproc) cores)"
  echo "memory: $(free -g | awk '/Mem:/ {print $2}') GiB"
  echo "os: $(. /etc/os-release && echo "$PRETTY_NAME")"
  echo "gpu: $(nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader)"
  echo "citywalk: $(cat "$repo/.devrun/commit" 2>/dev/null || echo unknown)"
} > "$R/machine.txt" 2>&1
cat "$R/machine.txt"
# The adapter: one frame rendered, or the driver path given explicitly.
if ! timeout 60 "$cw" render "$repo/scenes/data/chelsea.osm.pbf" --size 320x240 -o "$R/probe.png" > "$R/probe.txt" 2>&1; then
  log "probe failed; retrying with VK_DRIVER_FILES"; cat "$R/probe.txt"
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
  timeout 60 "$cw" render "$repo/scenes/data/chelsea.osm.pbf" --size 320x240 -o "$R/probe.png" > "$R/probe.txt" 2>&1 \
    || { log "no adapter"; cat "$R/probe.txt"; pack; exit 3; }
fi
cat "$R/probe.txt"; log "adapter ok"
# The 1M city in the background (preprocessing is single-threaded; it overlaps the rest).
T=""; [ -x /usr/bin/time ] && T="/usr/bin/time -v"
( $T "$cw" generate --buildings 1000000 --seed 1 -o g1m.geojson > gen1m.txt 2>&1 &&
  $T "$cw" preprocess g1m.geojson -o g1m.cwk --json > "$R/preprocess-1m.json" 2> pre1m.err;
  touch g1m.done ) &
"$cw" generate --buildings 100000 --seed 1 -o g100k.geojson > /dev/null 2>&1
"$cw" preprocess g100k.geojson -o g100k.cwk --json > "$R/preprocess-100k.json" 2>&1
"$cw" preprocess "$repo/scenes/data/chelsea.osm.pbf" -o chelsea.cwk > /dev/null 2>&1
"$cw" preprocess "$repo/.devrun/porto.osm.pbf" -o porto.cwk > /dev/null 2>&1
"$cw" preprocess "$repo/.devrun/DenHaag_01.json" -o denhaag.cwk > /dev/null 2>&1
log "packages ready"; pack
bench() { # name timeout args...
  local name=$1 t=$2; shift 2
  log "bench $name: citywalk bench $*"
  echo "citywalk bench $*" > "$R/$name-command.txt"
  timeout "$t" "$cw" bench "$@" --out "$W/$name" --png-every 0 > "$R/$name.log" 2>&1
  log "bench $name rc=$?"
  mkdir -p "$R/$name"; cp "$W/$name"/{bench.json,summary.md,frames.csv} "$R/$name/" 2>/dev/null; pack
}
ALL=brute,frustum,quadtree,hzb,occluders,lod,all,auto,oracle
bench 100k-1080p 200 g100k.cwk --paths street,walk,flyover --modes "$ALL" --frames 30 --size 1920x1080
bench bundled-720p 120 chelsea.cwk porto.cwk denhaag.cwk --modes brute,all,auto,oracle --frames 30 --size 1280x720
log "waiting for the 1M package"
while [ ! -f g1m.done ] && [ "$SECONDS" -lt 430 ]; do sleep 2; done
cp gen1m.txt pre1m.err "$R/" 2>/dev/null
[ -f g1m.done ] || { log "1M package not ready in time"; pack; exit 4; }
$T "$cw" bench g1m.cwk --paths walk,street,flyover --modes brute,all,auto,oracle --frames 30 --size 1920x1080 --out "$W/1m-1080p" --png-every 0 > "$R/1m-1080p.log" 2>&1 &
bpid=$!; log "bench 1m-1080p"
while kill -0 $bpid 2>/dev/null && [ "$SECONDS" -lt 570 ]; do sleep 2; done
kill $bpid 2>/dev/null; wait $bpid; log "bench 1m-1080p rc=$?"
mkdir -p "$R/1m-1080p"; cp "$W/1m-1080p"/{bench.json,summary.md,frames.csv} "$R/1m-1080p/" 2>/dev/null
pack; log done
