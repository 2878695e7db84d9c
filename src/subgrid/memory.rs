//! How much memory a cell's boxes need, checked before any box is lifted (issue 39: a
//! box of the largest accepted size, 1e7 bodies, killed the host process on allocation
//! failure, and a 1e6-body box peaked at 816 MB).
//!
//! A running box costs what a run costs per body ([`crate::memory::BYTES_PER_BODY`],
//! measured) plus what lifting holds while it runs — the lifted scene's bodies and the
//! placement grid, [`LIFT_BYTES_PER_BODY`] — and the boxes running at once are the
//! worker threads (at most the batch's boxes). A closed or persistent cell's state
//! holds each replica's box as bytes ([`KEPT_BYTES_PER_BODY`]). The sum, with the
//! process's own [`crate::memory::BASE_BYTES`], is compared with the memory the kernel
//! says is available, as `agglo run` does.

use crate::memory::{BASE_BYTES, BYTES_PER_BODY};

use super::error::SubgridError;

/// Bytes per body lifting adds to a running box [B]: the scene's `PlacedBody` (about
/// 130 B with its options) and the placement grid (up to 8 cells per body, a 24 B list
/// each, and 32 B per placed body), rounded up; with [`BYTES_PER_BODY`] it makes
/// 1000 B per body. Measured (the `#[ignore]`d `one_box_for_measuring_its_memory` of
/// tests/suite/subgrid_harden.rs under `/usr/bin/time -v`, dev build, sticky monomers
/// at φ = 0.02): peak resident 94 MB at N = 1e5, 325 MB at 4e5, 807 MB at 1e6, a slope
/// of 786–824 B per body (issue 39 saw 816 MB at 1e6).
pub const LIFT_BYTES_PER_BODY: f64 = 350.0;

/// Bytes per body a kept box takes in the cell's state [B]: its restart snapshot's row
/// (an id and twelve f64; tests/suite/subgrid_harden.rs measures a kept state's bytes
/// per body, 98 B, and checks it is below this). Until issue 37's cost work a kept box also
/// held its lifted scene as JSON, and this was 600.
pub const KEPT_BYTES_PER_BODY: f64 = 120.0;

/// The memory a cell's step needs [B]: `at_once` boxes of `bodies` running, and
/// `kept` boxes of `bodies` held in the state.
pub fn cell_bytes(bodies: f64, at_once: usize, kept: usize) -> f64 {
    BASE_BYTES
        + at_once as f64 * bodies * (BYTES_PER_BODY + LIFT_BYTES_PER_BODY)
        + kept as f64 * bodies * KEPT_BYTES_PER_BODY
}

/// Refuse `cell`'s step when its boxes of `bodies` (`at_once` running, `kept` held in
/// its state) need more than `available` bytes (None: unknown, not checked); the
/// message gives the estimate and what fits.
pub fn check_memory(
    cell: u64,
    bodies: f64,
    at_once: usize,
    kept: usize,
    available: Option<f64>,
) -> Result<(), SubgridError> {
    let Some(available) = available else {
        return Ok(());
    };
    let need = cell_bytes(bodies, at_once, kept);
    if need <= available {
        return Ok(());
    }
    let per_body =
        at_once as f64 * (BYTES_PER_BODY + LIFT_BYTES_PER_BODY) + kept as f64 * KEPT_BYTES_PER_BODY;
    let fits = ((available - BASE_BYTES) / per_body).max(0.0).floor();
    Err(SubgridError::input(
        cell,
        "bodies",
        format!("{bodies:.3e} per box"),
        format!(
            "{at_once} boxes running at once and {kept} kept in the cell's state need about \
             {:.1} GB ({:.0} MB fixed + {per_body:.0} B per body of a box), but only {:.1} GB \
             of memory is available; at most {fits:.3e} bodies per box fit on this machine \
             now: lower N (bodies or max_bodies), the replicas or the threads",
            need / 1e9,
            BASE_BYTES / 1e6,
            available / 1e9
        ),
    ))
}
