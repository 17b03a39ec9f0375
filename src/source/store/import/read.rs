//! Phase 1, **read**: each extract once, block by block, decoded over the cores while the
//! previous batch is written; node positions to the node file, tagged nodes, raw ways and
//! relations to SQLite, the first extract listed winning where several hold an element.

use super::*;

/// The node file: written while nodes come, read once ways come.
pub(super) enum Nodes {
    Writing(NodeWriter),
    Reading(Resolver),
    /// Between the two.
    Closed,
}

impl Nodes {
    /// Ends writing, once; the nodes can be read.
    pub(super) fn resolver(&mut self) -> Result<&mut Resolver, ImportError> {
        if let Nodes::Writing(_) = self {
            if let Nodes::Writing(writer) = std::mem::replace(self, Nodes::Closed) {
                *self = Nodes::Reading(Resolver::new(writer.finish()?)?);
            }
        }
        match self {
            Nodes::Reading(resolver) => Ok(resolver),
            _ => Err(Nodes::closed()),
        }
    }

    pub(super) fn into_resolver(mut self) -> Result<Resolver, ImportError> {
        self.resolver()?;
        match self {
            Nodes::Reading(resolver) => Ok(resolver),
            _ => Err(Nodes::closed()),
        }
    }

    /// A node file whose writing failed is not read.
    pub(super) fn closed() -> ImportError {
        ImportError::NodeFile(NodeStoreError::Io {
            path: PathBuf::new(),
            source: std::io::Error::other("the node file was not finished"),
        })
    }
}

/// One block's elements, ready to write.
#[derive(Default)]
pub(super) struct Rows {
    pub(super) header: Option<Bounds>,
    /// Whether the header says the extract is sorted by type, then id.
    pub(super) sorted: bool,
    /// A block of data (not the header).
    pub(super) data: bool,
    /// Relations read, kept or not.
    pub(super) relations_read: u64,
    /// The replication sequence the extract is current to, when its header says.
    pub(super) sequence: Option<u64>,
    pub(super) nodes: Vec<NodeRow>,
    pub(super) ways: Vec<(i64, Vec<u8>)>,
    pub(super) relations: Vec<(i64, Vec<u8>)>,
}

pub(super) struct NodeRow {
    pub(super) id: i64,
    pub(super) at: Decimicro,
    pub(super) position: LonLat,
    /// Its tags' row, when it has tags.
    pub(super) tags: Option<Vec<u8>>,
    /// Whether it reaches into the ground (and may stand over a tunnel).
    pub(super) deep: bool,
}

pub(super) enum RowsError {
    Pbf(String),
    Nodes(NodeStoreError),
}

/// Blobs decoded at once, spread over the cores.
pub(super) const BATCH: usize = 32;

/// Decodes a blob into rows.
pub(super) fn rows_of(blob: &osmpbf::Blob, rules: &Rules) -> Result<Rows, RowsError> {
    let mut rows = Rows::default();
    match blob.decode().map_err(|e| RowsError::Pbf(e.to_string()))? {
        BlobDecode::OsmHeader(header) => {
            rows.header = crate::source::osm_pbf::bounds_in(&header);
            rows.sorted = header
                .optional_features()
                .iter()
                .any(|f| f == crate::source::osm_pbf::SORTED_BY_TYPE);
            rows.sequence = header
                .osmosis_replication_sequence_number()
                .and_then(|s| u64::try_from(s).ok());
        }
        BlobDecode::OsmData(block) => {
            rows.data = true;
            for element in block.elements() {
                let (id, nano, position, tags) = match &element {
                    Element::Node(n) => (
                        n.id(),
                        (n.nano_lon(), n.nano_lat()),
                        LonLat {
                            lon: n.lon(),
                            lat: n.lat(),
                        },
                        Tags::from_pairs(n.tags()),
                    ),
                    Element::DenseNode(n) => (
                        n.id(),
                        (n.nano_lon(), n.nano_lat()),
                        LonLat {
                            lon: n.lon(),
                            lat: n.lat(),
                        },
                        Tags::from_pairs(n.tags()),
                    ),
                    Element::Way(way) => {
                        let tags = Tags::from_pairs(way.tags());
                        let refs: Vec<i64> = way.refs().collect();
                        rows.ways
                            .push((way.id(), codec::encode_raw_way(&tags, &refs)));
                        continue;
                    }
                    Element::Relation(relation) => {
                        rows.relations_read += 1;
                        let relation = crate::source::osm_pbf::relation_of(relation);
                        if !(rules.relation)(&relation.tags) {
                            continue;
                        }
                        rows.relations
                            .push((relation.id, codec::encode_relation(&relation)));
                        continue;
                    }
                };
                let at = Decimicro::from_nano(id, nano.0, nano.1).map_err(RowsError::Nodes)?;
                let element_tags = tags;
                let tags = (!element_tags.is_empty()).then(|| {
                    let mut w = codec::Writer::default();
                    w.tags(&element_tags);
                    w.0
                });
                rows.nodes.push(NodeRow {
                    id,
                    at,
                    position,
                    deep: tags.is_some() && (rules.depth)(&element_tags).is_some(),
                    tags,
                });
            }
        }
        BlobDecode::Unknown(_) => {}
    }
    Ok(rows)
}

