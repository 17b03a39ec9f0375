#!/usr/bin/env python3
"""Writes the EGM96 geoid grid terrastitch embeds (src/geoid-egm96-15.bin) from PROJ's
`egm96_15.gtx` (Debian package proj-data: /usr/share/proj/egm96_15.gtx; EGM96 is a work of the
US National Geospatial-Intelligence Agency, public domain; PROJ's grid file is under the MIT
licence).

    egm96_grid.py egm96_15.gtx src/geoid-egm96-15.bin

The GTX file: a 40-byte big-endian header (south-west latitude and longitude, latitude and
longitude spacing as f64; rows and columns as i32), then rows × columns f32 undulations in
metres, rows from south to north. The output: a 16-byte little-endian header (rows, columns
as u32; south-west latitude and longitude in hundredths of a degree as i32), then the
undulations in centimetres as i16, rows from south to north, columns from west to east.
"""
import struct
import sys


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    data = open(sys.argv[1], 'rb').read()
    south, west, dlat, dlon = struct.unpack('>4d', data[:32])
    rows, cols = struct.unpack('>2i', data[32:40])
    assert (dlat, dlon) == (0.25, 0.25), (dlat, dlon)
    values = struct.unpack(f'>{rows * cols}f', data[40:40 + 4 * rows * cols])
    out = bytearray(struct.pack('<2I2i', rows, cols, round(south * 100), round(west * 100)))
    for value in values:
        out += struct.pack('<h', round(value * 100))
    open(sys.argv[2], 'wb').write(out)
    print(f'{rows} rows x {cols} columns from {south}, {west}; {len(out)} bytes')


if __name__ == '__main__':
    main()
