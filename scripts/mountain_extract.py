#!/usr/bin/env python3
"""Writes a synthetic mountain area as an OSM extract, for benchmarks: a valley road that
crosses its stream on bridges and cuts through spurs in tunnels, roads of hairpin bends up
the valley sides, tracks from their bends, houses along the valley road and two villages of
residential streets on its sides, laid over the SRTM
terrain of a steep valley of the bundled file (the Estéron, north-west of Nice, whose sides
rise 1,200 m in 3 km).

    mountain_extract.py OUT.osm.pbf [--srtm data/N43E007.hgt] [--centre LAT,LON]

Prints the box it covers (W,S,E,N) on stdout.
"""

import argparse
import math
import sys

import numpy as np
import osmium

# A window of the valley: its centre and half sizes, degrees.
CENTRE = (43.915, 7.10)
HALF_LAT, HALF_LON = 0.02, 0.035
METRES_PER_DEGREE = 111_320.0


class Area:
    """The terrain of the window, and metres east and north of its centre."""

    def __init__(self, hgt, centre):
        self.samples = np.fromfile(hgt, dtype=">i2").reshape(1201, 1201).astype(float)
        self.lat0, self.lon0 = centre
        self.south_west = (math.floor(self.lat0), math.floor(self.lon0))
        self.cos = math.cos(math.radians(self.lat0))

    def lonlat(self, x, y):
        return (self.lon0 + x / (METRES_PER_DEGREE * self.cos), self.lat0 + y / METRES_PER_DEGREE)

    def height(self, x, y):
        lon, lat = self.lonlat(x, y)
        row = (self.south_west[0] + 1 - lat) * 1200
        col = (lon - self.south_west[1]) * 1200
        r, c = int(row), int(col)
        fr, fc = row - r, col - c
        s = self.samples
        return ((s[r, c] * (1 - fc) + s[r, c + 1] * fc) * (1 - fr)
                + (s[r + 1, c] * (1 - fc) + s[r + 1, c + 1] * fc) * fr)


def valley_floor(area, width, height, step=40.0):
    """The stream: at each step east, the lowest point north to south, smoothed."""
    xs = np.arange(-width, width + step, step)
    ys = []
    for x in xs:
        column = [(area.height(x, y), y) for y in np.arange(-height * 0.8, height * 0.8, 20.0)]
        ys.append(min(column)[1])
    ys = np.convolve(np.pad(ys, 3, mode="edge"), np.ones(7) / 7, mode="valid")
    return list(zip(xs, ys))


def offset(line, distance):
    """The line moved `distance` metres to its left."""
    out = []
    for k, (x, y) in enumerate(line):
        (ax, ay), (bx, by) = line[max(k - 1, 0)], line[min(k + 1, len(line) - 1)]
        dx, dy = bx - ax, by - ay
        n = math.hypot(dx, dy) or 1.0
        out.append((x - dy / n * distance, y + dx / n * distance))
    return out


class Writer:
    """Nodes and ways with ids counted from 1; ways share the nodes of points they share."""

    def __init__(self, area):
        self.area = area
        self.nodes = {}
        self.ways = []

    def node(self, point):
        key = (round(point[0], 2), round(point[1], 2))
        if key not in self.nodes:
            self.nodes[key] = len(self.nodes) + 1
        return self.nodes[key]

    def way(self, points, tags):
        self.ways.append(([self.node(p) for p in points], tags))

    def write(self, path):
        writer = osmium.SimpleWriter(path, overwrite=True)
        try:
            for (x, y), id_ in sorted(self.nodes.items(), key=lambda item: item[1]):
                lon, lat = self.area.lonlat(x, y)
                writer.add_node(osmium.osm.mutable.Node(
                    id=id_, location=osmium.osm.Location(lon, lat), version=1))
            for id_, (refs, tags) in enumerate(self.ways, start=1):
                writer.add_way(osmium.osm.mutable.Way(id=id_, nodes=refs, tags=tags, version=1))
        finally:
            writer.close()


def valley_road(out, stream, every=6):
    """Beside the stream, crossing it on a bridge every `every` steps (240 m), through tunnels
    where spurs stand between two of its points 400 m apart. Returns its points and how many
    bridges it has."""
    side, road, piece = 1, [], []
    crossings = 0
    for k in range(len(stream)):
        if k and k % every == 0:
            # A bridge: from this side, over the stream, to the other.
            here = offset(stream[k - 1:k + 2], 28 * side)[1]
            side = -side
            there = offset(stream[k:k + 2], 28 * side)[0]
            piece.append(here)
            out.way(piece, {"highway": "secondary", "name": "Route de la vallée"})
            out.way([here, there], {"highway": "secondary", "bridge": "yes", "layer": "1",
                                    "name": "Route de la vallée"})
            piece = [there]
            crossings += 1
            continue
        point = offset(stream[max(k - 1, 0):k + 2], 28 * side)[min(k, 1)]
        piece.append(point)
        road.append(point)
    out.way(piece, {"highway": "secondary", "name": "Route de la vallée"})
    # Tunnel shortcuts through the highest ground between two points 10 steps apart, in two
    # halves of the road.
    rise = [out.area.height((road[k][0] + road[k + 10][0]) / 2, (road[k][1] + road[k + 10][1]) / 2)
            - max(out.area.height(*road[k]), out.area.height(*road[k + 10]))
            for k in range(len(road) - 10)]
    half = len(rise) // 2
    for best in (max(range(half), key=rise.__getitem__),
                 max(range(half, len(rise)), key=rise.__getitem__)):
        a, b = road[best], road[best + 10]
        inside = [(a[0] + (b[0] - a[0]) * t / 8, a[1] + (b[1] - a[1]) * t / 8) for t in range(9)]
        out.way(inside[:2], {"highway": "secondary"})
        out.way(inside[1:-1], {"highway": "secondary", "tunnel": "yes", "layer": "-1"})
        out.way(inside[-2:], {"highway": "secondary"})
    return road, crossings


