//! `mps bench --baseline FILE.csv`: each figure of a benchmark against a stored run of the
//! same command (its `--csv`), as the ratio new / old, so that a change that slows a stage
//! shows. Rows are matched by thread count and particle count.

use crate::failure::{bad, Failure};
use std::path::Path;

/// A benchmark table: column names and rows of numbers (a cell that is not a number is NaN).
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Table {
    /// Parses a CSV table as `mps bench --csv` writes it; `what` names it in errors.
    pub fn parse(text: &str, what: &str) -> Result<Table, Failure> {
        let mut r = csv::ReaderBuilder::new().from_reader(text.as_bytes());
        let header: Vec<String> = r
            .headers()
            .map_err(|e| bad(format!("{what}: not a benchmark table: {e}")))?
            .iter()
            .map(str::to_string)
            .collect();
        for key in ["threads", "particles"] {
            if !header.iter().any(|h| h == key) {
                return Err(bad(format!(
                    "{what}: no `{key}` column (not a `mps bench --csv` table)"
                )));
            }
        }
        let mut rows = Vec::new();
        for rec in r.records() {
            let rec = rec.map_err(|e| bad(format!("{what}: {e}")))?;
            rows.push(
                rec.iter()
                    .map(|c| c.trim().parse().unwrap_or(f64::NAN))
                    .collect(),
            );
        }
        Ok(Table { header, rows })
    }

    /// Reads a stored table.
    pub fn read(path: &Path) -> Result<Table, Failure> {
        let what = format!("--baseline {}", path.display());
        let text =
            std::fs::read_to_string(path).map_err(|e| bad(format!("{what}: cannot read: {e}")))?;
        Table::parse(&text, &what)
    }

    fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// The (threads, particles) key of row `r`.
    fn key(&self, r: usize) -> (f64, f64) {
        let at = |name| self.column(name).map_or(f64::NAN, |c| self.rows[r][c]);
        (at("threads"), at("particles"))
    }
}

/// One line per row of `new`: every figure it shares with its row in `old` as new / old.
pub fn ratios(new: &Table, old: &Table) -> Vec<String> {
    let mut lines = Vec::new();
    for r in 0..new.rows.len() {
        let (t, n) = new.key(r);
        let head = format!("threads {t}, particles {n}:");
        let Some(o) = (0..old.rows.len()).find(|&o| old.key(o) == (t, n)) else {
            lines.push(format!("{head} no row in the baseline"));
            continue;
        };
        let mut line = head;
        for (c, name) in new.header.iter().enumerate() {
            if name == "threads" || name == "particles" {
                continue;
            }
            let Some(oc) = old.column(name) else { continue };
            let (a, b) = (new.rows[r][c], old.rows[o][oc]);
            if a.is_finite() && b.is_finite() && b != 0.0 {
                line.push_str(&format!(" {name} {:.2}x", a / b));
            }
        }
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_matched_by_threads_and_particles() {
        let old = "threads,particles,ms_per_step,ppe_iterations\n1,100,10,20\n2,100,8,20\n";
        let new = "threads,particles,ms_per_step,ppe_iterations,extra\n2,100,4,20,1\n1,200,5,5,1\n";
        let (old, new) = (
            Table::parse(old, "old").unwrap(),
            Table::parse(new, "new").unwrap(),
        );
        let lines = ratios(&new, &old);
        assert_eq!(
            lines[0],
            "threads 2, particles 100: ms_per_step 0.50x ppe_iterations 1.00x"
        );
        assert_eq!(lines[1], "threads 1, particles 200: no row in the baseline");
        assert!(Table::parse("a,b\n1,2\n", "x.csv").is_err());
    }
}
