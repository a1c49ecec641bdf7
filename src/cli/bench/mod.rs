//! `tessera bench`: a benchmark anyone can trust and compare. It renders a named, fixed
//! workload (or a custom scene) after a warm-up, repeatedly at each thread count (1, 2, 4, …,
//! every CPU), checks every image against the hash the workload must produce, and reports the
//! medians with their spread, as text or JSON with the build and host (`measure`), recorded
//! in the results database. `--compare` sets two result files side by side; `--chart` draws
//! them.

mod measure;

use super::charts;
use super::flags::{self, DbArg, SimdArg};
use super::output::{note, out};
use super::writable::{check_output, names_database_file, same_file};
use anyhow::{Result, bail};
use measure::Measure;
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::ExitCode;
use tessera::atomic_file::{write_atomically, write_result_atomically_with};
use tessera::record::result::{BenchResult, MAX_RUNS};
use tessera::record::stats::{self, Scaling};
use tessera::record::workload::{self, Workload, hash_text};
use tessera::render::{self, RenderOptions};
use tessera::scene::Overrides;
use tessera::text::terminal_safe;

/// `tessera bench` as typed.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file of a custom workload (default: the standard workload --workload names).
    scene: Option<PathBuf>,
    /// Standard workload: `quick` (default, seconds) or `cover` (the full book cover);
    /// `--list` describes them. Its image is checked against the hash it must produce.
    /// With `--write-workloads`, it may repeat: only those are rendered.
    #[arg(long, conflicts_with = "scene", value_name = "NAME")]
    workload: Vec<String>,
    /// Image width of a custom workload.
    #[arg(long, requires = "scene", value_name = "PX", allow_negative_numbers = true, value_parser = flags::positive_u32)]
    width: Option<u32>,
    /// Samples per pixel of a custom workload.
    #[arg(long, requires = "scene", value_name = "N", allow_negative_numbers = true, value_parser = flags::positive_u32)]
    spp: Option<u32>,
    /// Threads of the headline result (default: every CPU).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = flags::threads)]
    threads: Option<usize>,
    #[command(flatten)]
    simd: SimdArg,
    /// Measured renders per thread count; the median is reported with min and max.
    #[arg(long, value_name = "N", default_value_t = 3, allow_negative_numbers = true, value_parser = flags::positive_u32)]
    repeat: u32,
    /// Renders before measuring, not counted.
    #[arg(long, value_name = "N", default_value_t = 1, allow_negative_numbers = true, value_parser = flags::whole_u32)]
    warmup: u32,
    /// Measure only the headline thread count, not 1, 2, 4, … every CPU.
    #[arg(long)]
    no_scaling: bool,
    /// Print the JSON result instead of text.
    #[arg(long)]
    json: bool,
    /// Also write the JSON result to FILE (atomically).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    #[command(flatten)]
    db: DbArg,
    /// Do not record the result in the results database.
    #[arg(long)]
    no_save: bool,
    /// Compare two JSON results of the same workload, thread count by thread count.
    #[arg(long, num_args = 2, value_names = ["OLD", "NEW"], conflicts_with_all = ["scene", "workload"])]
    compare: Option<Vec<PathBuf>>,
    /// Draw samples/s against threads of JSON results as an SVG chart: `--chart OUT.svg A.json [B.json …]`.
    #[arg(long, num_args = 2.., value_names = ["SVG", "RESULT"], conflicts_with_all = ["scene", "workload", "compare"])]
    chart: Option<Vec<PathBuf>>,
    /// List the standard workloads.
    #[arg(long)]
    list: bool,
    /// Render each standard workload once and write the workloads file with their image
    /// hashes (after a deliberate change of the image): `--write-workloads benches/workloads.toml`;
    /// with `--workload NAME …`, only those, the others keeping the hashes built in.
    #[arg(long, value_name = "FILE")]
    write_workloads: Option<PathBuf>,
}

/// What `tessera bench` is asked to do, checked.
enum BenchMode {
    Measure(Box<Measure>),
    Compare {
        old: PathBuf,
        new: PathBuf,
    },
    Chart {
        out: PathBuf,
        results: Vec<PathBuf>,
    },
    List,
    WriteWorkloads {
        path: PathBuf,
        options: RenderOptions,
        /// The workloads to render (none: all); the others keep their hashes.
        only: Vec<String>,
    },
}

