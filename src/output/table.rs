//! Tables written row by row as CSV, or as Parquet when the path ends in `.parquet`,
//! and read back by [`read_table`] (the tests, and `cloud.from_file`).
//!
//! CSV: a header line, then one line per row; floats in shortest round-trip form
//! (`ryu`), so they parse back to the same bits; counts as integers; no quoting
//! (no value holds a comma); a batch of rows reaches the file in one write, so a kill
//! leaves whole rows. Parquet ([`super::parquet_sink`]): rows are buffered per column
//! and written as a row group every [`ROW_GROUP_ROWS`] rows, so memory stays bounded
//! however long the run, and the file stays readable if the run is killed.
//!
//! **Threads.** [`TableWriter::row`] only copies the cells into a batch; every
//! [`BATCH_ROWS`] rows the batch goes to the table's writer thread
//! ([`super::offload`]), which formats the CSV or compresses the Parquet columns and
//! writes the file, rows in the order they came, so the bytes are those one thread
//! writes. At most [`QUEUED_BATCHES`] batches wait for it.

use std::fs::File;
use std::io::Write;
use std::path::Path;

use anyhow::{Context, bail, ensure};
use parquet::file::reader::FileReader;
use parquet::file::serialized_reader::SerializedFileReader;
use parquet::record::Field;

use super::offload::{Offload, Sink, Threading};
use super::parquet_sink::ParquetSink;

pub use super::column::{Cell, Column, Kind, float, id, int, text};

pub use super::parquet_sink::ROW_GROUP_ROWS;

/// Rows copied on the simulation thread before they are handed to the writer thread
/// (13 columns: 0.85 MB a batch): few enough hand-overs that they cost nothing, small
/// enough that the writer starts early.
pub const BATCH_ROWS: usize = 4096;

/// Batches that may wait for a table's writer thread: the memory a slow disk can take.
pub const QUEUED_BATCHES: usize = 4;

/// True when `path` names a Parquet file (its name ends in `.parquet`).
pub fn is_parquet(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("parquet"))
}

/// A table being written.
pub struct TableWriter {
    columns: usize,
    /// `None` once finished.
    out: Option<Offload<TableSink>>,
    batch: Batch,
    rows: u64,
}

/// Rows copied for the writer thread: `columns` cells a row, text in one string.
#[derive(Default)]
struct Batch {
    cells: Vec<OwnedCell>,
    text: String,
    rows: usize,
}

/// A [`Cell`] that owns its value; text is a range of [`Batch::text`].
#[derive(Clone, Copy)]
enum OwnedCell {
    F(f64),
    I(i64),
    U(u64),
    S(usize, usize),
}

/// The file and its format, on the writer thread.
struct TableSink {
    columns: Vec<Column>,
    format: Format,
}

impl Sink for TableSink {
    type Job = Batch;
    type Output = ();

    fn take(&mut self, batch: Batch) -> anyhow::Result<()> {
        let mut cells = Vec::with_capacity(self.columns.len());
        for row in batch.cells.chunks(self.columns.len()) {
            cells.clear();
            cells.extend(row.iter().map(|c| match *c {
                OwnedCell::F(x) => Cell::F(x),
                OwnedCell::I(n) => Cell::I(n),
                OwnedCell::U(n) => Cell::U(n),
                OwnedCell::S(a, b) => Cell::S(&batch.text[a..b]),
            }));
            self.format.row(&cells)?;
        }
        self.format.write_rows()
    }

    fn finish(self) -> anyhow::Result<()> {
        match self.format {
            Format::Csv(mut out) => out.write_rows()?,
            Format::Parquet(p) => p.finish()?,
        }
        Ok(())
    }
}

/// A CSV file and the rows of the batch being formatted: they reach the file in one
/// write, whole, so a kill leaves whole rows (a `BufWriter` wrote whenever its 8 kB
/// filled, mid-row).
struct CsvSink {
    file: File,
    rows: Vec<u8>,
}

