//! Command-line overrides of case fields: `--set key=value` on the parsed TOML table, before
//! the case is deserialised and checked.

/// Sets `key` (dotted path; numbers index arrays, e.g. `fluid.0.phase`) to `value` in `table`.
/// The value is parsed as TOML (`0.01`, `true`, `[1, 2]`, `"text"`), or taken as a string.
pub fn apply_override(table: &mut toml::Table, key: &str, value: &str) -> Result<(), String> {
    let parsed: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
        Ok(mut t) => t.remove("v").expect("parsed key"),
        Err(_) => toml::Value::String(value.to_string()),
    };
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!("--set {key}: empty path segment"));
    }
    let mut cur = table;
    for (k, part) in parts.iter().enumerate() {
        let last = k + 1 == parts.len();
        let next_is_index = !last && parts[k + 1].parse::<usize>().is_ok();
        if last {
            cur.insert(part.to_string(), parsed);
            return Ok(());
        }
        let entry = cur
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if next_is_index {
            let idx: usize = parts[k + 1].parse().unwrap();
            let arr = entry
                .as_array_mut()
                .ok_or_else(|| format!("--set {key}: `{part}` is not an array"))?;
            let len = arr.len();
            let item = arr.get_mut(idx).ok_or_else(|| {
                format!("--set {key}: index {idx} out of range (`{part}` has {len} entries)")
            })?;
            if k + 2 == parts.len() {
                *item = parsed;
                return Ok(());
            }
            // Skip the index segment.
            let rest = parts[k + 2..].join(".");
            let t = item
                .as_table_mut()
                .ok_or_else(|| format!("--set {key}: `{part}.{idx}` is not a table"))?;
            return apply_override(t, &rest, value);
        }
        cur = entry
            .as_table_mut()
            .ok_or_else(|| format!("--set {key}: `{part}` is not a table"))?;
    }
    Ok(())
}
