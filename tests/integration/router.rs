//! The routes against a provider that makes tiles at once from a counter: how the server
//! answers, whatever makes the tiles. No render runs, and nothing depends on how long anything
//! takes: a tile whose making must last is held at a gate the test opens.

use crate::common;

use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};

use common::TestServer;
use terrastitch::cache::Provenance;
use terrastitch::config::ServerConfig;
use terrastitch::format::{Format, TileKey};
use terrastitch::provider::{
    Availability, Deadline, Made, MakeError, Offer, StageTimings, TileProvider, Unavailable,
};
use terrastitch::TileId;

const ZOOM: u8 = 14;
/// Tiles in this column fail to be made.
const FAILING_X: u32 = 9000;

/// Makes a tile as a text naming it and the current version, long enough to be worth
/// compressing. Tiles put on the gate wait until it opens.
#[derive(Debug, Default)]
struct Fake {
    version: AtomicU64,
    made: AtomicUsize,
    gated: Mutex<HashSet<TileId>>,
    opened: Condvar,
    /// Told the tile each make starts on.
    started: Mutex<Option<tokio::sync::mpsc::UnboundedSender<TileId>>>,
}

impl Fake {
    fn body(tile: TileId, version: u64) -> Vec<u8> {
        format!("tile {tile} made from version {version}\n")
            .repeat(200)
            .into_bytes()
    }

    /// Holds makes of `tile` until [`Fake::open`]; returns where their starts are told.
    fn gate(&self, tile: TileId) -> tokio::sync::mpsc::UnboundedReceiver<TileId> {
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        *self.started.lock().unwrap() = Some(tx);
        self.gated.lock().unwrap().insert(tile);
        rx
    }

    fn open(&self) {
        self.gated.lock().unwrap().clear();
        self.opened.notify_all();
    }
}

impl TileProvider for Fake {
    fn offer(&self) -> Offer {
        Offer {
            zoom: ZOOM,
            coverage: Vec::new(),
            only: None,
            open_ended: false,
            far_zooms: Vec::new(),
        }
    }

    fn resolve(&self, tile: TileId, format: Format) -> Result<TileKey, Unavailable> {
        match tile.z {
            ZOOM => Ok(TileKey { tile, format }),
            z => Err(Unavailable::NotOffered(format!("zoom {z} is not served"))),
        }
    }

    fn availability(&self, _key: TileKey) -> Availability {
        Availability::Ready
    }

    fn provenance(&self, _tile: TileId) -> Option<Provenance> {
        Some(Provenance {
            pipeline: "fake".to_string(),
            sources: self.version.load(Ordering::SeqCst).to_string(),
        })
    }

    fn make(&self, key: TileKey, _deadline: Deadline) -> Result<Made, MakeError> {
        if let Some(started) = &*self.started.lock().unwrap() {
            let _ = started.send(key.tile);
        }
        let mut gated = self.gated.lock().unwrap();
        while gated.contains(&key.tile) {
            gated = self.opened.wait(gated).unwrap();
        }
        drop(gated);
        self.made.fetch_add(1, Ordering::SeqCst);
        if key.tile.x == FAILING_X {
            return Err(MakeError::Encode("the fake fails here".to_string()));
        }
        Ok(Made {
            bytes: Fake::body(key.tile, self.version.load(Ordering::SeqCst)),
            timings: StageTimings::default(),
            triangles: 0,
            lp_components: 0,
            lp_violations: 0,
            stats: None,
            shared: false,
        })
    }

    fn status(&self) -> serde_json::Value {
        serde_json::json!({ "fake": true })
    }
}

fn tile(x: u32) -> TileId {
    TileId {
        z: ZOOM,
        x,
        y: 5973,
    }
}

fn path(tile: TileId) -> String {
    format!("/tiles/{}/{}/{}.glb", tile.z, tile.x, tile.y)
}

