//! The suite's plots: per-block bars of each scene, scaling with threads,
//! and speed-up over the thesis.

use super::{Report, SceneReport, THESIS_METHODS};
use plotters::prelude::*;
use sinew_core::StepTimings;
use std::error::Error;
use std::path::Path;

const PALETTE: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(127, 127, 127),
];

/// The thesis' methods' lines, in [`THESIS_METHODS`] order.
const THESIS_COLORS: [RGBColor; 4] = [
    RGBColor(0, 0, 0),
    RGBColor(110, 110, 110),
    RGBColor(170, 170, 170),
    RGBColor(200, 140, 20),
];

/// A method's label short enough for a bar.
fn short_label(method: &str) -> String {
    let word = |w: &str| method.split_whitespace().any(|m| m == w);
    match method.split_whitespace().next().unwrap_or("") {
        "Colored" if word("Global") => "Col/G".into(),
        "Colored" => "Col/M".into(),
        "Sequential" => "Seq".into(),
        "Jacobi" => "Jac".into(),
        "Hybrid" => "Hyb".into(),
        other => other.into(),
    }
}

/// Registers the plot font (plotters draws text with `ab_glyph`, no system fonts).
fn register_font() -> Result<(), Box<dyn Error>> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::UBUNTU_LIGHT,
    )
    .map_err(|_| "the plot font could not be loaded".into())
}

pub(super) fn plot(report: &Report, out: &Path) -> Result<(), Box<dyn Error>> {
    register_font()?;
    for s in &report.scenes {
        let file = format!("blocks_{}.png", s.name.replace(' ', "_"));
        plot_blocks(s, &out.join(file))?;
    }
    plot_scaling(report, &out.join("scaling.png"))?;
    plot_speedup(report, &out.join("speedup.png"))?;
    Ok(())
}

/// Stacked per-block ms/frame, one bar per (method, threads).
fn plot_blocks(s: &SceneReport, path: &Path) -> Result<(), Box<dyn Error>> {
    let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let top = s.results.iter().map(|r| r.wall_ms).fold(0.0, f64::max) * 1.15;
    let labels: Vec<String> = s
        .results
        .iter()
        .map(|r| format!("{} ×{}", short_label(&r.method), r.threads))
        .collect();
    let n = s.results.len();
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{}: {:.0} active of {} constraints, {} iterations — ms/frame by block",
                s.name, s.active_constraints, s.constraints, s.iterations
            ),
            ("sans-serif", 26),
        )
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0.0..top.max(1e-3))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n)
        .x_label_formatter(&|x| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                labels.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .x_label_style(("sans-serif", 15))
        .y_desc("ms/frame")
        .draw()?;
    for (b, name) in StepTimings::NAMES.iter().enumerate() {
        let color = PALETTE[b % PALETTE.len()];
        chart
            .draw_series(s.results.iter().enumerate().map(|(i, r)| {
                let below: f64 = r.blocks_ms[..b].iter().map(|(_, v)| v).sum();
                let x = i as f64;
                Rectangle::new(
                    [(x - 0.35, below), (x + 0.35, below + r.blocks_ms[b].1)],
                    color.filled(),
                )
            }))?
            .label(*name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled()));
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}

/// The series legend in a framed box.
fn legend<'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, CT>,
    position: SeriesLabelPosition,
) -> Result<(), Box<dyn Error>> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// A labelled polyline with a dot at each point.
fn line_with_points<'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, CT>,
    points: Vec<(f64, f64)>,
    color: RGBColor,
    label: impl Into<String>,
) -> Result<(), Box<dyn Error>> {
    chart
        .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
    chart.draw_series(
        points
            .into_iter()
            .map(|p| Circle::new(p, 4, color.filled())),
    )?;
    Ok(())
}

/// Methods in first-seen order.
fn methods_of(report: &Report) -> Vec<String> {
    let mut methods: Vec<String> = Vec::new();
    for r in report.scenes.iter().flat_map(|s| &s.results) {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    methods
}

/// ms/frame against constraint count (log–log), every method at the most
/// threads, with the thesis' SST for reference.
fn plot_scaling(report: &Report, path: &Path) -> Result<(), Box<dyn Error>> {
    let root = BitMapBackend::new(path, (1100, 750)).into_drawing_area();
    root.fill(&WHITE)?;
    let max_threads = report.max_threads();
    let (mut lo_x, mut hi_x) = (f64::MAX, 1.0f64);
    let (mut lo_y, mut hi_y) = (f64::MAX, 1e-3f64);
    for s in &report.scenes {
        lo_x = lo_x.min(s.active_constraints);
        hi_x = hi_x.max(s.active_constraints);
        for v in s
            .results
            .iter()
            .map(|r| r.wall_ms)
            .chain(s.thesis_ms.iter().map(|t| t.1))
        {
            lo_y = lo_y.min(v);
            hi_y = hi_y.max(v);
        }
    }
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("ms/frame vs active constraints ({max_threads} threads; thesis dashed)"),
            ("sans-serif", 26),
        )
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (lo_x * 0.7..hi_x * 1.4).log_scale(),
            (lo_y * 0.5..hi_y * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("active constraints")
        .y_desc("ms/frame")
        .draw()?;
    for (i, method) in methods_of(report).iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let points: Vec<(f64, f64)> = report
            .scenes
            .iter()
            .filter_map(|s| {
                s.results
                    .iter()
                    .find(|r| &r.method == method && r.threads == max_threads)
                    .map(|r| (s.active_constraints, r.wall_ms))
            })
            .collect();
        line_with_points(&mut chart, points, color, method.as_str())?;
    }
    for (k, name) in THESIS_METHODS.iter().enumerate() {
        let points: Vec<(f64, f64)> = report
            .scenes
            .iter()
            .filter_map(|s| {
                s.thesis_ms
                    .iter()
                    .find(|t| t.0 == *name)
                    .map(|t| (s.active_constraints, t.1))
            })
            .collect();
        let color = THESIS_COLORS[k].mix(0.8);
        chart
            .draw_series(DashedLineSeries::new(points, 6, 4, color.stroke_width(2)))?
            .label(format!("thesis {name}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}

/// Speed-up over one thread against the thread count, per scene (its best
/// method at one thread).
fn plot_speedup(report: &Report, path: &Path) -> Result<(), Box<dyn Error>> {
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let max_threads = report.max_threads() as f64;
    let mut series = Vec::new();
    for s in &report.scenes {
        let best = s
            .results
            .iter()
            .filter(|r| r.threads == 1)
            .min_by(|a, b| a.wall_ms.total_cmp(&b.wall_ms));
        let Some(best) = best else { continue };
        let points: Vec<(f64, f64)> = s
            .results
            .iter()
            .filter(|r| r.method == best.method)
            .map(|r| (r.threads as f64, best.wall_ms / r.wall_ms))
            .collect();
        series.push((format!("{} ({})", s.name, best.method), points));
    }
    let top = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .fold(max_threads, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption("speed-up over 1 thread (ideal dashed)", ("sans-serif", 26))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5..max_threads + 0.5, 0.0..top * 1.1)?;
    chart
        .configure_mesh()
        .x_desc("threads")
        .y_desc("speed-up")
        .draw()?;
    chart.draw_series(DashedLineSeries::new(
        vec![(1.0, 1.0), (max_threads, max_threads)],
        6,
        4,
        BLACK.mix(0.5).stroke_width(1),
    ))?;
    for (i, (label, points)) in series.into_iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        line_with_points(&mut chart, points, color, label)?;
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}
