use super::*;

fn entry(tile_id: u64, offset: u64, length: u32, run_length: u32) -> Entry {
    Entry {
        tile_id,
        offset,
        length,
        run_length,
    }
}

#[test]
fn a_directory_decodes_its_delta_coded_columns() {
    // Three entries: ids 5, 6 and 10; runs 1, 2, 1; lengths 100, 50, 7; offsets 0, then
    // "just after", then 500.
    let bytes = [3, 5, 1, 4, 1, 2, 1, 100, 50, 7, 1, 0, 245, 3];
    let entries = parse_directory(&bytes).unwrap();
    assert_eq!(
        entries,
        vec![
            entry(5, 0, 100, 1),
            entry(6, 100, 50, 2),
            entry(10, 500, 7, 1)
        ]
    );
    assert_eq!(find_entry(&entries, 7), Some(entries[1]));
    assert_eq!(find_entry(&entries, 8), None);
    assert_eq!(find_entry(&entries, 4), None);
    assert!(parse_directory(&bytes[..9]).is_err());
    assert!(parse_directory(&[200, 1]).is_err());
}

#[test]
fn a_leaf_entry_holds_every_id_after_it() {
    let entries = vec![entry(0, 0, 10, 1), entry(100, 0, 60, 0)];
    assert_eq!(find_entry(&entries, 5000), Some(entries[1]));
}

#[test]
fn tile_numbers_follow_the_hilbert_curve_and_come_back() {
    let root = TileId { z: 0, x: 0, y: 0 };
    assert_eq!(hilbert_id(root), Some(0));
    assert_eq!(hilbert_id(TileId { z: 1, x: 0, y: 0 }), Some(1));
    let tile = TileId::new(14, 8528, 5974).unwrap();
    assert_eq!(hilbert_id(tile).and_then(tile_of), Some(tile));
}

#[test]
fn an_archive_with_leaf_directories_reads_back_every_tile() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.pmtiles");
    let file = std::fs::File::create(&path).unwrap();
    let mut writer = pmtiles::PmTilesWriter::new(pmtiles::TileType::Unknown)
        .metadata(r#"{"format": "glb"}"#)
        .create(std::io::BufWriter::new(file))
        .unwrap();
    let side = 250u32;
    let tiles: Vec<TileId> = (0..side)
        .flat_map(|y| {
            (0..side).map(move |x| TileId {
                z: 14,
                x: 8000 + x,
                y: 5000 + y,
            })
        })
        .collect();
    let mut ordered: Vec<(u64, TileId)> =
        tiles.iter().map(|&t| (hilbert_id(t).unwrap(), t)).collect();
    ordered.sort();
    let body = |t: TileId| format!("tile {}/{}", t.x, t.y).into_bytes();
    for &(_, t) in &ordered {
        let coord = pmtiles::TileCoord::new(t.z, t.x, t.y).unwrap();
        writer.add_tile(coord, &body(t)).unwrap();
    }
    writer.finalize().unwrap();

    let store = PmtilesStore::open(&path, 1 << 20).unwrap();
    assert!(store.header.leaves.1 > 0, "the writer split the directory");
    for &t in tiles.iter().step_by(97) {
        let key = TileKey {
            tile: t,
            format: crate::format::Format::GLB,
        };
        let tile = store.get(&key).unwrap().unwrap();
        assert_eq!(tile.bodies.identity.to_vec(), body(t), "{t}");
    }
    let beside = TileId {
        z: 14,
        x: 7999,
        y: 5000,
    };
    let key = TileKey {
        tile: beside,
        format: crate::format::Format::GLB,
    };
    assert!(store.get(&key).unwrap().is_none());
    assert_eq!(store.usage().unwrap().tiles, tiles.len() as u64);
    assert_eq!(store.list(&TileFilter::All).unwrap().len(), tiles.len());
}

