//! `agglo::subgrid` (issue 32): a box per cell per macro step. Determinism over threads
//! and submission order, the closed cell against one run, the ballistic kernel and
//! Smoluchowski, re-lifting against one long run, conservation, bad input.

use agglo::farm::Workers;
use agglo::subgrid::*;

pub(crate) use crate::common::cells::{coupling, monomers};

#[test]
fn a_cell_advances_and_conserves_mass() {
    let c = coupling(300, 2);
    let input = monomers(&c, 0.05, 2e-4);
    let (out, state) = advance_cell(&c, 3, 0, &input, None).unwrap();
    let impacts = out.impact_rate.mean * out.box_volume * out.dt;
    assert!(impacts > 1.0, "no impacts: {out:?}");
    assert_eq!(state.macro_steps(), 1);
    let total: f64 = out.classes.iter().map(|k| k.mass_rate.mean).sum();
    let scale = out.classes[0].mass_rate.mean.abs();
    assert!(total.abs() <= 1e-12 * scale, "{total:e} vs {scale:e}");
    // The flat columns the C and Python fronts read hold the same numbers.
    let columns = out.columns();
    let column = |name: &str| columns.iter().find(|c| c.name == name).unwrap();
    assert_eq!(
        column("number_rate").mean[0],
        out.classes[0].number_rate.mean
    );
    assert_eq!(column("velocity").se[3 + 2], out.classes[1].velocity[2].se);
    assert_eq!(column("velocity").shape, vec![5, 3]);
    assert_eq!(column("impact_rate").mean, vec![out.impact_rate.mean]);
}

/// The output and state of every cell as bytes, by cell id.
fn bytes_by_cell(
    cells: &[(u64, CellInput, Option<CellState>)],
    results: Vec<Result<(CellOutput, CellState), SubgridError>>,
) -> Vec<(u64, Vec<u8>, Vec<u8>)> {
    let mut out: Vec<_> = cells
        .iter()
        .zip(results)
        .map(|((cell, ..), r)| {
            let (o, s) = r.unwrap();
            (*cell, o.to_bytes(), s.to_bytes())
        })
        .collect();
    out.sort_by_key(|x| x.0);
    out
}

#[test]
fn a_batch_is_the_same_bytes_for_any_thread_count_and_order() {
    let mut c = coupling(200, 2);
    c.kernel = true;
    let cells: Vec<(u64, CellInput, Option<CellState>)> = [11u64, 3, 42, 7]
        .iter()
        .enumerate()
        .map(|(k, &id)| (id, monomers(&c, 0.02 + 0.01 * k as f64, 2e-4), None))
        .collect();
    let one = bytes_by_cell(&cells, advance_cells(&c, 5, &cells, &Workers::local(1)));
    let two = bytes_by_cell(&cells, advance_cells(&c, 5, &cells, &Workers::local(2)));
    let mut shuffled = cells.clone();
    shuffled.reverse();
    shuffled.swap(0, 2);
    let turned = bytes_by_cell(
        &shuffled,
        advance_cells(&c, 5, &shuffled, &Workers::local(2)),
    );
    assert_eq!(one, two, "1 and 2 threads differ");
    assert_eq!(one, turned, "the order of submission changed a result");
    // And a cell alone is its entry of the batch.
    let (id, input, _) = &cells[2];
    let (o, s) = advance_cell(&c, *id, 5, input, None).unwrap();
    let alone = one.iter().find(|x| x.0 == *id).unwrap();
    assert_eq!(
        (o.to_bytes(), s.to_bytes()),
        (alone.1.clone(), alone.2.clone())
    );
    // The seeds do depend on the macro step and the cell: another step differs.
    let (o6, _) = advance_cell(&c, *id, 6, input, None).unwrap();
    assert_ne!(
        o6.to_bytes(),
        alone.1,
        "macro step 6 drew the same boxes as step 5"
    );
}

