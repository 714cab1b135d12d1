-- The farm's store, first version: users, jobs (as the SQLite store keeps them, plus what
-- the farm needs), the tasks of a job with their leases and results, and the workers.
-- Times the queue compares (leases, heartbeats) are the database's own clock, timestamptz;
-- the job times the API reports are seconds since the epoch, as in SQLite.

CREATE TABLE users (
    id BIGINT PRIMARY KEY,
    name TEXT NOT NULL UNIQUE,
    token_hash TEXT NOT NULL UNIQUE,
    admin BOOLEAN NOT NULL,
    created DOUBLE PRECISION NOT NULL,
    -- Round-robin over users at task grain: the claim serves the user whose last_served
    -- is oldest (0: never served), then stamps it from serve_clock.
    last_served BIGINT NOT NULL DEFAULT 0
);

CREATE SEQUENCE serve_clock;

CREATE TABLE jobs (
    id BIGINT PRIMARY KEY,
    user_id BIGINT NOT NULL REFERENCES users(id),
    public BOOLEAN NOT NULL,
    status TEXT NOT NULL
        CHECK (status IN ('queued', 'running', 'done', 'failed', 'cancelled')),
    scene_name TEXT,
    scene_json TEXT,
    params_json TEXT NOT NULL,
    memory_bytes BIGINT NOT NULL,
    result_estimate BIGINT NOT NULL DEFAULT 0,
    width INTEGER,
    height INTEGER,
    created DOUBLE PRECISION NOT NULL,
    started DOUBLE PRECISION,
    finished DOUBLE PRECISION,
    error TEXT,
    stats_json TEXT,
    tasks_total INTEGER NOT NULL DEFAULT 0,
    tasks_done INTEGER NOT NULL DEFAULT 0
);

CREATE TABLE tasks (
    job_id BIGINT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
    -- The task's place in its job: results merge in this order.
    seq INTEGER NOT NULL,
    user_id BIGINT NOT NULL REFERENCES users(id),
    -- FIFO within a user: the job's creation, then seq.
    job_created DOUBLE PRECISION NOT NULL,
    -- What to render (`queue::Unit` as JSON: a range of passes, or a tile).
    unit JSONB NOT NULL,
    memory_bytes BIGINT NOT NULL,
    state TEXT NOT NULL DEFAULT 'queued'
        CHECK (state IN ('queued', 'leased', 'done', 'failed', 'cancelled')),
    -- Raised by every claim: a result is taken only from the current attempt (fencing).
    attempt INTEGER NOT NULL DEFAULT 0,
    -- Failed attempts (reported failures and expired leases); at the limit the job fails.
    failures INTEGER NOT NULL DEFAULT 0,
    worker TEXT,
    lease_until TIMESTAMPTZ,
    error TEXT,
    result BYTEA,
    PRIMARY KEY (job_id, seq)
);

-- The claim's scan: queued tasks in serving order; the reaper's: leases by expiry.
CREATE INDEX tasks_queued ON tasks (user_id, job_created, job_id, seq) WHERE state = 'queued';
CREATE INDEX tasks_leased ON tasks (lease_until) WHERE state = 'leased';

CREATE TABLE workers (
    id TEXT PRIMARY KEY,
    threads INTEGER NOT NULL,
    memory_bytes BIGINT NOT NULL,
    started TIMESTAMPTZ NOT NULL DEFAULT now(),
    last_heartbeat TIMESTAMPTZ NOT NULL DEFAULT now()
);
