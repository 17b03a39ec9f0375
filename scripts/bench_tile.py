#!/usr/bin/env python3
"""The cost of one tile, stage by stage.

Prints, for the release binary (and, with --base, for another binary, runs alternating so a
busy machine weighs on both alike):
  1. the densest bundled tile rendered cold (a process each) and warm (rendered a second
     time in the same process, with `--after`), median and least of each stage;
  2. every zoom-14 tile of the bundled extract rendered cold: mean, p95 and most.

Usage: scripts/bench_tile.py [--runs N] [--base OTHER_BINARY] [--tile Z/X/Y] [--pin]
(from the repository root, after a release build). --pin runs every render on one core.
"""

import argparse
import math
import re
import statistics
import subprocess
import sys
import tempfile
import time

BINARY = "target/release/terrastitch"
DENSEST = "14/8529/5974"
# The bundled extract's box (data/README.md): W, S, E, N.
EXTRACT = (7.349, 43.71, 7.491, 43.77)
STAGE = re.compile(r"^(\w+)\s+([0-9.]+) ms(?: \(render ([0-9.]+) ms\))?")


def tiles_of(box, zoom=14):
    west, south, east, north = box
    n = 2**zoom

    def x(lon):
        return int((lon + 180.0) / 360.0 * n)

    def y(lat):
        r = math.radians(lat)
        return int((1.0 - math.asinh(math.tan(r)) / math.pi) / 2.0 * n)

    return [
        f"{zoom}/{tx}/{ty}"
        for ty in range(y(north), y(south) + 1)
        for tx in range(x(west), x(east) + 1)
    ]


def render(binary, tile, pin, warm=False):
    """The stage times (ms) of one render, `render` being the total without loading."""
    with tempfile.NamedTemporaryFile(suffix=".glb") as out:
        command = [binary, "render", tile, "-o", out.name, "--timings"]
        if warm:
            command += ["--after", tile]
        if pin:
            command = ["taskset", "-c", "0"] + command
        started = time.monotonic()
        done = subprocess.run(command, capture_output=True, text=True)
        wall = (time.monotonic() - started) * 1000.0
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{done.stderr}")
    stages = {}
    for line in done.stderr.splitlines():
        m = STAGE.match(line)
        if m:
            stages[m.group(1)] = float(m.group(2))
            if m.group(3):
                stages["render"] = float(m.group(3))
    stages["wall"] = wall
    return stages


def table(title, names, results):
    """One row a stage, median and least a binary."""
    print(f"== {title}")
    print(f"{'stage':<14}" + "".join(f"{n + ' median':>18}{'least':>9}" for n in names))
    stages = list(results[names[0]][0].keys())
    for stage in stages:
        row = f"{stage:<14}"
        for n in names:
            values = [r[stage] for r in results[n] if stage in r]
            row += f"{statistics.median(values):>18.1f}{min(values):>9.1f}"
        print(row)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--base", help="another binary to measure alongside, e.g. an older build")
    parser.add_argument("--tile", default=DENSEST)
    parser.add_argument("--pin", action="store_true", help="run every render on one core")
    args = parser.parse_args()
    binaries = {"now": BINARY}
    if args.base:
        binaries = {"base": args.base, "now": BINARY}
    names = list(binaries)

    for warm in (False, True):
        results = {n: [] for n in names}
        for _ in range(args.runs):
            for n, b in binaries.items():
                results[n].append(render(b, args.tile, args.pin, warm))
        how = "warm (rendered again in the same process)" if warm else "cold (a process each)"
        table(f"{args.tile} {how}, {args.runs} runs, ms", names, results)

    tiles = tiles_of(EXTRACT)
    print(f"== every tile of the bundled extract cold ({len(tiles)} tiles), render ms (without loading)")
    for n, b in binaries.items():
        times = sorted(render(b, t, args.pin)["render"] for t in tiles)
        p95 = times[min(len(times) - 1, math.ceil(0.95 * len(times)) - 1)]
        print(
            f"{n}: mean {statistics.mean(times):.1f}  median {statistics.median(times):.1f}"
            f"  p95 {p95:.1f}  most {times[-1]:.1f}  total {sum(times) / 1000.0:.2f} s"
        )


if __name__ == "__main__":
    main()
