//! What the processes sharing a PostgreSQL database coordinate with, beside the tiles:
//!
//! - **Render leases** (table `leases`): a process claims a tile before it makes it, so a tile
//!   asked of several processes at once is made once; the others wait for it to land in the
//!   store. A claim lasts [`Cluster::lease`] unless its holder renews it (every third of that,
//!   by a heartbeat thread), so the claims of a process that died lapse and another takes the
//!   tile over.
//! - **The work queue** (table `work`): tiles to make again and tiles to seed, one row each,
//!   taken with `FOR UPDATE SKIP LOCKED` by any process's workers; a taken row is held as long
//!   as its worker's heartbeat goes on, so a crashed worker's rows are taken again.
//! - **Broadcasts** (`NOTIFY terrastitch`): a tile stored anew, tiles purged, work queued;
//!   every process listens and drops what its memory holds of them.
//!
//! Calls block, like the store's.

use std::sync::{Arc, Weak};
use std::time::Duration;

use postgres::fallible_iterator::FallibleIterator;
use serde_json::{json, Value};

use super::connections::Connections;
use super::{column, key_columns, key_of, TILES_PER_STATEMENT};
use crate::cache::coordinator::{Event, Job, JobKind, Priority};
use crate::cache::store::{StoreError, TileFilter};
use crate::format::{Format, TileKey};
use crate::tile::{TileId, TileRange};

/// The channel broadcasts go on.
const CHANNEL: &str = "terrastitch";

/// Longest payload `NOTIFY` takes, bytes (PostgreSQL's limit is 8000).
const PAYLOAD_LIMIT: usize = 7_900;

/// Failures after which a row of work is set aside as failed.
pub const MAX_ATTEMPTS: i32 = 3;

/// How the queue of one kind stands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QueueStatus {
    pub kind: String,
    /// Rows waiting to be taken.
    pub waiting: u64,
    /// Rows a live worker holds.
    pub taken: u64,
    /// Rows set aside after failing [`MAX_ATTEMPTS`] times.
    pub failed: u64,
}

/// A process of the cluster, as it last reported.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkerStatus {
    pub name: String,
    pub kind: String,
    /// Seconds since it started, and since it was last heard of.
    pub running_s: f64,
    pub silent_s: f64,
    /// Tiles it made from the queue, and tiles it gave up on.
    pub made: i64,
    pub failed: i64,
}

/// The cluster as one process sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    pub queues: Vec<QueueStatus>,
    pub workers: Vec<WorkerStatus>,
    /// Render leases held now.
    pub leases: u64,
    /// Failed rows, up to 20: the tile, its format and the error.
    pub failures: Vec<(TileKey, String)>,
}

pub struct Cluster {
    connections: Arc<Connections>,
    /// This process's name in the cluster: host, process id and a random part.
    holder: String,
    lease: Duration,
}

impl std::fmt::Debug for Cluster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cluster")
            .field("place", &self.connections.place())
            .field("holder", &self.holder)
            .field("lease", &self.lease)
            .finish()
    }
}

/// This machine's name, as the kernel has it.
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|name| name.trim().to_string())
        .filter(|name| !name.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "host".to_string())
}

/// Bits that tell apart two processes of one host and pid (a restart in a container).
fn random_tag() -> u32 {
    use std::hash::{BuildHasher, Hasher};
    let mut hasher = std::collections::hash_map::RandomState::new().build_hasher();
    hasher.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    hasher.finish() as u32
}

impl Cluster {
    pub(super) fn new(connections: Arc<Connections>, lease: Duration) -> Cluster {
        Cluster {
            connections,
            holder: format!(
                "{}:{}:{:08x}",
                host_name(),
                std::process::id(),
                random_tag()
            ),
            lease: lease.max(Duration::from_secs(1)),
        }
    }

    /// This process's name in the cluster.
    pub fn holder(&self) -> &str {
        &self.holder
    }

    /// How long a claim lasts unrenewed.
    pub fn lease(&self) -> Duration {
        self.lease
    }

    fn lease_s(&self) -> f64 {
        self.lease.as_secs_f64()
    }

