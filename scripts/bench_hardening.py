#!/usr/bin/env python3
"""A hostile client's figures against `terrastitch serve` on the bundled sample (loopback,
default configuration): 100 concurrent debug views of the densest tile with a cold tile asked
meanwhile (answers, the cold tile's latency, the server's peak and held memory, views made);
80 requests for a cold tile opened and dropped, then one whole request (renders made); how long
a half-sent request stays open; how long SIGTERM takes with five half-sent requests open.
Usage: scripts/bench_hardening.py   (from the repository root, after a release build)"""
import socket
import subprocess
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