#[test]
fn a_truncated_file_is_a_named_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.pmtiles");
    let mut header = vec![0u8; HEADER_LEN];
    header[..7].copy_from_slice(b"PMTiles");
    header[7] = 3;
    header[8] = 127; // the root directory just after the header…
    header[16] = 40; // …40 bytes long, past the end.
    header[97] = 1;
    header[98] = 1;
    std::fs::write(&path, &header).unwrap();
    let error = PmtilesStore::open(&path, 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("cut.pmtiles") && error.contains("points at bytes 127 to 167 of its 127"),
        "{error}"
    );
    // A length no file holds is refused before anything is read.
    header[23] = 0x40;
    std::fs::write(&path, &header).unwrap();
    let error = PmtilesStore::open(&path, 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("points at bytes"), "{error}");
    header[7] = 2;
    std::fs::write(&path, &header).unwrap();
    let error = PmtilesStore::open(&path, 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("version 2"), "{error}");
}

/// A PMTiles file made by hand, as a hostile writer would: the header's sections as given,
/// the root directory, metadata and tile data placed one after the other after it.
struct Handmade {
    root: Vec<u8>,
    metadata: Vec<u8>,
    data: Vec<u8>,
    gzip: bool,
    max_zoom: u8,
    /// Replaces the tile data's offset in the header.
    data_offset: Option<u64>,
}

impl Handmade {
    /// One tile, 14/8529/5973, of `data`, and metadata naming glb.
    fn one_tile(data: &[u8]) -> Handmade {
        let id = hilbert_id(TileId::new(14, 8529, 5973).unwrap()).unwrap();
        Handmade {
            root: directory(&[entry(id, 0, data.len() as u32, 1)]),
            metadata: br#"{"format": "glb"}"#.to_vec(),
            data: data.to_vec(),
            gzip: false,
            max_zoom: 14,
            data_offset: None,
        }
    }

    fn write(&self, dir: &Path) -> PathBuf {
        let compress = |bytes: &[u8]| match self.gzip {
            true => gzip(bytes),
            false => bytes.to_vec(),
        };
        let (root, metadata) = (compress(&self.root), compress(&self.metadata));
        let mut header = vec![0u8; HEADER_LEN];
        header[..7].copy_from_slice(b"PMTiles");
        header[7] = 3;
        let mut at = HEADER_LEN as u64;
        let mut section = |field: usize, length: usize| {
            header[field..field + 8].copy_from_slice(&at.to_le_bytes());
            header[field + 8..field + 16].copy_from_slice(&(length as u64).to_le_bytes());
            at += length as u64;
        };
        section(8, root.len());
        section(24, metadata.len());
        section(40, 0);
        section(56, self.data.len());
        if let Some(offset) = self.data_offset {
            header[56..64].copy_from_slice(&offset.to_le_bytes());
        }
        let compression = if self.gzip { 2 } else { 1 };
        header[97] = compression;
        header[98] = compression;
        header[101] = self.max_zoom;
        let path = dir.join("handmade.pmtiles");
        let file = [header, root, metadata, self.data.clone()].concat();
        std::fs::write(&path, file).unwrap();
        path
    }
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn push_varint(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// Entries as a directory codes them (every offset written out, none "just after").
fn directory(entries: &[Entry]) -> Vec<u8> {
    let mut out = Vec::new();
    push_varint(&mut out, entries.len() as u64);
    let mut last = 0;
    for e in entries {
        push_varint(&mut out, e.tile_id - last);
        last = e.tile_id;
    }
    for e in entries {
        push_varint(&mut out, u64::from(e.run_length));
    }
    for e in entries {
        push_varint(&mut out, u64::from(e.length));
    }
    for e in entries {
        push_varint(&mut out, e.offset.wrapping_add(1));
    }
    out
}

fn glb_key() -> TileKey {
    TileKey {
        tile: TileId::new(14, 8529, 5973).unwrap(),
        format: crate::format::Format::GLB,
    }
}

#[test]
fn a_handmade_archive_serves_its_tile() {
    let dir = tempfile::tempdir().unwrap();
    let path = Handmade::one_tile(b"the tile").write(dir.path());
    let store = PmtilesStore::open(&path, 1 << 20).unwrap();
    let tile = store.get(&glb_key()).unwrap().unwrap();
    assert_eq!(tile.bodies.identity.to_vec(), b"the tile");
}

#[test]
fn a_data_offset_that_wraps_around_is_refused_not_followed() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = Handmade::one_tile(b"the tile");
    file.data_offset = Some(u64::MAX - 99);
    let error = PmtilesStore::open(&file.write(dir.path()), 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("its tile data points at bytes"), "{error}");
}

#[test]
fn an_entry_offset_that_wraps_around_is_refused_not_followed() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = Handmade::one_tile(b"the tile");
    let id = hilbert_id(glb_key().tile).unwrap();
    // Offset 2^64 - 6 with the tile's 8 bytes wraps to byte 2 of the data.
    file.root = directory(&[entry(id, u64::MAX - 5, 8, 1)]);
    let error = PmtilesStore::open(&file.write(dir.path()), 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("an entry points at bytes"), "{error}");
    // Coded "just after" an entry that ends past 2^64: refused as it is read.
    let mut coded = Vec::new();
    for value in [2, id, 1, 1, 1, 8, 8, u64::MAX - 4, 0] {
        push_varint(&mut coded, value);
    }
    assert!(parse_directory(&coded).is_err());
}

