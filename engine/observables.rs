//! Observables of a run (docs/model.md §11) and the summary written by `--summary`.
//!
//! b_f is the number-average radius of the bodies, b* the radius of one sphere
//! holding all the mass; Π04 = 1 − b_f / b* (P04 (7.1)), n_f = (b_f / b0)³ (P04 (7.2)),
//! Π02 = |b_f / (r_t b0) − 1| with r_t = 2 (P02 (26)); radius moments normalised as
//! m_r = M_r / M_2^{r/2} (P02 (24), (29)).

use serde::{Deserialize, Serialize};

use crate::components::BodyState;
use crate::resources::{Counters, EnergyLedger, EventStats};
use crate::schedule::{Pipeline, Simulation};

/// Target ratio r_t of P02's cost (b_f = 2 b0).
pub const P02_TARGET_RATIO: f64 = 2.0;

/// Statistics of a set of radii.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RadiusStats {
    /// Number-average radius b_f [m].
    pub mean: f64,
    /// Standard deviation [m].
    pub std_dev: f64,
    /// Normalised third central moment m_3.
    pub skewness: f64,
    /// Normalised fourth central moment m_4.
    pub kurtosis: f64,
}

impl RadiusStats {
    /// Moments of `radii` (0 spread gives skewness = kurtosis = 0).
    pub fn of(radii: &[f64]) -> Self {
        let n = radii.len() as f64;
        if radii.is_empty() {
            return Self::default();
        }
        let mean = radii.iter().sum::<f64>() / n;
        let moment = |r: i32| radii.iter().map(|b| (b - mean).powi(r)).sum::<f64>() / n;
        let m2 = moment(2);
        let (skewness, kurtosis) = if m2 > 0.0 {
            (moment(3) / m2.powf(1.5), moment(4) / (m2 * m2))
        } else {
            (0.0, 0.0)
        };
        Self {
            mean,
            std_dev: m2.sqrt(),
            skewness,
            kurtosis,
        }
    }
}

/// The agglomeration measures of docs/model.md §11.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Growth {
    /// Number-average radius b_f [m].
    pub b_f: f64,
    /// Radius of one sphere holding all the mass b* [m].
    pub b_star: f64,
    /// Primary radius b0 [m].
    pub b0: f64,
    /// b_f / b0.
    pub growth_ratio: f64,
    /// Π04 = 1 − b_f / b*.
    pub pi04: f64,
    /// n_f = (b_f / b0)³.
    pub n_f: f64,
    /// Π02 = |b_f / (2 b0) − 1|.
    pub pi02: f64,
    /// Radius [m].
    pub radius: RadiusStats,
}

impl Growth {
    /// From the bodies' radii and masses, with density ρ [kg/m³] and primary radius b0 [m].
    pub fn of(bodies: &[BodyState], rho: f64, b0: f64) -> Self {
        let radii: Vec<f64> = bodies.iter().map(|b| b.radius).collect();
        let radius = RadiusStats::of(&radii);
        let mass: f64 = bodies.iter().map(|b| b.mass).sum();
        let b_star = (3.0 * mass / (4.0 * std::f64::consts::PI * rho)).cbrt();
        let b_f = radius.mean;
        Self {
            b_f,
            b_star,
            b0,
            growth_ratio: b_f / b0,
            pi04: 1.0 - b_f / b_star,
            n_f: (b_f / b0).powi(3),
            pi02: (b_f / (P02_TARGET_RATIO * b0) - 1.0).abs(),
            radius,
        }
    }
}

