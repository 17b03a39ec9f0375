-- Tiles stored compressed, with the versions of the sources they were made from, their size,
-- and when they were last served (for least-recently-used eviction under the size cap).
--
-- `data` is in the coding `encoding` names (gzip where it pays, else identity); `data_br` is
-- the brotli form when that pays. `sources` names the versions of the OSM extracts and SRTM
-- files the tile was made from; a tile whose pipeline or sources differ from the server's is
-- stale: it is served while a new one is made.
ALTER TABLE tiles ADD COLUMN encoding TEXT NOT NULL DEFAULT 'identity';
ALTER TABLE tiles ADD COLUMN data_br BLOB;
ALTER TABLE tiles ADD COLUMN sources TEXT NOT NULL DEFAULT '';
ALTER TABLE tiles ADD COLUMN size INTEGER NOT NULL DEFAULT 0;
ALTER TABLE tiles ADD COLUMN accessed_at INTEGER NOT NULL DEFAULT 0;

-- Terrain tiles were kept gzipped, glb tiles as they are.
UPDATE tiles SET
    encoding = CASE WHEN format = 'glb' THEN 'identity' ELSE 'gzip' END,
    size = length(data),
    accessed_at = created_at;

CREATE INDEX tiles_by_access ON tiles (accessed_at);
