-- Rendered tiles shared by every process of a cluster, one row per tile and format: the same
-- columns as the SQLite cache (see ../0002_codings_versions_access.sql). `data` is in the
-- coding `encoding` names, `data_br` the brotli form when that pays; `sources` the versions of
-- the sources the tile was made from; `accessed_at` when it was last served, for eviction of
-- the least recently served under the size cap.
CREATE TABLE tiles (
    z smallint NOT NULL,
    x integer NOT NULL,
    y integer NOT NULL,
    format text NOT NULL,
    pipeline text NOT NULL,
    sources text NOT NULL,
    etag text NOT NULL,
    encoding text NOT NULL,
    size bigint NOT NULL,
    created_at bigint NOT NULL,
    accessed_at bigint NOT NULL,
    data bytea NOT NULL,
    data_br bytea,
    PRIMARY KEY (z, x, y, format)
);

-- Eviction walks the least recently served first.
CREATE INDEX tiles_by_access ON tiles (accessed_at);

-- What the store holds, kept by a trigger so the size cap costs no scan.
CREATE TABLE usage (
    id integer PRIMARY KEY CHECK (id = 0),
    tiles bigint NOT NULL,
    bytes bigint NOT NULL
);
INSERT INTO usage VALUES (0, 0, 0);

CREATE FUNCTION tiles_usage() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'INSERT' THEN
        UPDATE usage SET tiles = tiles + 1, bytes = bytes + NEW.size WHERE id = 0;
    ELSIF TG_OP = 'DELETE' THEN
        UPDATE usage SET tiles = tiles - 1, bytes = bytes - OLD.size WHERE id = 0;
    ELSIF NEW.size <> OLD.size THEN
        UPDATE usage SET bytes = bytes - OLD.size + NEW.size WHERE id = 0;
    END IF;
    RETURN NULL;
END;
$$;

CREATE TRIGGER tiles_usage AFTER INSERT OR DELETE OR UPDATE OF size ON tiles
    FOR EACH ROW EXECUTE FUNCTION tiles_usage();

-- Components of the elevation linear program already solved, by the SHA-256 digest of what the
-- solver is given (see src/elevation/solutions.rs); the oldest go first past a bound on their
-- number. Not counted in the tiles' size cap.
CREATE TABLE solutions (
    key bytea PRIMARY KEY,
    data bytea NOT NULL,
    kept bigserial NOT NULL
);
CREATE INDEX solutions_by_age ON solutions (kept);