    fn error(&self, source: postgres::Error) -> StoreError {
        self.connections.error(source)
    }

    /// Says this process is in the cluster, as a `kind` (`serve`, `seed`), and forgets
    /// processes not heard of for a day.
    pub fn register(&self, kind: &str) -> Result<(), StoreError> {
        let mut client = self.connections.client()?;
        client
            .execute(
                "INSERT INTO workers (name, kind) VALUES ($1, $2)
                 ON CONFLICT (name) DO UPDATE SET seen_at = now()",
                &[&self.holder, &kind],
            )
            .map_err(|e| self.error(e))?;
        client
            .execute(
                "DELETE FROM workers WHERE seen_at < now() - interval '1 day'",
                &[],
            )
            .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// Claims `key` for a render: true when this process holds it now (nobody held it, or the
    /// holder let it lapse), false while another holds it.
    pub fn try_lease(&self, key: &TileKey) -> Result<bool, StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        let row = self
            .connections
            .client()?
            .query_opt(
                "INSERT INTO leases (z, x, y, format, holder, expires_at)
                 VALUES ($1, $2, $3, $4, $5, now() + make_interval(secs => $6))
                 ON CONFLICT (z, x, y, format) DO UPDATE
                   SET holder = excluded.holder, expires_at = excluded.expires_at
                   WHERE leases.expires_at < now()
                 RETURNING holder",
                &[
                    &z,
                    &x,
                    &y,
                    &key.format.as_str(),
                    &self.holder,
                    &self.lease_s(),
                ],
            )
            .map_err(|e| self.error(e))?;
        Ok(row.is_some())
    }