/// Checks `args` and runs what they ask for.
pub fn run(args: Args) -> Result<ExitCode> {
    match BenchMode::new(args)? {
        BenchMode::Measure(m) => measure::run(*m),
        BenchMode::Compare { old, new } => {
            out(&compare_files(
                &BenchResult::read(&old)?,
                &BenchResult::read(&new)?,
            )?)?;
            Ok(ExitCode::SUCCESS)
        }
        BenchMode::Chart { out, results } => {
            let results = (results.iter())
                .map(|p| BenchResult::read(p))
                .collect::<Result<Vec<_>>>()?;
            let ids: BTreeSet<_> = results.iter().map(|r| &r.workload.id).collect();
            if ids.len() > 1 {
                bail!("the results measure different workloads: chart one at a time");
            }
            let lines: Vec<(String, Scaling)> = (results.iter())
                .map(|r| (r.label(), stats::scaling_of(r)))
                .collect();
            if lines.len() > charts::COLOURS.len() {
                note(format_args!(
                    "tessera: note: the chart shows the first {} of the {} results",
                    charts::COLOURS.len(),
                    lines.len()
                ));
            }
            let w = &results[0].workload;
            let title = format!(
                "tessera bench: {} ({}x{}, {} spp)",
                w.name, w.width, w.height, w.spp
            );
            write_atomically(
                &out,
                charts::scaling_svg_document(&title, &lines).as_bytes(),
            )?;
            Ok(ExitCode::SUCCESS)
        }
        BenchMode::List => {
            let mut text = String::new();
            for w in workload::standard() {
                text.push_str(&format!(
                    "{:<8} {} ({} at {} wide, {} spp)\n",
                    w.name, w.about, w.scene, w.width, w.spp
                ));
            }
            out(&text)?;
            Ok(ExitCode::SUCCESS)
        }
        BenchMode::WriteWorkloads {
            path,
            options,
            only,
        } => {
            let text = workload::with_new_hashes(&mut |w| {
                if !only.is_empty() && !only.contains(&w.name) {
                    note(format_args!("{}: {} (kept, not rendered)", w.name, w.image));
                    return Ok(w.image.clone());
                }
                let workload = Workload::from_standard(w)?;
                let (film, _) = render::render(&workload.scene, &options, &|_| {})?;
                let hash = hash_text(film.content_hash());
                if hash == w.image {
                    note(format_args!("{}: {hash} (rendered, unchanged)", w.name));
                } else {
                    note(format_args!(
                        "{}: {hash} (rendered, changed from {})",
                        w.name, w.image
                    ));
                }
                Ok(hash)
            })?;
            // Each workload's render took minutes: a file that cannot be put in place (another
            // user's, made in `/tmp` while they ran) is kept under the name the error gives.
            write_result_atomically_with(&path, &mut |w| w.write_all(text.as_bytes()))?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

impl BenchMode {
    fn new(args: Args) -> Result<Self> {
        if let Some(files) = args.compare {
            let [old, new] = <[PathBuf; 2]>::try_from(files)
                .map_err(|_| anyhow::anyhow!("--compare takes two result files"))?;
            return Ok(Self::Compare { old, new });
        }
        if let Some(mut files) = args.chart {
            let out = files.remove(0);
            check_output("--chart", &out)?;
            // The chart replaces whatever file it is written to: a result it draws would be lost.
            if let Some(result) = files.iter().find(|r| same_file(&out, r)) {
                bail!(
                    "--chart {} names the same file as the result {}: give the chart a name \
                     of its own",
                    out.display(),
                    result.display()
                );
            }
            // Nor is the results database (`--db`, TESSERA_DB or the default) or its
            // write-ahead log: every run recorded would be lost.
            if let Some(save) = measure::save_to(false, args.db.db)
                && let Some(what) = names_database_file(&out, &save.path)
            {
                bail!(
                    "--chart {} names {what}: give the chart a name of its own",
                    out.display()
                );
            }
            return Ok(Self::Chart {
                out,
                results: files,
            });
        }
        if args.list {
            return Ok(Self::List);
        }
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = args.threads.unwrap_or(cpus);
        let simd = args.simd.path()?;
        if let Some(path) = args.write_workloads {
            check_output("--write-workloads", &path)?;
            // The workloads file replaces whatever file it is written to.
            if let Some(save) = measure::save_to(false, args.db.db.clone())
                && let Some(what) = names_database_file(&path, &save.path)
            {
                bail!(
                    "--write-workloads {} names {what}: the workloads file goes elsewhere \
                     (benches/workloads.toml)",
                    path.display()
                );
            }
            let options = RenderOptions {
                threads: Some(threads),
                tile: render::DEFAULT_TILE,
                simd,
            };
            for name in &args.workload {
                workload::standard_named(name)?;
            }
            return Ok(Self::WriteWorkloads {
                path,
                options,
                only: args.workload,
            });
        }
        if args.workload.len() > 1 {
            bail!(
                "--workload: bench measures one workload at a time (several only with --write-workloads)"
            );
        }
        let workload = match &args.scene {
            Some(scene) => {
                let overrides = Overrides {
                    width: args.width,
                    samples_per_pixel: args.spp,
                    ..Overrides::default()
                };
                Workload::custom(scene, &overrides)?
            }
            None => {
                let default = workload::standard().first().map(|w| w.name.clone());
                let name = args
                    .workload
                    .into_iter()
                    .next()
                    .or(default)
                    .unwrap_or_default();
                Workload::named(&name)?
            }
        };
        if let Some(out) = &args.out {
            check_output("--out", out)?;
            // The result replaces whatever file it is written to: the scene measured would be
            // lost.
            if let Some(scene) = args.scene.as_deref().filter(|s| same_file(out, s)) {
                bail!(
                    "--out {} names the scene file measured, {}: give the result a name of its own",
                    out.display(),
                    scene.display()
                );
            }
        }
        let scaling = tessera::record::measure::scaling_counts(cpus);
        // The result keeps every run's rate: too many make a result no import reads.
        let mut counts = if args.no_scaling {
            Vec::new()
        } else {
            scaling.clone()
        };
        counts.push(threads);
        counts.sort_unstable();
        counts.dedup();
        let kept = args.repeat as usize * (counts.len() + 1);
        if kept > MAX_RUNS {
            bail!(
                "--repeat {r}: a result keeps every run's rate, {r} at each of {} and again \
                 for the headline: {kept}, more than the {MAX_RUNS} a result may hold (an \
                 import reads at most 1 MiB); at most --repeat {}",
                tessera::text::count(counts.len() as u64, "thread count"),
                MAX_RUNS / (counts.len() + 1),
                r = args.repeat,
            );
        }
        let save = measure::save_to(args.no_save, args.db.db);
        // The result file replaces whatever file it is written to: the database would be
        // lost, every earlier run with it (or, for its write-ahead log, the runs not yet in it).
        if let (Some(out), Some(save)) = (&args.out, &save)
            && let Some(what) = names_database_file(out, &save.path)
        {
            bail!(
                "--out {} names {what} the result is recorded in: give it a name of its own \
                 (or --no-save)",
                out.display()
            );
        }
        Ok(Self::Measure(Box::new(Measure {
            plan: tessera::record::measure::Plan {
                workload,
                threads,
                scaling: if args.no_scaling { Vec::new() } else { scaling },
                repeat: args.repeat,
                warmup: args.warmup,
                simd,
                simd_chosen: args.simd.is_chosen(),
            },
            json: args.json,
            out: args.out,
            save,
        })))
    }
}

/// Two result files side by side, thread count by thread count.
fn compare_files(old: &BenchResult, new: &BenchResult) -> Result<String> {
    if old.workload.id != new.workload.id {
        bail!(
            "the results measure different workloads ({} {} and {} {}): their speeds do not compare",
            old.workload.name,
            old.workload.id,
            new.workload.name,
            new.workload.id
        );
    }
    let w = &new.workload;
    // A result's text, escaped as one line: a newline in a stranger's workload name would
    // start a line of its own, such as a forged row of the table below.
    let mut text = format!(
        "workload {} ({}x{}, {} spp; {})\n",
        terminal_safe(&w.name, 64),
        w.width,
        w.height,
        w.spp,
        terminal_safe(&w.id, 64)
    );
    for (which, r) in [("old", old), ("new", new)] {
        if r.validation.status != "valid" {
            text.push_str(&format!(
                "warning: the {which} result is {}\n",
                r.validation.status
            ));
        }
    }
    let side_by_side = stats::side_by_side(
        &format!("old: {}", old.label()),
        &stats::scaling_of(old),
        &format!("new: {}", new.label()),
        &stats::scaling_of(new),
    );
    match side_by_side {
        Some(table) => Ok(text + &table),
        None => bail!("the results share no thread count"),
    }
}
