//! The campaign report: one static HTML file (`campaign.html`) with inline SVG plots and
//! a table of runs. It loads nothing at view time (no scripts, no network, no fonts).

use std::fmt::Write as _;

use plotters::prelude::*;

use crate::review::{color_of, display_name};

/// One run in the report.
#[derive(Debug, Clone, Default)]
pub struct ReportRow {
    /// Run name.
    pub name: String,
    /// The error, if the run failed.
    pub error: Option<String>,
    /// Distance to the last control point, m.
    pub distance_m: Option<f64>,
    /// Horizontal error at the last control point per settings (`initial`, methods), m.
    pub last_cp_error_m: Vec<(String, f64)>,
    /// Errors at every control point: (control point id, settings label, m).
    pub cp_errors_m: Vec<(u32, String, f64)>,
    /// Joint estimate with 1σ, when it ran.
    pub joint: Option<JointEstimate>,
    /// Median and largest error of the joint fit at a control point left out of it, m.
    pub holdout_m: Option<(f64, f64)>,
    /// What the reports of a run that did not fail flag (an odometer flagged failed on some
    /// samples, methods not run or not used, a coarse azimuth turn refused, an odometer
    /// boresight estimated, inconsistent or repeatedly marked control points), as in
    /// `campaign.md`'s error column.
    pub note: Option<String>,
    /// Relative link to the run's review recording.
    pub recording: Option<String>,
    /// Wall time, s.
    pub wall_s: f64,
    /// Stages computed (empty: everything cached).
    pub computed: Vec<String>,
}

/// The joint estimator's settings with their 1σ.
#[derive(Debug, Clone, Copy, Default)]
pub struct JointEstimate {
    /// Azimuth correction (estimate − initial), degrees.
    pub azimuth_change_deg: f64,
    /// 1σ, degrees.
    pub azimuth_sigma_deg: f64,
    /// Vertical gyro drift, °/h.
    pub drift_z_deg_h: f64,
    /// 1σ, °/h.
    pub drift_z_sigma_deg_h: f64,
    /// Odometer scale correction, ppm.
    pub odo_ppm: f64,
    /// 1σ, ppm.
    pub odo_sigma_ppm: f64,
}

const METHODS: [&str; 4] = ["initial", "oepi", "owpi", "joint"];

fn rgb(label: &str) -> RGBColor {
    let c = color_of(label);
    RGBColor(c[0], c[1], c[2])
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// Error at the last control point per run and settings, logarithmic.
fn plot_last_cp(rows: &[ReportRow], svg: &mut String) -> PlotResult {
    let values: Vec<f64> = rows
        .iter()
        .flat_map(|r| r.last_cp_error_m.iter().map(|e| e.1))
        .collect();
    let hi = values.iter().copied().fold(1.0, f64::max) * 2.0;
    let lo = values
        .iter()
        .copied()
        .filter(|v| *v > 0.0)
        .fold(hi, f64::min)
        .max(1e-3)
        / 2.0;
    let root = SVGBackend::with_string(svg, (860, 340)).into_drawing_area();
    root.fill(&WHITE)?;
    let n = rows.len().max(1);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Horizontal error at the last control point",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(60)
        .y_label_area_size(60)
        .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_labels(n.min(30))
        .x_label_formatter(&|x| {
            let k = x.round();
            if (x - k).abs() < 1e-6 && k >= 0.0 {
                rows.get(k as usize)
                    .map(|r| r.name.clone())
                    .unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc("error [m]")
        .draw()?;
    for (m, method) in METHODS.iter().enumerate() {
        let offset = (m as f64 - 1.5) * 0.12;
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                r.last_cp_error_m
                    .iter()
                    .find(|e| e.0 == *method)
                    .map(|e| (i as f64 + offset, e.1.max(lo)))
            })
            .collect();
        let color = rgb(method);
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, color.filled())))?;
    }
    root.present()?;
    Ok(())
}

