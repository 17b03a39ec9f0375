//! A [`TileStore`] in PostgreSQL, shared by every process that names the same database
//! (`cache.url = "postgres://…"`): the same rows, codings, validators, size cap and
//! least-recently-served eviction as [`super::sqlite::SqliteStore`].
//!
//! Calls block (the `postgres` client runs its own small runtime); like every store call they
//! run on the blocking pool. Connections are kept in a small pool of our own and opened as
//! needed; one that failed is dropped, not returned.

pub mod cluster;
mod connections;
pub mod coordinator;

use std::sync::Arc;

use super::encoding::Bodies;
use super::sqlite::{stored_bytes, EVICT_TO, MAX_SOLUTIONS};
use super::store::{
    Provenance, SolutionEntry, StoreError, StoredEntry, StoredTile, TileFilter, TileReader,
    TileStore, Usage,
};
use crate::format::Encoding;
use crate::format::{Format, TileKey};
use crate::tile::TileId;
pub use cluster::Cluster;
pub use connections::redacted;
use connections::Connections;

/// The schema's migrations, in order; the database records how many it has applied.
const MIGRATIONS: &[(&str, &str)] = &[
    (
        "tiles",
        include_str!("../../../migrations/postgres/0001_tiles.sql"),
    ),
    (
        "cluster",
        include_str!("../../../migrations/postgres/0002_cluster.sql"),
    ),
];

/// The key of the advisory lock processes take while they migrate the schema.
const MIGRATION_LOCK: i64 = 0x7465_7272_6173_7469;

/// Tiles of a list removed or listed by one statement.
const TILES_PER_STATEMENT: usize = 1_000;

pub struct PostgresStore {
    connections: Arc<Connections>,
    max_bytes: Option<u64>,
    /// Largest tile, uncompressed, a row may give.
    max_tile: u64,
}

impl std::fmt::Debug for PostgresStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PostgresStore")
            .field("place", &self.place())
            .field("max_bytes", &self.max_bytes)
            .finish()
    }
}

impl PostgresStore {
    /// Connects to the database at `url`, applying the schema's migrations it lacks (one process
    /// at a time); past `max_bytes` of tiles, the least recently served are evicted.
    pub fn open(url: &str, max_bytes: Option<u64>) -> Result<PostgresStore, StoreError> {
        let store = PostgresStore {
            connections: Arc::new(Connections::new(url)),
            max_bytes,
            max_tile: super::store::DEFAULT_MAX_TILE_BYTES,
        };
        store.migrate()?;
        Ok(store)
    }

    /// The store with `bytes` as the largest tile, uncompressed, a row may give: a row that
    /// would inflate past it is damaged.
    pub fn with_max_tile(mut self, bytes: u64) -> PostgresStore {
        self.max_tile = bytes;
        self
    }

    /// Where the database is, without its password.
    pub fn place(&self) -> &str {
        self.connections.place()
    }

    /// What the processes sharing this database coordinate with: render leases, the work
    /// queue and broadcasts, on the same connections. `lease` is how long a claim lasts
    /// unrenewed.
    pub fn cluster(&self, lease: std::time::Duration) -> Cluster {
        Cluster::new(self.connections.clone(), lease)
    }

    fn error(&self, source: postgres::Error) -> StoreError {
        self.connections.error(source)
    }