    /// Gives up the claim on `key` (if this process holds it).
    pub fn release(&self, key: &TileKey) -> Result<(), StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        self.connections
            .client()?
            .execute(
                "DELETE FROM leases
                 WHERE z = $1 AND x = $2 AND y = $3 AND format = $4 AND holder = $5",
                &[&z, &x, &y, &key.format.as_str(), &self.holder],
            )
            .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// Renews every claim and every row of work this process holds, and says it is alive.
    pub fn renew(&self) -> Result<(), StoreError> {
        let mut client = self.connections.client()?;
        let lease = self.lease_s();
        for statement in [
            "UPDATE leases SET expires_at = now() + make_interval(secs => $2) WHERE holder = $1",
            "UPDATE work SET taken_until = now() + make_interval(secs => $2) WHERE taken_by = $1",
        ] {
            client
                .execute(statement, &[&self.holder, &lease])
                .map_err(|e| self.error(e))?;
        }
        client
            .execute(
                "UPDATE workers SET seen_at = now() WHERE name = $1",
                &[&self.holder],
            )
            .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// Renews this process's claims every third of the lease, on a thread of its own, for as
    /// long as the cluster is in use.
    pub fn start_heartbeat(self: &Arc<Self>) -> std::io::Result<()> {
        let cluster: Weak<Cluster> = Arc::downgrade(self);
        let every = self.lease / 3;
        std::thread::Builder::new()
            .name("cluster-heartbeat".into())
            .spawn(move || loop {
                std::thread::sleep(every);
                let Some(cluster) = cluster.upgrade() else {
                    return;
                };
                if let Err(error) = cluster.renew() {
                    tracing::warn!(%error, "renewing this process's claims failed");
                }
            })
            .map(|_| ())
    }

    /// Queues tiles as `kind` work at `priority` (a tile already queued keeps its place, or
    /// moves up; one set aside as failed is tried afresh); returns how many rows were added or
    /// changed, and tells the cluster.
    pub fn enqueue(
        &self,
        keys: &[TileKey],
        kind: JobKind,
        priority: Priority,
        force: bool,
    ) -> Result<u64, StoreError> {
        let mut client = self.connections.client()?;
        let mut queued = 0;
        for chunk in keys.chunks(TILES_PER_STATEMENT) {
            let zs: Vec<i16> = chunk.iter().map(|k| i16::from(k.tile.z)).collect();
            let xs: Vec<i32> = chunk.iter().map(|k| column(k.tile.x)).collect();
            let ys: Vec<i32> = chunk.iter().map(|k| column(k.tile.y)).collect();
            let formats: Vec<&str> = chunk.iter().map(|k| k.format.as_str()).collect();
            queued += client
                .execute(
                    "INSERT INTO work (z, x, y, format, kind, priority, force)
                     SELECT z, x, y, f, $5, $6, $7
                     FROM unnest($1::smallint[], $2::integer[], $3::integer[], $4::text[])
                       AS k(z, x, y, f)
                     ON CONFLICT (z, x, y, format) DO UPDATE SET
                       priority = least(work.priority, excluded.priority),
                       force = work.force OR excluded.force,
                       failed = false,
                       attempts = CASE WHEN work.failed THEN 0 ELSE work.attempts END
                     WHERE work.priority > excluded.priority
                        OR (excluded.force AND NOT work.force) OR work.failed",
                    &[
                        &zs,
                        &xs,
                        &ys,
                        &formats,
                        &kind.as_str(),
                        &(priority as i16),
                        &force,
                    ],
                )
                .map_err(|e| self.error(e))?;
        }
        if queued > 0 {
            self.broadcast(&Event::Work)?;
        }
        Ok(queued)
    }

    /// Takes the next row of `kind` nobody holds, with the other rows of `kind` of its tile
    /// nobody holds, for as long as this process renews them.
    pub fn take(&self, kind: JobKind) -> Result<Vec<Job>, StoreError> {
        // Rows another taker locks are skipped, the first row's as the others': two takers
        // never wait on each other.
        let rows = self
            .connections
            .client()?
            .query(
                "UPDATE work SET taken_by = $1,
                   taken_until = now() + make_interval(secs => $2), attempts = attempts + 1
                 WHERE (z, x, y, format) IN (
                   SELECT z, x, y, format FROM work
                   WHERE kind = $3 AND NOT failed
                     AND (taken_until IS NULL OR taken_until < now())
                     AND (z, x, y) = (
                       SELECT z, x, y FROM work
                       WHERE kind = $3 AND NOT failed
                         AND (taken_until IS NULL OR taken_until < now())
                       ORDER BY priority, queued LIMIT 1
                       FOR UPDATE SKIP LOCKED)
                   FOR UPDATE SKIP LOCKED)
                 RETURNING z, x, y, format, force, attempts",
                &[&self.holder, &self.lease_s(), &kind.as_str()],
            )
            .map_err(|e| self.error(e))?;
        // A format this version does not know is left for a process that does.
        let mut jobs: Vec<Job> = rows
            .iter()
            .filter_map(|row| {
                Some(Job {
                    key: key_of(row)?,
                    force: row.get(4),
                    attempts: row.get(5),
                })
            })
            .collect();
        jobs.sort_by_key(|job| job.key);
        Ok(jobs)
    }

    /// Done with a taken row: it leaves the queue; `made` counts a tile made.
    pub fn finish(&self, key: &TileKey, made: bool) -> Result<(), StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        let mut client = self.connections.client()?;
        client
            .execute(
                "DELETE FROM work
                 WHERE z = $1 AND x = $2 AND y = $3 AND format = $4 AND taken_by = $5",
                &[&z, &x, &y, &key.format.as_str(), &self.holder],
            )
            .map_err(|e| self.error(e))?;
        if made {
            client
                .execute(
                    "UPDATE workers SET made = made + 1, seen_at = now() WHERE name = $1",
                    &[&self.holder],
                )
                .map_err(|e| self.error(e))?;
        }
        Ok(())
    }

