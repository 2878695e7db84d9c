//! `agglo::subgrid` without bias (issue 37): Poisson class counts and independent
//! velocities make a lifted box's pair rates the cell's; restriction hands back
//! unbiased class variances, "not measured" where a class held one body, Poisson floors
//! on count rates, and energy rates that close; traces are ignored, not refused.

use agglo::prelude::*;
use agglo::subgrid::*;

use crate::subgrid::{coupling, monomers};

use std::f64::consts::PI;

/// ⟨|v_a − v_b|⟩ of two Maxwellians of variances `ta`, `tb` per component at one mean.
fn mean_relative_speed(ta: f64, tb: f64) -> f64 {
    (8.0 * (ta + tb) / PI).sqrt()
}

/// `input` with class densities in the proportions `lambda` (the same total), so that a
/// box of N = Σλ bodies expects λ_k bodies of class k.
fn expecting(mut input: CellInput, lambda: &[f64]) -> CellInput {
    let total: f64 = input.classes.iter().map(|k| k.number_density).sum();
    let sum: f64 = lambda.iter().sum();
    for (k, l) in input.classes.iter_mut().zip(lambda) {
        k.number_density = total * l / sum;
    }
    input
}

#[test]
fn a_step_without_impacts_hands_back_each_class_temperature() {
    // Classes expecting 276.98, 16, 4, 2 and 0.02 bodies per box (N = 299; before issue
    // 37 the lift subtracted each class's sample mean and restriction divided by M, and
    // 277, 16, 4, 2 bodies came back at 0.992, 0.959, 0.750, 0.517 of T_in and a
    // one-body class at 0 ± 0). Each class at its own T, so that a mix-up shows. Δt =
    // 1e-9 s is 2e-6 of a monomer's free time: no impact, so what comes back is what
    // lifting put in, through restriction. K = 128 boxes: the 2-body class is measured
    // in about 75 of them, to about 10 % (a Bessel estimate from two bodies scatters by
    // √(2/3)), which resolves the old halving many times over.
    let mut c = coupling(299, 128);
    c.replicas = 128;
    let t_in = [1.0, 0.5, 2.0, 1.5, 0.7];
    let mut input = expecting(monomers(&c, 0.05, 1e-9), &[276.98, 16.0, 4.0, 2.0, 0.02]);
    for (k, class) in input.classes.iter_mut().enumerate() {
        class.granular_temperature = t_in[k];
        class.velocity = [0.3 * k as f64, -0.1, 0.0];
    }
    let (out, _) = advance_cell(&c, 37, 0, &input, None).unwrap();
    assert_eq!(out.impact_rate.mean, 0.0, "an impact: not a step without");
    for (k, o) in out.classes.iter().enumerate().take(4) {
        let t = o.granular_temperature;
        assert!(o.granular_replicas >= 40, "class {k}: {o:?}");
        assert!(t.se > 0.0 && t.se < 0.15 * t_in[k], "class {k}: {t:?}");
        assert!(
            (t.mean - t_in[k]).abs() <= 3.0 * t.se,
            "class {k}: T = {} ± {}, T_in {}",
            t.mean,
            t.se,
            t_in[k]
        );
        // Counts and mean velocities: the lift's noise, inside its own error bars.
        let n = o.number_density;
        let want = input.classes[k].number_density;
        assert!(
            (n.mean - want).abs() <= 3.0 * n.se,
            "class {k}: n {n:?} vs {want:e}"
        );
        for x in 0..3 {
            let v = o.velocity[x];
            let u = input.classes[k].velocity[x];
            assert!(
                (v.mean - u).abs() <= 3.0 * v.se,
                "class {k}: v[{x}] {v:?} vs {u}"
            );
        }
    }
    // The class expecting 0.02 bodies: held by a few boxes, never by two bodies in one.
    let one = &out.classes[4];
    assert!(one.present >= 1, "the trace class was never drawn: {one:?}");
    assert_eq!(one.granular_replicas, 0);
    assert!(one.granular_temperature.mean.is_nan() && one.granular_temperature.se.is_nan());
    // 0.02 bodies per box is rare, not a trace (below 1e-3): it was lifted.
    assert!(!one.ignored && !out.classes.iter().any(|k| k.ignored));
}

