//! Particle snapshots: each particle a disc of its diameter (l0) in world units, coloured by
//! a field, walls in grey, optional velocity vectors with a reference arrow, a colour bar
//! with its range and unit, the time in the title, the domain's true aspect ratio.

use crate::canvas::{Canvas, BLACK, WHITE};
use crate::colormap::viridis;
use mps::io::vtu::read_particle_file;
use std::path::Path;

pub use mps::io::vtu::read_pvd;

/// One output state of a run, as read from its VTU file.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    /// Simulated time (s).
    pub time: f64,
    /// Particle spacing l0 (m).
    pub spacing: f64,
    /// Positions (m).
    pub position: Vec<[f64; 2]>,
    /// Velocities (m/s).
    pub velocity: Vec<[f64; 2]>,
    /// Kind: 0 fluid, 1 wall, 2 dummy.
    pub kind: Vec<u8>,
    /// Pressure (Pa).
    pub pressure: Vec<f64>,
    /// Density (kg/m^3).
    pub density: Vec<f64>,
    /// Phase index.
    pub phase: Vec<f64>,
    /// Free-surface flag (1 on the surface).
    pub free_surface: Vec<f64>,
    /// Speed (m/s), of all components (a 3D run's out-of-page one included).
    pub speed: Vec<f64>,
    /// Brightness factor of each particle (1; less for far particles of a 3D view).
    pub shade: Vec<f64>,
}