impl CsvSink {
    fn write_rows(&mut self) -> anyhow::Result<()> {
        self.file.write_all(&self.rows)?;
        self.rows.clear();
        Ok(())
    }
}

enum Format {
    Csv(CsvSink),
    Parquet(Box<ParquetSink>),
}

impl TableWriter {
    /// Create `path` for rows of `columns` (Parquet if it ends in `.parquet`, else CSV);
    /// `name` names the Parquet schema.
    pub fn create(path: &Path, name: &str, columns: &[Column]) -> anyhow::Result<Self> {
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let format = if is_parquet(path) {
            let sink = ParquetSink::create(file, name, columns)
                .with_context(|| format!("writing {}", path.display()))?;
            Format::Parquet(Box::new(sink))
        } else {
            let mut out = CsvSink {
                file,
                rows: Vec::new(),
            };
            let header: Vec<&str> = columns.iter().map(|c| c.name).collect();
            // Written now, so that a run killed before its first batch leaves a table
            // a reader opens (an empty file is not one).
            writeln!(out.rows, "{}", header.join(","))?;
            out.write_rows()
                .with_context(|| format!("writing {}", path.display()))?;
            Format::Csv(out)
        };
        let sink = TableSink {
            columns: columns.to_vec(),
            format,
        };
        Ok(Self {
            columns: columns.len(),
            out: Some(Offload::new(
                sink,
                path,
                Threading::from_env(QUEUED_BATCHES),
            )?),
            batch: Batch::default(),
            rows: 0,
        })
    }

    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Append one row: one cell per column, of the column's kind. Errors writing the
    /// file come from a later call (or [`TableWriter::finish`]), naming the file.
    pub fn row(&mut self, cells: &[Cell]) -> anyhow::Result<()> {
        let out = self.out.as_mut().context("a row after finish (a bug)")?;
        ensure!(
            cells.len() == self.columns,
            "a row of {} cells for {} columns of {} (a bug)",
            cells.len(),
            self.columns,
            out.path().display()
        );
        self.rows += 1;
        let batch = &mut self.batch;
        batch.cells.extend(cells.iter().map(|c| match *c {
            Cell::F(x) => OwnedCell::F(x),
            Cell::I(n) => OwnedCell::I(n),
            Cell::U(n) => OwnedCell::U(n),
            Cell::S(text) => {
                let start = batch.text.len();
                batch.text.push_str(text);
                OwnedCell::S(start, batch.text.len())
            }
        }));
        batch.rows += 1;
        if batch.rows >= BATCH_ROWS {
            out.send(std::mem::take(batch))?;
        }
        Ok(())
    }

    /// Write what is buffered and close the file (waits for its writer thread).
    pub fn finish(mut self) -> anyhow::Result<()> {
        let mut out = self.out.take().context("finished twice (a bug)")?;
        let last = std::mem::take(&mut self.batch);
        if last.rows > 0 {
            out.send(last)?;
        }
        out.finish()
    }
}

impl Drop for TableWriter {
    /// Not finished (an early return): the rows taken still reach the file, as they did
    /// through a `BufWriter` when tables were written on the simulation thread.
    fn drop(&mut self) {
        if let Some(out) = self.out.as_mut()
            && self.batch.rows > 0
        {
            let _ = out.send(std::mem::take(&mut self.batch));
        }
    }
}

impl Format {
    /// Hand the rows formatted so far to the file (CSV; Parquet writes row groups).
    fn write_rows(&mut self) -> anyhow::Result<()> {
        match self {
            Format::Csv(out) => out.write_rows(),
            Format::Parquet(_) => Ok(()),
        }
    }

