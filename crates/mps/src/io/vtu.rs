//! VTU particle files (unstructured grid, one vertex cell per particle, raw appended binary
//! data) with a `.pvd` index for ParaView, written from and read back into the particle field
//! registry. Hand-written for this one layout (docs/decisions.md, "VTU writer").

use crate::error::{Error, Result};
use crate::particles::{Column, Particles};
use std::path::Path;

/// Serialises particles as a VTU file: every field the registry marks for output, the
/// positions as points. `time` (s), the particle spacing `spacing` (m) and the dimension go
/// into the file's field data.
pub fn vtu_bytes<const D: usize>(p: &Particles<D>, time: f64, spacing: f64) -> Vec<u8> {
    let n = p.len();
    let columns = p.columns();
    let mut head = String::new();
    let mut blob: Vec<u8> = Vec::new();
    let push_block = |bytes: &[u8], blob: &mut Vec<u8>| -> usize {
        let off = blob.len();
        blob.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        blob.extend_from_slice(bytes);
        off
    };
    head.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n");
    head.push_str(&format!(
        "<FieldData><DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">{time:.9}</DataArray><DataArray type=\"Float64\" Name=\"Spacing\" NumberOfTuples=\"1\" format=\"ascii\">{spacing:.9e}</DataArray><DataArray type=\"Int32\" Name=\"Dimension\" NumberOfTuples=\"1\" format=\"ascii\">{D}</DataArray></FieldData>\n"
    ));
    head.push_str(&format!(
        "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">\n<PointData Scalars=\"pressure\" Vectors=\"velocity\">\n"
    ));
    let data_array = |c: &Column, off: usize| {
        format!(
            "<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" format=\"appended\" offset=\"{off}\"/>\n",
            c.vtk_type, c.name, c.components
        )
    };
    for c in columns.iter().filter(|c| c.name != "Points") {
        let off = push_block(&c.bytes, &mut blob);
        head.push_str(&data_array(c, off));
    }
    head.push_str("</PointData>\n<Points>\n");
    if let Some(c) = columns.iter().find(|c| c.name == "Points") {
        let off = push_block(&c.bytes, &mut blob);
        head.push_str(&data_array(c, off).replace(" Name=\"Points\"", ""));
    }
    head.push_str("</Points>\n<Cells>\n");
    let conn: Vec<u8> = (0..n as i64).flat_map(|x| x.to_le_bytes()).collect();
    let offs: Vec<u8> = (1..=n as i64).flat_map(|x| x.to_le_bytes()).collect();
    let types: Vec<u8> = vec![1u8; n];
    let o1 = push_block(&conn, &mut blob);
    let o2 = push_block(&offs, &mut blob);
    let o3 = push_block(&types, &mut blob);
    head.push_str(&format!(
        "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"{o1}\"/>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\" offset=\"{o2}\"/>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"{o3}\"/>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_"
    ));
    let mut out = head.into_bytes();
    out.extend_from_slice(&blob);
    out.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
    out
}

/// The index (`.pvtu`) of a snapshot written in pieces, one VTU file per process (`pieces`,
/// file names beside it), whose arrays are those [`vtu_bytes`] writes for `Particles<D>`.
pub fn pvtu_bytes<const D: usize>(pieces: &[String]) -> Vec<u8> {
    let columns = Particles::<D>::default().columns();
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PUnstructuredGrid GhostLevel=\"0\">\n<PPointData Scalars=\"pressure\" Vectors=\"velocity\">\n",
    );
    let array = |c: &Column| {
        format!(
            "<PDataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"/>\n",
            c.vtk_type, c.name, c.components
        )
    };
    for c in columns.iter().filter(|c| c.name != "Points") {
        s.push_str(&array(c));
    }
    s.push_str("</PPointData>\n<PPoints>\n");
    if let Some(c) = columns.iter().find(|c| c.name == "Points") {
        s.push_str(&array(c).replace(" Name=\"Points\"", ""));
    }
    s.push_str("</PPoints>\n<PCells>\n<PDataArray type=\"Int64\" Name=\"connectivity\"/>\n<PDataArray type=\"Int64\" Name=\"offsets\"/>\n<PDataArray type=\"UInt8\" Name=\"types\"/>\n</PCells>\n");
    for p in pieces {
        s.push_str(&format!("<Piece Source=\"{p}\"/>\n"));
    }
    s.push_str("</PUnstructuredGrid>\n</VTKFile>\n");
    s.into_bytes()
}