/// What `agglo run --summary` writes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The scenario's `name`.
    pub scenario: String,
    /// The run's seed.
    pub seed: u64,
    /// Simulated time reached [s].
    pub time: f64,
    /// Steps taken (events, on the event core).
    pub steps: u64,
    /// Bodies at t = 0.
    pub initial_bodies: usize,
    /// Bodies at the end.
    pub final_bodies: usize,
    /// The growth observables (docs/model.md §11).
    pub growth: Growth,
    /// Mean primaries per body.
    pub mean_primaries: f64,
    /// Σ ½ m v² [J].
    pub kinetic_energy: f64,
    /// Σ m C θ [J].
    pub thermal_energy: f64,
    /// Mean temperature [K].
    pub mean_temperature: f64,
    /// Maximum temperature [K].
    pub max_temperature: f64,
    /// The event counters.
    pub counters: Counters,
    /// The energy ledger: every term the run booked [J].
    pub energy: EnergyLedger,
    /// Worst |M − M0| / M0 seen.
    pub max_mass_error: f64,
    /// Worst |P − P0| / Σ m|v| seen.
    pub max_momentum_error: f64,
    /// Worst error of the total energy ledger (docs/model.md §10).
    pub max_energy_error: f64,
    /// Worst error of the kinetic energy ledger, relative to its own scale
    /// (docs/model.md §10).
    #[serde(default)]
    pub max_kinetic_energy_error: f64,
    #[serde(default)]
    /// Worst error of the thermal energy ledger, relative to its own scale.
    pub max_thermal_energy_error: f64,
    /// The first few invariant violations, human readable (empty: none).
    pub invariant_violations: Vec<String>,
    /// Plugins built into the run, in order.
    pub plugins: Vec<String>,
    /// The core, the systems in order and why the others were left out (as `agglo
    /// validate` prints them).
    #[serde(default)]
    pub pipeline: Pipeline,
    /// Wall-clock seconds spent stepping.
    pub wall_seconds: f64,
    /// The event core's own counts (absent on the stepped core).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub events: Option<EventStats>,
    /// The rigid aggregates: count, k, R_g and the fractal fit (absent unless
    /// `physics.merge_mode = "rigid"`, docs/model.md §6.1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aggregates: Option<crate::aggregates::AggregateSummary>,
}

impl Simulation {
    /// Observables (docs/model.md §11), counters and invariant errors of the run so far.
    pub fn summary(&self) -> Summary {
        let bodies = self.bodies();
        Summary::new(self, &bodies)
    }
}

impl Summary {
    /// The summary of `sim` now, from its `bodies` (sorted by id).
    pub fn new(sim: &Simulation, bodies: &[BodyState]) -> Self {
        let material = sim.material();
        let clock = sim.clock();
        let report = sim.invariants();
        let n = bodies.len().max(1) as f64;
        Self {
            scenario: sim.info().name.clone(),
            seed: sim.info().seed,
            time: clock.time,
            steps: clock.step,
            initial_bodies: sim.info().initial_bodies,
            final_bodies: bodies.len(),
            growth: Growth::of(bodies, material.rho, sim.primary().radius),
            mean_primaries: bodies.iter().map(|b| b.primaries).sum::<f64>() / n,
            kinetic_energy: bodies
                .iter()
                .map(|b| 0.5 * b.mass * b.velocity.length_squared())
                .sum(),
            thermal_energy: bodies
                .iter()
                .map(|b| b.mass * material.C * b.temperature)
                .sum(),
            mean_temperature: bodies.iter().map(|b| b.temperature).sum::<f64>() / n,
            max_temperature: bodies
                .iter()
                .map(|b| b.temperature)
                .fold(f64::MIN, f64::max),
            counters: sim.counters(),
            max_kinetic_energy_error: report.max_kinetic_error,
            max_thermal_energy_error: report.max_thermal_error,
            energy: sim.ledger(),
            max_mass_error: report.max_mass_error,
            max_momentum_error: report.max_momentum_error,
            max_energy_error: report.max_energy_error,
            invariant_violations: report.violations,
            plugins: sim.plugins().iter().map(|s| s.to_string()).collect(),
            pipeline: sim.pipeline().clone(),
            wall_seconds: sim.wall_seconds(),
            events: sim.core_stats(),
            aggregates: crate::aggregates::AggregateSummary::of(
                &crate::aggregates::aggregate_shapes(sim.world()),
                sim.primary().radius,
            ),
        }
    }
}
