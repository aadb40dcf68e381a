//! Reference curves a case names for its validation: a CSV of (time, value) rows, read when
//! the case is loaded so that a bad file is bad input (exit 1), not a failure at the end of
//! a long run.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Where a reference curve lies and how to read it (`[validation]` of kinds `probe_reference`
/// and `front_reference`).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ReferenceFile {
    /// CSV file, relative to the case file's folder (or absolute).
    pub file: String,
    /// Header names of the time and value columns; default the first two columns.
    #[serde(default)]
    pub columns: Option<[String; 2]>,
    /// Factor from the file's time unit to seconds (1000 ms in a file: 0.001).
    #[serde(default = "one")]
    pub time_scale: f64,
    /// Factor from the file's value unit to the solver's (kPa in a file: 1000 for Pa).
    #[serde(default = "one")]
    pub value_scale: f64,
    /// The curve, in seconds and solver units, sorted by time (filled when the case loads).
    #[serde(skip)]
    pub curve: Vec<(f64, f64)>,
}

fn one() -> f64 {
    1.0
}

impl Default for ReferenceFile {
    fn default() -> Self {
        ReferenceFile {
            file: String::new(),
            columns: None,
            time_scale: 1.0,
            value_scale: 1.0,
            curve: Vec::new(),
        }
    }
}

impl ReferenceFile {
    /// Reads the curve from `self.file`, relative to `base`. The error is one line saying
    /// what is wrong (the caller names the case file and field).
    pub fn load(&mut self, base: &Path) -> Result<(), String> {
        if !(self.time_scale.is_finite() && self.time_scale > 0.0) {
            return Err(format!(
                "time_scale {} must be finite and > 0",
                self.time_scale
            ));
        }
        if !self.value_scale.is_finite() || self.value_scale == 0.0 {
            return Err(format!(
                "value_scale {} must be finite and non-zero",
                self.value_scale
            ));
        }
        let path = base.join(&self.file);
        let text =
            std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let mut curve = parse_curve(&text, self.columns.as_ref())?;
        for p in &mut curve {
            p.0 *= self.time_scale;
            p.1 *= self.value_scale;
        }
        self.curve = curve;
        Ok(())
    }
}

/// The most rows a reference curve may have (a bound on the work at the end of a run).
pub const MAX_ROWS: usize = 1_000_000;

/// Parses CSV bytes into `(time, value)` rows: `#` lines are comments, a first row that is
/// not numeric is the header; times must be finite and strictly increasing, values finite,
/// at least two rows.
pub fn parse_curve(bytes: &[u8], columns: Option<&[String; 2]>) -> Result<Vec<(f64, f64)>, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let mut records = reader.records();
    let mut index = [0usize, 1usize];
    let mut rows = Vec::new();
    let mut first = true;
    for (line, record) in (1..).zip(records.by_ref()) {
        let record = record.map_err(|e| format!("row {line}: {e}"))?;
        if first {
            first = false;
            let numeric = record.get(0).is_some_and(|f| f.parse::<f64>().is_ok());
            if !numeric {
                if let Some(names) = columns {
                    for (k, name) in names.iter().enumerate() {
                        index[k] = record.iter().position(|h| h == name).ok_or_else(|| {
                            format!("no column {name:?} in the header {:?}", cut(&record))
                        })?;
                    }
                }
                continue;
            }
            if columns.is_some() {
                return Err("`columns` names header columns, but the file has no header".into());
            }
        }
        if rows.len() == MAX_ROWS {
            return Err(format!("more than {MAX_ROWS} rows"));
        }
        let field = |k: usize| -> Result<f64, String> {
            let text = record
                .get(index[k])
                .ok_or_else(|| format!("row {line}: no column {}", index[k] + 1))?;
            let v: f64 = text
                .parse()
                .map_err(|_| format!("row {line}: {:?} is not a number", cut_str(text)))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("row {line}: {v} is not finite"))
            }
        };
        let (t, v) = (field(0)?, field(1)?);
        if let Some(&(t0, _)) = rows.last() {
            if t <= t0 {
                return Err(format!(
                    "row {line}: time {t} does not increase (after {t0})"
                ));
            }
        }
        rows.push((t, v));
    }
    if rows.len() < 2 {
        return Err(format!(
            "{} data rows; a curve needs at least 2",
            rows.len()
        ));
    }
    Ok(rows)
}

fn cut(record: &csv::StringRecord) -> String {
    cut_str(&record.iter().collect::<Vec<_>>().join(","))
}

fn cut_str(s: &str) -> String {
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_curve_with_a_header_comments_and_named_columns_is_read() {
        let text = b"# gauge P1\ntime_ms, h, p_kpa\n0, 9, 1.5\n2, 9, 2.5\n4, 9, 3.5\n";
        let cols = ["time_ms".to_string(), "p_kpa".to_string()];
        let c = parse_curve(text, Some(&cols)).unwrap();
        assert_eq!(c, vec![(0.0, 1.5), (2.0, 2.5), (4.0, 3.5)]);
        let c = parse_curve(b"0,1\n1,2\n", None).unwrap();
        assert_eq!(c, vec![(0.0, 1.0), (1.0, 2.0)]);
    }

    #[test]
    fn bad_curves_are_refused_with_the_row() {
        let e = parse_curve(b"t,p\n0,1\n0,2\n", None).unwrap_err();
        assert!(
            e.contains("row 3") && e.contains("does not increase"),
            "{e}"
        );
        let e = parse_curve(b"0,1\n1,x\n", None).unwrap_err();
        assert!(e.contains("row 2") && e.contains("\"x\""), "{e}");
        let e = parse_curve(b"0,1\n1,NaN\n", None).unwrap_err();
        assert!(e.contains("not finite"), "{e}");
        let e = parse_curve(b"0,1\n", None).unwrap_err();
        assert!(e.contains("at least 2"), "{e}");
        let e = parse_curve(b"0\n1\n", None).unwrap_err();
        assert!(e.contains("no column 2"), "{e}");
        let cols = ["t".to_string(), "q".to_string()];
        let e = parse_curve(b"t,p\n0,1\n1,2\n", Some(&cols)).unwrap_err();
        assert!(e.contains("no column \"q\""), "{e}");
        let e = parse_curve(b"0,1\n1,2\n", Some(&cols)).unwrap_err();
        assert!(e.contains("no header"), "{e}");
        assert!(!e.contains('\n'));
    }

    #[test]
    fn units_are_scaled_when_loaded() {
        let dir = std::env::temp_dir().join(format!("mps_reference_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("r.csv"), "t_ms,p_kpa\n0,1\n500,2\n").unwrap();
        let mut r = ReferenceFile {
            file: "r.csv".into(),
            time_scale: 1e-3,
            value_scale: 1e3,
            ..Default::default()
        };
        r.load(&dir).unwrap();
        assert_eq!(r.curve, vec![(0.0, 1000.0), (0.5, 2000.0)]);
        r.file = "missing.csv".into();
        assert!(r.load(&dir).unwrap_err().contains("cannot read"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
