//! An SVG chart of samples/s against threads for one or more benchmark results (plotters).

use super::report::Report;
use anyhow::{Result, anyhow};
use plotters::prelude::*;

/// The chart of `reports` as an SVG document.
pub fn svg(reports: &[Report]) -> Result<String> {
    let mut out = String::new();
    {
        let max_threads = reports
            .iter()
            .flat_map(|r| r.scaling.iter().map(|row| row.threads))
            .max()
            .unwrap_or(1)
            .max(2);
        let max_rate = reports
            .iter()
            .flat_map(|r| r.scaling.iter().map(|row| row.samples_per_sec.max / 1e6))
            .fold(0.0f64, f64::max)
            .max(1e-3);
        let area = SVGBackend::with_string(&mut out, (800, 500)).into_drawing_area();
        let fail = |e: &dyn std::fmt::Display| anyhow!("could not draw the chart: {e}");
        area.fill(&WHITE).map_err(|e| fail(&e))?;
        let workload = &reports[0].workload;
        let title = format!(
            "tessera bench: {} ({}x{}, {} spp)",
            workload.name, workload.width, workload.height, workload.spp
        );
        let mut chart = ChartBuilder::on(&area)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(1usize..max_threads, 0.0..max_rate * 1.1)
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("threads")
            .y_desc("M samples/s (median; bars: min to max)")
            .draw()
            .map_err(|e| fail(&e))?;
        for (i, report) in reports.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let points: Vec<(usize, f64)> = (report.scaling.iter())
                .map(|row| (row.threads, row.samples_per_sec.median / 1e6))
                .collect();
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
                .map_err(|e| fail(&e))?
                .label(report.label())
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(|e| fail(&e))?;
            chart
                .draw_series(report.scaling.iter().map(|row| {
                    let s = row.samples_per_sec;
                    PathElement::new(
                        [(row.threads, s.min / 1e6), (row.threads, s.max / 1e6)],
                        color.stroke_width(1),
                    )
                }))
                .map_err(|e| fail(&e))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| fail(&e))?;
        area.present().map_err(|e| fail(&e))?;
    }
    Ok(out)
}
