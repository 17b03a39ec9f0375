#!/usr/bin/env python3
"""Writes an OSM change file that edits an extract, and the extract with the change applied.

    osm_diff.py EXTRACT.osm.pbf EDIT OUT.osc[.gz] [OUT.osm.pbf]

EDIT is one of:
  move-bridge-node   moves the middle node of the longest road bridge 2 m north
  delete-building    deletes the largest building way that no relation holds
  water-multipolygon turns the multipolygon with the most members into a lake
  many:N[:SEED]      N changes spread over the extract (seeded, 18 unless given): nodes moved
                     a metre, tags of ways changed, buildings deleted, in turn
  cut-node           deletes the middle node of the longest road on the ground (the road still
                     names it, as where an extract cuts a way at its border)
  bring-node         creates that node again, where it was
  cut-ways           deletes every way of the largest multipolygon of at most three ways, none
                     of them a coastline (the relation still names them)
  bring-ways         creates those ways again
  far-node:DEG       moves the middle node of the longest road on the ground DEG degrees north
                     and DEG east (to the pole at most; `far-node:pole` puts it there)

With OSM_DIFF_CACHE set to a directory, the extract's parts are kept there once read, for the
next runs. The chosen elements are printed to stderr (`way 123`), one a line. With OUT.osm.pbf the
extract with the change applied is written too (pyosmium's MergeInputReader, as `osmium
apply-changes`), to compare an updated store with one imported from it.
"""

import gzip
import hashlib
import os
import pickle
import random
import sys
from xml.sax.saxutils import quoteattr

import osmium

TIMESTAMP = "2030-01-01T00:00:00Z"


class Extract(osmium.SimpleHandler):
    """The parts of an extract the edits choose from."""

    def __init__(self):
        super().__init__()
        self.nodes = {}
        self.ways = {}
        self.relations = {}
        self.in_relation = set()

    def node(self, n):
        self.nodes[n.id] = (n.location.lon, n.location.lat, n.version, dict(n.tags))

    def way(self, w):
        self.ways[w.id] = ([n.ref for n in w.nodes], dict(w.tags), w.version)

    def relation(self, r):
        members = [(m.type, m.ref, m.role) for m in r.members]
        self.relations[r.id] = (members, dict(r.tags), r.version)
        for m in r.members:
            if m.type == "w":
                self.in_relation.add(m.ref)