/// The bodies (by id), ledger and counters of a snapshot, as bytes.
fn end_state(s: &agglo::restart::RestartSnapshot) -> Vec<u8> {
    let mut rows = s.bodies.clone();
    rows.sort_by_key(|b| b.id);
    let mut bytes = Vec::new();
    for b in &rows {
        for x in [b.position, b.velocity].concat() {
            bytes.extend(x.to_le_bytes());
        }
        for x in [b.mass, b.radius, b.temperature, b.primaries, b.local_time] {
            bytes.extend(x.to_le_bytes());
        }
        bytes.extend(b.id.to_le_bytes());
    }
    bytes.extend(format!("{:?}{:?}{:?}", s.ledger, s.counters, s.clock.time).bytes());
    bytes
}

#[test]
fn a_closed_cell_over_m_steps_ends_as_one_run_over_m_dt() {
    closed_cell_against_one_run(coupling(300, 1));
}

#[test]
fn a_closed_cell_of_bouncing_grains_ends_as_one_run_over_m_dt() {
    // A resumed box is built without its initial bodies (SimBuilder::resuming): the TC
    // model's collapse time, which a scene with a restitution and none given draws
    // from its initial velocities, is kept with the box (cell.rs's BoxStart). Without
    // it the resumed boxes ran with another t_c (or none) than the one run.
    let mut c = coupling(300, 1);
    c.base.impact.restitution = Some(agglo::scenario::RestitutionLaw::Constant(0.8));
    assert_eq!(c.base.impact.collapse_time, None);
    closed_cell_against_one_run(c);
}

/// A closed cell of `c`'s (one replica, 300 bodies) over M = 4 steps against one run of
/// its lifted box over 4 Δt: the same end state, bit for bit.
fn closed_cell_against_one_run(mut c: Coupling) {
    // Δt a power of two, so that the cell's clock t + Δt and the checkpoints' k·Δt are
    // the same numbers.
    let (dt, m) = (2f64.powi(-12), 4);
    c.keep_bodies = true;
    let cell = 9;
    let input = monomers(&c, 0.05, dt);
    let mut state = None;
    let mut impacts = 0.0;
    for step in 0..m {
        let (out, s) = advance_cell(&c, cell, step, &input, state.as_ref()).unwrap();
        impacts += out.impact_rate.mean * out.box_volume * dt;
        // Through bytes, as a flow solver stores it.
        state = Some(CellState::from_bytes(&s.to_bytes()).unwrap());
    }
    assert!(
        impacts >= 20.0,
        "too few impacts to tell runs apart: {impacts}"
    );
    let state = state.unwrap();
    assert_eq!(state.time(), m as f64 * dt);
    let kept = agglo::restart::RestartSnapshot::decode(&state.boxes()[0].snapshot).unwrap();
    // One run over M·Δt of the same lifted box, with the restart checkpoints at every
    // Δt: the points where the event core is rebuilt as a resumed run rebuilds it (a run
    // without them differs at rounding level, engine/restart.rs).
    let volume = box_volume(&c, cell, &input).unwrap();
    let long = CellInput {
        dt: m as f64 * dt,
        ..input.clone()
    };
    let mut s = lift(
        &c,
        cell,
        &long,
        volume,
        replica_seed(c.base.seed, cell, 0, 0),
    )
    .unwrap();
    s.output.restart = Some(agglo::restart::RestartSettings {
        every: dt,
        path: None,
    });
    let mut sim = agglo::kernel::simulation(&s).unwrap();
    assert!(s.uses_event_core());
    sim.run().unwrap();
    let reference = agglo_engine::restart::capture(sim.world_mut());
    assert_eq!(end_state(&kept), end_state(&reference));
}

/// The ballistic (free-molecular) kernel π(b_i + b_j)² ⟨|Δv|⟩ of two Maxwellian
/// classes of velocity variances `ti`, `tj` per component at the same mean:
/// ⟨|Δv|⟩ = √(8 (T_i + T_j) / π).
fn ballistic(bi: f64, bj: f64, ti: f64, tj: f64) -> f64 {
    use std::f64::consts::PI;
    PI * (bi + bj).powi(2) * (8.0 * (ti + tj) / PI).sqrt()
}

