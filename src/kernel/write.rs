//! The kernel file: `.npz` (NumPy: one `.npy` per named array, stored uncompressed in a
//! zip as `numpy.savez` does; `numpy.load(path)` opens it without pickles) and the same
//! arrays as a long Parquet table (`--parquet`), one row per array element that has a
//! value. (Not CSV: the text arrays — the scenario's JSON — hold commas and newlines.)
//!
//! The `.npy` header is NumPy's format 1.0: magic, version, a little-endian u16 header
//! length and a Python dict literal padded with spaces so the data starts on a 64-byte
//! boundary. Floats are `<f8`, integers `<i8` (seeds `<u8`), text `<U` (UTF-32LE).

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use zip::write::SimpleFileOptions;

use super::estimate::{Array, Data};
use crate::output::table::{Cell, Column, TableWriter, float, int, text};

/// Refuse `path` (given by `flag`) when its directory is missing or cannot be written,
/// before any run: a measurement of many seeds used to be lost at the end, when the file
/// could not be created. A probe file is created in the directory and removed.
pub fn check_writable(path: &Path, flag: &str) -> anyhow::Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        anyhow::bail!(
            "{flag} {}: the directory {} does not exist",
            path.display(),
            dir.display()
        );
    }
    if path.is_dir() {
        anyhow::bail!("{flag} {}: is a directory, not a file", path.display());
    }
    let probe = dir.join(format!(".agglo-write-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .with_context(|| {
            format!(
                "{flag} {}: the directory {} cannot be written",
                path.display(),
                dir.display()
            )
        })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// One `.npy` file's bytes.
pub fn npy_bytes(array: &Array) -> Vec<u8> {
    let mut out = Vec::new();
    // Writing to a Vec cannot fail.
    let _ = write_npy(&mut out, array);
    out
}

