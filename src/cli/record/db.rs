//! The results database: an SQLite file (rusqlite, with SQLite compiled in) holding every
//! benchmark result recorded or imported, each as its full JSON and the columns queries
//! need. It is opened carefully: a file that is not SQLite, a corrupt one, or one made by a
//! newer tessera is refused before anything is written to it; a new one is created readable
//! by its owner alone. Writers wait for each other (WAL, a busy timeout), and each run or
//! import is one transaction, so a crash never loses rows already there.

use super::result::BenchResult;
use anyhow::{Context, Result, anyhow, bail};
use rusqlite::{Connection, OptionalExtension, TransactionBehavior, params};
use std::io::Read;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The schema's migrations: `MIGRATIONS[i]` takes a database from `user_version` i to i + 1.
/// A migration is never edited once released; a change is a new one.
const MIGRATIONS: &[&str] = &[
    // 1: runs, and their scaling rows.
    "CREATE TABLE runs (
        id INTEGER PRIMARY KEY,
        digest TEXT NOT NULL UNIQUE,
        added_unix_s INTEGER NOT NULL,
        source TEXT NOT NULL,
        started_unix_s INTEGER NOT NULL,
        machine_id TEXT NOT NULL,
        cpu_model TEXT,
        logical_cpus INTEGER NOT NULL,
        version TEXT NOT NULL,
        commit_id TEXT NOT NULL,
        simd TEXT NOT NULL,
        workload TEXT NOT NULL,
        workload_id TEXT NOT NULL,
        threads INTEGER NOT NULL,
        sps_median REAL NOT NULL,
        sps_min REAL NOT NULL,
        sps_max REAL NOT NULL,
        validation TEXT NOT NULL,
        result TEXT NOT NULL
    ) STRICT;
    CREATE TABLE scaling (
        run_id INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE,
        threads INTEGER NOT NULL,
        sps_median REAL NOT NULL,
        sps_min REAL NOT NULL,
        sps_max REAL NOT NULL,
        PRIMARY KEY (run_id, threads)
    ) STRICT;
    CREATE INDEX runs_by_machine ON runs (machine_id, workload_id, started_unix_s);",
    // 2: whether the machine was busy while the run ran (results before it: not known, 0).
    "ALTER TABLE runs ADD COLUMN busy INTEGER NOT NULL DEFAULT 0;",
];

/// The schema version this build makes and reads.
pub const SCHEMA_VERSION: i64 = MIGRATIONS.len() as i64;

/// How long a writer waits for another before giving up.
const BUSY_TIMEOUT: Duration = Duration::from_secs(30);

/// Where the database is unless `--db` or `TESSERA_DB` says: `$XDG_DATA_HOME/tessera/
/// results.db`, or `~/.local/share/tessera/results.db`.
pub fn default_path() -> Option<PathBuf> {
    let absolute = |var: &str| {
        std::env::var_os(var)
            .map(PathBuf::from)
            .filter(|p| p.is_absolute())
    };
    let data =
        absolute("XDG_DATA_HOME").or_else(|| absolute("HOME").map(|h| h.join(".local/share")))?;
    Some(data.join("tessera").join("results.db"))
}

/// The database at `path`, or the default one.
pub fn resolve(path: Option<PathBuf>) -> Result<PathBuf> {
    path.or_else(default_path).ok_or_else(|| {
        anyhow!("no results database: set --db PATH or TESSERA_DB (neither XDG_DATA_HOME nor HOME is set)")
    })
}

/// One run as `list` shows it.
#[derive(Clone, Debug)]
pub struct Run {
    pub id: i64,
    pub started_unix_s: i64,
    pub machine_id: String,
    pub cpu_model: Option<String>,
    pub logical_cpus: i64,
    pub version: String,
    pub commit: String,
    pub simd: String,
    pub workload: String,
    pub workload_id: String,
    pub threads: i64,
    pub sps: [f64; 3],
    pub validation: String,
    /// The machine was busy while it ran (other work, steal time).
    pub busy: bool,
}

/// Which runs `list` shows.
#[derive(Default)]
pub struct Filter {
    pub workload: Option<String>,
    /// A machine id's prefix, or part of a CPU model.
    pub machine: Option<String>,
    /// A commit's prefix.
    pub commit: Option<String>,
    pub limit: Option<u32>,
}

/// What adding a result did.
#[derive(Debug, PartialEq)]
pub enum Added {
    New(i64),
    /// The same result was already there (by its digest).
    Duplicate(i64),
}

#[derive(Clone, Copy, PartialEq)]
enum Access {
    Read,
    Write,
}

