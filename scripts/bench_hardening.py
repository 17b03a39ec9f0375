#!/usr/bin/env python3
"""A hostile client's figures against `terrastitch serve` on the bundled sample (loopback,
default configuration): 100 concurrent debug views of the densest tile with a cold tile asked
meanwhile (answers, the cold tile's latency, the server's peak and held memory, views made);
80 requests for a cold tile opened and dropped, then one whole request (renders made); how long
a half-sent request stays open; how long SIGTERM takes with five half-sent requests open.
Then hostile data: one road node of the bundled extract moved 1, 2, 10 degrees north and east
and to the pole by a diff (scripts/osm_diff.py far-node:D), each applied to a fresh store:
`update`'s time, peak memory and tiles expired, and the next render of the road's tile.
Usage: scripts/bench_hardening.py   (from the repository root, after a release build, with a
Python that has pyosmium, tests/py/.venv/bin/python, and GNU time at /usr/bin/time)"""
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from collections import Counter

BIN = 'target/release/terrastitch'
port = 18095
d=tempfile.mkdtemp()
srv=subprocess.Popen([BIN,'serve','--listen',f'127.0.0.1:{port}','--cache',f'{d}/c.sqlite'],stderr=open(f'{d}/log','w'))
def get(path, timeout=120):
    t=time.time()
    try:
        r=urllib.request.urlopen(f'http://127.0.0.1:{port}{path}',timeout=timeout); r.read(); code=r.status
    except urllib.error.HTTPError as e: code=e.code
    except Exception as e: code=str(e)
    return code, time.time()-t
for _ in range(300):
    try:
        if get('/ready',2)[0]==200: break
    except Exception: pass
    time.sleep(0.1)
def status(k): return int(open(f'/proc/{srv.pid}/status').read().split(k+':')[1].split()[0])
def metric(name):
    txt=urllib.request.urlopen(f'http://127.0.0.1:{port}/metrics').read().decode()
    return float([l for l in txt.splitlines() if l.startswith(name+' ')][0].split()[1])
print('RSS at ready', status('VmRSS'),'KiB')
# 1. 100 concurrent debug requests + a cold tile
codes=[]; lock=threading.Lock()
def dbg():
    c,t=get('/debug/tiles/14/8529/5974.geojson')
    with lock: codes.append(c)
ths=[threading.Thread(target=dbg) for _ in range(100)]
t0=time.time()
for t in ths: t.start()
time.sleep(0.2)
cold=get('/tiles/14/8528/5973.glb')
for t in ths: t.join()
print('debug x100:', dict(Counter(codes)), 'in %.1f s'%(time.time()-t0), 'cold tile during it: %s in %.2f s'%cold, 'peak', status('VmHWM'),'KiB, held', status('VmRSS'),'KiB; debug views made', metric('terrastitch_debug_views_total'))
# 2. 80 dropped requests for a cold tile within 0.9 s
before=metric('terrastitch_renders_total')
t0=time.time()
for i in range(80):
    s=socket.create_connection(('127.0.0.1',port)); s.sendall(b'GET /tiles/14/8530/5974.glb HTTP/1.1\r\nHost: x\r\n\r\n'); time.sleep(0.01); s.close()
print('80 dropped in %.2f s'%(time.time()-t0))
c,t=get('/tiles/14/8530/5974.glb'); print('then the tile:',c,'%.2f s'%t,'renders:',metric('terrastitch_renders_total')-before)
# 3. half-sent request
s=socket.create_connection(('127.0.0.1',port)); s.sendall(b'GET /health HTTP/1.1\r\nHost: x'); t0=time.time(); s.settimeout(60)
try: r=s.recv(100)
except Exception as e: r=e
print('half-sent request closed after %.1f s'%(time.time()-t0), r)
# 4. shutdown with 5 half-sent requests
socks=[]
for i in range(5):
    s=socket.create_connection(('127.0.0.1',port)); s.sendall(b'POST /admin/purge HTTP/1.1\r\nHost: x'); socks.append(s)
t0=time.time(); srv.terminate(); srv.wait(); print('stopped %.1f s after SIGTERM with 5 half-sent requests open'%(time.time()-t0))

# 5. One node moved far away, by a diff, on a fresh store each time.
EXTRACT = 'data/monaco-osrm-2016.osm.pbf'
ROAD_TILE = '14/8527/5973'  # where the moved node lies before the move

def measured(args):
    """Runs a command to its end under GNU time (a child's own peak memory: the rusage of a
    child of this process would count the memory it had before exec): (seconds, peak memory in
    MiB, stdout)."""
    report = f'{d}/time.txt'
    started = time.time()
    done = subprocess.run(['/usr/bin/time', '-f', '%M', '-o', report, *args],
                          stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    if done.returncode != 0:
        raise SystemExit(f'{args[1]} failed: {done.returncode}')
    peak_kib = int(open(report).read().split()[-1])
    return time.time() - started, peak_kib / 1024, done.stdout

base = f'{d}/base'
os.makedirs(base)
measured([BIN, 'import', '--store', f'{base}/osm.sqlite', '--osm', EXTRACT])
for far in ['1', '2', '10', 'pole']:
    osc = f'{d}/far-{far}.osc'
    subprocess.run([sys.executable, 'scripts/osm_diff.py', EXTRACT, f'far-node:{far}', osc],
                   check=True, stderr=subprocess.DEVNULL)
    store = f'{d}/far-{far}'
    shutil.copytree(base, store)
    s_up, m_up, out = measured([BIN, 'update', '--store', f'{store}/osm.sqlite', '--osc', osc,
                                '--expired', '-'])
    expired = len(out.splitlines())
    s_r, m_r, _ = measured([BIN, 'render', ROAD_TILE, '--store', f'{store}/osm.sqlite', '--osm',
                            EXTRACT, '-o', f'{store}/tile.glb'])
    print(f'node moved {far if far == "pole" else far + "°"}: update {s_up:.2f} s, {m_up:.0f} MiB, {expired} tiles expired; '
          f'then {ROAD_TILE}: {s_r:.2f} s, {m_r:.0f} MiB')