#[test]
fn poisson_counts_make_every_pair_rate_unbiased_at_the_first_instant() {
    // At the first instant a box's impact rate between classes i and j is proportional
    // to its pairs: N_i N_j, or N_i (N_i − 1)/2 within a class. Poisson counts give
    // E[N_i N_j] = λ_i λ_j and E[N_i (N_i − 1)] = λ_i² exactly; random rounding (the
    // lift before issue 37) gives λ² − λ + f(1 − f): −70 %, −36 %, −10 %, −2.5 % at
    // these λ. 200 000 draws of the lift's own counts resolve each to a few 0.1 %.
    let lambda = [0.3, 2.5, 10.0, 40.0];
    let draws = 200_000u32;
    let mut first = vec![Vec::new(); 4];
    let mut pairs = vec![Vec::new(); 4];
    let mut cross = Vec::new();
    for r in 0..draws {
        let n: Vec<f64> = draw_counts(replica_seed(37, 1, 2, r), &lambda)
            .into_iter()
            .map(|x| x as f64)
            .collect();
        for k in 0..4 {
            first[k].push(n[k]);
            pairs[k].push(n[k] * (n[k] - 1.0));
        }
        cross.push(n[0] * n[3]);
    }
    for (k, &l) in lambda.iter().enumerate() {
        let (mean, square) = (Stat::of(&first[k]), Stat::of(&pairs[k]));
        assert!(
            (mean.mean - l).abs() <= 3.0 * mean.se,
            "E N = {mean:?}, λ {l}"
        );
        let rounding_bias = l - (l - l.floor()) * (1.0 - (l - l.floor()));
        assert!(
            (square.mean - l * l).abs() <= 3.0 * square.se && 3.0 * square.se < rounding_bias,
            "E N(N − 1) = {square:?}, λ² = {}",
            l * l
        );
    }
    let c = Stat::of(&cross);
    assert!((c.mean - 12.0).abs() <= 3.0 * c.se, "E N_0 N_3 = {c:?}, 12");
}

/// Σ |v_a − v_b| over the pairs of a lifted box between the bodies of mass `ma` and
/// those of mass `mb` (each pair once when they are the same class).
fn pair_speed_sum(s: &Scenario, ma: f64, mb: f64) -> f64 {
    let of = |m: f64| -> Vec<[f64; 3]> {
        s.cloud
            .bodies
            .iter()
            .filter(|b| b.mass == Some(m))
            .map(|b| b.velocity.expect("lifted bodies have velocities"))
            .collect()
    };
    let (a, b) = (of(ma), of(mb));
    let d = |p: &[f64; 3], q: &[f64; 3]| (0..3).map(|x| (p[x] - q[x]).powi(2)).sum::<f64>().sqrt();
    if ma == mb {
        (0..a.len())
            .flat_map(|i| (0..i).map(move |j| (i, j)))
            .map(|(i, j)| d(&a[i], &a[j]))
            .sum()
    } else {
        a.iter().flat_map(|p| b.iter().map(move |q| d(p, q))).sum()
    }
}