/// The piece files a `.pvtu` index names (`None` when `bytes` is not such an index).
pub fn pvtu_pieces(bytes: &[u8]) -> Option<Vec<String>> {
    let text = std::str::from_utf8(bytes).ok()?;
    if !text.contains("<PUnstructuredGrid") {
        return None;
    }
    let key = "Source=\"";
    Some(
        text.lines()
            .filter(|l| l.contains("<Piece "))
            .filter_map(|l| {
                let at = l.find(key)? + key.len();
                Some(l[at..at + l[at..].find('"')?].to_string())
            })
            .collect(),
    )
}

/// A ParaView collection (`.pvd`) listing `(time, file)` entries.
pub fn pvd_bytes(entries: &[(f64, String)]) -> Vec<u8> {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n<Collection>\n",
    );
    for (t, f) in entries {
        s.push_str(&format!(
            "<DataSet timestep=\"{t:.9}\" group=\"\" part=\"0\" file=\"{f}\"/>\n"
        ));
    }
    s.push_str("</Collection>\n</VTKFile>\n");
    s.into_bytes()
}

/// The (time, file) entries of a `.pvd` index written by [`pvd_bytes`].
pub fn read_pvd(text: &str) -> Vec<(f64, String)> {
    let attr = |line: &str, k: &str| -> Option<String> {
        let at = line.find(&format!("{k}=\""))? + k.len() + 2;
        Some(line[at..at + line[at..].find('"')?].to_string())
    };
    text.lines()
        .filter(|l| l.contains("<DataSet"))
        .filter_map(|l| Some((attr(l, "timestep")?.parse().ok()?, attr(l, "file")?)))
        .collect()
}

/// A value of the ASCII field data (e.g. `TimeValue`, `Spacing`) of a VTU written by
/// [`vtu_bytes`].
pub fn read_vtu_field_data(bytes: &[u8], name: &str) -> Option<f64> {
    let end = bytes
        .windows(14)
        .position(|w| w == b"<AppendedData ")
        .unwrap_or(bytes.len());
    let head = std::str::from_utf8(&bytes[..end]).ok()?;
    let key = format!("Name=\"{name}\"");
    let at = head.find(&key)?;
    let start = at + head[at..].find('>')? + 1;
    let end = start + head[start..].find('<')?;
    head[start..end].trim().parse().ok()
}

/// Reads back the arrays of a VTU written by [`vtu_bytes`]: each named array (the points as
/// `Points`, xyz) as f64 values. A truncated or inconsistent file is an error saying what is
/// wrong, never a panic.
pub fn read_vtu_arrays(bytes: &[u8]) -> std::result::Result<Vec<(String, Vec<f64>)>, String> {
    let marker = b"<AppendedData encoding=\"raw\">\n_";
    let start = bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .ok_or("not a VTU file with raw appended data")?
        + marker.len();
    let head = std::str::from_utf8(&bytes[..start]).map_err(|_| "header is not text")?;
    let mut out = Vec::new();
    for line in head.lines().filter(|l| l.contains("format=\"appended\"")) {
        let attr = |k: &str| -> Option<String> {
            let p = line.find(&format!("{k}=\""))? + k.len() + 2;
            Some(line[p..p + line[p..].find('"')?].to_string())
        };
        let name = attr("Name").unwrap_or_else(|| "Points".into());
        let ty = attr("type").ok_or_else(|| format!("array `{name}` has no type"))?;
        let off: usize = attr("offset")
            .and_then(|o| o.parse().ok())
            .ok_or_else(|| format!("array `{name}` has no offset"))?;
        let truncated = || format!("file is truncated (array `{name}`)");
        let at = start.checked_add(off).ok_or_else(truncated)?;
        let len_bytes = bytes.get(at..at.saturating_add(8)).ok_or_else(truncated)?;
        let len = u64::from_le_bytes(len_bytes.try_into().expect("8 bytes")) as usize;
        let data = bytes
            .get(at + 8..(at + 8).saturating_add(len))
            .ok_or_else(truncated)?;
        let vals: Vec<f64> = match ty.as_str() {
            "Float64" => data
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
            "Int32" => data
                .chunks_exact(4)
                .map(|c| i32::from_le_bytes(c.try_into().unwrap()) as f64)
                .collect(),
            "Int64" => data
                .chunks_exact(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()) as f64)
                .collect(),
            "UInt8" => data.iter().map(|&b| b as f64).collect(),
            other => return Err(format!("array `{name}` has unsupported type {other}")),
        };
        out.push((name, vals));
    }
    Ok(out)
}

