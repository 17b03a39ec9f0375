#!/usr/bin/env python3
"""Figures of several terrastitch processes sharing one PostgreSQL database, on one machine (so
the cores are shared: read the ratios), on a throwaway PostgreSQL cluster in a temporary
directory (run as the unprivileged user terrastitch-pg when run as root):

- cold tiles: 20 tiles of the bundled sample, each asked by three clients at once spread over
  1, 2 and 3 replicas: wall time, tiles per second, renders summed over the replicas;
- cached reads: the same 20 tiles read 2,000 times by 16 clients (asking for brotli or gzip, as
  browsers do) from one server with no memory cache, its store PostgreSQL, then SQLite:
  requests per second;
- seeding the 20 tiles with 1 and with 2 workers (one render thread each): tiles per second;
- PostgreSQL's size per stored tile (the tiles table with its index and TOAST, per row).

Usage: scripts/bench_cluster.py   (from the repository root, after a release build)"""
import glob
import http.client
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import threading
import time

BIN = os.path.abspath('target/release/terrastitch')
PG_USER = 'terrastitch-pg'
TILES = [(x, y) for y in range(5972, 5976) for x in range(8527, 8532)]
# The box of those tiles (W,S,E,N), as tests/integration/common/mod.rs computes it.
BBOX = '7.36085,43.70760,7.47069,43.77108'


def free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def as_pg_user(args):
    if os.geteuid() == 0:
        return ['runuser', '-u', PG_USER, '--'] + args
    return args


class Postgres:
    """A throwaway cluster: initdb, pg_ctl start on a free port, stopped by close()."""

    def __init__(self):
        bins = sorted(glob.glob('/usr/lib/postgresql/*/bin'), key=lambda p: int(p.split('/')[-2]))
        if not bins:
            raise SystemExit('PostgreSQL is not installed: run `make tests/.postgresql`')
        self.bin = bins[-1]
        self.dir = tempfile.mkdtemp(prefix='bench-pg-')
        if os.geteuid() == 0:
            user = pwd.getpwnam(PG_USER)
            os.chown(self.dir, user.pw_uid, user.pw_gid)
        self.data = os.path.join(self.dir, 'data')
        self.port = free_port()
        subprocess.run(as_pg_user([f'{self.bin}/initdb', '-D', self.data, '-A', 'trust', '-U', 'postgres']),
                       check=True, stdout=subprocess.DEVNULL)
        subprocess.run(as_pg_user([f'{self.bin}/pg_ctl', '-D', self.data, '-l', os.path.join(self.dir, 'log'), '-w',
                                   '-o', f'-p {self.port} -k {self.dir} -c listen_addresses=127.0.0.1', 'start']),
                       check=True, stdout=subprocess.DEVNULL)
        self.databases = 0

    def psql(self, database, sql):
        out = subprocess.run(as_pg_user([f'{self.bin}/psql', '-h', self.dir, '-p', str(self.port), '-U', 'postgres',
                                         '-d', database, '-At', '-c', sql]),
                             check=True, capture_output=True, text=True)
        return out.stdout.strip()

    def database(self):
        self.databases += 1
        name = f'bench{self.databases}'
        self.psql('postgres', f'CREATE DATABASE {name}')
        return f'postgres://postgres@127.0.0.1:{self.port}/{name}', name

    def close(self):
        subprocess.run(as_pg_user([f'{self.bin}/pg_ctl', '-D', self.data, '-m', 'immediate', '-w', 'stop']),
                       stdout=subprocess.DEVNULL)
        shutil.rmtree(self.dir, ignore_errors=True)


def get(port, path, connection=None, headers=None):
    conn = connection or http.client.HTTPConnection('127.0.0.1', port, timeout=300)
    conn.request('GET', path, headers=headers or {})
    response = conn.getresponse()
    body = response.read()
    if connection is None:
        conn.close()
    return response.status, body


class Server:
    def __init__(self, env, args=()):
        self.port = free_port()
        self.log = tempfile.TemporaryFile()
        self.process = subprocess.Popen([BIN, 'serve', '--listen', f'127.0.0.1:{self.port}', *args],
                                        env={**os.environ, 'RUST_LOG': 'warn', **env},
                                        stderr=self.log, stdout=subprocess.DEVNULL)
        for _ in range(1200):
            try:
                if get(self.port, '/ready')[0] == 200:
                    return
            except OSError:
                pass
            time.sleep(0.1)
        raise SystemExit('a server did not become ready')

    def metric(self, name):
        text = get(self.port, '/metrics')[1].decode()
        return float(next(l.split()[1] for l in text.splitlines() if l.startswith(name + ' ')))

    def stop(self):
        self.process.terminate()
        self.process.wait()


