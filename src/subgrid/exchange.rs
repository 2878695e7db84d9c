//! What crosses between a flow solver's cell and its boxes (docs/model.md §15): the
//! macro state handed in ([`CellInput`]: size classes, gas state, Δt) and the
//! homogenized figures handed back ([`CellOutput`]: source rates per class, the new
//! class states, what the gas received, event rates), each as the mean over the K
//! replica boxes with its standard error ([`Stat`]).
//!
//! Plain `f64`s and vectors in SI units, so that the C and Python fronts can hand them
//! over as arrays. Densities and rates are per unit volume of the cell [1/m³, kg/m³,
//! …]; a rate is the change over the macro step divided by Δt.

use serde::{Deserialize, Serialize};

use crate::kernel::Accumulator;
use agglo_engine::field::Relaxation;

/// One size class of the cell, as the flow solver holds it (macro → micro).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ClassInput {
    /// Bodies per unit volume n_k [1/m³], ≥ 0.
    pub number_density: f64,
    /// The class's representative body mass m_k [kg], inside the class's edges and at
    /// least the primary grain's mass; its radius is (3 m_k / 4πρ)^(1/3).
    pub mass: f64,
    /// Mean velocity of the class [m/s].
    pub velocity: [f64; 3],
    /// Temperature θ_k of the class's bodies [K], > 0.
    pub temperature: f64,
    /// Granular temperature T_k [m²/s²], ≥ 0: the mean over the three axes of the
    /// variance of a velocity component about the class mean (Maxwellian fluctuations
    /// are drawn with it; ½ρ_k·3T_k is the class's granular energy).
    pub granular_temperature: f64,
    /// How T_k splits over the axes x, y, z: component i's variance is
    /// T_k · 3a_i/(a_x + a_y + a_z) — the diagonal of the class's granular temperature
    /// tensor, T_xx, T_yy, T_zz, whose mean is T_k. Each a_i ≥ 0 and finite, their sum
    /// > 0; [`ISOTROPIC`] = [1, 1, 1].
    pub granular_anisotropy: [f64; 3],
}

/// The anisotropy of an isotropic class ([`ClassInput::granular_anisotropy`]).
pub const ISOTROPIC: [f64; 3] = [1.0; 3];

impl ClassInput {
    /// The diagonal of the class's granular temperature tensor, T_xx, T_yy, T_zz
    /// [m²/s²] (their mean is `granular_temperature`).
    pub fn granular_temperature_axes(&self) -> [f64; 3] {
        let a = self.granular_anisotropy;
        let sum = a[0] + a[1] + a[2];
        a.map(|x| self.granular_temperature * 3.0 * x / sum)
    }
}

/// The gas the boxes' bodies fly through (uniform over the cell and the macro step).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GasState {
    /// Gas velocity u [m/s] (the drag pulls bodies toward it).
    pub velocity: [f64; 3],
    /// Gas temperature [K], > 0: the ambient θ0 of convective cooling (docs/model.md
    /// §8); it replaces the base scenario's `material.theta0`.
    pub temperature: f64,
    /// How a body's drag relaxation time follows from the gas: Stokes (viscosity μ),
    /// Epstein (gas density ρ_g and mean thermal speed v_th) or a constant τ. `None`:
    /// no drag (the bodies do not feel the gas velocity).
    pub drag: Option<Relaxation>,
}

/// A cell's macro state for one macro step (macro → micro).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellInput {
    /// One entry per class of the coupling's grid ([`super::Coupling::edges`]).
    pub classes: Vec<ClassInput>,
    /// The gas the bodies sit in.
    pub gas: GasState,
    /// The macro time step Δt [s], > 0.
    pub dt: f64,
}

/// An ensemble figure: the mean over the replicas that define it, and the standard
/// error of that mean, s/√K (s the sample standard deviation over those replicas).
/// With a single replica the standard error is NaN (it cannot be estimated); with none
/// the mean is NaN too ("not measured"). A count rate ([`Stat::of_counts`]) has a
/// Poisson floor. The standard error covers replica noise only, not the biases of a
/// finite box or a finite Δt (docs/coupling.md).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Stat {
    /// The mean over the replicas.
    pub mean: f64,
    /// Its standard error.
    pub se: f64,
}

