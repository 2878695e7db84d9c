//! Where methods fail (`agglo study stability`).
//!
//! 1. **Pair solve** (docs/model.md §5, §14): two identical spheres head on, over impact
//!    speed (0.05–3 × the critical speed) × a0 ∈ [0, 0.9]. The papers' plain
//!    iteration e_{K+1} = G(e_K) from e_0 = 0 is run with a generous iteration budget
//!    ([`PLAIN_BUDGET`]) to see where it converges and how slowly; the safeguarded
//!    solver is run with the engine's defaults (100 plain iterations, TOL = 1e-12) to
//!    see what it needs there. Without softening the result is checked against the
//!    closed form of §14; at a0 = 0 every sub-critical speed gives the 2-cycle
//!    0 ↔ 1 − λ (|G'(e*)| = 1), which the map must flag.
//! 2. The same with **thermal softening** (α > 0, Q > 0): G then depends on e through
//!    the reaction heat α a_c(e), which softens the contact the more it adheres.
//! 3. **Cooling** (§8): explicit and implicit Euler against the radiative closed form
//!    (hc = 0, θs = 0) over Δt × initial temperature, ten steps each; a run is
//!    flagged *unstable* when a step leaves the physical band (θ must stay in
//!    (0, θ_previous]: a cooling body neither heats nor drops below the far field) or
//!    turns non-finite. The explicit limit 1/(4 k θ³) (`explicit_limit`) is where
//!    forward Euler stops being monotone in the linearisation; with θs = 0 its first
//!    step is θ(1 − r/4), r = Δt / limit, so it leaves the band exactly beyond 4 × the limit.
//! 4. **Step size** (§4): the fraction of collisions a step misses. Kinematically, from
//!    the scene's initial clouds: of the pairs whose ballistic paths touch within Δt,
//!    the fraction not found overlapping-and-approaching at the step's end (they passed
//!    through, or touched and separated). And in whole runs of an elastic version of
//!    the scene (no bonding, merging, heating or cooling): impacts counted under fixed
//!    Δt and step factor c, relative to the resolved run (c = 1), with the seed spread.

use std::path::Path;

use glam::DVec3;

use crate::laws::cooling::{CoolingLaw, radiative_closed_form};
use crate::prelude::*;
use crate::resources::STEFAN_BOLTZMANN;
use crate::scenario::{CoolingMethod, DurationLaw, SolverKind, Stepping};
use crate::systems::impact::{
    FixedPoint, PairBody, PairModel, SolveMethod, closed_form_restitution, critical_speed,
    find_fixed_point, trial,
};

use super::{mean_std, num, write_csv};

/// Iteration budget of the plain iteration in the map (far above the ~28/a0 iterations
/// it needs near the critical speed for a0 ≥ 0.02, so "not converged" means "never").
pub const PLAIN_BUDGET: u32 = 100_000;

/// The pair-map grid.
#[derive(Debug, Clone)]
pub struct PairGrid {
    /// Approach speed of each sphere over the (cold) critical speed.
    pub speed_ratios: Vec<f64>,
    /// Contact-area fractions at full rebound a0.
    pub a0s: Vec<f64>,
}

impl Default for PairGrid {
    fn default() -> Self {
        Self {
            speed_ratios: (1..=60).map(|k| 0.05 * k as f64).collect(),
            a0s: (0..=45).map(|k| 0.02 * k as f64).collect(),
        }
    }
}

/// The pair set-up: 1 mm spheres, ρ = 2000 kg/m³, H0 = 1e4 Pa, af = 1, β = 1, P04
/// duration, θ0 = 300 K, C = 1000 J/(kg K); softening adds α = 3e5 J/m² and
/// Q = 2e4 J/mol (H(300 K) = 3.0 H0; one adhering impact heats each sphere by ~110 K,
/// which softens it about threefold).
#[derive(Debug, Clone, Copy)]
pub struct PairSetup {
    /// Radius [m].
    pub radius: f64,
    /// Density ρ [kg/m³].
    pub rho: f64,
    /// Hardness scale H0 [Pa].
    pub h0: f64,
    /// Temperature θ0 [K].
    pub theta0: f64,
    /// Heat capacity C [J/(kg K)].
    pub heat_capacity: f64,
    /// Reaction heat per contact area α [J/m²].
    pub alpha: f64,
    /// Activation energy Q [J/mol].
    pub activation_energy: f64,
}