#[test]
fn dilute_sticky_cell_follows_the_ballistic_kernel_and_smoluchowski() {
    // Monomers at volume fraction 0.002 (φ = 0.004 with the dimers) and half as many dimers, in equipartition
    // (velocity variance T/size, which merging keeps: (T + T)/4 = T/2 for a dimer,
    // (T + 4 T/2)/9 = T/3 for a trimer), so the kernel between any two sizes i, j is
    // ballistic(b_i, b_j, T/i, T/j). Δt is 3 % of a monomer's mean free time, so the
    // cell barely changes and the velocity distributions stay Maxwellian. K = 64 boxes
    // of 2000 bodies: about 1500 monomer impacts, a 2.6 % standard error (measured with
    // 128 boxes: K_00, K_01, K_11 within 1.8 %, 0.6 %, 0.9 % of ballistic).
    let mut c = coupling(2000, 64);
    c.kernel = true;
    let (b0, m0) = c.primary();
    let t = 1.0;
    let dt = 5e-4;
    let mut input = monomers(&c, 0.002, dt);
    let n1 = input.classes[0].number_density;
    input.classes[1].number_density = n1 / 2.0;
    input.classes[1].granular_temperature = t / 2.0;
    let (out, _) = advance_cell(&c, 1, 0, &input, None).unwrap();

    let b = |s: f64| b0 * s.cbrt();
    let kernel = |i: usize, j: usize| {
        let (i, j) = (i as f64, j as f64);
        ballistic(b(i), b(j), t / i, t / j)
    };
    // Measured kernels of the pairs (monomer, monomer), (monomer, dimer), (dimer, dimer)
    // against the ballistic one: within 3 Poisson standard errors √C/E (impacts are
    // independent, docs/kernel.md); the Enskog factor at φ = 0.004 (1 %) and the
    // depletion of fast bodies over 3 % of a free time are well inside that.
    let acc = out.kernel.as_ref().expect("kernel asked for");
    let classes = acc.classes();
    for (i, j) in [(0, 0), (0, 1), (1, 1)] {
        let p = i * classes + j;
        let (count, exposure) = (acc.pooled.total(p) as f64, acc.pooled.exposure[p]);
        let measured = count / exposure;
        let se = count.sqrt() / exposure;
        let expected = kernel(i + 1, j + 1);
        assert!(count >= 50.0, "pair ({i}, {j}): only {count} impacts");
        assert!(
            (measured - expected).abs() <= 3.0 * se,
            "K_{i}{j} = {measured:e} ± {se:e} m³/s, ballistic {expected:e}"
        );
    }

    // Smoluchowski over Δt for sizes 1..=24 with that kernel (RK4, 200 steps), then
    // binned on the coupling's classes: the measured number rates agree within 3 SE.
    let sizes = 24;
    let rhs = |n: &[f64]| -> Vec<f64> {
        let mut d = vec![0.0; sizes + 1];
        for i in 1..=sizes {
            for j in 1..=sizes {
                let r = kernel(i, j) * n[i] * n[j];
                d[i] -= r;
                if i + j <= sizes {
                    d[i + j] += 0.5 * r;
                }
            }
        }
        d
    };
    let mut n = vec![0.0; sizes + 1];
    n[1] = n1;
    n[2] = n1 / 2.0;
    let h = dt / 200.0;
    for _ in 0..200 {
        let k1 = rhs(&n);
        let at = |k: &[f64], f: f64| n.iter().zip(k).map(|(x, y)| x + f * y).collect::<Vec<_>>();
        let k2 = rhs(&at(&k1, h / 2.0));
        let k3 = rhs(&at(&k2, h / 2.0));
        let k4 = rhs(&at(&k3, h));
        for s in 0..=sizes {
            n[s] += h / 6.0 * (k1[s] + 2.0 * k2[s] + 2.0 * k3[s] + k4[s]);
        }
    }
    let class_of_size = |s: usize| c.class_of(s as f64 * m0);
    let mut expected = [0.0; 5];
    expected[0] -= n1;
    expected[1] -= n1 / 2.0;
    for s in 1..=sizes {
        expected[class_of_size(s)] += n[s];
    }
    for (k, change) in expected.iter().enumerate().take(3) {
        let rate = out.classes[k].number_rate;
        let want = change / dt;
        assert!(
            (rate.mean - want).abs() <= 3.0 * rate.se,
            "class {k}: dn/dt = {:e} ± {:e}, Smoluchowski {want:e} 1/(m³ s)",
            rate.mean,
            rate.se
        );
        assert!(
            rate.se < 0.2 * want.abs(),
            "class {k}: SE {:e} too wide to test",
            rate.se
        );
    }
}

