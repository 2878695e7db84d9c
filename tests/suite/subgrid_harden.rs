//! Issue 39's subgrid findings: a Δt no rate can be divided by, a kept cell's stored
//! state re-checked on restore, cell-state bytes under a checksum, a closed cell's state
//! given to an open coupling, and a box too large for the machine's memory.

use agglo::subgrid::*;

use crate::subgrid::{coupling, monomers};

/// A closed cell's state after one step of 40 bodies in one box.
fn kept_state() -> (Coupling, CellInput, CellState) {
    let mut c = coupling(40, 1);
    c.keep_bodies = true;
    let input = monomers(&c, 0.02, 1e-4);
    let (_, state) = advance_cell(&c, 4, 0, &input, None).unwrap();
    (c, input, state)
}

/// `bytes` with their checksum made again, as a hand that edits a state would.
fn resealed(mut payload: Vec<u8>) -> Vec<u8> {
    let crc = crc32fast::hash(&payload);
    payload.extend_from_slice(&crc.to_le_bytes());
    payload
}

#[test]
fn a_dt_whose_box_volume_product_underflows_is_refused_naming_dt_and_its_range() {
    let c = coupling(300, 2);
    // V ≈ 5e-7 m³ for 300 monomers at φ = 0.02: V·dt = 0 for the smallest subnormal dt
    // (every rate was NaN), 5e-297 for dt = 1e-290 (rates of order 1e297 per body).
    for dt in [5e-324, 1e-300, 1e-290] {
        let input = monomers(&c, 0.02, dt);
        let e = advance_cell(&c, 17, 0, &input, None)
            .map(|(out, _)| out.impact_rate.mean)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(&format!("cell 17: dt = {dt:e}")), "{e}");
        let volume = box_volume(&c, 17, &input).unwrap();
        let lowest = VOLUME_TIME_RANGE.0 / volume;
        assert!(e.contains(&format!("dt must lie in [{lowest:e}, ")), "{e}");
    }
    // The edge of the range itself advances, with finite rates.
    let volume = box_volume(&c, 17, &monomers(&c, 0.02, 1e-4)).unwrap();
    let input = monomers(&c, 0.02, 1.01 * VOLUME_TIME_RANGE.0 / volume);
    let (out, _) = advance_cell(&c, 17, 0, &input, None).unwrap();
    assert!(out.classes[0].number_rate.mean.is_finite());
    // A kept box's step lost against the cell's clock (1e-4 s + 1e-25 s = 1e-4 s).
    let (c, input, state) = kept_state();
    let tiny = CellInput { dt: 1e-25, ..input };
    let e = advance_cell(&c, 4, 1, &tiny, Some(&state))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cell 4: dt = 1e-25") && e.contains("time + dt = time"),
        "{e}"
    );
}

#[test]
fn a_kept_state_whose_box_volume_is_out_of_range_is_refused_naming_it() {
    let (c, input, state) = kept_state();
    let bytes = state.to_bytes();
    let payload = &bytes[..bytes.len() - 4];
    // The volume's 8 bytes, found by value (postcard writes an f64 as itself).
    let v = state.box_volume().to_le_bytes();
    let at: Vec<usize> = (0..payload.len() - 8)
        .filter(|&i| payload[i..i + 8] == v)
        .collect();
    assert_eq!(at.len(), 1, "the volume's bytes occur once");
    for bad in [f64::NAN, 0.0, 1e-320, -1.0, f64::INFINITY] {
        let mut edited = payload.to_vec();
        edited[at[0]..at[0] + 8].copy_from_slice(&bad.to_le_bytes());
        let e = CellState::from_bytes(&resealed(edited)).unwrap_err();
        assert!(e.starts_with(&format!("box_volume = {bad:e}")), "{e}");
    }
    // Unchanged, the re-sealed bytes read and the cell continues.
    let again = CellState::from_bytes(&resealed(payload.to_vec())).unwrap();
    assert_eq!(again, state);
    advance_cell(&c, 4, 1, &input, Some(&again)).unwrap();
}

#[test]
fn every_single_bit_flip_of_a_kept_state_is_refused() {
    let (_, _, state) = kept_state();
    let bytes = state.to_bytes();
    assert!(bytes.len() > 1000, "{} bytes", bytes.len());
    // Every bit: a CRC-32 detects every single-bit error (issue 39: 83 of 300 flips were
    // read before it, 18 of them changing the outputs).
    for bit in 0..8 * bytes.len() {
        let mut flipped = bytes.clone();
        flipped[bit / 8] ^= 1 << (bit % 8);
        assert!(
            CellState::from_bytes(&flipped).is_err(),
            "bit {bit} of {} flipped was read",
            8 * bytes.len()
        );
    }
    // The layout before the checksum (version 2) is named as such.
    let mut old = bytes.clone();
    old[0] = 2;
    let e = CellState::from_bytes(&old).unwrap_err();
    assert!(
        e.contains(&format!(
            "layout version 2, this build reads version {STATE_VERSION}"
        )),
        "{e}"
    );
    assert_eq!(CellState::from_bytes(&bytes).unwrap(), state);
}