impl PairSetup {
    /// The cold pair: no reaction heat, no softening.
    pub fn cold() -> Self {
        Self {
            radius: 1e-3,
            rho: 2000.0,
            h0: 1e4,
            theta0: 300.0,
            heat_capacity: 1000.0,
            alpha: 0.0,
            activation_energy: 0.0,
        }
    }
    /// The softening pair: α = 3e5 J/m², Q = 2e4 J/mol.
    pub fn softening() -> Self {
        Self {
            alpha: 3e5,
            activation_energy: 2e4,
            ..Self::cold()
        }
    }
    fn model(&self, a0: f64, tol: f64, max_iterations: u32, solver: SolverKind) -> PairModel {
        PairModel {
            a0,
            af: 1.0,
            beta: 1.0,
            duration: DurationLaw::P04,
            friction_scales_with_adhesion: false,
            mu0: 0.0,
            alpha: self.alpha,
            heat_capacity: self.heat_capacity,
            h0: self.h0,
            activation_energy: self.activation_energy,
            tol,
            max_iterations,
            solver,
            pair_hardness: Default::default(),
            friction_cap: Default::default(),
            bond_test: Default::default(),
            work_heat: Default::default(),
        }
    }
    /// Hardness at θ0 [Pa].
    pub fn cold_hardness(&self) -> f64 {
        crate::resources::hardness(self.h0, self.activation_energy, self.theta0)
    }
    /// Critical approach speed of each sphere at θ0 [m/s].
    pub fn critical_speed(&self) -> f64 {
        critical_speed(1.0, self.cold_hardness(), 1.0, self.rho)
    }
    fn body(&self, v: DVec3) -> PairBody {
        PairBody {
            mass: 4.0 / 3.0 * std::f64::consts::PI * self.radius.powi(3) * self.rho,
            radius: self.radius,
            velocity: v,
            temperature: self.theta0,
        }
    }
}

/// One cell of the pair map.
#[derive(Debug, Clone, Copy)]
pub struct PairCell {
    /// The cell's contact-area fraction at full rebound a0.
    pub a0: f64,
    /// The approach speed over the cold critical speed.
    pub speed_ratio: f64,
    /// λ = 2 ρ v_p² / (3 H(θ0) β).
    pub lambda: f64,
    /// The papers' plain iteration's result.
    pub plain: FixedPoint,
    /// The safeguarded solve's result.
    pub safeguarded: FixedPoint,
    /// |e − G(e)| at the safeguarded solution.
    pub safeguarded_residual: f64,
    /// The closed-form e* of docs/model.md §14 (no softening only).
    pub closed_form: Option<f64>,
}

impl PairCell {
    /// True when the plain iteration converged.
    pub fn plain_converged(&self) -> bool {
        self.plain.method == SolveMethod::FixedPoint
    }
    /// True when the safeguarded solve found a root (residual ≤ 1e-9).
    pub fn safeguarded_converged(&self) -> bool {
        self.safeguarded.method != SolveMethod::Unconverged && self.safeguarded_residual <= 1e-9
    }
}

