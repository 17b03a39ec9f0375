//! Getting data: OSM extracts and SRTM files, local or downloaded ([`fetch`]), opened and
//! checked once at start, and the per-tile view of them that rendering needs.

use std::path::PathBuf;
use std::sync::Arc;

use crate::source::fetch::{self, Download, FetchError, Fetcher};
use crate::source::{osm_pbf, srtm};

use super::osm_source::{OsmSource, StoreOpenError, TileOsm};
use crate::osm::{OsmData, OsmIndex};
use crate::source::store::{import, StoreError};
use crate::terrain::cell::CellId;
use crate::terrain::Mosaic;
use crate::tile::TileId;
use srtm::{SrtmDirectory, SrtmError};

pub use super::osm_source::QUERY_MARGIN_DEG;

/// How far around a tile SRTM files are opened, in degrees (about 110 m): the terrain methods
/// reach a few samples beyond the tile.
const MOSAIC_MARGIN_DEG: f64 = 0.001;

#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error(transparent)]
    Osm(#[from] osm_pbf::OsmReadError),
    #[error(transparent)]
    Srtm(#[from] SrtmError),
    #[error(transparent)]
    Fetch(#[from] FetchError),
    #[error("OSM source {0} is a URL whose last path segment is not a file name")]
    UrlWithoutName(String),
    #[error("two OSM source URLs end in the same file name {0}; downloads are kept by that name")]
    SameFileName(String),
    #[error(transparent)]
    Store(#[from] StoreOpenError),
}

/// Why the SRTM files a tile lacks could not be had.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MissingSrtm {
    /// The configured source has no such file (the sea, or outside its coverage).
    #[error("no SRTM data for tile {tile}: {reason}")]
    NotFound { tile: TileId, reason: String },
    /// The download failed, or the file it brought is unusable.
    #[error("SRTM data for tile {tile} could not be had: {reason}")]
    Failed { tile: TileId, reason: String },
}

/// Why a tile cannot be rendered from the data the server has.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Uncovered {
    #[error("no data for tile {tile}: no OSM extract covers it and there is no SRTM file {}", .missing.join(", "))]
    Nothing { tile: TileId, missing: Vec<String> },
    #[error("no SRTM data for tile {tile}: missing {} in {directory}", .missing.join(", "))]
    MissingSrtm {
        tile: TileId,
        missing: Vec<String>,
        directory: String,
    },
}

/// Indexes OSM data at `zoom` with the feature rules the index needs over the whole extract:
/// which ways are bridges and tunnels, which join the road network, what reaches down into the
/// ground over a tunnel, which relations make features.
pub fn index_osm(mut data: OsmData, zoom: u8) -> OsmIndex {
    // The relations tiles are not made from are dropped, as the store does.
    crate::features::keep_relations_read(&mut data.relations);
    OsmIndex::new(data, zoom, crate::features::structures::classify)
        .with_joints(crate::features::roads::joins)
        .with_foundations(crate::features::structures::foundation_depth_m)
}

/// The extracts a configuration names as local files (those given by URL downloaded into
/// the data directory when it lacks them), with the URLs among them.
pub fn local_extracts(
    config: &crate::config::SourcesConfig,
    fetcher: &Fetcher,
) -> Result<(Vec<PathBuf>, Vec<String>), SourceError> {
    let mut osm_paths = Vec::new();
    let mut osm_urls = Vec::new();
    let mut osm_names = std::collections::HashMap::new();
    for entry in &config.osm {
        let text = entry.to_string_lossy();
        if fetch::is_url(&text) {
            let name = fetch::file_name_of(&text)
                .ok_or_else(|| SourceError::UrlWithoutName(text.to_string()))?;
            if osm_names.insert(name.clone(), text.to_string()).is_some() {
                return Err(SourceError::SameFileName(name));
            }
            let path = fetcher.fetch(&Download {
                url: &text,
                name: &name,
                source_name: "OSM",
                max_bytes: None,
            })?;
            osm_urls.push(text.to_string());
            osm_paths.push(path);
        } else {
            osm_paths.push(entry.clone());
        }
    }
    Ok((osm_paths, osm_urls))
}

/// The opened data sources.
#[derive(Debug)]
pub struct Inputs {
    pub osm: OsmSource,
    pub srtm: SrtmDirectory,
    pub osm_paths: Vec<PathBuf>,
    /// Each extract's version: a digest of its bytes.
    pub osm_versions: Vec<String>,
    /// Each extract's size and modification time when it was read.
    osm_files: Vec<String>,
    /// The URLs of the extracts that came from one.
    osm_urls: Vec<String>,
    /// Directories of SRTM files besides the main one (downloads).
    srtm_extra: Vec<PathBuf>,
    /// The URL template of missing SRTM files, with the fetcher that brings them.
    srtm_url: Option<String>,
    fetcher: Option<Arc<Fetcher>>,
}

impl Inputs {
    /// Why no tile can be made from these inputs, if none can: no SRTM file at hand and no
    /// URL to fetch one from.
    pub fn cannot_serve(&self) -> Option<String> {
        let files = self.srtm.cells().len();
        (files == 0 && self.srtm_url.is_none()).then(|| {
            "no SRTM file in the SRTM directory and no sources.srtm_url to fetch one: no tile can be made".to_string()
        })
    }

    /// Opens the sources a configuration names, downloading the extracts given by URL that
    /// the data directory does not have yet.
    pub fn load(
        config: &crate::config::SourcesConfig,
        zoom: u8,
        fetcher: Arc<Fetcher>,
    ) -> Result<Inputs, SourceError> {
        let (osm_paths, osm_urls) = local_extracts(config, &fetcher)?;
        let srtm_extra = vec![config.downloads.clone()];
        let mut sources = match &config.store {
            Some(store) => Inputs::open_store(&osm_paths, store, &config.srtm, &srtm_extra, zoom)?,
            None => Inputs::open_with(&osm_paths, &config.srtm, &srtm_extra, zoom)?,
        };
        sources.osm_urls = osm_urls;
        sources.srtm_url = (!config.srtm_url.is_empty()).then(|| config.srtm_url.clone());
        sources.fetcher = Some(fetcher);
        Ok(sources)
    }

    /// Reads the extracts, indexes them at `zoom`, and checks the SRTM directory.
    pub fn open(
        osm_paths: &[PathBuf],
        srtm_dir: &std::path::Path,
        zoom: u8,
    ) -> Result<Inputs, SourceError> {
        Inputs::open_with(osm_paths, srtm_dir, &[], zoom)
    }

    fn open_with(
        osm_paths: &[PathBuf],
        srtm_dir: &std::path::Path,
        srtm_extra: &[PathBuf],
        zoom: u8,
    ) -> Result<Inputs, SourceError> {
        let data = osm_pbf::read_extracts(osm_paths)?;
        let osm_versions = osm_paths
            .iter()
            .map(|path| osm_pbf::content_digest(path))
            .collect::<Result<Vec<_>, _>>()?;
        let osm_files = osm_paths
            .iter()
            .map(|path| srtm::file_version(path).unwrap_or_default())
            .collect();
        let srtm = SrtmDirectory::open_all(srtm_dir, srtm_extra)?;
        Ok(Inputs {
            osm: OsmSource::Memory(Box::new(index_osm(data, zoom))),
            srtm,
            osm_paths: osm_paths.to_vec(),
            osm_versions,
            osm_files,
            osm_urls: Vec::new(),
            srtm_extra: srtm_extra.to_vec(),
            srtm_url: None,
            fetcher: None,
        })
    }

    /// Opens the store of the extracts at `store` (importing them first when it is missing or
    /// older than they are) and checks the SRTM directory.
    pub fn open_store(
        osm_paths: &[PathBuf],
        store: &std::path::Path,
        srtm_dir: &std::path::Path,
        srtm_extra: &[PathBuf],
        zoom: u8,
    ) -> Result<Inputs, SourceError> {
        let logged = std::sync::Mutex::new(None::<import::Phase>);
        let progress = |p: &import::Progress| {
            let mut last = logged.lock().unwrap_or_else(|e| e.into_inner());
            if *last != Some(p.phase) {
                tracing::info!(phase = p.phase.as_str(), "importing the OSM extracts");
                *last = Some(p.phase);
            }
        };
        let (store, _) = super::osm_source::open_store(store, osm_paths, zoom, &progress)?;
        let srtm = SrtmDirectory::open_all(srtm_dir, srtm_extra)?;
        Ok(Inputs {
            osm_versions: store.extracts().iter().map(|e| e.digest.clone()).collect(),
            osm_files: store
                .extracts()
                .iter()
                .map(|e| e.file_version.clone())
                .collect(),
            osm_paths: osm_paths.to_vec(),
            osm: OsmSource::Store(store),
            srtm,
            osm_urls: Vec::new(),
            srtm_extra: srtm_extra.to_vec(),
            srtm_url: None,
            fetcher: None,
        })
    }

    /// Whether SRTM files a tile lacks can be downloaded.
    pub fn can_fetch_srtm(&self) -> bool {
        self.srtm_url.is_some() && self.fetcher.is_some()
    }

    /// Downloads the SRTM files the tile's mosaic reads that the directories lack. A file for
    /// the tile's own cells that cannot be had is an error; one only its margin reaches is
    /// left out (the terrain there comes from the files there are).
    pub fn fetch_missing_srtm(&self, tile: TileId) -> Result<(), MissingSrtm> {
        let own = Self::cells_for(tile);
        for cell in Self::mosaic_cells(tile) {
            match self.fetch_cell(tile, cell) {
                Ok(()) => {}
                Err(error) if own.contains(&cell) => return Err(error),
                Err(error) => {
                    tracing::info!(%tile, %error, "an SRTM file only the tile's margin reaches is not available");
                }
            }
        }
        Ok(())
    }

    /// Downloads the SRTM file of `cell` (for `tile`) when the directories lack it and files
    /// can be fetched.
    fn fetch_cell(&self, tile: TileId, cell: CellId) -> Result<(), MissingSrtm> {
        let (Some(template), Some(fetcher)) = (&self.srtm_url, &self.fetcher) else {
            return Ok(());
        };
        if self.srtm.has(cell) {
            return Ok(());
        }
        let (url, name) = fetch::srtm_download(template, &cell.name());
        fetcher
            .fetch(&Download {
                url: &url,
                name: &name,
                source_name: "SRTM",
                max_bytes: Some(crate::source::srtm::LARGEST_FILE_BYTES),
            })
            .map_err(|e| {
                if e.is_not_found() {
                    MissingSrtm::NotFound {
                        tile,
                        reason: e.to_string(),
                    }
                } else {
                    MissingSrtm::Failed {
                        tile,
                        reason: e.to_string(),
                    }
                }
            })
            .and_then(|path| {
                self.srtm.insert(cell, &path).map_err(|e| {
                    // An unusable file is not kept, and not asked for again before the
                    // failure memory runs out.
                    let _ = std::fs::remove_file(&path);
                    fetcher.remember_failure(
                        &name,
                        FetchError::Io {
                            path: path.clone(),
                            message: e.to_string(),
                        },
                    );
                    MissingSrtm::Failed {
                        tile,
                        reason: e.to_string(),
                    }
                })
            })
    }

    /// The source files that changed on disk since they were read: an extract rewritten or
    /// replaced, an SRTM file added, removed or rewritten.
    pub fn changed_files(&self) -> Vec<String> {
        let mut changed = Vec::new();
        if let Some(fetcher) = &self.fetcher {
            for url in &self.osm_urls {
                let Some(name) = fetch::file_name_of(url) else {
                    continue;
                };
                let download = Download {
                    url,
                    name: &name,
                    source_name: "OSM",
                    max_bytes: None,
                };
                // A new version replaces the file; the check below sees that it changed.
                match fetcher.refresh(&download) {
                    Ok(true) => tracing::info!(url, "a new version of an extract was downloaded"),
                    Ok(false) => {}
                    Err(error) => {
                        tracing::warn!(%error, "checking an extract for a new version failed")
                    }
                }
            }
        }
        for (path, version) in self.osm_paths.iter().zip(&self.osm_files) {
            if srtm::file_version(path).ok().as_ref() != Some(version) {
                changed.push(path.display().to_string());
            }
        }
        if let OsmSource::Store(store) = &self.osm {
            match store.current_generation() {
                Ok(now) if now != store.generation() => {
                    changed.push(format!("{} (diff {now} applied)", store.path().display()))
                }
                Ok(_) => {}
                Err(error) => tracing::warn!(%error, "checking the OSM store for diffs failed"),
            }
        }
        match SrtmDirectory::open_all(self.srtm.root(), &self.srtm_extra) {
            Ok(now) => {
                let cells: std::collections::BTreeSet<CellId> =
                    now.cells().into_iter().chain(self.srtm.cells()).collect();
                for cell in cells {
                    if now.version(cell) != self.srtm.version(cell) {
                        changed.push(format!("{}.hgt", cell.name()));
                    }
                }
            }
            Err(error) => changed.push(error.to_string()),
        }
        changed
    }

    /// The version of the sources a tile is made from: a digest of the versions of the
    /// extracts that reach it and of the SRTM files around it (those its mosaic reads). A tile stored with another
    /// version is stale.
    pub fn version_for(&self, tile: TileId) -> String {
        use sha2::Digest;
        let mut digest = sha2::Sha256::new();
        // Only the extracts that reach the tile's query area count.
        let area = tile.bounds().expanded(QUERY_MARGIN_DEG);
        let coverage = self.osm.coverage();
        for (i, version) in self.osm_versions.iter().enumerate() {
            if coverage.get(i).is_none_or(|c| c.intersects(&area)) {
                digest.update(version.as_bytes());
                digest.update(b";");
            }
        }
        // The last diff that changed what the tile reads.
        if let OsmSource::Store(store) = &self.osm {
            match store.tile_generation(tile) {
                Ok(0) => {}
                Ok(generation) => digest.update(format!("diff {generation};").as_bytes()),
                Err(error) => tracing::warn!(%tile, %error, "no diff generation for the tile"),
            }
        }
        // The files there are in the mosaic's cells (a coarse tile spans many cells, few with a
        // file: the directory is walked, not the cells).
        let b = tile.bounds().expanded(MOSAIC_MARGIN_DEG);
        let lats = b.south.floor() as i32..=b.north.floor() as i32;
        let lons = b.west.floor() as i32..=b.east.floor() as i32;
        for (cell, version) in self.srtm.versions_in(lats, lons) {
            digest.update(cell.name().as_bytes());
            digest.update(version.as_bytes());
            digest.update(b";");
        }
        digest.finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// The cells whose files the mosaic of a tile reads.
    fn mosaic_cells(tile: TileId) -> impl Iterator<Item = CellId> {
        let b = tile.bounds().expanded(MOSAIC_MARGIN_DEG);
        let (lon0, lon1) = (b.west.floor() as i32, b.east.floor() as i32);
        (b.south.floor() as i32..=b.north.floor() as i32)
            .flat_map(move |lat| (lon0..=lon1).map(move |lon| CellId { lat, lon }))
    }

    /// The SRTM cells a tile needs.
    fn cells_for(tile: TileId) -> Vec<CellId> {
        let b = tile.bounds();
        let mut cells = Vec::new();
        let (lat0, lat1) = (
            b.south.floor() as i32,
            (b.north.ceil() as i32 - 1).max(b.south.floor() as i32),
        );
        let (lon0, lon1) = (
            b.west.floor() as i32,
            (b.east.ceil() as i32 - 1).max(b.west.floor() as i32),
        );
        for lat in lat0..=lat1 {
            for lon in lon0..=lon1 {
                cells.push(CellId { lat, lon });
            }
        }
        cells
    }

    /// Checks that the tile can be rendered: SRTM must cover all of it.
    pub fn check_coverage(&self, tile: TileId) -> Result<(), Uncovered> {
        let missing: Vec<String> = Self::cells_for(tile)
            .into_iter()
            .filter(|c| !self.srtm.has(*c))
            .map(|c| format!("{}.hgt", c.name()))
            .collect();
        if missing.is_empty() {
            return Ok(());
        }
        if !self.osm.covers(&tile.bounds()) {
            return Err(Uncovered::Nothing { tile, missing });
        }
        Err(Uncovered::MissingSrtm {
            tile,
            missing,
            directory: self.srtm.root().display().to_string(),
        })
    }

    /// Lowest and highest SRTM ground under a tile, metres: read from the samples inside it
    /// (at most `budget` of them) when `sampled`, else the range of the whole files it
    /// overlaps, which holds the range of any tile inside it however read. `None` where the
    /// files it needs are missing (or, whole files, where none is there).
    pub fn ground_range(
        &self,
        tile: TileId,
        sampled: bool,
        budget: usize,
    ) -> Result<Option<(f64, f64)>, SrtmError> {
        if sampled {
            if self.check_coverage(tile).is_err() {
                return Ok(None);
            }
            let b = tile.bounds();
            let mosaic = self.mosaic(tile)?;
            return Ok(mosaic.height_range(b.west, b.south, b.east, b.north, budget));
        }
        let mut range: Option<(f64, f64)> = None;
        for cell in Self::cells_for(tile) {
            if let Some((low, high)) = self.srtm.height_range(cell)? {
                let (low, high) = (f64::from(low), f64::from(high));
                range = Some(range.map_or((low, high), |(l, h)| (l.min(low), h.max(high))));
            }
        }
        Ok(range)
    }

    /// The SRTM files around a tile (its own cells and any its margin reaches).
    pub fn mosaic(&self, tile: TileId) -> Result<Mosaic, SrtmError> {
        self.mosaic_of(Self::mosaic_cells(tile))
    }

    /// The SRTM files a tile made from `selection` reads: those around it, and those along
    /// the ways it is made from and its bridge and tunnel groups. What is found over a whole
    /// way (a river's fall, a lake's level, a group's or a road stretch's profile) reads the
    /// terrain along all of it, so every tile that shows part of it reads the same files and
    /// finds the same. Files along the ways that are missing are fetched when they can be;
    /// where none can be had, the terrain there is unknown. A way longer than `longest_m` is
    /// drawn from its part near the tile (see [`crate::features::FeatureSettings::longest_way_km`]):
    /// the files along the rest are not read.
    pub fn mosaic_for(
        &self,
        tile: TileId,
        selection: &crate::osm::index::Selection<'_>,
        longest_m: f64,
    ) -> Result<Mosaic, SrtmError> {
        let mut cells: std::collections::BTreeSet<CellId> = Self::mosaic_cells(tile).collect();
        cells.extend(reach_cells(selection, longest_m));
        for &cell in &cells {
            if let Err(error) = self.fetch_cell(tile, cell) {
                tracing::debug!(%tile, %error, "an SRTM file along the tile's ways is not available");
            }
        }
        self.mosaic_of(cells.into_iter())
    }

    fn mosaic_of(&self, cells: impl Iterator<Item = CellId>) -> Result<Mosaic, SrtmError> {
        let mut tiles: Vec<Arc<crate::terrain::cell::SrtmTile>> = Vec::new();
        for cell in cells {
            if let Some(t) = self.srtm.tile(cell)? {
                tiles.push(t);
            }
        }
        Ok(Mosaic::new(tiles))
    }

    /// The OSM data a tile is made from (its [`TileOsm::selection`] is what is near it).
    pub fn osm_for(&self, tile: TileId) -> Result<TileOsm<'_>, StoreError> {
        self.osm.tile(tile)
    }
}

/// The SRTM cells within [`MOSAIC_MARGIN_DEG`] of the ways of a selection (and of its
/// relations' member ways) and of its bridge and tunnel groups' chains. A segment longer than
/// [`LONGEST_SEGMENT_DEG`] (a ferry line, an error) adds the cells of its ends only.
fn reach_cells(
    selection: &crate::osm::index::Selection<'_>,
    longest_m: f64,
) -> std::collections::BTreeSet<CellId> {
    use crate::osm::{ElementType, LonLat};
    let mut cells = std::collections::BTreeSet::new();
    let mut along = |positions: &[LonLat]| {
        for pair in positions.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let long = (a.lon - b.lon).abs().max((a.lat - b.lat).abs()) > LONGEST_SEGMENT_DEG;
            if long {
                along_pair(&mut cells, a, a);
                along_pair(&mut cells, b, b);
            } else {
                along_pair(&mut cells, a, b);
            }
        }
    };
    for way in &selection.ways {
        if crate::osm::length_m(&way.positions) <= longest_m {
            along(&way.positions);
        }
    }
    let all = selection.all_ways;
    for relation in &selection.relations {
        for member in &relation.members {
            if member.element.element_type != ElementType::Way {
                continue;
            }
            if let Ok(i) = all.binary_search_by_key(&member.element.id, |w| w.id) {
                along(&all[i].positions);
            }
        }
    }
    for group in &selection.structures {
        for chain in &group.chains {
            along(&chain.positions);
        }
    }
    cells
}

/// Longer segments do not bring the cells between their ends into a tile's mosaic.
const LONGEST_SEGMENT_DEG: f64 = 1.0;

/// Adds the cells within [`MOSAIC_MARGIN_DEG`] of the box of `a` and `b`.
fn along_pair(
    cells: &mut std::collections::BTreeSet<CellId>,
    a: crate::osm::LonLat,
    b: crate::osm::LonLat,
) {
    let m = MOSAIC_MARGIN_DEG;
    let lats = (a.lat.min(b.lat) - m).floor() as i32..=(a.lat.max(b.lat) + m).floor() as i32;
    let lons = (a.lon.min(b.lon) - m).floor() as i32..=(a.lon.max(b.lon) + m).floor() as i32;
    for lat in lats {
        for lon in lons.clone() {
            cells.insert(CellId { lat, lon });
        }
    }
}
