//! `agglo::subgrid` cost (issue 32): one cell per macro step at the P04 conditions
//! (scenarios/paper2004_best.json: monomers at volume fraction 0.26, v̄ = (10, 10, 100)
//! m/s, velocity variance (184.7², 18.47², 18.47²)/3 m²/s², i.e. 3866 m²/s² on
//! average) in boxes of 10³ bodies over Δt = 1 ms, one replica, on one core; and its
//! parts: lifting, building the box's simulation, restriction. Before the timings it
//! prints the spread of the growth rate over 16 replicas, from which the standard error
//! for K replicas is s/√K.
//!
//! Run: `cargo bench --bench subgrid`. Figures are in docs/coupling.md.
//!
//! Issue 37's cost goal — a macro step of 256 cells × 8 replicas of 10³-body P04 boxes
//! over 1 ms within 1.1× the boxes' own run time — is measured by [`macro_steps`], run
//! when `AGGLO_MACRO_CELLS` gives the cell count (`AGGLO_MACRO_CELLS=256 cargo bench
//! --bench subgrid -- macro`; it takes about a minute per step at 256 cells on one
//! core; `AGGLO_MACRO_MODES=persist` or `re-lift` runs one of its two modes). It times
//! each part of the step ([`agglo::subgrid::profile`]) in CPU time on one worker
//! thread, so the parts add up to the process's CPU time but for the task farm's own
//! cost, whatever else the machine runs. Each step prints the goal figure ([`goal`])
//! both ways: with building the box's simulation, its calendar (the event core's first
//! prediction of every body) and its teardown counted as the box's own run — a direct
//! run of the box does all three — and counted as overhead.

use std::path::Path;
use std::time::{Duration, Instant};

use agglo::farm::Workers;
use agglo::subgrid::profile::{self, Part};

use agglo::prelude::*;
use agglo::subgrid::*;
use criterion::{Criterion, criterion_group, criterion_main};

const DT: f64 = 1e-3;

fn p04() -> (Coupling, CellInput) {
    let base = Scenario::load(
        &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .join("scenarios")
            .join("paper2004_best.json"),
    )
    .expect("shipped scenario");
    let side = 2.0 * base.domain.half_width;
    let n = base.cloud.count as f64 / side.powi(3);
    let theta0 = base.material.theta0;
    let v_rel = base.cloud.v_rel.expect("P04 gives v_rel");
    let tg = v_rel.iter().map(|v| v * v / 3.0).sum::<f64>() / 3.0;
    let v_mean = base.cloud.v_mean;
    let m0 = 4.0 / 3.0 * std::f64::consts::PI * base.primary_radius().powi(3) * base.material.rho;
    let edges = [0.5, 1.5, 2.5, 4.5, 8.5, 16.5, 32.5, 64.5, 1e6]
        .map(|x| x * m0)
        .to_vec();
    let mut c = Coupling::new(base, edges).expect("coupling");
    c.bodies = BoxSize::Bodies(1000);
    c.replicas = 1;
    c.check().expect("coupling");
    let classes = (0..c.classes())
        .map(|k| ClassInput {
            number_density: if k == 0 { n } else { 0.0 },
            mass: c.edges[k].max(m0),
            velocity: v_mean,
            temperature: theta0,
            granular_temperature: tg,
            granular_anisotropy: ISOTROPIC,
        })
        .collect();
    let input = CellInput {
        classes,
        gas: GasState {
            velocity: [0.0; 3],
            temperature: theta0,
            drag: None,
        },
        dt: DT,
    };
    (c, input)
}