/// The next step's input from a step's output, as a flow solver without transport
/// updates its cell: n ← n + Δt dn/dt (clipped at 0), the class mass from the mass
/// density, the class states from the output where the class held bodies.
fn next_input(input: &CellInput, out: &CellOutput) -> CellInput {
    let dt = input.dt;
    let classes = input
        .classes
        .iter()
        .zip(&out.classes)
        .map(|(k, o)| {
            let n = (k.number_density + dt * o.number_rate.mean).max(0.0);
            let rho = k.number_density * k.mass + dt * o.mass_rate.mean;
            let present = o.present > 0;
            let measured = o.granular_replicas > 0;
            ClassInput {
                number_density: n,
                mass: if n > 0.0 && rho > 0.0 {
                    rho / n
                } else {
                    k.mass
                },
                velocity: if present {
                    o.velocity.map(|v| v.mean)
                } else {
                    k.velocity
                },
                temperature: if present {
                    o.temperature.mean
                } else {
                    k.temperature
                },
                granular_temperature: if measured {
                    o.granular_temperature.mean
                } else {
                    k.granular_temperature
                },
                granular_anisotropy: k.granular_anisotropy,
            }
        })
        .collect();
    CellInput {
        classes,
        ..input.clone()
    }
}

/// Mean and standard error over seeds.
fn over_seeds(x: &[f64]) -> (f64, f64) {
    let s = Stat::of(x);
    (s.mean, s.se)
}

#[test]
fn relifting_every_step_agrees_with_one_long_run() {
    // A closed sticky cell at φ = 0.01 over about one monomer free time: six macro
    // steps, each re-lifted from the last step's output, against one run over the
    // whole time; eight seeds (cells) of each, K = 4 boxes of 300 bodies per cell.
    let c = coupling(300, 4);
    let (dt, m, seeds) = (5e-4, 6, 8u64);
    let start = monomers(&c, 0.01, dt);
    let n0 = start.classes[0].number_density;
    let (mut chain_total, mut chain_mono, mut long_total, mut long_mono) =
        (vec![], vec![], vec![], vec![]);
    for seed in 0..seeds {
        let mut input = start.clone();
        for step in 0..m {
            let (out, _) = advance_cell(&c, 100 + seed, step, &input, None).unwrap();
            input = next_input(&input, &out);
        }
        chain_total.push(input.classes.iter().map(|k| k.number_density).sum::<f64>() / n0);
        chain_mono.push(input.classes[0].number_density / n0);
        let long = CellInput {
            dt: m as f64 * dt,
            ..start.clone()
        };
        let (out, _) = advance_cell(&c, 200 + seed, 0, &long, None).unwrap();
        let end = next_input(&long, &out);
        long_total.push(end.classes.iter().map(|k| k.number_density).sum::<f64>() / n0);
        long_mono.push(end.classes[0].number_density / n0);
    }
    for (what, a, b) in [
        ("bodies", &chain_total, &long_total),
        ("monomers", &chain_mono, &long_mono),
    ] {
        let ((ma, sa), (mb, sb)) = (over_seeds(a), over_seeds(b));
        let se = (sa * sa + sb * sb).sqrt();
        assert!(
            (ma - mb).abs() <= 3.0 * se,
            "{what}/n0: re-lifted {ma:.4} ± {sa:.4}, one run {mb:.4} ± {sb:.4}"
        );
        // The cell did change: the comparison is not between two untouched clouds.
        assert!(mb < 0.9 && (ma - mb).abs() < 0.2, "{what}: {ma} vs {mb}");
    }
}

