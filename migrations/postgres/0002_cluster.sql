-- What the processes sharing this database coordinate with (see src/cache/postgres/cluster.rs).

-- Render leases: the process making a tile claims it here first, so a tile asked of several
-- processes at once is made once. A claim lasts until `expires_at`; its holder renews it while
-- it renders, so a process that died lets it lapse and another takes the tile over.
CREATE TABLE leases (
    z smallint NOT NULL,
    x integer NOT NULL,
    y integer NOT NULL,
    format text NOT NULL,
    holder text NOT NULL,
    expires_at timestamptz NOT NULL,
    PRIMARY KEY (z, x, y, format)
);

-- Tiles to make: stale tiles met by a request (priority 0), tiles to make again (1) and tiles
-- to seed (2). A process takes a row by setting `taken_by` and `taken_until` (renewed while it
-- works, so a crashed worker's rows are taken again once it lapses) and deletes it when done.
-- A tile that failed `attempts` times is kept with its error, `failed`, for an operator to see.
CREATE TABLE work (
    z smallint NOT NULL,
    x integer NOT NULL,
    y integer NOT NULL,
    format text NOT NULL,
    kind text NOT NULL CHECK (kind IN ('regenerate', 'seed')),
    priority smallint NOT NULL,
    force boolean NOT NULL DEFAULT false,
    queued bigserial NOT NULL,
    taken_by text,
    taken_until timestamptz,
    attempts integer NOT NULL DEFAULT 0,
    failed boolean NOT NULL DEFAULT false,
    error text,
    PRIMARY KEY (z, x, y, format)
);
CREATE INDEX work_in_order ON work (kind, priority, queued) WHERE NOT failed;

-- The processes of the cluster, as they last reported.
CREATE TABLE workers (
    name text PRIMARY KEY,
    kind text NOT NULL,
    started_at timestamptz NOT NULL DEFAULT now(),
    seen_at timestamptz NOT NULL DEFAULT now(),
    made bigint NOT NULL DEFAULT 0,
    failed bigint NOT NULL DEFAULT 0
);