#[test]
fn a_lifted_box_gives_its_pairs_the_cells_relative_speeds() {
    // A box's first-instant impact rate between two classes is π σ² Σ_pairs |Δv| / V
    // (uniform positions): against the cell's λ_a λ_b ⟨|Δv|⟩ / V this ratio is the
    // lift's bias of the kernel at the first instant, with no run in between.
    // examples/lifting_bias.py measures it for the old lift (random rounding, sample mean
    // subtracted): 0.814 ± 0.004 for 20-mers at 1.5 per box among 298.5 monomers, 0.900
    // ± 0.001 for monomer pairs in boxes of 10 (the dynamic runs: 0.806 ± 0.018
    // and 0.908).
    let mut c = coupling(300, 1);
    let m0 = c.primary().1;
    let mut input = expecting(monomers(&c, 0.05, 1e-4), &[298.5, 0.0, 0.0, 0.0, 1.5]);
    input.classes[4].mass = 20.0 * m0;
    let volume = box_volume(&c, 1, &input).unwrap();
    let lifts = 4000u32;
    let ratios: Vec<f64> = (0..lifts)
        .map(|r| {
            let s = lift(&c, 1, &input, volume, replica_seed(5, 1, 0, r)).unwrap();
            pair_speed_sum(&s, 20.0 * m0, m0) / (1.5 * 298.5 * mean_relative_speed(1.0, 1.0))
        })
        .collect();
    let collector = Stat::of(&ratios);
    // 3 SE: about 4 %, which tells 1 from 0.81.
    assert!(collector.se < 0.02, "{collector:?}");
    assert!(
        (collector.mean - 1.0).abs() <= 3.0 * collector.se,
        "collector-monomer pairs: {collector:?} of the cell's"
    );

    // Monomer pairs in boxes of 10 bodies: the diagonal's λ²/2 pairs.
    c.bodies = BoxSize::Bodies(10);
    let small = monomers(&c, 0.05, 1e-4);
    let volume = box_volume(&c, 2, &small).unwrap();
    let ratios: Vec<f64> = (0..20_000u32)
        .map(|r| {
            let s = lift(&c, 2, &small, volume, replica_seed(5, 2, 0, r)).unwrap();
            pair_speed_sum(&s, m0, m0) / (0.5 * 100.0 * mean_relative_speed(1.0, 1.0))
        })
        .collect();
    let pairs = Stat::of(&ratios);
    assert!(pairs.se < 0.01, "{pairs:?}");
    assert!(
        (pairs.mean - 1.0).abs() <= 3.0 * pairs.se,
        "monomer pairs in boxes of 10: {pairs:?} of the cell's"
    );
}

/// The BMCSL contact value g_ij of a hard-sphere mixture of number densities `n` [1/m³]
/// and diameters `d` [m] (Boublík, Mansoori, Carnahan, Starling, Leland 1971).
fn bmcsl(n: &[f64], d: &[f64], i: usize, j: usize) -> f64 {
    let xi = |l: i32| PI / 6.0 * n.iter().zip(d).map(|(n, d)| n * d.powi(l)).sum::<f64>();
    let (x2, x3) = (xi(2), xi(3));
    let h = d[i] * d[j] / (d[i] + d[j]);
    1.0 / (1.0 - x3)
        + 3.0 * x2 * h / (1.0 - x3).powi(2)
        + 2.0 * (x2 * h).powi(2) / (1.0 - x3).powi(3)
}