pub struct ResultsDb {
    conn: Connection,
    path: PathBuf,
    /// The schema version of the file: older than this build's only where it could not be
    /// brought up to date (read on a read-only disk).
    schema: i64,
}

/// SQLite's file header.
const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

impl ResultsDb {
    /// Opens the database at `path`, creating it (and its directory) if it does not exist.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_as(path, Access::Write)
    }

    /// Opens the database at `path` to read it: it is not created, and nothing is written,
    /// so it reads on a read-only disk too. One that needs a migration is opened to write.
    pub fn open_to_read(path: &Path) -> Result<Self> {
        if !path.exists() {
            bail!(
                "{}: no results database yet (`tessera bench` records its runs there, `tessera results import` adds others')",
                path.display()
            );
        }
        Self::open_as(path, Access::Read)
    }

    fn open_as(path: &Path, access: Access) -> Result<Self> {
        let shown = path.display();
        match std::fs::metadata(path) {
            Ok(meta) if !meta.is_file() => {
                bail!("{shown}: not a file: the results database must be one")
            }
            Ok(_) => {
                let mut head = Vec::with_capacity(16);
                std::fs::File::open(path)
                    .and_then(|f| f.take(16).read_to_end(&mut head))
                    .with_context(|| format!("{shown}: could not read the results database"))?;
                if !head.is_empty() && head != SQLITE_MAGIC {
                    bail!(
                        "{shown}: not an SQLite database, so not a tessera results database; left as it is"
                    );
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => create(path)?,
            Err(e) => {
                return Err(e)
                    .with_context(|| format!("{shown}: could not open the results database"));
            }
        }
        let flags = match access {
            Access::Read => rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
            Access::Write => rusqlite::OpenFlags::SQLITE_OPEN_READ_WRITE,
        } | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let conn = Connection::open_with_flags(path, flags)
            .with_context(|| format!("{shown}: could not open the results database"))?;
        let mut db = Self {
            conn,
            path: path.to_owned(),
            schema: 0,
        };
        db.conn.busy_timeout(BUSY_TIMEOUT)?;
        // Read-only checks first: a database this build must refuse is left untouched.
        let check: String = db
            .conn
            .query_row("PRAGMA quick_check", [], |r| r.get(0))
            .map_err(|e| db.error(e, "could not read it"))?;
        if check != "ok" {
            bail!(
                "{shown}: the results database is damaged ({}); left as it is",
                check.escape_debug()
            );
        }
        let version: i64 = db.conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
        if version > SCHEMA_VERSION {
            bail!(
                "{shown}: the results database has schema {version}, made by a newer tessera (this one knows up to {SCHEMA_VERSION}); left as it is"
            );
        }
        if version < 0 {
            bail!("{shown}: not a tessera results database (schema {version}); left as it is");
        }
        db.schema = version;
        if access == Access::Read && version < SCHEMA_VERSION {
            // Brought up to date where it can be written; a tessera schema is read as it is
            // where it cannot (a read-only disk).
            drop(db);
            let updated = Self::open_as(path, Access::Write);
            if version == 0 {
                return updated;
            }
            return updated.or_else(|_| {
                let flags = rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY
                    | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX;
                let conn = Connection::open_with_flags(path, flags)
                    .with_context(|| format!("{shown}: could not open the results database"))?;
                conn.busy_timeout(BUSY_TIMEOUT)?;
                Ok(Self {
                    conn,
                    path: path.to_owned(),
                    schema: version,
                })
            });
        }
        if access == Access::Read {
            return Ok(db);
        }
        if version == 0 {
            let tables: i64 = db
                .conn
                .query_row("SELECT count(*) FROM sqlite_schema", [], |r| r.get(0))?;
            if tables > 0 {
                bail!(
                    "{shown}: an SQLite database of something else, not tessera's results; left as it is"
                );
            }
        }
        db.conn
            .pragma_update(None, "journal_mode", "wal")
            .map_err(|e| db.error(e, "could not switch it to WAL"))?;
        db.conn.pragma_update(None, "foreign_keys", true)?;
        db.migrate(version)?;
        db.schema = SCHEMA_VERSION;
        Ok(db)
    }

    /// An SQLite error as the user should read it.
    fn error(&self, e: rusqlite::Error, doing: &str) -> anyhow::Error {
        let shown = self.path.display();
        match e.sqlite_error_code() {
            Some(rusqlite::ErrorCode::NotADatabase) => {
                anyhow!("{shown}: damaged or not a database ({e}); left as it is")
            }
            Some(rusqlite::ErrorCode::DatabaseCorrupt) => {
                anyhow!("{shown}: the results database is damaged ({e}); left as it is")
            }
            Some(rusqlite::ErrorCode::ReadOnly) | Some(rusqlite::ErrorCode::CannotOpen) => {
                anyhow!("{shown}: {doing}: the database or its directory is read-only ({e})")
            }
            Some(rusqlite::ErrorCode::DiskFull) => anyhow!("{shown}: {doing}: the disk is full"),
            Some(rusqlite::ErrorCode::DatabaseBusy) | Some(rusqlite::ErrorCode::DatabaseLocked) => {
                anyhow!("{shown}: {doing}: another process held the database for {BUSY_TIMEOUT:?}")
            }
            _ => anyhow!("{shown}: {doing}: {e}"),
        }
    }

    fn migrate(&self, from: i64) -> Result<()> {
        for (i, sql) in MIGRATIONS.iter().enumerate().skip(from as usize) {
            let tx =
                rusqlite::Transaction::new_unchecked(&self.conn, TransactionBehavior::Immediate)
                    .map_err(|e| self.error(e, "could not update its schema"))?;
            // Another process may have migrated it meanwhile.
            let now: i64 = tx.query_row("PRAGMA user_version", [], |r| r.get(0))?;
            if now > i as i64 {
                continue;
            }
            tx.execute_batch(sql)
                .and_then(|()| tx.pragma_update(None, "user_version", i as i64 + 1))
                .and_then(|()| tx.commit())
                .map_err(|e| self.error(e, "could not update its schema"))?;
        }
        Ok(())
    }

    /// Adds `reports` (from `source`: `bench` or `import`) in one transaction: all or none.
    pub fn add_all(&mut self, reports: &[BenchResult], source: &str) -> Result<Vec<Added>> {
        let added_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        let jsons = (reports.iter())
            .map(serde_json::to_string)
            .collect::<Result<Vec<_>, _>>()?;
        let written = (|| {
            let tx = self
                .conn
                .transaction_with_behavior(TransactionBehavior::Immediate)?;
            let mut outcomes = Vec::new();
            for (report, json) in reports.iter().zip(&jsons) {
                outcomes.push(insert(&tx, report, json, source, added_unix_s)?);
            }
            tx.commit()?;
            Ok(outcomes)
        })();
        written.map_err(|e| self.error(e, "could not write the results"))
    }

    /// The runs `filter` selects, newest first.
    pub fn runs(&self, filter: &Filter) -> Result<Vec<Run>> {
        // Schema 1 (read where it could not be updated) knows nothing of busy machines.
        let busy = if self.schema >= 2 { "busy" } else { "0" };
        let mut stmt = self.conn.prepare(&format!(
            "SELECT id, started_unix_s, machine_id, cpu_model, logical_cpus, version, commit_id,
                    simd, workload, workload_id, threads, sps_median, sps_min, sps_max, validation,
                    {busy}
             FROM runs
             WHERE (?1 IS NULL OR workload = ?1)
               AND (?2 IS NULL OR machine_id LIKE ?2 || '%' ESCAPE '\\'
                    OR instr(lower(cpu_model), lower(?3)) > 0)
               AND (?4 IS NULL OR commit_id LIKE ?4 || '%' ESCAPE '\\')
             ORDER BY started_unix_s DESC, id DESC
             LIMIT ?5"
        ))?;
        let like = |s: &Option<String>| {
            s.as_ref().map(|s| {
                s.replace('\\', "\\\\")
                    .replace('%', "\\%")
                    .replace('_', "\\_")
            })
        };
        let limit = filter.limit.map_or(-1, i64::from);
        let rows = stmt.query_map(
            params![
                filter.workload,
                like(&filter.machine),
                filter.machine,
                like(&filter.commit),
                limit
            ],
            |r| {
                Ok(Run {
                    id: r.get(0)?,
                    started_unix_s: r.get(1)?,
                    machine_id: r.get(2)?,
                    cpu_model: r.get(3)?,
                    logical_cpus: r.get(4)?,
                    version: r.get(5)?,
                    commit: r.get(6)?,
                    simd: r.get(7)?,
                    workload: r.get(8)?,
                    workload_id: r.get(9)?,
                    threads: r.get(10)?,
                    sps: [r.get(11)?, r.get(12)?, r.get(13)?],
                    validation: r.get(14)?,
                    busy: r.get(15)?,
                })
            },
        )?;
        Ok(rows.collect::<rusqlite::Result<Vec<_>>>()?)
    }
}

impl ResultsDb {
    /// Each thread count's samples/s (median, min, max) of run `id`, fewest threads first.
    pub fn scaling(&self, id: i64) -> Result<Vec<(i64, [f64; 3])>> {
        let mut stmt = self.conn.prepare(
            "SELECT threads, sps_median, sps_min, sps_max FROM scaling
             WHERE run_id = ?1 ORDER BY threads",
        )?;
        let rows = stmt.query_map([id], |r| Ok((r.get(0)?, [r.get(1)?, r.get(2)?, r.get(3)?])))?;
        Ok(rows.collect::<rusqlite::Result<Vec<_>>>()?)
    }

    /// How many runs it holds.
    pub fn count(&self) -> Result<usize> {
        let n: i64 = self
            .conn
            .query_row("SELECT count(*) FROM runs", [], |r| r.get(0))?;
        Ok(n as usize)
    }

    /// Every run's result JSON, oldest first.
    pub fn results_json(&self) -> Result<Vec<String>> {
        let mut stmt = self
            .conn
            .prepare("SELECT result FROM runs ORDER BY started_unix_s, id")?;
        let rows = stmt.query_map([], |r| r.get(0))?;
        Ok(rows.collect::<rusqlite::Result<Vec<_>>>()?)
    }
}

/// Adds one result in transaction `tx`, unless a result of the same digest is there.
fn insert(
    tx: &rusqlite::Transaction,
    report: &BenchResult,
    json: &str,
    source: &str,
    added_unix_s: i64,
) -> rusqlite::Result<Added> {
    let digest = format!("{:032x}", xxhash_rust::xxh3::xxh3_128(json.as_bytes()));
    let existing: Option<i64> = tx
        .query_row("SELECT id FROM runs WHERE digest = ?1", [&digest], |r| {
            r.get(0)
        })
        .optional()?;
    if let Some(id) = existing {
        return Ok(Added::Duplicate(id));
    }
    let r = &report.result;
    tx.execute(
        "INSERT INTO runs (digest, added_unix_s, source, started_unix_s, machine_id,
            cpu_model, logical_cpus, version, commit_id, simd, workload, workload_id,
            threads, sps_median, sps_min, sps_max, validation, result, busy)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18,
            ?19)",
        params![
            digest,
            added_unix_s,
            source,
            report.method.started_unix_s as i64,
            report.machine_id(),
            report.host.cpu_model,
            report.host.logical_cpus as i64,
            report.build.version,
            report.build.commit,
            report.build.simd,
            report.workload.name,
            report.workload.id,
            r.threads as i64,
            r.samples_per_sec.median,
            r.samples_per_sec.min,
            r.samples_per_sec.max,
            report.validation.status,
            json,
            report.busy.as_ref().is_some_and(|b| b.busy),
        ],
    )?;
    let id = tx.last_insert_rowid();
    for row in &report.scaling {
        let s = row.samples_per_sec;
        tx.execute(
            "INSERT OR REPLACE INTO scaling (run_id, threads, sps_median, sps_min, sps_max)
             VALUES (?1, ?2, ?3, ?4, ?5)",
            params![id, row.threads as i64, s.median, s.min, s.max],
        )?;
    }
    Ok(Added::New(id))
}