/// The growth rate (1/n) Σ_k dn_k/dt of one cell over 16 replicas, with its standard
/// error, and what the standard error is for K replicas (s/√K, s = SE·√16: the
/// replicas are independent), over Δt = 0.01, 0.1 and 1 ms.
fn spread() {
    for dt in [DT / 100.0, DT / 10.0, DT] {
        let (mut c, mut input) = p04();
        c.replicas = 16;
        input.dt = dt;
        let start = Instant::now();
        let (out, _) = advance_cell(&c, 0, 0, &input, None).expect("cell");
        let seconds = start.elapsed().as_secs_f64();
        let n: f64 = input.classes.iter().map(|k| k.number_density).sum();
        let (rate, se) = (out.total_number_rate.mean / n, out.total_number_rate.se / n);
        let impacts = out.impact_rate.mean * out.box_volume * dt;
        let merged = -out.total_number_rate.mean * out.box_volume * dt;
        eprintln!(
            "P04 cell, N = 1000, Δt = {dt} s, 16 replicas in {seconds:.2} s ({impacts:.0} \
             impacts, {merged:.0} bodies fewer per box): growth rate (1/n) Σ dn_k/dt = \
             {rate:.4e} ± {se:.2e} 1/s"
        );
        let s = se * 4.0;
        for k in [1.0f64, 4.0, 16.0, 64.0] {
            eprintln!(
                "  K = {k:>2}: SE of the growth rate {:.2} % of it",
                100.0 * s / k.sqrt() / rate.abs()
            );
        }
    }
}

fn cells(c: &mut Criterion) {
    if std::env::var_os("AGGLO_MACRO_CELLS").is_some() {
        return; // the macro step alone (module doc)
    }
    spread();
    let (coupling, input) = p04();
    let volume = box_volume(&coupling, 0, &input).unwrap();
    let mut group = c.benchmark_group("subgrid_p04");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("cell N=1000 K=1 dt=1ms", |b| {
        let mut step = 0;
        b.iter(|| {
            step += 1;
            advance_cell(&coupling, 0, step, &input, None).unwrap()
        })
    });
    let short = CellInput {
        dt: DT / 10.0,
        ..input.clone()
    };
    group.bench_function("cell N=1000 K=1 dt=0.1ms", |b| {
        let mut step = 0;
        b.iter(|| {
            step += 1;
            advance_cell(&coupling, 0, step, &short, None).unwrap()
        })
    });
    group.bench_function("lift N=1000", |b| {
        let mut seed = 0;
        b.iter(|| {
            seed += 1;
            lift(&coupling, 0, &input, volume, seed).unwrap()
        })
    });
    let scenario = lift(&coupling, 0, &input, volume, 1).unwrap();
    group.bench_function("validate lifted N=1000", |b| {
        b.iter(|| scenario.validate().unwrap())
    });
    group.bench_function("build box N=1000", |b| {
        b.iter(|| agglo::kernel::simulation(&scenario).unwrap())
    });
    let sim = agglo::kernel::simulation(&scenario).unwrap();
    group.bench_function("restrict N=1000", |b| {
        b.iter(|| ClassSums::of(&coupling, &sim.bodies()))
    });
    group.finish();
}

/// 10 % of the held state `held` replaced by the fresh input `fresh`, class by class (a
/// stirred cell: n ← 0.9 n + 0.1 n_fresh; the mean velocity and temperatures of a class
/// that gains fresh bodies mixed by number).
fn stirred(held: &CellInput, fresh: &CellInput) -> CellInput {
    let mut out = held.clone();
    for (o, f) in out.classes.iter_mut().zip(&fresh.classes) {
        let (nh, nf) = (0.9 * o.number_density, 0.1 * f.number_density);
        let n = nh + nf;
        if nf > 0.0 && n > 0.0 {
            let (wh, wf) = (nh / n, nf / n);
            o.velocity = [0, 1, 2].map(|x| wh * o.velocity[x] + wf * f.velocity[x]);
            o.granular_temperature = wh * o.granular_temperature + wf * f.granular_temperature;
            o.temperature = wh * o.temperature + wf * f.temperature;
        }
        o.number_density = n;
    }
    out
}

/// A macro step's outputs and states, the process's CPU seconds over it, and each
/// part's CPU seconds ([`Part::ALL`]'s order).
type TimedStep = (
    Vec<(CellOutput, CellState)>,
    f64,
    [(Part, f64); profile::COUNT],
);

