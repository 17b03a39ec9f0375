-- The imported OSM store: the extracts' elements with their positions resolved, a grid index
-- of zoom-14 cells, and what was found once over all of them. Written whole by an import,
-- beside the store it replaces; its format is `meta.format`.

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

-- Each element in every cell its bounding box meets. kind: 0 node, 1 way, 2 relation,
-- 3 structure group.
CREATE TABLE cells (
    x INTEGER NOT NULL,
    y INTEGER NOT NULL,
    kind INTEGER NOT NULL,
    id INTEGER NOT NULL
);

-- Bridges and tunnels found over all the data: one row a group, in the order found.
CREATE TABLE groups (
    id INTEGER PRIMARY KEY,
    data BLOB NOT NULL
);

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

CREATE TABLE coastlines (
    way INTEGER PRIMARY KEY
);
