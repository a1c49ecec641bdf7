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
//! `file` recognises a file and makes a new one; this module opens, migrates and queries.

mod file;

use super::result::{
    BenchResult, MAX_FILE, MAX_SAMPLES_PER_SEC, MAX_SCALING_ROWS, MAX_TEXT, MAX_THREADS,
    MIN_SAMPLES_PER_SEC, is_kept_run_time,
};
use anyhow::{Context, Result, anyhow, bail};
use file::{
    cannot_open_wal_files, create, create_with, immutable_there, open_immutable, recognise,
    refuse_dangling_link, schema_difference, whose,
};
use rusqlite::{Connection, OpenFlags, OptionalExtension, TransactionBehavior, params};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
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

/// The most bytes a run's stored result may hold to be read at all. An import keeps a result
/// of at most `MAX_FILE` bytes of UTF-8 (`BenchResult::parse`), which is at most twice as
/// many in UTF-16, the other encoding an SQLite database may have; a longer one is refused
/// by its length alone, before its text is read. One within it is read and then held to
/// `MAX_FILE` as an import holds it.
const MAX_RESULT_BYTES: i64 = 2 * MAX_FILE as i64;

/// A run's (and a scaling row's) samples/s columns, in the order `Run::sps` holds them.
const SPS_COLUMNS: [&str; 3] = ["sps_median", "sps_min", "sps_max"];

/// The text columns of a run that `runs` reads, each of at most `MAX_TEXT` characters as an
/// import takes them.
const RUN_TEXTS: [&str; 8] = [
    "machine_id",
    "cpu_model",
    "version",
    "commit_id",
    "simd",
    "workload",
    "workload_id",
    "validation",
];

/// The most bytes a run's text column may hold to be read: `MAX_TEXT` characters are at most
/// four bytes each, in UTF-8 as in UTF-16. A longer one is refused by its length alone.
const MAX_TEXT_BYTES: i64 = 4 * MAX_TEXT as i64;

/// The schema version this build makes and reads.
pub const SCHEMA_VERSION: i64 = MIGRATIONS.len() as i64;

/// How long one open of the database, or one statement after it, waits for another
/// process's lock before giving up.
const BUSY_TIMEOUT: Duration = Duration::from_secs(30);

/// How long a wait for another process's lock sleeps between looks at its stop flag.
const BUSY_LOOK: Duration = Duration::from_millis(10);

thread_local! {
    /// The flag that ends this thread's waits for another process's lock (`stopped_by`).
    static STOP: RefCell<Option<Arc<AtomicBool>>> = const { RefCell::new(None) };
}

/// Runs `read` on this thread with each connection it opens waiting for another process's
/// lock (up to `BUSY_TIMEOUT`: `wait_for_others`) only until `stop` is set: then the
/// statement gives up as busy at once. SQLite's own wait looks at nothing but the clock, and a reader
/// that the user may stop (Python's `tessera.results`, on Ctrl-C) sat out two such waits,
/// 60 s, on a database whose owner held it locked, deaf to Ctrl-C.
pub fn stopped_by<R>(stop: Arc<AtomicBool>, read: impl FnOnce() -> R) -> R {
    let before = STOP.with(|s| s.replace(Some(stop)));
    let done = read();
    STOP.with(|s| *s.borrow_mut() = before);
    done
}