    fn client(&self) -> Result<connections::Pooled<'_>, StoreError> {
        self.connections.client()
    }

    fn migrate(&self) -> Result<(), StoreError> {
        let mut client = self.client()?;
        let mut transaction = client.transaction().map_err(|e| self.error(e))?;
        transaction
            .execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK])
            .map_err(|e| self.error(e))?;
        transaction
            .batch_execute(
                "CREATE TABLE IF NOT EXISTS terrastitch_schema (
                     id integer PRIMARY KEY CHECK (id = 0), version bigint NOT NULL);
                 INSERT INTO terrastitch_schema VALUES (0, 0) ON CONFLICT DO NOTHING;",
            )
            .map_err(|e| self.error(e))?;
        let version: i64 = transaction
            .query_one("SELECT version FROM terrastitch_schema", &[])
            .map_err(|e| self.error(e))?
            .get(0);
        if version > MIGRATIONS.len() as i64 {
            return Err(StoreError::NewerSchema {
                path: self.place().to_string().into(),
                found: version,
                supported: MIGRATIONS.len(),
            });
        }
        for (number, (name, sql)) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
            transaction.batch_execute(sql).map_err(|e| self.error(e))?;
            transaction
                .execute(
                    "UPDATE terrastitch_schema SET version = $1",
                    &[&(number as i64 + 1)],
                )
                .map_err(|e| self.error(e))?;
            tracing::info!(place = %self.place(), migration = name, "tile cache schema migrated");
        }
        transaction.commit().map_err(|e| self.error(e))
    }

    /// Stores a tile in one step, replacing the one before where `only` (a `WHERE` on the row
    /// held, or nothing) allows; says whether it was written.
    fn upsert(&self, key: &TileKey, tile: &StoredTile, only: &str) -> Result<bool, StoreError> {
        let (coding, primary) = tile.bodies.primary();
        let (z, x, y) = key_columns(&key.tile);
        let size = stored_bytes(key, tile) as i64;
        let mut client = self.client()?;
        let mut transaction = client.transaction().map_err(|e| self.error(e))?;
        // A tile made again keeps the time it was last served.
        let written = transaction
            .execute(
                &format!(
                    "INSERT INTO tiles
                       (z, x, y, format, pipeline, data, etag, created_at,
                        encoding, data_br, sources, size, accessed_at)
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $8)
                     ON CONFLICT (z, x, y, format) DO UPDATE SET
                       pipeline = excluded.pipeline, data = excluded.data, etag = excluded.etag,
                       created_at = excluded.created_at, encoding = excluded.encoding,
                       data_br = excluded.data_br, sources = excluded.sources,
                       size = excluded.size
                     {only}"
                ),
                &[
                    &z,
                    &x,
                    &y,
                    &key.format.as_str(),
                    &tile.made_by.pipeline,
                    &primary.as_ref(),
                    &tile.etag,
                    &tile.created_at,
                    &coding.as_str(),
                    &tile.bodies.brotli.as_deref(),
                    &tile.made_by.sources,
                    &size,
                ],
            )
            .map_err(|e| self.error(e))?;
        let evicted = match written {
            0 => 0,
            _ => self
                .evict(&mut transaction, key)
                .map_err(|e| self.error(e))?,
        };
        transaction.commit().map_err(|e| self.error(e))?;
        crate::cache::store::log_eviction(evicted, self.max_bytes);
        Ok(written > 0)
    }

    /// Deletes the least recently served tiles (never `keep`) until the store is under
    /// [`EVICT_TO`] of its cap, reading at most 10,000 candidates a time (the next store goes
    /// on); returns how many went.
    fn evict(
        &self,
        transaction: &mut postgres::Transaction<'_>,
        keep: &TileKey,
    ) -> Result<u64, postgres::Error> {
        let Some(cap) = self.max_bytes else {
            return Ok(0);
        };
        let total: i64 = transaction
            .query_one("SELECT bytes FROM usage WHERE id = 0", &[])?
            .get(0);
        let mut total = total.max(0) as u64;
        if total <= cap {
            return Ok(0);
        }
        let target = (cap as f64 * EVICT_TO) as u64;
        let (z, x, y) = key_columns(&keep.tile);
        let oldest = transaction.query(
            "SELECT z, x, y, format, size FROM tiles
             WHERE NOT (z = $1 AND x = $2 AND y = $3 AND format = $4)
             ORDER BY accessed_at ASC LIMIT 10000",
            &[&z, &x, &y, &keep.format.as_str()],
        )?;
        let mut evicted = 0;
        for row in oldest {
            if total <= target {
                break;
            }
            let size: i64 = row.get(4);
            evicted += transaction.execute(
                "DELETE FROM tiles WHERE z = $1 AND x = $2 AND y = $3 AND format = $4",
                &[
                    &row.get::<_, i16>(0),
                    &row.get::<_, i32>(1),
                    &row.get::<_, i32>(2),
                    &row.get::<_, String>(3),
                ],
            )?;
            total = total.saturating_sub(size.max(0) as u64);
        }
        Ok(evicted)
    }

    fn delete_row(&self, key: &TileKey) -> Result<(), StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        self.client()?
            .execute(
                "DELETE FROM tiles WHERE z = $1 AND x = $2 AND y = $3 AND format = $4",
                &[&z, &x, &y, &key.format.as_str()],
            )
            .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// The rows of `statement` (a `SELECT` or `DELETE` of the tiles table) over the tiles a
    /// filter selects, `order` (or `RETURNING`) after its condition; a list of tiles is matched
    /// by arrays of its columns, a statement per thousand tiles.
    fn select_keys(
        &self,
        filter: &TileFilter,
        statement: &str,
        order: &str,
    ) -> Result<Vec<postgres::Row>, StoreError> {
        let mut client = self.client()?;
        let rows = match filter {
            TileFilter::All => client.query(&format!("{statement} {order}"), &[]),
            TileFilter::Range(range) => client.query(
                &format!(
                    "{statement} WHERE z = $1 AND x BETWEEN $2 AND $3 AND y BETWEEN $4 AND $5 \
                     {order}"
                ),
                &[
                    &i16::from(range.z),
                    &column(range.min_x),
                    &column(range.max_x),
                    &column(range.min_y),
                    &column(range.max_y),
                ],
            ),
            TileFilter::Tiles(tiles) => {
                let mut rows = Vec::new();
                for chunk in tiles.chunks(TILES_PER_STATEMENT) {
                    let zs: Vec<i16> = chunk.iter().map(|t| i16::from(t.z)).collect();
                    let xs: Vec<i32> = chunk.iter().map(|t| column(t.x)).collect();
                    let ys: Vec<i32> = chunk.iter().map(|t| column(t.y)).collect();
                    rows.extend(
                        client
                            .query(
                                &format!(
                                    "{statement} WHERE (z, x, y) IN \
                                     (SELECT * FROM unnest($1::smallint[], $2::integer[], \
                                     $3::integer[])) {order}"
                                ),
                                &[&zs, &xs, &ys],
                            )
                            .map_err(|e| self.error(e))?,
                    );
                }
                Ok(rows)
            }
        };
        rows.map_err(|e| self.error(e))
    }
}