/// Particle spacing (m) estimated as the median nearest-neighbour distance of up to 200
/// sampled particles (for VTU files without a `Spacing` field).
fn estimate_spacing(p: &[[f64; 2]]) -> Option<f64> {
    if p.len() < 2 {
        return None;
    }
    let step = (p.len() / 200).max(1);
    let mut d: Vec<f64> = (0..p.len())
        .step_by(step)
        .map(|i| {
            p.iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| ((q[0] - p[i][0]).powi(2) + (q[1] - p[i][1]).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

impl std::str::FromStr for Field {
    type Err = String;
    fn from_str(s: &str) -> Result<Field, String> {
        Field::parse(s).ok_or_else(|| format!("{s}: one of {}", Field::NAMES.join(", ")))
    }
}

/// The quantity a snapshot is coloured by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// Pressure (Pa).
    Pressure,
    /// Speed (m/s).
    Velocity,
    /// Phase index.
    Phase,
    /// Density (kg/m^3).
    Density,
    /// The free-surface flag (0 or 1).
    Surface,
}

impl Field {
    /// The field names as written on the command line.
    pub const NAMES: [&'static str; 5] = ["pressure", "velocity", "phase", "density", "surface"];

    /// Parses `pressure`, `velocity`, `phase`, `density`.
    pub fn parse(s: &str) -> Option<Field> {
        match s {
            "pressure" => Some(Field::Pressure),
            "velocity" => Some(Field::Velocity),
            "phase" => Some(Field::Phase),
            "density" => Some(Field::Density),
            "surface" => Some(Field::Surface),
            _ => None,
        }
    }

    /// Its name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Field::Pressure => "pressure",
            Field::Velocity => "velocity",
            Field::Phase => "phase",
            Field::Density => "density",
            Field::Surface => "surface",
        }
    }
    /// Name and unit for titles and colour bars.
    pub fn label(&self) -> (&'static str, &'static str) {
        match self {
            Field::Pressure => ("pressure", "Pa"),
            Field::Velocity => ("speed", "m/s"),
            Field::Phase => ("phase", "-"),
            Field::Density => ("density", "kg/m3"),
            Field::Surface => ("free-surface flag", "-"),
        }
    }
}

/// How a 3D run is drawn on the page (a 2D run is drawn as it is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// The particles within l0/2 of the plane `x[axis] = at` (m); `at` by default through
    /// the middle of the fluid.
    Slice {
        /// Axis normal to the plane (0 x, 1 y, 2 z).
        axis: usize,
        /// Position of the plane along it (m).
        at: Option<f64>,
    },
    /// Every fluid particle seen along `axis` from its low side, nearer ones drawn over
    /// farther ones and shaded by depth; walls only behind the fluid.
    View {
        /// Axis of the line of sight (0 x, 1 y, 2 z).
        axis: usize,
    },
}

impl Default for Projection {
    fn default() -> Self {
        Projection::Slice { axis: 1, at: None }
    }
}

impl Projection {
    /// The two page axes (right, up) for line of sight `axis`: the others, in order.
    pub fn page_axes(axis: usize) -> [usize; 2] {
        match axis {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        }
    }

    /// Parses `x=0.05` (a slice) or `y` (a view along the axis).
    pub fn parse(s: &str, slice: bool) -> Result<Projection, String> {
        let (name, at) = match s.split_once('=') {
            Some((n, v)) => (n.trim(), Some(v.trim())),
            None => (s.trim(), None),
        };
        let axis = ["x", "y", "z"]
            .iter()
            .position(|a| *a == name)
            .ok_or_else(|| format!("{s}: the axis is x, y or z"))?;
        if !slice {
            return match at {
                None => Ok(Projection::View { axis }),
                Some(_) => Err(format!("{s}: a view names an axis only (x, y or z)")),
            };
        }
        let at = match at {
            None => None,
            Some(v) => match v.parse::<f64>() {
                Ok(x) if x.is_finite() => Some(x),
                _ => return Err(format!("{s}: expected AXIS=POSITION, e.g. y=0.05")),
            },
        };
        Ok(Projection::Slice { axis, at })
    }
}

/// The median of the fluid's coordinate `axis` (m); 0 without fluid.
fn fluid_median(pos: &[[f64; 3]], kind: &[u8], axis: usize) -> f64 {
    let mut v: Vec<f64> = (0..pos.len())
        .filter(|&i| kind[i] == 0)
        .map(|i| pos[i][axis])
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

impl Frame {
    /// Reads a frame from the bytes of VTU (or `.pvtu`) file `path` written by the solver (a
    /// 3D run through the default slice).
    pub fn from_vtu(bytes: &[u8], path: &Path) -> mps::error::Result<Frame> {
        Frame::from_vtu_projected(bytes, path, Projection::default())
    }

    /// Reads a frame from VTU file `path`; a 3D run is drawn by `projection`.
    pub fn from_vtu_projected(
        bytes: &[u8],
        path: &Path,
        projection: Projection,
    ) -> mps::error::Result<Frame> {
        // A VTU, or the .pvtu index of a distributed run's snapshot (its pieces joined).
        let ((p, time, spacing), dimension) = read_particle_file::<3>(bytes, path)?;
        let dimension = dimension.unwrap_or(2.0);
        let pos3: Vec<[f64; 3]> = p.position.iter().map(|x| x.0).collect();
        let kind: Vec<u8> = p.kind.iter().map(|&k| k as u8).collect();
        // Which particles are drawn, in which order, on which page axes; and a depth shade.
        let n = pos3.len();
        let (order, axes, shade): (Vec<usize>, [usize; 2], Vec<f64>) = if dimension < 2.5 {
            ((0..n).collect(), [0, 1], vec![1.0; n])
        } else {
            let l0 = spacing.unwrap_or(0.0);
            match projection {
                Projection::Slice { axis, at } => {
                    let at = at.unwrap_or_else(|| fluid_median(&pos3, &kind, axis));
                    let keep = (0..n)
                        .filter(|&i| (pos3[i][axis] - at).abs() <= 0.5 * l0 + 1e-12)
                        .collect();
                    (keep, Projection::page_axes(axis), vec![1.0; n])
                }
                Projection::View { axis } => {
                    let fluid = (0..n).filter(|&i| kind[i] == 0);
                    let depths = fluid.clone().map(|i| pos3[i][axis]);
                    let near = depths.clone().fold(f64::INFINITY, f64::min);
                    let far = depths.fold(f64::NEG_INFINITY, f64::max);
                    // Fluid, and walls from the nearest fluid depth back; far ones first.
                    let mut keep: Vec<usize> = (0..n)
                        .filter(|&i| kind[i] == 0 || (kind[i] == 1 && pos3[i][axis] >= near))
                        .collect();
                    keep.sort_by(|&a, &b| pos3[b][axis].total_cmp(&pos3[a][axis]));
                    let span = (far - near).max(1e-12);
                    let shade = (0..n)
                        .map(|i| 1.0 - 0.45 * ((pos3[i][axis] - near) / span).clamp(0.0, 1.0))
                        .collect();
                    (keep, Projection::page_axes(axis), shade)
                }
            }
        };
        let position: Vec<[f64; 2]> = order
            .iter()
            .map(|&i| [pos3[i][axes[0]], pos3[i][axes[1]]])
            .collect();
        let pick = |v: &[f64]| order.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        let speed: Vec<f64> = p.velocity.iter().map(|u| u.norm()).collect();
        let spacing = spacing
            .or_else(|| estimate_spacing(&position))
            .ok_or_else(|| mps::Error::Format {
                path: path.to_path_buf(),
                message: "no Spacing in field data and too few particles to estimate it".into(),
            })?;
        let phase: Vec<f64> = p.phase.iter().map(|&v| v as f64).collect();
        let surface: Vec<f64> = p.free_surface.iter().map(|&f| f as u8 as f64).collect();
        Ok(Frame {
            time: time.unwrap_or(0.0),
            spacing,
            position,
            velocity: order
                .iter()
                .map(|&i| [p.velocity[i][axes[0]], p.velocity[i][axes[1]]])
                .collect(),
            speed: pick(&speed),
            kind: order.iter().map(|&i| kind[i]).collect(),
            pressure: pick(&p.pressure),
            density: pick(&p.density),
            phase: pick(&phase),
            free_surface: pick(&surface),
            shade: pick(&shade),
        })
    }

    /// The values of `field` for every particle.
    pub fn values(&self, field: Field) -> Vec<f64> {
        match field {
            Field::Pressure => self.pressure.clone(),
            Field::Velocity => self.speed.clone(),
            Field::Phase => self.phase.clone(),
            Field::Density => self.density.clone(),
            Field::Surface => self.free_surface.clone(),
        }
    }

    /// The colour range of `field` over fluid particles: its 1st to 99th percentile, so that
    /// a few spikes do not wash out the picture (the full range for the 0/1 flag and phase).
    pub fn range(&self, field: Field) -> (f64, f64) {
        let v = self.values(field);
        let mut fluid: Vec<f64> = v
            .iter()
            .zip(&self.kind)
            .filter(|(x, k)| **k == 0 && x.is_finite())
            .map(|(x, _)| *x)
            .collect();
        if fluid.is_empty() {
            return (0.0, 1.0);
        }
        fluid.sort_by(f64::total_cmp);
        let exact = matches!(field, Field::Surface | Field::Phase);
        let q = |f: f64| fluid[((fluid.len() - 1) as f64 * f).round() as usize];
        let (lo, hi) = if exact {
            (q(0.0), q(1.0))
        } else {
            (q(0.01), q(0.99))
        };
        if hi > lo {
            (lo, hi)
        } else {
            (lo - 0.5, lo + 0.5)
        }
    }

    /// The box (m) that frames the fluid: the 0.5th to 99.5th percentile of the fluid
    /// positions per axis (spray far away does not shrink the picture), joined with the
    /// walls' extent, padded by two spacings.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for k in 0..2 {
            let mut xs: Vec<f64> = (0..self.position.len())
                .filter(|&i| self.kind[i] == 0)
                .map(|i| self.position[i][k])
                .collect();
            xs.sort_by(f64::total_cmp);
            if let (Some(_), n) = (xs.first(), xs.len()) {
                lo[k] = xs[((n - 1) as f64 * 0.005).round() as usize];
                hi[k] = xs[((n - 1) as f64 * 0.995).round() as usize];
            }
            for i in (0..self.position.len()).filter(|&i| self.kind[i] != 0) {
                lo[k] = lo[k].min(self.position[i][k]);
                hi[k] = hi[k].max(self.position[i][k]);
            }
            if !lo[k].is_finite() {
                (lo[k], hi[k]) = (0.0, 1.0);
            }
        }
        let pad = 2.0 * self.spacing;
        ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad])
    }
}

