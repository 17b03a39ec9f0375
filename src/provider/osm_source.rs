//! Where a tile's OSM elements come from: the whole extract indexed in memory, or the imported
//! on-disk store, which gives each tile its closure indexed with the facts found over all the
//! data. Both select the same elements for a tile, so a tile's bytes do not depend on which.

use std::path::{Path, PathBuf};

use crate::osm::index::Selection;
use crate::osm::{Bounds, OsmIndex};
use crate::source::fetch::Fetcher;
use crate::source::osc::{self, OscError, OsmChange};
use crate::source::replication::{Replication, ReplicationError};
use crate::source::store::import::{self, ImportError, Imported, Progress, Rules};
use crate::source::store::update::{self, Applied, DiffOrigin, UpdateError};
use crate::source::store::{OsmStore, StoreError};
use crate::tile::TileId;

/// How far around a tile elements are fetched, in degrees (220 m north–south, 160 m east–west at
/// Monaco's latitude): wide enough for the widest road polygon, for buildings that straddle the
/// edge, and for every way through a junction whose polygon or cut-back arms can reach the tile
/// (a junction reaches at most 25 m plus a half width along its arms, and how far an arm is cut
/// depends on whether the next node along it, up to 55 m on, is a junction too).
pub const QUERY_MARGIN_DEG: f64 = 0.002;

/// The feature rules the extract-wide facts need: which ways are bridges and tunnels, which
/// join the road network, what reaches down into the ground over a tunnel.
pub fn rules() -> Rules {
    Rules {
        classify: crate::features::structures::classify,
        joins: crate::features::roads::joins,
        depth: crate::features::structures::foundation_depth_m,
        relation: crate::features::reads_relation,
        generalise: crate::features::overview::generalise,
    }
}

/// The OSM data a server renders from.
#[derive(Debug)]
pub enum OsmSource {
    /// The whole data, read at start and indexed in memory.
    Memory(Box<OsmIndex>),
    /// An imported store.
    Store(OsmStore),
}

/// A tile's OSM data: a view of the whole index, or the tile's closure read from the store.
#[derive(Debug)]
pub enum TileOsm<'a> {
    Whole(&'a OsmIndex),
    Closure(Box<OsmIndex>),
    /// A far tile's generalised data, kept by the store.
    Far(Box<crate::osm::far::FarTile>),
}

impl TileOsm<'_> {
    /// The elements near `tile`.
    pub fn selection(&self, tile: TileId) -> Selection<'_> {
        match self {
            TileOsm::Whole(index) => index.query(tile, QUERY_MARGIN_DEG),
            TileOsm::Closure(index) => index.query(tile, QUERY_MARGIN_DEG),
            TileOsm::Far(far) => far.selection(),
        }
    }
}

impl OsmSource {
    /// The area each extract declares, in the order they were given.
    pub fn coverage(&self) -> Vec<Bounds> {
        match self {
            OsmSource::Memory(index) => index.data().coverage.clone(),
            OsmSource::Store(store) => store.coverage(),
        }
    }

    /// True when some extract covers part of `bounds`.
    pub fn covers(&self, bounds: &Bounds) -> bool {
        self.coverage().iter().any(|c| c.intersects(bounds))
    }

    /// The OSM data a tile is made from.
    pub fn tile(&self, tile: TileId) -> Result<TileOsm<'_>, StoreError> {
        match self {
            OsmSource::Memory(index) => Ok(TileOsm::Whole(index)),
            OsmSource::Store(store) if crate::tile::is_overview_zoom(tile.z, store.zoom()) => {
                Ok(TileOsm::Far(Box::new(store.far_tile(tile)?)))
            }
            OsmSource::Store(store) => Ok(TileOsm::Closure(Box::new(
                store.tile_index(tile, QUERY_MARGIN_DEG)?,
            ))),
        }
    }

    /// The whole data's index, when it is in memory.
    pub fn index(&self) -> Option<&OsmIndex> {
        match self {
            OsmSource::Memory(index) => Some(index),
            OsmSource::Store(_) => None,
        }
    }
}

