//! One benchmark measurement of a workload: the warm-up, the renders at each thread count,
//! the validation of every image against the workload's hash, and whether the machine was
//! busy meanwhile, as the `BenchResult` that `tessera bench` prints and records (and the
//! Python package returns).

use crate::record::host::{Build, Busy, CpuTimes, Host};
use crate::record::result::{BenchResult, Method, Row, SCHEMA, Spread, Validation, WorkloadInfo};
use crate::record::workload::{Workload, hash_text};
use crate::render::{self, RenderOptions, RenderStats};
use std::collections::BTreeSet;
use std::sync::atomic::AtomicBool;

/// What to measure.
pub struct Plan {
    pub workload: Workload,
    /// Threads of the headline result.
    pub threads: usize,
    /// The thread counts of the scaling table: 1, 2, 4, … and every CPU; empty for none.
    pub scaling: Vec<usize>,
    /// Measured renders per thread count, at least 1.
    pub repeat: u32,
    pub warmup: u32,
    /// The SIMD path of every render.
    pub simd: crate::simd::Path,
    /// Whether the user named the path, rather than leaving it to `auto`.
    pub simd_chosen: bool,
}

/// The thread counts of a scaling table on `cpus` CPUs: 1, 2, 4, … below them, then `cpus`.
pub fn scaling_counts(cpus: usize) -> Vec<usize> {
    let mut counts: Vec<usize> = std::iter::successors(Some(1usize), |n| n.checked_mul(2))
        .take_while(|&n| n < cpus)
        .collect();
    counts.push(cpus);
    counts
}

/// Renders `plan`'s workload as it says and makes the result; `Err` only when a thread pool
/// cannot be started. An image that is not the workload's makes the result `invalid`.
pub fn measure(plan: &Plan) -> Result<BenchResult, rayon::ThreadPoolBuildError> {
    let stop = AtomicBool::new(false);
    let done = measure_unless(plan, &stop)?;
    Ok(done.expect("a measurement nothing stops is finished"))
}

/// `measure`, given up (`None`) soon after `stop` is set: each render looks at it between
/// rays, as every render does (the Python package's Ctrl-C).
pub fn measure_unless(
    plan: &Plan,
    stop: &AtomicBool,
) -> Result<Option<BenchResult>, rayon::ThreadPoolBuildError> {
    let started_unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    // Read before the renders load the machine.
    let host = Host::this();
    let cpu_times_at_start = CpuTimes::now();
    let mut images = BTreeSet::new();
    let mut render = |threads: usize| -> Result<Option<RenderStats>, rayon::ThreadPoolBuildError> {
        let options = RenderOptions {
            threads: Some(threads),
            tile: render::DEFAULT_TILE,
            simd: plan.simd,
        };
        let done = render::render_unless(&plan.workload.scene, &options, &|_| {}, stop)?;
        Ok(done.map(|(film, stats)| {
            images.insert(hash_text(film.content_hash()));
            stats
        }))
    };
    for _ in 0..plan.warmup {
        if render(plan.threads)?.is_none() {
            return Ok(None);
        }
    }
    let mut counts: Vec<usize> = plan.scaling.clone();
    counts.push(plan.threads);
    counts.sort_unstable();
    counts.dedup();
    let mut rows = Vec::new();
    for &threads in &counts {
        let mut runs = Vec::new();
        for _ in 0..plan.repeat {
            let Some(stats) = render(threads)? else {
                return Ok(None);
            };
            runs.push(stats);
        }
        rows.push(row(threads, &runs));
    }
    let base = rows
        .iter()
        .find(|r| r.threads == 1)
        .map(|r| r.samples_per_sec.median);
    for r in &mut rows {
        r.speedup = base.map(|b| r.samples_per_sec.median / b);
        r.efficiency = r.speedup.map(|s| s / r.threads as f64);
    }
    let busy = Busy::judge(&host, cpu_times_at_start.as_ref(), CpuTimes::now().as_ref());
    let validation = validate(&plan.workload, images);
    let s = &plan.workload.scene.settings;
    // The headline thread count is among `counts`, so its row is there.
    let result = (rows.iter().find(|r| r.threads == plan.threads))
        .cloned()
        .unwrap_or_else(|| row(plan.threads, &[]));
    Ok(Some(BenchResult {
        schema: SCHEMA.into(),
        build: Build::this(plan.simd, plan.simd_chosen),
        host,
        workload: WorkloadInfo {
            name: plan.workload.name.clone(),
            scene: plan.workload.scene_name.clone(),
            id: plan.workload.id.clone(),
            width: s.width,
            height: s.height,
            spp: s.samples_per_pixel,
            max_depth: s.max_depth,
            seed: s.seed,
        },
        method: Method {
            threads: plan.threads,
            repeat: plan.repeat,
            warmup: plan.warmup,
            started_unix_s,
        },
        result,
        scaling: rows,
        validation,
        busy: Some(busy),
    }))
}

/// The measurement of `runs` at `threads`.
fn row(threads: usize, runs: &[RenderStats]) -> Row {
    let of = |f: fn(&RenderStats) -> f64| Spread::of(&runs.iter().map(f).collect::<Vec<_>>());
    Row {
        threads,
        samples_per_sec: of(RenderStats::samples_per_sec),
        mrays_per_sec: of(RenderStats::mrays_per_sec),
        wall_s: of(|r| r.wall.as_secs_f64()),
        rays_per_sample: runs.first().map_or(0.0, RenderStats::rays_per_sample),
        speedup: None,
        efficiency: None,
        runs: runs.iter().map(RenderStats::samples_per_sec).collect(),
    }
}

fn validate(workload: &Workload, images: BTreeSet<String>) -> Validation {
    let status = match &workload.expected {
        None => "unvalidated",
        Some(want) if images.len() == 1 && images.contains(want) => "valid",
        Some(_) => "invalid",
    };
    Validation {
        status: status.into(),
        expected: workload.expected.clone(),
        images: images.into_iter().collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quick_with(expected: Option<&str>) -> Workload {
        let mut w = Workload::named("quick").unwrap();
        w.expected = expected.map(str::to_owned);
        w
    }

    #[test]
    fn a_result_is_valid_only_if_every_image_has_the_expected_hash() {
        let images = |list: &[&str]| list.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>();
        let status = |w: &Workload, i: &[&str]| validate(w, images(i)).status;
        assert_eq!(status(&quick_with(Some("a")), &["a"]), "valid");
        assert_eq!(status(&quick_with(Some("a")), &["b"]), "invalid");
        assert_eq!(status(&quick_with(Some("a")), &["a", "b"]), "invalid");
        assert_eq!(status(&quick_with(Some("a")), &[]), "invalid");
        assert_eq!(status(&quick_with(None), &["b"]), "unvalidated");
    }
}
