//! Files an operator may be handed that lie, made small by each test itself: archives whose
//! tiles table is missing or never answers, a tile that does not inflate. Each is refused by
//! name or answered with a JSON error, and a server serving one still stops when told.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Stdio;

use common::process::{request, spawn_server};
use common::{wait_for, HUNG};

const TILE: (u32, u32) = (8529, 5973);

/// A child process, killed when dropped: a failing test leaves nothing running.
struct Running(std::process::Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// An MBTiles file of glb holding one small tile at 14/8529/5973.
fn mbtiles(dir: &Path) -> PathBuf {
    let path = dir.join("area.mbtiles");
    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         INSERT INTO metadata VALUES ('format', 'glb'), ('minzoom', '14'), ('maxzoom', '14');
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER,
                             tile_data BLOB);",
    )
    .unwrap();
    let row = (1i64 << 14) - 1 - i64::from(TILE.1);
    db.execute(
        "INSERT INTO tiles VALUES (14, ?1, ?2, ?3)",
        rusqlite::params![TILE.0, row, b"glTF a tile".to_vec()],
    )
    .unwrap();
    path
}

fn tile_path() -> String {
    format!("/tiles/14/{}/{}.glb", TILE.0, TILE.1)
}

/// `serve --archive FILE` run to its end: its exit status and what it said.
fn serve_archive_to_end(file: &Path) -> (std::process::ExitStatus, String) {
    let output = common::terrastitch()
        .args(["serve", "--listen", "127.0.0.1:0", "--archive"])
        .arg(file)
        .stdout(Stdio::null())
        .output()
        .unwrap();
    (
        output.status,
        String::from_utf8_lossy(&output.stderr).to_string(),
    )
}

#[test]
fn an_mbtiles_file_without_a_tiles_table_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let path = mbtiles(dir.path());
    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute_batch("DROP TABLE tiles").unwrap();
    drop(db);
    let (status, said) = serve_archive_to_end(&path);
    assert!(!status.success(), "{said}");
    assert!(
        said.contains("area.mbtiles") && said.contains("it has no tiles table"),
        "{said}"
    );
    // A tiles table without the MBTiles columns is refused alike.
    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute_batch("CREATE TABLE tiles (z INTEGER, data BLOB)")
        .unwrap();
    drop(db);
    let (status, said) = serve_archive_to_end(&path);
    assert!(!status.success(), "{said}");
    assert!(said.contains("has no zoom_level column"), "{said}");
}

#[test]
fn a_tiles_view_that_never_ends_is_stopped_and_the_server_still_stops() {
    let dir = tempfile::tempdir().unwrap();
    let path = mbtiles(dir.path());
    let (child, address, _lines) = spawn_server(
        &["--archive", path.to_str().unwrap()],
        &[("TERRASTITCH_SERVER__SHUTDOWN_GRACE_S", "2")],
    );
    let mut child = Running(child);
    let (status, _, body) = request(&address, &tile_path(), &[]);
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    // The file changes under the server: its tiles become a view with no end.
    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute_batch(
        "DROP TABLE tiles;
         CREATE VIEW tiles AS
           WITH RECURSIVE n(i) AS (SELECT 0 UNION ALL SELECT i + 1 FROM n)
           SELECT 14 AS zoom_level, i % 7 AS tile_column, i % 11 AS tile_row, x'00' AS tile_data
           FROM n;",
    )
    .unwrap();
    drop(db);
    // A tile not in memory yet: its lookup is stopped at the time limit, and answered.
    let (status, head, body) = request(&address, "/tiles/14/8530/5973.glb", &[]);
    let body = String::from_utf8_lossy(&body).to_string();
    assert_eq!(status, 500, "{body}");
    assert!(head.contains("application/json"), "{head}");
    assert!(body.contains("ran past 10 s and was stopped"), "{body}");
    // A request that hangs on the file, then the stop: the process ends.
    let asked = tile_requests(&address);
    let hanging = {
        let address = address.clone();
        std::thread::spawn(move || request(&address, "/tiles/14/8531/5973.glb", &[]))
    };
    wait_for("the hanging request to reach the server", || {
        (tile_requests(&address) > asked).then_some(())
    });
    // SAFETY: kill sends a signal to the child this test started.
    let pid = libc::pid_t::try_from(child.0.id()).unwrap();
    assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
    let status = wait_for("the server to stop on SIGTERM", || {
        child.0.try_wait().unwrap()
    });
    assert!(status.success(), "{status}");
    let _ = hanging.join();
}

#[test]
fn a_tile_an_archive_holds_but_cannot_read_is_a_json_500_not_a_404() {
    let dir = tempfile::tempdir().unwrap();
    let path = mbtiles(dir.path());
    let (child, address, _lines) = spawn_server(
        &["--archive", path.to_str().unwrap()],
        &[("TERRASTITCH_CACHE__MAX_TILE_MIB", "1")],
    );
    let _child = Running(child);
    // The tile grows past the largest a tile may be, under the server.
    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute("UPDATE tiles SET tile_data = zeroblob(2 * 1024 * 1024)", [])
        .unwrap();
    drop(db);
    for _ in 0..2 {
        let (status, head, body) = request(&address, &tile_path(), &[]);
        let body = String::from_utf8_lossy(&body).to_string();
        assert_eq!(status, 500, "{body}");
        assert!(head.contains("application/json"), "{head}");
        assert!(
            body.contains("tile 14/8529/5973 holds 2097152 bytes, more than the 1048576"),
            "{body}"
        );
    }
    // A tile the file does not hold is still a 404.
    let (status, _, _) = request(&address, "/tiles/14/8530/5973.glb", &[]);
    assert_eq!(status, 404);
}

#[test]
fn a_render_past_its_memory_budget_fails_its_tile_and_the_server_lives() {
    let (child, address, lines) = spawn_server(
        &[],
        &[
            ("TERRASTITCH_SERVER__RENDER_MEMORY_MIB", "1"),
            ("TERRASTITCH_SERVER__CHECK_INTERVAL_S", "0"),
        ],
    );
    let _child = Running(child);
    wait_for("the server to become ready", || {
        (request(&address, "/ready", &[]).0 == 200).then_some(())
    });
    let (status, head, body) = request(&address, "/tiles/14/8529/5973.glb", &[]);
    let body = String::from_utf8_lossy(&body).to_string();
    assert_eq!(status, 503, "{body}");
    assert!(head.contains("application/json"), "{head}");
    assert!(
        body.contains("more memory than its limit of 1 MiB"),
        "{body}"
    );
    // The server lives, and says why in its log.
    assert_eq!(request(&address, "/health", &[]).0, 200);
    let logged = std::iter::from_fn(|| lines.recv_timeout(HUNG).ok())
        .any(|line| line.contains("render stopped at its memory limit"));
    assert!(logged, "the failure is logged");
}

/// The tile requests a server has taken in, from its metrics.
fn tile_requests(address: &str) -> f64 {
    common::process::metric(address, "terrastitch_tile_requests_total")
        .expect("a count of tile requests in the metrics")
}