/// Creates an empty database file readable by its owner alone, and its directory.
fn create(path: &Path) -> Result<()> {
    let shown = path.display();
    if let Some(dir) = (path.parent()).filter(|d| !d.as_os_str().is_empty() && !d.exists()) {
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(dir)
            .with_context(|| format!("{shown}: could not create the directory"))?;
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .map(drop)
        .or_else(|e| match e.kind() {
            // Another process created it first: use theirs.
            std::io::ErrorKind::AlreadyExists => Ok(()),
            _ => Err(e),
        })
        .with_context(|| format!("{shown}: could not create the results database"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn migrations_take_every_version_to_the_latest() {
        for start in 0..=MIGRATIONS.len() {
            let conn = Connection::open_in_memory().unwrap();
            for sql in &MIGRATIONS[..start] {
                conn.execute_batch(sql).unwrap();
            }
            conn.pragma_update(None, "user_version", start as i64)
                .unwrap();
            let db = ResultsDb {
                conn,
                path: PathBuf::from(":memory:"),
                schema: start as i64,
            };
            db.migrate(start as i64).unwrap();
            let v: i64 = db
                .conn
                .query_row("PRAGMA user_version", [], |r| r.get(0))
                .unwrap();
            assert_eq!(v, SCHEMA_VERSION);
        }
    }
}
