-- Each task's STATS.json (times, photons, effects, a piece's passes), handed in with its
-- result: the worker that ends the job composes the job's stats from them.
ALTER TABLE tasks ADD COLUMN stats_json TEXT;
