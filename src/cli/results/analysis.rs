//! What the kept runs say together: a ranking of machines and builds, and one machine's
//! speed over commits with the drops beyond the runs' own spread flagged. Pure functions of
//! the runs, so they are tested without a database.

use super::utc;
use crate::cli::output::count;
use std::collections::BTreeMap;
use tessera::record::db::Run;
use tessera::record::host::short_commit;
use tessera::record::stats::{Pooled, pool, sps};
use tessera::text::terminal_safe;

pub fn build(r: &Run) -> String {
    let commit = short_commit(&r.commit, 8);
    format!("{} {commit} {}", r.version, r.simd)
}

pub fn cpu(r: &Run) -> String {
    format!(
        "{} ({})",
        r.cpu_model.as_deref().unwrap_or("unknown CPU"),
        count(r.logical_cpus.max(0) as u64, "CPU")
    )
}

/// Whether a run counts in a ranking: its image was the workload's.
pub fn counts(r: &Run) -> bool {
    r.validation == "valid"
}

/// One line of a ranking: a machine and build, its score and spread.
#[derive(Debug)]
pub struct Ranked<'a> {
    pub example: &'a Run,
    pub score: Pooled,
    pub threads: i64,
    /// The runs pooled.
    pub ids: Vec<i64>,
    /// How many of them ran on a busy machine (their speed is the machine's and the other
    /// work's): the line says so.
    pub busy: usize,
}

/// The runs of one workload grouped by machine and build (version, commit, SIMD path), each
/// scored by its headline samples/s (all threads, as bench measures by default), best
/// first. Runs that do not count (`counts`) are left out unless `all`.
pub fn rank(runs: &[Run], all: bool) -> Vec<Ranked<'_>> {
    let mut groups: BTreeMap<(&str, &str, &str, &str, i64), Vec<&Run>> = BTreeMap::new();
    for r in runs.iter().filter(|r| all || counts(r)) {
        let key = (
            r.machine_id.as_str(),
            r.version.as_str(),
            r.commit.as_str(),
            r.simd.as_str(),
            r.threads,
        );
        groups.entry(key).or_default().push(r);
    }
    let mut ranked: Vec<Ranked> = groups
        .into_values()
        .filter_map(|runs| {
            let score = pool(&runs.iter().map(|r| r.sps).collect::<Vec<_>>())?;
            Some(Ranked {
                example: runs[0],
                score,
                threads: runs[0].threads,
                ids: runs.iter().map(|r| r.id).collect(),
                busy: runs.iter().filter(|r| r.busy).count(),
            })
        })
        .collect();
    ranked.sort_by(|a, b| b.score.median.total_cmp(&a.score.median));
    ranked
}

/// The ranking as a table; when it is empty, why (of `runs`, ranked with `all` or not).
pub fn rank_text(ranked: &[Ranked], runs: &[Run], all: bool) -> String {
    if ranked.is_empty() {
        return if all || runs.is_empty() {
            "no runs to rank\n".to_owned()
        } else {
            format!(
                "no valid runs to rank; --all ranks the other {}\n",
                count(runs.len() as u64, "run")
            )
        };
    }
    let mut t = format!(
        "{:>4}  {:<18}  {:<36}  {:<30}  {:>4}  {:>7}  {:<26}  {:>14}\n",
        "rank", "machine", "CPU", "build", "runs", "threads", "M samples/s [spread]", "per thread"
    );
    for (i, r) in ranked.iter().enumerate() {
        t.push_str(&format!(
            "{:>4}  {:<18}  {:<36}  {:<30}  {:>4}  {:>7}  {:<26}  {:>14.3}{}\n",
            i + 1,
            terminal_safe(&r.example.machine_id, 18),
            terminal_safe(&cpu(r.example), 36),
            terminal_safe(&build(r.example), 30),
            r.score.runs,
            r.threads,
            sps(&r.score),
            r.score.median / 1e6 / r.threads.max(1) as f64,
            busy_note(r.busy, r.score.runs),
        ));
    }
    t
}

/// `  (1 of 3 runs on a busy machine)`, or nothing.
pub fn busy_note(busy: usize, runs: usize) -> String {
    if busy == 0 {
        String::new()
    } else {
        format!(
            "  ({busy} of {} on a busy machine)",
            count(runs as u64, "run")
        )
    }
}

/// One commit's place in a machine's history.
#[derive(Debug)]
pub struct Step {
    pub commit: String,
    pub first_seen: i64,
    pub score: Pooled,
    /// Slower than the commit before it by more than either's spread.
    pub regression: bool,
    /// Measured only on a busy machine: shown, but neither flagged nor compared with.
    pub busy: bool,
}

/// A machine's headline speed over commits (in the order each was first measured), at
/// `threads` on SIMD path `simd`, each commit flagged when it is slower than the one before
/// beyond both spreads. A commit's runs on a busy machine count only where it has no other.
pub fn history(runs: &[Run], threads: i64, simd: &str) -> Vec<Step> {
    // Per commit: its first run's start, and its measurements on an idle and a busy machine.
    type Measured = (i64, Vec<[f64; 3]>, Vec<[f64; 3]>);
    let mut by_commit: BTreeMap<&str, Measured> = BTreeMap::new();
    for r in (runs.iter()).filter(|r| r.threads == threads && r.simd == simd) {
        let entry = by_commit.entry(r.commit.as_str()).or_insert((
            r.started_unix_s,
            Vec::new(),
            Vec::new(),
        ));
        entry.0 = entry.0.min(r.started_unix_s);
        if r.busy {
            entry.2.push(r.sps);
        } else {
            entry.1.push(r.sps);
        }
    }
    let mut steps: Vec<Step> = by_commit
        .into_iter()
        .filter_map(|(commit, (first_seen, idle, busy))| {
            let only_busy = idle.is_empty();
            Some(Step {
                commit: commit.to_owned(),
                first_seen,
                score: pool(if only_busy { &busy } else { &idle })?,
                regression: false,
                busy: only_busy,
            })
        })
        .collect();
    steps.sort_by_key(|s| s.first_seen);
    // Each commit against the last one before it measured on an idle machine.
    let mut before: Option<Pooled> = None;
    for step in steps.iter_mut().filter(|s| !s.busy) {
        if let Some(b) = before {
            step.regression = step.score.median < b.median && !step.score.overlaps(&b);
        }
        before = Some(step.score);
    }
    steps
}