/// A particle file read back: the particles, and the time (s) and spacing (m) when the file
/// records them.
pub type Snapshot<const D: usize> = (Particles<D>, Option<f64>, Option<f64>);

/// Reads the bytes of a particle file `path`, a VTU ([`vtu_bytes`]) or the `.pvtu` index of
/// a snapshot in pieces ([`pvtu_bytes`], the pieces read from beside it and joined in id
/// order); returns the particles, time and spacing, and the dimension the file records.
pub fn read_particle_file<const D: usize>(
    bytes: &[u8],
    path: &Path,
) -> Result<(Snapshot<D>, Option<f64>)> {
    let Some(pieces) = pvtu_pieces(bytes) else {
        let dimension = read_vtu_field_data(bytes, "Dimension");
        return Ok((read_vtu(bytes, path)?, dimension));
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut parts = Vec::with_capacity(pieces.len());
    let mut first = None;
    for name in &pieces {
        if name.contains(['/', '\\']) || name.starts_with('.') {
            return Err(Error::Format {
                path: path.to_path_buf(),
                message: format!("piece `{name}` is not a file beside the index"),
            });
        }
        let at = dir.join(name);
        let b = std::fs::read(&at).map_err(|e| Error::io(&at, e))?;
        let (s, dim) = (
            read_vtu::<D>(&b, &at)?,
            read_vtu_field_data(&b, "Dimension"),
        );
        first.get_or_insert((s.1, s.2, dim));
        parts.push(s.0);
    }
    let Some((time, spacing, dimension)) = first else {
        return Err(Error::Format {
            path: path.to_path_buf(),
            message: "the index names no piece".into(),
        });
    };
    let p = Particles::joined(parts.iter().map(|p| (p, p.len())));
    Ok(((p, time, spacing), dimension))
}

/// Reads the bytes of VTU file `path` (written by [`vtu_bytes`]) back into particles.
pub fn read_vtu<const D: usize>(bytes: &[u8], path: &Path) -> Result<Snapshot<D>> {
    let bad = |message: String| Error::Format {
        path: path.to_path_buf(),
        message,
    };
    let arrays = read_vtu_arrays(bytes).map_err(bad)?;
    let p = Particles::<D>::from_columns(&arrays).map_err(bad)?;
    Ok((
        p,
        read_vtu_field_data(bytes, "TimeValue"),
        read_vtu_field_data(bytes, "Spacing"),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::{Kind, NewParticle, Vector};

    #[test]
    fn vtu_round_trips_its_arrays() {
        let mut p = Particles::<2>::default();
        for (x, u, kind) in [
            ([0.1, 0.2], [1.0, -1.0], Kind::Fluid),
            ([0.3, 0.4], [0.0, 0.0], Kind::Wall),
        ] {
            p.push(NewParticle {
                position: Vector(x),
                velocity: Vector(u),
                kind,
                phase: 0,
                density: 1000.0,
            });
        }
        p.pressure = vec![12.5, -3.0];
        let b = vtu_bytes(&p, 0.5, 0.01);
        let arrays = read_vtu_arrays(&b).unwrap();
        let get = |n: &str| arrays.iter().find(|a| a.0 == n).unwrap().1.clone();
        assert_eq!(get("pressure"), vec![12.5, -3.0]);
        assert_eq!(get("kind"), vec![0.0, 1.0]);
        assert_eq!(get("Points"), vec![0.1, 0.2, 0.0, 0.3, 0.4, 0.0]);
        assert_eq!(get("velocity")[..3], [1.0, -1.0, 0.0]);
    }

    #[test]
    fn truncated_files_are_errors() {
        let mut p = Particles::<2>::default();
        p.push(NewParticle {
            position: Vector([0.1, 0.2]),
            velocity: Vector([0.0, 0.0]),
            kind: Kind::Fluid,
            phase: 0,
            density: 1000.0,
        });
        let b = vtu_bytes(&p, 0.5, 0.01);
        for cut in [b.len() / 2, b.len() - 60, 100] {
            let e = read_vtu::<2>(&b[..cut], Path::new("p.vtu")).unwrap_err();
            assert!(e.to_string().starts_with("p.vtu: "), "cut at {cut}: {e}");
        }
        let (q, t, s) = read_vtu::<2>(&b, Path::new("p.vtu")).unwrap();
        assert_eq!((q.position, t, s), (p.position, Some(0.5), Some(0.01)));
    }
}