/// The pair map over `grid` for `setup`.
pub fn pair_map(setup: &PairSetup, grid: &PairGrid) -> Vec<PairCell> {
    let vc = setup.critical_speed();
    let h = setup.cold_hardness();
    let mut cells = Vec::with_capacity(grid.a0s.len() * grid.speed_ratios.len());
    for &a0 in &grid.a0s {
        for &ratio in &grid.speed_ratios {
            let vp = ratio * vc;
            let (bi, bj) = (setup.body(DVec3::X * vp), setup.body(-DVec3::X * vp));
            let g_of = |model: &PairModel| {
                let model = *model;
                move |e: f64| trial(&model, &bi, &bj, DVec3::X, e).g
            };
            let plain_model = setup.model(a0, 1e-12, PLAIN_BUDGET, SolverKind::Plain);
            let plain = find_fixed_point(&plain_model, g_of(&plain_model));
            let safe_model = setup.model(a0, 1e-12, 100, SolverKind::Safeguarded);
            let g = g_of(&safe_model);
            let safeguarded = find_fixed_point(&safe_model, g);
            let lambda = 2.0 * setup.rho * vp * vp / (3.0 * h);
            cells.push(PairCell {
                a0,
                speed_ratio: ratio,
                lambda,
                plain,
                safeguarded,
                safeguarded_residual: (safeguarded.e - g(safeguarded.e)).abs(),
                closed_form: (setup.alpha == 0.0 && setup.activation_energy == 0.0)
                    .then(|| closed_form_restitution(a0, 1.0, lambda)),
            });
        }
    }
    cells
}

fn method_name(m: SolveMethod) -> &'static str {
    match m {
        SolveMethod::FixedPoint => "fixed_point",
        SolveMethod::Fallback => "fallback",
        SolveMethod::Unconverged => "unconverged",
        SolveMethod::ClosedForm => "closed_form",
        SolveMethod::Seeded => "seeded",
        SolveMethod::IterateBonded => "iterate_bonded",
    }
}

fn write_pair_csv(path: &Path, cells: &[PairCell]) -> anyhow::Result<()> {
    let rows: Vec<Vec<String>> = cells
        .iter()
        .map(|c| {
            vec![
                num(c.a0),
                num(c.speed_ratio),
                num(c.lambda),
                c.plain_converged().to_string(),
                c.plain.iterations.to_string(),
                num(c.plain.e),
                method_name(c.safeguarded.method).into(),
                c.safeguarded.iterations.to_string(),
                c.safeguarded.fallback_iterations.to_string(),
                num(c.safeguarded.e),
                num(c.safeguarded_residual),
                c.closed_form.map(num).unwrap_or_default(),
            ]
        })
        .collect();
    write_csv(
        path,
        &[
            "a0",
            "speed_over_critical",
            "lambda",
            "plain_converged",
            "plain_iterations",
            "plain_e",
            "safeguarded_method",
            "safeguarded_plain_iterations",
            "safeguarded_fallback_iterations",
            "safeguarded_e",
            "safeguarded_residual",
            "closed_form_e",
        ],
        &rows,
    )
}

/// One cell of the cooling map.
#[derive(Debug, Clone, Copy)]
pub struct CoolingCell {
    /// The step Δt [s].
    pub dt: f64,
    /// The initial temperature [K].
    pub theta_initial: f64,
    /// Explicit limit 1/(4 k θ0³) at the initial temperature [s].
    pub limit: f64,
    /// Relative error of explicit (forward Euler) cooling at the end of `COOLING_STEPS` steps against the radiative closed form.
    pub explicit_error: f64,
    /// Relative error of implicit cooling at the end of `COOLING_STEPS` steps against the radiative closed form.
    pub implicit_error: f64,
    /// True when an explicit step left the band (non-finite, below the far-field temperature, or warming).
    pub explicit_unstable: bool,
    /// The same for implicit steps.
    pub implicit_unstable: bool,
}

/// Steps per cooling-map cell.
pub const COOLING_STEPS: usize = 10;

/// The cooling law of the map: a 1 mm grain with P04's best-case material (ρ = 6652.7,
/// C = 1796.3, ε = 0.5), hc = 0 and θs = 0 so the closed form applies.
pub fn cooling_law() -> CoolingLaw {
    let (radius, rho, c, eps) = (1e-3, 6652.7, 1796.3, 0.5);
    let area = 4.0 * std::f64::consts::PI * radius * radius;
    let mass = 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3) * rho;
    CoolingLaw {
        k_convection: 0.0,
        k_radiation: STEFAN_BOLTZMANN * eps * area / (mass * c),
        theta_gas: 0.0,
        theta_far: 0.0,
    }
}