impl Stat {
    /// Mean and standard error of `values` (summed in order: the same bits for the
    /// same values). Empty: mean and se NaN (not measured).
    pub fn of(values: &[f64]) -> Self {
        let k = values.len();
        if k == 0 {
            return Self {
                mean: f64::NAN,
                se: f64::NAN,
            };
        }
        let mean = values.iter().sum::<f64>() / k as f64;
        if k == 1 {
            return Self { mean, se: f64::NAN };
        }
        let var = values.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (k - 1) as f64;
        Self {
            mean,
            se: (var / k as f64).sqrt(),
        }
    }

    /// A rate or density made of counts: `values[r]` = `counts[r]` × `scale` in replica
    /// r (`counts` the bodies or events behind it, their magnitude when a change can be
    /// negative). Its standard error is at least the Poisson floor
    /// √(Σ|counts|) · `scale` / K, so replicas that happen to agree (a rare class, a
    /// rare event in few boxes) do not claim certainty; with no count in any replica
    /// nothing can be said of the spread and the standard error is NaN. One replica:
    /// NaN, as [`Stat::of`].
    pub fn of_counts(values: &[f64], counts: &[f64], scale: f64) -> Self {
        let mut s = Self::of(values);
        let k = values.len();
        if k < 2 {
            return s;
        }
        let events: f64 = counts.iter().map(|c| c.abs()).sum();
        s.se = if events == 0.0 {
            f64::NAN
        } else {
            s.se.max(events.sqrt() * scale.abs() / k as f64)
        };
        s
    }
}

/// One class after the macro step (micro → macro). Rates are (end − start)/(V Δt) in
/// each box of volume V, averaged over the replicas; the class states at the end are
/// averaged over the replicas in which the class holds bodies at the end (`present`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClassOutput {
    /// Source rate of number density [1/(m³ s)].
    pub number_rate: Stat,
    /// Source rate of mass density [kg/(m³ s)]; over all classes they sum to zero
    /// (mass moves between classes, none is made or lost) to rounding.
    pub mass_rate: Stat,
    /// Source rate of momentum density [N/m³]: what collisions moved between classes
    /// plus what the drag and g gave the class's bodies.
    pub momentum_rate: [Stat; 3],
    /// Number density at the end of the step [1/m³].
    pub number_density: Stat,
    /// Mass density at the end of the step [kg/m³].
    pub mass_density: Stat,
    /// Mass-weighted mean velocity of the class's bodies at the end [m/s].
    pub velocity: [Stat; 3],
    /// Mass-weighted mean temperature of the class's bodies at the end [K].
    pub temperature: Stat,
    /// Granular temperature at the end [m²/s²]: the unbiased mass-weighted variance of
    /// a velocity component about the class's mean velocity, Σm|v − ū|² / (3(M −
    /// Σm²/M)) (Bessel's N/(N − 1) for equal masses), in each replica where the class
    /// holds at least two bodies, averaged over those (`granular_replicas`); NaN where
    /// none did (a one-body class has no measurable spread).
    pub granular_temperature: Stat,
    /// The diagonal of the class's granular temperature tensor at the end, T_xx, T_yy,
    /// T_zz [m²/s²]: per axis the unbiased variance Σm(v_i − ū_i)² / (M − Σm²/M), over
    /// the same replicas as `granular_temperature` (their mean); NaN where none.
    pub granular_temperature_axes: [Stat; 3],
    /// Replicas in which the class holds bodies at the end (the states above are means
    /// over these; with 0 they are NaN, "not measured").
    pub present: u32,
    /// Replicas in which the class holds at least two bodies at the end (the granular
    /// temperature's mean is over these).
    pub granular_replicas: u32,
    /// Rate of the class's fluctuation (granular) energy density [W/m³]: its kinetic
    /// energy rate less the change of its mean-flow energy ½|p_k|²/ρ_k that the
    /// handed-back mass and momentum rates make from the input's ρ_k = n_k m_k,
    /// p_k = ρ_k u_k (an emptied class, ρ_k + Δt·rate ≤ 0, has none). Over the classes,
    /// fluctuation plus mean-flow energy change exactly as the field's work less the
    /// impact dissipation: a solver transporting ½ρ_k·3T_k with this rate closes its
    /// kinetic energy (docs/model.md §15). Its SE is the replicas' spread of their
    /// kinetic energy rate less the mean-flow change linearised about the handed-back
    /// rates (the delta method), so that energy moved with the momentum along the drift
    /// does not count as noise.
    pub fluctuation_energy_rate: Stat,
    /// Rate of the class's thermal energy density C Σmθ / V [W/m³]; over the classes it
    /// is the dissipation, reaction heat, fracture energy and cooling loss rates'
    /// balance D + R − Z − L.
    pub thermal_energy_rate: Stat,
    /// The class was a trace (fewer than [`super::TRACE_BODIES`] bodies expected per
    /// box) and was not lifted: its rates are 0 from it alone (merges elsewhere may
    /// still feed it).
    pub ignored: bool,
}