#[cfg(test)]
thread_local! {
    /// How many times this thread slept waiting for another process's lock.
    static SLEPT: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Whether a statement that has waited for another process's lock since `since` waits
/// again: after a sleep of `BUSY_LOOK`, unless `stop` is set or `BUSY_TIMEOUT` has passed.
fn wait_unless(stop: Option<&AtomicBool>, since: Instant) -> bool {
    let stopped = || stop.is_some_and(|s| s.load(Ordering::Relaxed));
    if stopped() || since.elapsed() >= BUSY_TIMEOUT {
        return false;
    }
    #[cfg(test)]
    SLEPT.with(|n| n.set(n.get() + 1));
    std::thread::sleep(BUSY_LOOK);
    !stopped()
}

/// Has `conn` wait for another process's lock, a look every `BUSY_LOOK`, up to
/// `BUSY_TIMEOUT` from `since`, or where it is None from each statement's first try; and
/// only until this thread's stop flag (`stopped_by`) is set. An open gives its start as
/// `since`, so that its statements (the first read, `quick_check`, the schema's, a
/// migration's) share one wait: each once waited `BUSY_TIMEOUT` of its own, and a locked
/// database kept `results list` 60 s while its message said 30 s.
fn wait_for_others(conn: &mut Connection, since: Option<Instant>) -> rusqlite::Result<()> {
    let stop = STOP.with(|s| s.borrow().clone());
    let mut began = since.unwrap_or_else(Instant::now);
    conn.busy_handler(Some(move |tries| {
        // SQLite counts a statement's tries from 0: its own wait starts at the first.
        if tries == 0 && since.is_none() {
            began = Instant::now();
        }
        wait_unless(stop.as_deref(), began)
    }))
}

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

impl Filter {
    /// Whether `run` (checked against its result) is one this filter selects, as SQL's
    /// `LIKE` and `lower` select: a workload by its whole name; a machine by its id's
    /// start or by part of its CPU model, and a commit by its start, each ignoring the
    /// case of ASCII letters only.
    pub fn selects(&self, run: &Run) -> bool {
        let starts = |text: &str, start: &str| {
            (text.as_bytes().get(..start.len()))
                .is_some_and(|t| t.eq_ignore_ascii_case(start.as_bytes()))
        };
        let holds = |text: &str, part: &str| {
            (text.to_ascii_lowercase()).contains(&part.to_ascii_lowercase())
        };
        self.workload.as_ref().is_none_or(|w| run.workload == *w)
            && self.machine.as_ref().is_none_or(|m| {
                starts(&run.machine_id, m) || run.cpu_model.as_ref().is_some_and(|c| holds(c, m))
            })
            && self.commit.as_ref().is_none_or(|c| starts(&run.commit, c))
    }
}

/// What adding a result did.
#[derive(Debug, PartialEq)]
pub enum Added {
    New(i64),
    /// The same result was already there (by its digest).
    Duplicate(i64),
}

/// What adding results did: how many were new, and how many were there already (by their
/// digest).
#[derive(Debug, Default, PartialEq)]
pub struct Tally {
    pub new: usize,
    pub present: usize,
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

impl ResultsDb {
    /// Opens the database at `path`, creating it (and its directory) if it does not exist.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_as(path, Access::Write, Instant::now())?.opened()
    }

    /// Adds `reports` (from `source`) to the database at `path` in one transaction, as
    /// `add_fed_to` does.
    pub fn add_to(path: &Path, reports: &[BenchResult], source: &str) -> Result<Tally> {
        Self::add_fed_to(path, source, |add| reports.iter().try_for_each(add))
    }

    /// Adds the results `feed` hands over (from `source`) to the database at `path` in one
    /// transaction, as `add_fed` does, creating it where it does not exist: then they are
    /// written into the new database before it is published, so that an import that fails
    /// (a full disk) leaves no database of no runs behind, as one did. `feed` is asked
    /// again where another process published a new database first.
    pub fn add_fed_to<F>(path: &Path, source: &str, feed: F) -> Result<Tally>
    where
        F: Fn(&mut dyn FnMut(&BenchResult) -> Result<()>) -> Result<()>,
    {
        let missing = matches!(std::fs::symlink_metadata(path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound);
        if missing {
            let made = create_with(path, |db| db.add_fed(source, &feed))?;
            if let Some(added) = made {
                return Ok(added);
            }
        }
        // There already, or published by another process first: added to it.
        Self::open(path)?.add_fed(source, &feed)
    }

    /// Checks, making nothing, that a new database could be made at `path`, where none is
    /// there: `path` is no link to nothing, and the nearest of its directories that exists
    /// is one this user may add to. `bench` asks this before it renders, so that it does
    /// not run for nothing, and makes the database only when it has a result to add
    /// (`add_to`): made before the renders, a bench stopped or failed while it rendered
    /// left a database of no runs (and, killed, its -wal and -shm files).
    pub fn could_make(path: &Path) -> Result<()> {
        use rustix::fs::Access;
        refuse_dangling_link(path)?;
        let mut dir = path.parent().unwrap_or(Path::new(""));
        loop {
            let at = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            match std::fs::metadata(at) {
                Ok(meta) if meta.is_dir() => {
                    return rustix::fs::access(at, Access::WRITE_OK | Access::EXEC_OK)
                        .with_context(|| {
                            format!(
                                "{}: could not create the results database: {} cannot be \
                                 written",
                                path.display(),
                                at.display()
                            )
                        });
                }
                Ok(_) => bail!(
                    "{}: could not create the results database: {} is not a directory",
                    path.display(),
                    at.display()
                ),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound && at != Path::new(".") => {
                    dir = dir.parent().unwrap_or(Path::new(""));
                }
                Err(e) => {
                    return Err(e).with_context(|| {
                        format!(
                            "{}: could not create the results database ({})",
                            path.display(),
                            at.display()
                        )
                    });
                }
            }
        }
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
        Self::open_as(path, Access::Read, Instant::now())?.opened()
    }

    /// The database once open: each statement from now waits up to `BUSY_TIMEOUT` of its
    /// own for another process's lock.
    fn opened(mut self) -> Result<Self> {
        wait_for_others(&mut self.conn, None)?;
        Ok(self)
    }

    /// Opens the database at `path` for `access`; every wait for another process's lock
    /// it makes counts from `since`, when the open began.
    fn open_as(path: &Path, access: Access, since: Instant) -> Result<Self> {
        let missing = matches!(std::fs::metadata(path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound);
        if missing && access == Access::Write {
            refuse_dangling_link(path)?;
            create(path)?;
        }
        // Whose the file is, from what it holds, before SQLite opens it to use it: a file
        // this build must refuse is left as it was, and no -wal or -shm file is made for it.
        recognise(path)?;
        refuse_strangers_companions(path)?;
        if access == Access::Write {
            refuse_a_strangers_database(path)?;
        }
        let mut db = match access {
            Access::Read => Self::connect_to_read(path, since)?,
            Access::Write => Self::connect(path, OpenFlags::SQLITE_OPEN_READ_WRITE, since)?,
        };
        // The same checks through SQLite, which also reads what the WAL holds.
        db.schema = db.check(since)?;
        // Again once SQLite has opened them: one planted between the first look and the open.
        refuse_strangers_companions(path)?;
        if access == Access::Read {
            if db.schema < SCHEMA_VERSION {
                // Brought up to date where it can be written; read as it is where it cannot
                // (a read-only disk). This connection is closed first: the upgrade reads the
                // file's header itself, and closing a file drops every POSIX lock the
                // process holds on it, SQLite's too.
                drop(db);
                return Self::open_as(path, Access::Write, since).or_else(|_| {
                    let mut db = Self::connect_to_read(path, since)?;
                    db.schema = db.check(since)?;
                    Ok(db)
                });
            }
            return Ok(db);
        }
        db.conn.pragma_update(None, "foreign_keys", true)?;
        db.migrate(db.schema, since)?;
        db.schema = SCHEMA_VERSION;
        Ok(db)
    }

    /// A connection to `path` with `flags`, waiting for other writers up to `BUSY_TIMEOUT`
    /// from `since`, when the open began.
    fn connect(path: &Path, flags: OpenFlags, since: Instant) -> Result<Self> {
        let mut conn = Connection::open_with_flags(path, flags | OpenFlags::SQLITE_OPEN_NO_MUTEX)
            .with_context(|| {
            format!("{}: could not open the results database", path.display())
        })?;
        wait_for_others(&mut conn, Some(since))?;
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
    fn connect_to_read(path: &Path, since: Instant) -> Result<Self> {
        if read_as_immutable(path)? {
            let conn = open_immutable(path).with_context(|| {
                format!("{}: could not open the results database", path.display())
            })?;
            return Ok(Self {
                conn,
                path: path.to_owned(),
                schema: 0,
            });
        }
        let db = Self::connect(path, OpenFlags::SQLITE_OPEN_READ_ONLY, since)?;
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
                    return Self::connect(path, OpenFlags::SQLITE_OPEN_READ_ONLY, since);
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
    /// returns that schema version. It only reads; `started` is when the open began.
    fn check(&self, started: Instant) -> Result<i64> {
        let shown = self.path.display();
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

    /// Brings the schema from version `from` to this build's; `started` is when the open
    /// began.
    fn migrate(&self, from: i64, started: Instant) -> Result<()> {
        for (i, sql) in MIGRATIONS.iter().enumerate().skip(from as usize) {
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
    pub fn add_all(&mut self, reports: &[BenchResult], source: &str) -> Result<Tally> {
        self.add_fed(source, |add| reports.iter().try_for_each(add))
    }

    /// Adds each result `feed` hands over (from `source`: `bench` or `import`) in one
    /// transaction, as it is handed over: all of them, or none where `feed` or a write
    /// fails. Memory follows one result: an import that gathered every result (and its
    /// JSON) before it wrote any took 1.1 GB for a file of 100 MB.
    pub fn add_fed(
        &mut self,
        source: &str,
        feed: impl FnOnce(&mut dyn FnMut(&BenchResult) -> Result<()>) -> Result<()>,
    ) -> Result<Tally> {
        let added_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        let started = Instant::now();
        let writing = |e| self.error(e, "could not write the results", started);
        let tx = rusqlite::Transaction::new_unchecked(&self.conn, TransactionBehavior::Immediate)
            .map_err(writing)?;
        let mut tally = Tally::default();
        feed(&mut |report| {
            let json = serde_json::to_string(report)?;
            match insert(&tx, report, &json, source, added_unix_s).map_err(writing)? {
                Added::New(_) => tally.new += 1,
                Added::Duplicate(_) => tally.present += 1,
            }
            Ok(())
        })?;
        // Dropped uncommitted where `feed` failed: rolled back, nothing added.
        tx.commit().map_err(writing)?;
        Ok(tally)
    }

    /// The runs `filter` selects, newest first, each as its result says (every column
    /// shown is checked against it: `agrees_with_its_result`). Every run is checked,
    /// whatever the filter, and the filter then selects among the checked runs: a filter
    /// applied to the columns first let a column that lied hide its run from a filtered
    /// command (`list --workload quick` said "no results" of a run whose workload column
    /// said `cover`, its result `quick`) while the unfiltered one refused the database. One
    /// read transaction holds the rows, their results and their scaling rows together; it
    /// also keeps the lock SQLite would otherwise take and drop for each run's every query
    /// (3,000 runs took `list` 0.6 s so, 0.45 s in one, on a loaded machine).
    pub fn runs(&self, filter: &Filter) -> Result<Vec<Run>> {
        self.as_one_read(|db| db.runs_in_one_read(filter))
    }

    /// `runs`, within a read transaction.
    fn runs_in_one_read(&self, filter: &Filter) -> Result<Vec<Run>> {
        // Schema 1 (read where it could not be updated) knows nothing of busy machines.
        let busy = if self.schema >= 2 { "busy" } else { "0" };
        // Each text column's length is read from its record (`octet_length`, which reads no
        // text) before its text: one longer than `MAX_TEXT_BYTES` is read as '' and named
        // in `too_long`, to be refused. A machine id of 300 MB took 1.2 GB (the text,
        // SQLite's copy and `lower` of it for `--machine`) before it was refused as longer
        // than 256 characters.
        let text = |column: &str| {
            format!("CASE WHEN octet_length({column}) > ?1 THEN '' ELSE {column} END AS {column}")
        };
        let too_long = (RUN_TEXTS.iter())
            .map(|column| format!("WHEN octet_length({column}) > ?1 THEN '{column}'"))
            .collect::<Vec<_>>()
            .join(" ");
        let mut stmt = self.conn.prepare(&format!(
            "SELECT id, started_unix_s, {machine_id}, {cpu_model}, logical_cpus, {version},
                    {commit_id}, {simd}, {workload}, {workload_id}, threads, sps_median,
                    sps_min, sps_max, {validation}, {busy}, CASE {too_long} END
             FROM runs
             ORDER BY started_unix_s DESC, id DESC",
            machine_id = text("machine_id"),
            cpu_model = text("cpu_model"),
            version = text("version"),
            commit_id = text("commit_id"),
            simd = text("simd"),
            workload = text("workload"),
            workload_id = text("workload_id"),
            validation = text("validation"),
        ))?;
        // The run being read, to name it where one of its values cannot be.
        let reading = std::cell::Cell::new(None);
        let rows = stmt.query_map(params![MAX_TEXT_BYTES], |r| {
            reading.set(r.get(0).ok());
            let run = Run {
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
                busy: r.get::<_, i64>(15)? != 0,
            };
            Ok((run, r.get::<_, i64>(15)?, r.get::<_, Option<String>>(16)?))
        })?;
        let read = (rows.collect::<rusqlite::Result<Vec<(Run, i64, Option<String>)>>>())
            .map_err(|e| self.unreadable(reading.get(), &stmt, e))?;
        let mut runs = Vec::with_capacity(read.len());
        for (run, busy, too_long) in read {
            self.sound(run.id, "", run.threads, run.sps)?;
            if !(1..=MAX_THREADS as i64).contains(&run.logical_cpus) {
                bail!(self.unsound(
                    run.id,
                    format!(
                        "logical_cpus is {}, not 1 to {MAX_THREADS}",
                        run.logical_cpus
                    )
                ));
            }
            // A run's time orders the runs (`latest`, the workload `rank` shows first, a
            // history's commits), and a run dated 292277026596 stayed the newest of every
            // later one; the busy flag is 0 or 1, and -7 was read as busy. The reader's
            // clock is not the bound: one over a day behind the recording one refused
            // the whole database.
            if !u64::try_from(run.started_unix_s).is_ok_and(is_kept_run_time) {
                bail!(self.unsound(
                    run.id,
                    format!(
                        "started_unix_s is {}, not a time a run took place (2020 to 2100)",
                        run.started_unix_s
                    )
                ));
            }
            if !(0..=1).contains(&busy) {
                bail!(self.unsound(run.id, format!("busy is {busy}, not 0 or 1")));
            }
            // Each text an import takes is at most `MAX_TEXT` characters; one of 50,001
            // (a machine id) failed `history` with SQLite's "LIKE or GLOB pattern too
            // complex", as if the database could not be read.
            let texts = [
                ("machine_id", Some(&run.machine_id)),
                ("cpu_model", run.cpu_model.as_ref()),
                ("version", Some(&run.version)),
                ("commit_id", Some(&run.commit)),
                ("simd", Some(&run.simd)),
                ("workload", Some(&run.workload)),
                ("workload_id", Some(&run.workload_id)),
                ("validation", Some(&run.validation)),
            ];
            for (name, text) in texts {
                if too_long.as_deref() == Some(name)
                    || text.is_some_and(|t| t.chars().count() > MAX_TEXT)
                {
                    bail!(self.unsound(
                        run.id,
                        format!("{name} is longer than {MAX_TEXT} characters")
                    ));
                }
            }
            runs.push(run);
        }
        // Every column shown is what the run's result says, each run's result read and
        // parsed in turn (at most `MAX_RESULT_BYTES`, one at a time): after the checks
        // above, so that a number no import takes is named as such first.
        for run in &runs {
            self.agrees_with_its_result(run)?;
        }
        let most = filter.limit.map_or(usize::MAX, |n| n as usize);
        Ok((runs.into_iter())
            .filter(|run| filter.selects(run))
            .take(most)
            .collect())
    }

    /// Checks that `run`, as its columns and scaling rows give it, is what its stored
    /// result says: the result parses as one an import takes, each column shown (and each
    /// scaling row) is the result's value, and its digest is the result's. An import writes
    /// them from the result; a database made elsewhere may not, and one whose columns said
    /// `valid`, 900 M samples/s, beside a result saying `invalid`, 1 M samples/s, was ranked
    /// and reported by its columns, and ranked otherwise once exported and imported.
    fn agrees_with_its_result(&self, run: &Run) -> Result<()> {
        let id = run.id;
        let (json, digest) = self.result_read(id, true)?;
        let report = BenchResult::parse_kept(json.as_bytes(), "its result")
            .map_err(|why| self.unsound(id, format!("{why:#}")))?;
        let r = &report.result;
        let machine_id = report.machine_id();
        let texts = [
            ("machine_id", Some(&run.machine_id), Some(&machine_id)),
            (
                "cpu_model",
                run.cpu_model.as_ref(),
                report.host.cpu_model.as_ref(),
            ),
            ("version", Some(&run.version), Some(&report.build.version)),
            ("commit_id", Some(&run.commit), Some(&report.build.commit)),
            ("simd", Some(&run.simd), Some(&report.build.simd)),
            ("workload", Some(&run.workload), Some(&report.workload.name)),
            (
                "workload_id",
                Some(&run.workload_id),
                Some(&report.workload.id),
            ),
            (
                "validation",
                Some(&run.validation),
                Some(&report.validation.status),
            ),
        ];
        for (column, says, result_says) in texts {
            if says != result_says {
                let shown = |t: Option<&String>| t.map_or("nothing".to_owned(), |t| quoted(t));
                bail!(self.contradiction(id, column, shown(says), shown(result_says)));
            }
        }
        let counts = [
            (
                "started_unix_s",
                run.started_unix_s,
                report.method.started_unix_s as i64,
            ),
            (
                "logical_cpus",
                run.logical_cpus,
                report.host.logical_cpus as i64,
            ),
            ("threads", run.threads, r.threads as i64),
            (
                "busy",
                i64::from(run.busy),
                i64::from(report.busy.as_ref().is_some_and(|b| b.busy)),
            ),
        ];
        for (column, says, result_says) in counts {
            if says != result_says {
                bail!(self.contradiction(id, column, says.to_string(), result_says.to_string()));
            }
        }
        let s = r.samples_per_sec;
        let sps = SPS_COLUMNS
            .into_iter()
            .zip(run.sps)
            .zip([s.median, s.min, s.max]);
        for ((column, says), result_says) in sps {
            if says != result_says {
                bail!(self.contradiction(id, column, says.to_string(), result_says.to_string()));
            }
        }
        // The scaling rows, fewest threads first, as `scaling` reads them (bounded, each
        // sound) and as the result holds them (each thread count once).
        let rows = self.scaling(id)?;
        let mut of_result: Vec<(i64, [f64; 3])> = (report.scaling.iter())
            .map(|row| {
                let s = row.samples_per_sec;
                (row.threads as i64, [s.median, s.min, s.max])
            })
            .collect();
        of_result.sort_by_key(|&(threads, _)| threads);
        // Both are in order of threads, each count once (the table's key, the result's
        // check): the first place they part is named.
        for i in 0..rows.len().max(of_result.len()) {
            let why = match (rows.get(i), of_result.get(i)) {
                (Some(&(t, says)), Some(&(u, result_says))) if t == u => {
                    let parted = (SPS_COLUMNS.into_iter().zip(says).zip(result_says))
                        .find(|&((_, a), b)| a != b);
                    match parted {
                        Some(((column, a), b)) => format!(
                            "the scaling row of {t} threads: column {column} says {a}, its \
                             result says {b}"
                        ),
                        None => continue,
                    }
                }
                (Some(&(t, _)), Some(&(u, _))) if t > u => {
                    format!("no scaling row of {u} threads, where its result has one")
                }
                (Some(&(t, _)), _) => {
                    format!("a scaling row of {t} threads, where its result has none")
                }
                (None, Some(&(u, _))) => {
                    format!("no scaling row of {u} threads, where its result has one")
                }
                (None, None) => break,
            };
            bail!(self.unsound(id, why));
        }
        // Last, the digest the run is known by (an import of the same result finds it by
        // it), read with the result, its length first, as every text's is.
        let kept = digest_of(&json);
        if digest.as_deref() != Some(kept.as_str()) {
            let says = digest.map_or("more than any digest holds".to_owned(), |d| quoted(&d));
            bail!(self.unsound(
                id,
                format!("column digest says {says}, its result's is {kept}")
            ));
        }
        Ok(())
    }

    /// The error for run `id`, whose `column` says `says` where its result says
    /// `result_says`.
    fn contradiction(
        &self,
        id: i64,
        column: &str,
        says: String,
        result_says: String,
    ) -> anyhow::Error {
        self.unsound(
            id,
            format!("column {column} says {says}, its result says {result_says}"),
        )
    }

    /// Checks that run `id`'s numbers (its headline, or the scaling row `row` names) are ones
    /// an import takes: a thread count of 1 to 65,536 and samples/s of at least 3.125e-8
    /// (a sample in a year), at most 1e12 and in order. The columns hold any number of their type, and a database made
    /// elsewhere may hold 0, a negative rate or infinity, which drew `NaN%` and `-inf`
    /// into the report and ranked nonsense: such a database is refused, naming the run.
    fn sound(&self, id: i64, row: &str, threads: i64, sps: [f64; 3]) -> Result<()> {
        if !(1..=MAX_THREADS as i64).contains(&threads) {
            bail!(self.unsound(
                id,
                format!("{row}threads is {threads}, not 1 to {MAX_THREADS}")
            ));
        }
        for (name, x) in SPS_COLUMNS.into_iter().zip(sps) {
            if !(x.is_finite() && (MIN_SAMPLES_PER_SEC..=MAX_SAMPLES_PER_SEC).contains(&x)) {
                bail!(self.unsound(
                    id,
                    format!(
                        "{row}{name} is {x:e}, not a rate of at least {MIN_SAMPLES_PER_SEC:e} \
                         and at most {MAX_SAMPLES_PER_SEC:e}"
                    )
                ));
            }
        }
        let [median, min, max] = sps;
        if !(min <= median && median <= max) {
            bail!(self.unsound(
                id,
                format!("{row}sps_min, sps_median and sps_max are out of order")
            ));
        }
        Ok(())
    }

    /// The error for a value of run `id` (where known) that `stmt` read but that cannot be
    /// taken as its type: text that is not UTF-8, which SQLite keeps as it is given, and
    /// which tessera never writes. It names the column, not the position in the query.
    fn unreadable(
        &self,
        id: Option<i64>,
        stmt: &rusqlite::Statement,
        e: rusqlite::Error,
    ) -> anyhow::Error {
        let column = |i: usize| stmt.column_name(i).unwrap_or("?").to_owned();
        let (column, why) = match &e {
            rusqlite::Error::Utf8Error(i, _) => (column(*i), "not UTF-8 text".to_owned()),
            rusqlite::Error::FromSqlConversionFailure(i, _, cause) => {
                (column(*i), cause.to_string())
            }
            rusqlite::Error::InvalidColumnType(i, _, found) => (
                column(*i),
                format!("{found} where tessera writes another type"),
            ),
            rusqlite::Error::IntegralValueOutOfRange(i, value) => {
                (column(*i), format!("{value} is out of range"))
            }
            _ => return explain(&self.path, e, "could not read it", Instant::now()),
        };
        let run = id.map_or("a run".to_owned(), |id| format!("run {id}"));
        anyhow!(
            "{}: {run}: {column} cannot be read ({why}); tessera records none such, so the \
             database was changed by something else",
            self.path.display()
        )
    }

    /// The error for run `id` of this database, whose `what` no import makes.
    fn unsound(&self, id: i64, what: String) -> anyhow::Error {
        anyhow!(
            "{}: run {id}: {what}; tessera records none such, so the database was changed by \
             something else",
            self.path.display()
        )
    }
}

impl ResultsDb {
    /// Each thread count's samples/s (median, min, max) of run `id`, fewest threads first.
    /// `runs` checks them against the run's result for every run it returns.
    /// At most `MAX_SCALING_ROWS` are read, as many as an import keeps: a run of more is
    /// refused once one more is read. A run of 3 million rows was read whole (4.8 s,
    /// 103 MB) before its first row out of bounds refused it, and each of 65,536 rows
    /// within bounds was kept, for every run `report` pools.
    pub fn scaling(&self, id: i64) -> Result<Vec<(i64, [f64; 3])>> {
        let mut stmt = self.conn.prepare(
            "SELECT threads, sps_median, sps_min, sps_max FROM scaling
             WHERE run_id = ?1 ORDER BY threads LIMIT ?2",
        )?;
        let most = MAX_SCALING_ROWS as i64;
        let rows = stmt.query_map(params![id, most + 1], |r| {
            Ok((r.get(0)?, [r.get(1)?, r.get(2)?, r.get(3)?]))
        })?;
        let rows = (rows.collect::<rusqlite::Result<Vec<(i64, [f64; 3])>>>())
            .map_err(|e| self.unreadable(Some(id), &stmt, e))?;
        if rows.len() > MAX_SCALING_ROWS {
            bail!(self.unsound(
                id,
                format!("more than {MAX_SCALING_ROWS} scaling rows, more than any result holds")
            ));
        }
        for &(threads, sps) in &rows {
            self.sound(id, "a scaling row's ", threads, sps)?;
        }
        Ok(rows)
    }

    /// How many runs it holds.
    pub fn count(&self) -> Result<usize> {
        let n: i64 = self
            .conn
            .query_row("SELECT count(*) FROM runs", [], |r| r.get(0))?;
        Ok(n as usize)
    }

    /// Run `id`'s result JSON, as it was recorded. Its length is read first, from the
    /// record, without its text: one of more than `MAX_RESULT_BYTES` is refused unread. A
    /// database of 300 MB in one result made `results export` take 1.77 GB and 11 s before
    /// it refused the result as larger than 1024 KiB.
    pub fn result_json(&self, id: i64) -> Result<String> {
        self.result_read(id, false).map(|(json, _)| json)
    }

    /// Run `id`'s result JSON (as `result_json` reads it) and, `with_digest`, its digest in
    /// the same query (None where it is longer than any text an import writes): the check
    /// of a run (`agrees_with_its_result`) read the digest in a query of its own.
    fn result_read(&self, id: i64, with_digest: bool) -> Result<(String, Option<String>)> {
        // `octet_length` of a column reads the length the record gives, not the text.
        let mut stmt = self.conn.prepare(
            "SELECT octet_length(result),
                    CASE WHEN octet_length(result) <= ?2 THEN result END AS result,
                    CASE WHEN octet_length(digest) <= ?3 THEN digest END AS digest
             FROM runs WHERE id = ?1",
        )?;
        let read = stmt.query_row(params![id, MAX_RESULT_BYTES, MAX_TEXT_BYTES], |r| {
            let digest = if with_digest { r.get(2)? } else { None };
            Ok((
                r.get::<_, Option<i64>>(0)?,
                r.get::<_, Option<String>>(1)?,
                digest,
            ))
        });
        match read.map_err(|e| self.unreadable(Some(id), &stmt, e))? {
            (_, Some(json), digest) => Ok((json, digest)),
            (bytes, None, _) => bail!(self.unsound(
                id,
                format!(
                    "result is {} bytes, more than any result tessera keeps ({} KiB)",
                    bytes.unwrap_or(0),
                    MAX_FILE >> 10
                )
            )),
        }
    }

    /// Every run's id, its result's oldest first: `result_json` reads each, one at a time,
    /// so that memory follows one result, not the database.
    pub fn result_ids(&self) -> Result<Vec<i64>> {
        let mut stmt = self
            .conn
            .prepare("SELECT id FROM runs ORDER BY started_unix_s, id")?;
        let rows = stmt.query_map([], |r| r.get(0))?;
        (rows.collect::<rusqlite::Result<Vec<i64>>>()).map_err(|e| self.unreadable(None, &stmt, e))
    }

    /// Runs `read` in one read transaction: every query it makes sees the database as it was
    /// at the first, whatever another process writes meanwhile (an export that checks every
    /// result before it writes any, and then writes them, writes the results it checked).
    /// Within one already, `read` runs in that one.
    pub fn as_one_read<R>(&self, read: impl FnOnce(&Self) -> Result<R>) -> Result<R> {
        if !self.conn.is_autocommit() {
            return read(self);
        }
        let started = Instant::now();
        let snapshot = (self.conn.unchecked_transaction())
            .map_err(|e| self.error(e, "could not read it", started))?;
        let done = read(self);
        // Nothing was written: the transaction ends with a rollback.
        drop(snapshot);
        done
    }
}

/// Refuses the database at `path` where its -wal, -shm or -journal file is there and is
/// another user's (not the database's owner's, this process's user's or root's) or not a
/// plain file. SQLite reads a WAL file's pages in place of the database's, and writes them
/// into it at a checkpoint: in a directory others may write to (`/tmp`), another user who
/// leaves a -wal file of their making beside a database (its checksums are no secret)
/// chooses the rows every command shows, and the rows the next write keeps.
fn refuse_strangers_companions(path: &Path) -> Result<()> {
    use std::os::unix::fs::MetadataExt;
    let Ok(owner) = std::fs::metadata(path).map(|m| m.uid()) else {
        return Ok(());
    };
    let real = companions_base(path);
    for suffix in ["-wal", "-shm", "-journal"] {
        let mut name = real.as_os_str().to_owned();
        name.push(suffix);
        let companion = PathBuf::from(name);
        let Ok(meta) = std::fs::symlink_metadata(&companion) else {
            continue;
        };
        if !meta.file_type().is_file() {
            bail!(
                "{}: not a plain file, so SQLite would not use it; remove it to use {}",
                companion.display(),
                path.display()
            );
        }
        if crate::owner::is_another_users(meta.uid(), &[owner]) {
            bail!(
                "{}: belongs to another user (uid {}; the database is uid {owner}'s, this is \
                 uid {}), and SQLite would take its pages for the database's; remove it to \
                 use {}",
                companion.display(),
                meta.uid(),
                crate::owner::this_user(),
                path.display()
            );
        }
    }
    Ok(())
}

/// Refuses to write to the database at `path` where it is another user's (not this
/// process's user's or root's). It is read as any other (`results` on a colleague's
/// database), but in a directory others may write to (`/tmp`), another user who leaves a
/// database under the name `--db` gives, readable and writable by all, would have every
/// run recorded in it: they would read this user's machines and results, and choose the
/// runs beside them that every command shows.
fn refuse_a_strangers_database(path: &Path) -> Result<()> {
    use std::os::unix::fs::MetadataExt;
    let Ok(owner) = std::fs::metadata(path).map(|m| m.uid()) else {
        return Ok(());
    };
    if crate::owner::is_another_users(owner, &[]) {
        bail!(
            "{}: belongs to another user (uid {owner}; this is uid {}): runs are recorded \
             only in a database of this user's, which no one else reads or changes; \
             `tessera results` still reads this one, and --db names another to record in",
            path.display(),
            crate::owner::this_user()
        );
    }
    Ok(())
}

/// Whether the database at `path` is to be read as an immutable file. SQLite makes a WAL
/// database's -wal and -shm files where they are missing, even to read it, and a -wal or
/// -shm of another user's beside a database is refused by every command
/// (`refuse_strangers_companions`): one `results list` of a colleague's database, readable
/// by all in a shared directory, left theirs there, which its owner could neither use nor
/// remove. So another user's database is read through its -wal and -shm where both are
/// there (its owner's, in use), and as an immutable file where no -wal holds changes (it
/// holds every row then); a -wal of changes without its -shm cannot be read without making
/// one, and is refused. This user's own database is read as immutable where neither
/// companion is there (nor changes in a -wal) and SQLite could not make them for a use
/// that lasts (`companions_cannot_last`).
fn read_as_immutable(path: &Path) -> Result<bool> {
    use std::os::unix::fs::MetadataExt;
    let Ok(owner) = std::fs::metadata(path).map(|m| m.uid()) else {
        return Ok(false);
    };
    let real = companions_base(path);
    let companion = |suffix: &str| {
        let mut name = real.as_os_str().to_owned();
        name.push(suffix);
        std::fs::metadata(PathBuf::from(name)).ok()
    };
    if owner == crate::owner::this_user() {
        let no_changes = companion("-wal").is_none_or(|wal| wal.len() == 0);
        return Ok(no_changes && companion("-shm").is_none() && companions_cannot_last(&real));
    }
    match (companion("-wal"), companion("-shm")) {
        (Some(_), Some(_)) => {
            // Its owner's, in use, and read through SQLite only where this user may read
            // them: one made with its owner's umask (0600) failed as "the database or its
            // directory is read-only (unable to open database file)", which it is not.
            for suffix in ["-wal", "-shm"] {
                let mut name = real.as_os_str().to_owned();
                name.push(suffix);
                if rustix::fs::access(name.as_os_str(), rustix::fs::Access::READ_OK).is_err() {
                    bail!(
                        "{}: another user's database (uid {owner}) whose {suffix} file this \
                         user may not read, and SQLite reads the database through it; left \
                         as it is (read it once its owner has closed it, or ask \
                         them for an export: `tessera results export --jsonl`)",
                        path.display()
                    );
                }
            }
            Ok(false)
        }
        (Some(wal), None) if wal.len() > 0 => bail!(
            "{}: another user's database (uid {owner}) whose -wal file holds changes but \
             has no -shm file: reading them would leave a -shm file of this user's beside \
             it, which would keep its owner out; left as it is (its owner's next use of it \
             writes the changes in)",
            path.display()
        ),
        _ => Ok(true),
    }
}

/// Whether SQLite, reading the database whose file is `real`, could not make its -shm file
/// one that its writes use later: this user may not write the file (a database made
/// read-only, `chmod a-w`), so that a -shm made to read it takes its mode, read-only, and
/// is left behind, after which every write failed as "read-only" even once the file was
/// writable again; or may not add to its directory (a read-only one), where SQLite cannot
/// make one at all and `results list` failed as "attempt to write a readonly database".
/// Nobody but its owner writes such a file, and its owner's writes need the same
/// companions, so an immutable read of it reads every row.
fn companions_cannot_last(real: &Path) -> bool {
    use rustix::fs::Access;
    let dir = match real.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    rustix::fs::access(real, Access::WRITE_OK).is_err()
        || rustix::fs::access(dir, Access::WRITE_OK | Access::EXEC_OK).is_err()
}

/// The name SQLite gives the -wal, -shm and -journal files of the database at `path`:
/// that of the file its links lead to, not the link's. Looked for beside a link's name, a
/// -wal file another user left beside the database itself went unseen, and its rows were
/// listed. Where the path cannot be resolved, SQLite cannot open it either: `path`.
fn companions_base(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_owned())
}

/// The digest a result is kept under: the XXH3-128 of its JSON as stored, in hex.
fn digest_of(json: &str) -> String {
    format!("{:032x}", xxhash_rust::xxh3::xxh3_128(json.as_bytes()))
}

/// `text` of a database as an error quotes it: one line, at most 64 characters.
fn quoted(text: &str) -> String {
    format!("`{}`", crate::text::terminal_safe(text, 64))
}

/// Adds one result in transaction `tx`, unless a result of the same digest is there.
fn insert(
    tx: &rusqlite::Transaction,
    report: &BenchResult,
    json: &str,
    source: &str,
    added_unix_s: i64,
) -> rusqlite::Result<Added> {
    let digest = digest_of(json);
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
            db.migrate(start as i64, Instant::now()).unwrap();
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

    /// One open of a database that another connection holds locked waits once: its first
    /// read and its `quick_check` each waited `BUSY_TIMEOUT` of their own, so `results list`
    /// sat 60 s before saying it gave up after 30. Here the open began `BUSY_TIMEOUT` ago:
    /// every statement of it finds the wait used up, and gives up without a sleep, saying
    /// how long the open waited.
    #[test]
    fn one_open_of_a_locked_database_shares_one_wait() {
        let dir = std::env::temp_dir().join(format!("tessera-db-locked-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("locked.db");
        let _ = std::fs::remove_file(&path);
        // A schema 1 database, in the rollback journal that locks readers out too.
        let holder = Connection::open(&path).unwrap();
        holder.execute_batch(MIGRATIONS[0]).unwrap();
        holder.pragma_update(None, "user_version", 1).unwrap();
        holder.execute_batch("BEGIN EXCLUSIVE").unwrap();
        let Some(long_ago) = Instant::now().checked_sub(BUSY_TIMEOUT) else {
            return;
        };
        SLEPT.with(|n| n.set(0));
        for access in [Access::Read, Access::Write] {
            let e = ResultsDb::open_as(&path, access, long_ago)
                .err()
                .expect("a locked database is not opened")
                .to_string();
            assert!(
                e.contains("another process held the database; gave up after 30."),
                "{e}"
            );
        }
        assert_eq!(
            SLEPT.with(std::cell::Cell::get),
            0,
            "a statement of the open waited anew"
        );
        drop(holder);
        // Unlocked, the same open goes through (and brings the schema up to date).
        let db = ResultsDb::open_as(&path, Access::Read, long_ago)
            .and_then(ResultsDb::opened)
            .unwrap();
        assert_eq!(db.count().unwrap(), 0);
        assert_eq!(db.schema, SCHEMA_VERSION);
        drop(db);
        let _ = std::fs::remove_dir_all(&dir);
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
}