/// One macro step of `inputs` (cell i at index i) on one worker thread, timed.
fn timed_step(
    c: &Coupling,
    step: u64,
    inputs: &[CellInput],
    states: Vec<Option<CellState>>,
) -> TimedStep {
    let cells: Vec<_> = inputs
        .iter()
        .cloned()
        .zip(states)
        .enumerate()
        .map(|(i, (input, state))| (i as u64, input, state))
        .collect();
    profile::enable(true);
    profile::reset();
    let start = profile::process_cpu_seconds();
    let results = advance_cells(c, step, &cells, &Workers::local(1));
    let cpu = profile::process_cpu_seconds() - start;
    let parts = profile::seconds();
    let results = results.into_iter().map(|r| r.expect("cell")).collect();
    (results, cpu, parts)
}

/// Issue 37's goal figure for one macro step from its CPU seconds `cpu` and its parts:
/// the coupling's share — lifting, adjusting, restoring kept boxes, restriction,
/// keeping and the coupling's bookkeeping (its own part plus the task farm's, the CPU
/// time no part covers) — against the boxes' own run, and total ÷ run, counted two
/// ways: with building the box's simulation, its calendar (the event core's first
/// prediction of every body) and its teardown as overhead too (`run` alone is the
/// box's run), and with them as the box's own run (a direct run of the box also builds
/// its world, predicts its calendar and frees it). Returns the lines to print.
fn goal(cpu: f64, parts: &[(Part, f64); profile::COUNT]) -> String {
    let of = |part: Part| parts.iter().find(|(p, _)| *p == part).map_or(0.0, |x| x.1);
    let farm = cpu - parts.iter().map(|x| x.1).sum::<f64>();
    let coupling = of(Part::Lift)
        + of(Part::Adjust)
        + of(Part::Restore)
        + of(Part::Restrict)
        + of(Part::Keep)
        + of(Part::Coupling)
        + farm;
    let own = of(Part::Build) + of(Part::Calendar) + of(Part::Teardown);
    let run = of(Part::Run);
    format!(
        "  GOAL (≤ 10 %, ≤ 1.1×), build + calendar + teardown as the box's run: (lift + \
         adjust + restore + restrict + keep + coupling) = {:.1} % of (run + build + \
         calendar + teardown), total ÷ (run + build + calendar + teardown) = {:.3}\n  \
         GOAL, build + calendar + teardown as overhead: (lift + adjust + restore + build + \
         calendar + teardown + restrict + keep + coupling) = {:.1} % of run, total ÷ run = \
         {:.3}",
        100.0 * coupling / (run + own),
        cpu / (run + own),
        100.0 * (coupling + own) / run,
        cpu / run,
    )
}

/// A hash of a step's outputs and next states, all their bytes: the same for two builds
/// whose boxes compute the same bits (printed so that a change meant to cost less can be
/// checked to change nothing else).
fn fingerprint(results: &[(CellOutput, CellState)]) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::hash::DefaultHasher::new();
    for (out, state) in results {
        postcard::to_allocvec(out)
            .expect("an output encodes")
            .hash(&mut h);
        state.to_bytes().hash(&mut h);
    }
    h.finish()
}

fn report(
    label: &str,
    cells: usize,
    c: &Coupling,
    cpu: f64,
    parts: &[(Part, f64); profile::COUNT],
) {
    let run = parts
        .iter()
        .find(|(p, _)| *p == Part::Run)
        .map_or(f64::NAN, |x| x.1);
    let accounted: f64 = parts.iter().map(|x| x.1).sum();
    let farm = cpu - accounted;
    let boxes = cells * c.replicas as usize;
    eprintln!(
        "{label}: {cells} cells × {} replicas in {cpu:.3} s of CPU ({:.3} ms per box)",
        c.replicas,
        1e3 * cpu / boxes as f64,
    );
    eprintln!("{}", goal(cpu, parts));
    let mut line = String::new();
    for (p, t) in parts {
        line += &format!(" {} {:.3} s ({:.2} %),", p.name(), t, 100.0 * t / run);
    }
    line += &format!(" farm {farm:.3} s ({:.2} %)", 100.0 * farm / run);
    eprintln!("  parts, % of the run:{line}");
}