/// A tile coordinate as its column (coordinates of zoom 30 and below fit).
fn column(v: u32) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

fn key_columns(tile: &TileId) -> (i16, i32, i32) {
    (i16::from(tile.z), column(tile.x), column(tile.y))
}

/// The key of a row whose first four columns are `z`, `x`, `y`, `format` (`None` for a
/// format this version does not know).
fn key_of(row: &postgres::Row) -> Option<TileKey> {
    let z: i16 = row.get(0);
    let (x, y): (i32, i32) = (row.get(1), row.get(2));
    Some(TileKey {
        tile: TileId {
            z: u8::try_from(z).ok()?,
            x: u32::try_from(x).ok()?,
            y: u32::try_from(y).ok()?,
        },
        format: Format::from_name(row.get::<_, &str>(3))?,
    })
}

impl TileReader for PostgresStore {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        let row = self
            .client()?
            .query_opt(
                "SELECT data, encoding, data_br, etag, pipeline, sources, created_at FROM tiles
                 WHERE z = $1 AND x = $2 AND y = $3 AND format = $4",
                &[&z, &x, &y, &key.format.as_str()],
            )
            .map_err(|e| self.error(e))?;
        let Some(row) = row else {
            return Ok(None);
        };
        let etag: String = row.get(3);
        let coding = Encoding::from_name(row.get(1)).unwrap_or(Encoding::Identity);
        let bodies = match Bodies::from_stored(row.get(0), coding, row.get(2), self.max_tile)
            .and_then(|bodies| bodies.verify(&etag).map(|()| bodies))
        {
            Ok(bodies) => bodies,
            Err(error) => {
                tracing::warn!(tile = %key.tile, format = key.format.as_str(), %error, "dropping a damaged cached tile");
                self.delete_row(key)?;
                return Ok(None);
            }
        };
        Ok(Some(StoredTile {
            bodies,
            etag,
            made_by: Provenance {
                pipeline: row.get(4),
                sources: row.get(5),
            },
            created_at: row.get(6),
        }))
    }

    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError> {
        let rows = self.select_keys(
            filter,
            "SELECT z, x, y, format, pipeline, sources, size, accessed_at FROM tiles",
            "ORDER BY accessed_at DESC",
        )?;
        let mut entries: Vec<StoredEntry> = rows
            .iter()
            .filter_map(|row| {
                Some(StoredEntry {
                    key: key_of(row)?,
                    made_by: Provenance {
                        pipeline: row.get(4),
                        sources: row.get(5),
                    },
                    size: row.get::<_, i64>(6).max(0) as u64,
                    accessed_at: row.get(7),
                })
            })
            .collect();
        // Lists read in chunks come back chunk by chunk: one order for the whole.
        entries.sort_by_key(|e| std::cmp::Reverse(e.accessed_at));
        Ok(entries)
    }

    fn usage(&self) -> Result<Usage, StoreError> {
        let row = self
            .client()?
            .query_one("SELECT tiles, bytes FROM usage WHERE id = 0", &[])
            .map_err(|e| self.error(e))?;
        Ok(Usage {
            tiles: row.get::<_, i64>(0).max(0) as u64,
            bytes: row.get::<_, i64>(1).max(0) as u64,
        })
    }

    fn solutions(&self, limit: usize) -> Result<Vec<SolutionEntry>, StoreError> {
        let rows = self
            .client()?
            .query(
                "SELECT key, data FROM solutions ORDER BY kept DESC LIMIT $1",
                &[&i64::try_from(limit).unwrap_or(i64::MAX)],
            )
            .map_err(|e| self.error(e))?;
        Ok(rows
            .iter()
            .filter_map(|row| {
                let key = <[u8; 32]>::try_from(row.get::<_, &[u8]>(0)).ok()?;
                Some((key, row.get::<_, Vec<u8>>(1)))
            })
            .collect())
    }
}

