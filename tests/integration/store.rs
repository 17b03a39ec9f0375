//! The imported OSM store: `import` makes it whole or not at all, a bad extract leaves the store
//! in use as it was, and the commands that read it import again when the extract changed.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{sample_osm, terrastitch};
use sha2::{Digest, Sha256};

fn import(store: &Path, extracts: &[PathBuf]) -> Output {
    let mut command = terrastitch();
    command.arg("import").arg("--store").arg(store);
    for extract in extracts {
        command.arg("--osm").arg(extract);
    }
    command.output().unwrap()
}

fn digest(path: &Path) -> Vec<u8> {
    Sha256::digest(std::fs::read(path).unwrap()).to_vec()
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// The files in `dir` besides `keep`.
fn others(dir: &Path, keep: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p != keep)
        .collect()
}

#[test]
fn a_truncated_extract_is_named_with_its_position_and_the_store_stays_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("osm.sqlite");
    let good = import(&store, &[sample_osm()]);
    assert!(good.status.success(), "{}", stderr(&good));
    let before = digest(&store);

    let bytes = std::fs::read(sample_osm()).unwrap();
    let truncated = dir.path().join("cut.osm.pbf");
    std::fs::write(&truncated, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let failed = import(&store, &[truncated]);
    assert!(!failed.status.success());
    let message = stderr(&failed);
    assert!(
        message.contains("cut.osm.pbf") && message.contains("at byte"),
        "{message}"
    );
    assert_eq!(digest(&store), before, "the store in use is untouched");
    let node_files = |left: &[PathBuf]| {
        left.iter()
            .filter(|p| p.to_string_lossy().contains("osm.sqlite.nodes-"))
            .count()
    };
    let left: Vec<PathBuf> = others(dir.path(), &store)
        .into_iter()
        .filter(|p| !p.ends_with("cut.osm.pbf") && !p.ends_with("osm.sqlite.lock"))
        .collect();
    assert_eq!(
        node_files(&left),
        1,
        "the store keeps its node file: {left:?}"
    );
    assert_eq!(left.len(), 1, "nothing half-written is left: {left:?}");
}

#[test]
fn an_import_killed_midway_leaves_the_previous_store_in_use() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("osm.sqlite");
    assert!(import(&store, &[sample_osm()]).status.success());
    let before = digest(&store);
    // Eight copies of the sample under other names: an import long enough to stop midway.
    let copies: Vec<PathBuf> = (0..8)
        .map(|k| {
            let copy = dir.path().join(format!("copy{k}.osm.pbf"));
            std::fs::copy(sample_osm(), &copy).unwrap();
            copy
        })
        .collect();
    let mut command = terrastitch();
    command.arg("import").arg("--store").arg(&store);
    for copy in &copies {
        command.arg("--osm").arg(copy);
    }
    let mut child = command.stderr(std::process::Stdio::null()).spawn().unwrap();
    let partial = dir.path().join("osm.sqlite.partial");
    while !partial.exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the import ended before it could be stopped"
        );
        std::thread::yield_now();
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(digest(&store), before, "the store in use is untouched");

    // The store still serves tiles, from the extract it was imported from.
    let out = dir.path().join("tile.glb");
    let render = terrastitch()
        .args(["render", "14/8529/5973", "--store"])
        .arg(&store)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(render.status.success(), "{}", stderr(&render));
    assert_eq!(
        digest(&store),
        before,
        "the store was current: not imported again"
    );

    // A new import starts over, leaving no part of the stopped one.
    assert!(import(&store, &copies[..1]).status.success());
    assert!(!partial.exists());
}

#[test]
fn a_store_older_than_its_extract_is_imported_again() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("osm.sqlite");
    let extract = dir.path().join("region.osm.pbf");
    // The newer extract holds more than the older: the store may be replaced without --force.
    std::fs::copy(
        common::repo().join("tests/data/monaco-planetiler-2021.osm.pbf"),
        &extract,
    )
    .unwrap();
    let render = |name: &str| {
        let out = dir.path().join(name);
        let output = terrastitch()
            .args(["render", "14/8529/5973", "--store"])
            .arg(&store)
            .arg("--osm")
            .arg(&extract)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", stderr(&output));
        std::fs::read(out).unwrap()
    };
    let first = render("first.glb");
    let imported = digest(&store);
    assert_eq!(render("again.glb"), first);
    assert_eq!(digest(&store), imported, "a current store is read as it is");

    std::fs::copy(sample_osm(), &extract).unwrap();
    let changed = render("changed.glb");
    assert_ne!(digest(&store), imported, "the new extract was imported");
    assert_ne!(changed, first, "the tile is made from the new extract");
}

