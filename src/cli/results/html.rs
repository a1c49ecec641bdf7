//! `tessera results report`: one self-contained HTML file (no script, nothing fetched: its
//! Content-Security-Policy forbids both) with, for each workload, the ranking, a chart of
//! samples/s by machine, speed against threads per machine with efficiency, and each
//! machine's history over commits. Every text from a result passes through one escape
//! (`text::html_safe`). On a phone the ranking becomes one card per line, the score first,
//! and charts shrink to the screen.

use super::analysis::{self, Ranked, Step};
use super::utc;
use crate::cli::charts::{self, COLOURS};
use std::fmt::Write;
use tessera::record::host::short_commit;
use tessera::record::stats::{Pooled, Scaling};
use tessera::text::html_safe;

/// One line of a ranking, as the page shows it.
pub struct Line {
    pub machine_id: String,
    pub cpu: String,
    pub build: String,
    pub threads: i64,
    pub score: Pooled,
    /// Runs of the line measured on a busy machine.
    pub busy: usize,
}

impl Line {
    pub fn of(ranked: &Ranked) -> Self {
        Self {
            machine_id: ranked.example.machine_id.clone(),
            cpu: analysis::cpu(ranked.example),
            build: analysis::build(ranked.example),
            threads: ranked.threads,
            score: ranked.score,
            busy: ranked.busy,
        }
    }

    /// A label for charts: the CPU (cut short) and the build.
    fn label(&self) -> String {
        let cpu: String = self.cpu.chars().take(40).collect();
        format!("{cpu} · {}", self.build)
    }
}

/// A machine's history at one thread count and SIMD path.
pub struct History {
    pub machine: String,
    pub threads: i64,
    pub simd: String,
    pub steps: Vec<Step>,
}

/// What the page shows of one workload.
pub struct Section {
    pub title: String,
    /// Its runs in the database (ranked or not).
    pub runs: usize,
    pub ranked: Vec<Line>,
    /// Each ranked line's speed against threads (same order).
    pub scaling: Vec<Scaling>,
    pub histories: Vec<History>,
}

/// The whole page.
pub struct ReportPage<'a> {
    pub generated_unix_s: i64,
    pub total_runs: usize,
    /// Whether runs that are not `valid` count.
    pub all: bool,
    pub sections: &'a [Section],
}

