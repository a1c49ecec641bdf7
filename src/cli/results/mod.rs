//! `tessera results`: the benchmark results kept in the local database (`db`): listing
//! them, importing results other machines made, ranking, comparing and following them over
//! commits (`analysis`), and exporting them. Every text that came from a result is shown
//! escaped, as a result file may come from anyone.

mod analysis;
pub mod db;
mod html;

use super::bench::report::Report;
use super::print_out;
use anyhow::{Result, bail};
use db::{Added, Filter, ResultsDb};
use std::path::PathBuf;

/// What `tessera results` was asked to do.
pub enum ResultsMode {
    List {
        db: PathBuf,
        filter: Filter,
    },
    Import {
        db: PathBuf,
        files: Vec<PathBuf>,
    },
    Rank {
        db: PathBuf,
        workload: String,
        all: bool,
    },
    Compare {
        db: PathBuf,
        a: String,
        b: String,
        workload: Option<String>,
        simd: Option<String>,
    },
    History {
        db: PathBuf,
        machine: String,
        workload: String,
        threads: Option<i64>,
        simd: Option<String>,
    },
    Export {
        db: PathBuf,
    },
    Report {
        db: PathBuf,
        output: PathBuf,
        workload: String,
        all: bool,
    },
}

pub fn run(mode: ResultsMode) -> Result<()> {
    match mode {
        ResultsMode::List { db, filter } => {
            let db = ResultsDb::open_to_read(&db)?;
            print_out(&list(&db.runs(&filter)?))
        }
        ResultsMode::Import { db, files } => {
            // Every file is read and checked before anything is added: one bad file adds
            // nothing.
            let reports = (files.iter())
                .map(|f| Report::read(f))
                .collect::<Result<Vec<_>>>()?;
            let mut db = ResultsDb::open(&db)?;
            let added = db.add_all(&reports, "import")?;
            let new = added.iter().filter(|a| matches!(a, Added::New(_))).count();
            print_out(&format!(
                "imported {new} new result{}, {} already present\n",
                if new == 1 { "" } else { "s" },
                added.len() - new
            ))
        }
        ResultsMode::Rank { db, workload, all } => {
            let db = ResultsDb::open_to_read(&db)?;
            let runs = db.newest_workload_runs(&workload)?;
            print_out(&analysis::rank_text(&analysis::rank(&runs, all), &workload))
        }
        ResultsMode::Compare {
            db,
            a,
            b,
            workload,
            simd,
        } => {
            let db = ResultsDb::open_to_read(&db)?;
            let all = db.runs(&Filter::default())?;
            let side_a = select(&all, &a)?;
            let workload_id = match &workload {
                Some(name) => match all.iter().find(|r| &r.workload == name) {
                    Some(r) => r.workload_id.clone(),
                    None => bail!("no runs of workload `{}`", terminal_safe(name, 32)),
                },
                None => side_a[0].workload_id.clone(),
            };
            // Like with like: both sides on one SIMD path, --simd's or that of A's newest run
            // (of the workload).
            let path = match simd {
                Some(path) => path,
                None => match side_a.iter().find(|r| r.workload_id == workload_id) {
                    Some(r) => r.simd.clone(),
                    None => bail!("{}: no runs of that workload", terminal_safe(&a, 40)),
                },
            };
            let side = |runs: Vec<&db::Run>, what: &str| -> Result<analysis::Scaling> {
                let runs: Vec<_> = (runs.into_iter())
                    .filter(|r| r.workload_id == workload_id && r.simd == path)
                    .collect();
                if runs.is_empty() {
                    bail!(
                        "{}: no runs of that workload on SIMD path {} (--simd chooses another)",
                        terminal_safe(what, 40),
                        terminal_safe(&path, 16)
                    );
                }
                let rows = (runs.iter())
                    .map(|r| db.scaling(r.id))
                    .collect::<Result<Vec<_>>>()?;
                Ok(analysis::pool_scaling(&rows))
            };
            let pa = side(side_a, &a)?;
            let pb = side(select(&all, &b)?, &b)?;
            let (name_a, name_b) = (format!("{a} ({path})"), format!("{b} ({path})"));
            match analysis::compare_text(&name_a, &pa, &name_b, &pb) {
                Some(text) => print_out(&text),
                None => bail!("the two share no thread count"),
            }
        }
        ResultsMode::History {
            db,
            machine,
            workload,
            threads,
            simd,
        } => {
            let db = ResultsDb::open_to_read(&db)?;
            let runs = db.runs(&Filter {
                workload: Some(workload.clone()),
                machine: Some(machine.clone()),
                ..Filter::default()
            })?;
            let mut machines: Vec<&str> = runs.iter().map(|r| r.machine_id.as_str()).collect();
            machines.sort_unstable();
            machines.dedup();
            let id = match machines[..] {
                [] => bail!(
                    "no runs of `{}` on a machine matching `{}`",
                    terminal_safe(&workload, 32),
                    terminal_safe(&machine, 40)
                ),
                [one] => one.to_owned(),
                _ => bail!(
                    "`{}` matches {} machines ({}): give more of a machine id",
                    terminal_safe(&machine, 40),
                    machines.len(),
                    machines
                        .iter()
                        .map(|m| terminal_safe(m, 18))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            };
            let threads = threads.unwrap_or(runs[0].threads);
            let simd = simd.unwrap_or_else(|| runs[0].simd.clone());
            let steps = analysis::history(&runs, threads, &simd);
            if steps.is_empty() {
                bail!(
                    "no runs at {threads} threads on SIMD path {} on {}",
                    terminal_safe(&simd, 16),
                    terminal_safe(&id, 18)
                );
            }
            print_out(&analysis::history_text(&steps, &id, threads, &simd))
        }
        ResultsMode::Report {
            db,
            output,
            workload,
            all,
        } => {
            let db = ResultsDb::open_to_read(&db)?;
            let total_runs = db.count()?;
            let runs: Vec<_> = (db.newest_workload_runs(&workload)?.into_iter())
                .filter(|r| all || r.validation == "valid")
                .collect();
            let ranked = analysis::rank(&runs, all);
            let scaling = (ranked.iter())
                .map(|line| {
                    let rows = (line.ids.iter())
                        .map(|&id| db.scaling(id))
                        .collect::<Result<Vec<_>>>()?;
                    Ok(analysis::pool_scaling(&rows))
                })
                .collect::<Result<Vec<_>>>()?;
            let mut histories = Vec::new();
            let mut seen = std::collections::BTreeSet::new();
            for line in &ranked {
                let machine = &line.example.machine_id;
                if !seen.insert(machine.clone()) {
                    continue;
                }
                let mine: Vec<db::Run> = (runs.iter())
                    .filter(|r| &r.machine_id == machine)
                    .cloned()
                    .collect();
                // At the thread count and SIMD path of the machine's best line.
                let (threads, simd) = (line.threads, line.example.simd.clone());
                let steps = analysis::history(&mine, threads, &simd);
                histories.push((machine.clone(), threads, simd, steps));
            }
            let generated_unix_s = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs() as i64);
            let page = html::render(&html::Report {
                workload: &workload,
                generated_unix_s,
                total_runs,
                ranked: &ranked,
                scaling: &scaling,
                histories: &histories,
            });
            tessera::atomic_file::write_atomically(&output, page.as_bytes())?;
            super::note(format_args!(
                "{}: {} machine and build lines, {} runs",
                output.display(),
                ranked.len(),
                runs.len()
            ));
            Ok(())
        }
        ResultsMode::Export { db } => {
            let db = ResultsDb::open_to_read(&db)?;
            let mut text = String::new();
            for json in db.results_json()? {
                text.push_str(&json);
                text.push('\n');
            }
            print_out(&text)
        }
    }
}

