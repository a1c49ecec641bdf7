CREATE TABLE runs (
    id INTEGER PRIMARY KEY, digest TEXT NOT NULL UNIQUE, added_unix_s INTEGER NOT NULL,
    source TEXT NOT NULL, started_unix_s INTEGER NOT NULL, machine_id TEXT NOT NULL,
    cpu_model TEXT, logical_cpus INTEGER NOT NULL, version TEXT NOT NULL,
    commit_id TEXT NOT NULL, simd TEXT NOT NULL, workload TEXT NOT NULL,
    workload_id TEXT NOT NULL, threads INTEGER NOT NULL, sps_median REAL NOT NULL,
    sps_min REAL NOT NULL, sps_max REAL NOT NULL, validation TEXT NOT NULL,
    result TEXT NOT NULL) STRICT;
CREATE TABLE scaling (
    run_id INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE,
    threads INTEGER NOT NULL, sps_median REAL NOT NULL, sps_min REAL NOT NULL,
    sps_max REAL NOT NULL, PRIMARY KEY (run_id, threads)) STRICT;
CREATE INDEX runs_by_machine ON runs (machine_id, workload_id, started_unix_s);
PRAGMA user_version = 1;