    /// Hands a taken row back, to be taken again after `after` without counting this attempt
    /// (its tile is claimed by a render elsewhere).
    pub fn defer(&self, key: &TileKey, after: Duration) -> Result<(), StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        self.connections
            .client()?
            .execute(
                "UPDATE work SET taken_by = NULL,
                   taken_until = now() + make_interval(secs => $6), attempts = attempts - 1
                 WHERE z = $1 AND x = $2 AND y = $3 AND format = $4 AND taken_by = $5",
                &[
                    &z,
                    &x,
                    &y,
                    &key.format.as_str(),
                    &self.holder,
                    &after.as_secs_f64(),
                ],
            )
            .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// A taken row whose tile failed: tried again later, or set aside after
    /// [`MAX_ATTEMPTS`]; returns whether it was set aside.
    pub fn fail(&self, key: &TileKey, error: &str) -> Result<bool, StoreError> {
        let (z, x, y) = key_columns(&key.tile);
        let mut client = self.connections.client()?;
        let row = client
            .query_opt(
                "UPDATE work SET taken_by = NULL, error = $6, failed = attempts >= $7,
                   taken_until = now() + make_interval(secs => attempts * 2.0)
                 WHERE z = $1 AND x = $2 AND y = $3 AND format = $4 AND taken_by = $5
                 RETURNING failed",
                &[
                    &z,
                    &x,
                    &y,
                    &key.format.as_str(),
                    &self.holder,
                    &error,
                    &MAX_ATTEMPTS,
                ],
            )
            .map_err(|e| self.error(e))?;
        let set_aside = row.is_some_and(|row| row.get(0));
        if set_aside {
            client
                .execute(
                    "UPDATE workers SET failed = failed + 1 WHERE name = $1",
                    &[&self.holder],
                )
                .map_err(|e| self.error(e))?;
        }
        Ok(set_aside)
    }

    /// Rows of `kind` not set aside: waiting or taken.
    pub fn pending(&self, kind: JobKind) -> Result<u64, StoreError> {
        let row = self
            .connections
            .client()?
            .query_one(
                "SELECT count(*) FROM work WHERE kind = $1 AND NOT failed",
                &[&kind.as_str()],
            )
            .map_err(|e| self.error(e))?;
        Ok(row.get::<_, i64>(0).max(0) as u64)
    }

    /// Tells every process of the cluster (this one's listener ignores it).
    pub fn broadcast(&self, event: &Event) -> Result<(), StoreError> {
        let mut client = self.connections.client()?;
        for payload in payloads(&self.holder, event) {
            client
                .execute("SELECT pg_notify($1, $2)", &[&CHANNEL, &payload])
                .map_err(|e| self.error(e))?;
        }
        Ok(())
    }

    /// Listens to the cluster's broadcasts on a connection and thread of their own, for as long
    /// as the cluster is in use, and hands each from another process to `on_event`. A lost
    /// connection is opened again, and `on_event` told [`Event::Missed`].
    pub fn listen(
        self: &Arc<Self>,
        on_event: impl Fn(Event) + Send + 'static,
    ) -> std::io::Result<()> {
        let cluster: Weak<Cluster> = Arc::downgrade(self);
        let holder = self.holder.clone();
        std::thread::Builder::new()
            .name("cluster-listener".into())
            .spawn(move || {
                let mut lost = false;
                loop {
                    let Some(connections) = cluster.upgrade().map(|c| c.connections.clone()) else {
                        return;
                    };
                    match connections.connect().and_then(|mut client| {
                        client
                            .batch_execute(&format!("LISTEN {CHANNEL}"))
                            .map_err(|e| connections.error(e))?;
                        Ok(client)
                    }) {
                        Ok(mut client) => {
                            drop(connections);
                            if lost {
                                on_event(Event::Missed);
                            }
                            relay(&mut client, &cluster, &holder, &on_event);
                            lost = true;
                        }
                        Err(error) => {
                            tracing::warn!(%error, "listening to the cluster failed; trying again");
                            std::thread::sleep(Duration::from_secs(1));
                        }
                    }
                }
            })
            .map(|_| ())
    }

