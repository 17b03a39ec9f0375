//! Inputs fetched on demand from a local HTTP server that serves the bundled files, and
//! misbehaves on request: 404s, 500s, a server that fails twice then recovers, truncated
//! bodies, answers slower than the timeout.

use crate::common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{repo, sample_osm, TestServer};
use terrastitch::config::{ServerConfig, SourcesConfig};
use terrastitch::provider::{Inputs, Renderer};
use terrastitch::render::RenderSettings;
use terrastitch::source::fetch::Fetcher;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// A tile of the bundled sample; it needs N43E007 alone.
const TILE: &str = "/tiles/14/8529/5973.glb";

/// An HTTP server on 127.0.0.1 serving the files of `root` under `/MODE/NAME`, where MODE is
/// `ok`, `missing` (404), `error` (500), `flaky` (500 twice per path, then the file),
/// `truncated` (the announced length, half the body, then the connection closes), `slow`
/// (the answer after three seconds) or `unannounced` (the file without its length). It counts
/// the requests per path.
struct Upstream {
    base: String,
    hits: Arc<Mutex<HashMap<String, usize>>>,
}

impl Upstream {
    async fn start(root: PathBuf) -> Upstream {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let base = format!("http://{}", listener.local_addr().unwrap());
        let hits: Arc<Mutex<HashMap<String, usize>>> = Arc::default();
        let counted = hits.clone();
        tokio::spawn(async move {
            loop {
                let Ok((stream, _)) = listener.accept().await else {
                    return;
                };
                let (root, hits) = (root.clone(), counted.clone());
                tokio::spawn(async move {
                    let _ = answer(stream, &root, &hits).await;
                });
            }
        });
        Upstream { base, hits }
    }

    fn url(&self, mode: &str, name: &str) -> String {
        format!("{}/{mode}/{name}", self.base)
    }

    fn hits(&self, mode: &str, name: &str) -> usize {
        let path = format!("/{mode}/{name}");
        self.hits.lock().unwrap().get(&path).copied().unwrap_or(0)
    }
}

async fn answer(
    mut stream: tokio::net::TcpStream,
    root: &Path,
    hits: &Mutex<HashMap<String, usize>>,
) -> std::io::Result<()> {
    let mut request = Vec::new();
    let mut buffer = [0u8; 4096];
    while !request.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buffer).await?;
        if n == 0 {
            return Ok(());
        }
        request.extend_from_slice(&buffer[..n]);
    }
    let text = String::from_utf8_lossy(&request).to_string();
    let path = text.split_whitespace().nth(1).unwrap_or("/").to_string();
    let if_none_match = text
        .lines()
        .find_map(|l| {
            l.strip_prefix("If-None-Match: ")
                .or(l.strip_prefix("if-none-match: "))
        })
        .map(|v| v.trim().to_string());
    let count = {
        let mut hits = hits.lock().unwrap();
        let n = hits.entry(path.clone()).or_insert(0);
        *n += 1;
        *n
    };
    let mut parts = path.trim_start_matches('/').splitn(2, '/');
    let (mode, name) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let status =
        |code: &str| format!("HTTP/1.1 {code}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
    let body = std::fs::read(root.join(name));
    let reply = match (mode, body) {
        ("missing", _) | (_, Err(_)) => status("404 Not Found").into_bytes(),
        ("error", _) => status("500 Internal Server Error").into_bytes(),
        ("flaky", _) if count <= 2 => status("503 Service Unavailable").into_bytes(),
        (mode, Ok(body)) => {
            if mode == "slow" {
                tokio::time::sleep(Duration::from_secs(3)).await;
            }
            let etag = format!(
                "\"{}-{}\"",
                body.len(),
                body.iter().map(|&b| u64::from(b)).sum::<u64>()
            );
            if if_none_match.as_deref() == Some(etag.as_str()) {
                format!("HTTP/1.1 304 Not Modified\r\nETag: {etag}\r\nConnection: close\r\n\r\n")
                    .into_bytes()
            } else {
                let length = match mode {
                    "unannounced" => String::new(),
                    _ => format!("Content-Length: {}\r\n", body.len()),
                };
                let mut reply =
                    format!("HTTP/1.1 200 OK\r\n{length}ETag: {etag}\r\nConnection: close\r\n\r\n")
                        .into_bytes();
                let sent = if mode == "truncated" {
                    &body[..body.len() / 2]
                } else {
                    &body[..]
                };
                reply.extend_from_slice(sent);
                reply
            }
        }
    };
    stream.write_all(&reply).await?;
    stream.shutdown().await
}

