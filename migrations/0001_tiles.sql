-- Rendered tiles, one row per tile and format.
-- `pipeline` names the rendering code and settings that made the row; a row made by another
-- pipeline is stale and is rendered again.
CREATE TABLE tiles (
    z INTEGER NOT NULL,
    x INTEGER NOT NULL,
    y INTEGER NOT NULL,
    format TEXT NOT NULL,
    pipeline TEXT NOT NULL,
    data BLOB NOT NULL,
    etag TEXT NOT NULL,
    created_at INTEGER NOT NULL,
    PRIMARY KEY (z, x, y, format)
) WITHOUT ROWID;