/// Run `COOLING_STEPS` steps of `method`; (relative error at the end, left the band).
fn cooling_run(law: &CoolingLaw, method: CoolingMethod, theta0: f64, dt: f64) -> (f64, bool) {
    let mut theta = theta0;
    let mut unstable = false;
    for _ in 0..COOLING_STEPS {
        let next = law.step(method, theta, dt);
        if !next.is_finite() || next <= law.theta_far || next > theta {
            unstable = true;
        }
        theta = next;
        if !theta.is_finite() {
            break;
        }
    }
    let exact = radiative_closed_form(theta0, law.k_radiation, COOLING_STEPS as f64 * dt);
    let error = if theta.is_finite() {
        (theta - exact).abs() / exact
    } else {
        f64::INFINITY
    };
    (error, unstable)
}

/// The cooling map over `dts` × `thetas`.
pub fn cooling_map(law: &CoolingLaw, dts: &[f64], thetas: &[f64]) -> Vec<CoolingCell> {
    let mut cells = Vec::new();
    for &theta in thetas {
        for &dt in dts {
            let (explicit_error, explicit_unstable) =
                cooling_run(law, CoolingMethod::Explicit, theta, dt);
            let (implicit_error, implicit_unstable) =
                cooling_run(law, CoolingMethod::Implicit, theta, dt);
            cells.push(CoolingCell {
                dt,
                theta_initial: theta,
                limit: law.explicit_limit(theta),
                explicit_error,
                implicit_error,
                explicit_unstable,
                implicit_unstable,
            });
        }
    }
    cells
}

/// Default cooling grid: Δt from 1e-16 to 1e8 s and θ0 from 1e2 to 1e10 K, logarithmic.
pub fn cooling_grid() -> (Vec<f64>, Vec<f64>) {
    let dts = (0..=48)
        .map(|k| 10f64.powf(-16.0 + 0.5 * k as f64))
        .collect();
    let thetas = (0..=32)
        .map(|k| 10f64.powf(2.0 + 0.25 * k as f64))
        .collect();
    (dts, thetas)
}

fn write_cooling_csv(path: &Path, cells: &[CoolingCell]) -> anyhow::Result<()> {
    let rows: Vec<Vec<String>> = cells
        .iter()
        .map(|c| {
            vec![
                num(c.dt),
                num(c.theta_initial),
                num(c.limit),
                num(c.dt / c.limit),
                num(c.explicit_error),
                c.explicit_unstable.to_string(),
                num(c.implicit_error),
                c.implicit_unstable.to_string(),
            ]
        })
        .collect();
    write_csv(
        path,
        &[
            "dt",
            "theta_initial",
            "explicit_limit",
            "dt_over_limit",
            "explicit_error",
            "explicit_unstable",
            "implicit_error",
            "implicit_unstable",
        ],
        &rows,
    )
}

/// Kinematic miss fraction of one step Δt, pooled over clouds.
#[derive(Debug, Clone, Copy)]
pub struct KinematicMiss {
    /// The step Δt [s].
    pub dt: f64,
    /// Pairs whose ballistic paths touch within Δt.
    pub colliding: u64,
    /// Of those, pairs found overlapping and approaching at the step's end.
    pub detected: u64,
}

impl KinematicMiss {
    /// The fraction of colliding pairs not detected (0 with none colliding).
    pub fn missed_fraction(&self) -> f64 {
        if self.colliding == 0 {
            0.0
        } else {
            1.0 - self.detected as f64 / self.colliding as f64
        }
    }
}

/// For every pair of `bodies` (periodic box of half-width `half_width`): the ballistic
/// interval on which they overlap, as (t_in, t_closest). O(N²), once per cloud: this is
/// an analysis, not a step.
fn contact_windows(bodies: &[crate::components::BodyState], half_width: f64) -> Vec<(f64, f64)> {
    let side = 2.0 * half_width;
    let mut out = Vec::new();
    for i in 0..bodies.len() {
        for j in i + 1..bodies.len() {
            let mut d = bodies[j].position - bodies[i].position;
            d -= side * (d / side).round();
            let u = bodies[j].velocity - bodies[i].velocity;
            let s = bodies[i].radius + bodies[j].radius;
            let b = d.dot(u);
            let a = u.length_squared();
            if b >= 0.0 || a == 0.0 {
                continue;
            }
            let c = d.length_squared() - s * s;
            let disc = b * b - a * c;
            if disc < 0.0 {
                continue;
            }
            let t_in = if c <= 0.0 {
                0.0
            } else {
                c / (-b + disc.sqrt())
            };
            out.push((t_in, -b / a));
        }
    }
    out
}

