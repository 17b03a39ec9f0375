#!/usr/bin/env bash
# Prints the server's figures, all on loopback with the load generator on the same machine:
#   1. one tile's cold render: stage times, peak memory, size;
#   2. cached requests per second and latency percentiles (wrk), for a dense tile as sent to a
#      browser (brotli) and uncompressed, and for a small tile;
#   3. a cold burst: 200 concurrent requests over 20 tiles never rendered, its completion time,
#      the answers, and the server's peak memory;
#   4. seeding the whole area of the bundled extract, then a synthetic mountain area
#      (scripts/mountain_extract.py): tiles per second and the time in each stage;
#   5. exporting it to MBTiles: the file's size;
#   6. the bytes of three tiles in every glb variant (flat or east-north-up, plain or meshopt)
#      as sent uncompressed, gzip and brotli, and each variant's render time.
# Usage: scripts/bench.sh   (from the repository root, after a release build; needs wrk)
set -euo pipefail
bin=target/release/terrastitch
tile=14/8529/5973
port=18080
out=$(mktemp -d)
server=
trap '[ -n "$server" ] && kill $server 2>/dev/null; rm -rf "$out"' EXIT

echo "== 1. cold render of $tile (render command)"
/usr/bin/time -v "$bin" render "$tile" -o "$out/tile.glb" --timings 2> "$out/render.txt" || { cat "$out/render.txt"; exit 1; }
grep -E '^(load|features|structures|roads|triangulation|terrain|elevation|glb|total|triangles|elevation LP:|of which ground roads:) ' "$out/render.txt"
grep -E 'Maximum resident set size|Elapsed \(wall' "$out/render.txt"
ls -l "$out/tile.glb" | awk '{print "glb bytes", $5}'

start_server() {
  "$bin" serve --listen 127.0.0.1:$port --cache "$out/cache-$1.sqlite" 2> "$out/serve-$1.txt" &
  server=$!
  for _ in $(seq 1 300); do
    curl -fsS -o /dev/null "http://127.0.0.1:$port/ready" 2>/dev/null && return 0
    sleep 0.1
  done
  echo "the server did not become ready"; cat "$out/serve-$1.txt"; exit 1
}
stop_server() { kill -TERM $server; wait $server 2>/dev/null || true; server=; }
peak_kib() { awk '/VmHWM/ {print $2}' /proc/$server/status; }
rss_kib() { awk '/VmRSS/ {print $2}' /proc/$server/status; }

start_server warm
command -v wrk >/dev/null || { echo "wrk is not installed (apt-get install wrk)"; exit 1; }
for case in "$tile br" "$tile identity" "14/8527/5975 identity"; do
  set -- $case
  url="http://127.0.0.1:$port/tiles/$1.glb"
  curl -fsS -o "$out/body" -H "Accept-Encoding: $2" "$url"
  echo "== 2. cached $1 ($2, $(stat -c %s "$out/body") bytes a response): wrk -t2 -c32 -d10s"
  wrk -t2 -c32 -d10s --latency -H "Accept-Encoding: $2" "$url" \
    | grep -E 'Requests/sec|Transfer/sec|^ +(50|90|99)%|Non-2xx|Socket errors'
done
stop_server

echo "== 3. cold burst: 200 concurrent requests over 20 tiles never rendered"
start_server cold
tiles=()
for y in 5972 5973 5974 5975; do for x in 8526 8527 8528 8529 8530; do tiles+=("14/$x/$y"); done; done
rss_before=$(peak_kib)
started=$(date +%s.%N)
for i in $(seq 0 199); do
  t=${tiles[$((i % 20))]}
  curl -s -o /dev/null -w '%{http_code}\n' -H 'Accept-Encoding: br' "http://127.0.0.1:$port/tiles/$t.glb" &
done > "$out/codes.txt"
wait $(jobs -p | grep -v "^$server$") 2>/dev/null || true
ended=$(date +%s.%N)
echo "completed in $(awk "BEGIN {printf \"%.2f\", $ended - $started}") s; answers: $(sort "$out/codes.txt" | uniq -c | tr '\n' ' ')"
memory_mib=$(awk -F'= *' '/^memory_mib/ {print $2}' config/default.toml)
echo "server peak memory: $(peak_kib) KiB (before the burst: $rss_before KiB; held after: $(rss_kib) KiB; cache.memory_mib: $memory_mib MiB)"
curl -fsS "http://127.0.0.1:$port/metrics" | grep -E '^terrastitch_(renders_total|cache_misses_total|rejected_busy_total) '
bounds=$(curl -fsS "http://127.0.0.1:$port/tiles.json" | python3 -c 'import json,sys; print(",".join(str(v) for v in json.load(sys.stdin)["bounds"]))')
stop_server

echo "== 4. seed of the extract's area ($bounds)"
"$bin" seed --bbox "$bounds" --format glb --cache "$out/seed.sqlite" 2>&1 | grep -E 'tiles in the box|made [0-9]+ tiles|time in each stage'

# The same over a synthetic mountain area: a valley road crossing its river on bridges and
# cutting through spurs in tunnels, roads of hairpin bends up steep sides, houses (over the
# bundled SRTM file's Estéron valley).
mountain_box=$(tests/py/.venv/bin/python scripts/mountain_extract.py "$out/mountain.osm.pbf" 2>"$out/mountain.txt")
echo "== 4b. seed of a synthetic mountain area ($mountain_box: $(cat "$out/mountain.txt"))"
"$bin" seed --bbox "$mountain_box" --osm "$out/mountain.osm.pbf" --srtm data --format glb \
    --cache "$out/mountain.sqlite" 2>&1 | grep -E 'tiles in the box|made [0-9]+ tiles|time in each stage'

echo "== 5. export of that area to MBTiles"
"$bin" export --bbox "$bounds" --cache "$out/seed.sqlite" -o "$out/area.mbtiles" 2>&1 | grep -E '^exported'
ls -l "$out/area.mbtiles" | awk '{print "MBTiles bytes", $5}'
ls -l "$out/seed.sqlite" | awk '{print "cache bytes (compressed tiles)", $5}'

echo "== 6. tile sizes by variant (bytes sent: identity / gzip / br) and render time"
start_server sizes
for t in 14/8529/5973 14/8530/5973 14/8527/5975; do
  for path in "tiles/$t.glb" "tiles/$t.glb?compress=meshopt" "3dtiles/$t.glb" "3dtiles/$t.glb?compress=meshopt"; do
    url="http://127.0.0.1:$port/$path"
    first=$(curl -fsS -o /dev/null -w '%{time_total}' "$url")
    sizes=""
    for coding in identity gzip br; do
      sizes="$sizes $(curl -fsS -o /dev/null -w '%{size_download}' -H "Accept-Encoding: $coding" "$url")"
    done
    printf '%-45s %9s %9s %9s  first request %.2f s\n' "$path" $sizes "$first"
  done
done
stop_server
