#!/usr/bin/env bash
# Prints the figures of one tile's cold render and of warm requests per second.
# Usage: scripts/bench.sh [Z/X/Y]   (run from the repository root after a release build)
set -euo pipefail
tile=${1:-14/8529/5973}
bin=target/release/terrastitch
out=$(mktemp -d)
trap 'kill $server 2>/dev/null || true; rm -rf "$out"' EXIT

echo "== cold render of $tile (render command, release build)"
/usr/bin/time -v "$bin" render "$tile" -o "$out/tile.glb" --timings 2> "$out/render.txt" || { cat "$out/render.txt"; exit 1; }
grep -E '^(load|features|structures|roads|triangulation|terrain|elevation|glb|total|triangles|elevation LP:|of which ground roads:) ' "$out/render.txt"
grep -E 'Maximum resident set size|Elapsed \(wall' "$out/render.txt"
ls -l "$out/tile.glb" | awk '{print "glb bytes", $5}'

echo "== warm requests per second (cached tile, loopback)"
"$bin" serve --listen 127.0.0.1:18080 --cache "$out/cache.sqlite" 2> "$out/serve.txt" &
server=$!
for _ in $(seq 1 100); do grep -q listening "$out/serve.txt" && break; sleep 0.1; done
url="http://127.0.0.1:18080/tiles/$tile.glb"
curl -fsS -o /dev/null "$url"
if command -v oha >/dev/null; then
  oha -z 10s -c 32 --no-tui "$url"
elif command -v wrk >/dev/null; then
  wrk -t2 -c32 -d10s --latency "$url"
else
  echo "neither oha nor wrk is installed (apt-get install wrk)"
fi
