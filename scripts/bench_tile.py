#!/usr/bin/env python3
"""The cost of one tile, stage by stage.

Prints, for the release binary (and, with --base, for another binary, runs alternating so a
busy machine weighs on both alike):
  1. the densest bundled tile rendered cold (a process each) and warm (rendered a second
     time in the same process, with `--after`), median and least of each stage;
  2. cold tiles asked of the server (`serve`, a fresh cache): the answer's time against the
     render's, as the server logs it, by coding asked for;
  3. the flat viewer's first full view on a fresh cache, in headless Chromium
     (tests/js/first_view.mjs; needs the packages `make test` installs in tests/js);
  4. every zoom-14 tile of the bundled extract rendered cold: mean, p95 and most.

Usage: scripts/bench_tile.py [--runs N] [--base OTHER_BINARY] [--tile Z/X/Y] [--pin]
(from the repository root, after a release build). --pin runs every render on one core.
"""

import argparse
import contextlib
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

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


ANSI = re.compile(r"\x1b\[[0-9;]*m")
RENDERED = re.compile(r"rendered.*tile=(\S+).*\bms=(\d+)")
# Cold tiles asked of the server, and how: (tile, Accept-Encoding, query).
ASKED = [
    ("14/8529/5973", "identity", ""),
    ("14/8530/5973", "br", ""),
    ("14/8528/5973", "gzip", ""),
    ("14/8528/5974", "identity", "?compress=meshopt"),
]


@contextlib.contextmanager
def serving(binary, port):
    """A server of the bundled data with an empty cache, ready: yields its base URL and the
    file its log goes to."""
    with tempfile.TemporaryDirectory() as scratch:
        log_path = os.path.join(scratch, "serve.log")
        with open(log_path, "w") as log:
            server = subprocess.Popen(
                [binary, "serve", "--listen", f"127.0.0.1:{port}", "--cache", os.path.join(scratch, "c.sqlite")],
                stdout=subprocess.DEVNULL,
                stderr=log,
            )
            try:
                base = f"http://127.0.0.1:{port}"
                for _ in range(300):
                    try:
                        urllib.request.urlopen(base + "/ready", timeout=1).read()
                        break
                    except OSError:
                        time.sleep(0.1)
                yield base, log_path
            finally:
                server.terminate()
                server.wait()


def cold_answers(binary, port):
    """Each tile of ASKED asked once of a server with an empty cache: (tile, coding, query,
    answer ms, render ms as logged)."""
    with serving(binary, port) as (base, log_path):
        answers = []
        for tile, coding, query in ASKED:
            request = urllib.request.Request(
                f"{base}/tiles/{tile}.glb{query}", headers={"Accept-Encoding": coding}
            )
            started = time.monotonic()
            with urllib.request.urlopen(request, timeout=120) as response:
                response.read()
            answers.append((tile, coding, query, (time.monotonic() - started) * 1000.0))
        rendered = {}
        with open(log_path) as log:
            for line in log:
                m = RENDERED.search(ANSI.sub("", line))
                if m:
                    rendered.setdefault(m.group(1), float(m.group(2)))
    return [(t, c, q, a, rendered.get(t, float("nan"))) for t, c, q, a in answers]


# The viewer's start view in the bench: Monte-Carlo from 1.8 km (as its own test opens it).
START_VIEW = "/#43.7396,7.4255,1800,20,50"


def first_view(binary, port):
    """The flat viewer opened in headless Chromium on a server with an empty cache: the
    report of tests/js/first_view.mjs, or None without its packages (`make test` installs
    them)."""
    if not os.path.isdir("tests/js/node_modules/playwright-core"):
        return None
    with serving(binary, port) as (base, _):
        out = subprocess.run(
            ["node", "tests/js/first_view.mjs", base + START_VIEW],
            capture_output=True, text=True, check=False,
        )
    try:
        return json.loads(out.stdout.strip())
    except ValueError:
        return {"error": (out.stdout + out.stderr)[-500:]}


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

    print("== cold tiles asked of the server: answer against render, ms")
    for n, b in binaries.items():
        for tile, coding, query, answer, rendered in cold_answers(b, 18190):
            print(
                f"{n}: {tile}{query} Accept-Encoding {coding}: answered in {answer:.0f}, "
                f"rendered in {rendered:.0f}, {answer - rendered:.0f} after the render"
            )

    print("== the flat viewer's first full view on an empty cache (nine zoom-14 tiles around its start)")
    for n, b in binaries.items():
        report = first_view(b, 18191)
        if report is None:
            print(f"{n}: skipped (tests/js has no node_modules: run make test once)")
        elif report.get("error"):
            print(f"{n}: failed: {report['error']}")
        else:
            print(
                f"{n}: {report['firstFullViewMs']:.0f} ms from the page's request "
                f"({report['inPageMs']:.0f} in the page), {len(report['requested'])} tiles asked for"
            )

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
