//! Output writers: VTU particle files with a `.pvd` index for ParaView, CSV time series.
//! Every file is written atomically: to a temporary name in the same folder, then renamed.

use crate::particles::Particles;
use std::io::{self, Write};
use std::path::Path;

/// Writes `bytes` to `path` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "no file name"))?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_data().ok();
    }
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

/// One data array of a VTU file.
enum Array<'a> {
    F64(&'a str, usize, Vec<f64>),
    I32(&'a str, Vec<i32>),
    U8(&'a str, Vec<u8>),
}

/// Serialises particles as an unstructured-grid VTU file (one vertex cell per particle) with
/// raw appended binary data: position, velocity, pressure, density, phase, kind,
/// free-surface flag, number density and id.
/// `time` (s) and the particle spacing `spacing` (m) go into the file's field data.
pub fn vtu_bytes<const D: usize>(p: &Particles<D>, time: f64, spacing: f64) -> Vec<u8> {
    let n = p.len();
    let mut pts = Vec::with_capacity(3 * n);
    let mut vel = Vec::with_capacity(3 * n);
    for i in 0..n {
        for k in 0..3 {
            pts.push(if k < D { p.position[i][k] } else { 0.0 });
            vel.push(if k < D { p.velocity[i][k] } else { 0.0 });
        }
    }
    let arrays = vec![
        Array::F64("velocity", 3, vel),
        Array::F64("pressure", 1, p.pressure.clone()),
        Array::F64("density", 1, p.density.clone()),
        Array::I32("phase", p.phase.iter().map(|&v| v as i32).collect()),
        Array::I32("kind", p.kind.iter().map(|&v| v as i32).collect()),
        Array::U8(
            "free_surface",
            p.free_surface.iter().map(|&v| v as u8).collect(),
        ),
        Array::F64("number_density", 1, p.number_density.clone()),
        Array::I32("id", p.id.iter().map(|&v| v as i32).collect()),
    ];
    let mut head = String::new();
    let mut blob: Vec<u8> = Vec::new();
    let push_block = |bytes: &[u8], blob: &mut Vec<u8>| -> usize {
        let off = blob.len();
        blob.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        blob.extend_from_slice(bytes);
        off
    };
    let f64_bytes = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let i32_bytes = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    head.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n");
    head.push_str(&format!(
        "<FieldData><DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">{time:.9}</DataArray><DataArray type=\"Float64\" Name=\"Spacing\" NumberOfTuples=\"1\" format=\"ascii\">{spacing:.9e}</DataArray></FieldData>\n"
    ));
    head.push_str(&format!(
        "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">\n<PointData Scalars=\"pressure\" Vectors=\"velocity\">\n"
    ));
    for a in &arrays {
        let (name, ty, comps, off) = match a {
            Array::F64(name, c, v) => (name, "Float64", *c, push_block(&f64_bytes(v), &mut blob)),
            Array::I32(name, v) => (name, "Int32", 1, push_block(&i32_bytes(v), &mut blob)),
            Array::U8(name, v) => (name, "UInt8", 1, push_block(v, &mut blob)),
        };
        head.push_str(&format!(
            "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"appended\" offset=\"{off}\"/>\n"
        ));
    }
    head.push_str("</PointData>\n<Points>\n");
    let off = push_block(&f64_bytes(&pts), &mut blob);
    head.push_str(&format!(
        "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{off}\"/>\n</Points>\n<Cells>\n"
    ));
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

/// Reads back the arrays of a VTU written by [`vtu_bytes`] (tests and post-processing):
/// each named array (the points as `Points`, xyz) as f64 values.
pub fn read_vtu_arrays(bytes: &[u8]) -> Option<Vec<(String, Vec<f64>)>> {
    let marker = b"<AppendedData encoding=\"raw\">\n_";
    let start = bytes.windows(marker.len()).position(|w| w == marker)? + marker.len();
    let head = std::str::from_utf8(&bytes[..start]).ok()?;
    let mut out = Vec::new();
    for line in head.lines().filter(|l| l.contains("format=\"appended\"")) {
        let attr = |k: &str| -> Option<String> {
            let p = line.find(&format!("{k}=\""))? + k.len() + 2;
            Some(line[p..p + line[p..].find('"')?].to_string())
        };
        let name = attr("Name").unwrap_or_else(|| "Points".into());
        let ty = attr("type")?;
        let off: usize = attr("offset")?.parse().ok()?;
        let at = start + off;
        let len = u64::from_le_bytes(bytes[at..at + 8].try_into().ok()?) as usize;
        let data = &bytes[at + 8..at + 8 + len];
        let vals: Vec<f64> = match ty.as_str() {
            "Float64" => data
                .chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
            "Int32" => data
                .chunks(4)
                .map(|c| i32::from_le_bytes(c.try_into().unwrap()) as f64)
                .collect(),
            "Int64" => data
                .chunks(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()) as f64)
                .collect(),
            "UInt8" => data.iter().map(|&b| b as f64).collect(),
            _ => return None,
        };
        out.push((name, vals));
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::Kind;
    use crate::vector::Vector;

    #[test]
    fn vtu_round_trips_its_arrays() {
        let mut p = Particles::<2>::default();
        p.push(
            Vector([0.1, 0.2]),
            Vector([1.0, -1.0]),
            Kind::Fluid,
            0,
            1000.0,
        );
        p.push(
            Vector([0.3, 0.4]),
            Vector([0.0, 0.0]),
            Kind::Wall,
            0,
            1000.0,
        );
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
    fn atomic_write_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("mps_atomic_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("a.txt");
        write_atomic(&f, b"one").unwrap();
        write_atomic(&f, b"two").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
