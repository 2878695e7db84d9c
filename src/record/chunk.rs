//! A recording's chunk decoded with every length bounded by the bytes there are: the
//! chunk's stated size by its compressed bytes (at most [`MAX_RATIO`] to one), the data
//! decompressed streaming (memory grows with what is really decoded, not with what the
//! header says), each record's length by the bytes that remain after it, the content by
//! its CRC. `agglo inspect`, `agglo layout` and the scan behind them read chunks here:
//! mcap's own chunk reader reserves a record's stated length before reading it, so one
//! flipped bit in a damaged file asked for 2.8e18 bytes and aborted.

use std::io::Read;

use anyhow::{bail, ensure};
use mcap::records::{ChunkHeader, Record};

/// The most a chunk's content may outgrow its compressed bytes: zstd reaches about
/// 1:10 on a recording's snapshots and ~1:30 000 only on runs of one repeated byte, which
/// no recording holds. A stated size above this is damage, refused before decoding.
pub const MAX_RATIO: u64 = 1024;

/// Slack on the ratio for tiny chunks [bytes].
const SLACK: u64 = 1 << 20;

/// The records of a chunk whose compressed bytes are `data`.
pub fn records(header: &ChunkHeader, data: &[u8]) -> anyhow::Result<Vec<Record<'static>>> {
    let size = header.uncompressed_size;
    let bound = (data.len() as u64).saturating_mul(MAX_RATIO) + SLACK;
    ensure!(
        size <= bound,
        "the chunk states {size} bytes of content from {} compressed bytes (allowed at most \
         {MAX_RATIO} to one): a damaged length",
        data.len()
    );
    // At most size + 1 bytes are taken, so a decoder that yields more is caught without
    // holding more than that.
    let mut content = Vec::new();
    let limit = size + 1;
    match header.compression.as_str() {
        "" => content.extend_from_slice(&data[..data.len().min(limit as usize)]),
        "zstd" => {
            zstd::stream::read::Decoder::new(data)?
                .take(limit)
                .read_to_end(&mut content)?;
        }
        "lz4" => {
            lz4_flex::frame::FrameDecoder::new(data)
                .take(limit)
                .read_to_end(&mut content)?;
        }
        other => bail!("unsupported chunk compression `{other}`"),
    }
    ensure!(
        content.len() as u64 == size,
        "the chunk states {size} bytes of content but decompresses to {}{}",
        content.len().min(size as usize),
        if content.len() as u64 > size {
            " and more"
        } else {
            ""
        }
    );
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(&content);
        ensure!(
            crc == header.uncompressed_crc,
            "the chunk's content does not match its CRC ({crc:#010x}, stated {:#010x})",
            header.uncompressed_crc
        );
    }
    let mut records = Vec::new();
    let mut rest = &content[..];
    while !rest.is_empty() {
        ensure!(
            rest.len() >= 9,
            "a record header cut off ({} bytes left)",
            rest.len()
        );
        let opcode = rest[0];
        let len = u64::from_le_bytes(rest[1..9].try_into()?);
        let remaining = rest.len() - 9;
        ensure!(
            len <= remaining as u64,
            "a record (opcode {opcode:#04x}) states {len} bytes, but only {remaining} remain in its chunk"
        );
        let (body, next) = rest[9..].split_at(len as usize);
        records.push(mcap::parse_record(opcode, body)?.into_owned());
        rest = next;
    }
    Ok(records)
}