/// Decodes blobs on every core, in their order.
pub(super) fn decode_all(
    blobs: &[(u64, osmpbf::Blob)],
    rules: &Rules,
) -> Vec<Result<Rows, (u64, RowsError)>> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let per_thread = blobs.len().div_ceil(threads.max(1)).max(1);
    std::thread::scope(|scope| {
        let workers: Vec<_> = blobs
            .chunks(per_thread)
            .map(|chunk| {
                scope.spawn(move || {
                    chunk
                        .iter()
                        .map(|(offset, blob)| rows_of(blob, rules).map_err(|e| (*offset, e)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| {
                w.join().unwrap_or_else(|_| {
                    vec![Err((
                        0,
                        RowsError::Pbf("decoding a block panicked".to_string()),
                    ))]
                })
            })
            .collect()
    })
}

/// One extract being read: a thread reads and decodes its blocks (on every core), writes the
/// node file and resolves the ways, while this one writes the store.
pub(super) struct Reading<'a> {
    pub(super) partial: &'a Partial,
    pub(super) decoder: Decoder<'a>,
}

/// What the decoding thread hands the store's: a batch of blocks decoded (only the tagged
/// nodes kept), their ways resolved when they come after every node.
pub(super) struct Decoded {
    pub(super) rows: Vec<Rows>,
    pub(super) resolved: Vec<Resolved>,
    /// Nodes and resolved ways in the batch.
    pub(super) nodes: u64,
    pub(super) ways: u64,
    /// Bytes of the extract read so far.
    pub(super) read: u64,
}

/// What the decoding thread found of the whole extract.
#[derive(Default)]
pub(super) struct Decoding {
    pub(super) header: Option<Bounds>,
    pub(super) extent: Option<Bounds>,
    pub(super) sequence: Option<u64>,
    pub(super) read: ExtractRead,
}

/// Reads and decodes one extract's blocks.
pub(super) struct Decoder<'a> {
    pub(super) path: &'a Path,
    pub(super) rules: &'a Rules,
    pub(super) n: f64,
    /// Whether its ways are resolved as they come (all its nodes come before them).
    pub(super) one_pass: bool,
}

impl Decoder<'_> {
    pub(super) fn failed(&self, offset: u64, error: RowsError) -> ImportError {
        match error {
            RowsError::Pbf(message) => ImportError::Pbf {
                path: self.path.to_path_buf(),
                offset,
                message,
            },
            RowsError::Nodes(source) => ImportError::Nodes {
                path: self.path.to_path_buf(),
                source,
            },
        }
    }

    pub(super) fn unsorted(&self) -> ImportError {
        ImportError::Unsorted {
            path: self.path.to_path_buf(),
        }
    }

    /// Decodes the blocks `reader` gives, a batch at a time, and sends them on `send` until
    /// the extract ends or the receiver hangs up.
    pub(super) fn run<R: Read + Send>(
        &self,
        mut reader: BlobReader<R>,
        read: &AtomicU64,
        nodes: &mut Nodes,
        send: std::sync::mpsc::SyncSender<Decoded>,
    ) -> Result<Decoding, ImportError> {
        let mut found = Decoding::default();
        let mut last_way = None;
        loop {
            let mut batch = Vec::with_capacity(BATCH);
            while batch.len() < BATCH {
                let offset = read.load(Ordering::Relaxed);
                let Some(blob) = reader.next() else { break };
                let blob = blob.map_err(|e| self.failed(offset, RowsError::Pbf(e.to_string())))?;
                batch.push((offset, blob));
            }
            if batch.is_empty() {
                return Ok(found);
            }
            let mut decoded = Decoded {
                rows: Vec::with_capacity(batch.len()),
                resolved: Vec::new(),
                nodes: 0,
                ways: 0,
                read: 0,
            };
            let mut batch_ways = Vec::new();
            for rows in decode_all(&batch, self.rules) {
                let mut rows = rows.map_err(|(offset, e)| self.failed(offset, e))?;
                found.header = rows.header.or(found.header);
                found.sequence = rows.sequence.or(found.sequence);
                found.read.sorted |= rows.sorted;
                found.read.blocks += u64::from(rows.data);
                found.read.nodes += rows.nodes.len() as u64;
                found.read.ways += rows.ways.len() as u64;
                found.read.relations += rows.relations_read;
                if self.one_pass && last_way.is_some() && !rows.nodes.is_empty() {
                    return Err(self.unsorted());
                }
                if self.one_pass {
                    for &(id, _) in &rows.ways {
                        if last_way.is_some_and(|last| id <= last) {
                            return Err(self.unsorted());
                        }
                        last_way = Some(id);
                    }
                    batch_ways.append(&mut rows.ways);
                }
                if !rows.nodes.is_empty() {
                    let Nodes::Writing(node_writer) = nodes else {
                        return Err(self.unsorted());
                    };
                    for node in &rows.nodes {
                        node_writer.push(node.id, node.at)?;
                        crate::source::osm_pbf::grow(&mut found.extent, node.position);
                    }
                    decoded.nodes += rows.nodes.len() as u64;
                    rows.nodes.retain(|node| node.tags.is_some());
                }
                decoded.rows.push(rows);
            }
            if !batch_ways.is_empty() {
                decoded.ways = batch_ways.len() as u64;
                decoded.resolved = nodes.resolver()?.resolve(&batch_ways, self.n, self.rules)?;
            }
            decoded.read = read.load(Ordering::Relaxed);
            if send.send(decoded).is_err() {
                // The store's thread stopped, with an error of its own.
                return Ok(found);
            }
        }
    }
}

impl Reading<'_> {
    /// Reads the extract: node positions to the node file, the rest to the store.
    pub(super) fn extract(
        &mut self,
        nodes: &mut Nodes,
        ways: &mut ResolvedWriter,
        state: &mut Progress,
        progress: &dyn Fn(&Progress),
    ) -> Result<(ExtractRecord, ExtractRead), ImportError> {
        use sha2::Digest;
        let path = self.decoder.path;
        let file = std::fs::File::open(path).map_err(|source| ImportError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        let read = Arc::new(AtomicU64::new(0));
        let digest = Arc::new(std::sync::Mutex::new(sha2::Sha256::new()));
        let counting = Counting {
            inner: std::io::BufReader::with_capacity(1 << 20, file),
            read: read.clone(),
            digest: digest.clone(),
        };
        let before = state.bytes;
        let reader = BlobReader::new(counting);
        // The version the store records is the one read: taken before, checked after.
        let file_version = crate::source::srtm::file_version(path).unwrap_or_default();
        let sqlite = self.partial.sqlite();
        self.partial.db.execute_batch("BEGIN").map_err(&sqlite)?;
        let found = std::thread::scope(|scope| {
            // Two batches in flight: one being decoded while one is written.
            let (send, receive) = std::sync::mpsc::sync_channel(1);
            let decoder = &self.decoder;
            let decoding = scope.spawn(move || decoder.run(reader, &read, nodes, send));
            let written = self.write_decoded(receive, ways, before, state, progress);
            let found = decoding.join().map_err(|_| ImportError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other("decoding the extract panicked"),
            });
            // The store's error first: the decoder only stops early because of it.
            written?;
            found?
        })?;
        self.partial.db.execute_batch("COMMIT").map_err(&sqlite)?;
        let digest = std::mem::take(&mut *digest.lock().unwrap_or_else(|p| p.into_inner()));
        let digest: String = digest.finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        let read = ExtractRead {
            path: path.to_path_buf(),
            ..found.read
        };
        if let Some(why) = read.cut_short() {
            return Err(ImportError::CutShort {
                path: path.to_path_buf(),
                why,
            });
        }
        let bounds = found
            .header
            .or(found.extent)
            .ok_or_else(|| ImportError::Empty {
                path: path.to_path_buf(),
            })?;
        if crate::source::srtm::file_version(path).unwrap_or_default() != file_version {
            return Err(ImportError::Changed {
                path: path.to_path_buf(),
            });
        }
        let record = ExtractRecord {
            // Absolute, so the store is found current whichever directory a later command
            // runs in (a relative path would name another file there, and the store would be
            // imported again, losing the diffs applied to it).
            path: std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            digest,
            file_version,
            bounds: [bounds.west, bounds.south, bounds.east, bounds.north],
            replication_sequence: found.sequence,
        };
        Ok((record, read))
    }

    /// Writes what the decoder sends, as it comes; returns at its first error (dropping
    /// `receive`, which stops the decoder).
    pub(super) fn write_decoded(
        &self,
        receive: std::sync::mpsc::Receiver<Decoded>,
        ways: &mut ResolvedWriter,
        before: u64,
        state: &mut Progress,
        progress: &dyn Fn(&Progress),
    ) -> Result<(), ImportError> {
        let mut writer = RowWriter::new(self.partial)?;
        for decoded in receive {
            for rows in decoded.rows {
                writer.write(rows, state)?;
            }
            for resolved in &decoded.resolved {
                ways.write(resolved)?;
            }
            state.nodes += decoded.nodes;
            state.ways += decoded.ways;
            state.bytes = before + decoded.read;
            progress(state);
        }
        ways.flush()
    }
}