    /// What the cluster's queue, workers and leases are.
    pub fn status(&self) -> Result<Status, StoreError> {
        let mut client = self.connections.client()?;
        let queues = client
            .query(
                "SELECT kind,
                   count(*) FILTER (WHERE NOT failed
                     AND (taken_by IS NULL OR taken_until < now())),
                   count(*) FILTER (WHERE NOT failed
                     AND taken_by IS NOT NULL AND taken_until >= now()),
                   count(*) FILTER (WHERE failed)
                 FROM work GROUP BY kind ORDER BY kind",
                &[],
            )
            .map_err(|e| self.error(e))?
            .iter()
            .map(|row| QueueStatus {
                kind: row.get(0),
                waiting: row.get::<_, i64>(1).max(0) as u64,
                taken: row.get::<_, i64>(2).max(0) as u64,
                failed: row.get::<_, i64>(3).max(0) as u64,
            })
            .collect();
        let workers = client
            .query(
                "SELECT name, kind,
                   extract(epoch FROM now() - started_at)::float8,
                   extract(epoch FROM now() - seen_at)::float8, made, failed
                 FROM workers ORDER BY started_at",
                &[],
            )
            .map_err(|e| self.error(e))?
            .iter()
            .map(|row| WorkerStatus {
                name: row.get(0),
                kind: row.get(1),
                running_s: row.get(2),
                silent_s: row.get(3),
                made: row.get(4),
                failed: row.get(5),
            })
            .collect();
        let leases: i64 = client
            .query_one("SELECT count(*) FROM leases WHERE expires_at >= now()", &[])
            .map_err(|e| self.error(e))?
            .get(0);
        let failures = client
            .query(
                "SELECT z, x, y, format, coalesce(error, '') FROM work WHERE failed
                 ORDER BY queued LIMIT 20",
                &[],
            )
            .map_err(|e| self.error(e))?
            .iter()
            .filter_map(|row| Some((key_of(row)?, row.get(4))))
            .collect();
        Ok(Status {
            queues,
            workers,
            leases: leases.max(0) as u64,
            failures,
        })
    }
}

/// Hands the broadcasts `client` hears to `on_event` until its connection fails or the
/// cluster is no longer used.
fn relay(
    client: &mut postgres::Client,
    cluster: &Weak<Cluster>,
    holder: &str,
    on_event: &dyn Fn(Event),
) {
    loop {
        {
            let mut notifications = client.notifications();
            let mut waiting = notifications.timeout_iter(Duration::from_secs(1));
            loop {
                match waiting.next() {
                    Ok(Some(notification)) => match parse_event(notification.payload()) {
                        Some((from, _)) if from == holder => {}
                        Some((_, event)) => on_event(event),
                        None => tracing::warn!(
                            payload = notification.payload(),
                            "a broadcast not understood; ignored"
                        ),
                    },
                    Ok(None) => break,
                    Err(error) => {
                        tracing::warn!(%error, "the cluster's broadcasts were cut off; listening again");
                        return;
                    }
                }
            }
        }
        if client.is_closed() || cluster.strong_count() == 0 {
            return;
        }
    }
}

/// A key as broadcast: `Z/X/Y` and the format's name.
fn key_value(key: &TileKey) -> Value {
    json!([key.tile.to_string(), key.format.as_str()])
}

fn key_from(value: &Value) -> Option<TileKey> {
    let tile: TileId = value.get(0)?.as_str()?.parse().ok()?;
    let format = Format::from_name(value.get(1)?.as_str()?)?;
    Some(TileKey { tile, format })
}

/// The payloads that tell `event` from `holder`, each within `NOTIFY`'s limit: a long list of
/// keys is cut into several; a purge of a list too long for one says "all" (every process then
/// drops its whole memory, which costs lookups, never a stale tile).
fn payloads(holder: &str, event: &Event) -> Vec<String> {
    match event {
        Event::Stored(keys) => {
            let mut payloads = Vec::new();
            let mut part: Vec<Value> = Vec::new();
            let mut length = 0;
            for key in keys {
                let value = key_value(key);
                let size = value.to_string().len() + 1;
                if length + size > PAYLOAD_LIMIT - 200 && !part.is_empty() {
                    payloads.push(json!({ "from": holder, "stored": part }).to_string());
                    part = Vec::new();
                    length = 0;
                }
                length += size;
                part.push(value);
            }
            if !part.is_empty() {
                payloads.push(json!({ "from": holder, "stored": part }).to_string());
            }
            payloads
        }
        Event::Purged(filter) => {
            let purged = match filter {
                TileFilter::All => json!("all"),
                TileFilter::Range(r) => {
                    json!({ "range": [r.z, r.min_x, r.min_y, r.max_x, r.max_y] })
                }
                TileFilter::Tiles(tiles) => {
                    json!({ "tiles": tiles.iter().map(|t| t.to_string()).collect::<Vec<_>>() })
                }
            };
            let payload = json!({ "from": holder, "purged": purged }).to_string();
            if payload.len() <= PAYLOAD_LIMIT {
                vec![payload]
            } else {
                vec![json!({ "from": holder, "purged": "all" }).to_string()]
            }
        }
        Event::Work => vec![json!({ "from": holder, "work": true }).to_string()],
        Event::Missed => Vec::new(),
    }
}