/// The union of boxes.
pub fn union_bounds(
    boxes: impl IntoIterator<Item = ([f64; 2], [f64; 2])>,
) -> Option<([f64; 2], [f64; 2])> {
    boxes.into_iter().reduce(|a, b| {
        (
            [a.0[0].min(b.0[0]), a.0[1].min(b.0[1])],
            [a.1[0].max(b.1[0]), a.1[1].max(b.1[1])],
        )
    })
}

/// How to draw a snapshot.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Image width (px); the height follows from the domain's aspect ratio.
    pub width: u32,
    /// Colouring field.
    pub field: Field,
    /// Draw velocity vectors.
    pub vectors: bool,
    /// Colour range (default: the frame's fluid range).
    pub range: Option<(f64, f64)>,
    /// World bounds (lower-left, upper-right) in m (default: [`Frame::bounds`]).
    pub bounds: Option<([f64; 2], [f64; 2])>,
    /// Speed drawn as the longest arrow (m/s) (default: the frame's largest fluid speed).
    pub vector_scale: Option<f64>,
    /// Extra text before the title (e.g. the scheme).
    pub label: String,
    /// Mark the frame as broken down (a red band and the word in the title).
    pub breakdown: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 900,
            field: Field::Pressure,
            vectors: false,
            range: None,
            bounds: None,
            vector_scale: None,
            label: String::new(),
            breakdown: false,
        }
    }
}

