//! `tessera results report`: one self-contained HTML file (no script, nothing fetched: its
//! Content-Security-Policy forbids both) with the ranking, a chart of samples/s by machine,
//! speed against threads per machine with efficiency, and each machine's history over
//! commits. Charts are SVG written here, so every text from a result passes through one
//! escaping function; the page reads on a phone (tables scroll inside their boxes).

use super::analysis::{self, Pooled, Ranked, Scaling, Step};
use super::utc;
use std::fmt::Write;

/// `text` for HTML text and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{{{:x}}}", c as u32);
            }
            c => out.push(c),
        }
    }
    out
}

/// Series colours, distinguishable and readable on white.
const COLOURS: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2",
];

/// What the report shows.
pub struct Report<'a> {
    pub workload: &'a str,
    pub generated_unix_s: i64,
    pub total_runs: usize,
    pub ranked: &'a [Ranked<'a>],
    /// Each ranked line's speed against threads (same order).
    pub scaling: &'a [Scaling],
    /// Each machine's history: its id, thread count, SIMD path and steps.
    pub histories: &'a [(String, i64, String, Vec<Step>)],
}

const STYLE: &str = "
body{font:15px/1.45 system-ui,sans-serif;margin:0 auto;padding:12px;max-width:1100px;color:#222}
h1{font-size:1.4em}h2{font-size:1.15em;margin-top:1.6em}
.box{overflow-x:auto;-webkit-overflow-scrolling:touch}
table{border-collapse:collapse;font-variant-numeric:tabular-nums;white-space:nowrap}
th,td{padding:3px 8px;border-bottom:1px solid #ddd;text-align:left}td.n{text-align:right}
svg{width:100%;height:auto;max-width:640px;display:block}
svg text{font:13px system-ui,sans-serif;fill:#222}.muted{color:#666}.bad{color:#b00;font-weight:600}
.bars{max-width:760px}.row{margin:6px 0}.label{font-size:.9em;overflow-wrap:anywhere}
.track{position:relative;height:18px;background:#f3f3f3}.bar{position:absolute;left:0;top:0;bottom:0}
.whisker{position:absolute;top:8px;height:2px;background:#000}
.legend{list-style:none;padding:0;font-size:.9em}.legend li{margin:2px 0}
.swatch{display:inline-block;width:.8em;height:.8em;margin-right:.4em;vertical-align:-1px}
";

pub fn render(r: &Report) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'\">\
         <title>tessera benchmark results: {w}</title><style>{STYLE}</style></head><body>\
         <h1>tessera benchmark results: {w}</h1>\
         <p class=\"muted\">{runs} runs in the database; {lines} machine and build lines with valid runs of this workload. Made {when} UTC.</p>",
        w = escape(r.workload),
        runs = r.total_runs,
        lines = r.ranked.len(),
        when = utc(r.generated_unix_s),
    );
    if r.ranked.is_empty() {
        h.push_str("<p>No valid runs of this workload yet: run <code>tessera bench</code> or import results.</p></body></html>\n");
        return h;
    }
    h.push_str("<h2>Ranking</h2><div class=\"box\"><table class=\"rank\"><thead><tr><th>#</th><th>machine</th><th>CPU</th><th>build</th><th>runs</th><th>threads</th><th>M samples/s</th><th>spread</th><th>per thread</th></tr></thead><tbody>");
    for (i, line) in r.ranked.iter().enumerate() {
        let s = line.score;
        let _ = write!(
            h,
            "<tr><td class=\"n\">{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{:.3}</td><td class=\"n\">{:.3}–{:.3}</td><td class=\"n\">{:.3}</td></tr>",
            i + 1,
            escape(&line.example.machine_id),
            escape(&analysis::cpu(line.example)),
            escape(&analysis::build(line.example)),
            s.runs,
            line.threads,
            s.median / 1e6,
            s.min / 1e6,
            s.max / 1e6,
            s.median / 1e6 / line.threads.max(1) as f64,
        );
    }
    h.push_str("</tbody></table></div>");
    h.push_str("<h2>Samples per second by machine and build</h2>");
    h.push_str(&bars(r.ranked));
    h.push_str("<h2>Speed against threads</h2>");
    h.push_str(&scaling_chart(r.ranked, r.scaling));
    h.push_str(&efficiency_table(r.ranked, r.scaling));
    h.push_str("<h2>History over commits</h2>");
    for (machine, threads, simd, steps) in r.histories {
        let _ = write!(
            h,
            "<h3>{} · {threads} threads · {}</h3>",
            escape(machine),
            escape(simd)
        );
        h.push_str(&history_chart(steps));
        let flagged: Vec<String> = (steps.iter())
            .filter(|s| s.regression)
            .map(|s| escape(&s.commit.chars().take(12).collect::<String>()))
            .collect();
        if !flagged.is_empty() {
            let _ = write!(
                h,
                "<p class=\"bad\">Slower beyond the runs' spread at {}.</p>",
                flagged.join(", ")
            );
        }
    }
    h.push_str("</body></html>\n");
    h
}

/// A label of a ranked line for charts.
fn label(line: &Ranked) -> String {
    let cpu: String = analysis::cpu(line.example).chars().take(40).collect();
    format!("{cpu} · {}", analysis::build(line.example))
}

/// Horizontal bars of the pooled median with the spread as a whisker, in HTML so that the
/// labels wrap and stay readable on a phone.
fn bars(ranked: &[Ranked]) -> String {
    let max = ranked
        .iter()
        .map(|l| l.score.max)
        .fold(0.0, f64::max)
        .max(1.0);
    let pc = |v: f64| 100.0 * v / max;
    let mut h = "<div class=\"bars\">".to_owned();
    for (i, line) in ranked.iter().enumerate() {
        let p = line.score;
        let _ = write!(
            h,
            "<div class=\"row\"><div class=\"label\">{} <b>{:.2}</b></div><div class=\"track\">\
             <div class=\"bar\" style=\"width:{:.2}%;background:{}\"></div>\
             <div class=\"whisker\" style=\"left:{:.2}%;width:{:.2}%\"></div></div></div>",
            escape(&label(line)),
            p.median / 1e6,
            pc(p.median),
            COLOURS[i % COLOURS.len()],
            pc(p.min),
            (pc(p.max) - pc(p.min)).max(0.3),
        );
    }
    h.push_str("</div><p class=\"muted\">M samples/s: the median of the runs' medians; the line across each bar spans the least and greatest any run measured.</p>");
    h
}

/// The colour key of a chart's lines.
fn legend(labels: &[String]) -> String {
    let mut h = "<ul class=\"legend\">".to_owned();
    for (i, text) in labels.iter().enumerate() {
        let _ = write!(
            h,
            "<li><span class=\"swatch\" style=\"background:{}\"></span>{}</li>",
            COLOURS[i % COLOURS.len()],
            escape(text)
        );
    }
    h.push_str("</ul>");
    h
}

/// Axes with `ticks` on y (values in M samples/s) and x labels given.
fn axes(s: &mut String, plot: (f64, f64, f64, f64), y_max: f64, x_labels: &[(f64, String)]) {
    let (left, top, right, bottom) = plot;
    let _ = write!(
        s,
        "<line x1=\"{left}\" y1=\"{bottom}\" x2=\"{right}\" y2=\"{bottom}\" stroke=\"#888\"/>\
         <line x1=\"{left}\" y1=\"{top}\" x2=\"{left}\" y2=\"{bottom}\" stroke=\"#888\"/>"
    );
    for k in 0..=4 {
        let v = y_max * k as f64 / 4.0;
        let y = bottom - (bottom - top) * k as f64 / 4.0;
        let _ = write!(
            s,
            "<text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{:.1}</text>\
             <line x1=\"{left}\" x2=\"{right}\" y1=\"{y:.1}\" y2=\"{y:.1}\" stroke=\"#eee\"/>",
            left - 6.0,
            y + 4.0,
            v / 1e6
        );
    }
    for (x, text) in x_labels {
        let _ = write!(
            s,
            "<text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            bottom + 16.0,
            escape(text)
        );
    }
}

/// Samples/s against threads, one line per ranked line (up to eight).
fn scaling_chart(ranked: &[Ranked], scaling: &[Scaling]) -> String {
    let plot = (48.0, 10.0, 470.0, 230.0);
    let lines: Vec<(&Ranked, &Scaling)> = ranked.iter().zip(scaling).take(COLOURS.len()).collect();
    let mut threads: Vec<i64> = lines.iter().flat_map(|(_, s)| s.keys().copied()).collect();
    threads.sort_unstable();
    threads.dedup();
    let y_max = (lines.iter())
        .flat_map(|(_, s)| s.values().map(|p| p.max))
        .fold(1.0, f64::max);
    // Threads on a log scale: 1, 2, 4, … evenly spaced.
    let lg = |t: i64| (t.max(1) as f64).log2();
    let (t0, t1) = (
        threads.first().map_or(0.0, |&t| lg(t)),
        threads.last().map_or(1.0, |&t| lg(t)),
    );
    let x = |t: i64| plot.0 + (plot.2 - plot.0) * (lg(t) - t0) / (t1 - t0).max(1.0);
    let y = |v: f64| plot.3 - (plot.3 - plot.1) * v / y_max;
    let mut s = "<svg viewBox=\"0 0 480 272\" role=\"img\" aria-label=\"samples per second against threads\">".to_owned();
    let labels: Vec<(f64, String)> = threads.iter().map(|&t| (x(t), t.to_string())).collect();
    axes(&mut s, plot, y_max, &labels);
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
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{c}\"/>",
                x(t),
                y(p.median)
            );
        }
    }
    s.push_str("</svg>");
    let labels: Vec<String> = lines.iter().map(|(line, _)| label(line)).collect();
    s.push_str(&legend(&labels));
    s
}

