//! The Parquet side of an output table: rows buffered per column, written as a row
//! group every [`ROW_GROUP_ROWS`] rows, and a file that is readable at every moment.
//!
//! One required column per field (DOUBLE, INT64 or UTF8 BYTE_ARRAY), zstd-compressed,
//! through the crate's low-level column writer (no Arrow).
//!
//! **Kills.** Parquet keeps its index in a footer at the end of the file, so a writer
//! killed before closing leaves a file no reader opens (it used to be 0 bytes: the
//! writer's buffer had not reached the disk). Here the file always ends in a footer:
//! it is created with a provisional footer listing no rows, and each row group lands in
//! one write together with a new provisional footer listing the row groups so far,
//! written over the old one. A killed run's table therefore holds every row group
//! completed (only a kill inside that one write can tear it), and a finished table has
//! exactly the bytes of a file written straight through, since each write starts where
//! the row groups end and the last one carries the real footer.

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::sync::Arc;

use anyhow::{Context, bail};
use parquet::basic::{Compression, ZstdLevel};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::metadata::{FileMetaData, ParquetMetaDataBuilder, ParquetMetaDataWriter};
use parquet::file::properties::{WriterProperties, WriterPropertiesPtr};
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::parser::parse_message_type;
use parquet::schema::types::TypePtr;

use super::column::{Cell, Column, Kind};

/// Rows buffered before a Parquet row group is written (13 DOUBLE columns: ~14 MB).
pub const ROW_GROUP_ROWS: usize = 131_072;

/// A Parquet table being written, on its writer thread.
#[doc(hidden)]
pub struct ParquetSink {
    /// Writes into [`Staged`]; the bytes reach `file` a row group at a time.
    writer: SerializedFileWriter<Staged>,
    file: File,
    /// Bytes of the file that are final: the magic and the row groups so far. A
    /// provisional footer follows them.
    landed: u64,
    buffers: Vec<Buffer>,
    buffered: usize,
}

/// The writer's output since the last landing: the next row group's bytes.
#[derive(Default)]
struct Staged(Vec<u8>);

impl Write for Staged {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

enum Buffer {
    F(Vec<f64>),
    I(Vec<i64>),
    S(Vec<ByteArray>),
}

impl ParquetSink {
    /// Start a table of `columns` in `file` (schema `name`), readable (no rows) at once.
    pub fn create(file: File, name: &str, columns: &[Column]) -> anyhow::Result<Self> {
        let (schema, props) = schema_and_properties(name, columns)?;
        let writer = SerializedFileWriter::new(Staged::default(), schema, props)?;
        let buffers = columns
            .iter()
            .map(|c| match c.kind {
                Kind::Float => Buffer::F(Vec::new()),
                Kind::Int | Kind::Id => Buffer::I(Vec::new()),
                Kind::Text => Buffer::S(Vec::new()),
            })
            .collect();
        let mut sink = Self {
            writer,
            file,
            landed: 0,
            buffers,
            buffered: 0,
        };
        sink.land_with_provisional_footer()?;
        Ok(sink)
    }

    /// Buffer one row; every [`ROW_GROUP_ROWS`] rows, write them as a row group.
    pub fn row(&mut self, cells: &[Cell]) -> anyhow::Result<()> {
        for (buffer, cell) in self.buffers.iter_mut().zip(cells) {
            match (buffer, cell) {
                (Buffer::F(v), Cell::F(x)) => v.push(*x),
                (Buffer::I(v), Cell::I(n)) => v.push(*n),
                // The column is annotated unsigned: the same 64 bits.
                (Buffer::I(v), Cell::U(n)) => v.push(*n as i64),
                (Buffer::S(v), Cell::S(s)) => v.push(ByteArray::from(*s)),
                _ => bail!("a cell of the wrong kind for its column (a bug)"),
            }
        }
        self.buffered += 1;
        if self.buffered >= ROW_GROUP_ROWS {
            self.write_row_group()?;
        }
        Ok(())
    }