/// Write one `.npy` file to `out`: the header, then the data in chunks (no copy of the
/// whole array).
pub fn write_npy(out: &mut impl Write, array: &Array) -> std::io::Result<()> {
    let shape = match array.shape.len() {
        0 => "()".to_string(),
        1 => format!("({},)", array.shape[0]),
        _ => format!(
            "({})",
            array
                .shape
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let text_width = match &array.data {
        Data::Text(v) => v
            .iter()
            .map(|s| s.chars().count())
            .max()
            .unwrap_or(0)
            .max(1),
        _ => 0,
    };
    let descr = match &array.data {
        Data::F64(_) => "<f8".to_string(),
        Data::I64(_) => "<i8".to_string(),
        Data::U64(_) => "<u8".to_string(),
        Data::Text(_) => format!("<U{text_width}"),
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // 6 magic + 2 version + 2 length + header + '\n', padded to a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    out.write_all(b"\x93NUMPY\x01\x00")?;
    out.write_all(&(header.len() as u16).to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    let mut chunk: Vec<u8> = Vec::with_capacity(1 << 16);
    let mut put = |out: &mut dyn Write, bytes: &[u8]| -> std::io::Result<()> {
        chunk.extend_from_slice(bytes);
        if chunk.len() >= 1 << 16 {
            out.write_all(&chunk)?;
            chunk.clear();
        }
        Ok(())
    };
    match &array.data {
        Data::F64(v) => v.iter().try_for_each(|x| put(out, &x.to_le_bytes()))?,
        Data::I64(v) => v.iter().try_for_each(|x| put(out, &x.to_le_bytes()))?,
        Data::U64(v) => v.iter().try_for_each(|x| put(out, &x.to_le_bytes()))?,
        Data::Text(v) => {
            for s in v {
                let mut n = 0;
                for c in s.chars() {
                    put(out, &(c as u32).to_le_bytes())?;
                    n += 1;
                }
                for _ in n..text_width {
                    put(out, &0u32.to_le_bytes())?;
                }
            }
        }
    }
    out.write_all(&chunk)
}

/// Write `arrays` as an `.npz` at `path`.
pub fn write_npz(path: &Path, arrays: &[Array]) -> anyhow::Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut zip = zip::ZipWriter::new(std::io::BufWriter::new(file));
    // Stored, as numpy.savez; large_file lets an entry pass 4 GiB (Nm³ fragment fractions).
    let options = SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .large_file(true);
    for array in arrays {
        zip.start_file(format!("{}.npy", array.name), options)
            .with_context(|| format!("writing {}", path.display()))?;
        write_npy(&mut zip, array).with_context(|| format!("writing {}", path.display()))?;
    }
    zip.finish()
        .with_context(|| format!("writing {}", path.display()))?
        .flush()?;
    Ok(())
}

/// The columns of the long table.
pub const LONG_COLUMNS: &[Column] = &[
    text("array", "array name (docs/outputs.md, agglo kernel)"),
    text(
        "outcome",
        "bond, bounce or fragment for the per-outcome arrays, empty otherwise",
    ),
    int(
        "i",
        "-",
        "first class index (or the element index of a 1-D array); -1 if none",
    ),
    int("j", "-", "second class index; -1 if none"),
    int(
        "k",
        "-",
        "third class index (fragment_mass_fraction: the product class); -1 if none",
    ),
    float("value", "see unit", "the value (NaN for text)"),
    text("text", "the value of a text array, empty otherwise"),
    text("unit", "unit of value"),
];

/// Write `arrays` as a long Parquet table at `path` (ending in `.parquet`): one
/// row per element with a value (NaN elements, where there is no data, are left out).
pub fn write_long(path: &Path, arrays: &[Array]) -> anyhow::Result<()> {
    anyhow::ensure!(
        crate::output::table::is_parquet(path),
        "{}: the long kernel table is Parquet only (the name must end in .parquet)",
        path.display()
    );
    let mut table = TableWriter::create(path, "kernel", LONG_COLUMNS)?;
    for a in arrays {
        let outcome_axis =
            a.shape.len() == 3 && a.shape[0] == 3 && a.name != "fragment_mass_fraction";
        // Index → (outcome, i, j, k).
        let place = |flat: usize| -> (&str, i64, i64, i64) {
            let s = &a.shape;
            match s.len() {
                0 => ("", -1, -1, -1),
                1 => ("", flat as i64, -1, -1),
                2 => ("", (flat / s[1]) as i64, (flat % s[1]) as i64, -1),
                _ => {
                    let (x, rest) = (flat / (s[1] * s[2]), flat % (s[1] * s[2]));
                    let (y, z) = ((rest / s[2]) as i64, (rest % s[2]) as i64);
                    if outcome_axis {
                        (super::accumulator::OUTCOMES[x], y, z, -1)
                    } else {
                        ("", x as i64, y, z)
                    }
                }
            }
        };
        let mut row = |flat: usize, value: f64, text: &str| -> anyhow::Result<()> {
            let (outcome, i, j, k) = place(flat);
            table.row(&[
                Cell::S(a.name),
                Cell::S(outcome),
                Cell::I(i),
                Cell::I(j),
                Cell::I(k),
                Cell::F(value),
                Cell::S(text),
                Cell::S(a.unit),
            ])
        };
        match &a.data {
            Data::F64(v) => {
                for (n, &x) in v.iter().enumerate().filter(|(_, x)| !x.is_nan()) {
                    row(n, x, "")?;
                }
            }
            Data::I64(v) => {
                for (n, &x) in v.iter().enumerate() {
                    row(n, x as f64, "")?;
                }
            }
            Data::U64(v) => {
                // Seeds: the float is exact below 2^53; the text is always exact.
                for (n, &x) in v.iter().enumerate() {
                    row(n, x as f64, &x.to_string())?;
                }
            }
            Data::Text(v) => {
                for (n, s) in v.iter().enumerate() {
                    row(n, f64::NAN, s)?;
                }
            }
        }
    }
    table.finish()
}