/// The dynamic check: the kernel between 20-mer collectors (1.5 per box) and
/// monomers at φ = 0.05, T = 1, measured over 0.1 τ0 in boxes of N = 300, against the
/// ballistic kernel with the BMCSL contact value. Slow in a debug build (20 000 boxes
/// for a 1 % SE): `AGGLO_COLLECTOR_BOXES=2000 cargo test --test suite
/// rare_collector -- --ignored --nocapture` for a quicker, wider figure.
#[test]
#[ignore = "thousands of boxes; run by hand (docs/coupling.md quotes its figure)"]
fn rare_collector_kernel_at_n_300_is_the_ballistic_kernel() {
    let boxes: u32 = std::env::var("AGGLO_COLLECTOR_BOXES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000);
    let mut c = coupling(300, boxes);
    c.kernel = true;
    let (b0, m0) = c.primary();
    let tau0 = 5.2e-4; // the monomer free time at φ = 0.05, T = 1 (issue 37)
    let mut input = expecting(monomers(&c, 0.05, 0.1 * tau0), &[298.5, 0.0, 0.0, 0.0, 1.5]);
    input.classes[4].mass = 20.0 * m0;
    let (out, _) = advance_cell(&c, 3, 0, &input, None).unwrap();
    let acc = out.kernel.as_ref().unwrap();
    let p = 4; // pair (class 0, class 4), row-major, i ≤ j
    let (count, exposure) = (acc.pooled.total(p) as f64, acc.pooled.exposure[p]);
    let measured = count / exposure;
    let se = count.sqrt() / exposure;
    let b20 = b0 * 20f64.cbrt();
    let n: Vec<f64> = input.classes.iter().map(|k| k.number_density).collect();
    let d: Vec<f64> = [1.0, 2.0, 3.0, 5.0, 20.0]
        .map(|s: f64| 2.0 * b0 * s.cbrt())
        .to_vec();
    let g = bmcsl(&n, &d, 0, 4);
    let ballistic = PI * (b0 + b20).powi(2) * mean_relative_speed(1.0, 1.0) * g;
    eprintln!(
        "rare collector, N = 300, {boxes} boxes: {count} impacts, kernel / ballistic·g(BMCSL {g:.4}) = {:.4} ± {:.4}",
        measured / ballistic,
        se / ballistic
    );
    assert!((measured / ballistic - 1.0).abs() <= 0.03 + 3.0 * se / ballistic);
}

/// P04's cell (scenarios/paper2004_best.json: monomers at volume fraction 0.26, v̄ =
/// (10, 10, 100) m/s, its velocity variance lifted as an isotropic 3866 m²/s²), classes
/// of 1, 2, 3–4, …, 33–64, 65+ primaries, boxes of N bodies.
fn p04(bodies: u32, replicas: u32, dt: f64) -> (Coupling, CellInput) {
    let base = Scenario::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper2004_best.json"),
    )
    .unwrap();
    let side = 2.0 * base.domain.half_width;
    let n = base.cloud.count as f64 / side.powi(3);
    let theta0 = base.material.theta0;
    let v_rel = base.cloud.v_rel.unwrap();
    let tg = v_rel.iter().map(|v| v * v / 3.0).sum::<f64>() / 3.0;
    let v_mean = base.cloud.v_mean;
    let m0 = base.primary_mass();
    let edges = [0.5, 1.5, 2.5, 4.5, 8.5, 16.5, 32.5, 64.5, 1e6]
        .map(|x| x * m0)
        .to_vec();
    let mut c = Coupling::new(base, edges).unwrap();
    c.bodies = BoxSize::Bodies(bodies);
    c.replicas = replicas;
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
    let gas = GasState {
        velocity: [0.0; 3],
        temperature: theta0,
        drag: None,
    };
    (c, CellInput { classes, gas, dt })
}

/// The mean-flow energy density ½|p|²/ρ [J/m³] a solver holds for a class.
fn mean_flow(rho: f64, p: [f64; 3]) -> f64 {
    if rho > 0.0 {
        0.5 * p.iter().map(|x| x * x).sum::<f64>() / rho
    } else {
        0.0
    }
}

/// A solver's energy balances over one step [W/m³]: its kinetic energy change
/// Σ_k(mean-flow change + fluctuation_energy_rate), its thermal energy change
/// Σ_k thermal_energy_rate, and the granular energy change it would see updating
/// T_k from class_granular_temperature instead, G = 1.5 ρ T (with its standard error).
fn balances(input: &CellInput, out: &CellOutput) -> (f64, f64, Stat) {
    let dt = input.dt;
    let (mut kinetic, mut thermal, mut intensive, mut var) = (0.0, 0.0, 0.0, 0.0);
    for (k, o) in input.classes.iter().zip(&out.classes) {
        let rho0 = k.number_density * k.mass;
        let p0 = k.velocity.map(|u| rho0 * u);
        let rho1 = rho0 + dt * o.mass_rate.mean;
        let p1 = [0, 1, 2].map(|x| p0[x] + dt * o.momentum_rate[x].mean);
        let mean_flow_rate = (mean_flow(rho1, p1) - mean_flow(rho0, p0)) / dt;
        kinetic += mean_flow_rate + o.fluctuation_energy_rate.mean;
        thermal += o.thermal_energy_rate.mean;
        let g0 = 1.5 * rho0 * k.granular_temperature;
        let (g1, se) = if o.granular_replicas > 0 {
            let t = o.granular_temperature;
            (1.5 * rho1 * t.mean, 1.5 * rho1 * t.se)
        } else {
            (0.0, 0.0)
        };
        // Against the transported one, G + Δt·rate.
        intensive += (g1 - g0) / dt - o.fluctuation_energy_rate.mean;
        var += (se / dt).powi(2);
    }
    (
        kinetic,
        thermal,
        Stat {
            mean: intensive,
            se: var.sqrt(),
        },
    )
}