/// One setting per run with ±1σ bars.
fn plot_estimates(
    rows: &[ReportRow],
    title: &str,
    unit: &str,
    get: fn(&JointEstimate) -> (f64, f64),
    svg: &mut String,
) -> PlotResult {
    let pts: Vec<(usize, f64, f64)> = rows
        .iter()
        .enumerate()
        .filter_map(|(i, r)| r.joint.as_ref().map(|j| (i, get(j).0, get(j).1)))
        .collect();
    let lo = pts
        .iter()
        .map(|p| p.1 - p.2.abs())
        .fold(f64::INFINITY, f64::min);
    let hi = pts
        .iter()
        .map(|p| p.1 + p.2.abs())
        .fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi) = if lo.is_finite() && hi.is_finite() {
        (lo, hi)
    } else {
        (-1.0, 1.0)
    };
    let pad = ((hi - lo) * 0.15).max(1e-6);
    let n = rows.len().max(1);
    let root = SVGBackend::with_string(svg, (420, 300)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), (lo - pad)..(hi + pad))?;
    chart
        .configure_mesh()
        .x_labels(n.min(15))
        .x_label_formatter(&|x| format!("{}", x.round() as i64 + 1))
        .x_desc("run #")
        .y_desc(unit)
        .draw()?;
    let color = rgb("joint");
    chart.draw_series(pts.iter().map(|&(i, v, s)| {
        PathElement::new(
            vec![(i as f64, v - s.abs()), (i as f64, v + s.abs())],
            color.stroke_width(2),
        )
    }))?;
    chart.draw_series(
        pts.iter()
            .map(|&(i, v, _)| Circle::new((i as f64, v), 4, color.filled())),
    )?;
    root.present()?;
    Ok(())
}

