//! The results database: an SQLite file (rusqlite, with SQLite compiled in) holding every
//! benchmark result recorded or imported, each as its full JSON and the columns queries
//! need. It is opened carefully: before SQLite touches a file, its header says whose it is
//! (tessera's `application_id`, or a schema 1 or 2 database with exactly tessera's tables),
//! its schema must be tessera's statement for statement, and anything else (not SQLite,
//! another program's, a newer tessera's, damaged, SQL of its own) is refused with the file
//! and its directory left as they were. A new database is made whole under a
//! temporary name and published with a hard link, so no process ever sees one half-made; it
//! is readable by its owner alone. Writers wait for each other (WAL, a busy timeout), and
//! each run or import is one transaction, so a crash never loses rows already there.

use super::result::BenchResult;
use crate::text::terminal_safe;
use anyhow::{Context, Result, anyhow, bail};
use rusqlite::{Connection, OpenFlags, OptionalExtension, TransactionBehavior, params};
use std::fmt::Write as _;
use std::io::Read;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{DirBuilderExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// tessera's SQLite `application_id` (the file header's bytes 68..72, big-endian): the ASCII
/// bytes "TSRA". Migration 3 sets it; a database with another one is another program's.
pub const APPLICATION_ID: u32 = 0x5453_5241;

/// The first schema version that carries `APPLICATION_ID`. The versions before it (1 and 2,
/// application_id 0) are recognised by their tables, and brought up to date when opened to
/// write.
const APPLICATION_ID_SINCE: i64 = 3;

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
    // 3: tessera's application_id (APPLICATION_ID, "TSRA"), which says whose the file is.
    "PRAGMA application_id = 1414746689;",
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

/// The length of SQLite's file header.
const HEADER_LEN: usize = 100;

/// What a file's first 100 bytes (SQLite's header) say it is.
#[derive(Debug, PartialEq)]
enum Header {
    /// No bytes at all.
    Empty,
    /// Not SQLite's magic string.
    NotSqlite,
    /// SQLite's magic string, but less than a whole header.
    CutShort,
    Sqlite {
        /// Bytes 68..72.
        application_id: u32,
        /// Bytes 60..64, signed as SQLite reads them.
        user_version: i64,
    },
}

impl Header {
    fn parse(head: &[u8]) -> Self {
        if head.is_empty() {
            return Self::Empty;
        }
        if !head.starts_with(SQLITE_MAGIC) {
            return Self::NotSqlite;
        }
        let Some(header) = head.get(..HEADER_LEN) else {
            return Self::CutShort;
        };
        let word = |at: usize| {
            let mut bytes = [0; 4];
            bytes.copy_from_slice(&header[at..at + 4]);
            u32::from_be_bytes(bytes)
        };
        Self::Sqlite {
            application_id: word(68),
            user_version: i64::from(word(60) as i32),
        }
    }
}

impl ResultsDb {
    /// Opens the database at `path`, creating it (and its directory) if it does not exist.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_as(path, Access::Write)
    }

    /// Opens the database at `path` to read it: it is not created, and nothing is written,
    /// so it reads on a read-only disk too. One that needs a migration is opened to write
    /// where it can be, and read as it is where it cannot.
    pub fn open_to_read(path: &Path) -> Result<Self> {
        refuse_dangling_link(path)?;
        if !path.exists() {
            bail!(
                "{}: no results database yet (`tessera bench` records its runs there, `tessera results import` adds others')",
                path.display()
            );
        }
        Self::open_as(path, Access::Read)
    }

    fn open_as(path: &Path, access: Access) -> Result<Self> {
        let missing = matches!(std::fs::metadata(path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound);
        if missing && access == Access::Write {
            refuse_dangling_link(path)?;
            create(path)?;
        }
        // Whose the file is, from what it holds, before SQLite opens it to use it: a file
        // this build must refuse is left as it was, and no -wal or -shm file is made for it.
        recognise(path)?;
        let mut db = match access {
            Access::Read => Self::connect_to_read(path)?,
            Access::Write => Self::connect(path, OpenFlags::SQLITE_OPEN_READ_WRITE)?,
        };
        // The same checks through SQLite, which also reads what the WAL holds.
        db.schema = db.check()?;
        if access == Access::Read {
            if db.schema < SCHEMA_VERSION {
                // Brought up to date where it can be written; read as it is where it cannot
                // (a read-only disk). This connection is closed first: the upgrade reads the
                // file's header itself, and closing a file drops every POSIX lock the
                // process holds on it, SQLite's too.
                drop(db);
                return Self::open_as(path, Access::Write).or_else(|_| {
                    let mut db = Self::connect_to_read(path)?;
                    db.schema = db.check()?;
                    Ok(db)
                });
            }
            return Ok(db);
        }
        db.conn.pragma_update(None, "foreign_keys", true)?;
        db.migrate(db.schema)?;
        db.schema = SCHEMA_VERSION;
        Ok(db)
    }

    /// A connection to `path` with `flags`, waiting for other writers.
    fn connect(path: &Path, flags: OpenFlags) -> Result<Self> {
        let conn = Connection::open_with_flags(path, flags | OpenFlags::SQLITE_OPEN_NO_MUTEX)
            .with_context(|| format!("{}: could not open the results database", path.display()))?;
        conn.busy_timeout(BUSY_TIMEOUT)?;
        // Nothing of the file's schema runs a function with side effects, whoever made it.
        conn.pragma_update(None, "trusted_schema", false)?;
        Ok(Self {
            conn,
            path: path.to_owned(),
            schema: 0,
        })
    }

    /// A read-only connection to `path`. A WAL database needs its -shm file to be read,
    /// and a read-only file system cannot hold a new one: there it is read as immutable,
    /// which is true of it, since nobody can write it.
    fn connect_to_read(path: &Path) -> Result<Self> {
        let db = Self::connect(path, OpenFlags::SQLITE_OPEN_READ_ONLY)?;
        // The first read is where SQLite opens the -wal and -shm files. Any other error
        // shows at the checks that follow.
        let first = db
            .conn
            .query_row("SELECT count(*) FROM sqlite_schema", [], |r| {
                r.get::<_, i64>(0)
            });
        match first {
            Err(e) if cannot_open_wal_files(&e) => {
                // Closed before the file is probed: closing a file drops every POSIX lock the
                // process holds on it, SQLite's too.
                drop(db);
                if !immutable_there(path) {
                    return Self::connect(path, OpenFlags::SQLITE_OPEN_READ_ONLY);
                }
                let conn = open_immutable(path).with_context(|| {
                    format!("{}: could not open the results database", path.display())
                })?;
                Ok(Self {
                    conn,
                    path: path.to_owned(),
                    schema: 0,
                })
            }
            _ => Ok(db),
        }
    }

    /// Checks that the database is whole and tessera's, of a schema this build knows, and
    /// returns that schema version. It only reads.
    fn check(&self) -> Result<i64> {
        let shown = self.path.display();
        let started = Instant::now();
        let check: String = (self.conn)
            .query_row("PRAGMA quick_check", [], |r| r.get(0))
            .map_err(|e| self.error(e, "could not read it", started))?;
        if check != "ok" {
            bail!(
                "{shown}: the results database is damaged ({}); left as it is",
                check.escape_debug()
            );
        }
        let pragma = |name: &str| {
            (self.conn)
                .query_row(&format!("PRAGMA {name}"), [], |r| r.get::<_, i64>(0))
                .map_err(|e| self.error(e, "could not read it", started))
        };
        // SQLite returns the header's 32 bits as a signed number.
        let application_id = pragma("application_id")? as u32;
        let user_version = pragma("user_version")?;
        whose(&self.path, application_id, user_version, |version| {
            schema_difference(&self.conn, version)
                .map_err(|e| self.error(e, "could not read it", started))
        })
    }

    /// An SQLite error as the user should read it; `started` is when the operation began
    /// (how long it waited on a busy database).
    fn error(&self, e: rusqlite::Error, doing: &str, started: Instant) -> anyhow::Error {
        explain(&self.path, e, doing, started)
    }

    fn migrate(&self, from: i64) -> Result<()> {
        for (i, sql) in MIGRATIONS.iter().enumerate().skip(from as usize) {
            let started = Instant::now();
            let tx =
                rusqlite::Transaction::new_unchecked(&self.conn, TransactionBehavior::Immediate)
                    .map_err(|e| self.error(e, "could not update its schema", started))?;
            // Another process may have migrated it meanwhile.
            let now: i64 = tx.query_row("PRAGMA user_version", [], |r| r.get(0))?;
            if now > i as i64 {
                continue;
            }
            tx.execute_batch(sql)
                .and_then(|()| tx.pragma_update(None, "user_version", i as i64 + 1))
                .and_then(|()| tx.commit())
                .map_err(|e| self.error(e, "could not update its schema", started))?;
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
        let started = Instant::now();
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
        written.map_err(|e| self.error(e, "could not write the results", started))
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

    /// Run `id`'s result JSON, as it was recorded.
    pub fn result_json(&self, id: i64) -> Result<String> {
        Ok(self
            .conn
            .query_row("SELECT result FROM runs WHERE id = ?1", [id], |r| r.get(0))?)
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

/// An SQLite error as the user should read it; `started` is when the operation began.
fn explain(path: &Path, e: rusqlite::Error, doing: &str, started: Instant) -> anyhow::Error {
    let shown = path.display();
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
        // SQLite reports a full disk as an I/O error where it maps its -shm file.
        Some(rusqlite::ErrorCode::SystemIoFailure) => {
            anyhow!("{shown}: {doing}: {e} (is the disk full?)")
        }
        Some(rusqlite::ErrorCode::DatabaseBusy) | Some(rusqlite::ErrorCode::DatabaseLocked) => {
            // SQLite waits up to BUSY_TIMEOUT for most locks but returns some at once: say
            // how long it waited.
            let waited = started.elapsed();
            let waited = if waited >= Duration::from_secs(1) {
                format!("{:.1} s", waited.as_secs_f64())
            } else {
                format!("{} ms", waited.as_millis())
            };
            anyhow!(
                "{shown}: {doing}: another process held the database; gave up after {waited} ({e})"
            )
        }
        _ => anyhow!("{shown}: {doing}: {e}"),
    }
}

/// Whose a database of `application_id` and `user_version` is: its schema version where it
/// is a tessera results database this build can use, else why not. `schema_difference`
/// says how its schema differs from tessera's of a version, if it does: schemas 1 and 2,
/// which carry no application_id, are recognised by it, and one with tessera's
/// application_id must hold it too, so that a crafted file's views, triggers or columns
/// (a recursive view that never ends, a trigger on every insert) are never run.
fn whose(
    path: &Path,
    application_id: u32,
    user_version: i64,
    schema_difference: impl FnOnce(i64) -> Result<Option<String>>,
) -> Result<i64> {
    let shown = path.display();
    match application_id {
        APPLICATION_ID if user_version > SCHEMA_VERSION => bail!(
            "{shown}: the results database has schema {user_version}, made by a newer tessera (this one knows up to {SCHEMA_VERSION}); left as it is"
        ),
        APPLICATION_ID if user_version < APPLICATION_ID_SINCE => bail!(
            "{shown}: not a tessera results database (tessera's application_id, but schema {user_version}); left as it is"
        ),
        APPLICATION_ID => match schema_difference(user_version)? {
            None => Ok(user_version),
            Some(difference) => bail!(
                "{shown}: not a tessera results database (tessera's application_id, but not its schema {user_version}: {difference}); left as it is"
            ),
        },
        0 if (1..APPLICATION_ID_SINCE).contains(&user_version) => {
            match schema_difference(user_version)? {
                None => Ok(user_version),
                Some(difference) => bail!(
                    "{shown}: an SQLite database of another program (user_version {user_version} but not tessera's tables: {difference}), not tessera's results; left as it is"
                ),
            }
        }
        0 => bail!(
            "{shown}: an SQLite database of another program (application_id 0, user_version {user_version}; tessera's is {APPLICATION_ID:#010x}), not tessera's results; left as it is"
        ),
        other => bail!(
            "{shown}: an SQLite database of another program (application_id {other:#010x}; tessera's is {APPLICATION_ID:#010x}), not tessera's results; left as it is"
        ),
    }
}

/// Says whether the file at `path` is a tessera results database this build can use, from
/// its header (and, for schemas 1 and 2, its tables read as immutable), before SQLite opens
/// it to use it: nothing is written, nor any -wal or -shm file made. It opens the file
/// itself, so it runs while no connection of this process is open on it: closing a file
/// drops every POSIX lock the process holds on it, SQLite's too.
fn recognise(path: &Path) -> Result<()> {
    let shown = path.display();
    let meta = std::fs::metadata(path)
        .with_context(|| format!("{shown}: could not open the results database"))?;
    if !meta.is_file() {
        bail!("{shown}: not a file: the results database must be one");
    }
    let mut head = Vec::with_capacity(HEADER_LEN);
    std::fs::File::open(path)
        .and_then(|f| f.take(HEADER_LEN as u64).read_to_end(&mut head))
        .with_context(|| format!("{shown}: could not read the results database"))?;
    let (application_id, user_version) = match Header::parse(&head) {
        Header::Empty => bail!(
            "{shown}: an empty file, not a results database; left as it is (remove it, and tessera makes a new database there)"
        ),
        Header::NotSqlite => bail!(
            "{shown}: not an SQLite database, so not a tessera results database; left as it is"
        ),
        Header::CutShort => bail!(
            "{shown}: the results database is damaged (its header is cut short); left as it is"
        ),
        Header::Sqlite {
            application_id,
            user_version,
        } => (application_id, user_version),
    };
    whose(path, application_id, user_version, |version| {
        // One with tessera's header may be in use, and a file others write cannot be read
        // as immutable: its schema is checked through SQLite, with its locks (`check`),
        // still before anything of it runs.
        if application_id == APPLICATION_ID {
            return Ok(None);
        }
        let started = Instant::now();
        open_immutable(path)
            .and_then(|conn| schema_difference(&conn, version))
            .map_err(|e| explain(path, e, "could not read it", started))
    })
    .map(drop)
}

/// One object of a database's schema: its type, name, table and SQL (spacing normalised).
type SchemaObject = (String, String, String, String);

/// How the schema of `conn` differs from tessera's schema `version` (what the migrations up
/// to it make), or `None` where it is the same, object for object and statement for
/// statement but for spacing. Only SQLite's schema table is read, a bounded part of it: no
/// view, trigger or table of the file is run.
fn schema_difference(conn: &Connection, version: i64) -> rusqlite::Result<Option<String>> {
    let expected = tessera_schema(version)?;
    // More than one object beyond tessera's is already a difference: the rest is not read.
    let found = schema_objects(conn, expected.len() + 1)?;
    let shown = |(kind, name, ..): &SchemaObject| format!("{kind} `{}`", terminal_safe(name, 80));
    for object in &found {
        match expected
            .iter()
            .find(|e| (&e.0, &e.1) == (&object.0, &object.1))
        {
            None => {
                return Ok(Some(format!(
                    "{}, which tessera does not make",
                    shown(object)
                )));
            }
            Some(e) if e != object => {
                return Ok(Some(format!("its {} is not tessera's", shown(object))));
            }
            Some(_) => {}
        }
    }
    Ok(expected
        .iter()
        .find(|e| !found.contains(e))
        .map(|e| format!("no {}", shown(e))))
}

/// tessera's schema `version`, as its migrations make it in a database in memory.
fn tessera_schema(version: i64) -> rusqlite::Result<Vec<SchemaObject>> {
    let conn = Connection::open_in_memory()?;
    let upto = usize::try_from(version).unwrap_or(0).min(MIGRATIONS.len());
    for migration in &MIGRATIONS[..upto] {
        conn.execute_batch(migration)?;
    }
    schema_objects(&conn, usize::MAX)
}

/// Up to `limit` objects of the schema of `conn`, sorted, each name and statement cut at a
/// length that no object of tessera's reaches.
fn schema_objects(conn: &Connection, limit: usize) -> rusqlite::Result<Vec<SchemaObject>> {
    let mut stmt = conn.prepare(
        "SELECT substr(type, 1, 16), substr(name, 1, 256), substr(tbl_name, 1, 256),
                substr(coalesce(sql, ''), 1, 4096)
         FROM sqlite_schema ORDER BY type, name LIMIT ?1",
    )?;
    let limit = i64::try_from(limit).unwrap_or(i64::MAX);
    stmt.query_map([limit], |r| {
        Ok((
            r.get(0)?,
            r.get(1)?,
            r.get(2)?,
            normalise_sql(&r.get::<_, String>(3)?),
        ))
    })?
    .collect()
}

/// `sql` with each run of spacing made one space, and none beside `(`, `)`, `,` or `;`: a
/// statement as tessera wrote it, however it was laid out.
fn normalise_sql(sql: &str) -> String {
    let tight = |c: char| matches!(c, '(' | ')' | ',' | ';');
    let mut out = String::with_capacity(sql.len());
    let mut spaced = false;
    for c in sql.chars() {
        if c.is_whitespace() {
            spaced = true;
            continue;
        }
        if spaced && !out.is_empty() && !tight(c) && !out.ends_with(tight) {
            out.push(' ');
        }
        spaced = false;
        out.push(c);
    }
    out
}

/// A read-only connection to `path` as an immutable file: SQLite takes no locks, ignores any
/// -wal file and makes no file of its own.
fn open_immutable(path: &Path) -> rusqlite::Result<Connection> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY
        | OpenFlags::SQLITE_OPEN_URI
        | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let conn = Connection::open_with_flags(immutable_uri(path), flags)?;
    conn.pragma_update(None, "trusted_schema", false)?;
    Ok(conn)
}

/// The SQLite URI of `path` opened as immutable: each byte but the unreserved ones and `/`
/// percent-encoded, so that no `?`, `#` or `%` in a name is read as part of the URI.
fn immutable_uri(path: &Path) -> String {
    // An absolute path after an empty authority, so that one that starts with `//` is not
    // read as an authority.
    let mut uri = String::from(if path.has_root() { "file://" } else { "file:" });
    for &b in path.as_os_str().as_bytes() {
        if b.is_ascii_alphanumeric() || b"/-._~".contains(&b) {
            uri.push(char::from(b));
        } else {
            let _ = write!(uri, "%{b:02X}");
        }
    }
    uri.push_str("?immutable=1");
    uri
}

/// Whether `e` is SQLite failing to open (or make) a database's -wal or -shm file.
fn cannot_open_wal_files(e: &rusqlite::Error) -> bool {
    matches!(
        e.sqlite_error_code(),
        Some(rusqlite::ErrorCode::CannotOpen) | Some(rusqlite::ErrorCode::ReadOnly)
    )
}

/// Whether reading `path` as immutable reads what it holds: it lies on a read-only file
/// system (so nobody writes it while it is read), and no -wal file holds changes that an
/// immutable read would not see.
fn immutable_there(path: &Path) -> bool {
    // Opening the file to write changes nothing, and on a read-only file system fails so.
    let read_only = matches!(std::fs::OpenOptions::new().write(true).open(path),
        Err(e) if e.kind() == std::io::ErrorKind::ReadOnlyFilesystem);
    let mut wal = path.as_os_str().to_owned();
    wal.push("-wal");
    let wal_is_empty = match std::fs::metadata(&wal) {
        Ok(meta) => meta.len() == 0,
        Err(e) => e.kind() == std::io::ErrorKind::NotFound,
    };
    read_only && wal_is_empty
}

/// Makes a new database at `path`, and its directory, unless another process does first.
/// It is made whole (tessera's application_id, WAL, every migration) under a temporary,
/// unpredictable name in the same directory, readable by its owner alone, closed (so that
/// its -wal and -shm files are gone), and then published with a hard link, which fails
/// where a database is there already: then that one is used and this one removed. No
/// process ever sees a half-made database.
fn create(path: &Path) -> Result<()> {
    let shown = path.display();
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    if !dir.exists() {
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(dir)
            .with_context(|| format!("{shown}: could not create the directory"))?;
    }
    let made = tempfile::Builder::new()
        .prefix(".results.db.")
        .permissions(std::fs::Permissions::from_mode(0o600))
        .tempfile_in(dir)
        .with_context(|| format!("{shown}: could not create the results database"))?;
    // Removed when dropped, unless published by a rename.
    let made = made.into_temp_path();
    let built = build_new(&made, path);
    if built.is_err() {
        // What SQLite could not finish (on a full disk) leaves its -wal and -shm files
        // behind: they go with the temporary file.
        for suffix in ["-wal", "-shm"] {
            let mut side = made.as_os_str().to_owned();
            side.push(suffix);
            let _ = std::fs::remove_file(side);
        }
    }
    built?;
    match std::fs::hard_link(&made, path) {
        // Ours, or another process's made first: either is whole.
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        // A file system without hard links: renamed instead, where nothing is there yet.
        Err(e) if links_refused(&e) => match made.persist_noclobber(path) {
            Ok(()) => Ok(()),
            Err(e) if e.error.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
            Err(e)
                if std::fs::symlink_metadata(path)
                    .is_err_and(|m| m.kind() == std::io::ErrorKind::NotFound) =>
            {
                e.path.persist(path).map_err(|e| e.error)
            }
            Err(e) => Err(e.error),
        },
        Err(e) => Err(e),
    }
    .with_context(|| format!("{shown}: could not create the results database"))
}

/// Refuses a `path` that is a symbolic link to nothing: a database is not made through a
/// link (the hard link that publishes a new one would not follow it), and "no such file"
/// would not say which of the two is missing.
fn refuse_dangling_link(path: &Path) -> Result<()> {
    let dangling = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink())
        && std::fs::metadata(path).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound);
    if dangling {
        let target = std::fs::read_link(path).unwrap_or_default();
        bail!(
            "{}: a symbolic link to {}, which does not exist: no database is made through a link; left as it is",
            path.display(),
            terminal_safe(&target.display().to_string(), 400)
        );
    }
    Ok(())
}

/// Makes a whole database of the latest schema, in WAL mode, at `made` (named `path` in
/// messages), and closes it.
fn build_new(made: &Path, path: &Path) -> Result<()> {
    let mut db = ResultsDb::connect(made, OpenFlags::SQLITE_OPEN_READ_WRITE)?;
    // Messages name the database being made, not its temporary name.
    db.path = path.to_owned();
    let started = Instant::now();
    db.conn
        .pragma_update(None, "journal_mode", "wal")
        .map_err(|e| db.error(e, "could not create it", started))?;
    db.migrate(0)?;
    // Everything written back from the WAL into the file itself before it is published under
    // `path`: its -wal file is `made`'s, which `path` never reads. A close does this too, but
    // says nothing when it cannot (a full disk), and the published file would be empty.
    let (busy, frames, written): (i64, i64, i64) = db
        .conn
        .query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?))
        })
        .map_err(|e| db.error(e, "could not create it", started))?;
    if busy != 0 || frames != written {
        bail!(
            "{}: could not create it: its journal was not written back ({written} of {frames} pages; is the disk full?)",
            path.display()
        );
    }
    db.conn
        .close()
        .map_err(|(_, e)| explain(path, e, "could not create it", started))?;
    let mut wal = made.as_os_str().to_owned();
    wal.push("-wal");
    if std::fs::metadata(&wal).is_ok_and(|m| m.len() > 0) {
        bail!(
            "{}: could not create it: its journal was not written back (is the disk full?)",
            path.display()
        );
    }
    Ok(())
}

