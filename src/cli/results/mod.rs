//! `tessera results`: the benchmark results kept in the local database (`record::db`):
//! listing them, importing results other machines made, ranking, comparing and following
//! them over commits (`analysis`), a report page (`html`), and exporting them. With no flags
//! each shows the runs the database has, whatever their workload. Every text that came from
//! a result is shown escaped, as a result file may come from anyone.

mod analysis;
mod html;

use super::flags::DbArg;
use super::output::{count, note, out};
use super::writable::{check_output, names_database_file};
use anyhow::{Result, bail};
use clap::Subcommand;
use clap::builder::NonEmptyStringValueParser;
use std::collections::hash_map::Entry;
use std::collections::{HashMap, HashSet};
use std::hash::Hash;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tessera::record::db::{self, Filter, ResultsDb, Run};
use tessera::record::host::Host;
use tessera::record::result::BenchResult;
use tessera::record::stats::{self, Scaling};
use tessera::text::terminal_safe;

/// `tessera results` as typed.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    db: DbArg,
    #[command(subcommand)]
    command: ResultsCommand,
}

#[derive(Subcommand)]
enum ResultsCommand {
    /// The runs, newest first: when, machine, CPU, build, workload, threads, samples/s with
    /// their spread, validation (and `busy` where the machine was).
    List {
        /// Only this workload (`quick`, `cover`, `custom`).
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        workload: Option<String>,
        /// Only this machine: a machine id's start, or part of a CPU model.
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        machine: Option<String>,
        /// Only builds of this commit (its start).
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        commit: Option<String>,
        /// At most this many runs.
        #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = super::flags::positive_u32)]
        limit: Option<u32>,
    },
    /// Add results (JSON files of `bench --out`, or of `export --jsonl`: one result a line)
    /// from other machines; a result already in the database is not added twice, and one
    /// bad file adds nothing.
    Import {
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
    },
    /// One row per machine and build: the median samples/s of its runs at their thread
    /// count, the spread, and per thread; best first; a table for each workload with runs.
    /// Only `valid` runs unless --all.
    Rank {
        /// Only this workload [default: every workload with runs].
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        workload: Option<String>,
        /// Count unvalidated and invalid runs too.
        #[arg(long)]
        all: bool,
    },
    /// Two sets of runs thread count by thread count, each a run number (`results list`),
    /// `latest` or `latest~N` (the Nth run before the newest), a machine (`m-…`) or a
    /// commit (its start); `run:`, `machine:` or `commit:` before it says which. Two runs
    /// compare whatever their SIMD paths; a machine's or a commit's runs are taken on one
    /// path.
    Compare {
        a: String,
        b: String,
        /// The workload (default: that of A's newest run).
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        workload: Option<String>,
        /// The SIMD path of a machine's or commit's runs (default: that of A's newest run).
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        simd: Option<String>,
    },
    /// One machine's speed over commits, flagging a drop beyond the runs' own spread.
    History {
        /// The machine: a machine id's start, or part of a CPU model [default: this machine,
        /// else the newest run's].
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        machine: Option<String>,
        /// The workload [default: that of the machine's newest run].
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        workload: Option<String>,
        /// The thread count (default: that of the machine's newest run).
        #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = super::flags::recorded_threads)]
        threads: Option<usize>,
        /// The SIMD path (default: that of the machine's newest run).
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        simd: Option<String>,
    },
    /// A self-contained HTML report (no script, nothing fetched): for each workload, the
    /// ranking and charts of samples/s by machine, speed against threads, and history
    /// over commits.
    Report {
        /// The HTML file to write.
        #[arg(short, long, required = true)]
        output: PathBuf,
        /// Only this workload [default: every workload with runs].
        #[arg(long, value_parser = NonEmptyStringValueParser::new())]
        workload: Option<String>,
        /// Count unvalidated and invalid runs too.
        #[arg(long)]
        all: bool,
    },
    /// Every result, oldest first, as JSON lines (one result per line).
    Export {
        /// JSON lines (the one format).
        #[arg(long, required = true)]
        jsonl: bool,
    },
}