/// What a cell hands back after a macro step (micro → macro); see [`ClassOutput`] for
/// the per-class figures. Every figure is per unit volume of the cell.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CellOutput {
    /// The cell's id (the flow solver's).
    pub cell: u64,
    /// The macro step's number as the caller gave it.
    pub macro_step: u64,
    /// Δt [s] of the step.
    pub dt: f64,
    /// Replica boxes K the figures are averaged over.
    pub replicas: u32,
    /// Volume of each box [m³].
    pub box_volume: f64,
    /// Bodies per box at the start of the step.
    pub bodies: Stat,
    /// Per class of the coupling's grid, in its order.
    pub classes: Vec<ClassOutput>,
    /// Source rate of the total number density [1/(m³ s)], the column
    /// `total_number_rate` of [`Self::columns`] as in C and Python (the cell's growth:
    /// minus the bodies merges removed, plus the pieces fragmentations made); its
    /// standard error is over the replicas' totals (the classes' rates are correlated,
    /// so theirs do not add up to it). Named `number_rate` until issue 40, which gave
    /// every thing one name across Rust, C and Python (`number_rate` is a class's).
    pub total_number_rate: Stat,
    /// Granular temperature of all bodies at the end [m²/s²]: the unbiased
    /// mass-weighted variance of a velocity component about each body's class mean,
    /// Σ_k Σm|v − ū_k|² / (3 Σ_k (M_k − Σm²/M_k)) (one-body classes add nothing to
    /// either sum); NaN in a replica where no class holds two bodies.
    pub granular_temperature: Stat,
    /// Momentum the gas received from the bodies through drag [N/m³]: minus the drag's
    /// impulse on them (the field's impulse less M g Δt).
    pub gas_momentum_rate: [Stat; 3],
    /// Work the field (drag and g) did on the bodies [W/m³].
    pub force_work_rate: Stat,
    /// Heat the bodies gave off by cooling (convection to the gas and radiation, §8)
    /// [W/m³].
    pub heat_loss_rate: Stat,
    /// Heat released by reactions at bonds [W/m³].
    pub reaction_heat_rate: Stat,
    /// Kinetic energy impacts turned into heat [W/m³].
    pub dissipation_rate: Stat,
    /// Energy taken by fracture [W/m³].
    pub fracture_energy_rate: Stat,
    /// Impacts, bonds, bounces and fragmentations per unit volume and time [1/(m³ s)].
    pub impact_rate: Stat,
    /// Impacts that bonded [1/(m³ s)].
    pub bond_rate: Stat,
    /// Impacts that bounced [1/(m³ s)].
    pub bounce_rate: Stat,
    /// Fragmentations [1/(m³ s)].
    pub fragment_rate: Stat,
    /// With [`super::Coupling::kernel`]: the per-pair impact counts and exposure of
    /// `agglo kernel` on the coupling's classes, pooled over the replicas (replica
    /// order); [`crate::kernel::Estimate::of`] turns them into the kernel.
    pub kernel: Option<Accumulator>,
}