def hairpins(out, road, at, legs=7, leg=260.0, rise=45.0):
    """A road climbing the valley side in hairpin bends from point `at` of the valley road;
    a track goes on from every other bend. Returns the bends."""
    start = road[at]
    ahead = road[at + 1]
    along = np.array(ahead) - np.array(start)
    along /= np.linalg.norm(along)
    # Uphill: the side of the road where the ground 100 m away is higher.
    left = np.array([-along[1], along[0]])
    up = left if out.area.height(*(start + 100 * left)) > out.area.height(*(start - 100 * left)) else -left
    points, bends = [tuple(start)], []
    here = np.array(start)
    for k in range(legs):
        direction = along if k % 2 == 0 else -along
        for t in range(1, 6):
            points.append(tuple(here + direction * leg * t / 5 + up * rise * t / 5))
        here = here + direction * leg + up * rise
        bends.append(tuple(here))
    out.way(points, {"highway": "unclassified"})
    for k, bend in enumerate(bends[::2]):
        outward = (along if k % 2 else -along) * 180 + up * 60
        out.way([bend, tuple(np.array(bend) + outward / 2), tuple(np.array(bend) + outward)],
                {"highway": "track", "tracktype": "grade3"})
    return bends


def village(out, road, at, streets=5, spacing=70.0):
    """A grid of residential streets on the valley side from point `at` of the valley road,
    each with houses on both sides. Returns how many houses."""
    start = np.array(road[at])
    along = np.array(road[at + 1]) - start
    along /= np.linalg.norm(along)
    across = np.array([-along[1], along[0]])
    if out.area.height(*(start + 150 * across)) < out.area.height(*(start - 150 * across)):
        across = -across
    count = 0
    # Streets across the slope, joined by lanes along it.
    for k in range(streets):
        base = start + along * spacing * (k - streets // 2) + across * 45
        line = [tuple(base + across * spacing * t) for t in range(4)]
        out.way(line, {"highway": "residential"})
        for t in range(1, 4):
            for side in (1, -1):
                centre = base + across * (spacing * t - spacing / 2) + along * 14 * side
                u, v = across, along
                corners = [tuple(centre + u * dx + v * dy)
                           for dx, dy in ((-5, -4), (5, -4), (5, 4), (-5, 4))]
                out.way(corners + corners[:1], {"building": "house"})
                count += 1
    for t in range(1, 4):
        lane = [tuple(start + along * spacing * (k - streets // 2) + across * (45 + spacing * t))
                for k in range(streets)]
        out.way(lane, {"highway": "residential"})
    return count


def houses(out, road, spacing=2):
    """Houses beside every other point of the valley road, on both sides, in two rows set back
    18 and 34 m."""
    count = 0
    for k in range(2, len(road) - 2, spacing):
        (ax, ay), (bx, by) = road[k - 1], road[k + 1]
        n = math.hypot(bx - ax, by - ay) or 1.0
        ux, uy = (bx - ax) / n, (by - ay) / n
        for side, back in ((1, 18), (-1, 18), (1, 34), (-1, 34)):
            cx, cy = road[k][0] - uy * back * side, road[k][1] + ux * back * side
            corners = [(cx + ux * dx - uy * dy, cy + uy * dx + ux * dy)
                       for dx, dy in ((-6, -4.5), (6, -4.5), (6, 4.5), (-6, 4.5))]
            out.way(corners + corners[:1],
                    {"building": "house", "building:levels": str(1 + (k // spacing) % 3)})
            count += 1
    return count


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--srtm", default="data/N43E007.hgt")
    parser.add_argument("--centre", default=f"{CENTRE[0]},{CENTRE[1]}")
    args = parser.parse_args()
    lat, lon = (float(v) for v in args.centre.split(","))
    area = Area(args.srtm, (lat, lon))
    width = HALF_LON * METRES_PER_DEGREE * area.cos
    height = HALF_LAT * METRES_PER_DEGREE
    stream = valley_floor(area, width * 0.9, height)
    out = Writer(area)
    out.way(stream, {"waterway": "river", "name": "L'Estéron"})
    road, bridges = valley_road(out, stream)
    for share in (4, 2):
        hairpins(out, road, len(road) // share)
    hairpins(out, road, 3 * len(road) // 4, leg=200.0)
    built = houses(out, road)
    for at in (len(road) // 3, 2 * len(road) // 3):
        built += village(out, road, at)
    out.write(args.out)
    west, south = area.lonlat(-width, -height)
    east, north = area.lonlat(width, height)
    print(f"{west:.4f},{south:.4f},{east:.4f},{north:.4f}")
    print(f"{len(out.ways)} ways ({bridges} bridges, 2 tunnels, {built} houses), "
          f"{len(out.nodes)} nodes", file=sys.stderr)


if __name__ == "__main__":
    main()