/// Runs the subcommand on the database `--db` (or `TESSERA_DB`, or the default) names.
pub fn run(args: Args) -> Result<ExitCode> {
    let path = db::resolve(args.db.db)?;
    match args.command {
        ResultsCommand::List {
            workload,
            machine,
            commit,
            limit,
        } => list(
            &path,
            &Filter {
                workload,
                machine,
                commit,
                limit,
            },
        ),
        ResultsCommand::Import { files } => import(&path, &files),
        ResultsCommand::Rank { workload, all } => rank(&path, workload.as_deref(), all),
        ResultsCommand::Compare {
            a,
            b,
            workload,
            simd,
        } => compare(&path, &a, &b, workload.as_deref(), simd.as_deref()),
        ResultsCommand::History {
            machine,
            workload,
            threads,
            simd,
        } => history(
            &path,
            machine.as_deref(),
            workload.as_deref(),
            threads.map(|t| t as i64),
            simd.as_deref(),
        ),
        ResultsCommand::Report {
            output,
            workload,
            all,
        } => report(&path, &output, workload.as_deref(), all),
        ResultsCommand::Export { jsonl: _ } => export(&path),
    }?;
    Ok(ExitCode::SUCCESS)
}

/// `results list`: the runs as a table, newest first.
fn list(path: &Path, filter: &Filter) -> Result<()> {
    let db = ResultsDb::open_to_read(path)?;
    out(&list_text(&db.runs(filter)?))
}

/// `results import`: every file is read and checked before anything is added, so one bad
/// file adds nothing, and the database is not touched for a file it refuses. Both reads
/// keep one result at a time, not the files': gathering every result before adding them
/// took 1.1 GB for a file of 100 MB (and there are as many files as the user names). The
/// second read checks each result again as it adds it, in one transaction, so a file
/// changed between the two adds nothing either.
fn import(path: &Path, files: &[PathBuf]) -> Result<()> {
    let feed = |add: &mut dyn FnMut(&BenchResult) -> Result<()>| {
        (files.iter()).try_for_each(|file| BenchResult::read_each(file, |r| add(&r)))
    };
    feed(&mut |_| Ok(()))?;
    let tally = ResultsDb::add_fed_to(path, "import", feed)?;
    out(&format!(
        "imported {}, {} already present\n",
        count(tally.new as u64, "new result"),
        tally.present
    ))
}

/// The runs of one workload: its name, its id (the scene and settings), and its runs,
/// newest first.
struct WorkloadRuns {
    name: String,
    id: String,
    runs: Vec<Run>,
}

impl WorkloadRuns {
    /// The workload's name, with the start of its id where the name alone is not enough
    /// (`custom` stands for any scene).
    fn title(&self, ambiguous: bool) -> String {
        if ambiguous {
            let id: String = self.id.chars().skip("xxh3-128:".len()).take(12).collect();
            format!("{} (id {id})", self.name)
        } else {
            self.name.clone()
        }
    }
}

/// The runs `workload` names (its newest scene and settings), or every workload's, the
/// workload with the newest run first.
fn workloads(db: &ResultsDb, workload: Option<&str>) -> Result<Vec<WorkloadRuns>> {
    let runs = db.runs(&Filter {
        workload: workload.map(str::to_owned),
        ..Filter::default()
    })?;
    let mut groups: Vec<WorkloadRuns> = grouped(runs, |r| r.workload_id.clone())
        .into_iter()
        .map(|runs| WorkloadRuns {
            name: runs[0].workload.clone(),
            id: runs[0].workload_id.clone(),
            runs,
        })
        .collect();
    // A named workload is its newest scene and settings: `custom` covers several.
    if workload.is_some() {
        groups.truncate(1);
    }
    Ok(groups)
}

