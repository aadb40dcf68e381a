//! An RGB raster with the few primitives the figures need, and PNG encoding.

use std::path::Path;

/// An RGB image, row-major from the top-left corner.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// RGB bytes, 3 per pixel.
    pub pixels: Vec<u8>,
}

/// White.
pub const WHITE: [u8; 3] = [255, 255, 255];
/// Black.
pub const BLACK: [u8; 3] = [0, 0, 0];

impl Canvas {
    /// A white canvas.
    pub fn new(width: u32, height: u32) -> Self {
        Canvas {
            width,
            height,
            pixels: vec![255; (width * height * 3) as usize],
        }
    }
    /// Colour at pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> [u8; 3] {
        let i = ((y * self.width + x) * 3) as usize;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }
    /// Sets pixel (x, y) if it lies on the canvas.
    pub fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            let i = ((y as u32 * self.width + x as u32) * 3) as usize;
            self.pixels[i..i + 3].copy_from_slice(&c);
        }
    }
    /// Fills a disc of radius `r` (px) centred at (cx, cy).
    pub fn disc(&mut self, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        let r = r.max(0.5);
        let (x0, x1) = ((cx - r).floor() as i64, (cx + r).ceil() as i64);
        let (y0, y1) = ((cy - r).floor() as i64, (cy + r).ceil() as i64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                if dx * dx + dy * dy <= r * r {
                    self.set(x, y, c);
                }
            }
        }
    }
    /// Fills the rectangle [x0, x1) x [y0, y1).
    pub fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3]) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.set(x, y, c);
            }
        }
    }
    /// A line of width about `w` px from (x0, y0) to (x1, y1).
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, w: f64, c: [u8; 3]) {
        let len = ((x1 - x0).powi(2) + (y1 - y0).powi(2)).sqrt();
        let n = (len * 2.0).ceil().max(1.0) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            self.disc(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, w / 2.0, c);
        }
    }
    /// An arrow from (x0, y0) to (x1, y1) with a head.
    pub fn arrow(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: [u8; 3]) {
        self.line(x0, y0, x1, y1, 1.0, c);
        let (dx, dy) = (x1 - x0, y1 - y0);
        let len = (dx * dx + dy * dy).sqrt();
        if len < 1.0 {
            return;
        }
        let head = (0.3 * len).clamp(2.0, 6.0);
        let (ux, uy) = (dx / len, dy / len);
        for s in [-1.0, 1.0] {
            let (hx, hy) = (
                x1 - head * (ux * 0.866 - s * uy * 0.5),
                y1 - head * (uy * 0.866 + s * ux * 0.5),
            );
            self.line(x1, y1, hx, hy, 1.0, c);
        }
    }
    /// Text from an 8x8 bitmap font at integer `scale`, top-left at (x, y); returns its width.
    pub fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: [u8; 3]) -> i64 {
        use font8x8::legacy::BASIC_LEGACY;
        let mut cx = x;
        for ch in s.chars() {
            let glyph = BASIC_LEGACY.get(ch as usize).copied().unwrap_or([0; 8]);
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits & (1 << col) != 0 {
                        self.rect(
                            cx + col * scale,
                            y + row as i64 * scale,
                            cx + (col + 1) * scale,
                            y + (row as i64 + 1) * scale,
                            c,
                        );
                    }
                }
            }
            cx += 8 * scale;
        }
        cx - x
    }
    /// Encodes as PNG.
    pub fn png_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().expect("in-memory PNG header");
            w.write_image_data(&self.pixels)
                .expect("in-memory PNG data");
        }
        out
    }
    /// Writes a PNG file atomically.
    pub fn write_png(&self, path: &Path) -> mps::error::Result<()> {
        mps::io::write_atomic(path, &self.png_bytes())
    }
}
