#!/usr/bin/env bash
# Device run 3 (2026-12-04): auto with the two HZB rungs (occluders on a jump or not) beside brute,
# hzb, all and the oracle on the generated 100k city at 1080p and Chelsea and Porto at 720p. Set up as
# bench.sh says; two minutes.
set -u
repo=$(pwd)
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
cw="$repo/.devrun/citywalk"; chmod +x "$cw"
W=/tmp/cw3; mkdir -p "$W/res"; cd "$W"; R="$W/res"
log() { echo "[$(date +%T) +${SECONDS}s] $*" | tee -a "$R/progress.txt"; }
pack() { tar czf "$OUT/results3.tar.gz" -C "$W" res 2>/dev/null; }
(nvidia-smi dmon -s pc -d 1 > "$R/dmon.txt" 2>&1 &)
"$cw" generate --buildings 100000 --seed 1 -o g100k.geojson > /dev/null 2>&1
"$cw" preprocess g100k.geojson -o g100k.cwk > /dev/null 2>&1 &
"$cw" preprocess "$repo/scenes/data/chelsea.osm.pbf" -o chelsea.cwk > /dev/null 2>&1
"$cw" preprocess "$repo/.devrun/porto.osm.pbf" -o porto.cwk > /dev/null 2>&1
wait; log "packages ready"
bench() { local name=$1; shift
  log "bench $name: $*"; echo "citywalk bench $*" > "$R/$name-command.txt"
  timeout 150 "$cw" bench "$@" --out "$W/$name" --png-every 0 > "$R/$name.log" 2>&1; log "rc=$?"
  mkdir -p "$R/$name"; cp "$W/$name"/{bench.json,summary.md,frames.csv} "$R/$name/" 2>/dev/null; pack; }
bench 100k-1080p g100k.cwk --paths street,walk,flyover --modes brute,hzb,all,auto,oracle --frames 30 --size 1920x1080
bench bundled-720p chelsea.cwk porto.cwk --modes brute,auto,oracle --frames 30 --size 1280x720
pkill nvidia-smi; pack; log done