/// `items` in groups of one `key`, each group in the order of its items, the groups in the
/// order of their first: each item's group is found in a map. Looking through the groups
/// so far for each item made rank and report's time grow with the square of the runs:
/// 50,000 runs of as many workloads took 105 s to rank, of as many machines over 120 s to
/// report. Every grouping of runs here goes through this one function, whose lookups
/// `grouping_compares_each_item_with_few_others` counts.
fn grouped<T, K: Eq + Hash>(
    items: impl IntoIterator<Item = T>,
    key: impl Fn(&T) -> K,
) -> Vec<Vec<T>> {
    let mut groups: Vec<Vec<T>> = Vec::new();
    let mut index: HashMap<K, usize> = HashMap::new();
    for item in items {
        match index.entry(key(&item)) {
            Entry::Occupied(at) => groups[*at.get()].push(item),
            Entry::Vacant(at) => {
                at.insert(groups.len());
                groups.push(vec![item]);
            }
        }
    }
    groups
}

/// Each group's title: its name, with the start of its id where another group shares the
/// name.
fn titles(groups: &[WorkloadRuns]) -> Vec<String> {
    let shared: HashSet<&str> = grouped(groups, |&g| g.name.as_str())
        .into_iter()
        .filter(|same| same.len() > 1)
        .map(|same| same[0].name.as_str())
        .collect();
    (groups.iter())
        .map(|g| g.title(shared.contains(g.name.as_str())))
        .collect()
}

/// What to say when there is nothing to show.
fn nothing_yet(workload: Option<&str>) -> String {
    match workload {
        Some(w) => format!(
            "no runs of workload `{}` in the database (`results list` shows what there is)\n",
            terminal_safe(w, 32)
        ),
        None => "no results yet: `tessera bench` records a run, `tessera results import` adds \
                 others'\n"
            .to_owned(),
    }
}

/// `results rank`: a table for each workload (or the one named).
fn rank(path: &Path, workload: Option<&str>, all: bool) -> Result<()> {
    let db = ResultsDb::open_to_read(path)?;
    let groups = workloads(&db, workload)?;
    if groups.is_empty() {
        return out(&nothing_yet(workload));
    }
    let mut text = String::new();
    for (i, (group, title)) in groups.iter().zip(titles(&groups)).enumerate() {
        if i > 0 {
            text.push('\n');
        }
        text.push_str(&format!(
            "workload {}: {}\n",
            terminal_safe(&title, 64),
            count(group.runs.len() as u64, "run")
        ));
        let ranked = analysis::rank(&group.runs, all);
        text.push_str(&analysis::rank_text(&ranked, &group.runs, all));
    }
    out(&text)
}

/// `results compare A B`: two runs, or two sets of runs, side by side.
fn compare(
    path: &Path,
    a: &str,
    b: &str,
    workload: Option<&str>,
    simd: Option<&str>,
) -> Result<()> {
    let db = ResultsDb::open_to_read(path)?;
    // One read: the runs checked against their results, and the scaling rows read after,
    // are of one state of the database, whatever another process writes meanwhile.
    db.as_one_read(|db| {
        let all = db.runs(&Filter::default())?;
        let (side_a, a_is_run) = select(&all, a)?;
        let (side_b, b_is_run) = select(&all, b)?;
        let workload_id = match workload {
            Some(name) => match all.iter().find(|r| r.workload == name) {
                Some(r) => r.workload_id.clone(),
                None => bail!("no runs of workload `{}`", terminal_safe(name, 32)),
            },
            None => side_a[0].workload_id.clone(),
        };
        let side_a = of_workload(side_a, &workload_id, &all, a)?;
        let side_b = of_workload(side_b, &workload_id, &all, b)?;
        // Like with like: a machine's or a commit's runs are taken on one SIMD path, --simd's
        // or that of A's newest run; a single run is what it is.
        let path_of_sets = simd.map_or_else(|| side_a[0].simd.clone(), str::to_owned);
        let on_path = |runs: Vec<&Run>, is_run: bool, what: &str| -> Result<(Scaling, String)> {
            let runs: Vec<&Run> = if is_run {
                runs
            } else {
                let on: Vec<&Run> = (runs.into_iter())
                    .filter(|r| r.simd == path_of_sets)
                    .collect();
                if on.is_empty() {
                    bail!(
                        "{}: no runs of that workload on SIMD path {} (--simd chooses another)",
                        terminal_safe(what, 40),
                        terminal_safe(&path_of_sets, 16)
                    );
                }
                on
            };
            let rows = (runs.iter())
                .map(|r| db.scaling(r.id))
                .collect::<Result<Vec<_>>>()?;
            let name = format!(
                "{what} ({}, {})",
                if is_run {
                    format!("run on {}", runs[0].simd)
                } else {
                    format!("{} on {}", count(runs.len() as u64, "run"), path_of_sets)
                },
                analysis::cpu(runs[0])
            );
            Ok((stats::pool_scaling(&rows), name))
        };
        let (pa, name_a) = on_path(side_a, a_is_run, a)?;
        let (pb, name_b) = on_path(side_b, b_is_run, b)?;
        match stats::side_by_side(&name_a, &pa, &name_b, &pb) {
            Some(text) => out(&text),
            None => bail!("the two share no thread count"),
        }
    })
}

