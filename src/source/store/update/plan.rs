//! What a diff changes, planned before anything is written: each node, way and relation it
//! names with what it had, the ways whose nodes move, the elements a diff brings that others
//! were missing, and the relations that hold any of them.

use super::*;

impl Update<'_> {
    /// Reads what the diff changes: its elements, the ways through the nodes it moves, the
    /// relations that hold changed ways, as they are and as they will be.
    pub(super) fn plan(&mut self, change: &OsmChange) -> Result<Plan, UpdateError> {
        let mut plan = Plan::default();
        let mut sources: BTreeMap<i64, Option<(crate::osm::Tags, Vec<i64>)>> = BTreeMap::new();
        for c in change.changes.values() {
            if let Changed::Node { id, at, .. } = &c.element {
                let after = if c.action == Action::Delete {
                    None
                } else {
                    *at
                };
                self.diff_nodes.insert(*id, after);
            }
        }
        let mut cells_before: HashMap<(u32, u32), Vec<Way>> = HashMap::new();
        for c in change.changes.values() {
            match &c.element {
                Changed::Node { id, at, tags } => {
                    let before = self.stored_position(*id)?;
                    let after = if c.action == Action::Delete {
                        None
                    } else {
                        *at
                    };
                    let old = super::super::node(self.db, *id).map_err(self.decode())?;
                    let new = after.filter(|_| !tags.is_empty()).map(|at| {
                        let (lon, lat) = at.lon_lat();
                        let mut row = codec::Writer::default();
                        row.tags(tags);
                        (LonLat { lon, lat }, row)
                    });
                    plan.nodes.push(NodeEdit {
                        id: *id,
                        at: after,
                        old: old.map(|n| n.position),
                        new,
                    });
                    // A way that misses this node is resolved again with it.
                    if after.is_some() {
                        for way in self.ways_missing(*id)? {
                            if let std::collections::btree_map::Entry::Vacant(slot) =
                                sources.entry(way)
                            {
                                if let Some(named) = self.incomplete(way)? {
                                    slot.insert(Some(named));
                                }
                            }
                        }
                    }
                    if before == after {
                        continue;
                    }
                    // Every way through the node lies in the cell where it was.
                    let Some(cell) = before.and_then(|b| {
                        let (lon, lat) = b.lon_lat();
                        self.cell_of(LonLat { lon, lat })
                    }) else {
                        continue;
                    };
                    if let std::collections::hash_map::Entry::Vacant(slot) =
                        cells_before.entry(cell)
                    {
                        slot.insert(self.ways_in(cell)?);
                    }
                    for way in cells_before.get(&cell).map_or(&[][..], |w| &w[..]) {
                        if way.nodes.contains(id) && !sources.contains_key(&way.id) {
                            let named = match self.incomplete(way.id)? {
                                Some(named) => named,
                                None => (way.tags.clone(), way.nodes.clone()),
                            };
                            sources.insert(way.id, Some(named));
                        }
                    }
                }
                Changed::Way { id, nodes, tags } => {
                    let after = (c.action != Action::Delete).then(|| (tags.clone(), nodes.clone()));
                    sources.insert(*id, after);
                }
                Changed::Relation(relation) => {
                    // A relation tiles are not made from is not kept, as the import does.
                    let kept = c.action != Action::Delete && (self.rules.relation)(&relation.tags);
                    let after = kept.then(|| relation.clone());
                    plan.relations.insert(
                        relation.id,
                        RelationEdit {
                            old: None,
                            new: after,
                        },
                    );
                }
            }
        }
        for (id, source) in sources {
            let old = super::super::way(self.db, id).map_err(self.decode())?;
            let (new, missing) = match &source {
                Some((tags, refs)) => self.resolve(id, tags.clone(), refs)?,
                None => (None, Vec::new()),
            };
            let old_row = old.as_ref().map(|w| {
                let at: Vec<Decimicro> = w.positions.iter().map(|p| decimicro_of(*p)).collect();
                codec::encode_way(&w.tags, &w.nodes, &at)
            });
            let same_row = old_row.as_ref() == new.as_ref().map(|(_, row)| row);
            if same_row && missing.is_empty() && self.incomplete(id)?.is_none() {
                continue;
            }
            for w in [old.as_ref(), new.as_ref().map(|(w, _)| w)]
                .into_iter()
                .flatten()
            {
                for (_, through) in super::super::facts(self.db, w.id)
                    .map_err(self.decode())?
                    .joints
                {
                    plan.joined_before.extend(through);
                }
            }
            plan.ways.insert(
                id,
                WayEdit {
                    old,
                    new,
                    named: source,
                    missing,
                },
            );
        }
        self.plan_relations(&mut plan)?;
        Ok(plan)
    }

    /// A way as the diff leaves it: its nodes found, the missing dropped (None with fewer
    /// than two), and the nodes it misses.
    pub(super) fn resolve(
        &mut self,
        id: i64,
        tags: crate::osm::Tags,
        refs: &[i64],
    ) -> Result<Resolved, UpdateError> {
        let mut nodes = Vec::with_capacity(refs.len());
        let mut at = Vec::with_capacity(refs.len());
        let mut missing = Vec::new();
        for &node in refs {
            match self.position(node)? {
                Some(p) => {
                    nodes.push(node);
                    at.push(p);
                }
                None => missing.push(node),
            }
        }
        if nodes.len() < 2 {
            return Ok((None, missing));
        }
        let row = codec::encode_way(&tags, &nodes, &at);
        let positions = at
            .iter()
            .map(|p| {
                let (lon, lat) = p.lon_lat();
                LonLat { lon, lat }
            })
            .collect();
        Ok((
            Some((
                Way {
                    id,
                    tags,
                    nodes,
                    positions,
                },
                row,
            )),
            missing,
        ))
    }

    /// The tags and every node of a way the store holds incomplete.
    pub(super) fn incomplete(
        &self,
        way: i64,
    ) -> Result<Option<(crate::osm::Tags, Vec<i64>)>, UpdateError> {
        let data: Option<Vec<u8>> = self
            .db
            .prepare_cached("SELECT data FROM incomplete_ways WHERE way = ?1")
            .and_then(|mut s| s.query_row([way], |row| row.get(0)).optional())
            .map_err(self.sqlite())?;
        data.map(|d| codec::decode_raw_way(&d))
            .transpose()
            .map_err(self.decode())
    }

    /// The ways that name `node` without the store holding it.
    pub(super) fn ways_missing(&self, node: i64) -> Result<Vec<i64>, UpdateError> {
        self.ids_of(
            "SELECT way FROM missing_nodes WHERE node = ?1 ORDER BY way",
            node,
        )
    }

    /// The relations that name way `way` without the store holding it.
    pub(super) fn relations_missing(&self, way: i64) -> Result<Vec<i64>, UpdateError> {
        self.ids_of(
            "SELECT relation FROM missing_members WHERE way = ?1 ORDER BY relation",
            way,
        )
    }

    pub(super) fn ids_of(&self, sql: &str, id: i64) -> Result<Vec<i64>, UpdateError> {
        let mut statement = self.db.prepare_cached(sql).map_err(self.sqlite())?;
        let rows = statement
            .query_map([id], |row| row.get(0))
            .map_err(self.sqlite())?;
        rows.collect::<Result<_, _>>().map_err(self.sqlite())
    }

    /// Adds the relations holding a changed way or relation, to any depth, and reads each
    /// one's state before. A relation is registered in the cells of its ways' box, so it
    /// lies in the cells of each way and relation it holds.
    pub(super) fn plan_relations(&mut self, plan: &mut Plan) -> Result<(), UpdateError> {
        // A relation that names a way the store did not hold, now brought, wherever it lies.
        let brought: Vec<i64> = plan
            .ways
            .iter()
            .filter(|(_, e)| e.old.is_none() && e.new.is_some())
            .map(|(&id, _)| id)
            .collect();
        for way in brought {
            for id in self.relations_missing(way)? {
                if plan.relations.contains_key(&id) {
                    continue;
                }
                if let Some(relation) =
                    super::super::relation(self.db, id).map_err(self.decode())?
                {
                    plan.relations.insert(
                        id,
                        RelationEdit {
                            old: None,
                            new: Some(relation),
                        },
                    );
                }
            }
        }
        let mut looked = BTreeSet::new();
        loop {
            // The state before of the relations added last.
            let ids: Vec<i64> = plan
                .relations
                .iter()
                .filter(|(_, e)| e.old.is_none())
                .map(|(&id, _)| id)
                .collect();
            for id in ids {
                let old = match super::super::relation(self.db, id).map_err(self.decode())? {
                    Some(r) => {
                        let b = relation_bounds(self.db, &r).map_err(self.decode())?;
                        Some((r, b))
                    }
                    None => None,
                };
                if let Some(edit) = plan.relations.get_mut(&id) {
                    edit.old = old;
                }
            }
            // A relation is registered over its box, which holds each of its ways' cells.
            let mut cells = BTreeSet::new();
            for edit in plan.ways.values() {
                for way in [edit.old.as_ref(), edit.new.as_ref().map(|(w, _)| w)]
                    .into_iter()
                    .flatten()
                {
                    cells.extend(cells_of_way(way, self.n));
                }
            }
            for edit in plan.relations.values() {
                if let Some((_, Some(b))) = &edit.old {
                    cells.extend(cells_of(b, self.n));
                }
            }
            cells.retain(|c| !looked.contains(c));
            if cells.is_empty() {
                return Ok(());
            }
            looked.extend(cells.iter().copied());
            let mut added = false;
            for id in self.in_cells(2, &cells)? {
                if plan.relations.contains_key(&id) {
                    continue;
                }
                let Some(relation) = super::super::relation(self.db, id).map_err(self.decode())?
                else {
                    continue;
                };
                let holds = relation
                    .members
                    .iter()
                    .any(|m| match m.element.element_type {
                        ElementType::Way => plan.ways.contains_key(&m.element.id),
                        ElementType::Relation => plan.relations.contains_key(&m.element.id),
                        ElementType::Node => false,
                    });
                if holds {
                    plan.relations.insert(
                        id,
                        RelationEdit {
                            old: None,
                            new: Some(relation),
                        },
                    );
                    added = true;
                }
            }
            if !added {
                return Ok(());
            }
        }
    }

    /// The elements of `kind` registered in `cells`.
    pub(super) fn in_cells(
        &self,
        kind: i64,
        cells: &BTreeSet<(u32, u32)>,
    ) -> Result<BTreeSet<i64>, UpdateError> {
        let mut s = self
            .db
            .prepare_cached("SELECT id FROM cells WHERE x = ?1 AND y = ?2 AND kind = ?3")
            .map_err(self.sqlite())?;
        let mut found = BTreeSet::new();
        for &(x, y) in cells {
            let rows = s
                .query_map(params![x, y, kind], |r| r.get::<_, i64>(0))
                .map_err(self.sqlite())?;
            for id in rows {
                found.insert(id.map_err(self.sqlite())?);
            }
        }
        Ok(found)
    }
}