#[test]
fn granular_and_thermal_energy_close_per_step_at_the_p04_cell() {
    // A solver that transports per class ρ_k, p_k, the granular energy G_k = ½ρ_k·3T_k
    // and the thermal energy C ρ_k θ_k, and adds Δt times the handed-back rates, must
    // see its kinetic energy Σ(½|p_k|²/ρ_k + G_k) change by (F − D)Δt and its thermal
    // energy by (D + R − Z − L)Δt, whatever Δt: the impact dissipation D moves from one
    // to the other. Checked to 1e-3 of D (the bar; before issue 37 no energy
    // rate was handed back, and updating T_k from class_granular_temperature lost
    // 18–23 % of D at Δt = 1e-7 s and 64 % at 3e-8 s). Measured: 4e-14 D (kinetic) and
    // 6e-7 D (thermal: its sums are ~2e9 D at P04's reaction heat), rounding.
    for dt in [1e-6, 1e-7, 3e-8] {
        let (c, input) = p04(300, 4, dt);
        let (out, _) = advance_cell(&c, 2004, 0, &input, None).unwrap();
        let d = out.dissipation_rate.mean;
        assert!(d > 0.0, "Δt = {dt:e}: no dissipation");
        let (kinetic, thermal, _) = balances(&input, &out);
        let work = out.force_work_rate.mean - d;
        let heat = d + out.reaction_heat_rate.mean
            - out.fracture_energy_rate.mean
            - out.heat_loss_rate.mean;
        eprintln!(
            "P04 cell, Δt = {dt:e} s: kinetic gap {:.2e} D, thermal gap {:.2e} D",
            (kinetic - work) / d,
            (thermal - heat) / d,
        );
        assert!(
            (kinetic - work).abs() <= 1e-3 * d,
            "Δt = {dt:e}: kinetic {kinetic:e} vs {work:e}"
        );
        assert!(
            (thermal - heat).abs() <= 1e-3 * d,
            "Δt = {dt:e}: thermal {thermal:e} vs {heat:e}"
        );
    }
}

/// A measurement, not a check: over 64 P04 cells per Δt, how far a solver that updates
/// T_k from class_granular_temperature (instead of transporting G_k with the energy
/// rates) strays per step, as a fraction of the step's dissipation, mean ± SE over the
/// cells. `cargo test --test suite granular_energy_from_class -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement for docs/coupling.md"]
fn granular_energy_from_class_temperatures_per_step() {
    for dt in [1e-6, 1e-7, 3e-8] {
        let (c, input) = p04(300, 4, dt);
        let (mut gaps, mut dissipation) = (Vec::new(), Vec::new());
        for cell in 0..64 {
            let (out, _) = advance_cell(&c, cell, 0, &input, None).unwrap();
            gaps.push(balances(&input, &out).2.mean);
            dissipation.push(out.dissipation_rate.mean);
        }
        let (g, d) = (Stat::of(&gaps), Stat::of(&dissipation));
        eprintln!(
            "Δt = {dt:e} s: granular energy from class temperatures − transported = \
             ({:.4} ± {:.4}) D per step",
            g.mean / d.mean,
            g.se / d.mean
        );
    }
}

