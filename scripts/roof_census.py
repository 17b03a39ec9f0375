#!/usr/bin/env python3
"""Counts the roofs of the buildings in glb tiles, from the tiles' own feature tables.

    roof_census.py EXTRACT.osm.pbf TILE.glb...

Each building (by OSM id, once however many tiles hold it) is counted by its `building` value
and its roof: the `roof:shape` tagged, else the one the tile says it inferred. Footprint areas
come from the extract (pyosmium). Prints, as JSON: the roof shapes by building type, the share
of untagged buildings under 300 m² with a pitched roof, the buildings of two levels or more
(tagged or inferred) with windows (drawn in a `facade_*` material) and those without by type,
and for each tile its buildings and the distinct roof colours it inferred.
"""

import json
import math
import struct
import sys
from collections import Counter, defaultdict

import osmium


def glb_chunks(path):
    """A glb's JSON document and binary chunk."""
    data = open(path, "rb").read()
    magic, _, _ = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67:
        raise SystemExit(f"{path}: not a glb")
    offset, chunks = 12, {}
    while offset < len(data):
        length, kind = struct.unpack_from("<II", data, offset)
        chunks[kind] = data[offset + 8 : offset + 8 + length]
        offset += 8 + length
    return json.loads(chunks[0x4E4F534A]), chunks.get(0x004E4942, b"")


def glazed_features(path):
    """The feature ids drawn in a facade material (with windows), of a plain (not compressed)
    glb."""
    document, binary = glb_chunks(path)
    glazed = set()
    for mesh in document["meshes"]:
        for primitive in mesh["primitives"]:
            material = document["materials"][primitive["material"]].get("name", "")
            if not material.startswith("facade"):
                continue
            accessor = document["accessors"][primitive["attributes"]["_FEATURE_ID_0"]]
            view = document["bufferViews"][accessor["bufferView"]]
            start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
            if accessor["componentType"] == 5123:
                stride = view.get("byteStride", 2)
                glazed.update(
                    struct.unpack_from("<H", binary, start + i * stride)[0]
                    for i in range(accessor["count"])
                )
            else:
                glazed.update(
                    int(v) for v in struct.unpack_from(f"<{accessor['count']}f", binary, start)
                )
    return glazed


def property_table(path):
    """The rows of a glb's feature table, as dicts of its string and id properties."""
    document, binary = glb_chunks(path)
    views = document["bufferViews"]

    def view(index):
        v = views[index]
        start = v.get("byteOffset", 0)
        return binary[start : start + v["byteLength"]]

    table = document["extensions"]["EXT_structural_metadata"]["propertyTables"][0]
    count = table["count"]
    rows = [dict() for _ in range(count)]
    schema = document["extensions"]["EXT_structural_metadata"]["schema"]
    declared = schema["classes"][table["class"]]["properties"]
    for name, prop in table["properties"].items():
        values = view(prop["values"])
        enum_type = declared[name].get("enumType")
        if "stringOffsets" in prop:
            offsets = view(prop["stringOffsets"])
            kind = "H" if prop.get("stringOffsetType") == "UINT16" else "I"
            bounds = struct.unpack_from(f"<{count + 1}{kind}", offsets, 0)
            for i in range(count):
                rows[i][name] = values[bounds[i] : bounds[i + 1]].decode("utf-8")
        elif enum_type is not None:
            names = {v["value"]: v["name"] for v in schema["enums"][enum_type]["values"]}
            for i in range(count):
                found = names.get(values[i], "")
                rows[i][name] = "" if found == declared[name].get("noData") else found
        else:
            kind = {"INT64": "q", "UINT16": "H", "UINT8": "B"}[declared[name]["componentType"]]
            width = {"SCALAR": 1, "VEC3": 3}[declared[name]["type"]]
            numbers = struct.unpack_from(f"<{count * width}{kind}", values, 0)
            no_data = declared[name].get("noData")
            for i in range(count):
                value = numbers[i] if width == 1 else list(numbers[i * width : (i + 1) * width])
                rows[i][name] = None if value == no_data else value
    return rows


def inferred_of(row):
    """The values a row's building inferred, as the tags they stand for."""
    inferred = {}
    if row.get("inferred_roof_shape"):
        inferred["roof:shape"] = row["inferred_roof_shape"]
    if row.get("inferred_building_levels") is not None:
        inferred["building:levels"] = str(row["inferred_building_levels"])
    for key in ("building:colour", "roof:colour"):
        colour = row.get("inferred_" + key.replace(":", "_"))
        if colour is not None:
            inferred[key] = "#%02x%02x%02x" % tuple(colour)
    return inferred


class Areas(osmium.SimpleHandler):
    """Footprint areas of closed building ways, square metres."""

    def __init__(self):
        super().__init__()
        self.areas = {}

    def way(self, w):
        if "building" not in w.tags or len(w.nodes) < 4 or w.nodes[0].ref != w.nodes[-1].ref:
            return
        try:
            points = [(n.lon, n.lat) for n in w.nodes]
        except osmium.InvalidLocationError:
            return
        lat0 = points[0][1]
        east = 111_320 * math.cos(math.radians(lat0))
        xy = [(lon * east, lat * 110_540) for lon, lat in points]
        area = sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(xy, xy[1:])) / 2
        self.areas[w.id] = abs(area)


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    areas = Areas()
    areas.apply_file(sys.argv[1], locations=True)
    seen = {}
    tiles = {}
    windows = {}
    for path in sys.argv[2:]:
        buildings, colours = 0, set()
        glazed = glazed_features(path)
        for feature, row in enumerate(property_table(path)):
            if row.get("class") != "building" or row.get("osm_type") != "way":
                continue
            buildings += 1
            tags = json.loads(row["tags"] or "{}")
            inferred = inferred_of(row)
            try:
                levels = float(tags.get("building:levels") or inferred.get("building:levels"))
            except (TypeError, ValueError):
                levels = 0
            if levels >= 2:
                has = feature in glazed or windows.get(row["osm_id"], (None, False))[1]
                windows[row["osm_id"]] = (tags.get("building", "yes"), has)
            if "roof:colour" in inferred:
                colours.add(inferred["roof:colour"])
            tagged = tags.get("roof:shape")
            shape = tagged or inferred.get("roof:shape", "flat")
            seen[row["osm_id"]] = (tags.get("building", "yes"), shape, tagged is not None)
        tiles[path] = {"buildings": buildings, "inferred_roof_colours": len(colours)}
    by_type = defaultdict(Counter)
    small = Counter()
    for osm_id, (kind, shape, tagged) in seen.items():
        by_type[kind][shape] += 1
        if not tagged and areas.areas.get(osm_id, math.inf) < 300:
            small["pitched" if shape != "flat" else "flat"] += 1
    total_small = sum(small.values())
    unglazed = Counter(kind for kind, has in windows.values() if not has)
    print(
        json.dumps(
            {
                "buildings": len(seen),
                "untagged_under_300m2": total_small,
                "pitched_share_untagged_under_300m2": small["pitched"] / total_small
                if total_small
                else None,
                "two_levels_or_more": len(windows),
                "of_them_with_windows": sum(1 for _, has in windows.values() if has),
                "without_windows_by_type": dict(unglazed.most_common()),
                "without_windows": sorted(i for i, (_, has) in windows.items() if not has),
                "shapes_by_type": {
                    k: dict(v.most_common())
                    for k, v in sorted(by_type.items(), key=lambda kv: -sum(kv[1].values()))
                },
                "tiles": tiles,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