#[test]
fn a_run_past_the_finest_zoom_is_refused_not_listed() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = Handmade::one_tile(b"the tile");
    let id = hilbert_id(glb_key().tile).unwrap();
    file.root = directory(&[entry(id, 0, 8, u32::MAX)]);
    let error = PmtilesStore::open(&file.write(dir.path()), 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("passes zoom 14"), "{error}");
}

#[test]
fn a_long_run_is_walked_over_a_range_without_listing_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = Handmade::one_tile(b"the sea");
    // Every tile of zoom 14 after the first: a run of 268 million.
    let first = ids_to_zoom(13) + 1;
    let run = (ids_to_zoom(14) - first) as u32;
    file.root = directory(&[entry(first, 0, 7, run)]);
    let store = PmtilesStore::open(&file.write(dir.path()), 1 << 20).unwrap();
    assert_eq!(store.usage().unwrap().tiles, u64::from(run));
    let range = crate::tile::TileRange {
        z: 14,
        min_x: 8528,
        max_x: 8530,
        min_y: 5973,
        max_y: 5974,
    };
    let mut seen = 0;
    store
        .each(&TileFilter::Range(range), &mut |_| seen += 1)
        .unwrap();
    assert_eq!(seen, 6);
    let named = TileFilter::tiles(vec![glb_key().tile]);
    assert_eq!(store.list(&named).unwrap().len(), 1);
}

#[test]
fn directories_and_metadata_that_inflate_past_their_bound_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = Handmade::one_tile(b"the tile");
    file.gzip = true;
    // A directory padded past its bound with zeros (each a varint the parser never reads).
    file.root.resize(MAX_DIRECTORY_BYTES as usize + 1, 0);
    let error = PmtilesStore::open(&file.write(dir.path()), 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("a directory: it inflates to more than 16777216 bytes"),
        "{error}"
    );
    let mut file = Handmade::one_tile(b"the tile");
    file.gzip = true;
    file.metadata.resize(MAX_METADATA_BYTES as usize + 1, b' ');
    let error = PmtilesStore::open(&file.write(dir.path()), 1 << 20)
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("its metadata: it inflates to more than"),
        "{error}"
    );
}

#[test]
fn a_tile_that_inflates_past_the_largest_tile_is_damaged() {
    let dir = tempfile::tempdir().unwrap();
    let bomb = gzip(&vec![0u8; 2 << 20]);
    let mut file = Handmade::one_tile(&bomb);
    file.gzip = true;
    let store = PmtilesStore::open(&file.write(dir.path()), 1 << 20).unwrap();
    let error = store.get(&glb_key()).err().unwrap().to_string();
    assert!(
        error.contains("tile 14/8529/5973: it inflates to more than 1048576 bytes"),
        "{error}"
    );
    // Uncompressed, a tile longer than the largest is refused before it is read.
    let file = Handmade::one_tile(&vec![1u8; 2000]);
    let store = PmtilesStore::open(&file.write(dir.path()), 1000).unwrap();
    assert!(store.get(&glb_key()).is_err());
}
