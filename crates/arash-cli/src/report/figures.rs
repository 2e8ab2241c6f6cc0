//! Report figures as PNG: scatter plots of a residual against the variable it depends on, before
//! and after, bar charts of per-joint errors, and time series. The font is DejaVu Sans, bundled,
//! so figures render the same on a machine without fonts.

use std::path::Path;
use std::sync::Once;

use anyhow::Context;
use plotters::prelude::*;

const WIDTH: u32 = 900;
const HEIGHT: u32 = 600;
/// More points than this are thinned evenly: a scatter of 10⁵ points says no more than 10⁴.
const MAX_POINTS: usize = 8000;

fn fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .unwrap_or_else(|_| panic!("the bundled DejaVu Sans is a valid font"));
    });
}

/// Lower and upper bounds of the finite values, widened a little (and made non-empty).
fn range<'a>(values: impl Iterator<Item = &'a f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = 0.05 * (hi - lo).max(1e-12 * lo.abs().max(1.0));
    (lo - pad, hi + pad)
}

fn thin(n: usize) -> usize {
    n.div_ceil(MAX_POINTS).max(1)
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;
type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// A white canvas for one figure at `path`.
fn canvas(path: &Path) -> anyhow::Result<Area<'_>> {
    fonts();
    let root = BitMapBackend::new(path, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE)?;
    Ok(root)
}

/// Axes with a title on `root`.
fn axes<'a, 'b>(
    root: &'a Area<'b>,
    title: &str,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
) -> anyhow::Result<Chart<'a, 'b>> {
    Ok(ChartBuilder::on(root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)?)
}

/// The legend, then the file.
fn finish<'a, 'b: 'a>(mut chart: Chart<'a, 'b>, root: &Area<'b>, path: &Path) -> anyhow::Result<()> {
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Two point clouds `y` against `x`: `before` in orange, `after` in blue.
pub fn scatter_before_after(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    x: &[f64],
    before: &[f64],
    after: &[f64],
) -> anyhow::Result<()> {
    let root = canvas(path)?;
    let (x0, x1) = range(x.iter());
    let (y0, y1) = range(before.iter().chain(after));
    let mut chart = axes(&root, title, x0..x1, y0..y1)?;
    chart.configure_mesh().x_desc(x_label).y_desc(y_label).label_style(("sans-serif", 15)).draw()?;
    let step = thin(x.len());
    for (values, color, label) in [(before, RGBColor(230, 120, 20), "before"), (after, RGBColor(30, 90, 200), "after")]
    {
        let points = x.iter().zip(values).step_by(step).map(|(a, b)| Circle::new((*a, *b), 2, color.mix(0.5).filled()));
        chart.draw_series(points)?.label(label).legend(move |(px, py)| Circle::new((px + 10, py), 4, color.filled()));
    }
    finish(chart, &root, path)
}

/// Grouped bars: for each label, `before` (orange) and `after` (blue).
pub fn bars_before_after(
    path: &Path,
    title: &str,
    y_label: &str,
    labels: &[String],
    before: &[f64],
    after: &[f64],
) -> anyhow::Result<()> {
    let root = canvas(path)?;
    let (lo, hi) = range(before.iter().chain(after).chain(std::iter::once(&0.0)));
    let n = labels.len();
    let mut chart = axes(&root, title, -0.5..n as f64 - 0.5, lo..hi)?;
    let names = labels.to_vec();
    // Groups sit on the integers, so the integer ticks carry their names.
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n.max(1))
        .x_label_formatter(&move |x| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(y_label)
        .label_style(("sans-serif", 15))
        .draw()?;
    for (offset, values, color, label) in
        [(-0.4, before, RGBColor(230, 120, 20), "before"), (0.0, after, RGBColor(30, 90, 200), "after")]
    {
        let rects = values
            .iter()
            .enumerate()
            .map(|(i, v)| Rectangle::new([(i as f64 + offset, 0.0), (i as f64 + offset + 0.4, *v)], color.filled()));
        chart
            .draw_series(rects)?
            .label(label)
            .legend(move |(px, py)| Rectangle::new([(px, py - 5), (px + 10, py + 5)], color.filled()));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Estimates against the truth, one group per parameter: each series' `(estimate − truth) / σ`
/// as a point with its ±3σ bar (so a bar that crosses zero covers the truth), the series side
/// by side in the palette's colours. Parameters are numbered from 1 on the x-axis; the report's
/// table names them.
pub fn estimates_against_truth(path: &Path, title: &str, series: &[(&str, Vec<f64>)]) -> anyhow::Result<()> {
    let root = canvas(path)?;
    let n = series.iter().map(|(_, z)| z.len()).max().unwrap_or(0);
    let ends: Vec<f64> = series.iter().flat_map(|(_, z)| z.iter().flat_map(|v| [v - 3.0, v + 3.0])).collect();
    let (lo, hi) = range(ends.iter());
    let mut chart = axes(&root, title, 0.0..n as f64 + 1.0, lo.min(-3.5)..hi.max(3.5))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n.min(30))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .x_desc("base parameter")
        .y_desc("(estimate − truth) / σ")
        .label_style(("sans-serif", 15))
        .draw()?;
    chart.draw_series(LineSeries::new([(0.0, 0.0), (n as f64 + 1.0, 0.0)], BLACK.stroke_width(1)))?;
    let width = 0.6 / series.len().max(1) as f64;
    for (s, (name, z)) in series.iter().enumerate() {
        let color = Palette99::pick(s).to_rgba();
        let offset = (s as f64 - (series.len() as f64 - 1.0) / 2.0) * width;
        let x = |i: usize| i as f64 + 1.0 + offset;
        let finite = || z.iter().enumerate().filter(|(_, v)| v.is_finite());
        let bars =
            finite().map(|(i, v)| PathElement::new(vec![(x(i), v - 3.0), (x(i), v + 3.0)], color.stroke_width(2)));
        chart.draw_series(bars)?;
        chart
            .draw_series(finite().map(|(i, v)| Circle::new((x(i), *v), 4, color.filled())))?
            .label(*name)
            .legend(move |(px, py)| PathElement::new(vec![(px, py - 6), (px, py + 6)], color.stroke_width(2)));
    }
    finish(chart, &root, path)
}

/// Named lines `y(x)`, thinned, in the palette's colours by order, with legend entries.
fn draw_lines<'s>(
    chart: &mut Chart<'_, '_>,
    series: impl Iterator<Item = (&'s str, &'s [f64], &'s [f64])>,
) -> anyhow::Result<()> {
    for (i, (name, x, y)) in series.enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let points = x.iter().zip(y).step_by(thin(x.len())).map(|(a, b)| (*a, *b));
        chart
            .draw_series(LineSeries::new(points, color.stroke_width(2)))?
            .label(name)
            .legend(move |(px, py)| PathElement::new(vec![(px, py), (px + 20, py)], color.stroke_width(2)));
    }
    Ok(())
}

/// One panel of [`panels`]: its y-axis label and its named series `(name, x, y)`.
pub struct Panel<'a> {
    pub y_label: String,
    pub series: Vec<(&'a str, &'a [f64], Vec<f64>)>,
}

