//! Measurements pooled over runs: the median of their medians with the least minimum and
//! greatest maximum any run saw, per thread count, and two such sets side by side with
//! whether their difference lies beyond the runs' own spread. Used on result files
//! (`bench --compare`) and on the database's runs (`results compare`, `rank`, `report`).

use super::result::BenchResult;
use crate::text::terminal_safe;
use std::collections::BTreeMap;

/// The median of `values` (not empty).
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        // Halved first: the sum of two speeds near the largest `f64` is infinite. Halving is
        // exact, so this is the number `(a + b) / 2` gives for any speed a run measures.
        values[n / 2 - 1] / 2.0 + values[n / 2] / 2.0
    }
}

/// A set of measurements of one thing: the median of their medians, and the least minimum
/// and greatest maximum (the spread every run saw).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pooled {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub runs: usize,
}

/// `[median, min, max]` measurements pooled; `None` for none.
pub fn pool(measurements: &[[f64; 3]]) -> Option<Pooled> {
    if measurements.is_empty() {
        return None;
    }
    let mut medians: Vec<f64> = measurements.iter().map(|m| m[0]).collect();
    Some(Pooled {
        median: median(&mut medians),
        min: measurements
            .iter()
            .map(|m| m[1])
            .fold(f64::INFINITY, f64::min),
        max: measurements
            .iter()
            .map(|m| m[2])
            .fold(f64::NEG_INFINITY, f64::max),
        runs: measurements.len(),
    })
}

impl Pooled {
    /// Whether the two spreads overlap: a difference within what the runs themselves vary.
    pub fn overlaps(&self, other: &Pooled) -> bool {
        self.min <= other.max && other.min <= self.max
    }
}

/// `12.345 [12.000-12.500]`: M samples/s with the spread.
pub fn sps(p: &Pooled) -> String {
    format!(
        "{:.3} [{:.3}-{:.3}]",
        p.median / 1e6,
        p.min / 1e6,
        p.max / 1e6
    )
}

/// Each thread count's pooled samples/s over a set of runs.
pub type Scaling = BTreeMap<i64, Pooled>;

/// The runs' scaling rows (thread count, `[median, min, max]`) pooled by thread count.
pub fn pool_scaling(rows: &[Vec<(i64, [f64; 3])>]) -> Scaling {
    let mut by_threads: BTreeMap<i64, Vec<[f64; 3]>> = BTreeMap::new();
    for run in rows {
        for &(threads, m) in run {
            by_threads.entry(threads).or_default().push(m);
        }
    }
    by_threads
        .into_iter()
        .filter_map(|(t, ms)| Some((t, pool(&ms)?)))
        .collect()
}

/// One result file's scaling table as a `Scaling`.
pub fn scaling_of(result: &BenchResult) -> Scaling {
    let rows: Vec<(i64, [f64; 3])> = (result.scaling.iter())
        .map(|row| {
            let s = row.samples_per_sec;
            (row.threads as i64, [s.median, s.min, s.max])
        })
        .collect();
    pool_scaling(&[rows])
}

/// `b` against `a`, thread count by thread count: the ratio of pooled medians and whether
/// it lies within the runs' spread; `None` when they share no thread count.
pub fn side_by_side(a_name: &str, a: &Scaling, b_name: &str, b: &Scaling) -> Option<String> {
    let mut t = format!(
        "A: {}\nB: {}\nthreads  A M samples/s [spread]        B M samples/s [spread]        B/A\n",
        terminal_safe(a_name, 120),
        terminal_safe(b_name, 120)
    );
    let mut shared = 0;
    for (threads, pb) in b {
        let Some(pa) = a.get(threads) else { continue };
        shared += 1;
        let ratio = pb.median / pa.median;
        let verdict = if pa.overlaps(pb) {
            "within the runs' spread"
        } else if ratio > 1.0 {
            "faster, beyond the spread"
        } else {
            "slower, beyond the spread"
        };
        t.push_str(&format!(
            "{threads:>7}  {:<28}  {:<28}  {ratio:.3}  {verdict}\n",
            format!(
                "{} ({})",
                sps(pa),
                crate::text::count(pa.runs as u64, "run")
            ),
            format!(
                "{} ({})",
                sps(pb),
                crate::text::count(pb.runs as u64, "run")
            ),
        ));
    }
    (shared > 0).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_by_side_needs_a_shared_thread_count() {
        let a = pool_scaling(&[vec![(1, [1.0, 0.9, 1.1]), (2, [2.0, 1.9, 2.1])]]);
        let b = pool_scaling(&[vec![(2, [3.0, 2.9, 3.1])]]);
        let text = side_by_side("a", &a, "b", &b).unwrap();
        assert!(text.contains("1.500  faster, beyond the spread"), "{text}");
        assert!(text.contains("(1 run)"), "{text}");
        let c = pool_scaling(&[vec![(8, [3.0, 2.9, 3.1])]]);
        assert!(side_by_side("a", &a, "c", &c).is_none());
    }
}
