//! One measurement of `tessera bench` (`tessera::record::measure` makes it): the result as
//! text or JSON, and its record in the results database. A machine that was busy while it
//! ran (load above its CPUs, stolen time) is said in the output: such a run's speed and
//! scaling are not the machine's.

use crate::cli::output::{self, count, note, out};
use anyhow::{Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;
use tessera::atomic_file::write_result_atomically_with;
#[cfg(feature = "results")]
use tessera::record::db::{self, ResultsDb};
use tessera::record::host::{Host, short_commit};
use tessera::record::measure;
use tessera::record::result::BenchResult;

/// A measurement, ready to run.
pub struct Measure {
    /// What is rendered, how often and on which threads and SIMD path.
    pub plan: measure::Plan,
    pub json: bool,
    pub out: Option<PathBuf>,
    /// The results database to record the result in; `None`: not recorded.
    #[cfg_attr(not(feature = "results"), allow(dead_code))]
    pub save: Option<SaveTo>,
}

/// Where `bench` records its result.
#[cfg_attr(not(feature = "results"), allow(dead_code))]
pub struct SaveTo {
    pub path: PathBuf,
    /// Named by `--db` or `TESSERA_DB`: a database that cannot be used is an error. The
    /// default one is only a warning when it cannot be created (a read-only home, a
    /// container); one that exists but cannot be used is an error all the same.
    pub chosen: bool,
}

/// Where to record a result: `--db`'s database, else the default one; none with
/// `--no-save` or in a build without the results database.
pub fn save_to(no_save: bool, db: Option<PathBuf>) -> Option<SaveTo> {
    if no_save || !cfg!(feature = "results") {
        return None;
    }
    match db {
        Some(path) => Some(SaveTo { path, chosen: true }),
        #[cfg(feature = "results")]
        None => db::default_path().map(|path| SaveTo {
            path,
            chosen: false,
        }),
        #[cfg(not(feature = "results"))]
        None => None,
    }
}

/// Measures, reports and records; exit 1 when an image is not the workload's.
pub fn run(m: Measure) -> Result<ExitCode> {
    // Opened (or, where there is none, found makeable) before the renders, so that a
    // database it cannot use stops it at once.
    #[cfg(feature = "results")]
    let db = open_results_db(m.save.as_ref())?;
    let report = measure::measure(&m.plan).context("could not start the thread pool")?;
    let json = tessera::text::ascii_json(&serde_json::to_string_pretty(&report)?) + "\n";
    // The measurement took minutes: where --out cannot take its file (another user's file
    // or pipe put in its place while it ran, in `/tmp`; a full disk), the result is still
    // shown and recorded, its file kept under the temporary name the error gives, and the
    // error said last.
    let written = match &m.out {
        Some(out) => write_result_atomically_with(out, &mut |w| w.write_all(json.as_bytes())),
        None => Ok(()),
    };
    out(&if m.json { json } else { text(&report) })?;
    if let Some(busy) = report.busy.as_ref().filter(|b| b.busy) {
        note(format_args!(
            "tessera: warning: the machine was busy ({}): this result is slower, and scales \
             worse, than the machine does; measure again when it is idle",
            busy.reasons.join("; ")
        ));
    }
    #[cfg(feature = "results")]
    if let Some(record) = db {
        record_result(record, &report)?;
    }
    written?;
    #[cfg(not(feature = "results"))]
    if m.out.is_none() && !m.json {
        note(format_args!(
            "tessera: note: this tessera was built without the results database (cargo \
             feature `results`): --out FILE keeps the result"
        ));
    }
    if report.validation.status == "invalid" {
        // A wrong image makes the speed meaningless: fail, after the result is written for
        // inspection. (Status 2 is kept for bad input.)
        note(format_args!(
            "tessera: the result is INVALID: the image is not the one this workload must produce"
        ));
        return Ok(ExitCode::from(output::NEGATIVE));
    }
    Ok(ExitCode::SUCCESS)
}

/// Where `bench` records its result.
#[cfg(feature = "results")]
enum Record<'a> {
    /// The database there, opened.
    Open(ResultsDb, &'a SaveTo),
    /// None there yet: one is made with the result in it (`ResultsDb::add_to`).
    New(&'a SaveTo),
}

/// Where the results database `save` names records the result: the database opened, or
/// where none is there, its place found makeable (nothing is made before there is a
/// result: a bench stopped while it rendered left a database of no runs); `None` when not
/// saving, or when the default database cannot be made (said as a warning).
#[cfg(feature = "results")]
fn open_results_db(save: Option<&SaveTo>) -> Result<Option<Record<'_>>> {
    let Some(save) = save else {
        return Ok(None);
    };
    let missing = matches!(std::fs::symlink_metadata(&save.path),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound);
    let found = if missing {
        ResultsDb::could_make(&save.path).map(|()| Record::New(save))
    } else {
        ResultsDb::open(&save.path).map(|db| Record::Open(db, save))
    };
    match found {
        Ok(record) => Ok(Some(record)),
        Err(e) if !save.chosen && !save.path.exists() => {
            not_recorded(&e);
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// Records `report` where `record` says. A default database that cannot be made after
/// all (a disk that filled while it rendered) is a warning, as before the renders.
#[cfg(feature = "results")]
fn record_result(record: Record<'_>, report: &BenchResult) -> Result<()> {
    let one = std::slice::from_ref(report);
    let save = match record {
        Record::Open(mut db, save) => {
            db.add_all(one, "bench")?;
            save
        }
        Record::New(save) => match ResultsDb::add_to(&save.path, one, "bench") {
            Ok(_) => save,
            Err(e) if !save.chosen && !save.path.exists() => {
                not_recorded(&e);
                return Ok(());
            }
            Err(e) => return Err(e),
        },
    };
    note(format_args!("tessera: recorded in {}", save.path.display()));
    Ok(())
}

/// Warns that the result is not recorded, the default database being unusable (`e`).
#[cfg(feature = "results")]
fn not_recorded(e: &anyhow::Error) {
    note(format_args!(
        "tessera: warning: the result will not be recorded ({e:#}); choose a database with --db or TESSERA_DB, or pass --no-save"
    ));
}

/// Where the run was confined (a container, a CPU quota, an affinity), as `host`'s last words.
fn confinement_text(h: &Host) -> String {
    let mut limits = Vec::new();
    if let Some(quota) = h.cpu_quota {
        limits.push(format!("a quota of {quota:.2} CPUs"));
    }
    if let Some(n) = h.cpus_allowed {
        limits.push(format!("an affinity of {}", count(n as u64, "CPU")));
    }
    let mut t = h
        .container
        .as_ref()
        .map_or(String::new(), |c| format!("\n  in a {c} container"));
    if !limits.is_empty() {
        t.push_str(if t.is_empty() {
            "\n  under "
        } else {
            " under "
        });
        t.push_str(&limits.join(" and "));
        t.push_str(&format!(": {} usable", h.cpus_usable));
    }
    t
}

/// The report for people.
fn text(r: &BenchResult) -> String {
    let w = &r.workload;
    let h = &r.host;
    let mut t = format!(
        "workload {} ({}): {}x{}, {} spp, depth {}, seed {}\n  id {}\n",
        w.name, w.scene, w.width, w.height, w.spp, w.max_depth, w.seed, w.id
    );
    t.push_str(&format!(
        "build {} {} ({}), SIMD {}\nhost {}, {}{}{}, load {}{}\n",
        r.build.version,
        short_commit(&r.build.commit, 12),
        r.build.rustc,
        r.build.simd,
        h.cpu_model.as_deref().unwrap_or("unknown CPU"),
        count(h.logical_cpus as u64, "CPU"),
        h.physical_cores
            .map_or(String::new(), |c| format!(" ({c} cores)")),
        h.memory_bytes.map_or(String::new(), |b| format!(
            ", {:.1} GiB",
            b as f64 / (1u64 << 30) as f64
        )),
        h.load_average
            .map_or("unknown".into(), |l| format!("{:.2}", l[0])),
        confinement_text(h),
    ));
    t.push_str(&format!(
        "median of {} after {}: {:.2} s wall, {:.3} M samples/s, {:.2} Mrays/s, \
         {:.3} rays/sample, {}\n",
        count(r.method.repeat, "run"),
        count(r.method.warmup, "warm-up"),
        r.result.wall_s.median,
        r.result.samples_per_sec.median / 1e6,
        r.result.mrays_per_sec.median,
        r.result.rays_per_sample,
        count(r.result.threads as u64, "thread"),
    ));
    if r.scaling.len() > 1 {
        t.push_str("threads  M samples/s [min-max]      speedup  efficiency\n");
        for row in &r.scaling {
            let s = row.samples_per_sec;
            t.push_str(&format!(
                "{:>7}  {:<27}  {:>7}  {:>10}\n",
                row.threads,
                format!(
                    "{:.3} [{:.3}-{:.3}]",
                    s.median / 1e6,
                    s.min / 1e6,
                    s.max / 1e6
                ),
                row.speedup.map_or("-".into(), |x| format!("{x:.2}")),
                row.efficiency
                    .map_or("-".into(), |x| format!("{:.0}%", 100.0 * x)),
            ));
        }
    }
    if let Some(busy) = r.busy.as_ref().filter(|b| b.busy) {
        t.push_str(&format!(
            "BUSY: the machine was busy while it ran: {}\n",
            busy.reasons.join("; ")
        ));
    }
    let v = &r.validation;
    t.push_str(&match v.status.as_str() {
        "valid" => format!("valid: every image is {}\n", v.images.join(", ")),
        "invalid" => format!(
            "INVALID: images {}, expected {}\n",
            v.images.join(", "),
            v.expected.as_deref().unwrap_or("-")
        ),
        _ => format!(
            "unvalidated (custom workload): image {}\n",
            v.images.join(", ")
        ),
    });
    t
}