/// The sender and event of a payload.
fn parse_event(payload: &str) -> Option<(String, Event)> {
    let value: Value = serde_json::from_str(payload).ok()?;
    let from = value.get("from")?.as_str()?.to_string();
    if let Some(stored) = value.get("stored") {
        let keys = stored.as_array()?.iter().filter_map(key_from).collect();
        return Some((from, Event::Stored(keys)));
    }
    if let Some(purged) = value.get("purged") {
        let filter = if purged.as_str() == Some("all") {
            TileFilter::All
        } else if let Some(range) = purged.get("range") {
            let n = |i: usize| range.get(i).and_then(Value::as_u64);
            TileFilter::Range(TileRange {
                z: u8::try_from(n(0)?).ok()?,
                min_x: u32::try_from(n(1)?).ok()?,
                min_y: u32::try_from(n(2)?).ok()?,
                max_x: u32::try_from(n(3)?).ok()?,
                max_y: u32::try_from(n(4)?).ok()?,
            })
        } else {
            let tiles = purged.get("tiles")?.as_array()?;
            TileFilter::tiles(
                tiles
                    .iter()
                    .filter_map(|t| t.as_str()?.parse().ok())
                    .collect(),
            )
        };
        return Some((from, Event::Purged(filter)));
    }
    value.get("work").map(|_| (from, Event::Work))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(x: u32) -> TileKey {
        TileKey {
            tile: TileId { z: 14, x, y: 5974 },
            format: Format::GLB,
        }
    }

    #[test]
    fn broadcasts_read_back_as_they_were_sent() {
        let range = TileRange {
            z: 14,
            min_x: 1,
            max_x: 3,
            min_y: 4,
            max_y: 9,
        };
        for event in [
            Event::Stored(vec![key(1), key(2)]),
            Event::Purged(TileFilter::All),
            Event::Purged(TileFilter::Range(range)),
            Event::Purged(TileFilter::tiles(vec![key(5).tile, key(3).tile])),
            Event::Work,
        ] {
            let payloads = payloads("a:1:0", &event);
            assert_eq!(payloads.len(), 1);
            assert_eq!(
                parse_event(&payloads[0]),
                Some(("a:1:0".to_string(), event))
            );
        }
        assert_eq!(parse_event("{\"from\": \"a\"}"), None);
        assert_eq!(parse_event("not json"), None);
    }

    #[test]
    fn long_broadcasts_stay_within_the_notify_limit() {
        let keys: Vec<TileKey> = (0..2_000).map(key).collect();
        let payloads = payloads("a:1:0", &Event::Stored(keys.clone()));
        assert!(payloads.len() > 1);
        assert!(payloads.iter().all(|p| p.len() <= PAYLOAD_LIMIT));
        let told: Vec<TileKey> = payloads
            .iter()
            .flat_map(|p| match parse_event(p) {
                Some((_, Event::Stored(keys))) => keys,
                _ => Vec::new(),
            })
            .collect();
        assert_eq!(told, keys);
        // A purge of too long a list says "all".
        let purge = Event::Purged(TileFilter::tiles(keys.iter().map(|k| k.tile).collect()));
        let payloads = payloads_of(&purge);
        assert_eq!(payloads.len(), 1);
        assert_eq!(
            parse_event(&payloads[0]).map(|(_, e)| e),
            Some(Event::Purged(TileFilter::All))
        );
    }

    fn payloads_of(event: &Event) -> Vec<String> {
        payloads("a:1:0", event)
    }
}
