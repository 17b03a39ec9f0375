//! Phase 3, **find once over all the data** what a tile needs from beyond itself: the joints
//! of the road network, and the bridge and tunnel groups, a cluster of structure ways at a
//! time with what they may cross and what reaches into the ground near them.

use super::*;

/// The joints: nodes the road network's ways meet more than once (`refs`: each way's node
/// references, as (node, way)), with the ways through each; and for each way, its joints with
/// the ways through them. Returns how many joints there are.
pub(super) fn find_joints(partial: &Partial, refs: ExternalSort<2>) -> Result<u64, ImportError> {
    let (sqlite, io) = (partial.sqlite(), partial.io());
    let db = &partial.db;
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    // (way, joint, a way through it), for each way through each joint.
    let mut facts = ExternalSort::<3>::new(&partial.path, RUN_RECORDS);
    let mut joints = 0u64;
    {
        let mut insert = db
            .prepare("INSERT INTO joints (node, way) VALUES (?1, ?2)")
            .map_err(&sqlite)?;
        let mut joint = |node: i64, ways: &mut Vec<i64>| -> Result<(), ImportError> {
            if ways.len() > 1 {
                ways.dedup();
                for &way in ways.iter() {
                    insert.execute(params![node, way]).map_err(&sqlite)?;
                    for &through in ways.iter() {
                        facts.push([way, node, through]).map_err(&io)?;
                    }
                }
                joints += 1;
            }
            ways.clear();
            Ok(())
        };
        let mut current: Option<i64> = None;
        let mut ways = Vec::new();
        for r in refs.sorted().map_err(&io)? {
            let [node, way] = r.map_err(&io)?;
            if let Some(before) = current.filter(|&c| c != node) {
                joint(before, &mut ways)?;
            }
            current = Some(node);
            ways.push(way);
        }
        if let Some(node) = current {
            joint(node, &mut ways)?;
        }
    }
    {
        let mut insert = db
            .prepare("INSERT INTO way_facts (way, joints) VALUES (?1, ?2)")
            .map_err(&sqlite)?;
        let mut current: Option<(i64, codec::WayJoints)> = None;
        for fact in facts.sorted().map_err(&io)? {
            let [way, node, through] = fact.map_err(&io)?;
            if current.as_ref().is_some_and(|(w, _)| *w != way) {
                if let Some((w, joints)) = current.take() {
                    insert
                        .execute(params![w, codec::encode_joints(&joints)])
                        .map_err(&sqlite)?;
                }
            }
            let (_, joints) = current.get_or_insert_with(|| (way, Vec::new()));
            match joints.last_mut() {
                Some((n, ways)) if *n == node => ways.push(through),
                _ => joints.push((node, vec![through])),
            }
        }
        if let Some((w, joints)) = current {
            insert
                .execute(params![w, codec::encode_joints(&joints)])
                .map_err(&sqlite)?;
        }
    }
    db.execute_batch("COMMIT").map_err(&sqlite)?;
    Ok(joints)
}

/// A group found, ready to store: its place in the order of the whole data (its smallest
/// structure way id), its row, its box, and where its bridges pass over ways.
pub(in crate::source::store) struct FoundGroup {
    pub first_way: i64,
    pub row: Vec<u8>,
    pub bounds: Bounds,
    pub under: std::collections::HashMap<i64, Vec<LonLat>>,
}

