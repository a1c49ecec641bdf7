//! SVG charts of benchmark speeds, written here so that every text from a result passes
//! through one escape (`text::html_safe`): samples/s against threads, one line per machine
//! and build with its spread as whiskers, and a machine's speed over commits. Axes carry
//! round ticks (1, 2 or 5 times a power of ten) and their units. `bench --chart` writes the
//! first as a standalone file; `results report` puts both in its page.

use std::fmt::Write;
use tessera::record::host::short_commit;
use tessera::record::stats::{Pooled, Scaling};
use tessera::text::html_safe;

/// Series colours, distinguishable and readable on white.
pub const COLOURS: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2",
];

/// The plot area inside a chart: left, top, right, bottom.
type Plot = (f64, f64, f64, f64);

/// The most intervals an axis is drawn with, whatever the values: `round_ticks` gives three
/// or four, and a result may come from anyone.
const MAX_TICKS: usize = 10;

/// Round ticks from 0 to at least `max`: a step of 1, 2, 2.5 or 5 times a power of ten,
/// giving three or four intervals, and the top of the axis (a whole number of steps). Both
/// are finite and positive whatever `max` is: near the largest `f64`, where a round top would
/// overflow to infinity, the top is `max` itself in four steps; below any speed (1e-300,
/// subnormals) the axis is that of 1.
pub fn round_ticks(max: f64) -> (f64, f64) {
    let max = if max.is_finite() && max >= 1e-300 {
        max
    } else {
        1.0
    };
    let rough = max / 4.0;
    let power = 10f64.powf(rough.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|&s| s >= rough)
        .unwrap_or(10.0 * power);
    let top = (max / step).ceil() * step;
    if top.is_finite() {
        (step, top)
    } else {
        (max / 4.0, max)
    }
}

/// A tick's value with the decimals its step needs, the same for every tick of an axis:
/// `0, 5, 10` for a step of 5; `0.0, 2.5, 5.0` for 2.5; `0.00, 0.02` for 0.02.
fn tick_label(value: f64, step: f64) -> String {
    let whole = |d: i32| {
        let scaled = step * 10f64.powi(d);
        (scaled - scaled.round()).abs() <= 1e-9 * scaled.abs().max(1.0)
    };
    let decimals = (0..=9).find(|&d| whole(d)).unwrap_or(9) as usize;
    format!("{value:.decimals$}")
}

/// Axes with round ticks on y (values in samples/s, shown in millions, the unit titled)
/// and the x labels given.
fn axes(s: &mut String, plot: Plot, y_top: f64, y_step: f64, x_labels: &[(f64, String)]) {
    let (left, top, right, bottom) = plot;
    let _ = write!(
        s,
        "<line x1=\"{left}\" y1=\"{bottom}\" x2=\"{right}\" y2=\"{bottom}\" stroke=\"#888\"/>\
         <line x1=\"{left}\" y1=\"{top}\" x2=\"{left}\" y2=\"{bottom}\" stroke=\"#888\"/>"
    );
    let ticks = ((y_top / y_step).round() as usize).min(MAX_TICKS);
    for k in 0..=ticks {
        let v = y_step * k as f64;
        // Divided first, here and in the charts: 220 × a speed near the largest `f64` is
        // infinite.
        let y = bottom - (bottom - top) * (v / y_top);
        let _ = write!(
            s,
            "<text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>\
             <line x1=\"{left}\" x2=\"{right}\" y1=\"{y:.1}\" y2=\"{y:.1}\" stroke=\"#eee\"/>",
            left - 6.0,
            y + 4.0,
            tick_label(v / 1e6, y_step / 1e6)
        );
    }
    let _ = write!(
        s,
        "<text x=\"12\" y=\"{:.1}\" text-anchor=\"middle\" transform=\"rotate(-90 12 {:.1})\">M samples/s</text>",
        (top + bottom) / 2.0,
        (top + bottom) / 2.0
    );
    for (x, text) in x_labels {
        let _ = write!(
            s,
            "<text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            bottom + 16.0,
            html_safe(text)
        );
    }
}

