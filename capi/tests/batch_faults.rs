//! A batch's faults stay with their cells (issue 39): an unknown `gas.drag` fails its
//! own cell and every `statuses[]` entry is written; one state given to two entries is
//! refused by index (it was freed twice, aborting the host); a closed cell's state given
//! to an open coupling is refused (its bodies were dropped without a word).

use std::ptr::{null, null_mut};

use agglo_c::AggloStatus;
use agglo_c::cell::*;
use agglo_c::coupling::*;
use agglo_c::output::agglo_output_free;
use agglo_c::state::{AggloCellState, agglo_state_free};

mod common;
use common::{message, two_class_coupling};

const CLASSES: usize = 2;

/// A coupling of ballistic_aggregation.json's grains on two classes (1 and 2+
/// primaries), 40 bodies per box, one replica; and its primary mass [kg].
fn coupling(keep_bodies: bool) -> (*mut AggloCoupling, f64) {
    let mut options = agglo_coupling_options_default();
    options.bodies = 40;
    options.replicas = 1;
    options.keep_bodies = keep_bodies;
    // Re-lifted or closed cells, as these tests were written (persist is the default).
    options.persist = false;
    two_class_coupling(&options)
}

/// One cell's arrays: monomers at volume fraction 0.02 (b0 from m0 at ρ = 1000 kg/m³).
struct Arrays {
    n: [f64; CLASSES],
    m: [f64; CLASSES],
    v: [f64; 3 * CLASSES],
    theta: [f64; CLASSES],
    tg: [f64; CLASSES],
}

impl Arrays {
    fn monomers(m0: f64) -> Self {
        let grain = m0 / 1000.0; // its volume [m³]
        Self {
            n: [0.02 / grain, 0.0],
            m: [m0, 2.0 * m0],
            v: [0.0; 3 * CLASSES],
            theta: [300.0; CLASSES],
            tg: [1.0; CLASSES],
        }
    }

    fn input(&self, drag: u32) -> AggloCellInput {
        AggloCellInput {
            number_density: self.n.as_ptr(),
            mass: self.m.as_ptr(),
            velocity: self.v.as_ptr(),
            temperature: self.theta.as_ptr(),
            granular_temperature: self.tg.as_ptr(),
            granular_anisotropy: std::ptr::null(),
            gas: AggloGas {
                velocity: [0.0; 3],
                temperature: 300.0,
                drag,
                drag_a: 1e-3,
                drag_b: 0.0,
            },
            dt: 1e-4,
        }
    }
}

/// Advance `inputs` as a batch from `states`; returns the call's status, the statuses
/// (pre-filled with `Internal`, which no cell of these gets, to see every entry written)
/// and the outputs, freed.
fn batch(
    c: *const AggloCoupling,
    step: u64,
    inputs: &[AggloCellInput],
    states: &mut [*mut AggloCellState],
) -> (AggloStatus, Vec<AggloStatus>, Vec<bool>) {
    let n = inputs.len();
    let ids: Vec<u64> = (0..n as u64).collect();
    let mut outs = vec![null_mut(); n];
    let mut statuses = vec![AggloStatus::Internal; n];
    // SAFETY: every array holds n entries; states NULL or live.
    let status = unsafe {
        agglo_cells_advance(
            c,
            step,
            n,
            ids.as_ptr(),
            inputs.as_ptr(),
            states.as_mut_ptr(),
            outs.as_mut_ptr(),
            statuses.as_mut_ptr(),
            2,
        )
    };
    let written = outs.iter().map(|o| !o.is_null()).collect();
    for o in outs {
        // SAFETY: NULL or an output of this batch.
        unsafe { agglo_output_free(o) };
    }
    (status, statuses, written)
}