impl CellOutput {
    /// The output as bytes (postcard: every f64 as its 8 bytes), for storage and for
    /// comparing outputs bit for bit.
    pub fn to_bytes(&self) -> Vec<u8> {
        postcard::to_allocvec(self).expect("an output always encodes")
    }

    /// An output from [`Self::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        postcard::from_bytes(bytes).map_err(|e| format!("the output does not decode ({e})"))
    }
}

/// One figure of a [`CellOutput`] as flat arrays, for the C and Python fronts:
/// `mean` and `se` hold `shape`'s product of values, row-major (class first, then
/// the axis for per-class vectors).
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// The figure's name (docs/coupling.md, "Figure names").
    pub name: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// `[classes]`, `[classes, 3]`, `[1]` or `[3]`.
    pub shape: Vec<usize>,
    /// The means, row-major.
    pub mean: Vec<f64>,
    /// Their standard errors, row-major (NaN where not defined).
    pub se: Vec<f64>,
}

impl CellOutput {
    /// Every figure as a named column, in a fixed order (the per-class ones first; with
    /// the kernel, its pooled sums last).
    pub fn columns(&self) -> Vec<Column> {
        let k = self.classes.len();
        let per_class = |name, unit, f: fn(&ClassOutput) -> Stat| Column {
            name,
            unit,
            shape: vec![k],
            mean: self.classes.iter().map(|c| f(c).mean).collect(),
            se: self.classes.iter().map(|c| f(c).se).collect(),
        };
        let per_class3 = |name, unit, f: fn(&ClassOutput) -> [Stat; 3]| Column {
            name,
            unit,
            shape: vec![k, 3],
            mean: self
                .classes
                .iter()
                .flat_map(|c| f(c).map(|s| s.mean))
                .collect(),
            se: self
                .classes
                .iter()
                .flat_map(|c| f(c).map(|s| s.se))
                .collect(),
        };
        let scalar = |name, unit, s: Stat| Column {
            name,
            unit,
            shape: vec![1],
            mean: vec![s.mean],
            se: vec![s.se],
        };
        let mut columns = vec![
            per_class("number_rate", "1/(m^3 s)", |c| c.number_rate),
            per_class("mass_rate", "kg/(m^3 s)", |c| c.mass_rate),
            per_class3("momentum_rate", "N/m^3", |c| c.momentum_rate),
            per_class("number_density", "1/m^3", |c| c.number_density),
            per_class("mass_density", "kg/m^3", |c| c.mass_density),
            per_class3("velocity", "m/s", |c| c.velocity),
            per_class("temperature", "K", |c| c.temperature),
            per_class("class_granular_temperature", "m^2/s^2", |c| {
                c.granular_temperature
            }),
            per_class3("class_granular_temperature_axes", "m^2/s^2", |c| {
                c.granular_temperature_axes
            }),
            per_class("present", "replicas", |c| Stat {
                mean: c.present as f64,
                se: 0.0,
            }),
            per_class("granular_replicas", "replicas", |c| Stat {
                mean: c.granular_replicas as f64,
                se: 0.0,
            }),
            per_class("fluctuation_energy_rate", "W/m^3", |c| {
                c.fluctuation_energy_rate
            }),
            per_class("thermal_energy_rate", "W/m^3", |c| c.thermal_energy_rate),
            per_class("ignored", "0 or 1", |c| Stat {
                mean: f64::from(u8::from(c.ignored)),
                se: 0.0,
            }),
            scalar("total_number_rate", "1/(m^3 s)", self.total_number_rate),
            scalar("granular_temperature", "m^2/s^2", self.granular_temperature),
            Column {
                name: "gas_momentum_rate",
                unit: "N/m^3",
                shape: vec![3],
                mean: self.gas_momentum_rate.map(|s| s.mean).to_vec(),
                se: self.gas_momentum_rate.map(|s| s.se).to_vec(),
            },
            scalar("force_work_rate", "W/m^3", self.force_work_rate),
            scalar("heat_loss_rate", "W/m^3", self.heat_loss_rate),
            scalar("reaction_heat_rate", "W/m^3", self.reaction_heat_rate),
            scalar("dissipation_rate", "W/m^3", self.dissipation_rate),
            scalar("fracture_energy_rate", "W/m^3", self.fracture_energy_rate),
            scalar("impact_rate", "1/(m^3 s)", self.impact_rate),
            scalar("bond_rate", "1/(m^3 s)", self.bond_rate),
            scalar("bounce_rate", "1/(m^3 s)", self.bounce_rate),
            scalar("fragment_rate", "1/(m^3 s)", self.fragment_rate),
            scalar("bodies", "bodies per box", self.bodies),
        ];
        if let Some(kernel) = &self.kernel {
            columns.extend(kernel_columns(&kernel.pooled));
        }
        columns
    }
}