/// A sticky cell in a gas moving along x, under gravity along −z, with Stokes drag.
fn dragged() -> (Coupling, CellInput) {
    let mut c = coupling(400, 3);
    c.base.field.gravity = [0.0, 0.0, -9.81];
    let mut input = monomers(&c, 0.02, 1e-3);
    input.classes[1].number_density = input.classes[0].number_density / 4.0;
    input.classes[1].velocity = [0.0, 0.3, 0.0];
    input.gas = GasState {
        velocity: [0.5, 0.0, 0.0],
        temperature: 350.0,
        drag: Some(agglo_engine::field::Relaxation::Stokes { viscosity: 1.8e-5 }),
    };
    (c, input)
}

#[test]
fn mass_is_exact_and_momentum_and_energy_close_against_the_ledgers() {
    let (c, input) = dragged();
    let (out, _) = advance_cell(&c, 4, 0, &input, None).unwrap();
    assert!(out.impact_rate.mean > 0.0);
    // Mass: moved between classes, never made or lost (each replica's sum is zero to
    // the rounding of its sums, ~1e-16 of the class masses).
    let mass_rate: f64 = out.classes.iter().map(|k| k.mass_rate.mean).sum();
    let mass_scale: f64 = out.classes.iter().map(|k| k.mass_rate.mean.abs()).sum();
    assert!(
        mass_rate.abs() <= 1e-12 * mass_scale,
        "{mass_rate:e} of {mass_scale:e}"
    );
    // Momentum: what the classes gained is what drag and g gave them, and the gas
    // received minus the drag's part: Σ_k dP_k/dt + gas = ρ_p g, to rounding relative
    // to the momentum the bodies carry per Δt.
    let rho_p: f64 = out.classes.iter().map(|k| k.mass_density.mean).sum();
    let scale = rho_p * (3.0f64.sqrt() + 0.5) / input.dt;
    let g = c.base.field.gravity;
    for (x, gx) in g.iter().enumerate() {
        let classes: f64 = out.classes.iter().map(|k| k.momentum_rate[x].mean).sum();
        let gap = classes + out.gas_momentum_rate[x].mean - rho_p * gx;
        assert!(gap.abs() <= 1e-12 * scale, "axis {x}: {gap:e} of {scale:e}");
    }
    // The gas pulls the bodies along +x, so it loses momentum along x, beyond noise.
    let gx = out.gas_momentum_rate[0];
    assert!(gx.mean < -5.0 * gx.se, "gas along x: {gx:?}");

    // Energy, box by box against the engine's ledger: kinetic ΔK = F − D and thermal
    // ΔΘ = D + R − Z − L, from the class sums (K = ½(Σ m|v − ū_k|² + |P_k|²/M_k)).
    let volume = box_volume(&c, 4, &input).unwrap();
    let run = run_task(
        &c,
        &ReplicaTask {
            cell: 4,
            macro_step: 0,
            replica: 0,
            input: input.clone(),
            volume,
            kept: None,
            expected: None,
        },
    )
    .unwrap();
    let r = &run.measured;
    let kinetic = |s: &ClassSums| -> f64 {
        (0..s.count.len())
            .filter(|&k| s.count[k] > 0)
            .map(|k| {
                let p2: f64 = s.momentum[k].iter().map(|p| p * p).sum();
                0.5 * (s.fluctuation[k] + p2 / s.mass[k])
            })
            .sum()
    };
    let heat_capacity = c.base.material.C;
    let thermal = |s: &ClassSums| heat_capacity * s.mass_temperature.iter().sum::<f64>();
    let l = &r.ledger;
    let (k0, k1) = (kinetic(&r.start), kinetic(&r.end));
    let dk = k1 - k0 - (l.force_work - l.impact_dissipation);
    assert!(l.impact_dissipation > 0.0 && l.force_work != 0.0);
    assert!(
        dk.abs() <= 1e-9 * (k0 + l.impact_dissipation + l.force_work_turnover),
        "kinetic: {dk:e} of {k0:e}"
    );
    let (t0, t1) = (thermal(&r.start), thermal(&r.end));
    let dt_heat = t1
        - t0
        - (l.impact_dissipation + l.reaction_heat - l.fracture_energy - l.cooling_loss
            + l.external_heat);
    assert!(
        dt_heat.abs() <= 1e-12 * t0,
        "thermal: {dt_heat:e} of {t0:e}"
    );
}