/// Efficiency (speedup over one thread ÷ threads) of each line at each thread count.
fn efficiency_table(ranked: &[Ranked], scaling: &[Scaling]) -> String {
    let mut threads: Vec<i64> = scaling.iter().flat_map(|s| s.keys().copied()).collect();
    threads.sort_unstable();
    threads.dedup();
    let mut h =
        "<div class=\"box\"><table class=\"efficiency\"><thead><tr><th>machine and build</th>"
            .to_owned();
    for t in &threads {
        let _ = write!(h, "<th>{t} thread{}</th>", if *t == 1 { "" } else { "s" });
    }
    h.push_str("</tr></thead><tbody>");
    for (line, sc) in ranked.iter().zip(scaling) {
        let _ = write!(h, "<tr><td>{}</td>", escape(&label(line)));
        let one = sc.get(&1).map(|p| p.median);
        for t in &threads {
            let cell = match (sc.get(t), one) {
                (Some(p), Some(one)) => format!(
                    "{:.3} M/s, {:.0}%",
                    p.median / 1e6,
                    100.0 * p.median / one / *t as f64
                ),
                (Some(p), None) => format!("{:.3} M/s", p.median / 1e6),
                (None, _) => "–".into(),
            };
            let _ = write!(h, "<td class=\"n\">{cell}</td>");
        }
        h.push_str("</tr>");
    }
    h.push_str("</tbody></table></div><p class=\"muted\">Percent: efficiency, the speedup over one thread divided by the threads.</p>");
    h
}