    /// Write what is buffered and the real footer.
    pub fn finish(mut self) -> anyhow::Result<()> {
        self.write_row_group()?;
        let staged = self.writer.into_inner()?;
        land(&mut self.file, self.landed, &staged.0, &[])
    }

    /// Write the buffered rows as one row group, then land it.
    fn write_row_group(&mut self) -> anyhow::Result<()> {
        if self.buffered == 0 {
            return Ok(());
        }
        let mut group = self.writer.next_row_group()?;
        let mut buffers = self.buffers.iter_mut();
        while let Some(mut column) = group.next_column()? {
            let buffer = buffers
                .next()
                .context("more columns than buffers (a bug)")?;
            match buffer {
                Buffer::F(v) => {
                    column.typed::<DoubleType>().write_batch(v, None, None)?;
                    v.clear();
                }
                Buffer::I(v) => {
                    column.typed::<Int64Type>().write_batch(v, None, None)?;
                    v.clear();
                }
                Buffer::S(v) => {
                    column.typed::<ByteArrayType>().write_batch(v, None, None)?;
                    v.clear();
                }
            }
            column.close()?;
        }
        group.close()?;
        self.buffered = 0;
        self.land_with_provisional_footer()
    }

    /// Put the staged bytes in the file after what has landed, followed by a footer
    /// listing the row groups so far (without page indexes: those come with the real
    /// footer, which is written over this one).
    fn land_with_provisional_footer(&mut self) -> anyhow::Result<()> {
        self.writer.flush()?;
        let props = self.writer.properties().clone();
        let groups = self.writer.flushed_row_groups().to_vec();
        let rows = groups.iter().map(|g| g.num_rows()).sum();
        let file_metadata = FileMetaData::new(
            props.writer_version().as_num(),
            rows,
            Some(props.created_by().to_string()),
            None,
            Arc::new(self.writer.schema_descr().clone()),
            None,
        );
        let metadata = ParquetMetaDataBuilder::new(file_metadata)
            .set_row_groups(groups)
            .build();
        let mut footer = Vec::new();
        ParquetMetaDataWriter::new(&mut footer, &metadata)
            .with_preserve_page_index_locations(false)
            .finish()?;
        let staged = std::mem::take(&mut self.writer.inner_mut().0);
        land(&mut self.file, self.landed, &staged, &footer)?;
        self.landed += staged.len() as u64;
        Ok(())
    }
}

/// The table's schema (one required column per field) and writer settings.
#[doc(hidden)]
pub fn schema_and_properties(
    name: &str,
    columns: &[Column],
) -> anyhow::Result<(TypePtr, WriterPropertiesPtr)> {
    let fields: String = columns
        .iter()
        .map(|c| match c.kind {
            Kind::Float => format!("REQUIRED DOUBLE {};", c.name),
            Kind::Int => format!("REQUIRED INT64 {};", c.name),
            Kind::Id => format!("REQUIRED INT64 {} (INTEGER(64,false));", c.name),
            Kind::Text => format!("REQUIRED BYTE_ARRAY {} (UTF8);", c.name),
        })
        .collect();
    let schema = parse_message_type(&format!("message {name} {{ {fields} }}"))?;
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .build();
    Ok((Arc::new(schema), Arc::new(props)))
}

/// Write `bytes` then `footer` at `at` in one write (so a kill leaves the file either as
/// it was or as it is after), and end the file there.
fn land(file: &mut File, at: u64, bytes: &[u8], footer: &[u8]) -> anyhow::Result<()> {
    let mut all = Vec::with_capacity(bytes.len() + footer.len());
    all.extend_from_slice(bytes);
    all.extend_from_slice(footer);
    file.seek(SeekFrom::Start(at))?;
    file.write_all(&all)?;
    // The new end is past the old footer whenever a row group came with it (the new
    // footer lists more); cut anything left over all the same.
    file.set_len(at + all.len() as u64)?;
    Ok(())
}