    /// Write one row.
    fn row(&mut self, cells: &[Cell]) -> anyhow::Result<()> {
        match self {
            Format::Csv(CsvSink { rows: out, .. }) => {
                let mut floats = ryu::Buffer::new();
                let mut ints = itoa::Buffer::new();
                for (k, cell) in cells.iter().enumerate() {
                    if k > 0 {
                        out.write_all(b",")?;
                    }
                    match cell {
                        // Shortest representation that parses back to the same f64
                        // (non-finite values as Rust and pandas read them: NaN, inf).
                        Cell::F(x) if x.is_finite() => {
                            out.write_all(floats.format_finite(*x).as_bytes())?
                        }
                        Cell::F(x) => write!(out, "{x}")?,
                        Cell::I(n) => out.write_all(ints.format(*n).as_bytes())?,
                        Cell::U(n) => out.write_all(ints.format(*n).as_bytes())?,
                        Cell::S(s) => out.write_all(s.as_bytes())?,
                    }
                }
                out.write_all(b"\n")?;
            }
            Format::Parquet(p) => p.row(cells)?,
        }
        Ok(())
    }
}

/// A table read back: column names and, per column, its values.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// The columns' names, in order.
    pub names: Vec<String>,
    /// Each column's values, in `names`' order.
    pub columns: Vec<Values>,
}

/// The values of one column.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    /// Floats.
    F(Vec<f64>),
    /// Integers.
    I(Vec<i64>),
    /// Integers some of which are above i64::MAX (ids).
    U(Vec<u64>),
    /// Text.
    S(Vec<String>),
}

impl Table {
    /// Rows in the table.
    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, |c| match c {
            Values::F(v) => v.len(),
            Values::I(v) => v.len(),
            Values::U(v) => v.len(),
            Values::S(v) => v.len(),
        })
    }
    /// True when the table has no row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The column called `name`, if there is one.
    pub fn column(&self, name: &str) -> Option<&Values> {
        let k = self.names.iter().position(|n| n == name)?;
        Some(&self.columns[k])
    }
    /// Column `name` as floats (integers converted); an error names a missing or text column.
    pub fn floats(&self, name: &str) -> anyhow::Result<Vec<f64>> {
        match self.column(name) {
            Some(Values::F(v)) => Ok(v.clone()),
            Some(Values::I(v)) => Ok(v.iter().map(|&n| n as f64).collect()),
            Some(Values::U(v)) => Ok(v.iter().map(|&n| n as f64).collect()),
            Some(Values::S(_)) => bail!("column `{name}` holds text, not numbers"),
            None => bail!("no column `{name}` (columns: {})", self.names.join(", ")),
        }
    }
    /// Column `name` as stable ids (any u64, read exactly; floats only when they are
    /// integers below 2^53, which a float holds exactly); an error names the row.
    pub fn ids(&self, name: &str) -> anyhow::Result<Vec<u64>> {
        match self.column(name) {
            Some(Values::U(v)) => Ok(v.clone()),
            Some(Values::I(v)) => v
                .iter()
                .enumerate()
                .map(|(row, &n)| {
                    u64::try_from(n).map_err(|_| {
                        anyhow::anyhow!(
                            "column `{name}`, row {row}: id {n} is negative (allowed 0 ≤ id ≤ 2^64 − 1)"
                        )
                    })
                })
                .collect(),
            Some(Values::F(v)) => v
                .iter()
                .enumerate()
                .map(|(row, &x)| {
                    if x.fract() == 0.0 && (0.0..9.0e15).contains(&x) {
                        Ok(x as u64)
                    } else {
                        bail!(
                            "column `{name}`, row {row}: {x} is not an id (an integer 0 ≤ id ≤ 2^64 − 1, \
                             written as an integer)"
                        )
                    }
                })
                .collect(),
            Some(Values::S(_)) => bail!("column `{name}` holds text, not numbers"),
            None => bail!("no column `{name}` (columns: {})", self.names.join(", ")),
        }
    }
    /// Column `name` as integers; an error names a missing column or a non-integer value.
    pub fn ints(&self, name: &str) -> anyhow::Result<Vec<i64>> {
        match self.column(name) {
            Some(Values::I(v)) => Ok(v.clone()),
            Some(Values::U(v)) => v
                .iter()
                .enumerate()
                .map(|(row, &n)| {
                    i64::try_from(n).map_err(|_| {
                        anyhow::anyhow!("column `{name}`, row {row}: {n} is above i64::MAX")
                    })
                })
                .collect(),
            Some(Values::F(v)) => v
                .iter()
                .enumerate()
                .map(|(row, &x)| {
                    if x.fract() == 0.0 && x.abs() < 9.0e15 {
                        Ok(x as i64)
                    } else {
                        bail!("column `{name}`, row {row}: {x} is not an integer")
                    }
                })
                .collect(),
            Some(Values::S(_)) => bail!("column `{name}` holds text, not numbers"),
            None => bail!("no column `{name}` (columns: {})", self.names.join(", ")),
        }
    }
    /// Column `name` as text.
    pub fn texts(&self, name: &str) -> anyhow::Result<Vec<String>> {
        match self.column(name) {
            Some(Values::S(v)) => Ok(v.clone()),
            Some(Values::F(v)) => Ok(v.iter().map(|x| format!("{x:?}")).collect()),
            Some(Values::I(v)) => Ok(v.iter().map(|x| x.to_string()).collect()),
            Some(Values::U(v)) => Ok(v.iter().map(|x| x.to_string()).collect()),
            None => bail!("no column `{name}` (columns: {})", self.names.join(", ")),
        }
    }
}