/// A machine's pooled speed per commit, the spread as whiskers, regressions in red.
fn history_chart(steps: &[Step]) -> String {
    let plot = (48.0, 10.0, 470.0, 190.0);
    let y_max = steps.iter().map(|s| s.score.max).fold(1.0, f64::max);
    let n = steps.len();
    let x = |i: usize| match n {
        0 | 1 => (plot.0 + plot.2) / 2.0,
        _ => plot.0 + 30.0 + (plot.2 - plot.0 - 60.0) * i as f64 / (n - 1) as f64,
    };
    let y = |v: f64| plot.3 - (plot.3 - plot.1) * v / y_max;
    let mut s =
        "<svg viewBox=\"0 0 480 215\" role=\"img\" aria-label=\"samples per second over commits\">"
            .to_owned();
    let labels: Vec<(f64, String)> = (steps.iter().enumerate())
        .map(|(i, st)| (x(i), st.commit.chars().take(8).collect()))
        .collect();
    axes(&mut s, plot, y_max, &labels);
    let points: Vec<String> = (steps.iter().enumerate())
        .map(|(i, st)| format!("{:.1},{:.1}", x(i), y(st.score.median)))
        .collect();
    let _ = write!(
        s,
        "<polyline points=\"{}\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"2\"/>",
        points.join(" ")
    );
    for (i, st) in steps.iter().enumerate() {
        let Pooled {
            median, min, max, ..
        } = st.score;
        let c = if st.regression { "#d00" } else { "#1f77b4" };
        let _ = write!(
            s,
            "<line x1=\"{cx:.1}\" x2=\"{cx:.1}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"{c}\"/>\
             <circle cx=\"{cx:.1}\" cy=\"{:.1}\" r=\"{}\" fill=\"{c}\"/>",
            y(min),
            y(max),
            y(median),
            if st.regression { 5 } else { 3 },
            cx = x(i),
        );
    }
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn everything_a_result_says_is_escaped() {
        assert_eq!(
            escape("<script>alert('x')</script> & \"q\"\u{1b}"),
            "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;\\u{1b}"
        );
    }
}