/// Issue 37's cost goal (module doc): `AGGLO_MACRO_CELLS` cells of the P04 input, K =
/// 8, N = 1000, Δt = 1 ms, persistent boxes, `AGGLO_MACRO_REPEATS` times (3): the first
/// step (lifted), a second step whose input is exactly what `apply_rates` left (the
/// boxes resume their snapshots: the closed cell), and a second step with 10 % of each
/// cell stirred in from the fresh input (the boxes adjusted). Then the same first and
/// second steps re-lifting (persist off).
fn macro_steps() {
    let Some(cells) = std::env::var("AGGLO_MACRO_CELLS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    else {
        return;
    };
    let repeats = std::env::var("AGGLO_MACRO_REPEATS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(3);
    // `AGGLO_MACRO_MODES`: "persist", "re-lift" or both (the default).
    let modes = std::env::var("AGGLO_MACRO_MODES").unwrap_or_default();
    let persists: Vec<bool> = [true, false]
        .into_iter()
        .filter(|&p| {
            let name = if p { "persist" } else { "re-lift" };
            modes.is_empty() || modes.split(',').any(|m| m.trim() == name)
        })
        .collect();
    // What the profile's clock costs: each box's parts take about ten readings of its
    // thread's CPU clock (a system call), in the figures below; unprofiled macro steps
    // (the default) do not read it.
    let reads = 100_000;
    let begun = Instant::now();
    let mut sum = 0.0;
    for _ in 0..reads {
        sum += profile::process_cpu_seconds();
    }
    eprintln!(
        "one reading of a CPU clock: {:.2} µs (wall, {reads} readings; checksum {:.0})",
        1e6 * begun.elapsed().as_secs_f64() / reads as f64,
        sum.signum()
    );
    let (mut c, input) = p04();
    c.replicas = 8;
    for repeat in 0..repeats {
        for &persist in &persists {
            c.persist = persist;
            let mode = if persist { "persist" } else { "re-lift" };
            let inputs = vec![input.clone(); cells];
            let (first, cpu, parts) = timed_step(&c, 2 * repeat as u64, &inputs, vec![None; cells]);
            report(
                &format!(
                    "[{repeat}] {mode}, first step (hash {:016x})",
                    fingerprint(&first)
                ),
                cells,
                &c,
                cpu,
                &parts,
            );
            let state_bytes: usize = first.iter().map(|(_, s)| s.to_bytes().len()).sum();
            eprintln!(
                "  states after the first step: {state_bytes} bytes, {:.0} per box",
                state_bytes as f64 / (cells * c.replicas as usize) as f64
            );
            let held: Vec<CellInput> = first
                .iter()
                .zip(&inputs)
                .map(|((out, _), i)| apply_rates(&c, i, out))
                .collect();
            let states: Vec<Option<CellState>> =
                first.iter().map(|(_, s)| Some(s.clone())).collect();
            let (second, cpu, parts) = timed_step(&c, 2 * repeat as u64 + 1, &held, states.clone());
            report(
                &format!(
                    "[{repeat}] {mode}, second step, no transport (hash {:016x})",
                    fingerprint(&second)
                ),
                cells,
                &c,
                cpu,
                &parts,
            );
            let stirred: Vec<CellInput> = held.iter().map(|h| stirred(h, &input)).collect();
            let (after, cpu, parts) = timed_step(&c, 2 * repeat as u64 + 1, &stirred, states);
            report(
                &format!(
                    "[{repeat}] {mode}, second step, 10 % stirred in (hash {:016x})",
                    fingerprint(&after)
                ),
                cells,
                &c,
                cpu,
                &parts,
            );
        }
    }
}

fn macro_group(_: &mut Criterion) {
    macro_steps();
}

criterion_group!(benches, macro_group, cells);
criterion_main!(benches);