#[test]
fn count_rates_have_a_poisson_floor_and_nan_where_nothing_is_known() {
    // Replicas that agree: the spread is 0, the Poisson floor √(Σ counts)·scale/K is not.
    let scale = 2.0;
    let s = Stat::of_counts(&[6.0, 6.0, 6.0, 6.0], &[3.0, 3.0, 3.0, 3.0], scale);
    assert_eq!(s.mean, 6.0);
    assert!((s.se - 12f64.sqrt() * 2.0 / 4.0).abs() < 1e-12, "{s:?}");
    // A spread above the floor is kept.
    let s = Stat::of_counts(&[0.0, 20.0], &[0.0, 10.0], scale);
    assert!((s.se - 10.0).abs() < 1e-12, "{s:?}");
    // No count anywhere: the mean is 0, its error unknown. One replica: unknown.
    assert!(
        Stat::of_counts(&[0.0, 0.0, 0.0], &[0.0; 3], scale)
            .se
            .is_nan()
    );
    assert!(Stat::of_counts(&[4.0], &[2.0], scale).se.is_nan());
    // No replica at all: not measured.
    assert!(Stat::of(&[]).mean.is_nan());

    // In a cell: the impact rate's error is never below √(impacts)/(K V Δt).
    let c = coupling(200, 4);
    let input = monomers(&c, 0.05, 1e-5);
    let (out, _) = advance_cell(&c, 6, 0, &input, None).unwrap();
    let per = 1.0 / (out.box_volume * out.dt);
    let impacts = out.impact_rate.mean / per * 4.0;
    assert!(impacts > 0.0, "no impact to count");
    assert!(out.impact_rate.se >= impacts.sqrt() * per / 4.0 * (1.0 - 1e-12));
    // Classes no box holds at the end (3–4, 5–8, 9+ over 1e-5 s): density 0, error
    // unknown, state not measured.
    let empty = &out.classes[4];
    assert_eq!(
        (empty.present, empty.number_density.mean),
        (0, 0.0),
        "{empty:?}"
    );
    assert!(empty.number_density.se.is_nan() && empty.velocity[0].mean.is_nan());
}

#[test]
fn traces_are_ignored_and_a_target_se_box_always_fits() {
    // Monomers at φ = 0.01 and 1000-mers at 1e-12 of their number density (3e-9 per
    // box expected): the 1000-mers (radius 10 b0) do not fit a box of 300 monomers, and
    // before issue 37 the cell was refused for them.
    let c = coupling(300, 2);
    let m0 = c.primary().1;
    let mut input = monomers(&c, 0.01, 1e-4);
    input.classes[4].number_density = 1e-12 * input.classes[0].number_density;
    input.classes[4].mass = 1000.0 * m0;
    let (out, _) = advance_cell(&c, 8, 0, &input, None).unwrap();
    assert!(out.classes[4].ignored && !out.classes[0].ignored);
    assert_eq!(
        out.columns()
            .iter()
            .find(|k| k.name == "ignored")
            .unwrap()
            .mean[4],
        1.0
    );
    // At three bodies per box it is a class, and a box of 300 cannot hold it.
    input.classes[4].number_density = 0.01 * input.classes[0].number_density;
    let e = advance_cell(&c, 8, 0, &input, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("classes[4].mass") && e.contains("raise N"),
        "{e}"
    );

    // A target SE that asks for a box of ~24 bodies (φ = 0.05, Δt = 1e-4 s, 50 % from
    // K = 2), with 40-mers (radius 3.4 b0) at 1 % of the monomers: the box is raised
    // to one the 40-mers fit (about 250 bodies) instead of being refused.
    let mut c = coupling(1, 2);
    c.bodies = BoxSize::TargetSe {
        relative: 0.5,
        min_bodies: 10,
        max_bodies: 100_000,
    };
    let mut input = monomers(&c, 0.05, 1e-4);
    input.classes[4].number_density = 0.01 * input.classes[0].number_density;
    input.classes[4].mass = 40.0 * m0;
    let volume = box_volume(&c, 9, &input).unwrap();
    let b40 = c.primary().0 * 40f64.cbrt();
    assert!(2.0 * b40 <= MAX_DIAMETER_PER_SIDE * volume.cbrt());
    let n: f64 = input.classes.iter().map(|k| k.number_density).sum();
    assert!(
        (200.0..300.0).contains(&(n * volume)),
        "{} bodies",
        n * volume
    );
    let (out, _) = advance_cell(&c, 9, 0, &input, None).unwrap();
    assert_eq!(out.box_volume, volume);
    // Unless the caller's ceiling forbids it: then the error names the ceiling.
    c.bodies = BoxSize::TargetSe {
        relative: 0.5,
        min_bodies: 10,
        max_bodies: 100,
    };
    let e = advance_cell(&c, 9, 0, &input, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bodies.max_bodies = 100") && e.contains("raise max_bodies"),
        "{e}"
    );
}