/// Samples/s against threads (on a log scale), one line per series (the first eight: the
/// caller says so of the rest), the median as a point and the spread as a whisker; the SVG
/// element alone.
pub fn scaling_svg(lines: &[(String, Scaling)]) -> String {
    let plot = (58.0, 10.0, 470.0, 230.0);
    let lines = &lines[..lines.len().min(COLOURS.len())];
    let mut threads: Vec<i64> = lines.iter().flat_map(|(_, s)| s.keys().copied()).collect();
    threads.sort_unstable();
    threads.dedup();
    let y_max = (lines.iter())
        .flat_map(|(_, s)| s.values().map(|p| p.max))
        .fold(0.0, f64::max);
    let (y_step, y_top) = round_ticks(y_max);
    // Threads on a log scale: 1, 2, 4, … evenly spaced.
    let lg = |t: i64| (t.max(1) as f64).log2();
    let (t0, t1) = (
        threads.first().map_or(0.0, |&t| lg(t)),
        threads.last().map_or(1.0, |&t| lg(t)),
    );
    let x = |t: i64| {
        if t1 > t0 {
            plot.0 + 20.0 + (plot.2 - plot.0 - 40.0) * (lg(t) - t0) / (t1 - t0)
        } else {
            (plot.0 + plot.2) / 2.0
        }
    };
    let y = |v: f64| plot.3 - (plot.3 - plot.1) * (v / y_top);
    let mut s = "<svg width=\"480\" height=\"272\" viewBox=\"0 0 480 272\" role=\"img\" \
                 aria-label=\"samples per second against threads\">"
        .to_owned();
    let labels: Vec<(f64, String)> = threads.iter().map(|&t| (x(t), t.to_string())).collect();
    axes(&mut s, plot, y_top, y_step, &labels);
    let _ = write!(
        s,
        "<text x=\"{}\" y=\"266\" text-anchor=\"middle\">threads</text>",
        (plot.0 + plot.2) / 2.0
    );
    for (i, (_, sc)) in lines.iter().enumerate() {
        let c = COLOURS[i];
        let points: Vec<String> = (sc.iter())
            .map(|(&t, p)| format!("{:.1},{:.1}", x(t), y(p.median)))
            .collect();
        let _ = write!(
            s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"2\"/>",
            points.join(" ")
        );
        for (&t, p) in sc.iter() {
            let _ = write!(
                s,
                "<line x1=\"{cx:.1}\" x2=\"{cx:.1}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"{c}\"/>\
                 <circle cx=\"{cx:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{c}\"/>",
                y(p.min),
                y(p.max),
                y(p.median),
                cx = x(t),
            );
        }
    }
    s.push_str("</svg>");
    s
}

/// `scaling_svg` as a file of its own: a title above, the legend below.
pub fn scaling_svg_document(title: &str, lines: &[(String, Scaling)]) -> String {
    let shown = lines.len().min(COLOURS.len());
    let height = 300 + 18 * shown;
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" \
         width=\"720\" height=\"{}\" viewBox=\"0 0 480 {height}\" font-family=\"sans-serif\" \
         font-size=\"11\"><rect width=\"100%\" height=\"100%\" fill=\"white\"/>\
         <text x=\"240\" y=\"16\" text-anchor=\"middle\" font-size=\"13\">{}</text>\
         <g transform=\"translate(0 24)\">{}</g>",
        height * 3 / 2,
        html_safe(title),
        scaling_svg(lines)
    );
    for (i, (label, _)) in lines.iter().take(shown).enumerate() {
        let y = 306 + 18 * i;
        let _ = write!(
            s,
            "<rect x=\"58\" y=\"{}\" width=\"10\" height=\"10\" fill=\"{}\"/>\
             <text x=\"74\" y=\"{y}\">{}</text>",
            y - 9,
            COLOURS[i],
            html_safe(label)
        );
    }
    s.push_str("</svg>\n");
    s
}

