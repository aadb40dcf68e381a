//! CSV time series, appended row by row as a run goes (through the `csv` crate) and flushed
//! at every output, so the cost of writing grows with the run, not with its square.

use crate::error::{Error, Result};
use serde::Serialize;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// One cell of a row whose columns are only known at run time (probes, groups).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Cell {
    /// A real number.
    Real(f64),
    /// A count.
    Count(u64),
}

/// A CSV file rows are appended to (or, for the processes of a distributed run that do not
/// write the shared files, none: every row is dropped).
pub struct Series {
    path: PathBuf,
    writer: Option<csv::Writer<BufWriter<File>>>,
    /// Whether the header is still to come from the first typed row.
    header_pending: bool,
    /// The first error of a write, kept until [`Series::flush`] reports it (so that a run's
    /// processes meet a failed write at the same point of the run).
    error: Option<Error>,
}

impl Series {
    /// Creates (or truncates) `path`; `header` is written first when given, otherwise the
    /// first typed row's field names become the header.
    pub fn create(path: &Path, header: Option<&[String]>) -> Result<Series> {
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let mut writer = csv::WriterBuilder::new()
            .has_headers(header.is_none())
            .from_writer(BufWriter::new(file));
        if let Some(h) = header {
            writer.write_record(h).map_err(|e| csv_error(path, e))?;
        }
        Ok(Series {
            path: path.to_path_buf(),
            writer: Some(writer),
            header_pending: header.is_none(),
            error: None,
        })
    }

    /// [`Series::create`] when `write`, otherwise a series that writes nothing.
    pub fn create_if(write: bool, path: &Path, header: Option<&[String]>) -> Result<Series> {
        if write {
            return Series::create(path, header);
        }
        Ok(Series {
            path: path.to_path_buf(),
            writer: None,
            header_pending: false,
            error: None,
        })
    }

    /// Appends one row: a struct (named columns) or a sequence of cells. A failed write is
    /// reported by the next [`Series::flush`].
    pub fn push<T: Serialize>(&mut self, row: &T) -> Result<()> {
        if let (Some(w), None) = (&mut self.writer, &self.error) {
            self.error = w.serialize(row).err().map(|e| csv_error(&self.path, e));
        }
        Ok(())
    }

    /// Appends one row as written by an earlier run (text fields, carried over unchanged).
    pub fn push_record(&mut self, fields: &[String]) -> Result<()> {
        if let (Some(w), None) = (&mut self.writer, &self.error) {
            self.error = w
                .write_record(fields)
                .err()
                .map(|e| csv_error(&self.path, e));
        }
        Ok(())
    }

    /// Starts the file with an earlier run's `header` and `rows`; typed rows pushed after
    /// these add no second header.
    pub fn carry(&mut self, header: &[String], rows: &[Vec<String>]) -> Result<()> {
        if self.header_pending {
            let file = File::create(&self.path).map_err(|e| Error::io(&self.path, e))?;
            self.writer = Some(
                csv::WriterBuilder::new()
                    .has_headers(false)
                    .from_writer(BufWriter::new(file)),
            );
            self.header_pending = false;
            self.push_record(header)?;
        }
        for r in rows {
            self.push_record(r)?;
        }
        Ok(())
    }

    /// Writes everything appended so far to the file.
    pub fn flush(&mut self) -> Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        match &mut self.writer {
            Some(w) => w.flush().map_err(|e| Error::io(&self.path, e)),
            None => Ok(()),
        }
    }
}

fn csv_error(path: &Path, e: csv::Error) -> Error {
    let message = e.to_string();
    match e.into_kind() {
        csv::ErrorKind::Io(io) => Error::io(path, io),
        _ => Error::Format {
            path: path.to_path_buf(),
            message: format!("not a valid CSV file: {message}"),
        },
    }
}

/// Reads a CSV file written by [`Series`] into typed rows.
pub fn read_rows<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    let mut r = csv::Reader::from_path(path).map_err(|e| csv_error(path, e))?;
    r.deserialize()
        .collect::<std::result::Result<Vec<T>, _>>()
        .map_err(|e| Error::Format {
            path: path.to_path_buf(),
            message: format!("not a valid series: {e}"),
        })
}

/// A CSV file as text: its header and its rows, each field as written.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Records {
    /// Column names.
    pub header: Vec<String>,
    /// The rows' fields.
    pub rows: Vec<Vec<String>>,
}

/// The header and the rows (text fields) of a CSV file; `None` when there is no file.
pub fn read_records(path: &Path) -> Result<Option<Records>> {
    if !path.exists() {
        return Ok(None);
    }
    // Flexible: a row cut short (a full disk) is read, and left to the caller to drop.
    let mut r = csv::ReaderBuilder::new()
        .flexible(true)
        .from_path(path)
        .map_err(|e| csv_error(path, e))?;
    let header = r
        .headers()
        .map_err(|e| csv_error(path, e))?
        .iter()
        .map(str::to_string)
        .collect();
    let rows = r
        .records()
        .map(|rec| {
            rec.map(|x| x.iter().map(str::to_string).collect())
                .map_err(|e| csv_error(path, e))
        })
        .collect::<Result<Vec<Vec<String>>>>()?;
    Ok(Some(Records { header, rows }))
}

/// A numeric CSV file as columns.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// One column of numbers per name.
    pub columns: Vec<Vec<f64>>,
}

/// Reads any numeric CSV file: its header and one column of numbers per header field (a cell
/// that is not a number reads as NaN).
pub fn read_table(path: &Path) -> Result<Table> {
    let mut r = csv::Reader::from_path(path).map_err(|e| csv_error(path, e))?;
    let header: Vec<String> = r
        .headers()
        .map_err(|e| csv_error(path, e))?
        .iter()
        .map(str::to_string)
        .collect();
    let mut columns = vec![Vec::new(); header.len()];
    for record in r.records() {
        let record = record.map_err(|e| csv_error(path, e))?;
        for (k, col) in columns.iter_mut().enumerate() {
            col.push(
                record
                    .get(k)
                    .and_then(|v| v.trim().parse().ok())
                    .unwrap_or(f64::NAN),
            );
        }
    }
    Ok(Table { header, columns })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, serde::Deserialize, Debug, PartialEq)]
    struct Row {
        time: f64,
        step: u64,
    }

    #[test]
    fn typed_and_free_rows_round_trip() {
        let dir = std::env::temp_dir().join(format!("mps_series_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let typed = dir.join("typed.csv");
        let mut s = Series::create(&typed, None).unwrap();
        s.push(&Row { time: 0.1, step: 1 }).unwrap();
        s.push(&Row {
            time: 1e-20,
            step: 2,
        })
        .unwrap();
        s.flush().unwrap();
        let back: Vec<Row> = read_rows(&typed).unwrap();
        assert_eq!(
            back,
            vec![
                Row { time: 0.1, step: 1 },
                Row {
                    time: 1e-20,
                    step: 2
                }
            ]
        );
        let free = dir.join("free.csv");
        let header = vec!["time".to_string(), "a".into(), "n".into()];
        let mut s = Series::create(&free, Some(&header)).unwrap();
        s.push(&[Cell::Real(0.5), Cell::Real(-2.25), Cell::Count(3)])
            .unwrap();
        s.flush().unwrap();
        let t = read_table(&free).unwrap();
        assert_eq!(t.header, header);
        assert_eq!(t.columns, vec![vec![0.5], vec![-2.25], vec![3.0]]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