/// A server on `fake` with `config`, its cache in a directory of its own.
async fn start(fake: &Arc<Fake>, config: ServerConfig) -> (TestServer, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let state = TestServer::state(&dir.path().join("cache.sqlite"), &config);
    state.provide(fake.clone());
    (TestServer::start_state(state).await, dir)
}

fn one_slot_no_queue() -> ServerConfig {
    ServerConfig {
        render_threads: 1,
        render_queue: 0,
        check_interval_s: 0,
        ..ServerConfig::default()
    }
}

/// Waits until the background work has nothing in line (polling: no deadline is asserted).
async fn background_done(server: &TestServer) {
    for _ in 0..20_000 {
        if server.state.work.regenerator.is_empty() {
            return;
        }
        tokio::time::sleep(std::time::Duration::from_millis(1)).await;
    }
    panic!("the background work never ended");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stale_tile_is_served_then_swapped() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, ServerConfig::default()).await;
    let first = server.get(&path(tile(1)), &[]).await;
    assert_eq!(first.headers()["x-cache"], "miss");
    assert_eq!(first.bytes().await.unwrap(), Fake::body(tile(1), 0));

    fake.version.store(1, Ordering::SeqCst);
    let stale = server.get(&path(tile(1)), &[]).await;
    assert_eq!(stale.headers()["x-cache"], "stale");
    assert_eq!(
        stale.bytes().await.unwrap(),
        Fake::body(tile(1), 0),
        "the old tile while the new one is made"
    );
    background_done(&server).await;
    let fresh = server.get(&path(tile(1)), &[]).await;
    assert_eq!(fresh.headers()["x-cache"], "hit");
    assert_eq!(fresh.bytes().await.unwrap(), Fake::body(tile(1), 1));
    assert_eq!(fake.made.load(Ordering::SeqCst), 2);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_past_the_queue_gets_503_with_retry_after() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, one_slot_no_queue()).await;
    let cached = server.get(&path(tile(3)), &[]).await;
    assert_eq!(cached.status(), 200);

    let mut started = fake.gate(tile(1));
    let holding = tokio::spawn(reqwest::get(server.url(&path(tile(1)))));
    assert_eq!(
        started.recv().await,
        Some(tile(1)),
        "the first render holds the slot"
    );

    let refused = server.get(&path(tile(2)), &[]).await;
    assert_eq!(refused.status(), 503);
    assert_eq!(refused.headers()["retry-after"], "5");
    let json: serde_json::Value = refused.json().await.unwrap();
    assert!(
        json["error"].as_str().unwrap().contains("render slot"),
        "{json}"
    );
    let hit = server.get(&path(tile(3)), &[]).await;
    assert_eq!(hit.status(), 200, "a stored tile needs no slot");
    assert_eq!(hit.headers()["x-cache"], "hit");

    fake.open();
    assert_eq!(holding.await.unwrap().unwrap().status(), 200);
    assert_eq!(server.metric("terrastitch_rejected_busy_total").await, 1.0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_304_only_for_the_coding_asked() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, ServerConfig::default()).await;
    let url = path(tile(1));
    let gzip = server.get(&url, &[("accept-encoding", "gzip")]).await;
    assert_eq!(gzip.headers()["content-encoding"], "gzip");
    let etag = gzip.headers()["etag"].to_str().unwrap().to_string();
    // The tile was made for this request, its gzip form in haste: a weak validator, until the
    // smaller form replaces it under the strong one. Either matches the other weakly.
    let bare = |tag: &str| tag.trim_start_matches("W/").to_string();

    for (accept, expected) in [("gzip", 304), ("", 200), ("br", 200), ("br;q=0, gzip", 304)] {
        let response = server
            .get(
                &url,
                &[("if-none-match", &etag), ("accept-encoding", accept)],
            )
            .await;
        assert_eq!(response.status(), expected, "Accept-Encoding: {accept}");
        let sent = bare(response.headers()["etag"].to_str().unwrap());
        if expected == 304 {
            assert_eq!(sent, bare(&etag));
        } else {
            assert_ne!(sent, bare(&etag));
        }
    }
    server.stop().await;
}