/// Finds the bridge and tunnel groups, a cluster of nearby structure ways at a time, among
/// the elements near them, and stores them in the order the whole data's index finds them,
/// with where bridges pass over ways; returns how many groups there are.
///
/// A group's chains share nodes or cross, so its ways' boxes meet: the clusters of structure
/// ways whose boxes (grown by what may stand over a tunnel) overlap hold whole groups, and
/// memory holds one cluster's surroundings at a time.
pub(super) fn find_structures(
    partial: &Partial,
    structure_ways: &[i64],
    zoom: u8,
    rules: &Rules,
) -> Result<u64, ImportError> {
    let n = f64::from(1u32 << zoom);
    // The store is read for one cluster while the groups of the one before are found.
    let clusters = batches(clusters(&partial.db, structure_ways, n, rules)?);
    // Found on every core (their order is restored below).
    let finders = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (send, receive) = std::sync::mpsc::sync_channel::<(&Cluster, OsmData)>(finders);
    let receive = std::sync::Mutex::new(receive);
    let receive = &receive;
    let mut found: Vec<FoundGroup> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..finders)
            .map(|_| {
                scope.spawn(move || {
                    let mut found = Vec::new();
                    loop {
                        let next = receive.lock().unwrap_or_else(|p| p.into_inner()).recv();
                        let Ok((cluster, data)) = next else { break };
                        found.extend(cluster.groups(data, zoom, rules));
                    }
                    found
                })
            })
            .collect();
        for cluster in &clusters {
            let data = cluster_data(
                &partial.db,
                &partial.path,
                cluster,
                rules,
                Candidates::Marked,
            )?;
            if send.send((cluster, data)).is_err() {
                break;
            }
        }
        drop(send);
        let mut found = Vec::new();
        for worker in workers {
            found.extend(worker.join().map_err(|_| ImportError::Io {
                path: partial.path.clone(),
                source: std::io::Error::other("finding bridge and tunnel groups panicked"),
            })?);
        }
        Ok::<_, ImportError>(found)
    })?;
    found.sort_by_key(|g| g.first_way);
    let sqlite = partial.sqlite();
    let db = &partial.db;
    let mut under: std::collections::HashMap<i64, Vec<LonLat>> = Default::default();
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    {
        let mut insert_group = db
            .prepare("INSERT INTO groups (id, data) VALUES (?1, ?2)")
            .map_err(&sqlite)?;
        let mut insert_cell = db
            .prepare("INSERT INTO cells (x, y, kind, id) VALUES (?1, ?2, 3, ?3)")
            .map_err(&sqlite)?;
        let mut insert_under = db
            .prepare("INSERT INTO group_under (way, grp, positions) VALUES (?1, ?2, ?3)")
            .map_err(&sqlite)?;
        for group in &found {
            let g = group.first_way;
            insert_group
                .execute(params![g, group.row])
                .map_err(&sqlite)?;
            for (x, y) in cells_of(&group.bounds, n) {
                insert_cell.execute(params![x, y, g]).map_err(&sqlite)?;
            }
            let mut ways: Vec<_> = group.under.iter().collect();
            ways.sort_by_key(|(way, _)| **way);
            for (way, positions) in ways {
                under.entry(*way).or_default().extend(positions);
                insert_under
                    .execute(params![way, g, codec::encode_positions(positions)])
                    .map_err(&sqlite)?;
            }
        }
        let mut insert_under = db
            .prepare(
                "INSERT INTO way_facts (way, under_bridges) VALUES (?1, ?2)
                 ON CONFLICT (way) DO UPDATE SET under_bridges = excluded.under_bridges",
            )
            .map_err(&sqlite)?;
        for (way, positions) in &under {
            insert_under
                .execute(params![way, codec::encode_positions(positions)])
                .map_err(&sqlite)?;
        }
    }
    db.execute_batch("COMMIT").map_err(&sqlite)?;
    Ok(found.len() as u64)
}

/// The cells of a cluster of structure ways: those their boxes meet, grown by what may stand
/// over a tunnel, and among them those near its tunnels.
#[derive(Debug, Default)]
pub(in crate::source::store) struct Cluster {
    /// Its structure ways.
    pub ways: BTreeSet<i64>,
    pub cells: BTreeSet<(u32, u32)>,
    pub near_tunnels: BTreeSet<(u32, u32)>,
    /// In each cell, the grown boxes of its structure ways there.
    pub boxes: BTreeMap<(u32, u32), Vec<Bounds>>,
}

impl Cluster {
    /// The groups of the cluster's ways among what was read around them (the same cells may
    /// hold ways of other clusters, whose groups are found with theirs).
    pub fn groups(&self, data: OsmData, zoom: u8, rules: &Rules) -> Vec<FoundGroup> {
        let mut groups = found_groups(data, zoom, rules);
        groups.retain(|g| self.ways.contains(&g.first_way));
        groups
    }
}