/// Why a store could not be had.
#[derive(Debug, thiserror::Error)]
pub enum StoreOpenError {
    #[error(transparent)]
    Import(#[from] ImportError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Update(#[from] UpdateError),
    #[error(transparent)]
    Osc(#[from] OscError),
    #[error(transparent)]
    Replication(#[from] ReplicationError),
    #[error("cannot lock {path} to import the OSM store: {source}")]
    Lock {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The store at `path` for `extracts` at `zoom`: opened when it was imported from exactly these
/// files as they are now, else imported first (beside it, then swapped in).
pub fn open_store(
    path: &Path,
    extracts: &[PathBuf],
    zoom: u8,
    progress: &dyn Fn(&Progress),
) -> Result<(OsmStore, Option<Imported>), StoreOpenError> {
    if let Some(store) = current_store(path, extracts, zoom) {
        return Ok((store, None));
    }
    // One import at a time (a server and a seed may start together); whoever waited finds
    // the store the other imported.
    let lock = lock_file(path)?;
    if let Some(store) = current_store(path, extracts, zoom) {
        return Ok((store, None));
    }
    tracing::info!(store = %path.display(), "the OSM store is missing or older than its extracts; importing them");
    let imported = import::import(extracts, path, zoom, &rules(), false, progress)?;
    drop(lock);
    Ok((OsmStore::open(path)?, Some(imported)))
}

/// Imports `extracts` into the store at `path`, one import of that store at a time.
/// With `force`, it replaces a store though it would lose most of a kind of element (see
/// [`import::import`]).
pub fn import_locked(
    path: &Path,
    extracts: &[PathBuf],
    zoom: u8,
    force: bool,
    progress: &dyn Fn(&Progress),
) -> Result<Imported, StoreOpenError> {
    let _lock = lock_file(path)?;
    Ok(import::import(
        extracts,
        path,
        zoom,
        &rules(),
        force,
        progress,
    )?)
}

/// Applies OSM change files, in the order given, to the store at `path` in one transaction
/// (one change to the store at a time); `sequence` is the replication sequence of the last.
pub fn update_locked(
    path: &Path,
    files: &[PathBuf],
    sequence: Option<u64>,
) -> Result<Applied, StoreOpenError> {
    let mut change = OsmChange::default();
    for file in files {
        change
            .merge(osc::read_osc(file)?)
            .map_err(|why| UpdateError::OutOfOrder {
                path: path.to_path_buf(),
                diff: file.display().to_string(),
                why: format!("{why} in the files before it"),
            })?;
    }
    let origin = DiffOrigin {
        name: files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        sequence,
    };
    apply_locked(path, &change, &origin)
}

/// Applies one change, read already, to the store at `path`.
pub fn apply_locked(
    path: &Path,
    change: &OsmChange,
    origin: &DiffOrigin,
) -> Result<Applied, StoreOpenError> {
    let _lock = lock_file(path)?;
    Ok(update::apply(
        path,
        change,
        origin,
        &rules(),
        QUERY_MARGIN_DEG,
    )?)
}

/// What catching up with a replication source did.
#[derive(Debug, Clone, Default)]
pub struct CaughtUp {
    /// The source's sequence when it was asked.
    pub source: u64,
    /// The diffs applied, in order, with their sequence.
    pub applied: Vec<(u64, Applied)>,
}

/// Applies the diffs of `replication` the store at `path` lacks, in order, each in its own
/// transaction: a run cut short (killed, or a diff that cannot be had) resumes after the
/// last one applied. A store that knows no sequence starts at the source's current one.
/// At most `limit` diffs are applied.
pub fn catch_up(
    path: &Path,
    replication: &Replication,
    fetcher: &Fetcher,
    limit: usize,
) -> Result<CaughtUp, StoreOpenError> {
    let state = replication.state(fetcher)?;
    let mut caught = CaughtUp {
        source: state.sequence,
        applied: Vec::new(),
    };
    // Held throughout: another run waits, then finds where this one stopped.
    let _lock = lock_file(path)?;
    let Some(last) = update::replication_sequence(path)? else {
        tracing::warn!(
            store = %path.display(),
            sequence = state.sequence,
            "the OSM store knows no replication sequence: diffs apply from the source's current one"
        );
        update::start_replication_at(path, state.sequence)?;
        return Ok(caught);
    };
    if state.sequence < last {
        tracing::warn!(
            store = %path.display(),
            source = replication.base(),
            source_sequence = state.sequence,
            store_sequence = last,
            behind = last - state.sequence,
            "the replication source is behind the OSM store: nothing to apply (is it the source the store follows?)"
        );
    }
    for sequence in (last + 1..=state.sequence).take(limit) {
        let (file, name) = replication.diff(fetcher, sequence)?;
        let change = match osc::read_osc(&file) {
            Ok(change) => change,
            Err(error) => {
                // A damaged download is fetched again next time.
                if crate::source::fetch::is_url(replication.base()) {
                    let _ = std::fs::remove_file(&file);
                }
                return Err(error.into());
            }
        };
        let origin = DiffOrigin {
            name,
            sequence: Some(sequence),
        };
        let applied = update::apply(path, &change, &origin, &rules(), QUERY_MARGIN_DEG)?;
        tracing::info!(
            sequence,
            expired = applied.expired.len(),
            "applied a replication diff to the OSM store"
        );
        caught.applied.push((sequence, applied));
    }
    Ok(caught)
}

fn current_store(path: &Path, extracts: &[PathBuf], zoom: u8) -> Option<OsmStore> {
    OsmStore::open(path)
        .ok()
        .filter(|store| is_current(store, extracts, zoom))
}

/// Holds `PATH.lock` locked until dropped.
fn lock_file(path: &Path) -> Result<std::fs::File, StoreOpenError> {
    let mut name = path.as_os_str().to_owned();
    name.push(".lock");
    let lock_path = PathBuf::from(name);
    let failed = |source| StoreOpenError::Lock {
        path: lock_path.clone(),
        source,
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(failed)?;
    }
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(failed)?;
    lock_exclusively(&file).map_err(failed)?;
    Ok(file)
}

/// Waits for an exclusive advisory lock on `file`, released when it is closed.
fn lock_exclusively(file: &std::fs::File) -> std::io::Result<()> {
    use std::os::unix::io::AsRawFd;
    // SAFETY: flock takes a file descriptor `file` owns and keeps open for the call.
    let done = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX) };
    if done == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Whether `store` holds `extracts` as they are on disk now, indexed at `zoom` by this version
/// of the program (another may find bridges, tunnels and joints by other rules).
pub fn is_current(store: &OsmStore, extracts: &[PathBuf], zoom: u8) -> bool {
    store.zoom() == zoom
        && store.program() == env!("CARGO_PKG_VERSION")
        && store.extracts().len() == extracts.len()
        && store.extracts().iter().zip(extracts).all(|(record, path)| {
            same_file(&record.path, path)
                && crate::source::srtm::file_version(path).ok().as_deref()
                    == Some(record.file_version.as_str())
        })
}

/// Whether two paths name one file (one may be relative, the other not).
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}
