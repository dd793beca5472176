#!/usr/bin/env bash
# Where a lent GPU spends a near-empty frame (2026-12-04, H200): the generated 100k city's walk
# and street in brute, hzb and oracle at three sizes, once more without its streets and ground
# areas, with the GPU's clocks logged by nvidia-smi dmon. Set up as bench.sh says; two minutes.
set -u
repo=$(pwd)
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
cw="$repo/.devrun/citywalk"; chmod +x "$cw"
W=/tmp/cw2; mkdir -p "$W/res"; cd "$W"; R="$W/res"
log() { echo "[$(date +%T) +${SECONDS}s] $*" | tee -a "$R/progress.txt"; }
pack() { tar czf "$OUT/results2.tar.gz" -C "$W" res 2>/dev/null; }
(nvidia-smi dmon -s pc -d 1 > "$R/dmon.txt" 2>&1 &)
nvidia-smi -q -d CLOCK,PERFORMANCE > "$R/clocks-before.txt" 2>&1
"$cw" generate --buildings 100000 --seed 1 -o g100k.geojson > /dev/null 2>&1
python3 -c "
import json; d=json.load(open('g100k.geojson'))
d['features']=[f for f in d['features'] if f['geometry']['type']!='LineString']
json.dump(d, open('g100k-nostreets.geojson','w'))"
"$cw" preprocess g100k-nostreets.geojson -o nostreets.cwk > /dev/null 2>&1 &
"$cw" preprocess g100k.geojson -o g100k.cwk > /dev/null 2>&1
wait; log "packages ready"
bench() { local name=$1; shift
  log "bench $name: $*"; echo "citywalk bench $*" > "$R/$name-command.txt"
  timeout 120 "$cw" bench "$@" --out "$W/$name" --png-every 0 > "$R/$name.log" 2>&1; log "rc=$?"
  mkdir -p "$R/$name"; cp "$W/$name"/{bench.json,summary.md,frames.csv} "$R/$name/" 2>/dev/null; pack; }
for size in 640x360 1920x1080 3840x2160; do
  bench "streets-$size" g100k.cwk --paths walk,street --modes brute,hzb,oracle --frames 30 --size $size
done
bench nostreets-1920x1080 nostreets.cwk --paths walk,street --modes brute,hzb,oracle --frames 30 --size 1920x1080
nvidia-smi -q -d CLOCK,PERFORMANCE > "$R/clocks-after.txt" 2>&1
pkill nvidia-smi; pack; log done