/// Miss fractions of one step of each Δt in `dts`, pooled over the initial clouds of
/// `scenario` with `seeds` seeds.
pub fn kinematic_misses(
    scenario: &Scenario,
    dts: &[f64],
    seeds: usize,
) -> anyhow::Result<Vec<KinematicMiss>> {
    let mut out: Vec<KinematicMiss> = dts
        .iter()
        .map(|&dt| KinematicMiss {
            dt,
            colliding: 0,
            detected: 0,
        })
        .collect();
    for k in 0..seeds.max(1) {
        let mut s = scenario.clone();
        s.seed = scenario.seed.wrapping_add(k as u64);
        let run = crate::run::Run::start(
            crate::run::RunPlan::unwritten(s.clone()),
            Default::default(),
        )?;
        let bodies = run.sim().bodies();
        for (t_in, t_closest) in contact_windows(&bodies, s.domain.half_width) {
            for m in out.iter_mut() {
                if t_in <= m.dt {
                    m.colliding += 1;
                    // Found at the step's end only if still overlapping and approaching.
                    if m.dt < t_closest {
                        m.detected += 1;
                    }
                }
            }
        }
    }
    Ok(out)
}

/// Crossing times b0 / |v_rel| the elastic scene runs for (a dense gas collides every
/// crossing time or so: enough impacts for statistics, few enough to run in seconds).
pub const ELASTIC_CROSSING_TIMES: f64 = 30.0;

/// Crossing time b0 / |v_rel| of a scene [s].
pub fn crossing_time(scenario: &Scenario) -> f64 {
    scenario.primary_radius()
        / DVec3::from_array(scenario.cloud.v_rel.unwrap_or_default())
            .length()
            .max(1e-300)
}

/// An elastic version of `scenario`: no bonding (H0 huge, no softening, no reaction
/// heat), no merging, fragmentation or cooling, so its impact count is the collision
/// count of a hard-sphere gas; it runs for [`ELASTIC_CROSSING_TIMES`] crossing times.
pub fn elastic_scene(scenario: &Scenario) -> Scenario {
    let mut s = scenario.clone();
    s.time.end = s
        .time
        .end
        .min(ELASTIC_CROSSING_TIMES * crossing_time(scenario));
    s.material.H0 = 1e18;
    s.material.Q = 0.0;
    s.material.alpha = 0.0;
    s.material.epsilon = 0.0;
    s.material.hc = 0.0;
    s.material.gamma = None;
    s.physics.merging = false;
    s.physics.fragmentation = false;
    s.physics.cooling = CoolingMethod::Off;
    s.output = Default::default();
    s
}

/// Impacts of one setting of the elastic scene, relative to the resolved run.
#[derive(Debug, Clone)]
pub struct RunMiss {
    /// "fixed_dt" or "adaptive_c".
    pub family: &'static str,
    /// Δt [s] or c.
    pub parameter: f64,
    /// Impacts per seed.
    pub impacts: Vec<u64>,
    /// Impacts of the resolved run (c = 1) per seed.
    pub reference: Vec<u64>,
}

impl RunMiss {
    /// 1 − Σ impacts / Σ reference impacts.
    pub fn missed_fraction(&self) -> f64 {
        let a: u64 = self.impacts.iter().sum();
        let r: u64 = self.reference.iter().sum();
        if r == 0 {
            0.0
        } else {
            1.0 - a as f64 / r as f64
        }
    }
}

