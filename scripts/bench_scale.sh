#!/usr/bin/env bash
# Country scale on one machine: for extracts of 1, 100 and 400 shifted copies of the bundled
# Monaco extract (made once with scripts/scale_extract.py and kept in target/scale/), prints
# the import's time, speed and peak memory, the store's size, `serve`'s time to /ready and
# memory there, the time of one cold tile through the server, and `render` of the densest
# Monaco tile (14/8529/5974, in the first copy) from the store and, up to 100 copies, from
# the extract in memory: "store ms" counts the tile's reading of the store, "after ms" the
# same after its eight neighbours in one process (the LP components they solved are found
# solved), "memory ms" the render alone (the whole extract was read before it). Last, a diff of 1,000 changes to the
# first copy (scripts/osm_diff.py) is applied to the store: its time and peak memory, and how
# many tiles it expired. "store MB" counts the store and its node file. "z10" and "z8" are
# the far views over the first copy, `render` of its zoom-10 and zoom-8 parents from the
# store: seconds and peak MB.
#
#   scripts/bench_scale.sh [COPIES...]      (default: 1 100 400)
set -euo pipefail
cd "$(dirname "$0")/.."

copies=("$@")
[ ${#copies[@]} -gt 0 ] || copies=(1 100 400)
bin=target/release/terrastitch
python=tests/py/.venv/bin/python
work=target/scale
tile=14/8529/5974
mkdir -p "$work"

ms_since() { echo $(( ($(date +%s%N) - $1) / 1000000 )); }

# Peak RSS (MB) and seconds of a command, from GNU time.
measure() {
    local log=$1; shift
    /usr/bin/time -f "%e %M" -o "$log.time" "$@" >"$log" 2>&1
    read -r seconds kb <"$log.time"
    echo "$seconds $((kb / 1024))"
}

total_ms() { # the tile's time with what it read (--timings' total)
    grep -o 'total *[0-9.]* ms' "$1" | grep -o '[0-9.]*' | head -1
}

render_ms() { # the render's own time, without the whole extract's load (--timings)
    grep -o 'render [0-9.]* ms' "$1" | grep -o '[0-9.]*' | head -1
}

diff=$work/diff-1000.osc.gz
[ -s "$diff" ] || "$python" scripts/osm_diff.py data/monaco-osrm-2016.osm.pbf many:1000 "$diff" 2>/dev/null

printf '%-7s %9s %9s %8s %10s %10s %9s %9s %9s %10s %10s %10s %9s %9s %8s %7s %7s %7s %7s\n' \
    copies "PBF MB" "import s" "MB/s" "import MB" "store MB" "ready s" "ready MB" "cold ms" \
    "store ms" "after ms" "memory ms" "update s" "update MB" "expired" "z10 s" "z10 MB" \
    "z8 s" "z8 MB"
for n in "${copies[@]}"; do
    pbf=$work/c$n.osm.pbf
    srtm=$work/srtm-c$n
    if [ ! -s "$pbf" ]; then
        "$python" scripts/scale_extract.py data/monaco-osrm-2016.osm.pbf "$n" "$pbf.partial.pbf" \
            2>"$work/c$n.cells"
        mv "$pbf.partial.pbf" "$pbf"
    fi
    rm -rf "$srtm" && mkdir -p "$srtm"
    while read -r cell; do
        ln -s "$PWD/data/N43E007.hgt" "$srtm/$cell.hgt"
    done <"$work/c$n.cells"
    pbf_mb=$(awk "BEGIN {printf \"%.1f\", $(stat -c %s "$pbf") / 1e6}")

    store=$work/c$n.sqlite
    rm -f "$store" "$store".nodes-*
    read -r import_s import_mb < <(measure "$work/import-c$n.log" \
        "$bin" import --osm "$pbf" --store "$store")
    mbps=$(awk "BEGIN {printf \"%.1f\", $pbf_mb / $import_s}")
    store_mb=$(awk "BEGIN {printf \"%.0f\", $(cat "$store" "$store".nodes-* | wc -c) / 1e6}")

    # serve on the store: time to /ready, memory there, then one cold tile.
    cache=$work/cache-c$n.sqlite
    rm -f "$cache"
    started=$(date +%s%N)
    "$bin" serve --store "$store" --osm "$pbf" --srtm "$srtm" --cache "$cache" \
        --listen 127.0.0.1:0 >"$work/serve-c$n.log" 2>&1 &
    pid=$!
    address=""
    while [ -z "$address" ]; do
        address=$(grep -o 'listening on http://[0-9.:]*' "$work/serve-c$n.log" | head -1 | sed 's/listening on //' || true)
        kill -0 "$pid" 2>/dev/null || { cat "$work/serve-c$n.log"; exit 1; }
        sleep 0.01
    done
    until curl -fs "$address/ready" >/dev/null; do sleep 0.01; done
    ready_ms=$(ms_since "$started")
    ready_mb=$(( $(awk '/VmRSS/ {print $2}' "/proc/$pid/status") / 1024 ))
    t=$(date +%s%N)
    curl -fs -o /dev/null "$address/tiles/$tile.glb"
    cold_ms=$(ms_since "$t")
    kill "$pid"; wait "$pid" 2>/dev/null || true

    "$bin" render "$tile" --store "$store" --osm "$pbf" --srtm "$srtm" --timings \
        -o "$work/tile-store.glb" >"$work/render-store-c$n.log" 2>&1
    store_ms=$(total_ms "$work/render-store-c$n.log")
    # The same tile after its eight neighbours in one process, as a server or a seed meets
    # it: the bridges and road stretches they share are found settled.
    neighbours=()
    for dx in -1 0 1; do
        for dy in -1 0 1; do
            [ "$dx$dy" = 00 ] || neighbours+=(--after "14/$((8529 + dx))/$((5974 + dy))")
        done
    done
    "$bin" render "$tile" "${neighbours[@]}" --store "$store" --osm "$pbf" --srtm "$srtm" \
        --timings -o "$work/tile-after.glb" >"$work/render-after-c$n.log" 2>&1
    after_ms=$(total_ms "$work/render-after-c$n.log")
    cmp -s "$work/tile-store.glb" "$work/tile-after.glb" ||
        echo "warning: the tile rendered after its neighbours differs" >&2
    memory_ms="-"
    if [ "$n" -le 100 ]; then
        "$bin" render "$tile" --osm "$pbf" --srtm "$srtm" --timings \
            -o "$work/tile-memory.glb" >"$work/render-memory-c$n.log" 2>&1
        memory_ms=$(render_ms "$work/render-memory-c$n.log")
        cmp -s "$work/tile-store.glb" "$work/tile-memory.glb" ||
            echo "warning: the tile from the store differs from the tile from memory" >&2
    fi
    # The far views over the first copy (the zoom-10 and zoom-8 parents of the tile), from the
    # store: time and peak memory of `render`.
    read -r z10_s z10_mb < <(measure "$work/render-z10-c$n.log" \
        "$bin" render 10/$((8529 >> 4))/$((5974 >> 4)) --store "$store" --osm "$pbf" \
        --srtm "$srtm" -o "$work/parent-z10.glb")
    read -r z8_s z8_mb < <(measure "$work/render-z8-c$n.log" \
        "$bin" render 8/$((8529 >> 6))/$((5974 >> 6)) --store "$store" --osm "$pbf" \
        --srtm "$srtm" -o "$work/parent-z8.glb")
    read -r update_s update_mb < <(measure "$work/update-c$n.log" \
        "$bin" update --store "$store" --osm "$pbf" --osc "$diff" --expired "$work/expired-c$n.txt")
    expired=$(wc -l <"$work/expired-c$n.txt")
    printf '%-7s %9s %9s %8s %10s %10s %9s %9s %9s %10s %10s %10s %9s %9s %8s %7s %7s %7s %7s\n' \
        "$n" "$pbf_mb" "$import_s" "$mbps" "$import_mb" "$store_mb" \
        "$(awk "BEGIN {printf \"%.2f\", $ready_ms / 1000}")" "$ready_mb" "$cold_ms" \
        "$store_ms" "$after_ms" "$memory_ms" "$update_s" "$update_mb" "$expired" \
        "$z10_s" "$z10_mb" "$z8_s" "$z8_mb"
done
