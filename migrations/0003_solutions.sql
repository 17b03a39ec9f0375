-- Components of the elevation linear program already solved, kept by the SHA-256 digest of
-- what the solver is given (see src/elevation/solutions.rs): a render that builds the same
-- component finds its solution here instead of solving it again, after a restart or a diff as
-- well. Content-addressed, so never stale; the oldest rows go first past a bound on their
-- number. Not counted in the tiles' size cap.
CREATE TABLE solutions (
    key BLOB PRIMARY KEY,
    data BLOB NOT NULL
);