/// Layout constants (px).
const MARGIN: i64 = 10;
const TITLE: i64 = 34;
const BAR_AREA: i64 = 130;
const BAR_WIDTH: i64 = 18;

/// A time for a title: four significant digits (0.0076 stays 0.0076, 3.0 reads 3.000).
pub fn time_label(t: f64) -> String {
    if t == 0.0 || !t.is_finite() {
        return format!("{t:.3}");
    }
    let decimals = (3 - t.abs().log10().floor() as i64).clamp(0, 12) as usize;
    format!("{t:.decimals$}")
}

/// Compact number for labels.
pub fn fmt_value(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) {
        format!("{v:.2e}")
    } else {
        format!("{v:.2}")
    }
}

/// Placement of the world in the image: scale (px/m), world lower-left, plot origin.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    /// Pixels per metre.
    pub scale: f64,
    /// World lower-left corner (m).
    pub lo: [f64; 2],
    /// World upper-right corner (m).
    pub hi: [f64; 2],
    /// Plot area's left edge (px).
    pub left: f64,
    /// Plot area's top edge (px).
    pub top: f64,
}

impl Placement {
    /// Pixel coordinates of a world point.
    pub fn to_px(&self, x: [f64; 2]) -> (f64, f64) {
        (
            self.left + (x[0] - self.lo[0]) * self.scale,
            self.top + (self.hi[1] - x[1]) * self.scale,
        )
    }
}

/// The placement of a frame's world in an image of the options' width.
pub fn placement(frame: &Frame, opts: &RenderOptions) -> Placement {
    let (lo, hi) = opts.bounds.unwrap_or_else(|| frame.bounds());
    let plot_w = (opts.width as i64 - 2 * MARGIN - BAR_AREA).max(50) as f64;
    Placement {
        scale: plot_w / (hi[0] - lo[0]).max(1e-12),
        lo,
        hi,
        left: MARGIN as f64,
        top: TITLE as f64,
    }
}

/// The brightness factor of particle `i` (1 where the frame has none).
fn self_shade(frame: &Frame, i: usize) -> f64 {
    frame.shade.get(i).copied().unwrap_or(1.0)
}

/// Draws one frame.
pub fn render_frame(frame: &Frame, opts: &RenderOptions) -> Canvas {
    let pl = placement(frame, opts);
    let plot_h = ((pl.hi[1] - pl.lo[1]) * pl.scale).ceil() as i64;
    let height = (TITLE + plot_h + MARGIN).max(TITLE + 120) as u32;
    let mut c = Canvas::new(opts.width, height);
    let values = frame.values(opts.field);
    let (vmin, vmax) = opts.range.unwrap_or_else(|| frame.range(opts.field));
    let span = if vmax > vmin { vmax - vmin } else { 1.0 };
    let r = (0.5 * frame.spacing * pl.scale).max(0.75);
    // Walls and dummies first (grey), then fluid on top.
    for i in 0..frame.position.len() {
        if frame.kind[i] != 0 {
            let (x, y) = pl.to_px(frame.position[i]);
            let g = if frame.kind[i] == 1 { 150 } else { 200 };
            c.disc(x, y, r, [g, g, g]);
        }
    }
    for i in 0..frame.position.len() {
        if frame.kind[i] == 0 {
            let (x, y) = pl.to_px(frame.position[i]);
            let rgb = viridis((values[i] - vmin) / span);
            let s = self_shade(frame, i);
            c.disc(x, y, r, rgb.map(|v| (v as f64 * s).round() as u8));
        }
    }
    let (name, unit) = opts.field.label();
    let mut title = format!("{name} ({unit})   t = {} s", time_label(frame.time));
    if !opts.label.is_empty() {
        title = format!("{}   {title}", opts.label);
    }
    if opts.breakdown {
        title.push_str("   BREAKDOWN");
        c.rect(0, 0, opts.width as i64, 4, [200, 30, 30]);
    }
    // Large font when the title fits beside the colour bar, else the small one.
    let fits = (title.len() as i64) * 16 <= opts.width as i64 - BAR_AREA - MARGIN;
    c.text(
        MARGIN,
        if fits { 12 } else { 16 },
        &title,
        if fits { 2 } else { 1 },
        BLACK,
    );
    if opts.vectors {
        draw_vectors(&mut c, frame, &pl, opts);
    }
    // Colour bar: max at the top, min at the bottom.
    let bx = opts.width as i64 - BAR_AREA + 12;
    let (top, bottom) = (TITLE + 22, TITLE + plot_h.max(100) - 14);
    for y in top..bottom {
        let t = 1.0 - (y - top) as f64 / (bottom - 1 - top).max(1) as f64;
        c.rect(bx, y, bx + BAR_WIDTH, y + 1, viridis(t));
    }
    c.text(bx, TITLE + 4, unit, 1, BLACK);
    c.text(bx + BAR_WIDTH + 4, top, &fmt_value(vmax), 1, BLACK);
    c.text(
        bx + BAR_WIDTH + 4,
        (top + bottom) / 2 - 4,
        &fmt_value(0.5 * (vmin + vmax)),
        1,
        BLACK,
    );
    c.text(bx + BAR_WIDTH + 4, bottom - 8, &fmt_value(vmin), 1, BLACK);
    c
}