/// Read a table written by [`TableWriter`] (or any CSV with a header line, e.g. pandas'
/// `to_csv`, whose unnamed leading index column is left out; or a Parquet file of flat
/// required or optional DOUBLE / INT64 / INT32 / FLOAT / UTF8 columns, uncompressed,
/// zstd or Snappy). A CSV column whose every value parses as an integer is read as
/// integers, else as floats if they all parse, else as text. A column named twice is
/// refused. A CSV whose last line is cut off mid-row (a writer killed) is read without
/// that line.
pub fn read_table(path: &Path) -> anyhow::Result<Table> {
    let table = if is_parquet(path) {
        read_parquet_guarded(path)
            .with_context(|| format!("reading Parquet file {}", path.display()))?
    } else {
        read_csv(path).with_context(|| format!("reading CSV file {}", path.display()))?
    };
    for (k, name) in table.names.iter().enumerate() {
        if table.names[..k].contains(name) {
            bail!("{}: column `{name}` appears twice", path.display());
        }
    }
    Ok(table)
}

/// The values of a CSV column as they are parsed: integers while every value is one
/// (unsigned past i64::MAX), floats from the first that is not, text from the first
/// that is no number.
enum Parsed {
    I(Vec<i64>),
    U(Vec<u64>),
    F(Vec<f64>),
    S,
}

impl Parsed {
    fn push(&mut self, field: &str) {
        let field = field.trim();
        match self {
            Parsed::I(v) => {
                if let Ok(n) = field.parse::<i64>() {
                    v.push(n);
                } else if let (Ok(n), true) = (field.parse::<u64>(), v.iter().all(|&n| n >= 0)) {
                    let mut u: Vec<u64> = v.iter().map(|&n| n as u64).collect();
                    u.push(n);
                    *self = Parsed::U(u);
                } else if let Ok(x) = field.parse::<f64>() {
                    let mut f: Vec<f64> = v.iter().map(|&n| n as f64).collect();
                    f.push(x);
                    *self = Parsed::F(f);
                } else {
                    *self = Parsed::S;
                }
            }
            Parsed::U(v) => {
                if let Ok(n) = field.parse::<u64>() {
                    v.push(n);
                } else if let Ok(x) = field.parse::<f64>() {
                    let mut f: Vec<f64> = v.iter().map(|&n| n as f64).collect();
                    f.push(x);
                    *self = Parsed::F(f);
                } else {
                    *self = Parsed::S;
                }
            }
            Parsed::F(v) => match field.parse::<f64>() {
                Ok(x) => v.push(x),
                Err(_) => *self = Parsed::S,
            },
            Parsed::S => {}
        }
    }
}