#[test]
fn bad_input_is_refused_naming_the_cell_and_the_field() {
    let c = coupling(300, 2);
    let good = monomers(&c, 0.02, 1e-4);
    let m0 = c.primary().1;
    type Change = fn(&mut CellInput, f64);
    let cases: [(Change, &str); 9] = [
        (
            |i, _| i.classes[2].number_density = -1.0,
            "cell 17: classes[2].number_density = -1 (must be ≥ 0",
        ),
        (
            |i, _| i.classes[0].number_density = f64::NAN,
            "cell 17: classes[0].number_density = NaN",
        ),
        (
            |i, _| i.classes[0].number_density = 0.0,
            "cell 17: classes[*].number_density = 0 in every class",
        ),
        (|i, _| i.dt = 0.0, "cell 17: dt = 0e0 (must be > 0"),
        (|i, _| i.dt = -1e-3, "cell 17: dt = -1e-3"),
        (
            |i, _| i.classes[0].velocity[1] = f64::INFINITY,
            "cell 17: classes[0].velocity[1] = inf",
        ),
        (
            |i, _| i.classes.truncate(3),
            "cell 17: classes = 3 classes (must be 5",
        ),
        (
            |i, m0| {
                // One class of bodies 1e5 primaries heavy: radius 46 b0, in a box of 300
                // monomers whose side is about 34 b0, at three bodies per box (not a trace).
                i.classes[4].number_density = i.classes[0].number_density / 100.0;
                i.classes[4].mass = 1e5 * m0;
            },
            "too large for the box",
        ),
        (
            |i, _| i.gas.temperature = -5.0,
            "cell 17: gas.temperature = -5",
        ),
    ];
    for (change, expected) in cases {
        let mut input = good.clone();
        change(&mut input, m0);
        let e = advance_cell(&c, 17, 0, &input, None).unwrap_err();
        assert!(
            e.to_string().contains(expected),
            "got `{e}`, expected `{expected}`"
        );
        assert_eq!(e.cell(), Some(17));
    }
    // In a batch, the bad cell is refused and the good ones advance.
    let mut bad = good.clone();
    bad.classes[1].number_density = -2.0;
    let cells = vec![
        (1, good.clone(), None),
        (2, bad, None),
        (3, good.clone(), None),
    ];
    let results = advance_cells(&c, 0, &cells, &Workers::local(2));
    assert!(results[0].is_ok() && results[2].is_ok());
    let e = results[1].as_ref().unwrap_err().to_string();
    assert!(e.contains("cell 2: classes[1].number_density = -2"), "{e}");
    // A state is another cell's, or damaged.
    let (_, state) = advance_cell(&c, 1, 0, &good, None).unwrap();
    let e = advance_cell(&c, 5, 1, &good, Some(&state))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cell 5: state: it is cell 1's state"), "{e}");
    let mut bytes = state.to_bytes();
    bytes.truncate(3);
    assert!(CellState::from_bytes(&bytes).is_err());
    // Flat arrays of the wrong length.
    let e = CellInput::from_columns(
        17,
        &[1.0; 5],
        &[m0; 5],
        &[0.0; 6],
        &[300.0; 5],
        &[1.0; 5],
        None,
        good.gas,
        1e-4,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("cell 17: velocity = 6 values (must be 15"),
        "{e}"
    );
    // A bad coupling names its field.
    let mut c2 = c.clone();
    c2.edges[2] = c2.edges[1];
    let e = advance_cell(&c2, 1, 0, &good, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("coupling: edges[2]"), "{e}");
}