#[test]
fn a_store_imported_by_a_relative_path_is_current_from_any_directory() {
    let dir = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    std::fs::copy(sample_osm(), dir.path().join("region.osm.pbf")).unwrap();
    let output = terrastitch()
        .current_dir(dir.path())
        .args(["import", "--osm", "region.osm.pbf", "--store", "osm.sqlite"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", stderr(&output));
    let store = dir.path().join("osm.sqlite");
    let imported = digest(&store);
    let output = terrastitch()
        .current_dir(elsewhere.path())
        .args(["render", "14/8529/5973", "--store"])
        .arg(&store)
        .arg("--osm")
        .arg(dir.path().join("region.osm.pbf"))
        .arg("--srtm")
        .arg(common::repo().join("data"))
        .arg("-o")
        .arg(elsewhere.path().join("tile.glb"))
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", stderr(&output));
    assert_eq!(
        digest(&store),
        imported,
        "the store holds the very extract named another way: read as it is, not imported again"
    );
}

#[test]
fn two_commands_that_need_a_missing_store_import_it_once() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("osm.sqlite");
    let children: Vec<_> = (0..2)
        .map(|k| {
            terrastitch()
                .args(["render", "14/8529/5973", "--store"])
                .arg(&store)
                .arg("-o")
                .arg(dir.path().join(format!("tile{k}.glb")))
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let mut imports = 0;
    for child in children {
        let output = child.wait_with_output().unwrap();
        let text = stderr(&output);
        assert!(output.status.success(), "{text}");
        imports += text.matches("importing them").count();
    }
    assert_eq!(
        imports, 1,
        "one command imported, the other waited and read it"
    );
    assert_eq!(
        std::fs::read(dir.path().join("tile0.glb")).unwrap(),
        std::fs::read(dir.path().join("tile1.glb")).unwrap()
    );
}

/// What a selection names: its elements by id, its groups by their chains' way ids, and the
/// joints at the nodes of its road network's ways (the ways whose profiles use them) with the
/// ways through them.
fn named(selection: &terrastitch::osm::index::Selection<'_>) -> Vec<String> {
    let all = selection.all_ways;
    let mut names: Vec<String> = Vec::new();
    names.extend(selection.ways.iter().map(|w| format!("way {}", w.id)));
    names.extend(selection.nodes.iter().map(|n| format!("node {}", n.id)));
    names.extend(
        selection
            .relations
            .iter()
            .map(|r| format!("relation {}", r.id)),
    );
    names.extend(
        selection
            .coastlines
            .iter()
            .map(|w| format!("coast {}", w.id)),
    );
    for group in &selection.structures {
        let ways: Vec<i64> = group
            .chains
            .iter()
            .flat_map(|c| c.ways.iter().map(|w| all[w.way as usize].id))
            .collect();
        names.push(format!("group {ways:?} crossing {}", group.crossings.len()));
    }
    if let Some(roads) = selection.roads {
        for way in &selection.ways {
            if !terrastitch::features::roads::joins(&way.tags) {
                continue;
            }
            for node in &way.nodes {
                if let Some(through) = roads.joints.get(node) {
                    let ids: Vec<i64> = through.iter().map(|&i| all[i as usize].id).collect();
                    names.push(format!("joint {node} {ids:?}"));
                }
            }
            if let Some(under) = roads.under_bridges.get(&way.id) {
                names.push(format!("under {} {}", way.id, under.len()));
            }
        }
    }
    names
}

#[test]
fn every_tile_of_the_sample_selects_from_the_store_what_it_selects_from_memory() {
    use terrastitch::provider::osm_source::rules;
    use terrastitch::source::store::{import::import, OsmStore};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("osm.sqlite");
    import(&[sample_osm()], &path, 14, &rules(), false, &|_| {}).unwrap();
    let store = OsmStore::open(&path).unwrap();
    let memory =
        terrastitch::provider::Inputs::open(&[sample_osm()], &common::sample_srtm(), 14).unwrap();
    let whole = common::whole(&memory);
    let margin = terrastitch::provider::inputs::QUERY_MARGIN_DEG;
    let mut tiles = 0;
    for x in 8526..=8533 {
        for y in 5972..=5976 {
            let tile = terrastitch::TileId { z: 14, x, y };
            let from_memory = named(&whole.query(tile, margin));
            let closure = store.tile_index(tile, margin).unwrap();
            let from_store = named(&closure.query(tile, margin));
            assert_eq!(from_store, from_memory, "tile {tile}");
            tiles += usize::from(!from_memory.is_empty());
        }
    }
    assert!(tiles >= 20, "{tiles} tiles hold data");
}

/// What a far view draws but its blocks: each surface's class and element, in order.
fn drawn(set: &terrastitch::features::FeatureSet) -> Vec<String> {
    set.surfaces
        .iter()
        .map(|s| {
            let info = &set.features[s.feature as usize];
            format!("{:?} {:?}", s.class, info.element)
        })
        .collect()
}

#[test]
fn every_far_view_of_the_sample_draws_from_the_store_what_it_draws_from_memory() {
    use terrastitch::features::overview::{collect, Level};
    use terrastitch::provider::osm_source::rules;
    use terrastitch::source::store::{import::import, OsmStore};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("osm.sqlite");
    let imported = import(&[sample_osm()], &path, 14, &rules(), false, &|_| {}).unwrap();
    let store = OsmStore::open(&path).unwrap();
    let memory =
        terrastitch::provider::Inputs::open(&[sample_osm()], &common::sample_srtm(), 14).unwrap();
    let whole = common::whole(&memory);
    let coverage = store.coverage();
    let settings = terrastitch::features::FeatureSettings::default();
    let margin = terrastitch::provider::inputs::QUERY_MARGIN_DEG;
    let (mut views, mut with_blocks) = (0, 0);
    for z in terrastitch::tile::overview_zooms(14) {
        let shift = 14 - z;
        for x in (8526 >> shift)..=(8533 >> shift) {
            for y in (5972 >> shift)..=(5976 >> shift) {
                let tile = terrastitch::TileId { z, x, y };
                let level = Level::new(tile, 14, &coverage);
                let from_memory = collect(&whole.query(tile, margin), level, &settings);
                let far = store.far_tile(tile).unwrap();
                let from_store = collect(&far.selection(), level, &settings);
                assert_eq!(drawn(&from_store), drawn(&from_memory), "tile {tile}");
                // Blocks are merged from the finer level's blocks, not from the buildings: the
                // same at 13 (but for rounding), near the same ground at 12 and 10, never none where
                // there are some.
                let (kept, made) = (from_store.buildings.len(), from_memory.buildings.len());
                assert_eq!(kept == 0, made == 0, "tile {tile}: {kept} blocks, {made}");
                let area = |set: &terrastitch::features::FeatureSet| -> f64 {
                    set.buildings.iter().map(|b| b.footprint.area()).sum()
                };
                let (kept_area, made_area) = (area(&from_store), area(&from_memory));
                let least = if z == 13 { 0.999 } else { 0.65 };
                assert!(
                    kept_area >= least * made_area && kept_area <= 1.05 * made_area,
                    "tile {tile}: blocks cover {kept_area:e}, from the buildings {made_area:e}"
                );
                views += 1;
                with_blocks += usize::from(kept > 0);
            }
        }
    }
    assert!(
        views >= 8 && with_blocks >= 4,
        "{views} views, {with_blocks} with blocks"
    );
    assert!(imported.far_rows >= 8, "{} rows", imported.far_rows);
}

#[test]
fn a_tile_reads_only_the_nearest_coast_and_finds_the_sea_every_coastline_gives() {
    let memory =
        terrastitch::provider::Inputs::open(&[sample_osm()], &common::sample_srtm(), 14).unwrap();
    let whole = common::whole(&memory);
    let every: Vec<&terrastitch::osm::Way> = whole
        .data()
        .ways
        .iter()
        .filter(|w| terrastitch::osm::index::is_coastline(&w.tags))
        .collect();
    let settings = terrastitch::features::FeatureSettings::default();
    let margin = terrastitch::provider::inputs::QUERY_MARGIN_DEG;
    let (mut fewer, mut sea) = (0, 0);
    for x in 8526..=8533 {
        for y in 5972..=5978 {
            let tile = terrastitch::TileId { z: 14, x, y };
            let nearest = whole.query(tile, margin);
            assert!(!nearest.coastlines.is_empty(), "tile {tile}");
            fewer += usize::from(nearest.coastlines.len() < every.len());
            let mut all = whole.query(tile, margin);
            all.coastlines = every.clone();
            let from_nearest = terrastitch::features::collect(&nearest, tile, &settings);
            let from_all = terrastitch::features::collect(&all, tile, &settings);
            assert_eq!(
                format!("{:?}", from_nearest.surfaces),
                format!("{:?}", from_all.surfaces),
                "tile {tile}"
            );
            sea += usize::from(
                from_all
                    .surfaces
                    .iter()
                    .any(|s| s.class == terrastitch::features::FeatureClass::Water),
            );
        }
    }
    assert!(every.len() > 1, "{} coastline ways", every.len());
    assert!(
        fewer >= 40,
        "{fewer} tiles read fewer coastline ways than all"
    );
    assert!(sea >= 10, "{sea} tiles have water");
}

/// The blobs of a PBF file, each with its framing (length, header, data).
fn blobs(pbf: &[u8]) -> Vec<&[u8]> {
    let mut blobs = Vec::new();
    let mut at = 0;
    while at + 4 <= pbf.len() {
        let header_len = u32::from_be_bytes(pbf[at..at + 4].try_into().unwrap()) as usize;
        let header = &pbf[at + 4..at + 4 + header_len];
        // BlobHeader field 3 (datasize), a varint.
        let mut k = 0;
        let mut data_len = 0usize;
        while k < header.len() {
            let key = header[k];
            k += 1;
            let mut varint = || {
                let (mut value, mut shift) = (0usize, 0);
                loop {
                    let byte = header[k];
                    k += 1;
                    value |= ((byte & 0x7f) as usize) << shift;
                    shift += 7;
                    if byte & 0x80 == 0 {
                        return value;
                    }
                }
            };
            match key & 7 {
                0 if key >> 3 == 3 => data_len = varint(),
                0 => {
                    varint();
                }
                2 => {
                    let len = varint();
                    k += len;
                }
                other => panic!("unexpected wire type {other} in a blob header"),
            }
        }
        let end = at + 4 + header_len + data_len;
        blobs.push(&pbf[at..end]);
        at = end;
    }
    assert_eq!(at, pbf.len(), "the blobs cover the file");
    blobs
}

/// What a store holds, table by table, in a fixed order.
fn contents(store: &Path) -> Vec<String> {
    common::table_rows(
        store,
        &[
            &common::STORE_TABLES[..],
            &[
                ("incomplete_ways", "way"),
                ("missing_nodes", "node, way"),
                ("missing_members", "way, relation"),
            ],
        ]
        .concat(),
    )
}

/// The number of rows of `table` among `rows`.
fn count(rows: &[String], table: &str) -> usize {
    rows.iter()
        .filter(|r| r.starts_with(&format!("{table}: ")))
        .count()
}

#[test]
fn an_extract_whose_nodes_do_not_all_come_first_is_read_again_in_two_passes_to_the_same_store() {
    let dir = tempfile::tempdir().unwrap();
    let sorted = dir.path().join("sorted.sqlite");
    let output = import(&sorted, &[sample_osm()]);
    assert!(output.status.success(), "{}", stderr(&output));
    // The first block of nodes moved to the end, after the ways and relations.
    let pbf = std::fs::read(sample_osm()).unwrap();
    let mut moved = blobs(&pbf);
    assert!(
        moved.len() > 3,
        "the sample has blocks of nodes, ways and relations"
    );
    let first_nodes = moved.remove(1);
    moved.push(first_nodes);
    let unsorted_pbf = dir.path().join("unsorted.osm.pbf");
    std::fs::write(&unsorted_pbf, moved.concat()).unwrap();
    let unsorted = dir.path().join("unsorted.sqlite");
    let output = import(&unsorted, &[unsorted_pbf]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("not sorted by type then id"),
        "the second reading is said: {}",
        stderr(&output)
    );
    let (a, b) = (contents(&sorted), contents(&unsorted));
    for table in ["ways", "cells", "groups", "joints"] {
        assert!(count(&a, table) > 0, "the sample fills {table}");
    }
    assert_eq!(a.len(), b.len());
    assert!(a == b, "the stores differ");
}

#[test]
fn two_extracts_holding_the_same_elements_make_the_store_one_of_them_makes() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one.sqlite");
    let output = import(&one, &[sample_osm()]);
    assert!(output.status.success(), "{}", stderr(&output));
    // Read in two passes: every element given twice, the first kept.
    let copy = dir.path().join("copy.osm.pbf");
    std::fs::copy(sample_osm(), &copy).unwrap();
    let two = dir.path().join("two.sqlite");
    let output = import(&two, &[sample_osm(), copy]);
    assert!(output.status.success(), "{}", stderr(&output));
    let (a, b) = (contents(&one), contents(&two));
    assert!(count(&a, "ways") > 0);
    assert_eq!(a.len(), b.len());
    assert!(a == b, "the stores differ");
}

/// Elements of each kind in one blob of a PBF file: nodes, ways, relations.
fn kinds(blob: &[u8]) -> [u64; 3] {
    let mut found = [0; 3];
    for blob in osmpbf::BlobReader::new(blob) {
        if let osmpbf::BlobDecode::OsmData(block) = blob.unwrap().decode().unwrap() {
            for element in block.elements() {
                let kind = match element {
                    osmpbf::Element::Node(_) | osmpbf::Element::DenseNode(_) => 0,
                    osmpbf::Element::Way(_) => 1,
                    osmpbf::Element::Relation(_) => 2,
                };
                found[kind] += 1;
            }
        }
    }
    found
}

/// The sample's bytes up to the first blob holding elements of `kind` (0 nodes, 1 ways, 2
/// relations): cut cleanly at a block boundary.
fn cut_before(kind: usize, dir: &Path) -> PathBuf {
    let bytes = std::fs::read(sample_osm()).unwrap();
    let mut length = 0;
    for blob in blobs(&bytes) {
        if kinds(blob)[kind] > 0 {
            break;
        }
        length += blob.len();
    }
    assert!(length < bytes.len());
    let cut = dir.join(format!("cut-{kind}.osm.pbf"));
    std::fs::write(&cut, &bytes[..length]).unwrap();
    cut
}

#[test]
fn an_extract_cut_at_a_block_boundary_does_not_replace_a_whole_store() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("osm.sqlite");
    let good = import(&store, &[sample_osm()]);
    assert!(good.status.success(), "{}", stderr(&good));
    let before = digest(&store);
    // The header alone, the nodes alone, all but the relations.
    for (kind, said) in [
        (
            0,
            "holds no OSM elements (0 blocks of data after its header)",
        ),
        (1, "it ends in its nodes"),
        (2, "and 0 relations: an extract cut short would do that"),
    ] {
        let cut = cut_before(kind, dir.path());
        let refused = import(&store, std::slice::from_ref(&cut));
        let message = stderr(&refused);
        assert!(!refused.status.success(), "{message}");
        assert!(message.contains(said), "{kind}: {message}");
        assert_eq!(digest(&store), before, "the store is unchanged");
        assert_eq!(
            others(dir.path(), &store)
                .iter()
                .filter(|p| { p.to_string_lossy().contains(".partial") })
                .count(),
            0
        );
    }
    let losing = import(&store, &[cut_before(2, dir.path())]);
    let message = stderr(&losing);
    assert!(
        message.contains("replace the 3090 tagged nodes, 27357 ways and 57 relations"),
        "{message}"
    );
    assert!(message.contains("--force"), "{message}");
    // Forced, the store is replaced, and the summary says what was read.
    let mut command = terrastitch();
    command
        .arg("import")
        .arg("--force")
        .arg("--store")
        .arg(&store);
    let forced = command
        .arg("--osm")
        .arg(cut_before(2, dir.path()))
        .output()
        .unwrap();
    let message = stderr(&forced);
    assert!(forced.status.success(), "{message}");
    assert!(
        message.contains("0 relations, sorted by type then id"),
        "{message}"
    );
    assert_ne!(digest(&store), before);
}

#[test]
fn a_node_outside_the_world_is_refused_by_both_readers() {
    let dir = tempfile::tempdir().unwrap();
    for (lon, lat) in [(7.42, 91.0), (200.0, 43.73)] {
        let extract = dir.path().join("outside.osm.pbf");
        let ways = serde_json::json!([
            {"tags": {"highway": "residential"}, "nodes": [[7.42, 43.73], [lon, lat], [7.43, 43.74]]}
        ]);
        common::write_extract(&ways, &extract);
        let store = dir.path().join("osm.sqlite");
        let refused = import(&store, std::slice::from_ref(&extract));
        let message = stderr(&refused);
        assert!(!refused.status.success(), "{message}");
        assert!(
            message.contains("node 2 lies at") && message.contains("outside the world"),
            "{message}"
        );
        assert!(!store.exists());
        let rendered = terrastitch()
            .args(["render", "14/8529/5973", "--osm"])
            .arg(&extract)
            .arg("-o")
            .arg(dir.path().join("tile.glb"))
            .output()
            .unwrap();
        let message = stderr(&rendered);
        assert!(!rendered.status.success(), "{message}");
        assert!(message.contains("outside the world"), "{message}");
    }
}
