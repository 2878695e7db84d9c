//! Cost of writing an output table: 2²⁰ rows of 13 float columns (the width of the
//! collision log) through `TableWriter`, as Parquet (zstd row groups of 131 072 rows,
//! each landed with a provisional footer so that a killed run's table stays readable)
//! and as CSV. Prints each file's size once.

use std::path::Path;

use agglo::output::table::{Cell, Column, TableWriter, float};
use criterion::{Criterion, criterion_group, criterion_main};

const ROWS: usize = 1 << 20;
const NAMES: [&str; 13] = [
    "t", "a", "b", "c", "d", "e", "f", "g", "h", "i", "j", "k", "l",
];

fn write(path: &Path) -> u64 {
    let columns: Vec<Column> = NAMES.iter().map(|n| float(n, "-", "a value")).collect();
    let mut table = TableWriter::create(path, "bench", &columns).expect("table created");
    let mut cells = [Cell::F(0.0); 13];
    for r in 0..ROWS {
        // Values that vary as a run's do (not constants zstd would erase).
        let x = r as f64;
        for (k, cell) in cells.iter_mut().enumerate() {
            *cell = Cell::F((x * 1e-4 + k as f64).sin() * 1e-3 + x * 1e-6);
        }
        table.row(&cells).expect("row written");
    }
    table.finish().expect("table finished");
    std::fs::metadata(path).expect("file written").len()
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let parquet = dir.path().join("t.parquet");
    let csv = dir.path().join("t.csv");
    eprintln!(
        "{ROWS} rows x 13 floats: Parquet {} bytes, CSV {} bytes",
        write(&parquet),
        write(&csv)
    );
    let mut group = c.benchmark_group("table_2e20_rows_13_floats");
    group.sample_size(10);
    group.bench_function("parquet", |b| b.iter(|| write(&parquet)));
    group.bench_function("csv", |b| b.iter(|| write(&csv)));
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
