//! Line charts of time series and benchmark ladders as SVG, drawn by `plotters`: round-number
//! ticks, a legend, lines for computed series and markers for reference data, logarithmic
//! axes where the data spans decades.

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// One curve of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
    /// Draw markers only (reference data) instead of a line.
    pub markers: bool,
}

/// A chart: title, axis labels, curves and axis scales.
#[derive(Clone, Debug, Default)]
pub struct Chart {
    /// Title above the plot.
    pub title: String,
    /// Label of the x axis, with its unit.
    pub x_label: String,
    /// Label of the y axis, with its unit.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Chart size (px).
const SIZE: (u32, u32) = (820, 460);

/// The data range `(lo, hi)` of the points usable on the axis (positive for a log axis),
/// widened when degenerate.
fn range(values: impl Iterator<Item = f64>, log: bool, pad: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if log { (1.0, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        let (l, h) = (lo.log10(), hi.log10().max(lo.log10() + 1e-3));
        let p = pad * (h - l);
        return (10f64.powf(l - p), 10f64.powf(h + p));
    }
    if hi <= lo {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - d, hi + d);
    }
    let p = pad * (hi - lo);
    (lo - p, hi + p)
}

/// Draws `c` on the SVG backend with the given axes.
fn draw<X, Y>(c: &Chart, svg: &mut String, x: X, y: Y) -> Result<(), String>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let root = SVGBackend::with_string(svg, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&c.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(78)
        .build_cartesian_2d(x, y)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(&c.x_label)
        .y_desc(&c.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .light_line_style(RGBColor(240, 240, 240))
        .draw()
        .map_err(|x| e(&x))?;
    for (k, s) in c.series.iter().enumerate() {
        let col = PALETTE[k % PALETTE.len()];
        let ok = |p: &&(f64, f64)| {
            p.0.is_finite() && p.1.is_finite() && (!c.log_x || p.0 > 0.0) && (!c.log_y || p.1 > 0.0)
        };
        let pts: Vec<(f64, f64)> = s.points.iter().filter(ok).copied().collect();
        if s.markers {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 4, col.filled())))
                .map_err(|x| e(&x))?
                .label(s.name.clone())
                .legend(move |(x, y)| Circle::new((x + 9, y), 4, col.filled()));
        } else {
            chart
                .draw_series(LineSeries::new(pts, col.stroke_width(2)))
                .map_err(|x| e(&x))?
                .label(s.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(3))
                });
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(200, 200, 200))
        .label_font(("sans-serif", 15))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// The chart as an SVG document.
pub fn line_chart_svg(c: &Chart) -> Result<String, String> {
    let xs = || c.series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let ys = || c.series.iter().flat_map(|s| s.points.iter().map(|p| p.1));
    let (x0, x1) = range(xs(), c.log_x, 0.0);
    let (y0, y1) = range(ys(), c.log_y, 0.05);
    let mut svg = String::new();
    let lin = |a: f64, b: f64| -> RangedCoordf64 { (a..b).into() };
    match (c.log_x, c.log_y) {
        (false, false) => draw(c, &mut svg, lin(x0, x1), lin(y0, y1))?,
        (true, false) => draw(c, &mut svg, (x0..x1).log_scale(), lin(y0, y1))?,
        (false, true) => draw(c, &mut svg, lin(x0, x1), (y0..y1).log_scale())?,
        (true, true) => draw(c, &mut svg, (x0..x1).log_scale(), (y0..y1).log_scale())?,
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart(log: bool) -> Chart {
        Chart {
            title: "t".into(),
            x_label: "particles".into(),
            y_label: "ms".into(),
            series: vec![
                Series {
                    name: "y = x".into(),
                    points: (1..=5).map(|k| (10f64.powi(k), k as f64)).collect(),
                    markers: false,
                },
                Series {
                    name: "reference".into(),
                    points: vec![(100.0, 2.0)],
                    markers: true,
                },
            ],
            log_x: log,
            log_y: false,
        }
    }

    #[test]
    fn a_chart_is_an_svg_with_its_labels_and_legend() {
        let svg = line_chart_svg(&chart(true)).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..80]);
        for text in ["particles", "ms", "y = x", "reference"] {
            assert!(svg.contains(text), "{text} missing");
        }
        // A log axis labels decades.
        assert!(svg.contains(">1000<") || svg.contains(">1e3<") || svg.contains("1000"));
    }

    #[test]
    fn ranges_are_padded_and_never_empty() {
        assert_eq!(range([2.0, 2.0].into_iter(), false, 0.0), (1.8, 2.2));
        assert_eq!(range([f64::NAN].into_iter(), false, 0.0), (0.0, 1.0));
        let (lo, hi) = range([-1.0, 10.0, 1000.0].into_iter(), true, 0.0);
        assert!((lo - 10.0).abs() < 1e-9 && (hi - 1000.0).abs() < 1e-6);
    }
}