/// The pooled kernel sums as columns (with [`super::Coupling::kernel`]): the exposure
/// and the impacts per outcome of each class pair, (classes, classes) row-major, filled
/// for i ≤ j. They are sums over the K replicas, not means: their `se` is NaN.
fn kernel_columns(t: &crate::kernel::Tally) -> Vec<Column> {
    let k = t.classes;
    let pairs = k * k;
    let sums = |name, unit, mean: Vec<f64>| Column {
        name,
        unit,
        shape: vec![k, k],
        se: vec![f64::NAN; mean.len()],
        mean,
    };
    let counts = |o: usize| {
        t.counts[o * pairs..(o + 1) * pairs]
            .iter()
            .map(|&c| c as f64)
            .collect()
    };
    vec![
        sums("kernel_exposure", "s/m^3", t.exposure.clone()),
        sums("kernel_bonds", "impacts", counts(0)),
        sums("kernel_bounces", "impacts", counts(1)),
        sums("kernel_fragments", "impacts", counts(2)),
    ]
}

impl CellInput {
    /// An input from flat arrays of one value per class (`velocity` and
    /// `granular_anisotropy`: 3 per class, row-major; no anisotropy: isotropic), as the
    /// C and Python fronts hold them. Lengths are checked, values are checked when the
    /// cell advances ([`super::check_input`]).
    #[allow(clippy::too_many_arguments)]
    pub fn from_columns(
        cell: u64,
        number_density: &[f64],
        mass: &[f64],
        velocity: &[f64],
        temperature: &[f64],
        granular_temperature: &[f64],
        granular_anisotropy: Option<&[f64]>,
        gas: GasState,
        dt: f64,
    ) -> Result<Self, super::SubgridError> {
        let k = number_density.len();
        for (name, len, want) in [
            ("mass", mass.len(), k),
            ("velocity", velocity.len(), 3 * k),
            ("temperature", temperature.len(), k),
            ("granular_temperature", granular_temperature.len(), k),
            (
                "granular_anisotropy",
                granular_anisotropy.map_or(3 * k, |a| a.len()),
                3 * k,
            ),
        ] {
            if len != want {
                return Err(super::SubgridError::input(
                    cell,
                    name,
                    format!("{len} values"),
                    format!("must be {want} (number_density has {k} classes)"),
                ));
            }
        }
        let classes = (0..k)
            .map(|i| ClassInput {
                number_density: number_density[i],
                mass: mass[i],
                velocity: [velocity[3 * i], velocity[3 * i + 1], velocity[3 * i + 2]],
                temperature: temperature[i],
                granular_temperature: granular_temperature[i],
                granular_anisotropy: granular_anisotropy
                    .map_or(ISOTROPIC, |a| [a[3 * i], a[3 * i + 1], a[3 * i + 2]]),
            })
            .collect();
        Ok(Self { classes, gas, dt })
    }
}