fn read_csv(path: &Path) -> anyhow::Result<Table> {
    let bytes = std::fs::read(path)?;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(&bytes[..]);
    let header = reader.headers()?.clone();
    if header.is_empty() || bytes.iter().all(u8::is_ascii_whitespace) {
        bail!("the file is empty (no header line)");
    }
    // A writer killed mid-row leaves a last line without its newline and with fewer
    // fields than the header: that torn line is left out (TableWriter ends every row
    // with a newline; a file written by hand may end without one, and keeps its row).
    let whole = match bytes.iter().rposition(|&b| b == b'\n') {
        Some(k) if k + 1 < bytes.len() && bytes[..k].contains(&b'\n') => {
            let mut tail = csv::ReaderBuilder::new()
                .has_headers(false)
                .flexible(true)
                .from_reader(&bytes[k + 1..]);
            let mut last = csv::StringRecord::new();
            match tail.read_record(&mut last) {
                Ok(true) if last.len() < header.len() => &bytes[..=k],
                _ => &bytes[..],
            }
        }
        _ => &bytes[..],
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(whole);
    reader.headers()?;
    let mut names: Vec<String> = header.iter().map(|s| s.trim().to_string()).collect();
    // pandas' `to_csv(path)` writes the row index first, under an empty name.
    let skip = usize::from(names.len() > 1 && names[0].is_empty());
    names.drain(..skip);
    // Parsed as they come, without a String per field (10⁶ bodies × 13 columns); text
    // columns are read again as text at the end.
    let mut columns: Vec<Parsed> = names.iter().map(|_| Parsed::I(Vec::new())).collect();
    let mut rows = 0usize;
    let mut record = csv::StringRecord::new();
    while reader.read_record(&mut record)? {
        if record.iter().all(|f| f.trim().is_empty()) {
            continue;
        }
        let line = record.position().map_or(0, |p| p.line());
        if record.len() != names.len() + skip {
            bail!(
                "line {line}: {} fields, but the header names {}",
                record.len(),
                names.len() + skip
            );
        }
        for (column, field) in columns.iter_mut().zip(record.iter().skip(skip)) {
            column.push(field);
        }
        rows += 1;
    }
    let mut out: Vec<Values> = Vec::with_capacity(columns.len());
    for (c, column) in columns.into_iter().enumerate() {
        out.push(match column {
            Parsed::I(v) => Values::I(v),
            Parsed::U(v) => Values::U(v),
            Parsed::F(v) => Values::F(v),
            Parsed::S => {
                let mut reader = csv::ReaderBuilder::new()
                    .has_headers(true)
                    .flexible(true)
                    .from_reader(whole);
                let mut values = Vec::with_capacity(rows);
                while reader.read_record(&mut record)? {
                    if record.iter().all(|f| f.trim().is_empty()) {
                        continue;
                    }
                    values.push(record.get(c + skip).unwrap_or("").trim().to_string());
                }
                Values::S(values)
            }
        });
    }
    Ok(Table {
        names,
        columns: out,
    })
}

/// [`read_parquet`], with a damaged file's panics inside the parquet crate turned into
/// an error: the fuzz harness (tests/interfaces/fuzz.rs) found its assertions "column start
/// and length should not be negative" and "Decoder for dict should have been set" fire
/// on one flipped bit. The first is also checked before reading (below).
fn read_parquet_guarded(path: &Path) -> anyhow::Result<Table> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| read_parquet(path))) {
        Ok(result) => result.map_err(|e| {
            // A codec this build leaves out (the crate says "Disabled feature at compile
            // time: brotli"): say which codecs are read.
            let text = format!("{e:#}");
            match text.split("Disabled feature at compile time: ").nth(1) {
                Some(codec) => anyhow::anyhow!(
                    "the file is compressed with {}, which agglo does not read: write it with \
                     compression \"snappy\" (pandas' default), \"zstd\", \"gzip\", \"lz4\" \
                     or none",
                    codec.trim()
                ),
                None => e,
            }
        }),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic in the Parquet reader".into());
            bail!("the file is damaged (the Parquet reader failed: {what})")
        }
    }
}

