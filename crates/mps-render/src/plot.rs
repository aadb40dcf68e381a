//! Line charts of time series: axes with round-number ticks, a legend, lines for computed
//! series and markers for reference data.

use crate::canvas::{Canvas, BLACK, WHITE};
use crate::snapshot::fmt_value;

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

const PALETTE: [[u8; 3]; 6] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [140, 86, 75],
];
const LEFT: f64 = 90.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 44.0;
const BOTTOM: f64 = 46.0;

/// Round tick positions covering [lo, hi], about five of them.
pub fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return vec![lo];
    }
    let raw = (hi - lo) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + 1e-9 * step {
        out.push(if t.abs() < 1e-12 * step { 0.0 } else { t });
        t += step;
    }
    out
}

/// Draws a chart of `series` with a title and axis labels.
pub fn line_chart(
    title: &str,
    xlabel: &str,
    ylabel: &str,
    series: &[Series],
    width: u32,
    height: u32,
) -> Canvas {
    let mut c = Canvas::new(width, height);
    let pts = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for p in pts {
        x0 = x0.min(p.0);
        x1 = x1.max(p.0);
        y0 = y0.min(p.1);
        y1 = y1.max(p.1);
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        let d = if y0 == 0.0 { 1.0 } else { 0.1 * y0.abs() };
        y0 -= d;
        y1 += d;
    }
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let (w, h) = (width as f64 - LEFT - RIGHT, height as f64 - TOP - BOTTOM);
    let px = |x: f64| LEFT + (x - x0) / (x1 - x0) * w;
    let py = |y: f64| TOP + (y1 - y) / (y1 - y0) * h;
    // Axes, ticks, grid.
    for t in ticks(x0, x1) {
        let x = px(t);
        c.line(x, TOP, x, TOP + h, 1.0, [230, 230, 230]);
        let s = fmt_value(t);
        c.text(
            x as i64 - 4 * s.len() as i64,
            (TOP + h + 6.0) as i64,
            &s,
            1,
            BLACK,
        );
    }
    for t in ticks(y0, y1) {
        let y = py(t);
        c.line(LEFT, y, LEFT + w, y, 1.0, [230, 230, 230]);
        let s = fmt_value(t);
        c.text(
            LEFT as i64 - 6 - 8 * s.len() as i64,
            y as i64 - 4,
            &s,
            1,
            BLACK,
        );
    }
    c.line(LEFT, TOP + h, LEFT + w, TOP + h, 1.0, BLACK);
    c.line(LEFT, TOP, LEFT, TOP + h, 1.0, BLACK);
    c.text(10, 10, title, 2, BLACK);
    c.text(
        (LEFT + w / 2.0) as i64 - 4 * xlabel.len() as i64,
        height as i64 - 16,
        xlabel,
        1,
        BLACK,
    );
    c.text(10, 30, ylabel, 1, BLACK);
    // Curves.
    for (k, s) in series.iter().enumerate() {
        let col = PALETTE[k % PALETTE.len()];
        let finite: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        if s.markers {
            for p in &finite {
                c.disc(px(p.0), py(p.1), 3.0, col);
            }
        } else {
            for pair in finite.windows(2) {
                c.line(
                    px(pair[0].0),
                    py(pair[0].1),
                    px(pair[1].0),
                    py(pair[1].1),
                    1.5,
                    col,
                );
            }
        }
        // Legend, top right.
        let ly = TOP as i64 + 8 + 14 * k as i64;
        let lx = (LEFT + w) as i64 - 12 - 8 * s.name.len() as i64 - 24;
        c.rect(lx - 4, ly - 3, (LEFT + w) as i64 - 4, ly + 11, WHITE);
        c.rect(lx, ly + 3, lx + 16, ly + 5, col);
        c.text(lx + 22, ly, &s.name, 1, BLACK);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(
            ticks(0.0, 1.0),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        let t = ticks(-147.0, 12.0);
        assert!(t.iter().all(|v| (v / 50.0).fract().abs() < 1e-9));
        assert!(t[0] >= -147.0 && *t.last().unwrap() <= 12.0);
    }

    #[test]
    fn a_rising_line_rises_on_the_canvas() {
        let s = Series {
            name: "y = x".into(),
            points: (0..=10).map(|k| (k as f64, k as f64)).collect(),
            markers: false,
        };
        let c = line_chart("t", "x", "y", &[s], 400, 300);
        let col = PALETTE[0];
        // Find the curve's pixels in the left and right quarter: the right ones sit higher.
        let mean_row = |xa: u32, xb: u32| {
            let (mut sum, mut n) = (0.0, 0.0);
            for x in xa..xb {
                for y in 0..c.height {
                    if c.get(x, y) == col {
                        sum += y as f64;
                        n += 1.0;
                    }
                }
            }
            sum / n
        };
        assert!(mean_row(100, 150) > mean_row(300, 360));
    }
}