/// The spread of identical cells' means over the RMS of their reported SEs, per figure
/// (1 when the SE is honest about replica noise; its own relative SE is about
/// 1/√(2(cells − 1)), 3.5 % over 400 cells).
/// A figure of a cell's output, by name.
type Figure<'a> = (&'a str, fn(&CellOutput) -> Stat);

fn se_calibration(outs: &[CellOutput], figures: &[Figure]) -> Vec<f64> {
    figures
        .iter()
        .map(|(name, figure)| {
            let stats: Vec<Stat> = outs.iter().map(figure).collect();
            let means: Vec<f64> = stats.iter().map(|s| s.mean).collect();
            let spread = Stat::of(&means).se * (means.len() as f64).sqrt();
            let rms = (stats.iter().map(|s| s.se * s.se).sum::<f64>() / stats.len() as f64).sqrt();
            eprintln!("  {name:28}: spread / RMS SE = {:.3}", spread / rms);
            spread / rms
        })
        .collect()
}

#[test]
fn the_fluctuation_energy_rate_s_se_is_calibrated_at_p04_s_cell() {
    // Issue 37: its SE was the kinetic energy rate's, and over identical P04 cells the
    // spread of the means was 0.58 of it (400 cells); it is now its own (the delta
    // method, restrict.rs), 1.02 over 400 cells (docs/coupling.md). Here 200 cells
    // (1.06): the ratio's own relative SE is about 1/√(2·199) = 5 % for Gaussian cell
    // means, more for P04's skewed ones (80 cells gave 1.19), so 0.8–1.25 allows about
    // ±4 of those, and 0.58 is 8 below 1.
    let (mut c, input) = p04(300, 8, 1e-5);
    c.persist = false;
    let outs: Vec<CellOutput> = (0..200)
        .map(|cell| advance_cell(&c, 40_000 + cell, 0, &input, None).unwrap().0)
        .collect();
    let figures: [Figure; 1] = [("fluctuation energy rate, 0", |o| {
        o.classes[0].fluctuation_energy_rate
    })];
    let ratio = se_calibration(&outs, &figures)[0];
    assert!((0.8..1.25).contains(&ratio), "spread / RMS SE = {ratio}");
}