/// What a Parquet value is, in words (for a refusal; the crate's names are its own).
fn kind_of(field: &Field) -> &'static str {
    match field {
        Field::Bool(_) => "true/false",
        Field::Decimal(_) => "decimal",
        Field::Float16(_) => "half-precision float",
        Field::Bytes(_) => "byte-string",
        Field::Date(_) => "date",
        Field::TimeMillis(_) | Field::TimeMicros(_) => "time-of-day",
        Field::TimestampMillis(_) | Field::TimestampMicros(_) => "timestamp",
        Field::Group(_) => "nested (struct)",
        Field::ListInternal(_) => "list",
        Field::MapInternal(_) => "map",
        _ => "these",
    }
}

fn read_parquet(path: &Path) -> anyhow::Result<Table> {
    let file_len = std::fs::metadata(path)?.len();
    let reader = SerializedFileReader::new(File::open(path)?)?;
    // Every column chunk lies inside the file (the crate asserts on a negative offset).
    for (g, group) in reader.metadata().row_groups().iter().enumerate() {
        for column in group.columns() {
            let start = column
                .dictionary_page_offset()
                .unwrap_or(column.data_page_offset());
            let len = column.compressed_size();
            ensure!(
                start >= 0 && len >= 0 && (start as u64).saturating_add(len as u64) <= file_len,
                "row group {g}, column `{}`: its data lies at bytes {start} + {len}, outside \
                 the file's {file_len} bytes (a damaged file)",
                column.column_path()
            );
        }
    }
    let schema = reader.metadata().file_metadata().schema_descr_ptr();
    let names: Vec<String> = schema
        .columns()
        .iter()
        .map(|c| c.name().to_string())
        .collect();
    let mut columns: Vec<Option<Values>> = vec![None; names.len()];
    for (row_number, row) in reader.get_row_iter(None)?.enumerate() {
        let row = row?;
        for (k, (name, field)) in row.get_column_iter().enumerate() {
            let Some(column) = columns.get_mut(k) else {
                bail!("row {row_number}: more fields than columns");
            };
            // Floats and integers of any width widen to f64 / i64 (u64 kept apart: ids).
            let value = match field {
                Field::Double(x) => Values::F(vec![*x]),
                Field::Float(x) => Values::F(vec![f64::from(*x)]),
                Field::Long(n) => Values::I(vec![*n]),
                Field::ULong(n) => Values::U(vec![*n]),
                Field::Int(n) => Values::I(vec![i64::from(*n)]),
                Field::Short(n) => Values::I(vec![i64::from(*n)]),
                Field::Byte(n) => Values::I(vec![i64::from(*n)]),
                Field::UInt(n) => Values::I(vec![i64::from(*n)]),
                Field::UShort(n) => Values::I(vec![i64::from(*n)]),
                Field::UByte(n) => Values::I(vec![i64::from(*n)]),
                Field::Str(s) => Values::S(vec![s.clone()]),
                Field::Null => Values::F(vec![f64::NAN]),
                other => bail!(
                    "row {row_number}, column `{name}`: {} values are not read; give numbers \
                     (floats, or integers for ids; times in seconds as floats)",
                    kind_of(other)
                ),
            };
            match (column, value) {
                (slot @ None, value) => *slot = Some(value),
                (Some(Values::F(v)), Values::F(x)) => v.extend(x),
                (Some(Values::I(v)), Values::I(x)) => v.extend(x),
                (Some(Values::S(v)), Values::S(x)) => v.extend(x),
                (Some(Values::U(v)), Values::U(x)) => v.extend(x),
                (Some(Values::F(v)), Values::I(x)) => v.extend(x.into_iter().map(|n| n as f64)),
                _ => bail!("row {row_number}, column `{name}`: values of mixed kinds"),
            }
        }
    }
    Ok(Table {
        names,
        columns: columns
            .into_iter()
            .map(|c| match c {
                // Unsigned ids (any u64) read as plain integers when they all fit one.
                Some(Values::U(v)) if v.iter().all(|&n| i64::try_from(n).is_ok()) => {
                    Values::I(v.into_iter().map(|n| n as i64).collect())
                }
                c => c.unwrap_or(Values::F(Vec::new())),
            })
            .collect(),
    })
}
