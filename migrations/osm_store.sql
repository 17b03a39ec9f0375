-- The imported OSM store: the extracts' elements with their positions resolved, a grid index
-- of zoom-14 cells, and what was found once over all of them. Written whole by an import,
-- beside the store it replaces, then changed in place by OSM diffs; its format is
-- `meta.format`.

CREATE TABLE meta (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);

-- Tagged nodes (untagged ones live in their ways).
CREATE TABLE nodes (
    id INTEGER PRIMARY KEY,
    lon REAL NOT NULL,
    lat REAL NOT NULL,
    tags BLOB NOT NULL
);

-- Ways with at least two resolved nodes: tags, node ids and positions (see codec.rs).
CREATE TABLE ways (
    id INTEGER PRIMARY KEY,
    data BLOB NOT NULL
);

CREATE TABLE relations (
    id INTEGER PRIMARY KEY,
    data BLOB NOT NULL
);

-- Each element in every cell it reaches: a node its own, a way those its segments pass through
-- (and for a closed way those inside it), a relation and a group those their box meets.
-- kind: 0 node, 1 way, 2 relation, 3 structure group.
CREATE TABLE cells (
    x INTEGER NOT NULL,
    y INTEGER NOT NULL,
    kind INTEGER NOT NULL,
    id INTEGER NOT NULL,
    PRIMARY KEY (x, y, kind, id)
) WITHOUT ROWID;

-- Bridges and tunnels found over all the data: one row a group, named by the smallest id of
-- its structure ways (the order the whole data's index finds them in).
CREATE TABLE groups (
    id INTEGER PRIMARY KEY,
    data BLOB NOT NULL
);

-- Where each group's bridges pass over a way (see codec.rs); `way_facts.under_bridges` is
-- each way's rows here in the order of the groups.
CREATE TABLE group_under (
    way INTEGER NOT NULL,
    grp INTEGER NOT NULL,
    positions BLOB NOT NULL,
    PRIMARY KEY (way, grp)
) WITHOUT ROWID;

-- The nodes where ways of the road network join, with the ways through each.
CREATE TABLE joints (
    node INTEGER NOT NULL,
    way INTEGER NOT NULL,
    PRIMARY KEY (node, way)
) WITHOUT ROWID;

-- What was found over all the data about a way: its joints, each with the ways through it,
-- and where bridges pass over it (see codec.rs).
CREATE TABLE way_facts (
    way INTEGER PRIMARY KEY,
    joints BLOB,
    under_bridges BLOB
);

-- Ways naming nodes the data does not hold (an extract cuts them at its border), with every
-- node they name (`data`: tags and node ids, as `ways` keeps them but without positions), and
-- the nodes they miss: a diff that brings such a node resolves the way again. A way of fewer
-- than two nodes held is kept here only.
CREATE TABLE incomplete_ways (
    way INTEGER PRIMARY KEY,
    data BLOB NOT NULL
);

CREATE TABLE missing_nodes (
    node INTEGER NOT NULL,
    way INTEGER NOT NULL,
    PRIMARY KEY (node, way)
) WITHOUT ROWID;
CREATE INDEX missing_nodes_by_way ON missing_nodes (way);

-- Ways a kept relation names that the data does not hold: a diff that brings one finds the
-- relation wherever the way lies.
CREATE TABLE missing_members (
    way INTEGER NOT NULL,
    relation INTEGER NOT NULL,
    PRIMARY KEY (way, relation)
) WITHOUT ROWID;
CREATE INDEX missing_members_by_relation ON missing_members (relation);

CREATE TABLE coastlines (
    way INTEGER PRIMARY KEY
);

-- Every node's position is in the node file `meta.nodes_file` beside the store (16-byte
-- records in runs of ascending ids); these are its runs, to read it again.
CREATE TABLE node_runs (
    run INTEGER PRIMARY KEY,
    start INTEGER NOT NULL,
    len INTEGER NOT NULL,
    last INTEGER NOT NULL,
    firsts BLOB NOT NULL
);

-- Nodes diffs created, moved or deleted since the import, in 10^-7 degrees; NULL for deleted.
-- They come before the node file.
CREATE TABLE node_moves (
    id INTEGER PRIMARY KEY,
    lon INTEGER,
    lat INTEGER
);

-- Tiles of the store's zoom whose elements a diff changed, with the last such diff
-- (`meta.generation` counts the diffs applied).
CREATE TABLE expired (
    x INTEGER NOT NULL,
    y INTEGER NOT NULL,
    generation INTEGER NOT NULL,
    PRIMARY KEY (x, y)
) WITHOUT ROWID;
CREATE INDEX expired_by_generation ON expired (generation);

-- The far views' generalised data (see far.rs): for each zoom far views are made at, a row
-- for each tile holding data, with the ways and relations drawn there simplified and the
-- building blocks the tile owns.
CREATE TABLE far (
    zoom INTEGER NOT NULL,
    x INTEGER NOT NULL,
    y INTEGER NOT NULL,
    data BLOB NOT NULL,
    PRIMARY KEY (zoom, x, y)
) WITHOUT ROWID;
