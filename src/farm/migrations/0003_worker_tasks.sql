-- Tasks each worker has completed (results accepted by the fence), for GET /api/workers:
-- an operator sees which boxes do the work, and a test that a job was spread.
ALTER TABLE workers ADD COLUMN tasks_done BIGINT NOT NULL DEFAULT 0;
