#!/usr/bin/env python3
"""Writes an OSM extract of the ways given as JSON on standard input, for tests on places the
bundled extracts do not cover.

    ways_extract.py OUT.osm.pbf < ways.json

The JSON is a list of ways, each `{"tags": {...}, "nodes": [[lon, lat], ...]}`; a node may
carry tags of its own as a third item, `[lon, lat, {...}]`. Ways are numbered from 1 and their
nodes from 1 in the order given (a position given twice in one way is one node, so a closed
ring closes); the file is sorted by type then id.
"""

import json
import os
import sys

import osmium


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    ways = json.load(sys.stdin)
    if os.path.exists(sys.argv[1]):
        os.remove(sys.argv[1])
    writer = osmium.SimpleWriter(sys.argv[1])
    nodes = []
    refs = []
    for way in ways:
        ids = {}
        way_refs = []
        for node in way["nodes"]:
            lon, lat = node[0], node[1]
            tags = node[2] if len(node) > 2 else {}
            key = (lon, lat)
            if key not in ids:
                nodes.append((len(nodes) + 1, lon, lat, tags))
                ids[key] = len(nodes)
            way_refs.append(ids[key])
        refs.append(way_refs)
    for node_id, lon, lat, tags in nodes:
        writer.add_node(
            osmium.osm.mutable.Node(id=node_id, location=(lon, lat), tags=tags, version=1)
        )
    for k, (way, way_refs) in enumerate(zip(ways, refs)):
        writer.add_way(
            osmium.osm.mutable.Way(id=k + 1, nodes=way_refs, tags=way["tags"], version=1)
        )
    writer.close()


if __name__ == "__main__":
    main()