/// A measurement for docs/coupling.md (issue 37 item 5, re-measured with the Poisson
/// lift): 400 identical cells, each its own seeds, spread of the cell means ÷ RMS of
/// the reported SE — sticky monomers (φ = 0.05, T = 1, N = 300, Δt = 0.1 τ0) at K = 8
/// and 32, and P04's cell (N = 300, K = 8, Δt = 10 µs). `cargo test --test suite
/// se_calibration -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement for docs/coupling.md (minutes)"]
fn se_calibration_over_400_identical_cells() {
    let figures: [Figure; 7] = [
        ("total number rate", |o| o.total_number_rate),
        ("number rate, class 0", |o| o.classes[0].number_rate),
        ("number rate, class 1", |o| o.classes[1].number_rate),
        ("impact rate", |o| o.impact_rate),
        ("dissipation rate", |o| o.dissipation_rate),
        ("granular temperature, 0", |o| {
            o.classes[0].granular_temperature
        }),
        ("fluctuation energy rate, 0", |o| {
            o.classes[0].fluctuation_energy_rate
        }),
    ];
    for k in [8u32, 32] {
        let c = coupling(300, k);
        let input = monomers(&c, 0.05, 0.1 * 5.2e-4);
        let outs: Vec<CellOutput> = (0..400)
            .map(|cell| advance_cell(&c, 20_000 + cell, 0, &input, None).unwrap().0)
            .collect();
        eprintln!("sticky monomers, φ = 0.05, N = 300, K = {k}, Δt = 0.1 τ0, 400 cells:");
        se_calibration(&outs, &figures);
    }
    let (mut c, input) = p04(300, 8, 1e-5);
    c.persist = false;
    let outs: Vec<CellOutput> = (0..400)
        .map(|cell| advance_cell(&c, 30_000 + cell, 0, &input, None).unwrap().0)
        .collect();
    eprintln!("P04's cell, N = 300, K = 8, Δt = 10 µs, 400 cells:");
    se_calibration(&outs, &figures);
}

#[test]
fn an_anisotropic_class_comes_back_with_its_temperature_tensor() {
    // Issue 37 item 4b: the diagonal T_xx, T_yy, T_zz of each class's granular
    // temperature tensor, lifted and restricted. A step without impacts (Δt = 1e-9 s,
    // as above): what comes back is what lifting drew. Classes of 277 and 16 bodies per
    // box, each with its own split (P04's draw is 10:1:1 in standard deviation, 100:1:1
    // in variance), K = 64: the axes within 3 SE.
    let mut c = coupling(293, 64);
    c.replicas = 64;
    let mut input = expecting(monomers(&c, 0.05, 1e-9), &[277.0, 16.0, 0.0, 0.0, 0.0]);
    input.classes[0].granular_temperature = 2.0;
    input.classes[0].granular_anisotropy = [100.0, 1.0, 1.0];
    input.classes[1].granular_temperature = 0.5;
    input.classes[1].granular_anisotropy = [0.2, 1.0, 3.0];
    let (out, _) = advance_cell(&c, 38, 0, &input, None).unwrap();
    assert_eq!(out.impact_rate.mean, 0.0, "an impact: not a step without");
    for k in 0..2 {
        let want = input.classes[k].granular_temperature_axes();
        let axes = out.classes[k].granular_temperature_axes;
        for x in 0..3 {
            let t = axes[x];
            assert!(
                t.se > 0.0 && t.se < 0.2 * want[x],
                "class {k} axis {x}: {t:?}"
            );
            assert!(
                (t.mean - want[x]).abs() <= 3.0 * t.se,
                "class {k} axis {x}: {} ± {} against {}",
                t.mean,
                t.se,
                want[x]
            );
        }
        // The mean of the axes is the scalar granular temperature.
        let mean = (axes[0].mean + axes[1].mean + axes[2].mean) / 3.0;
        let t = out.classes[k].granular_temperature.mean;
        assert!((mean - t).abs() <= 1e-12 * t, "{mean} vs {t}");
    }
    // The solver's update carries the measured split on.
    let next = apply_rates(&c, &input, &out);
    let a = next.classes[0].granular_anisotropy;
    assert!(a[0] > 20.0 * a[1] && a[0] > 20.0 * a[2], "{a:?}");
    // Bad weights are refused naming the field.
    let mut bad = input.clone();
    bad.classes[1].granular_anisotropy = [0.0, f64::NAN, 1.0];
    let e = advance_cell(&c, 38, 0, &bad, None).unwrap_err().to_string();
    assert!(e.contains("classes[1].granular_anisotropy[1]"), "{e}");
    bad.classes[1].granular_anisotropy = [0.0; 3];
    let e = advance_cell(&c, 38, 0, &bad, None).unwrap_err().to_string();
    assert!(e.contains("classes[1].granular_anisotropy"), "{e}");
}
