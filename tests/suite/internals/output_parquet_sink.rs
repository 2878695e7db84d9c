//! Unit tests of `output::parquet_sink` (src/output/parquet_sink.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::output::column::{Cell, Column};
use agglo::output::column::{float, id, text};
use agglo::output::parquet_sink::*;
use agglo::output::table::read_table;
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::writer::SerializedFileWriter;
use std::fs::File;

const COLUMNS: [Column; 3] = [
    float("x", "m", "a float"),
    id("id", "-", "an id"),
    text("word", "a word"),
];

/// What a reader sees if the process is killed now: the file as it stands.
fn rows_if_killed_now(path: &std::path::Path) -> usize {
    read_table(path).expect("a readable file").len()
}

/// The file opens at every moment between row groups: empty at first, then with each
/// completed row group, and in the end with every row, in order.
#[test]
fn a_table_is_readable_between_row_groups_and_whole_at_the_end() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.parquet");
    let mut sink = ParquetSink::create(File::create(&path).unwrap(), "t", &COLUMNS).unwrap();
    assert_eq!(rows_if_killed_now(&path), 0);
    let rows = 2 * ROW_GROUP_ROWS + 7;
    for k in 0..rows {
        let word = if k % 2 == 0 { "even" } else { "odd" };
        sink.row(&[
            Cell::F(k as f64),
            Cell::U(u64::MAX - k as u64),
            Cell::S(word),
        ])
        .unwrap();
        if k + 1 == ROW_GROUP_ROWS + 3 {
            // One group landed; the three rows after it are still buffered.
            assert_eq!(rows_if_killed_now(&path), ROW_GROUP_ROWS);
        }
    }
    assert_eq!(rows_if_killed_now(&path), 2 * ROW_GROUP_ROWS);
    sink.finish().unwrap();
    let table = read_table(&path).unwrap();
    assert_eq!(table.len(), rows);
    match table.column("id") {
        Some(agglo::output::table::Values::U(ids)) => {
            assert_eq!(ids[rows - 1], u64::MAX - (rows as u64 - 1))
        }
        other => panic!("id column read as {other:?}"),
    }
}

/// The finished file is the one a writer going straight to the file writes: the
/// provisional footers leave no trace.
#[test]
fn a_finished_table_has_the_bytes_of_a_straight_write() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.parquet");
    let mut sink = ParquetSink::create(File::create(&path).unwrap(), "t", &COLUMNS).unwrap();
    let rows = ROW_GROUP_ROWS + 11;
    for k in 0..rows {
        sink.row(&[Cell::F(0.5 * k as f64), Cell::U(k as u64), Cell::S("w")])
            .unwrap();
    }
    sink.finish().unwrap();
    // The same rows through the crate's writer alone, straight into memory.
    let (schema, props) = schema_and_properties("t", &COLUMNS).unwrap();
    let mut direct = SerializedFileWriter::new(Vec::new(), schema, props).unwrap();
    for range in [0..ROW_GROUP_ROWS, ROW_GROUP_ROWS..rows] {
        let mut group = direct.next_row_group().unwrap();
        let x: Vec<f64> = range.clone().map(|k| 0.5 * k as f64).collect();
        let ids: Vec<i64> = range.clone().map(|k| k as i64).collect();
        let words: Vec<ByteArray> = range.map(|_| ByteArray::from("w")).collect();
        let mut column = group.next_column().unwrap().unwrap();
        column
            .typed::<DoubleType>()
            .write_batch(&x, None, None)
            .unwrap();
        column.close().unwrap();
        let mut column = group.next_column().unwrap().unwrap();
        column
            .typed::<Int64Type>()
            .write_batch(&ids, None, None)
            .unwrap();
        column.close().unwrap();
        let mut column = group.next_column().unwrap().unwrap();
        column
            .typed::<ByteArrayType>()
            .write_batch(&words, None, None)
            .unwrap();
        column.close().unwrap();
        group.close().unwrap();
    }
    let direct = direct.into_inner().unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), direct);
}
