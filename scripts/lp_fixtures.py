#!/usr/bin/env python3
"""Picks LP components recorded by `terrastitch render --record-lp` for the solver fixtures.

Usage: scripts/lp_fixtures.py OUT.txt.gz RECORDED.txt...

Distinct components are bucketed by size (free variables and hard equalities, the width of the
system the component solver factorises) and taken evenly spaced within each bucket, so the
fixtures cover the small components a tile has hundreds of and the few large ones alike.
"""

import gzip
import sys

# (largest size in the bucket, components taken from it)
BUCKETS = [(5, 80), (10, 80), (20, 60), (50, 50), (100, 20), (300, 10)]


def size(component):
    """Free variables and hard equalities: the width of the component solver's system."""
    lines = component.splitlines()
    free = sum(1 for line in lines if line.startswith("v ") and line.endswith(" -"))
    # c <relation> <rhs> <penalty> …: a hard equality has "=" and no penalty.
    equal = sum(1 for line in lines if line.split()[:2] == ["c", "="] and line.split()[3] == "-")
    return free + equal


def components(paths):
    seen = set()
    for path in paths:
        with open(path) as f:
            block = []
            for line in f:
                line = line.rstrip("\n")
                block.append(line)
                if line == "end":
                    text = "\n".join(block) + "\n"
                    block = []
                    if text not in seen:
                        seen.add(text)
                        yield text


def main():
    out, recorded = sys.argv[1], sys.argv[2:]
    sized = [(size(c), c) for c in components(recorded)]
    picked = []
    low = -1
    for high, count in BUCKETS:
        bucket = [c for n, c in sized if low < n <= high]
        step = max(1, len(bucket) / count) if bucket else 1
        picked += [bucket[int(k * step)] for k in range(min(count, len(bucket)))]
        print(f"sizes {low + 1}..{high}: {len(bucket)} distinct, {min(count, len(bucket))} taken")
        low = high
    with gzip.GzipFile(out, "wb", mtime=0) as f:
        f.write("".join(picked).encode())
    print(f"{len(picked)} components written to {out}")


if __name__ == "__main__":
    main()