/// Refuse `seeds` seeds of [`run_misses`] over `settings` settings whose counts cannot
/// fit: a seed, its reference count and one count per setting and seed are kept
/// (`--seeds 4294967295` would list 34 GB of seeds alone).
fn misses_fit(seeds: usize, settings: usize) -> Result<(), String> {
    let kept = 16 + 8 * settings;
    crate::memory::fits("seeds", seeds, seeds as f64 * kept as f64)
}

/// Run the elastic scene under fixed Δt and step factor c over `seeds` seeds.
pub fn run_misses(
    scenario: &Scenario,
    dts: &[f64],
    factors: &[f64],
    seeds: usize,
) -> anyhow::Result<(Vec<RunMiss>, f64)> {
    let base = elastic_scene(scenario);
    let (dt_min, dt_max, skin) = match base.time.stepping {
        Stepping::Adaptive {
            dt_min,
            dt_max,
            skin,
            ..
        } => (dt_min.min(1e-12), dt_max, skin),
        Stepping::Fixed { .. } => (1e-12, 1e-3, 1.0),
    };
    let adaptive = |c: f64, seed: u64| {
        let mut s = base.clone();
        s.seed = seed;
        s.time.stepping = Stepping::Adaptive {
            step_factor: c,
            dt_min,
            dt_max,
            skin,
        };
        s
    };
    let impacts = |s: &Scenario| -> anyhow::Result<u64> {
        let plan = crate::run::RunPlan::unwritten(s.clone());
        // A failed run still reports the impacts it resolved.
        let (end, _outcome) = crate::run::Run::complete(plan, Vec::new())?;
        Ok(end.sim.counters().impacts)
    };
    misses_fit(seeds, dts.len() + factors.len()).map_err(anyhow::Error::msg)?;
    let seeds: Vec<u64> = (0..seeds.max(1) as u64)
        .map(|k| base.seed.wrapping_add(k))
        .collect();
    let reference: Vec<u64> = seeds
        .iter()
        .map(|&seed| impacts(&adaptive(1.0, seed)))
        .collect::<anyhow::Result<_>>()?;
    let refs: Vec<f64> = reference.iter().map(|&x| x as f64).collect();
    let (mean, std) = mean_std(&refs);
    let noise = if mean > 0.0 { std / mean } else { 0.0 };
    let mut out = Vec::new();
    for &dt in dts {
        let counts = seeds
            .iter()
            .map(|&seed| {
                let mut s = base.clone();
                s.seed = seed;
                s.time.stepping = Stepping::Fixed { dt };
                impacts(&s)
            })
            .collect::<anyhow::Result<_>>()?;
        out.push(RunMiss {
            family: "fixed_dt",
            parameter: dt,
            impacts: counts,
            reference: reference.clone(),
        });
    }
    for &c in factors {
        let counts = seeds
            .iter()
            .map(|&seed| impacts(&adaptive(c, seed)))
            .collect::<anyhow::Result<_>>()?;
        out.push(RunMiss {
            family: "adaptive_c",
            parameter: c,
            impacts: counts,
            reference: reference.clone(),
        });
    }
    Ok((out, noise))
}

/// Knobs of the stability study.
#[derive(Debug, Clone)]
pub struct StabilityOptions {
    /// The pair map's grid.
    pub pair_grid: PairGrid,
    /// Seeds for the step-size study.
    pub seeds: usize,
    /// Whole-run step-size study (costs scene runs); the kinematic one always runs.
    pub runs: bool,
}

impl Default for StabilityOptions {
    fn default() -> Self {
        Self {
            pair_grid: PairGrid::default(),
            seeds: 3,
            runs: true,
        }
    }
}

/// All maps of the stability study.
#[derive(Debug, Clone)]
pub struct StabilityStudy {
    /// The pair map of the cold pair.
    pub pair_cold: Vec<PairCell>,
    /// The pair map of the softening pair.
    pub pair_soft: Vec<PairCell>,
    /// The cooling map.
    pub cooling: Vec<CoolingCell>,
    /// Kinematic misses per step Δt.
    pub kinematic: Vec<KinematicMiss>,
    /// Δt over the scene's crossing time b0 / |v_rel| (for the chart's second axis).
    pub crossing_time: f64,
    /// Whole-run impact counts per step setting (empty without `runs`).
    pub runs: Vec<RunMiss>,
    /// Relative seed spread of the resolved impact count.
    pub runs_noise: f64,
}

