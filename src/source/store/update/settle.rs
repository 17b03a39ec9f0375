//! What the diff changes beyond its elements, found again: the joints at the nodes of the
//! road ways it touched, and the bridge and tunnel groups of the clusters it reaches, with
//! the ways that hold them.

use super::*;

impl Update<'_> {
    /// Finds the joints again at every node of the changed ways of the road network, and the
    /// joints of each way through one that changed.
    pub(super) fn settle_joints(
        &mut self,
        plan: &Plan,
        reach: &mut Reach,
    ) -> Result<(), UpdateError> {
        let joins = self.rules.joins;
        let mut touched = BTreeSet::new();
        for edit in plan.ways.values() {
            for way in [edit.old.as_ref(), edit.new.as_ref().map(|(w, _)| w)]
                .into_iter()
                .flatten()
            {
                if joins(&way.tags) {
                    touched.extend(way.nodes.iter().copied());
                }
            }
        }
        let mut changed_ways = BTreeSet::new();
        for node in touched {
            let through_now = self.road_ways_through(node)?;
            let through_before: Vec<i64> = {
                let mut s = self
                    .db
                    .prepare_cached("SELECT way FROM joints WHERE node = ?1 ORDER BY way")
                    .map_err(self.sqlite())?;
                let rows = s.query_map([node], |r| r.get(0)).map_err(self.sqlite())?;
                rows.collect::<Result<_, _>>().map_err(self.sqlite())?
            };
            if through_now == through_before {
                continue;
            }
            self.db
                .execute("DELETE FROM joints WHERE node = ?1", [node])
                .map_err(self.sqlite())?;
            for way in &through_now {
                self.db
                    .execute(
                        "INSERT INTO joints (node, way) VALUES (?1, ?2)",
                        params![node, way],
                    )
                    .map_err(self.sqlite())?;
            }
            changed_ways.extend(through_before);
            changed_ways.extend(through_now);
        }
        for &way in &changed_ways {
            self.write_joints(way)?;
            self.reach_way(way, reach)?;
        }
        self.reach_holders(&changed_ways, reach)?;
        for &way in &plan.joined_before {
            self.reach_way(way, reach)?;
        }
        Ok(())
    }

    /// The ways of the road network through `node` once the diff is applied, when it is a
    /// joint (the node counted more than once among them), ascending.
    pub(super) fn road_ways_through(&mut self, node: i64) -> Result<Vec<i64>, UpdateError> {
        let Some(at) = self.position(node)? else {
            return Ok(Vec::new());
        };
        let (lon, lat) = at.lon_lat();
        let Some(cell) = self.cell_of(LonLat { lon, lat }) else {
            return Ok(Vec::new());
        };
        let joins = self.rules.joins;
        let mut refs = 0;
        let mut through = Vec::new();
        for way in self.ways_after(cell)? {
            if !joins(&way.tags) {
                continue;
            }
            // As the import counts: a node next to itself is a duplicated point.
            let count = way
                .nodes
                .iter()
                .enumerate()
                .filter(|&(k, &n)| n == node && (k == 0 || way.nodes[k - 1] != node))
                .count();
            if count > 0 {
                refs += count;
                through.push(way.id);
            }
        }
        through.sort_unstable();
        Ok(if refs > 1 { through } else { Vec::new() })
    }

    pub(super) fn write_joints(&self, way: i64) -> Result<(), UpdateError> {
        let mut joints: codec::WayJoints = Vec::new();
        {
            let mut s = self
                .db
                .prepare_cached(
                    "SELECT j1.node, j2.way FROM joints j1 JOIN joints j2 ON j2.node = j1.node
                     WHERE j1.way = ?1 ORDER BY j1.node, j2.way",
                )
                .map_err(self.sqlite())?;
            let rows = s
                .query_map([way], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?)))
                .map_err(self.sqlite())?;
            for row in rows {
                let (node, through) = row.map_err(self.sqlite())?;
                match joints.last_mut() {
                    Some((n, ways)) if *n == node => ways.push(through),
                    _ => joints.push((node, vec![through])),
                }
            }
        }
        let row = (!joints.is_empty()).then(|| codec::encode_joints(&joints));
        self.set_fact(way, "joints", row)
    }

    /// Sets one column of a way's facts, dropping the row when it holds none.
    pub(super) fn set_fact(
        &self,
        way: i64,
        column: &str,
        value: Option<Vec<u8>>,
    ) -> Result<(), UpdateError> {
        let sqlite = self.sqlite();
        self.db
            .execute(
                &format!(
                    "INSERT INTO way_facts (way, {column}) VALUES (?1, ?2)
                     ON CONFLICT (way) DO UPDATE SET {column} = excluded.{column}"
                ),
                params![way, value],
            )
            .map_err(&sqlite)?;
        self.db
            .execute(
                "DELETE FROM way_facts WHERE way = ?1 AND joints IS NULL AND under_bridges IS NULL",
                [way],
            )
            .map_err(&sqlite)?;
        Ok(())
    }

    /// Adds a way's box as the store holds it now.
    pub(super) fn reach_way(&self, id: i64, reach: &mut Reach) -> Result<(), UpdateError> {
        let way = super::super::way(self.db, id).map_err(self.decode())?;
        reach.way(way.as_ref());
        Ok(())
    }

    /// Finds again the bridge and tunnel groups of every cluster the changes reach, and
    /// where their bridges pass over ways; returns how many groups were found.
    pub(super) fn settle_groups(
        &mut self,
        plan: &Plan,
        reach: &mut Reach,
    ) -> Result<usize, UpdateError> {
        let mut seeds = BTreeSet::new();
        let mut look = BTreeSet::new();
        // Relations take no part in groups: the nodes and ways changed are what counts.
        let mut changed = Reach::new(self.zoom);
        plan.elements(&mut changed);
        for &(x, y) in &changed.cells {
            let cell = TileId { z: self.zoom, x, y }.bounds();
            look.extend(cells_of(&cell.expanded(ABOVE_TUNNEL_DEG), self.n));
        }
        for edit in plan.ways.values() {
            if let Some(w) = &edit.old {
                if structure_of(self.rules.classify, &w.tags, &w.positions).is_some() {
                    seeds.insert(w.id);
                }
            }
        }
        let classify = self.rules.classify;
        for &cell in &look {
            for way in self.ways_after(cell)? {
                if structure_of(classify, &way.tags, &way.positions).is_some() {
                    seeds.insert(way.id);
                }
            }
        }
        let mut members = BTreeSet::new();
        let mut old_groups: BTreeMap<i64, Vec<u8>> = BTreeMap::new();
        // The groups held before that hold a way found again or changed are found again, with
        // all their ways (a group's box holds its ways, so it is in their cells).
        let mut cells: BTreeSet<(u32, u32)> = BTreeSet::new();
        for edit in plan.ways.values() {
            if let Some(old) = &edit.old {
                cells.extend(cells_of_way(old, self.n));
            }
        }
        loop {
            let before = members.clone();
            self.grow_cluster(&mut seeds, &mut members)?;
            for id in members.difference(&before) {
                if let Some(way) = super::super::way(self.db, *id).map_err(self.decode())? {
                    cells.extend(cells_of_way(&way, self.n));
                }
            }
            let mut more = BTreeSet::new();
            for (id, row) in self.groups_in(&cells)? {
                if old_groups.contains_key(&id) {
                    continue;
                }
                let chain = chain_ways(&row).map_err(self.decode())?;
                let held = chain
                    .iter()
                    .any(|w| members.contains(w) || plan.ways.contains_key(w));
                if !held {
                    continue;
                }
                more.extend(chain.into_iter().filter(|w| !members.contains(w)));
                old_groups.insert(id, row);
            }
            if more.is_empty() {
                break;
            }
            seeds = more;
        }
        let ids: Vec<i64> = members.into_iter().collect();
        let mut new_groups: BTreeMap<i64, FoundGroup> = BTreeMap::new();
        for cluster in clusters(self.db, &ids, self.n, self.rules)? {
            let data = cluster_data(self.db, self.path, &cluster, self.rules, Candidates::Every)?;
            for group in cluster.groups(data, self.zoom, self.rules) {
                new_groups.insert(group.first_way, group);
            }
        }
        let count = new_groups.len();
        self.write_groups(old_groups, new_groups, reach)?;
        Ok(count)
    }

    /// Adds to `members` every structure way linked to `seeds` (their boxes, grown by what
    /// may stand over a tunnel, overlapping), as the import clusters them.
    pub(super) fn grow_cluster(
        &mut self,
        seeds: &mut BTreeSet<i64>,
        members: &mut BTreeSet<i64>,
    ) -> Result<(), UpdateError> {
        let classify = self.rules.classify;
        let grow = |w: &Way| bounds_of(&w.positions).map(|b| b.expanded(ABOVE_TUNNEL_DEG));
        let mut frontier: Vec<i64> = seeds.iter().copied().collect();
        while let Some(id) = frontier.pop() {
            if members.contains(&id) {
                continue;
            }
            let Some(way) = super::super::way(self.db, id).map_err(self.decode())? else {
                continue;
            };
            if structure_of(classify, &way.tags, &way.positions).is_none() {
                continue;
            }
            members.insert(id);
            let Some(grown) = grow(&way) else {
                continue;
            };
            // A way whose grown box meets this one's lies in the cells of this one grown again.
            let near: Vec<(u32, u32)> =
                cells_of(&grown.expanded(ABOVE_TUNNEL_DEG), self.n).collect();
            for cell in near {
                for other in self.ways_after(cell)? {
                    let structure = structure_of(classify, &other.tags, &other.positions);
                    if members.contains(&other.id) || structure.is_none() {
                        continue;
                    }
                    if grow(other).is_some_and(|o| meets(&o, &grown)) {
                        frontier.push(other.id);
                    }
                }
            }
        }
        Ok(())
    }

    /// The groups registered in `cells`, with their rows.
    pub(super) fn groups_in(
        &self,
        cells: &BTreeSet<(u32, u32)>,
    ) -> Result<BTreeMap<i64, Vec<u8>>, UpdateError> {
        let ids = self.in_cells(3, cells)?;
        let mut found = BTreeMap::new();
        for id in ids {
            let row: Option<Vec<u8>> = self
                .db
                .query_row("SELECT data FROM groups WHERE id = ?1", [id], |r| r.get(0))
                .optional()
                .map_err(self.sqlite())?;
            if let Some(row) = row {
                found.insert(id, row);
            }
        }
        Ok(found)
    }

    /// Replaces the groups that changed, and the facts of the ways they pass over.
    pub(super) fn write_groups(
        &mut self,
        old: BTreeMap<i64, Vec<u8>>,
        new: BTreeMap<i64, FoundGroup>,
        reach: &mut Reach,
    ) -> Result<(), UpdateError> {
        let sqlite = self.sqlite();
        let mut under_changed = BTreeSet::new();
        for (&id, row) in &old {
            let bounds = group_bounds(row).map_err(self.decode())?;
            reach.boxes.push(bounds);
            if new.get(&id).is_some_and(|g| g.row == *row) {
                continue;
            }
            self.uncell(3, id, &cells_of(&bounds, self.n).collect::<Vec<_>>())?;
            self.db
                .execute("DELETE FROM groups WHERE id = ?1", [id])
                .map_err(&sqlite)?;
            let mut s = self
                .db
                .prepare_cached("DELETE FROM group_under WHERE grp = ?1 RETURNING way")
                .map_err(&sqlite)?;
            let rows = s.query_map([id], |r| r.get::<_, i64>(0)).map_err(&sqlite)?;
            for way in rows {
                under_changed.insert(way.map_err(&sqlite)?);
            }
        }
        for (&id, group) in &new {
            reach.boxes.push(group.bounds);
            if old.get(&id).is_some_and(|row| *row == group.row) {
                continue;
            }
            self.db
                .execute(
                    "INSERT INTO groups (id, data) VALUES (?1, ?2)",
                    params![id, group.row],
                )
                .map_err(&sqlite)?;
            self.encell(3, id, &cells_of(&group.bounds, self.n).collect::<Vec<_>>())?;
            for (way, positions) in &group.under {
                self.db
                    .execute(
                        "INSERT INTO group_under (way, grp, positions) VALUES (?1, ?2, ?3)",
                        params![way, id, codec::encode_positions(positions)],
                    )
                    .map_err(&sqlite)?;
                under_changed.insert(*way);
            }
        }
        for &way in &under_changed {
            let mut positions: Vec<LonLat> = Vec::new();
            {
                let mut s = self
                    .db
                    .prepare_cached("SELECT positions FROM group_under WHERE way = ?1 ORDER BY grp")
                    .map_err(&sqlite)?;
                let rows = s
                    .query_map([way], |r| r.get::<_, Vec<u8>>(0))
                    .map_err(&sqlite)?;
                for row in rows {
                    let bytes = row.map_err(&sqlite)?;
                    positions.extend(codec::decode_positions(&bytes).map_err(self.decode())?);
                }
            }
            let value = (!positions.is_empty()).then(|| codec::encode_positions(&positions));
            self.set_fact(way, "under_bridges", value)?;
            self.reach_way(way, reach)?;
            // The tiles near the ways joined to it read its facts too.
            for (_, through) in super::super::facts(self.db, way)
                .map_err(self.decode())?
                .joints
            {
                for other in through {
                    self.reach_way(other, reach)?;
                }
            }
        }
        self.reach_holders(&under_changed, reach)?;
        Ok(())
    }

    /// Adds the boxes of the relations that hold one of `ways` and of the groups that name
    /// one: the tiles that read those read the ways' facts.
    pub(super) fn reach_holders(
        &self,
        ways: &BTreeSet<i64>,
        reach: &mut Reach,
    ) -> Result<(), UpdateError> {
        let mut cells = BTreeSet::new();
        for &id in ways {
            if let Some(way) = super::super::way(self.db, id).map_err(self.decode())? {
                cells.extend(cells_of_way(&way, self.n));
            }
        }
        for id in self.in_cells(2, &cells)? {
            let Some(relation) = super::super::relation(self.db, id).map_err(self.decode())? else {
                continue;
            };
            let holds = super::super::relation_ways(self.db, &relation)
                .map_err(self.sqlite())?
                .iter()
                .any(|w| ways.contains(w));
            if holds {
                reach
                    .boxes
                    .extend(relation_bounds(self.db, &relation).map_err(self.decode())?);
            }
        }
        for (_, row) in self.groups_in(&cells)? {
            let mut named = false;
            let group = codec::decode_group(&row, &mut |id| {
                named |= ways.contains(&id);
                Some(0)
            })
            .map_err(self.decode())?;
            if named {
                reach.boxes.push(group.bounds);
            }
        }
        Ok(())
    }
}
