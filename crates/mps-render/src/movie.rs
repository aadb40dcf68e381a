//! Animations of a run: every snapshot drawn in one frame and one colour range, encoded as an
//! animated GIF by the `gif` crate.

use crate::canvas::Canvas;
use std::io::Write;

/// Encodes `frames` (all of one size) as a looping animated GIF, `delay_cs` hundredths of a
/// second per frame.
pub fn gif_bytes(frames: &[Canvas], delay_cs: u16) -> Result<Vec<u8>, String> {
    let first = frames.first().ok_or("no frames")?;
    let (w, h) = (first.width, first.height);
    let (w16, h16) = (
        u16::try_from(w).map_err(|_| format!("width {w} too large for a GIF"))?,
        u16::try_from(h).map_err(|_| format!("height {h} too large for a GIF"))?,
    );
    let mut out = Vec::new();
    {
        let mut enc = gif::Encoder::new(&mut out, w16, h16, &[]).map_err(|e| e.to_string())?;
        enc.set_repeat(gif::Repeat::Infinite)
            .map_err(|e| e.to_string())?;
        for c in frames {
            if (c.width, c.height) != (w, h) {
                return Err("frames differ in size".into());
            }
            // Quantisation speed 10 of 1..30: good colours at a few hundred ms per frame.
            let mut f = gif::Frame::from_rgb_speed(w16, h16, &c.pixels, 10);
            f.delay = delay_cs;
            enc.write_frame(&f).map_err(|e| e.to_string())?;
        }
    }
    out.flush().map_err(|e| e.to_string())?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canvas::BLACK;

    #[test]
    fn an_animation_has_one_image_per_frame() {
        let mut a = Canvas::new(20, 10);
        a.set(1, 1, BLACK);
        let b = Canvas::new(20, 10);
        let bytes = gif_bytes(&[a, b.clone(), b], 10).unwrap();
        assert!(bytes.starts_with(b"GIF89a"));
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut d = opts.read_info(bytes.as_slice()).unwrap();
        let mut n = 0;
        while d.read_next_frame().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, 3);
        assert!(gif_bytes(&[], 10).is_err());
    }
}