/// Whether `e` is a file system refusing hard links.
fn links_refused(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::PermissionDenied
            | std::io::ErrorKind::Unsupported
            | std::io::ErrorKind::TooManyLinks
    ) || e.raw_os_error() == Some(95) // EOPNOTSUPP
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
            let id: i64 = db
                .conn
                .query_row("PRAGMA application_id", [], |r| r.get(0))
                .unwrap();
            assert_eq!(
                id,
                i64::from(APPLICATION_ID),
                "the migration's number is not TSRA"
            );
        }
        assert_eq!(&APPLICATION_ID.to_be_bytes(), b"TSRA");
    }

    /// A header of `len` bytes with `application_id` and `user_version` in it.
    fn header(len: usize, application_id: u32, user_version: u32) -> Vec<u8> {
        let mut head = vec![0; len.max(HEADER_LEN)];
        head[..16].copy_from_slice(SQLITE_MAGIC);
        head[60..64].copy_from_slice(&user_version.to_be_bytes());
        head[68..72].copy_from_slice(&application_id.to_be_bytes());
        head.truncate(len);
        head
    }

    #[test]
    fn the_header_says_whose_database_it_is() {
        assert_eq!(Header::parse(b""), Header::Empty);
        assert_eq!(Header::parse(b"my notes"), Header::NotSqlite);
        assert_eq!(Header::parse(b"SQLite"), Header::NotSqlite);
        assert_eq!(Header::parse(&header(99, 0, 0)), Header::CutShort);
        assert_eq!(
            Header::parse(&header(100, APPLICATION_ID, 3)),
            Header::Sqlite {
                application_id: APPLICATION_ID,
                user_version: 3
            }
        );
        assert_eq!(
            Header::parse(&header(4096, 0x8000_0001, u32::MAX)),
            Header::Sqlite {
                application_id: 0x8000_0001,
                user_version: -1
            }
        );
        let path = Path::new("r.db");
        let never = |_| -> Result<Option<String>> {
            panic!("schema read for a database refused by its header")
        };
        let same = |_| Ok(None);
        let differs = |_| Ok(Some("trigger `t`, which tessera does not make".to_owned()));
        assert_eq!(
            whose(path, APPLICATION_ID, SCHEMA_VERSION, same).unwrap(),
            SCHEMA_VERSION
        );
        let err = (whose(path, APPLICATION_ID, SCHEMA_VERSION, differs).unwrap_err()).to_string();
        assert!(
            err.contains("tessera's application_id, but not its schema 3: trigger `t`"),
            "{err}"
        );
        for (id, version, reason) in [
            (APPLICATION_ID, SCHEMA_VERSION + 1, "newer tessera"),
            (APPLICATION_ID, 1, "but schema 1"),
            (0, 0, "another program (application_id 0, user_version 0"),
            (0, 3, "another program (application_id 0, user_version 3"),
            (0, -2, "another program (application_id 0, user_version -2"),
            (0x1234_5678, 2, "another program (application_id 0x12345678"),
        ] {
            let err = whose(path, id, version, never).unwrap_err().to_string();
            assert!(err.contains(reason), "{id:#x} {version}: {err}");
        }
        assert_eq!(whose(path, 0, 2, same).unwrap(), 2);
        let err = whose(path, 0, 1, differs).unwrap_err().to_string();
        assert!(
            err.contains("user_version 1 but not tessera's tables: trigger `t`"),
            "{err}"
        );
    }

    #[test]
    fn a_schema_is_tessera_s_statement_for_statement_whatever_its_layout() {
        assert_eq!(
            normalise_sql("CREATE TABLE t (\n    a INTEGER ,\n\tb  TEXT\n) STRICT ;"),
            "CREATE TABLE t(a INTEGER,b TEXT)STRICT;"
        );
        let conn = Connection::open_in_memory().unwrap();
        // Schema 1 laid out otherwise: one line, other spacing.
        let one_line = MIGRATIONS[0]
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        conn.execute_batch(&one_line).unwrap();
        assert_eq!(schema_difference(&conn, 1).unwrap(), None);
        let missing = schema_difference(&conn, 2).unwrap().unwrap();
        assert_eq!(missing, "its table `runs` is not tessera's");
        conn.execute_batch(MIGRATIONS[1]).unwrap();
        assert_eq!(schema_difference(&conn, 2).unwrap(), None);
        assert_eq!(schema_difference(&conn, SCHEMA_VERSION).unwrap(), None);
        conn.execute_batch("CREATE TABLE scaling2 (x)").unwrap();
        let extra = schema_difference(&conn, 2).unwrap().unwrap();
        assert_eq!(extra, "table `scaling2`, which tessera does not make");
        conn.execute_batch("DROP TABLE scaling2; DROP INDEX runs_by_machine")
            .unwrap();
        let gone = schema_difference(&conn, 2).unwrap().unwrap();
        assert_eq!(gone, "no index `runs_by_machine`");
    }

    #[test]
    fn a_busy_database_says_how_long_it_was_waited_for() {
        let busy = || {
            rusqlite::Error::SqliteFailure(
                rusqlite::ffi::Error::new(rusqlite::ffi::SQLITE_BUSY),
                None,
            )
        };
        let path = Path::new("r.db");
        let at_once = explain(path, busy(), "could not write", Instant::now()).to_string();
        assert!(at_once.contains("gave up after 0 ms"), "{at_once}");
        assert!(!at_once.contains("30"), "{at_once}");
        if let Some(long_ago) = Instant::now().checked_sub(Duration::from_secs(31)) {
            let waited = explain(path, busy(), "could not write", long_ago).to_string();
            assert!(waited.contains("gave up after 31.0 s"), "{waited}");
        }
    }

    #[test]
    fn immutable_uris_keep_every_byte_of_the_path() {
        assert_eq!(immutable_uri(Path::new("r.db")), "file:r.db?immutable=1");
        assert_eq!(
            immutable_uri(Path::new("/a b/r?#%.db")),
            "file:///a%20b/r%3F%23%25.db?immutable=1"
        );
        assert_eq!(
            immutable_uri(Path::new("//host/r.db")),
            "file:////host/r.db?immutable=1"
        );
    }

    #[test]
    fn a_new_database_is_made_whole_and_published_once() {
        let dir = std::env::temp_dir().join(format!("tessera-db-unit-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("new/r.db");
        create(&path).unwrap();
        let first = std::fs::read(&path).unwrap();
        // A second maker finds it there and leaves it.
        create(&path).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), first);
        let names: Vec<_> = std::fs::read_dir(dir.join("new"))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(
            names,
            ["r.db"],
            "a temporary name or a -wal or -shm file is left"
        );
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        assert_eq!(
            Header::parse(&first),
            Header::Sqlite {
                application_id: APPLICATION_ID,
                user_version: SCHEMA_VERSION
            }
        );
        // Born in WAL: the header's read and write versions are 2.
        assert_eq!(first[18..20], [2, 2]);
        let db = ResultsDb::open(&path).unwrap();
        assert_eq!(db.count().unwrap(), 0);
        drop(db);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