/// Run every map; the step-size part uses `scenario`.
pub fn run_stability(
    scenario: &Scenario,
    options: &StabilityOptions,
    mut progress: impl FnMut(&str),
) -> anyhow::Result<StabilityStudy> {
    // Refused before the maps, not after them.
    if options.runs {
        misses_fit(options.seeds, 8 + 6).map_err(anyhow::Error::msg)?;
    }
    let pair_cold = pair_map(&PairSetup::cold(), &options.pair_grid);
    progress("pair map (no softening) done");
    let pair_soft = pair_map(&PairSetup::softening(), &options.pair_grid);
    progress("pair map (thermal softening) done");
    let (dts, thetas) = cooling_grid();
    let cooling = cooling_map(&cooling_law(), &dts, &thetas);
    progress("cooling map done");

    let crossing_time = crossing_time(scenario);
    let end = scenario.time.end;
    // One step of Δt from 1e-3 to 1e2 crossing times (capped at T).
    let kin_dts: Vec<f64> = (0..=25)
        .map(|k| (crossing_time * 10f64.powf(-3.0 + 0.2 * k as f64)).min(end))
        .collect();
    let kinematic = kinematic_misses(scenario, &kin_dts, options.seeds.max(3))?;
    progress("kinematic step-size study done");
    let (runs, runs_noise) = if options.runs {
        let run_dts: Vec<f64> = (0..8)
            .map(|k| {
                (crossing_time * 10f64.powf(-1.5 + 0.5 * k as f64))
                    .min(elastic_scene(scenario).time.end / 4.0)
            })
            .collect();
        let mut run_dts = run_dts;
        run_dts.dedup();
        let r = run_misses(
            scenario,
            &run_dts,
            &[1.0, 2.0, 5.0, 10.0, 30.0, 100.0],
            options.seeds,
        )?;
        progress("step-size runs done");
        r
    } else {
        (Vec::new(), 0.0)
    };
    Ok(StabilityStudy {
        pair_cold,
        pair_soft,
        cooling,
        kinematic,
        crossing_time,
        runs,
        runs_noise,
    })
}

/// Write the CSVs of `study` into `dir` (with the charts: [`super::write::write_stability`]).
pub fn write_stability_tables(dir: &Path, study: &StabilityStudy) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    write_pair_csv(&dir.join("pair_map.csv"), &study.pair_cold)?;
    write_pair_csv(&dir.join("pair_map_softening.csv"), &study.pair_soft)?;
    write_cooling_csv(&dir.join("cooling_map.csv"), &study.cooling)?;
    let rows: Vec<Vec<String>> = study
        .kinematic
        .iter()
        .map(|k| {
            vec![
                num(k.dt),
                num(k.dt / study.crossing_time),
                k.colliding.to_string(),
                k.detected.to_string(),
                num(k.missed_fraction()),
            ]
        })
        .collect();
    write_csv(
        &dir.join("tunnelling_kinematic.csv"),
        &[
            "dt",
            "dt_over_crossing_time",
            "colliding_pairs",
            "detected_pairs",
            "missed_fraction",
        ],
        &rows,
    )?;
    let rows: Vec<Vec<String>> = study
        .runs
        .iter()
        .map(|r| {
            vec![
                r.family.into(),
                num(r.parameter),
                r.impacts.iter().sum::<u64>().to_string(),
                r.reference.iter().sum::<u64>().to_string(),
                num(r.missed_fraction()),
                num(study.runs_noise),
            ]
        })
        .collect();
    write_csv(
        &dir.join("tunnelling_runs.csv"),
        &[
            "family",
            "parameter",
            "impacts",
            "reference_impacts",
            "missed_fraction",
            "reference_seed_spread",
        ],
        &rows,
    )?;
    Ok(())
}