def run_together(threads):
    """Starts the threads at once and waits for them all; the seconds it took."""
    started = time.time()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return time.time() - started


def cold(pg, replicas):
    url, _ = pg.database()
    servers = [Server({'TERRASTITCH_CACHE__URL': url, 'TERRASTITCH_SERVER__CHECK_INTERVAL_S': '0'})
               for _ in range(replicas)]
    statuses = []
    lock = threading.Lock()

    def ask(i, tile):
        status, _ = get(servers[i % replicas].port, f'/tiles/14/{tile[0]}/{tile[1]}.glb')
        with lock:
            statuses.append(status)

    elapsed = run_together([threading.Thread(target=ask, args=(i * 3 + k, tile))
                            for i, tile in enumerate(TILES) for k in range(3)])
    renders = sum(s.metric('terrastitch_renders_total') for s in servers)
    for s in servers:
        s.stop()
    ok = statuses.count(200)
    return elapsed, renders, ok, len(statuses)


def cached(env, args=()):
    server = Server({**env, 'TERRASTITCH_CACHE__MEMORY_MIB': '0'}, args)
    for tile in TILES:
        get(server.port, f'/tiles/14/{tile[0]}/{tile[1]}.glb')
    count = [0]
    lock = threading.Lock()

    def client(n):
        conn = http.client.HTTPConnection('127.0.0.1', server.port, timeout=60)
        for i in range(125):
            tile = TILES[(n * 125 + i) % len(TILES)]
            # As browsers ask: the stored coding is sent as it is.
            status, _ = get(server.port, f'/tiles/14/{tile[0]}/{tile[1]}.glb', conn,
                            {'Accept-Encoding': 'br, gzip'})
            if status == 200:
                with lock:
                    count[0] += 1
        conn.close()

    elapsed = run_together([threading.Thread(target=client, args=(n,)) for n in range(16)])
    server.stop()
    return count[0] / elapsed, count[0]


def seed(pg, workers):
    url, name = pg.database()
    started = time.time()
    processes = [subprocess.Popen([BIN, 'seed', '--bbox', BBOX, '--format', 'glb', '--threads', '1',
                                   '--cache-url', url],
                                  stderr=subprocess.DEVNULL, env={**os.environ, 'RUST_LOG': 'warn'})
                 for _ in range(workers)]
    codes = [p.wait() for p in processes]
    elapsed = time.time() - started
    tiles = int(pg.psql(name, 'SELECT count(*) FROM tiles'))
    made = int(pg.psql(name, 'SELECT coalesce(sum(made), 0) FROM workers'))
    size = int(pg.psql(name, "SELECT pg_total_relation_size('tiles')"))
    held = int(pg.psql(name, 'SELECT bytes FROM usage'))
    return elapsed, tiles, made, codes, size, held


def main():
    pg = Postgres()
    try:
        base = None
        for replicas in (1, 2, 3):
            elapsed, renders, ok, asked = cold(pg, replicas)
            rate = len(TILES) / elapsed
            base = base or rate
            print(f'cold tiles, {replicas} replica(s): {len(TILES)} tiles ({asked} requests, {ok} answered 200) '
                  f'in {elapsed:.1f} s = {rate:.2f} tiles/s ({rate / base:.2f}x of one replica); '
                  f'renders in the cluster: {renders:.0f}')
        url, _ = pg.database()
        pg_rate, pg_count = cached({'TERRASTITCH_CACHE__URL': url})
        sqlite_dir = tempfile.mkdtemp(prefix='bench-sqlite-')
        sqlite_rate, sqlite_count = cached({}, ['--cache', os.path.join(sqlite_dir, 'tiles.sqlite')])
        shutil.rmtree(sqlite_dir, ignore_errors=True)
        print(f'cached reads, no memory cache, 16 clients: PostgreSQL {pg_rate:.0f} requests/s ({pg_count} answered), '
              f'SQLite {sqlite_rate:.0f} requests/s ({sqlite_count} answered): PostgreSQL at '
              f'{pg_rate / sqlite_rate:.2f}x of SQLite')
        one = None
        for workers in (1, 2):
            elapsed, tiles, made, codes, size, held = seed(pg, workers)
            rate = made / elapsed
            one = one or rate
            print(f'seed, {workers} worker(s) of one render thread: {made} tiles made, {tiles} stored, exit codes {codes}, '
                  f'in {elapsed:.1f} s = {rate:.2f} tiles/s ({rate / one:.2f}x of one worker)')
        print(f'PostgreSQL store: {size / tiles / 1024:.1f} KiB per tile on disk (tiles table, index and TOAST), '
              f'{held / tiles / 1024:.1f} KiB of tile data per tile as the size cap counts it')
    finally:
        pg.close()


if __name__ == '__main__':
    main()