/// Writes decoded rows: where an element is already stored (from an extract listed before),
/// the first one stays. Raw ways are kept to be resolved when all nodes are read, unless they
/// were taken to be resolved at once.
pub(super) struct RowWriter<'a> {
    pub(super) partial: &'a Partial,
    pub(super) node: rusqlite::Statement<'a>,
    pub(super) node_part: rusqlite::Statement<'a>,
    pub(super) way: rusqlite::Statement<'a>,
    pub(super) relation: rusqlite::Statement<'a>,
}

impl<'a> RowWriter<'a> {
    pub(super) fn new(partial: &'a Partial) -> Result<RowWriter<'a>, ImportError> {
        let sqlite = partial.sqlite();
        let prepare = |sql: &str| partial.db.prepare(sql).map_err(&sqlite);
        Ok(RowWriter {
            partial,
            node: prepare(
                "INSERT OR IGNORE INTO nodes (id, lon, lat, tags) VALUES (?1, ?2, ?3, ?4)",
            )?,
            node_part: prepare("INSERT OR IGNORE INTO node_parts (id) VALUES (?1)")?,
            way: prepare("INSERT OR IGNORE INTO raw_ways (id, data) VALUES (?1, ?2)")?,
            relation: prepare("INSERT OR IGNORE INTO relations (id, data) VALUES (?1, ?2)")?,
        })
    }

    /// Writes the tagged nodes, raw ways and relations of `rows`.
    pub(super) fn write(&mut self, rows: Rows, state: &mut Progress) -> Result<(), ImportError> {
        let sqlite = self.partial.sqlite();
        for node in rows.nodes {
            if let Some(tags) = node.tags {
                let p = node.position;
                self.node
                    .execute(params![node.id, p.lon, p.lat, tags])
                    .map_err(&sqlite)?;
                if node.deep {
                    self.node_part.execute(params![node.id]).map_err(&sqlite)?;
                }
            }
        }
        for (id, row) in rows.ways {
            self.way.execute(params![id, row]).map_err(&sqlite)?;
            state.ways += 1;
        }
        for (id, row) in rows.relations {
            self.relation.execute(params![id, row]).map_err(&sqlite)?;
            state.relations += 1;
        }
        Ok(())
    }
}
