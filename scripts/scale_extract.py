#!/usr/bin/env python3
"""Writes a large OSM extract made of shifted copies of a small one, for benchmarks of scale.

    scale_extract.py SOURCE.osm.pbf COPIES OUT.osm.pbf [--columns N]

Copy k sits `k % columns` steps east and `k // columns` steps north of the source, each step
the width or height of the source's node extent (plus a small gap), so copies never overlap.
Every id of copy k is the source's id plus k times a round number above the largest id, so ids
stay unique and each type stays sorted by id (nodes, then ways, then relations), as extracts
from Geofabrik or osmium are. Prints the SRTM cells the copies cover, one name per line on
stderr, so a benchmark can provide them.
"""

import argparse
import math
import sys

import osmium


def read(path):
    """The source's nodes, ways and relations as plain tuples."""
    nodes, ways, relations = [], [], []

    class Reader(osmium.SimpleHandler):
        def node(self, n):
            nodes.append((n.id, n.location.lon, n.location.lat, dict(n.tags)))

        def way(self, w):
            ways.append((w.id, [r.ref for r in w.nodes], dict(w.tags)))

        def relation(self, r):
            members = [(m.type, m.ref, m.role) for m in r.members]
            relations.append((r.id, members, dict(r.tags)))

    Reader().apply_file(path, locations=False)
    return nodes, ways, relations


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source")
    parser.add_argument("copies", type=int)
    parser.add_argument("out")
    parser.add_argument("--columns", type=int, default=0, help="copies per row (default: square)")
    args = parser.parse_args()

    nodes, ways, relations = read(args.source)
    if not nodes:
        sys.exit(f"{args.source} holds no nodes")
    largest = max(
        [n[0] for n in nodes] + [w[0] for w in ways] + [r[0] for r in relations]
    )
    offset = 10 ** (len(str(largest)))
    lons = sorted(n[1] for n in nodes)
    lats = sorted(n[2] for n in nodes)
    # The bulk of the nodes (a few stray boundary nodes would space the copies far apart).
    k = len(lons) // 100
    west, east = lons[k], lons[-1 - k]
    south, north = lats[k], lats[-1 - k]
    step_lon = round(east - west + 0.01, 3)
    step_lat = round(north - south + 0.01, 3)
    columns = args.columns or max(1, math.ceil(math.sqrt(args.copies)))

    def shift(copy):
        return (copy % columns) * step_lon, (copy // columns) * step_lat

    cells = set()
    for copy in range(args.copies):
        dlon, dlat = shift(copy)
        for lon in (west + dlon, east + dlon):
            for lat in (south + dlat, north + dlat):
                cells.add((math.floor(lat), math.floor(lon)))

    writer = osmium.SimpleWriter(args.out, overwrite=True)
    try:
        for copy in range(args.copies):
            dlon, dlat = shift(copy)
            base = copy * offset
            for id_, lon, lat, tags in nodes:
                writer.add_node(
                    osmium.osm.mutable.Node(
                        id=base + id_,
                        location=osmium.osm.Location(lon + dlon, lat + dlat),
                        tags=tags,
                        version=1,
                    )
                )
        for copy in range(args.copies):
            base = copy * offset
            for id_, refs, tags in ways:
                writer.add_way(
                    osmium.osm.mutable.Way(
                        id=base + id_, nodes=[base + r for r in refs], tags=tags, version=1
                    )
                )
        for copy in range(args.copies):
            base = copy * offset
            for id_, members, tags in relations:
                writer.add_relation(
                    osmium.osm.mutable.Relation(
                        id=base + id_,
                        members=[(t, base + ref, role) for t, ref, role in members],
                        tags=tags,
                        version=1,
                    )
                )
    finally:
        writer.close()
    for lat, lon in sorted(cells):
        ns = "N" if lat >= 0 else "S"
        ew = "E" if lon >= 0 else "W"
        print(f"{ns}{abs(lat):02d}{ew}{abs(lon):03d}", file=sys.stderr)


if __name__ == "__main__":
    main()