/// Every control point: error before against error after each method, log-log, with
/// the line of no change.
fn plot_control_points(rows: &[ReportRow], svg: &mut String) -> PlotResult {
    let mut pairs: Vec<(&str, f64, f64)> = Vec::new();
    for r in rows {
        for (k, (id, label, after)) in r.cp_errors_m.iter().enumerate() {
            if label == "initial" {
                continue;
            }
            // A point the route came back to has an error per visit, in time order: the
            // n-th after against the n-th before.
            let visit = r.cp_errors_m[..k]
                .iter()
                .filter(|e| e.0 == *id && e.1 == *label)
                .count();
            if let Some(before) = r
                .cp_errors_m
                .iter()
                .filter(|e| e.0 == *id && e.1 == "initial")
                .nth(visit)
            {
                let method = METHODS
                    .iter()
                    .find(|m| **m == label.as_str())
                    .copied()
                    .unwrap_or("other");
                pairs.push((method, before.2, *after));
            }
        }
    }
    let all = pairs.iter().flat_map(|p| [p.1, p.2]);
    let hi = all.clone().fold(1.0, f64::max) * 2.0;
    let lo = all.filter(|v| *v > 0.0).fold(hi, f64::min).max(1e-3) / 2.0;
    let root = SVGBackend::with_string(svg, (420, 360)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Control points: error before vs after", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d((lo..hi).log_scale(), (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("before [m]")
        .y_desc("after [m]")
        .draw()?;
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(lo, lo), (hi, hi)],
        BLACK.mix(0.4),
    )))?;
    for method in &METHODS[1..] {
        let color = rgb(method);
        chart
            .draw_series(
                pairs
                    .iter()
                    .filter(|p| p.0 == *method)
                    .map(|p| Circle::new((p.1.max(lo), p.2.max(lo)), 4, color.filled())),
            )?
            .label(display_name(method))
            .legend(move |(x, y)| Circle::new((x + 8, y), 4, color.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

fn figure(title: &str, draw: impl FnOnce(&mut String) -> PlotResult) -> String {
    let mut svg = String::new();
    match draw(&mut svg) {
        Ok(()) => format!("<figure>{svg}</figure>"),
        Err(e) => format!(
            "<figure><p class=\"err\">{}: cannot draw: {}</p></figure>",
            escape(title),
            escape(&e.to_string())
        ),
    }
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |v| format!("{v:.digits$}"))
}

/// The whole report as HTML.
pub fn campaign_html(title: &str, rows: &[ReportRow], pooled_markdown: &str) -> String {
    let ok = rows.iter().filter(|r| r.error.is_none()).count();
    let mut h = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
<meta name=\"viewport\" content=\"width=device-width\"><title>{t}</title><style>\
body{{font-family:sans-serif;margin:1.5em;color:#222}}table{{border-collapse:collapse;font-size:13px}}\
td,th{{border:1px solid #ccc;padding:3px 6px;text-align:right}}td.l,th.l{{text-align:left}}\
tr.failed{{background:#fde8e8}}figure{{display:inline-block;margin:0 1em 1em 0}}.err{{color:#b00}}.note{{color:#8a5a00}}\
.sw{{display:inline-block;width:10px;height:10px;margin-right:4px}}</style></head><body>\
<h1>{t}</h1><p>{n} runs: {ok} processed, {failed} failed.</p>\n",
        t = escape(title),
        n = rows.len(),
        failed = rows.len() - ok,
    );
    // Runs that failed have no results: the plots by name leave them out, the plots by
    // run number (the table's #) leave their number empty.
    let good: Vec<ReportRow> = rows.iter().filter(|r| r.error.is_none()).cloned().collect();
    h += &figure("last control point", |s| plot_last_cp(&good, s));
    h += "<p>";
    for m in METHODS {
        let c = color_of(m);
        let _ = write!(
            h,
            "<span class=\"sw\" style=\"background:rgb({},{},{})\"></span>{} &nbsp; ",
            c[0],
            c[1],
            c[2],
            escape(&display_name(m))
        );
    }
    h += "</p>";
    h += &figure("azimuth", |s| {
        plot_estimates(
            rows,
            "Joint: azimuth correction ±1σ",
            "[°]",
            |j| (j.azimuth_change_deg, j.azimuth_sigma_deg),
            s,
        )
    });
    h += &figure("drift z", |s| {
        plot_estimates(
            rows,
            "Joint: vertical gyro drift ±1σ",
            "[°/h]",
            |j| (j.drift_z_deg_h, j.drift_z_sigma_deg_h),
            s,
        )
    });
    h += &figure("odometer", |s| {
        plot_estimates(
            rows,
            "Joint: odometer scale ±1σ",
            "[ppm]",
            |j| (j.odo_ppm, j.odo_sigma_ppm),
            s,
        )
    });
    h += &figure("control points", |s| plot_control_points(&good, s));
    h += "\n<h2>Runs</h2>\n<table><tr><th>#</th><th class=\"l\">run</th><th>distance [m]</th>";
    for m in METHODS {
        let c = color_of(m);
        let _ = write!(
            h,
            "<th><span class=\"sw\" style=\"background:rgb({},{},{})\"></span>{} [m]</th>",
            c[0],
            c[1],
            c[2],
            escape(&display_name(m))
        );
    }
    h += "<th>joint Δaz [°]</th><th>σ [°]</th><th>driftz [°/h]</th><th>σ [°/h]</th><th>odo [ppm]</th><th>σ [ppm]</th><th>hold-out median [m]</th><th>hold-out max [m]</th><th>wall [s]</th><th class=\"l\">computed</th><th class=\"l\">recording / error</th></tr>\n";
    for (i, r) in rows.iter().enumerate() {
        let _ = write!(
            h,
            "<tr class=\"{}\"><td>{}</td><td class=\"l\">{}</td><td>{}</td>",
            if r.error.is_some() { "failed" } else { "ok" },
            i + 1,
            escape(&r.name),
            cell(r.distance_m, 0)
        );
        for m in METHODS {
            let v = r.last_cp_error_m.iter().find(|e| e.0 == m).map(|e| e.1);
            h += &format!("<td>{}</td>", cell(v, 1));
        }
        let j = r.joint.as_ref();
        for v in [
            j.map(|j| (j.azimuth_change_deg, 3)),
            j.map(|j| (j.azimuth_sigma_deg, 3)),
            j.map(|j| (j.drift_z_deg_h, 2)),
            j.map(|j| (j.drift_z_sigma_deg_h, 2)),
            j.map(|j| (j.odo_ppm, 0)),
            j.map(|j| (j.odo_sigma_ppm, 0)),
            r.holdout_m.map(|h| (h.0, 2)),
            r.holdout_m.map(|h| (h.1, 2)),
        ] {
            h += &format!(
                "<td>{}</td>",
                v.map_or("–".into(), |(v, d)| format!("{v:.d$}"))
            );
        }
        let computed = match (&r.error, r.computed.is_empty()) {
            (Some(_), true) => "–".to_owned(),
            (None, true) => "cached".to_owned(),
            (_, false) => r.computed.join(", "),
        };
        let mut last = match (&r.error, &r.recording) {
            (Some(e), _) => format!("<span class=\"err\">{}</span>", escape(e)),
            (None, Some(link)) => format!("<a href=\"{0}\">{0}</a>", escape(link)),
            (None, None) => String::new(),
        };
        if let (None, Some(note)) = (&r.error, &r.note) {
            let _ = write!(last, "<br><span class=\"note\">{}</span>", escape(note));
        }
        let _ = writeln!(
            h,
            "<td>{:.2}</td><td class=\"l\">{}</td><td class=\"l\">{last}</td></tr>",
            r.wall_s,
            escape(&computed)
        );
    }
    h += "</table>\n<p>Errors are horizontal, navigated minus surveyed, at the control points' stops. \
Open a recording with <code>rerun FILE.rrd</code>.</p>\n";
    h += &markdown_html(pooled_markdown);
    h += "</body></html>\n";
    h
}

/// `markdown` (CommonMark with tables: `campaign.md`'s pooled sections) as HTML. Any HTML
/// it holds is shown as text, not passed through: the page stays static whatever a run's
/// name or a note says.
fn markdown_html(markdown: &str) -> String {
    use pulldown_cmark::{Event, Options, Parser};
    let events = Parser::new_ext(markdown, Options::ENABLE_TABLES).map(|e| match e {
        Event::Html(raw) | Event::InlineHtml(raw) => Event::Text(raw),
        other => other,
    });
    let mut html = String::new();
    pulldown_cmark::html::push_html(&mut html, events);
    html
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(name: &str, before: f64, after: f64) -> ReportRow {
        ReportRow {
            name: name.into(),
            distance_m: Some(12_000.0),
            last_cp_error_m: vec![("initial".into(), before), ("joint".into(), after)],
            cp_errors_m: vec![(1, "initial".into(), before), (1, "joint".into(), after)],
            joint: Some(JointEstimate {
                azimuth_change_deg: 7.0,
                azimuth_sigma_deg: 0.1,
                ..JointEstimate::default()
            }),
            recording: Some(format!("{name}/review/{name}.rrd")),
            ..ReportRow::default()
        }
    }

    #[test]
    fn report_has_a_row_per_run_and_escapes_errors() {
        let mut bad = row("bad<run>", 1.0, 1.0);
        bad.error = Some("broken <manifest> & more".into());
        let html = campaign_html("Campaign", &[row("a", 1500.0, 3.0), bad], "");
        assert_eq!(html.matches("<tr class=").count(), 2);
        assert!(html.contains("broken &lt;manifest&gt; &amp; more"));
        assert!(!html.contains("<run>"));
        assert_eq!(html.matches("<svg").count(), 5, "five plots");
        assert!(html.contains("a/review/a.rrd"));
        assert!(!html.contains("<script"), "no scripts");
    }

    #[test]
    fn a_run_s_note_is_shown_escaped_and_a_failed_run_s_is_not() {
        let mut noted = row("noted", 100.0, 2.0);
        noted.note = Some("control point 6 inconsistent <check>".into());
        let mut failed = row("failed", 1.0, 1.0);
        failed.error = Some("broken".into());
        failed.note = Some("never shown".into());
        let html = campaign_html("Campaign", &[noted, failed], "");
        assert!(html.contains(
            "noted/review/noted.rrd</a><br><span class=\"note\">control point 6 inconsistent &lt;check&gt;</span>"
        ));
        assert!(!html.contains("never shown"));
    }

    /// The pooled sections: headings, emphasis, code and tables as HTML; HTML in them as
    /// text.
    #[test]
    fn the_pooled_sections_are_rendered_and_their_html_is_text() {
        let md = "\n## The odometer's lag\n\nTheir mean: **0.400 ± 0.041 s**. Set \
                  `[derive] odo_time_offset_s = -0.400`.\n\n| run | lag [s] |\n|---|---|\n\
                  | a<script>x</script> | 0.410 |\n";
        let html = campaign_html("Campaign", &[row("a", 1500.0, 3.0)], md);
        assert!(html.contains("<h2>The odometer's lag</h2>"), "{html}");
        assert!(html.contains("<strong>0.400 ± 0.041 s</strong>"), "{html}");
        assert!(
            html.contains("<code>[derive] odo_time_offset_s = -0.400</code>"),
            "{html}"
        );
        assert!(html.contains("<td>0.410</td>"), "{html}");
        assert!(!html.contains("<script"), "{html}");
        assert!(html.contains("&lt;script&gt;"), "{html}");
    }

    #[test]
    fn an_empty_campaign_still_renders() {
        let html = campaign_html("Empty", &[], "");
        assert!(html.contains("0 runs"));
        assert!(!html.contains("cannot draw"), "{html}");
    }
}
