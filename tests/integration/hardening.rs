//! The server against careless and hostile clients, on 127.0.0.1 only and bounded in count and
//! time: debug views made in the render slots, renders shared whoever drops their request,
//! slow, idle and surplus connections closed or refused, shutdown that ends, the admin token
//! checked before a body is read; and the cache's side: a purge beats a remake under way, a tile
//! the store cannot take is served all the same.

use crate::common;

use std::sync::atomic::Ordering;
use std::sync::Arc;

use common::{sample_osm, sample_srtm, wait_until, TestServer, HUNG};
use terrastitch::cache::{
    Provenance, Remade, SqliteStore, StoreError, StoredEntry, StoredTile, TileCache, TileFilter,
    TileReader, TileStore, Usage,
};
use terrastitch::config::ServerConfig;
use terrastitch::format::{Format, TileKey};
use terrastitch::provider::Inputs;
use terrastitch::TileId;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

async fn start(dir: &std::path::Path, config: ServerConfig) -> TestServer {
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data loads");
    TestServer::start_with(&dir.join("cache.sqlite"), sources, &config).await
}

fn address(server: &TestServer) -> String {
    server.base.trim_start_matches("http://").to_string()
}

/// Reads until the server closes the connection; returns what came. Fails the test if the
/// server never closes it (within [`HUNG`]: a bound that means it hung).
async fn read_to_close(stream: &mut TcpStream) -> Vec<u8> {
    let mut received = Vec::new();
    let mut buffer = [0u8; 4096];
    loop {
        match tokio::time::timeout(HUNG, stream.read(&mut buffer)).await {
            Ok(Ok(0)) | Ok(Err(_)) => return received,
            Ok(Ok(n)) => received.extend_from_slice(&buffer[..n]),
            Err(_) => panic!(
                "it hung: the server never closed the connection ({})",
                String::from_utf8_lossy(&received)
            ),
        }
    }
}