#[test]
fn a_target_standard_error_sizes_the_box() {
    // φ = 0.01 monomers over 1e-4 s, 10 % wanted on the impact rate from K = 16
    // boxes: the boxes should expect 1/0.1² = 100 impacts in all, so the measured
    // relative SE of the impact rate (Poisson, independent impacts) comes out near
    // 10 %. Allowed 6–16 %: the SE of 16 replicas is itself uncertain by about
    // 1/√(2·15) = 18 %, so this is about ±2.5 of its own errors.
    let mut c = coupling(1, 16);
    c.bodies = BoxSize::TargetSe {
        relative: 0.1,
        min_bodies: 10,
        max_bodies: 100_000,
    };
    let input = monomers(&c, 0.01, 1e-4);
    let (out, _) = advance_cell(&c, 8, 0, &input, None).unwrap();
    let n = input.classes[0].number_density;
    let expected_impacts = expected_impact_density(&c, &input) * out.box_volume * 16.0;
    assert!(
        (expected_impacts - 100.0).abs() < 1.0,
        "the box expects {expected_impacts} impacts, not 100"
    );
    assert!((out.bodies.mean - n * out.box_volume).abs() < 5.0 * out.bodies.mean.sqrt());
    let relative = out.impact_rate.se / out.impact_rate.mean;
    assert!(
        (0.06..0.16).contains(&relative),
        "relative SE {relative:.3} of the impact rate, wanted about 0.1"
    );
    // Clamped: a ceiling of 100 bodies wins over the target.
    c.bodies = BoxSize::TargetSe {
        relative: 0.1,
        min_bodies: 10,
        max_bodies: 100,
    };
    assert!((box_volume(&c, 8, &input).unwrap() * n - 100.0).abs() < 1e-9);
}

#[test]
fn kept_cells_in_a_batch_are_the_same_bytes_on_1_and_2_threads() {
    let mut c = coupling(150, 2);
    c.keep_bodies = true;
    let mut runs = Vec::new();
    for threads in [1, 2] {
        let mut cells: Vec<(u64, CellInput, Option<CellState>)> = (0..3u64)
            .map(|id| (id, monomers(&c, 0.03, 2e-4), None))
            .collect();
        let mut bytes = Vec::new();
        for step in 0..2 {
            let results = advance_cells(&c, step, &cells, &Workers::local(threads));
            for (cell, r) in cells.iter_mut().zip(results) {
                let (o, s) = r.unwrap();
                bytes.push((o.to_bytes(), s.to_bytes()));
                cell.2 = Some(s);
            }
        }
        // The second step continued the boxes: their clocks ran on.
        assert_eq!(cells[0].2.as_ref().unwrap().time(), 4e-4);
        runs.push(bytes);
    }
    assert!(
        runs[0] == runs[1],
        "kept cells differ between 1 and 2 threads"
    );
}

#[test]
fn the_stepped_core_advances_cells_too() {
    // Fixed steps select the stepped core (docs/model.md §4); kept boxes resume there
    // as well, and a gas that changes between steps is taken up.
    let mut c = coupling(150, 2);
    c.base.time.stepping = agglo::scenario::Stepping::Fixed { dt: 1e-5 };
    c.keep_bodies = true;
    assert!(!c.base.uses_event_core());
    let mut input = monomers(&c, 0.03, 2e-4);
    let (first, state) = advance_cell(&c, 2, 0, &input, None).unwrap();
    input.gas.drag = Some(agglo_engine::field::Relaxation::Constant { tau: 1e-3 });
    input.gas.velocity = [2.0, 0.0, 0.0];
    let (second, state) = advance_cell(&c, 2, 1, &input, Some(&state)).unwrap();
    assert_eq!(state.macro_steps(), 2);
    assert!(first.impact_rate.mean > 0.0 && second.impact_rate.mean > 0.0);
    for out in [&first, &second] {
        let sum: f64 = out.classes.iter().map(|k| k.mass_rate.mean).sum();
        let scale: f64 = out.classes.iter().map(|k| k.mass_rate.mean.abs()).sum();
        assert!(sum.abs() <= 1e-12 * scale, "{sum:e} of {scale:e}");
    }
    // No drag in the first step, a strong one (τ = 1 ms, u = 2 m/s) in the second.
    assert_eq!(first.gas_momentum_rate[0].mean, 0.0);
    assert!(second.gas_momentum_rate[0].mean < -5.0 * second.gas_momentum_rate[0].se);
}