/// The clusters of structure ways: ways whose boxes, grown by what may stand over a tunnel,
/// overlap are in one cluster (a group's ways share nodes or cross, so their boxes meet).
pub(in crate::source::store) fn clusters(
    db: &Connection,
    structure_ways: &[i64],
    n: f64,
    rules: &Rules,
) -> Result<Vec<Cluster>, ImportError> {
    use crate::osm::structures::StructureKind;
    // Each way's grown box and whether it is a tunnel.
    let mut grown: Vec<(i64, Bounds, bool)> = Vec::with_capacity(structure_ways.len());
    for &id in structure_ways {
        let Some(way) = super::super::way(db, id)? else {
            continue;
        };
        let tunnel = matches!(
            (rules.classify)(&way.tags),
            Some((StructureKind::Tunnel, _))
        );
        if let Some(b) = bounds_of(&way.positions) {
            grown.push((id, b.expanded(crate::osm::index::ABOVE_TUNNEL_DEG), tunnel));
        }
    }
    let mut sets = DisjointSets::new(grown.len());
    // The cells find the pairs that may overlap; their boxes decide.
    let mut in_cell: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, (_, b, _)) in grown.iter().enumerate() {
        for cell in cells_of(b, n) {
            let others = in_cell.entry(cell).or_default();
            for &other in others.iter() {
                if meets(b, &grown[other].1) {
                    sets.union(i, other);
                }
            }
            others.push(i);
        }
    }
    let mut by_root: BTreeMap<usize, Cluster> = BTreeMap::new();
    for (i, (id, b, tunnel)) in grown.iter().enumerate() {
        let cluster = by_root.entry(sets.find(i)).or_default();
        cluster.ways.insert(*id);
        let cells: Vec<(u32, u32)> = cells_of(b, n).collect();
        if *tunnel {
            cluster.near_tunnels.extend(cells.iter().copied());
        }
        for &cell in &cells {
            cluster.boxes.entry(cell).or_default().push(*b);
        }
        cluster.cells.extend(cells);
    }
    Ok(by_root.into_values().collect())
}

/// Clusters that share a cell, merged: the import reads each cell's elements once for all
/// the clusters there.
pub(super) fn batches(clusters: Vec<Cluster>) -> Vec<Cluster> {
    let mut sets = DisjointSets::new(clusters.len());
    let mut owner: HashMap<(u32, u32), usize> = HashMap::new();
    for (i, cluster) in clusters.iter().enumerate() {
        for cell in &cluster.cells {
            match owner.get(cell) {
                Some(&other) => sets.union(i, other),
                None => {
                    owner.insert(*cell, i);
                }
            }
        }
    }
    let mut merged: BTreeMap<usize, Cluster> = BTreeMap::new();
    for (i, cluster) in clusters.into_iter().enumerate() {
        let batch = merged.entry(sets.find(i)).or_default();
        batch.ways.extend(cluster.ways);
        batch.cells.extend(cluster.cells);
        batch.near_tunnels.extend(cluster.near_tunnels);
        for (cell, boxes) in cluster.boxes {
            batch.boxes.entry(cell).or_default().extend(boxes);
        }
    }
    merged.into_values().collect()
}

/// Disjoint sets of indices.
pub(super) struct DisjointSets(Vec<usize>);

impl DisjointSets {
    pub(super) fn new(n: usize) -> DisjointSets {
        DisjointSets((0..n).collect())
    }

    pub(super) fn find(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }

    pub(super) fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        self.0[a] = b;
    }
}

/// Which of a cell's elements are read to find groups.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(in crate::source::store) enum Candidates {
    /// Every one (the store as a diff finds it).
    Every,
    /// Those the import marked as able to take part (its `parts` and `node_parts`).
    Marked,
}

impl Candidates {
    /// The query of a cell's nodes and ways: `kind`, `id`, whether it takes part only near
    /// tunnels, and a way's box when known.
    pub(super) fn query(self) -> &'static str {
        match self {
            Candidates::Every => {
                "SELECT kind, id, 0, NULL, NULL, NULL, NULL FROM cells
                     WHERE x = ?1 AND y = ?2 AND kind < 2"
            }
            Candidates::Marked => {
                "SELECT c.kind, c.id, p.near_tunnels, p.west, p.south, p.east, p.north
                     FROM cells c JOIN parts p ON p.id = c.id
                     WHERE c.x = ?1 AND c.y = ?2 AND c.kind = 1
                 UNION ALL
                 SELECT c.kind, c.id, 1, NULL, NULL, NULL, NULL
                     FROM cells c JOIN node_parts p ON p.id = c.id
                     WHERE c.x = ?1 AND c.y = ?2 AND c.kind = 0"
            }
        }
    }
}