fn draw_vectors(c: &mut Canvas, frame: &Frame, pl: &Placement, opts: &RenderOptions) {
    let speeds = frame.values(Field::Velocity);
    let umax = opts.vector_scale.unwrap_or_else(|| {
        speeds
            .iter()
            .zip(&frame.kind)
            .filter(|(_, k)| **k == 0)
            .map(|(s, _)| *s)
            .fold(0.0, f64::max)
    });
    if umax <= 0.0 {
        return;
    }
    let longest = 24.0; // px for umax
    let cell = 14.0; // at most one arrow per cell of this size (px)
    let mut taken = std::collections::HashSet::new();
    for i in 0..frame.position.len() {
        if frame.kind[i] != 0 {
            continue;
        }
        let (x, y) = pl.to_px(frame.position[i]);
        if !taken.insert(((x / cell) as i64, (y / cell) as i64)) {
            continue;
        }
        let u = frame.velocity[i];
        let (dx, dy) = (u[0] / umax * longest, -u[1] / umax * longest);
        c.arrow(x, y, x + dx, y + dy, BLACK);
    }
    // Reference arrow in the title row, above the colour bar.
    let bx = opts.width as f64 - BAR_AREA as f64 + 12.0;
    let y = 16.0;
    c.rect(bx as i64 - 2, 4, c.width as i64, 28, WHITE);
    c.arrow(bx, y, bx + longest, y, BLACK);
    c.text(
        bx as i64 + longest as i64 + 4,
        y as i64 - 4,
        &format!("{} m/s", fmt_value(umax)),
        1,
        BLACK,
    );
}