/// Inputs with no SRTM file of their own, fetching them from `srtm_url`.
fn config(dir: &Path, srtm_url: String) -> SourcesConfig {
    let empty = dir.join("srtm");
    std::fs::create_dir_all(&empty).unwrap();
    SourcesConfig {
        osm: vec![sample_osm()],
        srtm: empty,
        srtm_url,
        downloads: dir.join("downloads"),
        download_timeout_s: 1,
        download_retries: 2,
        download_backoff_ms: 10,
        download_failure_memory_s: 60,
        ..SourcesConfig::default()
    }
}

/// A server on these sources, its cache in `dir`.
async fn server(dir: &Path, config: SourcesConfig) -> TestServer {
    let fetcher = Arc::new(Fetcher::new(config.fetch_settings()));
    let loading = (config.clone(), fetcher.clone());
    let sources = tokio::task::spawn_blocking(move || Inputs::load(&loading.0, 14, loading.1))
        .await
        .unwrap()
        .expect("sources load");
    let server_config = ServerConfig {
        render_threads: 2,
        check_interval_s: 0,
        ..ServerConfig::default()
    };
    let renderer = Renderer::new(sources, RenderSettings::default(), server_config.zoom)
        .reopening_from(config, fetcher);
    TestServer::start_rendering(&dir.join("cache.sqlite"), renderer, &server_config).await
}

async fn get(server: &TestServer, path: &str) -> (u16, String) {
    let response = reqwest::get(server.url(path)).await.unwrap();
    let status = response.status().as_u16();
    let body = response.bytes().await.unwrap();
    (
        status,
        String::from_utf8_lossy(&body[..body.len().min(2000)]).to_string(),
    )
}

/// The files a directory holds, by name.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().to_string())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_burst_of_requests_for_a_missing_srtm_file_downloads_it_once() {
    let dir = tempfile::tempdir().unwrap();
    let upstream = Upstream::start(repo().join("data")).await;
    let server = server_on(dir.path(), &upstream, "ok").await;
    // A hundred requests over five tiles of the same SRTM cell, all at once.
    let paths: Vec<String> = (0..100)
        .map(|i| format!("/tiles/14/{}/5973.terrain", 8527 + i % 5))
        .collect();
    let client = reqwest::Client::new();
    let requests = paths.iter().map(|path| {
        let request = client.get(server.url(path)).send();
        async move {
            let response = request.await.unwrap();
            let status = response.status().as_u16();
            let _ = response.bytes().await;
            status
        }
    });
    let statuses = futures_join_all(requests).await;
    assert!(statuses.iter().all(|&s| s == 200), "{statuses:?}");
    assert_eq!(upstream.hits("ok", "N43E007.hgt"), 1, "one download");
    assert_eq!(server.metric("terrastitch_downloads_total").await, 1.0);
    // The file is in place, whole, and nothing half-written is left beside it.
    let downloads = dir.path().join("downloads");
    assert_eq!(
        names(&downloads),
        vec!["N43E007.hgt", "N43E007.hgt.validators.json"]
    );
    assert_eq!(
        std::fs::read(downloads.join("N43E007.hgt")).unwrap(),
        std::fs::read(repo().join("data/N43E007.hgt")).unwrap()
    );
    server.stop().await;
}

