//! The `terrastitch` binary: corrupt data files stop it with a named error, and `render`
//! writes a tile.

use crate::common;

use common::terrastitch;

/// Runs `serve` with extra arguments and returns its stderr, asserting that it failed.
fn serve_fails(dir: &std::path::Path, args: &[&std::ffi::OsStr]) -> String {
    let output = terrastitch()
        .args(["serve", "--listen", "127.0.0.1:0", "--cache"])
        .arg(dir.join("cache.sqlite"))
        .args(args)
        .output()
        .unwrap();
    assert!(!output.status.success());
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn a_truncated_hgt_file_is_named_and_fatal() {
    let dir = tempfile::tempdir().unwrap();
    let original = std::fs::read(common::sample_srtm().join("N43E007.hgt")).unwrap();
    std::fs::write(
        dir.path().join("N43E007.hgt"),
        &original[..original.len() / 2],
    )
    .unwrap();
    let stderr = serve_fails(dir.path(), &["--srtm".as_ref(), dir.path().as_os_str()]);
    assert!(
        stderr.contains("N43E007.hgt") && stderr.contains("1442401"),
        "{stderr}"
    );
}

#[test]
fn a_truncated_pbf_file_is_named_and_fatal() {
    let dir = tempfile::tempdir().unwrap();
    let original = std::fs::read(common::sample_osm()).unwrap();
    let truncated = dir.path().join("truncated.osm.pbf");
    std::fs::write(&truncated, &original[..original.len() * 2 / 3]).unwrap();
    let stderr = serve_fails(dir.path(), &["--osm".as_ref(), truncated.as_os_str()]);
    assert!(stderr.contains("truncated.osm.pbf"), "{stderr}");
}

#[test]
fn render_writes_a_glb_and_reports_stage_times() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tile.glb");
    let output = terrastitch()
        .args(["render", "14/8529/5973", "--timings", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    for stage in ["load"]
        .into_iter()
        .chain(terrastitch::render::StageTimings::NAMES)
        .chain(["total"])
    {
        assert!(stderr.contains(stage), "no '{stage}' in:\n{stderr}");
    }
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
}

#[test]
fn help_shows_the_defaults() {
    let output = terrastitch().args(["serve", "--help"]).output().unwrap();
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(
        text.contains("127.0.0.1:8080") && text.contains("monaco-osrm-2016.osm.pbf"),
        "{text}"
    );
    let output = terrastitch().args(["render", "--help"]).output().unwrap();
    assert!(String::from_utf8_lossy(&output.stdout).contains("--timings"));
}