/// The runs among `runs` (which `what` selected) of the workload `id`.
fn of_workload<'a>(runs: Vec<&'a Run>, id: &str, all: &[Run], what: &str) -> Result<Vec<&'a Run>> {
    let runs: Vec<&Run> = runs.into_iter().filter(|r| r.workload_id == id).collect();
    if runs.is_empty() {
        let name = all.iter().find(|r| r.workload_id == id);
        bail!(
            "{}: no runs of workload {} (the workload is A's newest run's unless --workload)",
            terminal_safe(what, 40),
            terminal_safe(name.map_or("?", |r| &r.workload), 32)
        );
    }
    Ok(runs)
}

/// `results history`: one machine's speed over commits.
fn history(
    path: &Path,
    machine: Option<&str>,
    workload: Option<&str>,
    threads: Option<i64>,
    simd: Option<&str>,
) -> Result<()> {
    let db = ResultsDb::open_to_read(path)?;
    // One read: the runs checked against their results, and the scaling rows read after,
    // are of one state of the database, whatever another process writes meanwhile.
    db.as_one_read(|db| {
        let all = db.runs(&Filter::default())?;
        let machine = match machine {
            Some(m) => m.to_owned(),
            None => {
                // This machine when it has runs, else the newest run's.
                let here = Host::this().machine_id.unwrap_or_default();
                match all.iter().find(|r| r.machine_id == here).or(all.first()) {
                    Some(r) => r.machine_id.clone(),
                    None => return out(&nothing_yet(None)),
                }
            }
        };
        let mut runs = db.runs(&Filter {
            workload: workload.map(str::to_owned),
            machine: Some(machine.clone()),
            ..Filter::default()
        })?;
        // A machine spelt out whole is that machine, as `compare` takes one: the filter also
        // matches every id that begins so and every CPU model that holds it, and an imported
        // result may claim any such id or model, which made the user's own machine "match 2
        // machines" however much of its id was given.
        if runs.iter().any(|r| r.machine_id == machine) {
            runs.retain(|r| r.machine_id == machine);
        }
        let mut machines: Vec<&str> = runs.iter().map(|r| r.machine_id.as_str()).collect();
        machines.sort_unstable();
        machines.dedup();
        let id = match machines[..] {
            [] => bail!(
                "no runs{} on a machine matching `{}`",
                workload.map_or(String::new(), |w| format!(" of `{}`", terminal_safe(w, 32))),
                terminal_safe(&machine, 40)
            ),
            [one] => one.to_owned(),
            _ => bail!(
                "`{}` matches {} machines ({}): give more of a machine id",
                terminal_safe(&machine, 40),
                machines.len(),
                machines
                    .iter()
                    .map(|m| terminal_safe(m, 48))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        // The workload of the machine's newest run (its scene and settings), unless named.
        let newest = &runs[0];
        let runs: Vec<Run> = (runs.iter())
            .filter(|r| r.workload_id == newest.workload_id)
            .cloned()
            .collect();
        let threads = threads.unwrap_or(newest.threads);
        let simd = simd.map_or_else(|| newest.simd.clone(), str::to_owned);
        let steps = analysis::history(&runs, threads, &simd);
        if steps.is_empty() {
            bail!(
                "no runs of {} at {} on SIMD path {} on {}",
                terminal_safe(&newest.workload, 32),
                count(threads.max(0) as u64, "thread"),
                terminal_safe(&simd, 16),
                terminal_safe(&id, 18)
            );
        }
        out(&analysis::history_text(
            &steps,
            &id,
            &newest.workload,
            threads,
            &simd,
        ))
    })
}

/// `results report`: one HTML page, a section for each workload (or the one named).
fn report(path: &Path, output: &Path, workload: Option<&str>, all: bool) -> Result<()> {
    check_output("-o", output)?;
    // The page replaces whatever file it is written to: the database would be lost, or
    // its write-ahead log and the runs not yet in the database.
    if let Some(what) = names_database_file(output, path) {
        bail!(
            "-o {} names {what}: give the report a name of its own",
            output.display()
        );
    }
    let db = ResultsDb::open_to_read(path)?;
    // One read: the runs checked against their results, and the scaling rows read after,
    // are of one state of the database, whatever another process writes meanwhile.
    db.as_one_read(|db| {
        let total_runs = db.count()?;
        let groups = workloads(db, workload)?;
        let mut sections = Vec::new();
        for (group, title) in groups.iter().zip(titles(&groups)) {
            let runs: Vec<Run> = (group.runs.iter())
                .filter(|r| all || analysis::counts(r))
                .cloned()
                .collect();
            // Each machine's runs, gathered once: looking through every run for each ranked
            // machine took minutes for 50,000 runs of as many machines.
            let by_machine: HashMap<&str, Vec<Run>> = grouped(&runs, |&r| r.machine_id.as_str())
                .into_iter()
                .map(|mine| {
                    let machine = mine[0].machine_id.as_str();
                    (machine, mine.into_iter().cloned().collect())
                })
                .collect();
            let ranked = analysis::rank(&runs, all);
            let scaling = (ranked.iter())
                .map(|line| {
                    let rows = (line.ids.iter())
                        .map(|&id| db.scaling(id))
                        .collect::<Result<Vec<_>>>()?;
                    Ok(stats::pool_scaling(&rows))
                })
                .collect::<Result<Vec<_>>>()?;
            let mut histories = Vec::new();
            let mut seen = std::collections::BTreeSet::new();
            for line in &ranked {
                let machine = &line.example.machine_id;
                if !seen.insert(machine.clone()) {
                    continue;
                }
                let mine = by_machine
                    .get(machine.as_str())
                    .map_or(&[][..], Vec::as_slice);
                // At the thread count and SIMD path of the machine's best line.
                let (threads, simd) = (line.threads, line.example.simd.clone());
                let steps = analysis::history(mine, threads, &simd);
                histories.push(html::History {
                    machine: machine.clone(),
                    threads,
                    simd,
                    steps,
                });
            }
            sections.push(html::Section {
                title,
                runs: group.runs.len(),
                ranked: ranked.iter().map(html::Line::of).collect(),
                scaling,
                histories,
            });
        }
        let generated_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        let page = html::render(&html::ReportPage {
            generated_unix_s,
            total_runs,
            all,
            sections: &sections,
        });
        tessera::atomic_file::write_atomically(output, page.as_bytes())?;
        let lines: usize = sections.iter().map(|s| s.ranked.len()).sum();
        note(format_args!(
            "{}: {} of {}, {} in the database",
            output.display(),
            count(lines as u64, "machine and build line"),
            count(sections.len() as u64, "workload"),
            count(total_runs as u64, "run")
        ));
        Ok(())
    })
}

/// `results export --jsonl`: every result, oldest first. A database tessera did not write may
/// hold a result that is not JSON, JSON over several lines, or JSON that is no result, which
/// would make lines that are not results: it is refused, and nothing is written. Every
/// result is checked before any is written, and then each is read again and written as it
/// comes, in the same read of the database: memory follows one result (at most
/// `MAX_FILE` bytes), not the export, whatever the number of runs.
fn export(path: &Path) -> Result<()> {
    let db = ResultsDb::open_to_read(path)?;
    db.as_one_read(|db| {
        let ids = db.result_ids()?;
        for (n, &id) in ids.iter().enumerate() {
            let json = db.result_json(id)?;
            let not = if json.contains(['\n', '\r']) {
                Some("it spans lines".to_owned())
            } else {
                serde_json::from_str::<serde::de::IgnoredAny>(&json)
                    .err()
                    .map(|e| format!("not JSON: {e}"))
            };
            if let Some(not) = not {
                bail!(
                    "{}: result {} (oldest first) is not one line of JSON ({not}); tessera \
                     writes none such: nothing exported",
                    path.display(),
                    n + 1
                );
            }
            // A line of JSON that no import takes would make an export that does not import.
            if let Err(why) = BenchResult::parse_kept(json.as_bytes(), "it") {
                bail!(
                    "{}: result {} (oldest first) is not a result an import takes ({why:#}); \
                     tessera writes none such: nothing exported",
                    path.display(),
                    n + 1
                );
            }
        }
        for id in ids {
            let mut line = tessera::text::ascii_json(&db.result_json(id)?);
            line.push('\n');
            out(&line)?;
        }
        Ok(())
    })
}

/// The runs `what` names, and whether it names one run: `run:N` or a number (one run),
/// `latest` or `latest~N` (the newest run, or the Nth before it), `machine:ID` or `m-…` (a
/// machine's runs, by its id's start), `commit:HEX` or hex digits (a commit's runs, by its
/// start). `runs` are newest first.
fn select<'a>(runs: &'a [Run], what: &str) -> Result<(Vec<&'a Run>, bool)> {
    if let Some(back) = what.strip_prefix("latest") {
        let n = match back.strip_prefix('~') {
            None if back.is_empty() => Some(0),
            Some(n) => n.parse::<usize>().ok(),
            None => None,
        };
        let Some(n) = n else {
            bail!(
                "`{}`: write latest, or latest~N for the Nth run before it",
                terminal_safe(what, 40)
            );
        };
        return match runs.get(n) {
            Some(run) => Ok((vec![run], true)),
            None => bail!(
                "`{}`: the database holds {}",
                terminal_safe(what, 40),
                count(runs.len() as u64, "run")
            ),
        };
    }
    let (kind, key) = match what.split_once(':') {
        Some((kind @ ("run" | "machine" | "commit"), key)) => (kind, key),
        _ if !what.is_empty() && what.bytes().all(|b| b.is_ascii_digit()) => ("run", what),
        _ if what.starts_with("m-") => ("machine", what),
        _ => ("commit", what),
    };
    if key.is_empty() {
        bail!("`{}`: nothing to select by", terminal_safe(what, 40));
    }
    let chosen: Vec<&Run> = match kind {
        "run" => runs.iter().filter(|r| r.id.to_string() == key).collect(),
        "machine" => one_of(runs, what, key, "machines", |r| &r.machine_id)?,
        _ => one_of(runs, what, key, "commits", |r| &r.commit)?,
    };
    if chosen.is_empty() {
        bail!(
            "`{}` selects no runs ({kind}; `results list` numbers the runs)",
            terminal_safe(what, 40)
        );
    }
    Ok((chosen, kind == "run"))
}

/// The runs of the one machine or commit (`of` gives a run's) that `key` names: the one it
/// spells out whole, else the one it is the start of. A start shared by several is refused,
/// naming them, as `history` refuses one: their runs pooled under the first's name would
/// be one side of a comparison that no single machine or commit measured, and an imported
/// result may claim any id that begins as the user's does.
fn one_of<'a>(
    runs: &'a [Run],
    what: &str,
    key: &str,
    kinds: &str,
    of: impl Fn(&Run) -> &String,
) -> Result<Vec<&'a Run>> {
    let exact: Vec<&Run> = runs.iter().filter(|r| of(r) == key).collect();
    if !exact.is_empty() {
        return Ok(exact);
    }
    let chosen: Vec<&Run> = runs.iter().filter(|r| of(r).starts_with(key)).collect();
    let mut names: Vec<&str> = chosen.iter().map(|r| of(r).as_str()).collect();
    names.sort_unstable();
    names.dedup();
    if names.len() > 1 {
        const SHOWN: usize = 8;
        let mut listed: Vec<String> = (names.iter().take(SHOWN))
            .map(|n| terminal_safe(n, 48))
            .collect();
        if names.len() > SHOWN {
            listed.push(format!("{} more", names.len() - SHOWN));
        }
        bail!(
            "`{}` is the start of {} {kinds} ({}): give more of one",
            terminal_safe(what, 40),
            names.len(),
            listed.join(", ")
        );
    }
    Ok(chosen)
}

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
fn list_text(runs: &[Run]) -> String {
    if runs.is_empty() {
        return "no results\n".into();
    }
    let mut t = format!(
        "{:>5}  {:<16}  {:<18}  {:<36}  {:<30}  {:<8}  {:>7}  {:<26}  {}\n",
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
            "{:>5}  {:<16}  {:<18}  {:<36}  {:<30}  {:<8}  {:>7}  {:<26}  {}\n",
            r.id,
            utc(r.started_unix_s),
            terminal_safe(&r.machine_id, 18),
            terminal_safe(&analysis::cpu(r), 36),
            terminal_safe(&analysis::build(r), 30),
            terminal_safe(&r.workload, 8),
            r.threads,
            sps,
            if r.busy {
                format!("{} (busy)", terminal_safe(&r.validation, 12))
            } else {
                terminal_safe(&r.validation, 12)
            }
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

    /// A key whose comparisons are counted.
    struct Counted<'a> {
        key: u32,
        compared: &'a std::cell::Cell<u64>,
    }

    impl PartialEq for Counted<'_> {
        fn eq(&self, other: &Self) -> bool {
            self.compared.set(self.compared.get() + 1);
            self.key == other.key
        }
    }
    impl Eq for Counted<'_> {}
    impl Hash for Counted<'_> {
        fn hash<H: std::hash::Hasher>(&self, h: &mut H) {
            self.key.hash(h);
        }
    }

    /// Rank and report group runs by workload, name and machine (`grouped`). Found by
    /// looking through the groups so far, 50,000 runs of as many workloads took 105 s to
    /// rank: each run was compared with every group before it. Counted, not timed: 20,000
    /// items of as many keys (which that search compares 200 million times), and of one
    /// key, are each compared with at most a few others.
    #[test]
    fn grouping_compares_each_item_with_few_others() {
        const N: u32 = 20_000;
        for distinct in [true, false] {
            let compared = std::cell::Cell::new(0);
            let items: Vec<u32> = (0..N).map(|i| if distinct { i } else { 7 }).collect();
            let groups = grouped(items, |&key| Counted {
                key,
                compared: &compared,
            });
            assert_eq!(groups.len(), if distinct { N as usize } else { 1 });
            assert_eq!(groups.iter().map(Vec::len).sum::<usize>(), N as usize);
            assert!(
                compared.get() <= 2 * u64::from(N),
                "{} comparisons grouping {N} items (distinct keys: {distinct})",
                compared.get()
            );
        }
        // In the order of their first items, each in its items' order.
        let words = ["b", "a", "b", "c", "a"];
        let groups = grouped(words.iter().enumerate(), |&(_, w)| *w);
        let order: Vec<Vec<usize>> = (groups.iter())
            .map(|g| g.iter().map(|&(i, _)| i).collect())
            .collect();
        assert_eq!(order, [vec![0, 2], vec![1, 4], vec![3]]);
    }

    #[test]
    fn control_characters_are_escaped_for_terminals() {
        assert_eq!(terminal_safe("AMD EPYC", 20), "AMD EPYC");
        assert_eq!(terminal_safe("x\u{1b}[31mred", 20), "x\\u{1b}[31mred");
        assert_eq!(terminal_safe("abcdef", 3), "abc…");
    }
}
