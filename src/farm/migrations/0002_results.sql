-- A job's images, merged from its tasks' results by the worker that completed the last
-- task, and stored in the same transaction as the job's end: no shared file system.
ALTER TABLE jobs ADD COLUMN result_exr BYTEA;
ALTER TABLE jobs ADD COLUMN result_png BYTEA;

-- Farm-wide counters, so that any API instance's /metrics shows what every worker saw:
-- expired leases reaped and results refused by the fence.
CREATE TABLE counters (
    name TEXT PRIMARY KEY,
    n BIGINT NOT NULL DEFAULT 0
);
INSERT INTO counters (name) VALUES ('leases_expired'), ('fenced_refused');