#[test]
fn a_closed_cell_s_state_is_refused_by_an_open_coupling() {
    let (c, input, state) = kept_state();
    let mut open = c.clone();
    open.keep_bodies = false;
    let e = advance_cell(&open, 4, 1, &input, Some(&state))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("cell 4: state: it holds 1 boxes of bodies"),
        "{e}"
    );
    // Nor does a persistent coupling take a closed cell's state (it remembers nothing).
    let mut persist = open;
    persist.persist = true;
    let e = advance_cell(&persist, 4, 1, &input, Some(&state))
        .unwrap_err()
        .to_string();
    assert!(e.contains("it remembers no cell state"), "{e}");
}

#[test]
fn a_box_too_large_for_the_memory_is_refused_with_the_estimate_before_it_is_lifted() {
    let input = |c: &Coupling| monomers(c, 0.02, 1e-4);
    // The largest box, 1e7 bodies, kept by each of 1e5 replicas: 1e12 bodies' bytes.
    let mut c = coupling(MAX_BODIES, MAX_REPLICAS);
    c.keep_bodies = true;
    let e = advance_cell(&c, 6, 0, &input(&c), None)
        .unwrap_err()
        .to_string();
    // 1e7 expected bodies and a 5 σ Poisson margin: 1.0016e7.
    assert!(
        e.starts_with("cell 6: bodies = 1.002e7 per box (1 boxes running at once and 100000 kept"),
        "{e}"
    );
    // 1000 B per running body + 1e5 kept boxes × 120 B.
    assert!(e.contains("12001000 B per body of a box"), "{e}");
    // The same box sized by a target standard error that picks max_bodies.
    c.bodies = BoxSize::TargetSe {
        relative: 1e-300,
        min_bodies: 1,
        max_bodies: MAX_BODIES,
    };
    let e = advance_cell(&c, 6, 0, &input(&c), None)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("cell 6: bodies = 1.002e7 per box"), "{e}");
    // Open boxes on 1024 threads at once: 1024 × 1e7 × 1000 B.
    let mut open = coupling(MAX_BODIES, 2000);
    open.keep_bodies = false;
    let cells = vec![(6, input(&open), None)];
    let results = advance_cells(&open, 0, &cells, &agglo::farm::Workers::local(1024));
    let e = results[0].as_ref().unwrap_err().to_string();
    assert!(
        e.contains("1024 boxes running at once and 0 kept") && e.contains("GB"),
        "{e}"
    );
}

#[test]
fn a_kept_box_takes_fewer_bytes_per_body_than_the_estimate_says() {
    // Two closed cells of one box, N = 40 and 400: the slope of the state's bytes over
    // the bodies (the fixed part, the scene's settings, drops out).
    let size = |n: u32| {
        let mut c = coupling(n, 1);
        c.keep_bodies = true;
        let (_, state) = advance_cell(&c, 4, 0, &monomers(&c, 0.02, 1e-4), None).unwrap();
        let kept = agglo::restart::RestartSnapshot::decode(&state.boxes()[0].snapshot).unwrap();
        (kept.bodies.len() as f64, state.to_bytes().len() as f64)
    };
    let (n1, b1) = size(40);
    let (n2, b2) = size(400);
    let per_body = (b2 - b1) / (n2 - n1);
    println!("a kept box: {per_body:.0} B per body");
    assert!(
        per_body > 0.0 && per_body < KEPT_BYTES_PER_BODY,
        "{per_body} B per body"
    );
}

/// The peak memory of one open box of N bodies (`AGGLO_BOX_BODIES`, default 1e5), for
/// measuring src/subgrid/memory.rs's bytes per body by hand: run under `/usr/bin/time -v` at two
/// N and take the slope of the maximum resident size.
#[test]
#[ignore = "a measurement, run by hand under /usr/bin/time -v"]
fn one_box_for_measuring_its_memory() {
    let n: u32 = std::env::var("AGGLO_BOX_BODIES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000);
    let c = coupling(n, 1);
    let (out, _) = advance_cell(&c, 1, 0, &monomers(&c, 0.02, 1e-6), None).unwrap();
    println!("{n} bodies: impact rate {:e}", out.impact_rate.mean);
}
