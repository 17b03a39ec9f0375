//! Several terrastitch processes sharing one PostgreSQL database, on a real server (a throwaway
//! cluster, see `common/pg_cluster.rs`): servers render each cold tile once between them, take
//! over the tiles of a replica that died, hear each other's purges and new tiles, and seed
//! workers share one queue.

use crate::common;

use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use common::pg_cluster::Cluster;
use common::process::{request, spawn_server};
use common::wait_for;
use terrastitch::cache::encoding::Bodies;
use terrastitch::cache::{etag_of, PostgresStore, StoredTile, TileFilter, TileReader, TileStore};
use terrastitch::format::{Format, TileKey};
use terrastitch::tile::{TileId, TileRange};

const TOKEN: &str = "cluster-secret";

/// A child process, killed when dropped (so a failing test leaves nothing running).
struct Process(Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A `serve` process on the shared database.
struct Replica {
    process: Process,
    address: String,
    /// What it logged (read all along: a pipe left full would stop the server).
    log: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
    /// The thread reading the log; it ends when the process has closed its output.
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Replica {
    /// Starts a server on `url` with `lease_s` and `threads` render slots, once it is ready.
    fn start(url: &str, lease_s: u64, threads: usize) -> Replica {
        let lease = lease_s.to_string();
        let threads = threads.to_string();
        let (child, address, lines) = spawn_server(
            &[],
            &[
                ("TERRASTITCH_CACHE__URL", url),
                ("TERRASTITCH_CACHE__LEASE_S", &lease),
                ("TERRASTITCH_SERVER__ADMIN_TOKEN", TOKEN),
                ("TERRASTITCH_SERVER__RENDER_THREADS", &threads),
                ("TERRASTITCH_SERVER__CHECK_INTERVAL_S", "0"),
            ],
        );
        let log = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let keeping = log.clone();
        let reader = std::thread::spawn(move || {
            for line in lines {
                keeping.lock().unwrap().push(line);
            }
        });
        let replica = Replica {
            process: Process(child),
            address,
            log,
            reader: Some(reader),
        };
        wait_for("the server to become ready", || {
            (try_get(&replica.address, "/ready").map(|r| r.0) == Some(200)).then_some(())
        });
        replica
    }

    /// Everything it logged, once it has ended.
    fn whole_log(&mut self) -> String {
        if let Some(reader) = self.reader.take() {
            reader.join().unwrap();
        }
        self.log.lock().unwrap().join("\n")
    }

    fn get(&self, path: &str) -> (u16, String, Vec<u8>) {
        request(&self.address, path, &[])
    }

    /// A counter of `/metrics`.
    fn metric(&self, name: &str) -> f64 {
        common::process::metric(&self.address, name).unwrap_or(0.0)
    }

    fn post_admin(&self, route: &str, body: &str) -> u16 {
        let mut stream = std::net::TcpStream::connect(&self.address).unwrap();
        use std::io::{Read, Write};
        write!(
            stream,
            "POST {route} HTTP/1.1\r\nHost: {}\r\nAuthorization: Bearer {TOKEN}\r\n\
             Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            self.address,
            body.len()
        )
        .unwrap();
        let mut response = String::new();
        stream.read_to_string(&mut response).unwrap();
        response.split_whitespace().nth(1).unwrap().parse().unwrap()
    }
}

/// A GET that tells a refused or cut connection by `None` (a server still starting, or killed).
fn try_get(address: &str, path: &str) -> Option<(u16, Vec<u8>)> {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(address).ok()?;
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut response = Vec::new();
    stream.read_to_end(&mut response).ok()?;
    let split = response.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = String::from_utf8_lossy(&response[..split]).to_string();
    let status = head.split_whitespace().nth(1)?.parse().ok()?;
    Some((status, response[split + 4..].to_vec()))
}

fn path(x: u32, y: u32) -> String {
    format!("/tiles/14/{x}/{y}.glb")
}

fn key(x: u32, y: u32) -> TileKey {
    TileKey {
        tile: TileId { z: 14, x, y },
        format: Format::GLB,
    }
}

fn client(url: &str) -> postgres::Client {
    postgres::Client::connect(url, postgres::NoTls).expect("connecting to the test cluster")
}

/// The holder of the render claim on tile 14/x/y, if one holds it.
fn lease_holder(db: &mut postgres::Client, x: u32, y: u32) -> Option<String> {
    db.query_opt(
        "SELECT holder FROM leases WHERE z = 14 AND x = $1 AND y = $2 AND expires_at > now()",
        &[&(x as i32), &(y as i32)],
    )
    .unwrap()
    .map(|row| row.get(0))
}

#[test]
fn three_replicas_render_each_cold_tile_once_between_them() {
    let cluster = Cluster::start();
    let url = cluster.database("tiles");
    let replicas: Vec<Replica> = (0..3).map(|_| Replica::start(&url, 15, 2)).collect();
    let tiles: Vec<(u32, u32)> = (8527..=8531).map(|x| (x, 5973)).collect();
    // 150 requests at once, spread over the replicas and the tiles.
    let answers: Vec<((u32, u32), u16, Vec<u8>)> = std::thread::scope(|scope| {
        let asked: Vec<_> = (0..150)
            .map(|i| {
                let replica = &replicas[i % 3];
                let tile = tiles[(i / 3) % tiles.len()];
                scope.spawn(move || {
                    let (status, _, body) = replica.get(&path(tile.0, tile.1));
                    (tile, status, body)
                })
            })
            .collect();
        asked
            .into_iter()
            .map(|h| h.join().expect("a request"))
            .collect()
    });
    for (tile, status, body) in &answers {
        assert_eq!(*status, 200, "{tile:?}: {}", String::from_utf8_lossy(body));
    }
    for tile in &tiles {
        let bodies: Vec<&Vec<u8>> = answers
            .iter()
            .filter(|(t, ..)| t == tile)
            .map(|(.., body)| body)
            .collect();
        assert_eq!(bodies.len(), 30);
        assert!(
            bodies.iter().all(|b| *b == bodies[0]),
            "{tile:?}: every replica answers the same bytes"
        );
    }
    let renders: Vec<f64> = replicas
        .iter()
        .map(|r| r.metric("terrastitch_renders_total"))
        .collect();
    assert_eq!(
        renders.iter().sum::<f64>(),
        5.0,
        "one render a tile in the whole cluster: {renders:?}"
    );
    let store = PostgresStore::open(&url, None).unwrap();
    assert_eq!(store.usage().unwrap().tiles, 5);
}

#[test]
fn a_killed_replicas_claim_lapses_and_another_makes_its_tile() {
    let cluster = Cluster::start();
    let url = cluster.database("tiles");
    let lease = Duration::from_secs(2);
    // One render slot on the first replica: its third tile waits in line, claimed.
    let first = Replica::start(&url, lease.as_secs(), 1);
    let second = Replica::start(&url, lease.as_secs(), 2);
    let mut db = client(&url);
    let address = first.address.clone();
    let queued: Vec<_> = [(8529, 5974), (8530, 5974), (8528, 5974)]
        .into_iter()
        .map(|(x, y)| {
            let address = address.clone();
            let asked = std::thread::spawn(move || try_get(&address, &path(x, y)));
            wait_for("the tile to be claimed", || lease_holder(&mut db, x, y));
            asked
        })
        .collect();
    let holder = lease_holder(&mut db, 8528, 5974).expect("the third tile is claimed");
    let mut first = first;
    first.process.0.kill().unwrap();
    first.process.0.wait().unwrap();
    let killed = Instant::now();
    let store = PostgresStore::open(&url, None).unwrap();
    assert!(
        store.get(&key(8528, 5974)).unwrap().is_none(),
        "the killed replica had not made its third tile"
    );
    // Its clients were cut off; they ask the other replica again.
    for asked in queued {
        let answer = asked.join().unwrap();
        assert!(answer.is_none_or(|(status, _)| status == 200));
    }
    let (status, _, _) = second.get(&path(8528, 5974));
    let waited = killed.elapsed();
    assert_eq!(status, 200);
    assert_eq!(second.metric("terrastitch_renders_total"), 1.0);
    assert!(store.get(&key(8528, 5974)).unwrap().is_some());
    assert_ne!(lease_holder(&mut db, 8528, 5974).as_deref(), Some(&*holder));
    eprintln!("taken over and made {waited:?} after the kill (lease {lease:?})");
}

#[test]
fn purges_and_new_tiles_on_one_replica_reach_the_others_memory() {
    let cluster = Cluster::start();
    let url = cluster.database("tiles");
    let (a, b) = (Replica::start(&url, 15, 2), Replica::start(&url, 15, 2));
    let tile = path(8527, 5973);
    let (status, _, made) = b.get(&tile);
    assert_eq!(status, 200);
    let (_, head, _) = b.get(&tile);
    assert!(head.contains("x-cache-layer: memory"), "{head}");
    // A purge sent to the first replica: the second no longer answers from memory (it would
    // forever if the purge did not reach it).
    assert_eq!(a.post_admin("/admin/purge", r#"{"all": true}"#), 200);
    let purged = Instant::now();
    wait_for("the purge to reach the second replica", || {
        let (status, head, body) = b.get(&tile);
        assert_eq!(status, 200);
        (!head.contains("x-cache-layer: memory")).then(|| assert_eq!(body, made))
    });
    eprintln!(
        "the purge reached the other replica in {:?}",
        purged.elapsed()
    );

    // Another version of the tile put underneath, and told (as a process storing it would):
    // the second replica holds it in memory. Made again on request of the first replica, the
    // new tile is what the second serves within a second of its landing.
    let store = PostgresStore::open(&url, None).unwrap();
    let current = store.get(&key(8527, 5973)).unwrap().expect("stored");
    let other: Vec<u8> = b"another version of the tile".to_vec();
    let older = StoredTile {
        etag: etag_of(&other),
        bodies: Bodies::compress(other.clone()).unwrap(),
        ..current
    };
    store.put(&key(8527, 5973), &older).unwrap();
    client(&url)
        .execute(
            "SELECT pg_notify('terrastitch', $1)",
            &[&r#"{"from": "test", "stored": [["14/8527/5973", "glb"]]}"#],
        )
        .unwrap();
    wait_for("the told version to be held in memory", || {
        let (_, head, body) = b.get(&tile);
        (body == other && head.contains("x-cache-layer: memory")).then_some(())
    });
    assert_eq!(
        a.post_admin("/admin/regenerate", r#"{"tiles": ["14/8527/5973"]}"#),
        202
    );
    wait_for("the tile to be made again", || {
        let now = store.get(&key(8527, 5973)).unwrap().expect("stored");
        (now.etag != older.etag).then_some(())
    });
    let landed = Instant::now();
    wait_for("the new version to reach the second replica", || {
        let (_, _, body) = b.get(&tile);
        (body == made).then_some(())
    });
    eprintln!(
        "the new version reached the other replica in {:?}",
        landed.elapsed()
    );
}

/// Starts `terrastitch seed` on `bbox` into the shared database.
fn seed_worker(url: &str, (bbox, formats): (&str, &str), lease_s: u64) -> Process {
    let child = common::terrastitch()
        .args([
            "seed",
            "--bbox",
            bbox,
            "--format",
            formats,
            "--threads",
            "1",
        ])
        .args(["--cache-url", url])
        .env("TERRASTITCH_CACHE__LEASE_S", lease_s.to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("a seed worker");
    Process(child)
}

/// Waits for a worker to end; its exit status.
fn finish(mut worker: Process) -> std::process::ExitStatus {
    wait_for("the seed worker to finish", || worker.0.try_wait().unwrap())
}

/// Tiles made by the cluster's workers, summed.
fn made_by_workers(db: &mut postgres::Client) -> i64 {
    db.query_one("SELECT coalesce(sum(made), 0)::bigint FROM workers", &[])
        .unwrap()
        .get(0)
}

/// Every tile of the box is stored whole (its digest checked on reading).
fn assert_whole(store: &PostgresStore, range: TileRange) {
    let stored = store.list(&TileFilter::Range(range)).unwrap();
    assert_eq!(stored.len() as u64, range.len(), "every tile of the box");
    for entry in stored {
        assert!(store.get(&entry.key).unwrap().is_some(), "{entry:?}");
    }
}

#[test]
fn seed_workers_share_one_queue_and_finish_a_killed_workers_tiles() {
    let cluster = Cluster::start();
    let range = TileRange {
        z: 14,
        min_x: 8527,
        max_x: 8531,
        min_y: 5972,
        max_y: 5975,
    };
    assert_eq!(range.len(), 20);
    let bbox = common::bbox(8527, 8531, 5972, 5975);

    // Two workers from the start, in two formats (a tile's rows are taken together): each
    // tile made once.
    let url = cluster.database("together");
    let both = (bbox.as_str(), "glb,terrain");
    let workers = [seed_worker(&url, both, 3), seed_worker(&url, both, 3)];
    for worker in workers {
        assert!(finish(worker).success());
    }
    let store = PostgresStore::open(&url, None).unwrap();
    let stored = store.list(&TileFilter::Range(range)).unwrap();
    assert_eq!(stored.len(), 40, "every tile of the box in both formats");
    let mut db = client(&url);
    assert_eq!(made_by_workers(&mut db), 40, "each tile made once");
    let worked: i64 = db
        .query_one("SELECT count(*) FROM workers WHERE made > 0", &[])
        .unwrap()
        .get(0);
    assert_eq!(worked, 2, "both workers made tiles");

    // One worker killed after its first tile: the other finishes its share.
    let url = cluster.database("killed");
    let store = PostgresStore::open(&url, None).unwrap();
    let survivor = seed_worker(&url, (&bbox, "glb"), 2);
    let doomed = seed_worker(&url, (&bbox, "glb"), 2);
    let mut db = client(&url);
    let doomed_pid = doomed.0.id();
    wait_for("the doomed worker's first tile", || {
        let made: i64 = db
            .query_one(
                "SELECT coalesce(sum(made), 0)::bigint FROM workers WHERE name LIKE $1",
                &[&format!("%:{doomed_pid}:%")],
            )
            .unwrap()
            .get(0);
        (made >= 1).then_some(())
    });
    drop(doomed);
    assert!(finish(survivor).success());
    assert_whole(&store, range);
    assert_eq!(made_by_workers(&mut db), 20, "each tile made once");
    let left: i64 = db
        .query_one("SELECT count(*) FROM work", &[])
        .unwrap()
        .get(0);
    assert_eq!(left, 0, "the queue is empty");
}

#[test]
fn a_server_on_postgresql_stops_cleanly_on_sigterm_and_sigint() {
    let cluster = Cluster::start();
    for (signal, name) in [(libc::SIGTERM, "sigterm"), (libc::SIGINT, "sigint")] {
        let url = cluster.database(name);
        let mut replica = Replica::start(&url, 15, 1);
        // A tile made and stored, so connections are open and pooled when it stops.
        let (status, _, _) = replica.get(&path(8529, 5973));
        assert_eq!(status, 200);
        let pid = libc::pid_t::try_from(replica.process.0.id()).unwrap();
        // SAFETY: kill sends a signal to the child this test started.
        assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
        let status = wait_for(&format!("the server to stop on {name}"), || {
            replica.process.0.try_wait().unwrap()
        });
        let log = replica.whole_log();
        assert_eq!(status.code(), Some(0), "{name}: {status}\n{log}");
        assert!(!log.contains("panic"), "{name}:\n{log}");
    }
}

#[test]
fn a_password_in_the_cache_url_never_reaches_a_log_or_an_answer() {
    const SECRET: &str = "S3cretXyz";
    let cluster = Cluster::start();
    let url = format!("{}?password={SECRET}", cluster.database("secret"));
    let replica = Replica::start(&url, 15, 1);
    let (status, _, _) = replica.get(&path(8529, 5973));
    assert_eq!(status, 200);
    let log = wait_for("the store's place in the log", || {
        let log = replica.log.lock().unwrap().join("\n");
        log.contains("password=***").then_some(log)
    });
    assert!(!log.contains(SECRET), "{log}");
    let mut replica = replica;
    replica.process.0.kill().unwrap();
    let log = replica.whole_log();
    assert!(!log.contains(SECRET), "{log}");
    drop(replica);
    let status = common::terrastitch()
        .args(["seed", "status", "--cache-url", &url])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&status.stdout).to_string()
        + &String::from_utf8_lossy(&status.stderr);
    assert!(status.status.success(), "{said}");
    assert!(!said.contains(SECRET), "{said}");
    // A mistyped scheme, and the key-value form, are refused without echoing it.
    for wrong in [
        format!("postgress://tiles:{SECRET}@127.0.0.1/tiles"),
        format!("host=127.0.0.1 password={SECRET}"),
    ] {
        let refused = common::terrastitch()
            .args(["seed", "status", "--cache-url", &wrong])
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&refused.stderr).to_string();
        assert!(!refused.status.success(), "{said}");
        assert!(said.contains("must be a PostgreSQL URL"), "{said}");
        assert!(!said.contains(SECRET), "{said}");
    }
}