/// Waits until the server's metrics say `count` requests wait for tiles; a bound that means
/// it hung.
async fn waiting_requests_reach(server: &TestServer, count: usize) {
    let line = format!("terrastitch_tile_requests_waiting {count}\n");
    let bound = std::time::Instant::now() + std::time::Duration::from_secs(120);
    loop {
        let metrics = server.get("/metrics", &[]).await.text().await.unwrap();
        if metrics.contains(&line) {
            return;
        }
        assert!(
            std::time::Instant::now() < bound,
            "never {count} requests waiting:\n{metrics}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_for_one_cold_tile_share_one_make() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, ServerConfig::default()).await;
    let mut started = fake.gate(tile(1));
    let requests: Vec<_> = (0..20)
        .map(|_| tokio::spawn(reqwest::get(server.url(&path(tile(1))))))
        .collect();
    started.recv().await;
    // Every request is in before the make may end: without one flight, each would start its
    // own make, all held at the gate.
    waiting_requests_reach(&server, 20).await;
    fake.open();
    for request in requests {
        let response = request.await.unwrap().unwrap();
        assert_eq!(response.status(), 200);
        assert_eq!(response.bytes().await.unwrap(), Fake::body(tile(1), 0));
    }
    assert_eq!(fake.made.load(Ordering::SeqCst), 1);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_tile_is_answered_with_its_error_without_trying_again() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, ServerConfig::default()).await;
    let failing = path(tile(FAILING_X));
    for attempt in 0..3 {
        let response = server.get(&failing, &[]).await;
        assert_eq!(response.status(), 500, "attempt {attempt}");
        let json: serde_json::Value = response.json().await.unwrap();
        assert!(
            json["error"]
                .as_str()
                .unwrap()
                .contains("the fake fails here"),
            "{json}"
        );
    }
    assert_eq!(fake.made.load(Ordering::SeqCst), 1);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_zoom_the_provider_does_not_offer_is_a_404_with_a_json_body() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, ServerConfig::default()).await;
    let response = server.get("/tiles/13/4264/2986.glb", &[]).await;
    assert_eq!(response.status(), 404);
    let json: serde_json::Value = response.json().await.unwrap();
    assert_eq!(json["error"], "zoom 13 is not served");
    assert_eq!(fake.made.load(Ordering::SeqCst), 0);
    server.stop().await;
}

/// A provider without the capability of a route (here, a view into how a tile was made) is
/// asked nothing: the route says so with a 404 and a JSON body, and no render slot is taken.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_route_the_provider_has_no_capability_for_is_a_404_with_a_json_body() {
    let fake = Arc::new(Fake::default());
    let (server, _dir) = start(&fake, one_slot_no_queue()).await;
    let response = server.get("/debug/tiles/14/8529/5973.geojson", &[]).await;
    assert_eq!(response.status(), 404);
    let json: serde_json::Value = response.json().await.unwrap();
    let message = json["error"].as_str().unwrap_or_default();
    assert!(message.contains("does not make tiles"), "{json}");
    assert_eq!(fake.made.load(Ordering::SeqCst), 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tiles_are_refused_with_503_until_a_provider_is_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let state = TestServer::state(&dir.path().join("cache.sqlite"), &ServerConfig::default());
    let server = TestServer::start_state(state).await;
    let waiting = server.get(&path(tile(1)), &[]).await;
    assert_eq!(waiting.status(), 503);
    assert!(waiting.headers().contains_key("retry-after"));
    assert_eq!(server.get("/ready", &[]).await.status(), 503);

    server.state.provide(Arc::new(Fake::default()));
    let ready: serde_json::Value = server.get("/ready", &[]).await.json().await.unwrap();
    assert_eq!(
        ready,
        serde_json::json!({ "status": "ready", "fake": true })
    );
    assert_eq!(server.get(&path(tile(1)), &[]).await.status(), 200);
    server.stop().await;
}
