-- Tiles stored compressed, with the versions of the sources they were made from, their size,
-- and when they were last served (for least-recently-used eviction under the size cap).
--
-- The table is rebuilt so that the small columns come first and the blobs last: SQLite keeps the
-- start of a row in its B-tree page and the rest of a large row in overflow pages, so reading a
-- tile's bookkeeping (for eviction, listings, regeneration) never reads its bytes.
--
-- `data` is in the coding `encoding` names (gzip where it pays, else identity); `data_br` is
-- the brotli form when that pays. `sources` names the versions of the OSM extracts and SRTM
-- files the tile was made from; a tile whose pipeline or sources differ from the server's is
-- stale: it is served while a new one is made.
CREATE TABLE tiles_v2 (
    z INTEGER NOT NULL,
    x INTEGER NOT NULL,
    y INTEGER NOT NULL,
    format TEXT NOT NULL,
    pipeline TEXT NOT NULL,
    sources TEXT NOT NULL,
    etag TEXT NOT NULL,
    encoding TEXT NOT NULL,
    size INTEGER NOT NULL,
    created_at INTEGER NOT NULL,
    accessed_at INTEGER NOT NULL,
    data BLOB NOT NULL,
    data_br BLOB,
    PRIMARY KEY (z, x, y, format)
) WITHOUT ROWID;

-- Terrain tiles were kept gzipped, glb tiles as they are.
INSERT INTO tiles_v2
SELECT z, x, y, format, pipeline, '', etag,
       CASE WHEN format = 'glb' THEN 'identity' ELSE 'gzip' END,
       length(data), created_at, created_at, data, NULL
FROM tiles;

DROP TABLE tiles;
ALTER TABLE tiles_v2 RENAME TO tiles;

-- Eviction walks the least recently served first; the index covers what it reads.
CREATE INDEX tiles_by_access ON tiles (accessed_at, size);

-- What the store holds, kept by triggers so the size cap costs no scan.
CREATE TABLE usage (
    id INTEGER PRIMARY KEY CHECK (id = 0),
    tiles INTEGER NOT NULL,
    bytes INTEGER NOT NULL
);
INSERT INTO usage SELECT 0, count(*), coalesce(sum(size), 0) FROM tiles;

CREATE TRIGGER usage_insert AFTER INSERT ON tiles BEGIN
    UPDATE usage SET tiles = tiles + 1, bytes = bytes + NEW.size WHERE id = 0;
END;
CREATE TRIGGER usage_delete AFTER DELETE ON tiles BEGIN
    UPDATE usage SET tiles = tiles - 1, bytes = bytes - OLD.size WHERE id = 0;
END;
CREATE TRIGGER usage_update AFTER UPDATE OF size ON tiles BEGIN
    UPDATE usage SET bytes = bytes - OLD.size + NEW.size WHERE id = 0;
END;