/// Lays canvases out in a grid (row-major, `cols` per row) on a white background.
pub fn compose(panels: &[Canvas], cols: usize) -> Canvas {
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols);
    let w = panels.iter().map(|p| p.width).max().unwrap_or(1);
    let h = panels.iter().map(|p| p.height).max().unwrap_or(1);
    let mut out = Canvas::new(w * cols as u32, h * rows.max(1) as u32);
    for (k, p) in panels.iter().enumerate() {
        let (ox, oy) = ((k % cols) as u32 * w, (k / cols) as u32 * h);
        for y in 0..p.height {
            for x in 0..p.width {
                out.set((ox + x) as i64, (oy + y) as i64, p.get(x, y));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three fluid particles with known pressures and one wall particle.
    fn frame() -> Frame {
        Frame {
            time: 0.25,
            spacing: 0.1,
            position: vec![[0.0, 0.0], [1.0, 0.0], [0.5, 0.5], [0.0, 1.0]],
            velocity: vec![[1.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]],
            kind: vec![0, 0, 0, 1],
            pressure: vec![0.0, 100.0, 50.0, 0.0],
            density: vec![1000.0; 4],
            phase: vec![0.0; 4],
            free_surface: vec![0.0; 4],
            speed: vec![1.0, 0.0, 0.0, 0.0],
            shade: vec![1.0; 4],
        }
    }

    #[test]
    fn titles_keep_four_significant_digits_of_time() {
        assert_eq!(time_label(0.0076), "0.007600");
        assert_eq!(time_label(3.0), "3.000");
        assert_eq!(time_label(12.5), "12.50");
        assert_eq!(time_label(0.0), "0.000");
    }

    #[test]
    fn particles_take_the_colour_of_their_value_and_the_rest_stays_empty() {
        let f = frame();
        let opts = RenderOptions {
            width: 600,
            ..Default::default()
        };
        let c = render_frame(&f, &opts);
        let pl = placement(&f, &opts);
        assert_eq!(c.width, 600);
        // Square world (1.2 m x 1.2 m) -> plot as high as wide.
        let plot_w = 600 - 2 * MARGIN - BAR_AREA;
        assert_eq!(c.height as i64, TITLE + plot_w + MARGIN);
        for (i, want) in [(0usize, 0.0), (1, 1.0), (2, 0.5)] {
            let (x, y) = pl.to_px(f.position[i]);
            assert_eq!(c.get(x as u32, y as u32), viridis(want), "particle {i}");
        }
        let (x, y) = pl.to_px(f.position[3]);
        assert_eq!(c.get(x as u32, y as u32), [150, 150, 150], "wall in grey");
        // Empty space between particles stays white.
        let (x, y) = pl.to_px([0.5, 0.0]);
        assert_eq!(c.get(x as u32, y as u32), WHITE);
        let (x, y) = pl.to_px([0.25, 0.75]);
        assert_eq!(c.get(x as u32, y as u32), WHITE);
    }

    #[test]
    fn colour_bar_ends_match_the_field_range() {
        let f = frame();
        let c = render_frame(&f, &RenderOptions::default());
        let bx = (900 - BAR_AREA + 12 + BAR_WIDTH / 2) as u32;
        let top = (TITLE + 22) as u32;
        let plot_h = c.height as i64 - TITLE - MARGIN;
        let bottom = (TITLE + plot_h - 14 - 1) as u32;
        assert_eq!(c.get(bx, top), viridis(1.0));
        assert_eq!(c.get(bx, bottom), viridis(0.0));
    }

    #[test]
    fn velocity_arrow_points_along_the_velocity() {
        let f = frame();
        let opts = RenderOptions {
            width: 600,
            vectors: true,
            ..Default::default()
        };
        let c = render_frame(&f, &opts);
        let pl = placement(&f, &opts);
        let (x, y) = pl.to_px(f.position[0]);
        // Particle 0 moves in +x at the largest speed: black pixels to its right, on its row,
        // beyond the disc, and none to its left.
        let r = 0.5 * f.spacing * pl.scale;
        let right = (x + r + 3.0) as u32;
        assert_eq!(c.get(right, y as u32), BLACK);
        let left = (x - r - 3.0).max(0.0) as u32;
        assert_ne!(c.get(left, y as u32), BLACK);
    }

    #[test]
    fn spacing_of_older_files_is_estimated_from_the_lattice() {
        let p: Vec<[f64; 2]> = (0..400)
            .map(|k| [(k % 20) as f64 * 0.01, (k / 20) as f64 * 0.01])
            .collect();
        assert!((estimate_spacing(&p).unwrap() - 0.01).abs() < 1e-12);
        assert_eq!(estimate_spacing(&p[..1]), None);
    }

    #[test]
    fn panels_are_laid_out_row_by_row() {
        let mut a = Canvas::new(4, 3);
        a.set(0, 0, BLACK);
        let b = Canvas::new(4, 3);
        let g = compose(&[a.clone(), b.clone(), b, a], 2);
        assert_eq!((g.width, g.height), (8, 6));
        assert_eq!(g.get(0, 0), BLACK);
        assert_eq!(g.get(4, 0), WHITE);
        assert_eq!(g.get(4, 3), BLACK);
    }

    #[test]
    fn a_frame_round_trips_through_vtu() {
        use mps::particles::{Kind, NewParticle, Particles, Vector};
        let mut p = Particles::<2>::default();
        p.push(NewParticle {
            position: Vector([0.1, 0.2]),
            velocity: Vector([1.0, 2.0]),
            kind: Kind::Fluid,
            phase: 0,
            density: 1000.0,
        });
        p.pressure[0] = 42.0;
        let b = mps::io::vtu::vtu_bytes(&p, 0.75, 0.005);
        let f = Frame::from_vtu(&b, Path::new("f.vtu")).unwrap();
        assert_eq!(f.time, 0.75);
        assert_eq!(f.spacing, 0.005);
        assert_eq!(f.position, vec![[0.1, 0.2]]);
        assert_eq!(f.pressure, vec![42.0]);
    }
}