#[test]
fn an_unknown_drag_fails_only_its_own_cell_and_every_status_is_written() {
    let (c, m0) = coupling(false);
    let cell = Arrays::monomers(m0);
    let inputs = [
        cell.input(AGGLO_DRAG_NONE),
        cell.input(99),
        cell.input(AGGLO_DRAG_CONSTANT),
    ];
    let mut states = vec![null_mut(); 3];
    let (status, statuses, outs) = batch(c, 0, &inputs, &mut states);
    assert_eq!(status, AggloStatus::Input);
    assert_eq!(
        statuses,
        [AggloStatus::Ok, AggloStatus::Input, AggloStatus::Ok]
    );
    assert_eq!(outs, [true, false, true]);
    assert!(
        message().starts_with("cell 1: gas.drag = 99 (must be AGGLO_DRAG_NONE (0)"),
        "{}",
        message()
    );
    assert!(!states[0].is_null() && states[1].is_null() && !states[2].is_null());
    // A NULL array is its own cell's fault too.
    let mut no_mass = cell.input(AGGLO_DRAG_NONE);
    no_mass.mass = null();
    let inputs = [no_mass, cell.input(AGGLO_DRAG_NONE)];
    let mut fresh = vec![null_mut(); 2];
    let (_, statuses, _) = batch(c, 0, &inputs, &mut fresh);
    assert_eq!(statuses, [AggloStatus::Argument, AggloStatus::Ok]);
    assert!(message().contains("cell 0: mass is NULL"), "{}", message());
    // SAFETY: states of this test, each freed once; NULL is ignored.
    unsafe {
        for s in states.into_iter().chain(fresh) {
            agglo_state_free(s);
        }
        agglo_coupling_free(c);
    }
}

#[test]
fn one_state_given_to_two_entries_is_refused_naming_both_indices() {
    let (c, m0) = coupling(true);
    let cell = Arrays::monomers(m0);
    let input = cell.input(AGGLO_DRAG_NONE);
    let mut first = vec![null_mut(); 1];
    let (status, ..) = batch(c, 0, &[input], &mut first);
    assert_eq!(status, AggloStatus::Ok, "{}", message());
    let shared = first[0];
    // Entries 0 and 2 hold cell 0's state (entry 2, cell 2, would also be refused as
    // another cell's state: the pointer check comes first, naming the indices); entry 1
    // starts afresh.
    let mut states = vec![shared, null_mut(), shared];
    let (status, statuses, outs) = batch(c, 1, &[input, input, input], &mut states);
    assert_eq!(status, AggloStatus::Argument);
    assert_eq!(
        statuses,
        [
            AggloStatus::Argument,
            AggloStatus::Ok,
            AggloStatus::Argument
        ]
    );
    assert_eq!(outs, [false, true, false]);
    let text = message();
    assert!(
        text.contains("states[0] is the same state as states[2]")
            && text.contains("states[2] is the same state as states[0]"),
        "{text}"
    );
    // Neither entry was replaced: the shared state is still live and still cell 0's.
    assert_eq!((states[0], states[2]), (shared, shared));
    let mut again = vec![shared];
    let (status, ..) = batch(c, 1, &[input], &mut again);
    assert_eq!(status, AggloStatus::Ok, "{}", message());
    // SAFETY: states of this test, each freed once (`shared` was replaced by `again`).
    unsafe {
        agglo_state_free(again[0]);
        agglo_state_free(states[1]);
        agglo_coupling_free(c);
    }
}

#[test]
fn a_closed_cell_s_state_is_refused_by_an_open_coupling() {
    let (closed, m0) = coupling(true);
    let (open, _) = coupling(false);
    let cell = Arrays::monomers(m0);
    let input = cell.input(AGGLO_DRAG_NONE);
    let mut states = vec![null_mut(); 1];
    let (status, ..) = batch(closed, 0, &[input], &mut states);
    assert_eq!(status, AggloStatus::Ok, "{}", message());
    let (status, statuses, _) = batch(open, 1, &[input], &mut states);
    assert_eq!(status, AggloStatus::State);
    assert_eq!(statuses, [AggloStatus::State]);
    assert!(
        message().starts_with("cell 0: state: it holds 1 boxes of bodies"),
        "{}",
        message()
    );
    // The same through the single-cell call.
    let mut out = null_mut();
    // SAFETY: valid pointers; states[0] live.
    let status = unsafe { agglo_cell_advance(open, 0, 1, &input, &mut states[0], &mut out) };
    assert_eq!(status, AggloStatus::State);
    assert!(out.is_null());
    // SAFETY: each freed once.
    unsafe {
        agglo_state_free(states[0]);
        agglo_coupling_free(closed);
        agglo_coupling_free(open);
    }
}