#[cfg_attr(not(feature = "results"), allow(dead_code))]
/// A machine's pooled speed per commit (`(commit, pooled, slower beyond the spread)`), the
/// spread as whiskers, regressions in red.
pub fn history_svg(steps: &[(String, Pooled, bool)]) -> String {
    let plot = (58.0, 10.0, 470.0, 190.0);
    let y_max = steps.iter().map(|s| s.1.max).fold(0.0, f64::max);
    let (y_step, y_top) = round_ticks(y_max);
    let n = steps.len();
    let x = |i: usize| match n {
        0 | 1 => (plot.0 + plot.2) / 2.0,
        _ => plot.0 + 30.0 + (plot.2 - plot.0 - 60.0) * i as f64 / (n - 1) as f64,
    };
    let y = |v: f64| plot.3 - (plot.3 - plot.1) * (v / y_top);
    let mut s = "<svg width=\"480\" height=\"215\" viewBox=\"0 0 480 215\" role=\"img\" \
                 aria-label=\"samples per second over commits\">"
        .to_owned();
    let labels: Vec<(f64, String)> = (steps.iter().enumerate())
        .map(|(i, (commit, _, _))| (x(i), short_commit(commit, 8)))
        .collect();
    axes(&mut s, plot, y_top, y_step, &labels);
    let points: Vec<String> = (steps.iter().enumerate())
        .map(|(i, (_, p, _))| format!("{:.1},{:.1}", x(i), y(p.median)))
        .collect();
    let _ = write!(
        s,
        "<polyline points=\"{}\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"2\"/>",
        points.join(" ")
    );
    for (i, (_, p, regression)) in steps.iter().enumerate() {
        let c = if *regression { "#d00" } else { "#1f77b4" };
        let _ = write!(
            s,
            "<line x1=\"{cx:.1}\" x2=\"{cx:.1}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"{c}\"/>\
             <circle cx=\"{cx:.1}\" cy=\"{:.1}\" r=\"{}\" fill=\"{c}\"/>",
            y(p.min),
            y(p.max),
            y(p.median),
            if *regression { 5 } else { 3 },
            cx = x(i),
        );
    }
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use tessera::record::stats::pool_scaling;

    #[test]
    fn ticks_are_round_and_reach_the_maximum() {
        assert_eq!(round_ticks(18.3e6), (5e6, 20e6));
        assert_eq!(round_ticks(7.2e6), (2e6, 8e6));
        assert_eq!(round_ticks(1.0e6), (0.25e6, 1.0e6));
        assert_eq!(round_ticks(0.0), (0.25, 1.0));
        assert_eq!(round_ticks(f64::NAN), (0.25, 1.0));
        // Speeds no run makes, from an imported result: a round top of 1.7e308 is 2e308,
        // infinity, and an axis of infinitely many ticks took memory until it ran out.
        for max in [
            f64::MAX,
            1.7e308,
            1.5e308,
            1e-310,
            5e-324,
            f64::MIN_POSITIVE,
        ] {
            let (step, top) = round_ticks(max);
            assert!(
                step > 0.0 && top.is_finite() && top >= max,
                "{max}: {step}, {top}"
            );
            assert!(
                (top / step).round() <= MAX_TICKS as f64,
                "{max}: {step}, {top}"
            );
        }
        assert_eq!(tick_label(15.0, 5.0), "15");
        assert_eq!(tick_label(0.4, 0.2), "0.4");
        assert_eq!(tick_label(0.75, 0.25), "0.75");
        assert_eq!(tick_label(0.02, 0.01), "0.02");
    }

    #[test]
    fn the_scaling_chart_shows_round_ticks_and_escapes_labels() {
        let a = pool_scaling(&[vec![
            (1, [9.0e6, 8.5e6, 9.5e6]),
            (2, [17.0e6, 16.0e6, 18.3e6]),
        ]]);
        let doc = scaling_svg_document("t<i>tle", &[("CPU <b>".into(), a)]);
        for tick in [">0<", ">5<", ">10<", ">15<", ">20<"] {
            assert!(doc.contains(tick), "{tick} in {doc}");
        }
        assert!(doc.contains("M samples/s") && doc.contains(">threads<"));
        assert!(doc.contains("CPU &lt;b&gt;") && doc.contains("t&lt;i&gt;tle"));
        assert!(!doc.contains("<b>"));
    }
}
