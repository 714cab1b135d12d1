-- Results are stored as they are, out of line, without PostgreSQL's pglz compression: a
-- task's sums are f64 noise that pglz barely shrinks but spends CPU on, on a box whose
-- cores are rendering; the job's EXR and PNG are compressed already.
ALTER TABLE tasks ALTER COLUMN result SET STORAGE EXTERNAL;
ALTER TABLE jobs ALTER COLUMN result_exr SET STORAGE EXTERNAL;
ALTER TABLE jobs ALTER COLUMN result_png SET STORAGE EXTERNAL;