async fn futures_join_all<F: std::future::Future<Output = u16> + Send + 'static>(
    futures: impl Iterator<Item = F>,
) -> Vec<u16> {
    let handles: Vec<_> = futures.map(tokio::spawn).collect();
    let mut out = Vec::new();
    for handle in handles {
        out.push(handle.await.unwrap());
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_file_the_source_lacks_is_a_404_naming_it_and_asked_for_once() {
    let dir = tempfile::tempdir().unwrap();
    let upstream = Upstream::start(repo().join("data")).await;
    let server = server(
        dir.path(),
        config(dir.path(), upstream.url("missing", "{lat}{lon}.hgt.zip")),
    )
    .await;
    for _ in 0..10 {
        let (status, body) = get(&server, TILE).await;
        assert_eq!(status, 404, "{body}");
        assert!(
            body.contains("404 for N43E007.hgt.zip from the configured SRTM source"),
            "{body}"
        );
    }
    // The failure is remembered: one request upstream, however many tiles asked.
    assert_eq!(upstream.hits("missing", "N43E007.hgt.zip"), 1);
    assert_eq!(
        server.metric("terrastitch_download_failures_total").await,
        1.0
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn server_errors_are_retried_with_backoff_then_named() {
    let dir = tempfile::tempdir().unwrap();
    let upstream = Upstream::start(repo().join("data")).await;
    let server = server(
        dir.path(),
        config(dir.path(), upstream.url("error", "{lat}{lon}.hgt")),
    )
    .await;
    let (status, body) = get(&server, TILE).await;
    assert_eq!(status, 502, "{body}");
    assert!(body.contains("N43E007.hgt"), "{body}");
    assert!(
        body.contains("after 3 attempts") && body.contains("500"),
        "{body}"
    );
    assert_eq!(
        upstream.hits("error", "N43E007.hgt"),
        3,
        "the first try and two retries"
    );
    server.stop().await;

    // A server that fails twice and then recovers is waited out.
    let dir = tempfile::tempdir().unwrap();
    let server = server_on(dir.path(), &upstream, "flaky").await;
    let (status, body) = get(&server, TILE).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(upstream.hits("flaky", "N43E007.hgt"), 3);
    server.stop().await;
}

async fn server_on(dir: &Path, upstream: &Upstream, mode: &str) -> TestServer {
    server(dir, config(dir, upstream.url(mode, "{lat}{lon}.hgt"))).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn truncated_and_slow_downloads_fail_without_leaving_a_file() {
    let upstream = Upstream::start(repo().join("data")).await;
    for mode in ["truncated", "slow"] {
        let dir = tempfile::tempdir().unwrap();
        let server = server_on(dir.path(), &upstream, mode).await;
        let (status, body) = get(&server, TILE).await;
        assert_eq!(status, 502, "{mode}: {body}");
        assert!(
            body.contains("N43E007.hgt") && body.contains("after 3 attempts"),
            "{mode}: {body}"
        );
        if mode == "slow" {
            // Each attempt gave up at the timeout rather than waiting for the slow server.
            assert!(body.to_lowercase().contains("timeout"), "{body}");
        }
        assert_eq!(upstream.hits(mode, "N43E007.hgt"), 3);
        // Neither the file nor a partial one is left behind.
        assert_eq!(
            names(&dir.path().join("downloads")),
            Vec::<String>::new(),
            "{mode}"
        );
        server.stop().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_download_whose_checksum_differs_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let upstream = Upstream::start(repo().join("data")).await;
    let mut config = config(dir.path(), upstream.url("ok", "{lat}{lon}.hgt"));
    config
        .checksums
        .insert("N43E007.hgt".to_string(), "00".repeat(32));
    let server = server(dir.path(), config).await;
    let (status, body) = get(&server, TILE).await;
    assert_eq!(status, 502, "{body}");
    assert!(
        body.contains("SHA-256") && body.contains("N43E007.hgt"),
        "{body}"
    );
    assert_eq!(names(&dir.path().join("downloads")), Vec::<String>::new());
    server.stop().await;
}

/// An extract given by URL is downloaded at start; when a new version is published there, the
/// source check brings it, the tiles it changes are served stale while they are made again,
/// then the new tiles are served.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn an_extract_published_anew_at_its_url_is_fetched_and_its_tiles_made_again() {
    let dir = tempfile::tempdir().unwrap();
    let published = dir.path().join("published");
    std::fs::create_dir_all(&published).unwrap();
    std::fs::copy(sample_osm(), published.join("monaco.osm.pbf")).unwrap();
    let upstream = Upstream::start(published.clone()).await;
    let mut sources = config(dir.path(), String::new());
    sources.srtm = repo().join("data");
    sources.osm = vec![PathBuf::from(upstream.url("ok", "monaco.osm.pbf"))];
    let server = server(dir.path(), sources.clone()).await;
    assert_eq!(upstream.hits("ok", "monaco.osm.pbf"), 1);

    let first = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(first.status(), 200);
    let first_etag = first.headers()["etag"].clone();
    let first = first.bytes().await.unwrap();

    // Nothing changed: the check asks (with the ETag) and leaves everything as it is.
    let queued = terrastitch::server::regenerate::check_sources(&server.state)
        .await
        .unwrap();
    assert_eq!(queued, 0);

    // A new extract is published at the same URL.
    std::fs::copy(
        repo().join("tests/data/monaco-planetiler-2021.osm.pbf"),
        published.join("monaco.osm.pbf"),
    )
    .unwrap();
    let queued = terrastitch::server::regenerate::check_sources(&server.state)
        .await
        .unwrap();
    assert_eq!(queued, 1, "the one stored tile is stale");
    let stale = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(stale.headers()["x-cache"], "stale");
    assert_eq!(
        stale.bytes().await.unwrap(),
        first,
        "the old tile while the new one is made"
    );

    let deadline = Instant::now() + common::HUNG;
    while server.metric("terrastitch_regenerations_total").await < 1.0 {
        assert!(Instant::now() < deadline, "the tile was not made again");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let fresh = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(fresh.headers()["x-cache"], "hit");
    assert_ne!(fresh.headers()["etag"], first_etag);
    assert_ne!(fresh.bytes().await.unwrap(), first);
    server.stop().await;
}

/// The source check notices local files that changed: a new SRTM file far away reloads the
/// sources but leaves the tile fresh, as does its own SRTM file written again with the same
/// bytes; other bytes in it make the tile stale.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_changed_local_file_makes_stale_only_the_tiles_it_reaches() {
    let dir = tempfile::tempdir().unwrap();
    let srtm = dir.path().join("srtm");
    std::fs::create_dir_all(&srtm).unwrap();
    std::fs::copy(repo().join("data/N43E007.hgt"), srtm.join("N43E007.hgt")).unwrap();
    let mut sources = config(dir.path(), String::new());
    sources.srtm = srtm.clone();
    let server = server(dir.path(), sources.clone()).await;
    let first = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(first.headers()["x-cache"], "miss");
    let _ = first.bytes().await;
    let check = || terrastitch::server::regenerate::check_sources(&server.state);
    assert_eq!(check().await.unwrap(), 0);

    std::fs::copy(
        repo().join("tests/data/N48E009.hgt"),
        srtm.join("N48E009.hgt"),
    )
    .unwrap();
    assert_eq!(
        check().await.unwrap(),
        0,
        "a file far from the tile stales nothing"
    );
    let layer = server.state.provider().unwrap().terrain_layer().unwrap();
    assert_eq!(layer.available.last().map(Vec::len), Some(2));
    let fresh = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(fresh.headers()["x-cache"], "hit");
    let _ = fresh.bytes().await;

    // The same bytes written anew (a copy made on another machine, another time): the tile
    // was made from the same data, and stays fresh.
    let mut bytes = std::fs::read(srtm.join("N43E007.hgt")).unwrap();
    std::fs::remove_file(srtm.join("N43E007.hgt")).unwrap();
    std::fs::write(srtm.join("N43E007.hgt"), &bytes).unwrap();
    later_modified(&srtm.join("N43E007.hgt"));
    assert_eq!(check().await.unwrap(), 0, "the same content stales nothing");
    let fresh = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(fresh.headers()["x-cache"], "hit");
    let _ = fresh.bytes().await;

    // Other content (one sample a metre higher): stale.
    let sample = u16::from_be_bytes([bytes[0], bytes[1]]).wrapping_add(1);
    bytes[..2].copy_from_slice(&sample.to_be_bytes());
    std::fs::write(srtm.join("N43E007.hgt"), &bytes).unwrap();
    assert_eq!(check().await.unwrap(), 1);
    let stale = reqwest::get(server.url(TILE)).await.unwrap();
    assert_eq!(stale.headers()["x-cache"], "stale");
    let _ = stale.bytes().await;
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_download_longer_than_its_kind_allows_is_refused_and_not_kept() {
    let dir = tempfile::tempdir().unwrap();
    let served = dir.path().join("served");
    std::fs::create_dir_all(&served).unwrap();
    std::fs::write(served.join("N43E007.hgt"), vec![0u8; 100_000]).unwrap();
    let upstream = Upstream::start(served).await;
    let downloads = dir.path().join("downloads");
    let fetcher = Arc::new(Fetcher::new(
        config(dir.path(), String::new()).fetch_settings(),
    ));
    // The length announced, and a body that only ends.
    for mode in ["ok", "unannounced"] {
        let url = upstream.url(mode, "N43E007.hgt");
        let fetching = fetcher.clone();
        let fetched = tokio::task::spawn_blocking(move || {
            let name = format!("{mode}.hgt");
            fetching.fetch(&terrastitch::source::fetch::Download {
                url: &url,
                name: &name,
                source_name: "SRTM",
                max_bytes: Some(50_000),
            })
        });
        let error = fetched.await.unwrap().unwrap_err().to_string();
        assert!(
            error.contains("is longer than the 50000 bytes such a file may have"),
            "{mode}: {error}"
        );
        assert!(
            names(&downloads).is_empty(),
            "{mode}: {:?}",
            names(&downloads)
        );
    }
}

/// Marks a file as modified a minute from now: a rewrite the source check cannot miss, however
/// coarse the file system's clock.
fn later_modified(path: &Path) {
    let file = std::fs::File::options().write(true).open(path).unwrap();
    file.set_modified(std::time::SystemTime::now() + Duration::from_secs(60))
        .unwrap();
}
