#!/usr/bin/env python3
"""Greedy-insertion meshing of raw SRTM windows: terrastitch against pydelatin and pymartini.

  scripts/terrain_compare.py FILE.hgt... [--errors 1,5,10] [--windows win257,crop1025]

terrastitch runs through `target/release/examples/tin_bench` (build it first); the peers through
their Python packages. Every mesh is checked by the same independent measure
(../shared/tools/tin_error.py: max and RMS vertical error over all grid points, holes), so the
comparison is at *measured* error. Times are best of three, wall clock, on this machine.
"""
import argparse, json, os, subprocess, sys, tempfile, time
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
TOOLS = os.path.join(HERE, '..', '..', 'shared', 'tools')
sys.path.insert(0, TOOLS)
from tin_error import tin_error  # noqa: E402

BENCH = os.path.join(HERE, '..', 'target', 'release', 'examples', 'tin_bench')


def window(h, name):
    n = h.shape[0]
    o = (n - 257) // 2
    return {'full': h, 'crop1025': h[:1025, :1025], 'win256': h[o:o + 256, o:o + 256],
            'win257': h[o:o + 257, o:o + 257]}[name]


def best(fn, repeat=3):
    t, out = 1e9, None
    for _ in range(repeat):
        s = time.perf_counter(); out = fn(); t = min(t, time.perf_counter() - s)
    return t, out


def ours(path, name, err, w):
    with tempfile.TemporaryDirectory() as d:
        prefix = os.path.join(d, 'mesh')
        out = subprocess.run([BENCH, path, name, str(err), prefix], check=True, capture_output=True, text=True)
        r = json.loads(out.stdout)
        v = np.fromfile(prefix + '.vertices', '<f8').reshape(-1, 3)
        t = np.fromfile(prefix + '.triangles', '<u4').reshape(-1, 3)
    c = tin_error(w, v[:, :2], t, z=v[:, 2])
    return dict(tool='terrastitch', seconds=r['seconds'], triangles=len(t), max=c['max_err'], rms=c['rms_err'], holes=c['uncovered'])


def delatin(w, err):
    from pydelatin import Delatin
    hf = np.ascontiguousarray(w, np.float32)
    t, d = best(lambda: Delatin(hf, max_error=err))
    v, tri = d.vertices, d.triangles
    xy = np.c_[v[:, 0], (w.shape[0] - 1) - v[:, 1]]
    c = tin_error(w, xy, tri, z=v[:, 2])
    return dict(tool='pydelatin', seconds=t, triangles=len(tri), max=c['max_err'], rms=c['rms_err'], holes=c['uncovered'])


def martini(w, err):
    from pymartini import Martini
    m = Martini(w.shape[0])
    hf = np.ascontiguousarray(w, np.float32)
    t1, tile = best(lambda: m.create_tile(hf))
    t2, (v, tri) = best(lambda: tile.get_mesh(err))
    c = tin_error(w, v.astype(float), tri)
    return dict(tool='pymartini', seconds=t1 + t2, triangles=len(tri), max=c['max_err'], rms=c['rms_err'], holes=c['uncovered'])


if __name__ == '__main__':
    ap = argparse.ArgumentParser()
    ap.add_argument('hgt', nargs='+'); ap.add_argument('--errors', default='1,5,10')
    ap.add_argument('--windows', default='win257,crop1025')
    a = ap.parse_args()
    print(f"{'file':8} {'window':9} {'bound':>5} {'tool':12} {'seconds':>8} {'triangles':>9} {'max err':>8} {'rms':>6} {'holes':>5}")
    for path in a.hgt:
        h = np.fromfile(path, '>i2'); n = int(round(np.sqrt(h.size))); h = h.reshape(n, n).astype(np.float64)
        for name in a.windows.split(','):
            w = window(h, name)
            for err in [float(e) for e in a.errors.split(',')]:
                rows = [ours(path, name, err, w), delatin(w, err)]
                if w.shape[0] in (257, 1025):
                    rows.append(martini(w, err))
                for r in rows:
                    print(f"{os.path.basename(path)[:7]:8} {name:9} {err:5g} {r['tool']:12} {r['seconds']:8.4f} {r['triangles']:9d} "
                          f"{r['max']:8.3f} {r['rms']:6.3f} {r['holes']:5d}", flush=True)