def node_xml(extract, node_id, lon, lat):
    _, _, version, tags = extract.nodes[node_id]
    body = "".join(f"<tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in tags.items())
    return (
        f'<node id="{node_id}" version="{version + 1}" timestamp="{TIMESTAMP}" '
        f'lat="{lat:.7f}" lon="{lon:.7f}">{body}</node>'
    )


def way_xml(extract, way_id, tags=None, deleted=False):
    refs, old_tags, version = extract.ways[way_id]
    if deleted:
        return f'<way id="{way_id}" version="{version + 1}" timestamp="{TIMESTAMP}"/>'
    tags = old_tags if tags is None else tags
    body = "".join(f'<nd ref="{r}"/>' for r in refs)
    body += "".join(f"<tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in tags.items())
    return f'<way id="{way_id}" version="{version + 1}" timestamp="{TIMESTAMP}">{body}</way>'


def relation_xml(extract, relation_id, tags):
    members, _, version = extract.relations[relation_id]
    kinds = {"n": "node", "w": "way", "r": "relation"}
    body = "".join(
        f'<member type="{kinds[t]}" ref="{ref}" role={quoteattr(role)}/>' for t, ref, role in members
    )
    body += "".join(f"<tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in tags.items())
    return (
        f'<relation id="{relation_id}" version="{version + 1}" timestamp="{TIMESTAMP}">'
        f"{body}</relation>"
    )


def move(extract, node_id, north_m=2.0):
    lon, lat, _, _ = extract.nodes[node_id]
    return node_xml(extract, node_id, lon, lat + north_m / 111_320.0)


def length(extract, refs):
    points = [extract.nodes[r][:2] for r in refs if r in extract.nodes]
    return sum(abs(a[0] - b[0]) + abs(a[1] - b[1]) for a, b in zip(points, points[1:]))


def buildings(extract):
    return [
        w for w, (refs, tags, _) in extract.ways.items()
        if "building" in tags and w not in extract.in_relation and refs[0] == refs[-1]
    ]


def road_node(extract):
    """The longest road on the ground, and its middle node."""
    roads = [
        w for w, (refs, tags, _) in extract.ways.items()
        if "highway" in tags and tags.get("bridge") in (None, "no")
        and tags.get("tunnel") in (None, "no") and len(refs) >= 5
    ]
    way = max(roads, key=lambda w: (length(extract, extract.ways[w][0]), -w))
    refs = extract.ways[way][0]
    return way, refs[len(refs) // 2]


def small_multipolygon(extract):
    """The largest multipolygon made of at most three ways the extract holds, and its ways."""
    polygons = [
        r for r, (members, tags, _) in extract.relations.items()
        if tags.get("type") == "multipolygon" and 1 <= len(members) <= 3
        and all(t == "w" and ref in extract.ways for t, ref, _ in members)
        and not any(extract.ways[ref][1].get("natural") == "coastline" for _, ref, _ in members)
    ]
    size = lambda r: sum(len(extract.ways[ref][0]) for _, ref, _ in extract.relations[r][0])
    relation = max(polygons, key=lambda r: (size(r), -r))
    return relation, [ref for _, ref, _ in extract.relations[relation][0]]


def restore(extract, what):
    """(create, delete) XML fragments and the chosen elements of the cut and bring edits."""
    if what in ("cut-node", "bring-node"):
        way, node = road_node(extract)
        chosen = [f"way {way}", f"node {node}"]
        if what == "cut-node":
            version = extract.nodes[node][2]
            return [], [f'<node id="{node}" version="{version + 1}" timestamp="{TIMESTAMP}"/>'], chosen
        lon, lat, _, _ = extract.nodes[node]
        return [node_xml(extract, node, lon, lat)], [], chosen
    relation, ways = small_multipolygon(extract)
    chosen = [f"relation {relation}"] + [f"way {w}" for w in ways]
    if what == "cut-ways":
        return [], [way_xml(extract, w, deleted=True) for w in ways], chosen
    return [way_xml(extract, w) for w in ways], [], chosen


def edit(extract, what):
    """(modify, delete) XML fragments and the chosen elements."""
    if what == "move-bridge-node":
        bridges = [
            w for w, (refs, tags, _) in extract.ways.items()
            if tags.get("bridge") not in (None, "no") and "highway" in tags and len(refs) >= 3
        ]
        way = max(bridges, key=lambda w: (length(extract, extract.ways[w][0]), -w))
        refs = extract.ways[way][0]
        node = refs[len(refs) // 2]
        return [move(extract, node)], [], [f"way {way}", f"node {node}"]
    if what.startswith("far-node:"):
        way, node = road_node(extract)
        lon, lat, _, _ = extract.nodes[node]
        far = what.split(":")[1]
        if far == "pole":
            lat = 90.0
        else:
            lat, lon = min(90.0, lat + float(far)), min(180.0, lon + float(far))
        return [node_xml(extract, node, lon, lat)], [], [f"way {way}", f"node {node}"]
    if what == "delete-building":
        way = max(buildings(extract), key=lambda w: (len(extract.ways[w][0]), -w))
        return [], [way_xml(extract, way, deleted=True)], [f"way {way}"]
    if what == "water-multipolygon":
        polygons = [
            r for r, (members, tags, _) in extract.relations.items()
            if tags.get("type") == "multipolygon" and tags.get("natural") != "water"
        ]
        relation = max(polygons, key=lambda r: (len(extract.relations[r][0]), -r))
        tags = {"type": "multipolygon", "natural": "water"}
        return [relation_xml(extract, relation, tags)], [], [f"relation {relation}"]
    if what.startswith("many:"):
        parts = what.split(":")
        count = int(parts[1])
        rng = random.Random(int(parts[2]) if len(parts) > 2 else 18)
        way_ids = sorted(extract.ways)
        houses = set(buildings(extract))
        modify, delete, chosen, used = [], [], [], set()
        while len(chosen) < count:
            way = rng.choice(way_ids)
            if way in used:
                continue
            used.add(way)
            refs, tags, _ = extract.ways[way]
            kind = len(chosen) % 3
            if kind == 0:
                node = refs[len(refs) // 2]
                if node in used or node not in extract.nodes:
                    continue
                used.add(node)
                modify.append(move(extract, node, 1.0))
                chosen.append(f"node {node}")
            elif kind == 1:
                modify.append(way_xml(extract, way, {**tags, "note": "changed"}))
                chosen.append(f"way {way}")
            elif way in houses:
                delete.append(way_xml(extract, way, deleted=True))
                chosen.append(f"way {way}")
        return modify, delete, chosen
    raise SystemExit(f"unknown edit {what}")


def read(source):
    """The extract's parts, read once: with OSM_DIFF_CACHE set to a directory, kept there
    (pickled, named for the file's path, size and time) and read back by later runs."""
    folder = os.environ.get("OSM_DIFF_CACHE")
    if not folder:
        extract = Extract()
        extract.apply_file(source)
        return extract
    stat = os.stat(source)
    name = hashlib.sha256(f"{os.path.abspath(source)}:{stat.st_size}:{stat.st_mtime_ns}".encode())
    path = os.path.join(folder, name.hexdigest()[:16] + ".pickle")
    try:
        with open(path, "rb") as cached:
            parts = pickle.load(cached)
        extract = Extract()
        extract.nodes, extract.ways, extract.relations, extract.in_relation = parts
        return extract
    except (OSError, pickle.UnpicklingError, EOFError, ValueError):
        pass
    extract = Extract()
    extract.apply_file(source)
    os.makedirs(folder, exist_ok=True)
    # Written beside its place and moved there whole: runs at once never read half a file.
    partial = f"{path}.{os.getpid()}"
    with open(partial, "wb") as out:
        parts = (extract.nodes, extract.ways, extract.relations, extract.in_relation)
        pickle.dump(parts, out, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(partial, path)
    return extract


def main():
    if len(sys.argv) not in (4, 5):
        raise SystemExit(__doc__)
    source, what, osc = sys.argv[1:4]
    extract = read(source)
    create = []
    if what in ("cut-node", "bring-node", "cut-ways", "bring-ways"):
        create, delete, chosen = restore(extract, what)
        modify = []
    else:
        modify, delete, chosen = edit(extract, what)
    text = '<?xml version="1.0" encoding="UTF-8"?>\n<osmChange version="0.6" generator="osm_diff.py">\n'
    if create:
        text += "<create>\n" + "\n".join(create) + "\n</create>\n"
    if modify:
        text += "<modify>\n" + "\n".join(modify) + "\n</modify>\n"
    if delete:
        text += "<delete>\n" + "\n".join(delete) + "\n</delete>\n"
    text += "</osmChange>\n"
    opener = gzip.open if osc.endswith(".gz") else open
    with opener(osc, "wt", encoding="utf-8") as out:
        out.write(text)
    for line in chosen:
        print(line, file=sys.stderr)
    if len(sys.argv) == 5:
        merged = osmium.MergeInputReader()
        merged.add_file(osc)
        writer = osmium.io.Writer(osmium.io.File(sys.argv[4]), overwrite=True)
        reader = osmium.io.Reader(source)
        merged.apply_to_reader(reader, writer)
        reader.close()
        writer.close()


if __name__ == "__main__":
    main()