pub fn history_text(
    steps: &[Step],
    machine: &str,
    workload: &str,
    threads: i64,
    simd: &str,
) -> String {
    let mut t = format!(
        "machine {}, workload {}, {}, SIMD {}\n{:<16}  {:<18}  {:>4}  {:<26}  {:>7}\n",
        terminal_safe(machine, 80),
        terminal_safe(workload, 32),
        count(threads.max(0) as u64, "thread"),
        terminal_safe(simd, 16),
        "first run (UTC)",
        "commit",
        "runs",
        "M samples/s [spread]",
        "vs prev"
    );
    for (i, s) in steps.iter().enumerate() {
        let versus = match i.checked_sub(1).map(|p| &steps[p]) {
            Some(prev) => format!("{:.3}", s.score.median / prev.score.median),
            None => "-".into(),
        };
        t.push_str(&format!(
            "{:<16}  {:<18}  {:>4}  {:<26}  {versus:>7}{}\n",
            utc(s.first_seen),
            terminal_safe(&short_commit(&s.commit, 12), 18),
            s.score.runs,
            sps(&s.score),
            if s.regression {
                "  REGRESSION: slower beyond the runs' spread"
            } else if s.busy {
                "  (on a busy machine only: not compared)"
            } else {
                ""
            }
        ));
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(machine: &str, commit: &str, started: i64, sps: [f64; 3], valid: bool) -> Run {
        Run {
            id: started,
            started_unix_s: started,
            machine_id: machine.into(),
            cpu_model: Some("CPU".into()),
            logical_cpus: 4,
            version: "0.1.0".into(),
            commit: commit.into(),
            simd: "avx2".into(),
            workload: "cover".into(),
            workload_id: "w".into(),
            threads: 4,
            sps,
            validation: if valid { "valid" } else { "unvalidated" }.into(),
            busy: false,
        }
    }

    #[test]
    fn a_ranking_pools_each_machine_and_build_best_first() {
        let runs = [
            run("m-a", "c1", 1, [10.0, 9.0, 11.0], true),
            run("m-a", "c1", 2, [12.0, 11.0, 13.0], true),
            run("m-a", "c1", 3, [14.0, 13.0, 15.0], true),
            run("m-b", "c1", 4, [20.0, 19.0, 21.0], true),
            run("m-c", "c1", 5, [99.0, 98.0, 100.0], false),
        ];
        let ranked = rank(&runs, false);
        assert_eq!(ranked.len(), 2);
        assert_eq!(ranked[0].example.machine_id, "m-b");
        let a = ranked[1].score;
        assert_eq!((a.median, a.min, a.max, a.runs), (12.0, 9.0, 15.0, 3));
        assert_eq!(rank(&runs, true)[0].example.machine_id, "m-c");
        assert!(rank_text(&rank(&runs[4..], false), &runs[4..], false).contains("--all ranks"));
    }

    #[test]
    fn runs_of_a_busy_machine_are_ranked_marked_and_flag_no_regression() {
        let busy = |mut r: Run| {
            r.busy = true;
            r
        };
        let runs = [
            run("m-a", "c1", 1, [10.0, 9.0, 11.0], true),
            busy(run("m-a", "c1", 2, [5.0, 4.0, 6.0], true)),
            busy(run("m-a", "c2", 3, [2.0, 1.9, 2.1], true)),
            run("m-a", "c3", 4, [10.0, 9.5, 10.5], true),
        ];
        let ranked = rank(&runs, false);
        let c1 = ranked.iter().find(|l| l.example.commit == "c1").unwrap();
        assert_eq!((c1.score.runs, c1.busy), (2, 1));
        assert!(rank_text(&ranked, &runs, false).contains("(1 of 2 runs on a busy machine)"));
        let steps = history(&runs, 4, "avx2");
        // c1 from its idle run; c2 only busy, shown but not compared; c3 against c1.
        assert_eq!(steps[0].score.runs, 1);
        assert!(steps[1].busy && !steps[1].regression);
        assert!(!steps[2].regression && !steps[2].busy);
        assert!(history_text(&steps, "m-a", "cover", 4, "avx2").contains("busy machine only"));
    }

    #[test]
    fn history_flags_only_drops_beyond_the_spread() {
        let runs = [
            run("m", "c1", 10, [100.0, 95.0, 105.0], true),
            run("m", "c2", 20, [98.0, 94.0, 103.0], true),
            run("m", "c3", 30, [80.0, 78.0, 82.0], true),
            run("m", "c4", 40, [90.0, 85.0, 95.0], true),
        ];
        let steps = history(&runs, 4, "avx2");
        let flags: Vec<bool> = steps.iter().map(|s| s.regression).collect();
        assert_eq!(flags, [false, false, true, false]);
        assert!(history(&runs, 4, "avx512").is_empty());
        let text = history_text(&steps, "m", "cover", 4, "avx2");
        assert_eq!(text.matches("REGRESSION").count(), 1, "{text}");
    }
}
