//! A results database as a file: what its header and schema say it is (tessera's, another
//! program's, damaged), opened read-only where the disk is, and a new one made whole under a
//! temporary name and published once.

use super::{APPLICATION_ID, APPLICATION_ID_SINCE, MIGRATIONS, ResultsDb, SCHEMA_VERSION, explain};
use crate::text::terminal_safe;
use anyhow::{Context, Result, bail};
use rusqlite::{Connection, OpenFlags};
use std::fmt::Write as _;
use std::io::Read;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{DirBuilderExt, PermissionsExt};
use std::path::Path;
use std::time::Instant;

/// SQLite's file header.
const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The length of SQLite's file header.
const HEADER_LEN: usize = 100;

/// What a file's first 100 bytes (SQLite's header) say it is.
#[derive(Debug, PartialEq)]
pub(super) enum Header {
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
    pub(super) fn parse(head: &[u8]) -> Self {
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

/// Whose a database of `application_id` and `user_version` is: its schema version where it
/// is a tessera results database this build can use, else why not. `schema_difference`
/// says how its schema differs from tessera's of a version, if it does: schemas 1 and 2,
/// which carry no application_id, are recognised by it, and one with tessera's
/// application_id must hold it too, so that a crafted file's views, triggers or columns
/// (a recursive view that never ends, a trigger on every insert) are never run.
pub(super) fn whose(
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
pub(super) fn recognise(path: &Path) -> Result<()> {
    let shown = path.display();
    // Opened without blocking and checked by its handle: a pipe swapped in for the file
    // after a look at its name (by another user, in `/tmp`) would wait for a writer forever.
    let file = match crate::input_file::open_regular(path) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => {
            bail!("{shown}: not a file: the results database must be one ({e})")
        }
        Err(e) => return Err(e).context(format!("{shown}: could not open the results database")),
    };
    let mut head = Vec::with_capacity(HEADER_LEN);
    file.take(HEADER_LEN as u64)
        .read_to_end(&mut head)
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
pub(super) fn schema_difference(
    conn: &Connection,
    version: i64,
) -> rusqlite::Result<Option<String>> {
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
pub(super) fn tessera_schema(version: i64) -> rusqlite::Result<Vec<SchemaObject>> {
    let conn = Connection::open_in_memory()?;
    let upto = usize::try_from(version).unwrap_or(0).min(MIGRATIONS.len());
    for migration in &MIGRATIONS[..upto] {
        conn.execute_batch(migration)?;
    }
    schema_objects(&conn, usize::MAX)
}

/// Up to `limit` objects of the schema of `conn`, sorted, each name and statement cut at a
/// length that no object of tessera's reaches.
pub(super) fn schema_objects(
    conn: &Connection,
    limit: usize,
) -> rusqlite::Result<Vec<SchemaObject>> {
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
pub(super) fn normalise_sql(sql: &str) -> String {
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
pub(super) fn open_immutable(path: &Path) -> rusqlite::Result<Connection> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY
        | OpenFlags::SQLITE_OPEN_URI
        | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let conn = Connection::open_with_flags(immutable_uri(path), flags)?;
    conn.pragma_update(None, "trusted_schema", false)?;
    Ok(conn)
}

/// The SQLite URI of `path` opened as immutable: each byte but the unreserved ones and `/`
/// percent-encoded, so that no `?`, `#` or `%` in a name is read as part of the URI.
pub(super) fn immutable_uri(path: &Path) -> String {
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
pub(super) fn cannot_open_wal_files(e: &rusqlite::Error) -> bool {
    matches!(
        e.sqlite_error_code(),
        Some(rusqlite::ErrorCode::CannotOpen) | Some(rusqlite::ErrorCode::ReadOnly)
    )
}

/// Whether reading `path` as immutable reads what it holds: it lies on a read-only file
/// system (so nobody writes it while it is read), and no -wal file holds changes that an
/// immutable read would not see.
pub(super) fn immutable_there(path: &Path) -> bool {
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
pub(super) fn create(path: &Path) -> Result<()> {
    create_with(path, |_| Ok(())).map(drop)
}

/// Makes a new database at `path` as `create` does, with `fill` run on it before it is
/// published: what `fill` writes is there from the first moment anyone sees it, and where
/// `fill` fails nothing is published. It gives what `fill` gave where this one was
/// published, and None where another process published one first (then `fill`'s rows are
/// not in it).
pub(super) fn create_with<T>(
    path: &Path,
    fill: impl FnOnce(&mut ResultsDb) -> Result<T>,
) -> Result<Option<T>> {
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
    let built = build_new(&made, path, fill);
    if built.is_err() {
        // What SQLite could not finish (on a full disk) leaves its -wal and -shm files
        // behind: they go with the temporary file.
        for suffix in ["-wal", "-shm"] {
            let mut side = made.as_os_str().to_owned();
            side.push(suffix);
            let _ = std::fs::remove_file(side);
        }
    }
    let filled = built?;
    match std::fs::hard_link(&made, path) {
        // Ours, or another process's made first: either is whole.
        Ok(()) => Ok(Some(filled)),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(None),
        // A file system without hard links: renamed instead, where nothing is there yet.
        Err(e) if links_refused(&e) => match made.persist_noclobber(path) {
            Ok(()) => Ok(Some(filled)),
            Err(e) if e.error.kind() == std::io::ErrorKind::AlreadyExists => Ok(None),
            Err(e)
                if std::fs::symlink_metadata(path)
                    .is_err_and(|m| m.kind() == std::io::ErrorKind::NotFound) =>
            {
                e.path
                    .persist(path)
                    .map(|()| Some(filled))
                    .map_err(|e| e.error)
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
pub(super) fn refuse_dangling_link(path: &Path) -> Result<()> {
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
/// messages), runs `fill` on it, and closes it.
pub(super) fn build_new<T>(
    made: &Path,
    path: &Path,
    fill: impl FnOnce(&mut ResultsDb) -> Result<T>,
) -> Result<T> {
    let started = Instant::now();
    let mut db = ResultsDb::connect(made, OpenFlags::SQLITE_OPEN_READ_WRITE, started)?;
    // Messages name the database being made, not its temporary name.
    db.path = path.to_owned();
    db.conn
        .pragma_update(None, "journal_mode", "wal")
        .map_err(|e| db.error(e, "could not create it", started))?;
    db.migrate(0, started)?;
    db.conn.pragma_update(None, "foreign_keys", true)?;
    let filled = fill(&mut db)?;
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
    Ok(filled)
}

/// Whether `e` is a file system refusing hard links.
pub(super) fn links_refused(e: &std::io::Error) -> bool {
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
    fn a_pipe_swapped_in_for_a_database_is_not_waited_on() {
        use std::sync::Arc;
        use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
        let dir = std::env::temp_dir().join(format!("tessera-db-swap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (file, pipe, db) = (dir.join("file"), dir.join("pipe"), dir.join("r.db"));
        std::fs::write(&file, header(100, APPLICATION_ID, SCHEMA_VERSION as u32)).unwrap();
        rustix::fs::mkfifoat(rustix::fs::CWD, &pipe, rustix::fs::Mode::from(0o644)).unwrap();
        // Another user, in `/tmp`, puts a file and a pipe in the database's place by turns.
        let stop = Arc::new(AtomicBool::new(false));
        let swapper = {
            let (stop, dir, db) = (Arc::clone(&stop), dir.clone(), db.clone());
            let (file, pipe) = (file.clone(), pipe.clone());
            std::thread::spawn(move || {
                let next = dir.join("next");
                while !stop.load(Ordering::Relaxed) {
                    for what in [&file, &pipe] {
                        let _ = std::fs::remove_file(&next);
                        std::fs::hard_link(what, &next).unwrap();
                        std::fs::rename(&next, &db).unwrap();
                    }
                }
            })
        };
        const LOOKS: u64 = 20_000;
        let looked = Arc::new(AtomicU64::new(0));
        let checker = {
            let (looked, db) = (Arc::clone(&looked), db.clone());
            std::thread::spawn(move || {
                while looked.load(Ordering::Relaxed) < LOOKS {
                    let _ = recognise(&db);
                    looked.fetch_add(1, Ordering::Relaxed);
                }
            })
        };
        // Each look takes microseconds; one that makes no progress for 30 s waits on the pipe.
        let (mut last, mut since) = (0, Instant::now());
        while !checker.is_finished() {
            let now = looked.load(Ordering::Relaxed);
            if now != last {
                (last, since) = (now, Instant::now());
            } else if since.elapsed() > std::time::Duration::from_secs(30) {
                stop.store(true, Ordering::Relaxed);
                // Let the waiting open go, so that the test ends.
                let _ = std::fs::OpenOptions::new().write(true).open(&pipe);
                panic!("recognise waited on a pipe after {now} looks");
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        stop.store(true, Ordering::Relaxed);
        swapper.join().unwrap();
        checker.join().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
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