const STYLE: &str = "
body{font:15px/1.45 system-ui,sans-serif;margin:0 auto;padding:12px;max-width:1100px;color:#222}
h1{font-size:1.4em}h2{font-size:1.25em;margin-top:1.8em;border-bottom:2px solid #ddd}
h3{font-size:1.05em;margin-top:1.4em}h4{font-size:.95em;font-weight:600;margin:1em 0 .3em}
.box{overflow-x:auto;-webkit-overflow-scrolling:touch}
table{border-collapse:collapse;font-variant-numeric:tabular-nums}
th,td{padding:3px 8px;border-bottom:1px solid #ddd;text-align:left;vertical-align:top}
td.n,th.n{text-align:right;white-space:nowrap}td.score{font-weight:600}
.cpu{overflow-wrap:anywhere}.id{color:#666;font-size:.85em}
svg{width:100%;height:auto;max-width:640px;display:block}
svg text{font:13px system-ui,sans-serif;fill:#222}.muted{color:#666}.bad{color:#b00;font-weight:600}
.bars{max-width:760px}.row{margin:6px 0}.label{font-size:.9em;overflow-wrap:anywhere}
.track{position:relative;height:18px;background:#f3f3f3}.bar{position:absolute;left:0;top:0;bottom:0}
.whisker{position:absolute;top:8px;height:2px;background:#000}
.legend{list-style:none;padding:0;font-size:.9em}.legend li{margin:2px 0}
.swatch{display:inline-block;width:.8em;height:.8em;margin-right:.4em;vertical-align:-1px}
@media (max-width:640px){
 body{padding:8px;font-size:14px}
 table.rank,table.rank tbody,table.rank tr,table.rank td{display:block}
 table.rank thead{display:none}
 table.rank tr{border:1px solid #ddd;border-radius:6px;margin:8px 0;padding:6px 8px}
 table.rank td{border:0;padding:1px 0;text-align:left}
 table.rank td[data-label]::before{content:attr(data-label) \": \";color:#666;font-weight:400}
 table.rank td.rankno{float:right;color:#666}
 table.rank td.score{font-size:1.15em}
}
";

pub fn render(r: &ReportPage) -> String {
    let mut h = String::new();
    let workloads: Vec<String> = r.sections.iter().map(|s| html_safe(&s.title)).collect();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'\">\
         <title>tessera benchmark results</title><style>{STYLE}</style></head><body>\
         <h1>tessera benchmark results</h1>\
         <p class=\"muted\">{runs} in the database; {which}. {counted} Made {when} UTC.</p>",
        runs = plural(r.total_runs, "run"),
        which = if workloads.is_empty() {
            "no workloads yet".to_owned()
        } else {
            format!("workloads: {}", workloads.join(", "))
        },
        counted = if r.all {
            "Every run counts, valid or not."
        } else {
            "Only valid runs count."
        },
        when = utc(r.generated_unix_s),
    );
    if r.sections.is_empty() {
        h.push_str("<p>No results yet: run <code>tessera bench</code> or import results with <code>tessera results import</code>.</p></body></html>\n");
        return h;
    }
    for section in r.sections {
        section_html(&mut h, section);
    }
    h.push_str("</body></html>\n");
    h
}

fn plural(n: usize, noun: &str) -> String {
    crate::cli::output::count(n as u64, noun)
}

fn section_html(h: &mut String, s: &Section) {
    let _ = write!(
        h,
        "<h2>Workload {} <span class=\"muted\">({})</span></h2>",
        html_safe(&s.title),
        plural(s.runs, "run")
    );
    if s.ranked.is_empty() {
        h.push_str("<p>No valid runs of this workload: <code>results report --all</code> counts the others.</p>");
        return;
    }
    h.push_str("<h3>Ranking</h3><div class=\"box\"><table class=\"rank\"><thead><tr><th class=\"n\">#</th><th class=\"n\">M samples/s</th><th>CPU and machine</th><th>build</th><th class=\"n\">threads</th><th class=\"n\">spread</th><th class=\"n\">per thread</th><th class=\"n\">runs</th></tr></thead><tbody>");
    for (i, line) in s.ranked.iter().enumerate() {
        let p = line.score;
        let _ = write!(
            h,
            "<tr><td class=\"n rankno\">{}</td><td class=\"n score\" data-label=\"M samples/s\">{:.3}</td>\
             <td class=\"cpu\">{} <span class=\"id\">{}</span></td><td data-label=\"build\">{}</td>\
             <td class=\"n\" data-label=\"threads\">{}</td><td class=\"n\" data-label=\"spread\">{:.3}–{:.3}</td>\
             <td class=\"n\" data-label=\"per thread\">{:.3}</td><td class=\"n\" data-label=\"runs\">{}{}</td></tr>",
            i + 1,
            p.median / 1e6,
            html_safe(&line.cpu),
            html_safe(&line.machine_id),
            html_safe(&line.build),
            line.threads,
            p.min / 1e6,
            p.max / 1e6,
            p.median / 1e6 / line.threads.max(1) as f64,
            p.runs,
            if line.busy > 0 {
                format!(" <span class=\"bad\">({} busy)</span>", line.busy)
            } else {
                String::new()
            },
        );
    }
    h.push_str("</tbody></table></div>");
    h.push_str("<h3>Samples per second by machine and build</h3>");
    h.push_str(&bars(&s.ranked));
    h.push_str("<h3>Speed against threads</h3>");
    let lines: Vec<(String, Scaling)> = (s.ranked.iter().zip(&s.scaling))
        .map(|(line, sc)| (line.label(), sc.clone()))
        .collect();
    h.push_str(&charts::scaling_svg(&lines));
    h.push_str(&legend(&lines));
    // The chart draws the first lines only: a line it leaves out is said to be left out,
    // not shown as missing from the ranking.
    if lines.len() > COLOURS.len() {
        let _ = write!(
            h,
            "<p class=\"muted\">The chart shows the first {} of the {} lines of the ranking; \
             the table below has every one.</p>",
            COLOURS.len(),
            lines.len()
        );
    }
    h.push_str(&efficiency_table(&s.ranked, &s.scaling));
    h.push_str("<h3>History over commits</h3>");
    for history in &s.histories {
        let _ = write!(
            h,
            "<h4>{} · {} · {}</h4>",
            html_safe(&history.machine),
            plural(history.threads.max(0) as usize, "thread"),
            html_safe(&history.simd)
        );
        let steps: Vec<(String, Pooled, bool)> = (history.steps.iter())
            .map(|st| (st.commit.clone(), st.score, st.regression))
            .collect();
        h.push_str(&charts::history_svg(&steps));
        let flagged: Vec<String> = (history.steps.iter())
            .filter(|s| s.regression)
            .map(|s| html_safe(&short_commit(&s.commit, 12)))
            .collect();
        if !flagged.is_empty() {
            let _ = write!(
                h,
                "<p class=\"bad\">Slower beyond the runs' spread at {}.</p>",
                flagged.join(", ")
            );
        }
    }
}

/// Horizontal bars of the pooled median with the spread as a whisker, in HTML so that the
/// labels wrap and stay readable on a phone.
fn bars(ranked: &[Line]) -> String {
    let max = ranked
        .iter()
        .map(|l| l.score.max)
        .fold(0.0, f64::max)
        .max(1.0);
    // Divided first: 100 × a speed near the largest `f64` would be infinite.
    let pc = |v: f64| v / max * 100.0;
    let mut h = "<div class=\"bars\">".to_owned();
    for (i, line) in ranked.iter().enumerate() {
        let p = line.score;
        let _ = write!(
            h,
            "<div class=\"row\"><div class=\"label\">{} <b>{:.2} M samples/s</b></div><div class=\"track\">\
             <div class=\"bar\" style=\"width:{:.2}%;background:{}\"></div>\
             <div class=\"whisker\" style=\"left:{:.2}%;width:{:.2}%\"></div></div></div>",
            html_safe(&line.label()),
            p.median / 1e6,
            pc(p.median),
            COLOURS[i % COLOURS.len()],
            pc(p.min),
            (pc(p.max) - pc(p.min)).max(0.3),
        );
    }
    h.push_str("</div><p class=\"muted\">The median of the runs' medians; the line across each bar spans the least and greatest any run measured.</p>");
    h
}

/// The colour key of a chart's lines.
fn legend(lines: &[(String, Scaling)]) -> String {
    let mut h = "<ul class=\"legend\">".to_owned();
    for (i, (text, _)) in lines.iter().take(COLOURS.len()).enumerate() {
        let _ = write!(
            h,
            "<li><span class=\"swatch\" style=\"background:{}\"></span>{}</li>",
            COLOURS[i],
            html_safe(text)
        );
    }
    h.push_str("</ul>");
    h
}

/// The most thread counts the efficiency table gives a column each: as many as one result
/// measures. Beyond them each line lists its own, so that the page grows with the rows the
/// database holds, not with the lines times every count any line has (5,000 imported
/// results of as many thread counts made a table of 25 million cells, a page of 554 MB).
const MAX_THREAD_COLUMNS: usize = 64;

/// Efficiency (speedup over one thread ÷ threads) of each line at each thread count.
fn efficiency_table(ranked: &[Line], scaling: &[Scaling]) -> String {
    let mut threads: Vec<i64> = scaling.iter().flat_map(|s| s.keys().copied()).collect();
    threads.sort_unstable();
    threads.dedup();
    let columns = threads.len() <= MAX_THREAD_COLUMNS;
    let mut h =
        "<div class=\"box\"><table class=\"efficiency\"><thead><tr><th>machine and build</th>"
            .to_owned();
    if columns {
        for &t in &threads {
            let _ = write!(
                h,
                "<th class=\"n\">{}</th>",
                plural(t.max(0) as usize, "thread")
            );
        }
    } else {
        h.push_str("<th>by thread count</th>");
    }
    h.push_str("</tr></thead><tbody>");
    for (line, sc) in ranked.iter().zip(scaling) {
        let _ = write!(h, "<tr><td class=\"cpu\">{}</td>", html_safe(&line.label()));
        let one = sc.get(&1).map(|p| p.median);
        let cell = |t: i64, p: &Pooled| match one {
            Some(one) => format!(
                "{:.3} M/s, {:.0}%",
                p.median / 1e6,
                100.0 * p.median / one / t as f64
            ),
            None => format!("{:.3} M/s", p.median / 1e6),
        };
        if columns {
            for t in &threads {
                let text = sc.get(t).map_or_else(|| "–".into(), |p| cell(*t, p));
                let _ = write!(h, "<td class=\"n\">{text}</td>");
            }
        } else {
            let own: Vec<String> = (sc.iter())
                .map(|(&t, p)| format!("{}: {}", plural(t.max(0) as usize, "thread"), cell(t, p)))
                .collect();
            let _ = write!(h, "<td>{}</td>", own.join("; "));
        }
        h.push_str("</tr>");
    }
    h.push_str("</tbody></table></div><p class=\"muted\">M/s: million samples per second. Percent: efficiency, the speedup over one thread divided by the threads.</p>");
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(cpu: &str) -> Line {
        Line {
            machine_id: "m-0123".into(),
            cpu: cpu.into(),
            build: "0.1.0 abc avx2".into(),
            threads: 2,
            score: Pooled {
                median: 18.3e6,
                min: 18.0e6,
                max: 18.5e6,
                runs: 3,
            },
            busy: 0,
        }
    }

    #[test]
    fn everything_a_result_says_is_escaped_and_the_score_comes_first() {
        let section = Section {
            title: "quick".into(),
            runs: 1,
            ranked: vec![line("<script>alert('x')</script>\u{202e}")],
            scaling: vec![Scaling::new()],
            histories: Vec::new(),
        };
        let page = render(&ReportPage {
            generated_unix_s: 0,
            total_runs: 1,
            all: false,
            sections: std::slice::from_ref(&section),
        });
        assert!(!page.contains("<script>"));
        assert!(page.contains("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;\\u{202e}"));
        // In each row the score is the second cell, after the rank: on a phone it is the
        // card's first line.
        let row = &page[page.find("<tbody><tr>").unwrap()..];
        let score = row.find("18.300").unwrap();
        assert!(score < row.find("m-0123").unwrap());
        assert!(page.contains("@media (max-width:640px)"));
    }

    /// The chart of speed against threads draws the first eight lines: a ninth and tenth
    /// (the user's own machine, once others' faster results are imported) were left out
    /// of it and of its legend without a word.
    #[test]
    fn a_chart_that_leaves_lines_out_says_so() {
        let page = |n: usize| {
            let section = Section {
                title: "quick".into(),
                runs: n,
                ranked: (0..n).map(|i| line(&format!("CPU {i}"))).collect(),
                scaling: vec![Scaling::new(); n],
                histories: Vec::new(),
            };
            render(&ReportPage {
                generated_unix_s: 0,
                total_runs: n,
                all: false,
                sections: std::slice::from_ref(&section),
            })
        };
        let said = "The chart shows the first 8 of the 10 lines of the ranking";
        assert!(page(10).contains(said));
        assert!(!page(8).contains("The chart shows the first"));
    }

    /// A line per thread count, each measured at its own count: the efficiency table had a
    /// column for every count any line has, cells growing with their square (5,000 lines, a
    /// page of 554 MB). Beyond one result's 64 counts each line lists its own.
    #[test]
    fn the_efficiency_table_grows_with_the_lines_not_their_square() {
        let page = |n: i64| {
            let section = Section {
                title: "quick".into(),
                runs: n as usize,
                ranked: (0..n).map(|i| line(&format!("CPU {i}"))).collect(),
                scaling: (1..=n)
                    .map(|t| Scaling::from([(t, line("x").score)]))
                    .collect(),
                histories: Vec::new(),
            };
            let page = render(&ReportPage {
                generated_unix_s: 0,
                total_runs: n as usize,
                all: false,
                sections: std::slice::from_ref(&section),
            });
            let table = &page[page.find("class=\"efficiency\"").unwrap()..];
            let table = &table[..table.find("</table>").unwrap()];
            (table.matches("<td").count(), table.to_owned())
        };
        // As many counts as one result has: a column each.
        let (cells, table) = page(64);
        assert_eq!(cells, 64 * 65);
        assert!(table.contains("<th class=\"n\">64 threads</th>"), "{table}");
        let (cells, table) = page(2000);
        assert_eq!(cells, 2 * 2000);
        assert!(
            table.contains("<td>2000 threads: 18.300 M/s</td>"),
            "{table}"
        );
    }

    #[test]
    fn an_empty_database_says_how_to_fill_it() {
        let page = render(&ReportPage {
            generated_unix_s: 0,
            total_runs: 0,
            all: false,
            sections: &[],
        });
        assert!(page.contains("tessera bench"), "{page}");
    }
}
