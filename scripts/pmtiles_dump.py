#!/usr/bin/env python3
"""Reads a PMTiles file with the `pmtiles` package (the format's own Python reader, nothing of
terrastitch) and prints what it holds as JSON, for tests that compare it with the tile cache.

    pmtiles_dump.py FILE.pmtiles

Prints `{"header": {...}, "metadata": {...}, "tiles": [{"z", "x", "y", "length", "sha256"}]}`;
tiles as the reader walks the directories.
"""

import hashlib
import json
import sys

from pmtiles.reader import MmapSource, Reader, all_tiles


def main():
    with open(sys.argv[1], "rb") as f:
        reader = Reader(MmapSource(f))
        header = reader.header()
        tiles = [
            {
                "z": z,
                "x": x,
                "y": y,
                "length": len(data),
                "sha256": hashlib.sha256(data).hexdigest(),
            }
            for (z, x, y), data in all_tiles(reader.get_bytes)
        ]
        out = {
            "header": {
                "min_zoom": header["min_zoom"],
                "max_zoom": header["max_zoom"],
                "clustered": bool(header["clustered"]),
                "tile_compression": int(header["tile_compression"].value),
                "addressed_tiles_count": header["addressed_tiles_count"],
            },
            "metadata": reader.metadata(),
            "tiles": tiles,
        }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