/// Panels stacked vertically over a shared x-axis (one per joint, as in the paper's figures),
/// the series in the same colours in every panel.
pub fn panels(path: &Path, title: &str, x_label: &str, panels: &[Panel]) -> anyhow::Result<()> {
    fonts();
    let height = 80 + 260 * panels.len() as u32;
    let root = BitMapBackend::new(path, (WIDTH, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 22))?;
    let (x0, x1) = range(panels.iter().flat_map(|p| p.series.iter().flat_map(|s| s.1.iter())));
    for (i, (area, panel)) in root.split_evenly((panels.len().max(1), 1)).iter().zip(panels).enumerate() {
        let (y0, y1) = range(panel.series.iter().flat_map(|s| s.2.iter()));
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart.configure_mesh().x_desc(x_label).y_desc(&panel.y_label).label_style(("sans-serif", 14)).draw()?;
        draw_lines(&mut chart, panel.series.iter().map(|(name, x, y)| (*name, *x, y.as_slice())))?;
        // One legend, on the first panel: the colours are the same in every panel.
        if i == 0 {
            chart.configure_series_labels().background_style(WHITE.mix(0.6)).border_style(BLACK).draw()?;
        }
    }
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A figure is a PNG with ink on it: not blank and not all one colour.
    #[test]
    fn figures_are_pngs_with_content() {
        let dir = std::env::temp_dir().join(format!("arash-figures-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let x: Vec<f64> = (0..500).map(|i| i as f64 * 0.01).collect();
        let y: Vec<f64> = x.iter().map(|v| v.sin()).collect();
        let z: Vec<f64> = x.iter().map(|v| 0.1 * v.cos()).collect();
        let scatter = dir.join("scatter.png");
        scatter_before_after(&scatter, "residual", "q (rad)", "N·m", &x, &y, &z).unwrap();
        let bars = dir.join("bars.png");
        bars_before_after(&bars, "FP%", "%", &["yaw".into(), "pitch".into()], &[80.0, 90.0], &[95.0, 99.0]).unwrap();
        let stacked = dir.join("panels.png");
        let panel =
            |label: &str| Panel { y_label: label.into(), series: vec![("a", &x[..], y.clone()), ("b", &x, z.clone())] };
        panels(&stacked, "two joints", "t (s)", &[panel("rad"), panel("m")]).unwrap();
        for path in [scatter, bars, stacked] {
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", path.display());
            assert!(bytes.len() > 5000, "{} is suspiciously small", path.display());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