impl TileStore for PostgresStore {
    fn put(&self, key: &TileKey, tile: &StoredTile) -> Result<(), StoreError> {
        self.upsert(key, tile, "").map(|_| ())
    }

    fn put_if_vacant(&self, key: &TileKey, tile: &StoredTile) -> Result<bool, StoreError> {
        self.upsert(key, tile, "WHERE tiles.etag = excluded.etag")
    }

    fn touch(&self, keys: &[TileKey], at: i64) -> Result<(), StoreError> {
        let mut client = self.client()?;
        let mut transaction = client.transaction().map_err(|e| self.error(e))?;
        let statement = transaction
            .prepare(
                "UPDATE tiles SET accessed_at = greatest(accessed_at, $5)
                 WHERE z = $1 AND x = $2 AND y = $3 AND format = $4",
            )
            .map_err(|e| self.error(e))?;
        for key in keys {
            let (z, x, y) = key_columns(&key.tile);
            transaction
                .execute(&statement, &[&z, &x, &y, &key.format.as_str(), &at])
                .map_err(|e| self.error(e))?;
        }
        transaction.commit().map_err(|e| self.error(e))
    }

    fn remove(&self, filter: &TileFilter) -> Result<Vec<TileKey>, StoreError> {
        let rows = self.select_keys(filter, "DELETE FROM tiles", "RETURNING z, x, y, format")?;
        Ok(rows.iter().filter_map(key_of).collect())
    }

    fn keep_solutions(&self, entries: &[SolutionEntry]) -> Result<(), StoreError> {
        if entries.is_empty() {
            return Ok(());
        }
        let mut client = self.client()?;
        let mut transaction = client.transaction().map_err(|e| self.error(e))?;
        let insert = transaction
            .prepare("INSERT INTO solutions (key, data) VALUES ($1, $2) ON CONFLICT DO NOTHING")
            .map_err(|e| self.error(e))?;
        for (key, data) in entries {
            transaction
                .execute(&insert, &[&key.as_slice(), data])
                .map_err(|e| self.error(e))?;
        }
        transaction
            .execute(
                "DELETE FROM solutions WHERE kept <= (SELECT max(kept) FROM solutions) - $1",
                &[&MAX_SOLUTIONS],
            )
            .map_err(|e| self.error(e))?;
        transaction.commit().map_err(|e| self.error(e))
    }
}
