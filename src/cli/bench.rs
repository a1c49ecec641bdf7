//! `tessera bench`: the median speed of repeated renders, and how it scales with threads, as
//! text or one JSON object.

use super::settings::{BenchSettings, render_options};
use super::{print_out, summary};
use anyhow::{Context, Result};
use tessera::render::{self, RenderStats};
use tessera::scene::Scene;
use tessera::simd::Path;

/// Renders `repeat` times with `threads` workers; returns the run with the median speed.
fn median_run(scene: &Scene, threads: usize, repeat: u32, simd: Path) -> Result<RenderStats> {
    let options = render_options(Some(threads), render::DEFAULT_TILE, simd)?;
    let mut runs = (0..repeat)
        .map(|_| {
            Ok(render::render(scene, &options, &|_| {})
                .context("could not start the thread pool")?
                .1)
        })
        .collect::<Result<Vec<RenderStats>>>()?;
    runs.sort_by(|a, b| a.samples_per_sec().total_cmp(&b.samples_per_sec()));
    Ok(runs[runs.len() / 2])
}

pub fn run(settings: BenchSettings) -> Result<()> {
    let BenchSettings {
        scene,
        scene_path,
        threads,
        scaling,
        repeat,
        json,
        simd,
    } = settings;
    // Thread scaling, each the median of `repeat` renders.
    let scaling = (scaling.iter())
        .map(|&t| median_run(&scene, t, repeat, simd))
        .collect::<Result<Vec<_>>>()?;
    // The headline run at `threads`, unless the table already measured it.
    let stats = match scaling.iter().find(|r| r.threads == threads) {
        Some(r) => *r,
        None => median_run(&scene, threads, repeat, simd)?,
    };
    let base = scaling.first().map_or(1.0, RenderStats::samples_per_sec);
    // Per thread count: samples/s, speedup over one thread, parallel efficiency.
    let rows: Vec<(usize, f64, f64, f64)> = scaling
        .iter()
        .map(|r| {
            let speedup = r.samples_per_sec() / base;
            let efficiency = speedup / r.threads as f64;
            (r.threads, r.samples_per_sec(), speedup, efficiency)
        })
        .collect();
    let s = &scene.settings;
    if json {
        let table: Vec<_> = rows
            .iter()
            .map(|&(threads, samples_per_sec, speedup, efficiency)| {
                serde_json::json!({
                    "threads": threads,
                    "samples_per_sec": samples_per_sec,
                    "speedup": speedup,
                    "efficiency": efficiency,
                })
            })
            .collect();
        let report = serde_json::json!({
            "samples_per_sec": stats.samples_per_sec(),
            "mrays_per_sec": stats.mrays_per_sec(),
            "rays_per_sample": stats.rays_per_sample(),
            "wall_s": stats.wall.as_secs_f64(),
            "threads": stats.threads,
            "width": s.width,
            "height": s.height,
            "spp": s.samples_per_pixel,
            "scaling": table,
        });
        return print_out(&format!("{report}\n"));
    }
    let mut text = format!(
        "{}: {}x{}, {} spp, depth {}, median of {repeat}\n{}\n",
        scene_path.display(),
        s.width,
        s.height,
        s.samples_per_pixel,
        s.max_depth,
        summary(&stats)
    );
    if !rows.is_empty() {
        text.push_str("threads  M samples/s  speedup  efficiency\n");
        for (threads, samples_per_sec, speedup, efficiency) in rows {
            text.push_str(&format!(
                "{threads:>7}  {:>11.3}  {speedup:>7.2}  {:>9.0}%\n",
                samples_per_sec / 1e6,
                100.0 * efficiency
            ));
        }
    }
    print_out(&text)
}
