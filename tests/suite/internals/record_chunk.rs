//! Unit tests of `record::chunk` (src/record/chunk.rs): the bounded chunk decoder that
//! `agglo inspect`, `agglo layout` and resuming from a recording read chunks with.

use std::io::Write;

use mcap::read::{LinearReader, Options};
use mcap::records::Record;

use agglo::record::chunk;

/// A recording's first chunk, as written (zstd): its header and compressed bytes.
fn first_chunk(dir: &std::path::Path) -> (mcap::records::ChunkHeader, Vec<u8>) {
    let recording = dir.join("run.mcap");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_agglo"))
        .args([
            "run",
            "scenarios/quick_demo.json",
            "-q",
            "--set",
            "time.end=2e-4",
        ])
        .arg("--recording")
        .arg(&recording)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .unwrap();
    assert!(status.success());
    let buf = std::fs::read(&recording).unwrap();
    let reader = LinearReader::new_with_options(&buf, Options::IgnoreEndMagic.into()).unwrap();
    for record in reader {
        if let Record::Chunk { header, data } = record.unwrap() {
            return (header, data.into_owned());
        }
    }
    panic!("no chunk in {}", recording.display());
}

/// MCAP's other codec, lz4 (the frame format), is read without the lz4 C library: a
/// chunk of our own recording, recompressed as an lz4 frame, decodes to the same records
/// as the zstd chunk it came from; and a frame cut short is an error, not a panic.
#[test]
fn an_lz4_chunk_decodes_to_the_records_of_its_zstd_twin() {
    let dir = tempfile::tempdir().unwrap();
    let (header, zstd_data) = first_chunk(dir.path());
    assert_eq!(header.compression, "zstd");
    let content = zstd::decode_all(&zstd_data[..]).unwrap();
    let mut encoder = lz4_flex::frame::FrameEncoder::new(Vec::new());
    encoder.write_all(&content).unwrap();
    let lz4_data = encoder.finish().unwrap();
    let mut lz4_header = header.clone();
    lz4_header.compression = "lz4".into();
    lz4_header.compressed_size = lz4_data.len() as u64;

    let from_zstd = chunk::records(&header, &zstd_data).unwrap();
    let from_lz4 = chunk::records(&lz4_header, &lz4_data).unwrap();
    assert!(from_zstd.len() >= 3, "{} records", from_zstd.len());
    assert_eq!(format!("{from_zstd:?}"), format!("{from_lz4:?}"));

    let cut = &lz4_data[..lz4_data.len() / 2];
    let e = chunk::records(&lz4_header, cut).unwrap_err().to_string();
    assert!(!e.is_empty());
}