/// The runs `what` names: `run:N` or a number (one run), `machine:ID` or `m-…` (a machine's
/// runs, by its id's start), `commit:HEX` or hex digits (a commit's runs, by its start).
fn select<'a>(runs: &'a [db::Run], what: &str) -> Result<Vec<&'a db::Run>> {
    let (kind, key) = match what.split_once(':') {
        Some((kind @ ("run" | "machine" | "commit"), key)) => (kind, key),
        _ if !what.is_empty() && what.bytes().all(|b| b.is_ascii_digit()) => ("run", what),
        _ if what.starts_with("m-") => ("machine", what),
        _ => ("commit", what),
    };
    if key.is_empty() {
        bail!("`{}`: nothing to select by", terminal_safe(what, 40));
    }
    let chosen: Vec<&db::Run> = match kind {
        "run" => runs.iter().filter(|r| r.id.to_string() == key).collect(),
        "machine" => runs
            .iter()
            .filter(|r| r.machine_id.starts_with(key))
            .collect(),
        _ => runs.iter().filter(|r| r.commit.starts_with(key)).collect(),
    };
    if chosen.is_empty() {
        bail!("`{}` selects no runs ({kind})", terminal_safe(what, 40));
    }
    Ok(chosen)
}

pub use tessera::text::terminal_safe;

/// A Unix time as a UTC date and time, `2026-12-01 19:27`.
pub fn utc(unix_s: i64) -> String {
    let days = unix_s.div_euclid(86_400);
    let secs = unix_s.rem_euclid(86_400);
    // Howard Hinnant's days-to-civil algorithm.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02}",
        secs / 3600,
        secs % 3600 / 60
    )
}

/// The runs as a table, newest first.
fn list(runs: &[db::Run]) -> String {
    if runs.is_empty() {
        return "no results\n".into();
    }
    let mut t = format!(
        "{:>5}  {:<16}  {:<18}  {:<36}  {:<24}  {:<8}  {:>7}  {:<26}  {}\n",
        "run",
        "when (UTC)",
        "machine",
        "CPU",
        "build",
        "workload",
        "threads",
        "M samples/s [min-max]",
        "validation"
    );
    for r in runs {
        let sps = format!(
            "{:.3} [{:.3}-{:.3}]",
            r.sps[0] / 1e6,
            r.sps[1] / 1e6,
            r.sps[2] / 1e6
        );
        t.push_str(&format!(
            "{:>5}  {:<16}  {:<18}  {:<36}  {:<24}  {:<8}  {:>7}  {:<26}  {}\n",
            r.id,
            utc(r.started_unix_s),
            terminal_safe(&r.machine_id, 18),
            terminal_safe(&analysis::cpu(r), 36),
            terminal_safe(&analysis::build(r), 24),
            terminal_safe(&r.workload, 8),
            r.threads,
            sps,
            terminal_safe(&r.validation, 12)
        ));
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_utc_calendar_dates() {
        assert_eq!(utc(0), "1970-01-01 00:00");
        assert_eq!(utc(951_782_400), "2000-02-29 00:00");
        assert_eq!(utc(1_796_145_000), "2026-12-01 17:10");
        assert_eq!(utc(-1), "1969-12-31 23:59");
    }

    #[test]
    fn control_characters_are_escaped_for_terminals() {
        assert_eq!(terminal_safe("AMD EPYC", 20), "AMD EPYC");
        assert_eq!(terminal_safe("x\u{1b}[31mred", 20), "x\\u{1b}[31mred");
        assert_eq!(terminal_safe("abcdef", 3), "abc…");
    }
}