/// What can take part in a cluster's groups: the structure ways, the ways they may cross, and
/// near tunnels what reaches down into the ground.
pub(in crate::source::store) fn cluster_data(
    db: &Connection,
    path: &Path,
    cluster: &Cluster,
    rules: &Rules,
    candidates: Candidates,
) -> Result<OsmData, ImportError> {
    use crate::osm::structures::may_be_crossed;
    let sqlite = |source| ImportError::Sqlite {
        path: path.to_path_buf(),
        source,
    };
    // Each element in the cluster's cells, and whether it is near a tunnel.
    let mut way_ids: Vec<(i64, bool)> = Vec::new();
    let mut node_ids: Vec<(i64, bool)> = Vec::new();
    {
        let mut in_cell = db.prepare_cached(candidates.query()).map_err(&sqlite)?;
        for &cell in &cluster.cells {
            let tunnel = cluster.near_tunnels.contains(&cell);
            let structures = cluster.boxes.get(&cell).map_or(&[][..], Vec::as_slice);
            let rows = in_cell
                .query_map(params![cell.0, cell.1], |row| {
                    let bounds = match row.get::<_, Option<f64>>(3)? {
                        Some(west) => Some(Bounds {
                            west,
                            south: row.get(4)?,
                            east: row.get(5)?,
                            north: row.get(6)?,
                        }),
                        None => None,
                    };
                    Ok((
                        row.get::<_, i64>(0)?,
                        row.get::<_, i64>(1)?,
                        row.get::<_, bool>(2)?,
                        bounds,
                    ))
                })
                .map_err(&sqlite)?;
            for row in rows {
                let (kind, id, near_tunnels_only, bounds) = row.map_err(&sqlite)?;
                // One near tunnels only is left out where there are none (were it near one
                // in another cell, that cell gives it), and a way whose box meets no grown box
                // of a structure way here (it neither crosses one nor stands over a tunnel;
                // where it meets one in another cell, that cell gives it).
                if near_tunnels_only && !tunnel {
                    continue;
                }
                if bounds.is_some_and(|b| !structures.iter().any(|s| meets(s, &b))) {
                    continue;
                }
                match kind {
                    0 => node_ids.push((id, tunnel)),
                    _ => way_ids.push((id, tunnel)),
                }
            }
        }
    }
    for ids in [&mut way_ids, &mut node_ids] {
        // Near a tunnel in any of its cells counts.
        ids.sort_unstable_by_key(|&(id, tunnel)| (id, !tunnel));
        ids.dedup_by_key(|(id, _)| *id);
    }
    let mut data = OsmData::default();
    for (id, tunnel) in way_ids {
        if let Some(way) = super::super::way(db, id)? {
            let takes_part = (rules.classify)(&way.tags).is_some()
                || may_be_crossed(&way.tags)
                || (tunnel && (rules.depth)(&way.tags).is_some());
            if takes_part {
                data.ways.push(way);
            }
        }
    }
    for (id, tunnel) in node_ids {
        if !tunnel {
            continue;
        }
        if let Some(node) = super::super::node(db, id)? {
            if (rules.depth)(&node.tags).is_some() {
                data.nodes.push(node);
            }
        }
    }
    Ok(data)
}

/// The groups among a cluster's elements, as they will be stored.
pub(super) fn found_groups(data: OsmData, zoom: u8, rules: &Rules) -> Vec<FoundGroup> {
    let index = OsmIndex::new(data, zoom, rules.classify).with_foundations(rules.depth);
    let ways: &[Way] = &index.data().ways;
    let way_id = |i: u32| ways.get(i as usize).map_or(0, |w| w.id);
    index
        .structures()
        .iter()
        .map(|group| FoundGroup {
            first_way: group
                .chains
                .iter()
                .flat_map(|c| c.ways.iter().map(|w| way_id(w.way)))
                .min()
                .unwrap_or(i64::MAX),
            row: codec::encode_group(group, &way_id),
            bounds: group.bounds,
            under: crate::osm::index::under_bridges(ways, std::slice::from_ref(group)),
        })
        .collect()
}

#[cfg(test)]
mod tests;
