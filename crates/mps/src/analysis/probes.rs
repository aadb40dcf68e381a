//! Probe series read as a user reads a pressure gauge: smoothed over a short window, and the
//! step-to-step noise around that smooth curve.

/// Smoothing window of probe series (s): 1 ms, shorter than any physical pressure event of the
/// shipped cases (an impact peak lasts several ms) and longer than a few steps.
pub const SMOOTHING_WINDOW: f64 = 1e-3;

/// The centred moving average of `series` (`(t, value)`, sorted by time) over `window` (s):
/// each point the mean of the values within `window / 2` of it. NaN values are skipped.
pub fn smooth(series: &[(f64, f64)], window: f64) -> Vec<(f64, f64)> {
    let half = 0.5 * window;
    let (mut lo, mut hi) = (0usize, 0usize);
    let (mut sum, mut count) = (0.0, 0usize);
    let mut out = Vec::with_capacity(series.len());
    for &(t, _) in series {
        while hi < series.len() && series[hi].0 <= t + half {
            if series[hi].1.is_finite() {
                sum += series[hi].1;
                count += 1;
            }
            hi += 1;
        }
        while series[lo].0 < t - half {
            if series[lo].1.is_finite() {
                sum -= series[lo].1;
                count -= 1;
            }
            lo += 1;
        }
        out.push((
            t,
            if count > 0 {
                sum / count as f64
            } else {
                f64::NAN
            },
        ));
    }
    out
}

/// The RMS of the raw series minus its smoothed curve (same unit as the values).
pub fn noise(series: &[(f64, f64)], window: f64) -> f64 {
    let s = smooth(series, window);
    let (mut sum, mut n) = (0.0, 0usize);
    for (raw, sm) in series.iter().zip(&s) {
        let d = raw.1 - sm.1;
        if d.is_finite() {
            sum += d * d;
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth ramp passes the smoothing unchanged away from the ends, and an alternating
    /// +-1 on a constant is measured as noise of about 1.
    #[test]
    fn smoothing_keeps_a_ramp_and_measures_alternating_noise() {
        let dt = 1e-4;
        let ramp: Vec<(f64, f64)> = (0..200).map(|k| (k as f64 * dt, 5.0 * k as f64)).collect();
        let s = smooth(&ramp, 1.05e-3);
        for k in 10..190 {
            assert!((s[k].1 - ramp[k].1).abs() < 1e-9, "{k}");
        }
        let noisy: Vec<(f64, f64)> = (0..200)
            .map(|k| (k as f64 * dt, 7.0 + if k % 2 == 0 { 1.0 } else { -1.0 }))
            .collect();
        let n = noise(&noisy, 1.05e-3);
        assert!(n > 0.85 && n < 1.15, "noise {n}");
        let flat: Vec<(f64, f64)> = (0..200).map(|k| (k as f64 * dt, 7.0)).collect();
        assert!(noise(&flat, 1.05e-3) < 1e-12);
    }
}