/// Reads a response's head and a body of `Content-Length` bytes from a kept-alive connection.
async fn read_response(stream: &mut TcpStream) -> String {
    let mut received = Vec::new();
    let mut buffer = [0u8; 4096];
    loop {
        let text = String::from_utf8_lossy(&received).to_string();
        if let Some(end) = text.find("\r\n\r\n") {
            let length = text[..end]
                .lines()
                .find_map(|l| {
                    l.to_lowercase()
                        .strip_prefix("content-length: ")
                        .map(String::from)
                })
                .and_then(|l| l.trim().parse::<usize>().ok())
                .unwrap_or(0);
            if received.len() >= end + 4 + length {
                return text;
            }
        }
        match tokio::time::timeout(HUNG, stream.read(&mut buffer)).await {
            Ok(Ok(n)) if n > 0 => received.extend_from_slice(&buffer[..n]),
            other => panic!("no whole response ({other:?}): {text}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_debug_views_of_a_tile_are_made_once_in_a_render_slot() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        render_threads: 1,
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    let url = server.url("/debug/tiles/14/8529/5973.geojson");
    let requests: Vec<_> = (0..30)
        .map(|_| {
            let url = url.clone();
            tokio::spawn(async move {
                let response = reqwest::get(url).await.unwrap();
                (
                    response.status().as_u16(),
                    response.bytes().await.unwrap().len(),
                )
            })
        })
        .collect();
    for request in requests {
        let (status, length) = request.await.unwrap();
        assert_eq!(status, 200);
        assert!(length > 100, "{length}");
    }
    assert_eq!(
        server.metric("terrastitch_debug_views_total").await,
        1.0,
        "thirty requests at once share one view"
    );
    server.stop().await;

    // Turned off, the route is a JSON 404.
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        render_threads: 1,
        debug_view: false,
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    let response = server.get("/debug/tiles/14/8529/5973.geojson", &[]).await;
    assert_eq!(response.status(), 404);
    let body: serde_json::Value = response.json().await.unwrap();
    assert!(
        body["error"].as_str().unwrap().contains("debug_view"),
        "{body}"
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_dropped_midway_leave_one_render_for_the_next() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), ServerConfig::default()).await;
    let path = "/tiles/14/8529/5974.glb";
    let metrics = server.state.metrics.clone();
    for sent in 1..=20 {
        let mut stream = TcpStream::connect(address(&server)).await.unwrap();
        let request = format!("GET {path} HTTP/1.1\r\nHost: test\r\n\r\n");
        stream.write_all(request.as_bytes()).await.unwrap();
        // Dropped once the server has taken the request in, the first once its render began.
        wait_until("the request to reach the server", || {
            metrics.tile_requests.load(Ordering::Relaxed) >= sent
                && (sent > 1
                    || server.state.pool_gauges().running > 0
                    || metrics.renders.load(Ordering::Relaxed) > 0)
        })
        .await;
        drop(stream);
    }
    let response = server.get(path, &[]).await;
    assert_eq!(response.status(), 200);
    assert!(response.bytes().await.unwrap().len() > 1000);
    assert_eq!(
        server.metric("terrastitch_renders_total").await,
        1.0,
        "every dropped request joined the first one's render"
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slow_and_idle_connections_are_closed_after_the_head_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        header_timeout_s: 1,
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    // Connected, nothing sent.
    let mut idle = TcpStream::connect(address(&server)).await.unwrap();
    // Half a request's head.
    let mut slow = TcpStream::connect(address(&server)).await.unwrap();
    slow.write_all(b"GET /health HTTP/1.1\r\nHost: te")
        .await
        .unwrap();
    // One request answered, then the connection kept alive and idle.
    let mut kept = TcpStream::connect(address(&server)).await.unwrap();
    kept.write_all(b"GET /health HTTP/1.1\r\nHost: test\r\n\r\n")
        .await
        .unwrap();
    // Each is closed by the server (the head timeout is a second; a connection it left open
    // would hang the read).
    for (name, stream) in [
        ("idle", &mut idle),
        ("slow", &mut slow),
        ("kept", &mut kept),
    ] {
        let received = read_to_close(stream).await;
        if name == "kept" {
            assert!(received.starts_with(b"HTTP/1.1 200"), "{name}");
        }
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn past_the_connection_limit_one_more_is_refused_with_a_json_503() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        max_connections: 3,
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    // Three connections, each known to be open: the server answered a request on it.
    let mut held = Vec::new();
    for _ in 0..3 {
        let mut stream = TcpStream::connect(address(&server)).await.unwrap();
        stream
            .write_all(b"GET /health HTTP/1.1\r\nHost: test\r\n\r\n")
            .await
            .unwrap();
        let answer = read_response(&mut stream).await;
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
        held.push(stream);
    }
    let mut surplus = TcpStream::connect(address(&server)).await.unwrap();
    let received = read_to_close(&mut surplus).await;
    let text = String::from_utf8_lossy(&received);
    assert!(text.starts_with("HTTP/1.1 503"), "{text}");
    assert!(text.to_lowercase().contains("retry-after: "), "{text}");
    assert!(text.contains("{\"error\":"), "{text}");
    drop(held);
    let metrics = server.state.metrics.clone();
    wait_until("the held connections to close", || {
        metrics.connections_open.load(Ordering::Relaxed) == 0
    })
    .await;
    assert_eq!(server.get("/health", &[]).await.status(), 200);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_closes_half_sent_requests_after_the_grace_period() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        header_timeout_s: 600,
        shutdown_grace_s: 1,
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    let mut streams = Vec::new();
    for _ in 0..5 {
        let mut stream = TcpStream::connect(address(&server)).await.unwrap();
        stream
            .write_all(b"POST /admin/purge HTTP/1.1\r\nHost: te")
            .await
            .unwrap();
        streams.push(stream);
    }
    let metrics = server.state.metrics.clone();
    wait_until("the five connections to be open", || {
        metrics.connections_open.load(Ordering::Relaxed) == 5
    })
    .await;
    // The stop ends (after the grace period of a second) with the half-sent requests still
    // unfinished, and closes their connections.
    tokio::time::timeout(HUNG, server.stop())
        .await
        .expect("it hung: the server never stopped");
    for stream in &mut streams {
        read_to_close(stream).await;
    }
    assert_eq!(metrics.connections_open.load(Ordering::Relaxed), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_admin_token_is_checked_before_a_body_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        admin_token: "secret".to_string(),
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    for (authorization, status) in [("", "401"), ("authorization: bEaReR secret\r\n", "413")] {
        let mut stream = TcpStream::connect(address(&server)).await.unwrap();
        let head = format!(
            "POST /admin/purge HTTP/1.1\r\nHost: test\r\n{authorization}\
             content-type: application/json\r\ncontent-length: 10000000000\r\n\r\n{{"
        );
        stream.write_all(head.as_bytes()).await.unwrap();
        let received = read_to_close(&mut stream).await;
        let text = String::from_utf8_lossy(&received);
        assert!(text.starts_with(&format!("HTTP/1.1 {status}")), "{text}");
        assert!(text.contains("{\"error\":"), "{text}");
    }
    server.stop().await;
}

fn key(x: u32) -> TileKey {
    TileKey {
        tile: TileId { z: 14, x, y: 5973 },
        format: Format::GLB,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_purge_made_while_a_tile_is_made_again_wins() {
    let dir = tempfile::tempdir().unwrap();
    let store = Arc::new(SqliteStore::open(&dir.path().join("c.sqlite"), None).unwrap());
    let cache = TileCache::new(store.clone(), 1 << 20);
    let made_by = Provenance::default();
    let render = |bytes: Vec<u8>| move || Ok::<_, std::io::Error>(bytes);
    cache
        .get_or_render(key(1), None, render(vec![1; 100]))
        .await
        .unwrap();
    // The remake waits until the purge is done.
    let (go, wait) = std::sync::mpsc::channel::<()>();
    let (began, beginning) = tokio::sync::oneshot::channel::<()>();
    let since = cache.purges_so_far();
    let remake = {
        let cache = cache.clone();
        tokio::spawn(async move {
            let slow = move || {
                let _ = began.send(());
                let _ = wait.recv();
                Ok::<_, std::io::Error>(vec![2; 100])
            };
            cache.remake(key(1), made_by, since, slow).await
        })
    };
    tokio::time::timeout(HUNG, beginning)
        .await
        .expect("it hung: the remake never began")
        .unwrap();
    let removed = cache
        .purge(TileFilter::Tiles(vec![key(1).tile]))
        .await
        .unwrap();
    assert_eq!(removed, vec![key(1)]);
    go.send(()).unwrap();
    assert_eq!(remake.await.unwrap().unwrap(), Remade::Purged);
    assert_eq!(
        store.usage().unwrap().tiles,
        0,
        "the purged tile stays gone"
    );
    assert!(cache.peek(&key(1)).await.is_none());

    // A remake of another tile, begun before the purge, is stored.
    let since = cache.purges_so_far();
    let remade = cache
        .remake(key(2), Provenance::default(), since, render(vec![3; 100]))
        .await
        .unwrap();
    assert_eq!(remade, Remade::Stored);
    assert_eq!(store.usage().unwrap().tiles, 1);
}

/// A store whose disk is full: it reads, but takes nothing.
#[derive(Debug)]
struct FullDisk(SqliteStore);

impl TileReader for FullDisk {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        self.0.get(key)
    }
    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError> {
        self.0.list(filter)
    }
    fn usage(&self) -> Result<Usage, StoreError> {
        self.0.usage()
    }
}

impl TileStore for FullDisk {
    fn put(&self, _key: &TileKey, _tile: &StoredTile) -> Result<(), StoreError> {
        Err(full(self.0.path()))
    }
    fn put_if_vacant(&self, _key: &TileKey, _tile: &StoredTile) -> Result<bool, StoreError> {
        Err(full(self.0.path()))
    }
    fn touch(&self, keys: &[TileKey], at: i64) -> Result<(), StoreError> {
        self.0.touch(keys, at)
    }
    fn remove(&self, filter: &TileFilter) -> Result<Vec<TileKey>, StoreError> {
        self.0.remove(filter)
    }
}

fn full(path: &std::path::Path) -> StoreError {
    StoreError::Sqlite {
        path: path.to_path_buf(),
        source: rusqlite::Error::SqliteFailure(
            rusqlite::ffi::Error::new(rusqlite::ffi::SQLITE_FULL),
            Some("database or disk is full".to_string()),
        ),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tile_the_store_cannot_take_is_served_from_memory() {
    let dir = tempfile::tempdir().unwrap();
    let store = FullDisk(SqliteStore::open(&dir.path().join("c.sqlite"), None).unwrap());
    let cache = TileCache::new(Arc::new(store), 1 << 20);
    let renders = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    for _ in 0..3 {
        let counted = renders.clone();
        let served = cache
            .get_or_render(key(1), None, move || {
                counted.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                Ok::<_, std::io::Error>(vec![7; 1000])
            })
            .await
            .expect("served though not stored");
        assert_eq!(served.tile.bodies.identity.as_ref(), &[7; 1000][..]);
        assert!(!served.tile.stored);
    }
    assert_eq!(
        renders.load(std::sync::atomic::Ordering::SeqCst),
        1,
        "kept in memory, not made at every request"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_srtm_files_the_server_says_it_cannot_serve() {
    let dir = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    let sources = Inputs::open(&[sample_osm()], empty.path(), 14).expect("sources open");
    let server = TestServer::start_with(
        &dir.path().join("cache.sqlite"),
        sources,
        &ServerConfig::default(),
    )
    .await;
    let response = server.get("/ready", &[]).await;
    assert_eq!(response.status(), 503);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["srtm_files"], 0);
    assert!(
        body["cannot_serve"].as_str().unwrap().contains("SRTM"),
        "{body}"
    );
    server.stop().await;
}

/// Sends one raw request and returns the status line, the headers (lower case) and the body.
async fn raw(server: &TestServer, request: &[u8]) -> (String, String, String) {
    let mut stream = TcpStream::connect(address(server)).await.unwrap();
    stream.write_all(request).await.unwrap();
    let received = read_to_close(&mut stream).await;
    let text = String::from_utf8_lossy(&received).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let (status, headers) = head.split_once("\r\n").unwrap_or((head, ""));
    (status.to_string(), headers.to_lowercase(), body.to_string())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_error_is_json_with_its_right_code() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        admin_token: "secret".to_string(),
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    let close = "Host: test\r\nConnection: close\r\n";
    for (request, status) in [
        (format!("GET /tiles/14/%FF%FE/1.glb HTTP/1.1\r\n{close}\r\n"), "400"),
        (format!("GET foo HTTP/1.1\r\n{close}\r\n"), "400"),
        (format!("POST /nonexistent.html HTTP/1.1\r\n{close}content-length: 0\r\n\r\n"), "404"),
        (format!("POST /index.html HTTP/1.1\r\n{close}content-length: 0\r\n\r\n"), "405"),
        (format!("DELETE /tiles/14/8529/5973.glb HTTP/1.1\r\n{close}\r\n"), "405"),
        (format!("GET /.hidden HTTP/1.1\r\n{close}\r\n"), "404"),
        (
            format!("POST /admin/purge HTTP/1.1\r\n{close}authorization: Bearer secret\r\ncontent-length: 3000000\r\n\r\n"),
            "413",
        ),
        // What hyper refuses before any route sees it.
        (format!("GET /{} HTTP/1.1\r\n{close}\r\n", "a".repeat(70_000)), "414"),
        (
            format!(
                "GET /health HTTP/1.1\r\n{close}{}\r\n",
                (0..120).map(|i| format!("x-h{i}: v\r\n")).collect::<String>()
            ),
            "431",
        ),
        (format!("GET /tiles/\u{ff}\u{fe} HTTP/1.1\r\n{close}\r\n"), "400"),
        (format!("GET /tiles/14/8529/5973.glb?compress= HTTP/1.1\r\n{close}\r\n"), "400"),
        (format!("GET /tiles/14/08529/5973.glb HTTP/1.1\r\n{close}\r\n"), "400"),
        (format!("GET /tiles/14/+8529/5973.glb HTTP/1.1\r\n{close}\r\n"), "400"),
    ] {
        // Characters below 256 as bytes: a request line that is not UTF-8.
        let bytes: Vec<u8> = match request.chars().all(|c| u32::from(c) < 256) {
            true => request.chars().map(|c| c as u8).collect(),
            false => request.clone().into_bytes(),
        };
        let (line, headers, body) = raw(&server, &bytes).await;
        let request: String = request.chars().take(200).collect();
        assert!(line.starts_with(&format!("HTTP/1.1 {status}")), "{request}: {line}");
        assert!(headers.contains("content-type: application/json"), "{request}: {headers}");
        let parsed: serde_json::Value = serde_json::from_str(&body).expect(&body);
        assert!(parsed["error"].is_string(), "{body}");
    }

    // A client's request id is kept when it is short and plain, replaced otherwise.
    let long = "a".repeat(300);
    for (id, kept) in [("abc-1", true), (long.as_str(), false), ("a b", false)] {
        let request = format!("GET /health HTTP/1.1\r\n{close}x-request-id: {id}\r\n\r\n");
        let (_, headers, _) = raw(&server, request.as_bytes()).await;
        let sent = headers
            .lines()
            .find_map(|l| l.strip_prefix("x-request-id: "))
            .unwrap()
            .to_string();
        assert_eq!(sent == id, kept, "{id}: {sent}");
        assert!(sent.len() <= 128);
    }

    // TileJSON is built from Host: a shared cache must key it on Host.
    let (_, headers, _) = raw(
        &server,
        format!("GET /tiles.json HTTP/1.1\r\n{close}\r\n").as_bytes(),
    )
    .await;
    assert!(headers.contains("vary: host"), "{headers}");
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coarse_tiles_far_from_the_data_are_served_but_not_stored() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), ServerConfig::default()).await;
    let store = server.state.cache.reader();
    // Zoom 6 over the Pacific, then zoom 6 over Monaco.
    for (path, stored) in [("/tiles/6/2/30.terrain", 0), ("/tiles/6/33/23.terrain", 1)] {
        let response = server.get(path, &[]).await;
        assert_eq!(response.status(), 200, "{path}");
        assert!(!response.bytes().await.unwrap().is_empty());
        // A tile made for a request is stored once its forms kept are made.
        server.state.cache.refined().await;
        assert_eq!(store.usage().unwrap().tiles, stored, "{path}");
    }
    // Served again, from memory.
    let response = server.get("/tiles/6/2/30.terrain", &[]).await;
    assert_eq!(response.headers()["x-cache-layer"], "memory");
    assert_eq!(server.metric("terrastitch_tiles_unstored_total").await, 0.0);
    server.stop().await;
}
