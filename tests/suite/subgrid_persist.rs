//! Boxes that persist across macro steps (issue 37 item 3): with no transport the cell is
//! the closed cell, bit for bit; transport adds and removes bodies in the kept boxes.

use agglo::subgrid::*;

use crate::subgrid::{coupling, monomers};

#[test]
fn a_persistent_cell_without_transport_is_the_closed_cell() {
    // Δt a power of two (the closed cell's clock and checkpoints, subgrid.rs).
    let (dt, steps) = (2f64.powi(-12), 3);
    let mut closed = coupling(300, 2);
    closed.keep_bodies = true;
    let mut persist = coupling(300, 2);
    persist.persist = true;
    let input = monomers(&closed, 0.05, dt);
    let mut solver = input.clone();
    let (mut a, mut b) = (None, None);
    let mut impacts = 0.0;
    for step in 0..steps {
        let (_, sa) = advance_cell(&closed, 9, step, &input, a.as_ref()).unwrap();
        let (out, sb) = advance_cell(&persist, 9, step, &solver, b.as_ref()).unwrap();
        impacts += out.impact_rate.mean * out.box_volume * dt;
        // The solver applies the rates and transports nothing.
        solver = apply_rates(&persist, &solver, &out);
        a = Some(sa);
        b = Some(CellState::from_bytes(&sb.to_bytes()).unwrap());
    }
    assert!(
        impacts >= 10.0,
        "too few impacts to tell boxes apart: {impacts}"
    );
    let (a, b) = (a.unwrap(), b.unwrap());
    assert_eq!(a.boxes().len(), 2);
    for (x, y) in a.boxes().iter().zip(b.boxes()) {
        assert!(
            x.snapshot == y.snapshot,
            "a persistent box left the closed cell"
        );
    }
}

#[test]
fn transport_adds_and_removes_bodies_in_the_kept_boxes() {
    let mut c = coupling(300, 8);
    c.persist = true;
    let mut input = monomers(&c, 0.05, 2e-4);
    // Some dimers to remove later.
    input.classes[1].number_density = 0.2 * input.classes[0].number_density;
    let (first, state) = advance_cell(&c, 4, 0, &input, None).unwrap();
    let volume = first.box_volume;
    let mut next = apply_rates(&c, &input, &first);
    // Transport brings 50 % more monomers and takes half the dimers away.
    let mono = next.classes[0].number_density;
    next.classes[0].number_density *= 1.5;
    next.classes[1].number_density *= 0.5;
    let (second, _) = advance_cell(&c, 4, 1, &next, Some(&state)).unwrap();
    assert_eq!(second.box_volume, volume, "a kept box keeps its volume");
    // Per box: the bodies the first step ended with, plus Poisson(0.5 n_1 V) monomers
    // (n_1 the solver's), less each of its own dimers with probability 1/2. Within 4
    // standard errors of the K = 8 boxes' mean.
    let ended: f64 = first
        .classes
        .iter()
        .map(|k| k.number_density.mean * volume)
        .sum();
    let dimers = first.classes[1].number_density.mean * volume;
    let (added, removed) = (0.5 * mono * volume, 0.5 * dimers);
    let se = ((added + 0.25 * 2.0 * removed) / 8.0).sqrt();
    let start = second.bodies.mean;
    assert!(
        (start - (ended + added - removed)).abs() <= 4.0 * se,
        "boxes start with {start} bodies; {ended} + {added} − {removed} ± {se} expected"
    );
    // The change is seen: without adjusting, the boxes would start where they ended.
    assert!(added - removed > 8.0 * se, "{added} − {removed} vs {se}");

    // keep_bodies and persist exclude each other.
    let mut both = c.clone();
    both.keep_bodies = true;
    let e = advance_cell(&both, 4, 0, &input, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("coupling: persist"), "{e}");
}

/// A measurement, not a check (issue 37 item 3's figure): closed uniform cells of
/// sticky monomers (φ = 0.05, T = 1, N = 1000, K = 4, 128 cells) stepped as a sectional
/// solver steps them ([`apply_rates`], energy transported) to t = 2 τ0, re-lifted every
/// step or persisting (which, without transport, is the closed cell: the boxes' own
/// dynamics), for 1, 4 and 20 steps. Prints N/N0 and n1/n0 at the end, mean ± SE over
/// the cells. `cargo test --test suite relifted_chains -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement for docs/coupling.md (about two minutes)"]
fn relifted_chains_against_persistent_boxes() {
    let tau0 = 5.2e-4;
    for steps in [1u64, 4, 20] {
        let dt = 2.0 * tau0 / steps as f64;
        for persist in [false, true] {
            let mut c = coupling(1000, 4);
            c.persist = persist;
            let start = monomers(&c, 0.05, dt);
            let n0 = start.classes[0].number_density;
            let (mut total, mut mono) = (Vec::new(), Vec::new());
            for cell in 0..128u64 {
                let (mut input, mut state) = (start.clone(), None);
                for step in 0..steps {
                    let (out, s) =
                        advance_cell(&c, 1000 + cell, step, &input, state.as_ref()).unwrap();
                    input = apply_rates(&c, &input, &out);
                    state = Some(s);
                }
                total.push(input.classes.iter().map(|k| k.number_density).sum::<f64>() / n0);
                mono.push(input.classes[0].number_density / n0);
            }
            let (t, m) = (Stat::of(&total), Stat::of(&mono));
            eprintln!(
                "{steps:2} steps of {:.3} τ0, {}: N/N0 = {:.4} ± {:.4}, n1/n0 = {:.4} ± {:.4}",
                dt / tau0,
                if persist { "persistent" } else { "re-lifted " },
                t.mean,
                t.se,
                m.mean,
                m.se
            );
        }
    }
}

/// The direct reference of [`relifted_chains_against_persistent_boxes`]: eight boxes of
/// 10⁵ bodies of the same cell run in one step to 2 τ0 (the figure docs/coupling.md
/// quotes; about 15 s). `cargo test --test suite direct_boxes -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement for docs/coupling.md"]
fn direct_boxes_of_1e5_bodies_at_2_tau0() {
    let tau0 = 5.2e-4;
    let c = coupling(100_000, 8);
    let start = monomers(&c, 0.05, 2.0 * tau0);
    let n0 = start.classes[0].number_density;
    let (out, _) = advance_cell(&c, 7, 0, &start, None).unwrap();
    let end = apply_rates(&c, &start, &out);
    let total: f64 = end.classes.iter().map(|k| k.number_density).sum::<f64>() / n0;
    eprintln!(
        "8 boxes of 1e5 bodies to 2 τ0: N/N0 = {total:.4} ± {:.4}, n1/n0 = {:.4} ± {:.4}",
        out.number_rate.se * 2.0 * tau0 / n0,
        end.classes[0].number_density / n0,
        out.classes[0].number_rate.se * 2.0 * tau0 / n0
    );
}
