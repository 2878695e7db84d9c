//! Restriction (docs/model.md §15): from a box's bodies back to the cell's classes —
//! bodies binned by mass on the coupling's edges, summed per class ([`ClassSums`]); a
//! replica's change over the step ([`Replica`]); the K replicas' means and standard
//! errors ([`combine`]): unbiased class variances (a class of one body has none to
//! give: "not measured"), Poisson floors on count rates, and per-class energy rates
//! that close the solver's kinetic and thermal energy.
//!
//! Sums run over the bodies in id order, so they depend on nothing but the bodies.

use serde::{Deserialize, Serialize};

use crate::components::BodyState;
use crate::resources::{Counters, EnergyLedger};

use super::config::Coupling;
use super::exchange::{CellInput, CellOutput, ClassOutput, Stat};

/// Per-class sums over a box's bodies.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ClassSums {
    /// Bodies per class.
    pub count: Vec<u64>,
    /// Σ m [kg].
    pub mass: Vec<f64>,
    /// Σ m v [kg m/s].
    pub momentum: Vec<[f64; 3]>,
    /// Σ m θ [kg K].
    pub mass_temperature: Vec<f64>,
    /// Σ m |v − ū_k|² about the class's mass-weighted mean [kg m²/s²].
    pub fluctuation: Vec<f64>,
    /// Σ m (v_i − ū_k,i)² per axis [kg m²/s²] (their sum is `fluctuation`).
    pub fluctuation_axes: Vec<[f64; 3]>,
    /// Σ m² [kg²] (the effective sample size of a mass-weighted variance).
    pub mass_squared: Vec<f64>,
}

impl ClassSums {
    /// Bin `bodies` on the classes of `c`.
    pub fn of(c: &Coupling, bodies: &[BodyState]) -> Self {
        let k = c.classes();
        let mut s = Self {
            count: vec![0; k],
            mass: vec![0.0; k],
            momentum: vec![[0.0; 3]; k],
            mass_temperature: vec![0.0; k],
            fluctuation: vec![0.0; k],
            fluctuation_axes: vec![[0.0; 3]; k],
            mass_squared: vec![0.0; k],
        };
        let mut sorted: Vec<&BodyState> = bodies.iter().collect();
        sorted.sort_by_key(|b| b.id);
        let classes: Vec<usize> = sorted.iter().map(|b| c.class_of(b.mass)).collect();
        for (b, &k) in sorted.iter().zip(&classes) {
            s.count[k] += 1;
            s.mass[k] += b.mass;
            let p = b.velocity * b.mass;
            for x in 0..3 {
                s.momentum[k][x] += p[x];
            }
            s.mass_temperature[k] += b.mass * b.temperature;
            s.mass_squared[k] += b.mass * b.mass;
        }
        // Second pass about the class means (no cancellation of large means).
        for (b, &k) in sorted.iter().zip(&classes) {
            let mean = s.momentum[k].map(|p| p / s.mass[k]);
            let d2 = [0, 1, 2].map(|x| (b.velocity[x] - mean[x]).powi(2));
            s.fluctuation[k] += b.mass * (d2[0] + d2[1] + d2[2]);
            for (axis, d) in s.fluctuation_axes[k].iter_mut().zip(d2) {
                *axis += b.mass * d;
            }
        }
        s
    }

    /// Kinetic energy ½Σm|v|² of class `k` [J], as its fluctuation about the class mean
    /// plus the mean's ½|P|²/M (0 for an empty class).
    pub fn kinetic(&self, k: usize) -> f64 {
        if self.count[k] == 0 {
            return 0.0;
        }
        let p2: f64 = self.momentum[k].iter().map(|p| p * p).sum();
        0.5 * (self.fluctuation[k] + p2 / self.mass[k])
    }

    /// The denominator of class `k`'s unbiased mass-weighted variance, M − Σm²/M [kg]
    /// (M (N − 1)/N for equal masses; 0 for fewer than two bodies).
    fn effective_mass(&self, k: usize) -> f64 {
        if self.count[k] < 2 {
            return 0.0;
        }
        self.mass[k] - self.mass_squared[k] / self.mass[k]
    }
}

/// What one replica box measured over the step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Replica {
    /// The class sums at the start of the step.
    pub start: ClassSums,
    /// At the end.
    pub end: ClassSums,
    /// Ledger at the end less the ledger at the start.
    pub ledger: EnergyLedger,
    /// Impacts, bonds, bounces, fragmentations over the step.
    pub events: [u64; 4],
    /// Σ m over the box [kg] (constant).
    pub total_mass: f64,
}

impl Replica {
    /// The change between two ledgers and two counter sets.
    pub fn new(
        start: ClassSums,
        end: ClassSums,
        ledger0: &EnergyLedger,
        ledger1: &EnergyLedger,
        counters0: &Counters,
        counters1: &Counters,
    ) -> Self {
        let mut ledger = *ledger1;
        ledger.reaction_heat -= ledger0.reaction_heat;
        ledger.fracture_energy -= ledger0.fracture_energy;
        ledger.cooling_loss -= ledger0.cooling_loss;
        ledger.impact_dissipation -= ledger0.impact_dissipation;
        ledger.force_work -= ledger0.force_work;
        ledger.force_work_turnover -= ledger0.force_work_turnover;
        ledger.external_heat -= ledger0.external_heat;
        for x in 0..3 {
            ledger.force_impulse[x] -= ledger0.force_impulse[x];
        }
        ledger.force_impulse_turnover -= ledger0.force_impulse_turnover;
        ledger.double_counted_heat -= ledger0.double_counted_heat;
        let events = [
            counters1.impacts - counters0.impacts,
            counters1.bonds - counters0.bonds,
            counters1.bounces - counters0.bounces,
            counters1.fragmentations - counters0.fragmentations,
        ];
        let total_mass = start.mass.iter().sum();
        Self {
            start,
            end,
            ledger,
            events,
            total_mass,
        }
    }
}

/// Figures over replicas: collect one value per replica, then [`Stat::of`].
fn stat(replicas: &[Replica], f: impl Fn(&Replica) -> f64) -> Stat {
    Stat::of(&replicas.iter().map(f).collect::<Vec<_>>())
}

/// Over the replicas where `keep` holds.
fn stat_where(
    replicas: &[Replica],
    keep: impl Fn(&Replica) -> bool,
    f: impl Fn(&Replica) -> f64,
) -> Stat {
    Stat::of(
        &replicas
            .iter()
            .filter(|r| keep(r))
            .map(f)
            .collect::<Vec<_>>(),
    )
}

/// The mean-flow energy density ½|p|²/ρ [J/m³] of a class of mass density `rho`
/// [kg/m³] and momentum density `p` [kg/(m² s)]; none when the class is empty.
fn mean_flow_energy(rho: f64, p: [f64; 3]) -> f64 {
    if rho > 0.0 {
        0.5 * p.iter().map(|x| x * x).sum::<f64>() / rho
    } else {
        0.0
    }
}

/// The cell's output from its replicas (in replica order), each a box of `volume`
/// [m³] run over `input.dt` [s] (gravity and heat capacity C from the coupling's base
/// scene); `input` is the solver's state the energy rates are measured against, and
/// `ignored[k]` marks the classes lifting skipped as traces.
pub fn combine(
    c: &Coupling,
    cell: u64,
    macro_step: u64,
    input: &CellInput,
    volume: f64,
    ignored: &[bool],
    replicas: &[Replica],
) -> CellOutput {
    let dt = input.dt;
    let g = c.base.field.gravity;
    let heat_capacity = c.base.material.C;
    let per = 1.0 / (volume * dt);
    // A count rate: the change of a count in each replica, with its Poisson floor.
    let count_rate = |f: &dyn Fn(&Replica) -> f64| {
        let counts: Vec<f64> = replicas.iter().map(f).collect();
        let rates: Vec<f64> = counts.iter().map(|x| x * per).collect();
        Stat::of_counts(&rates, &counts, per)
    };
    let classes = (0..c.classes())
        .map(|k| {
            let present = |r: &Replica| r.end.count[k] > 0;
            let end_mass = |r: &Replica| r.end.mass[k];
            let mass_rate = stat(replicas, |r| (r.end.mass[k] - r.start.mass[k]) * per);
            let momentum_rate = [0, 1, 2].map(|x| {
                stat(replicas, |r| {
                    (r.end.momentum[k][x] - r.start.momentum[k][x]) * per
                })
            });
            // The solver's mean-flow energy before and after it applies the rates.
            let class = &input.classes[k];
            let rho0 = class.number_density * class.mass;
            let p0 = class.velocity.map(|u| rho0 * u);
            let rho1 = rho0 + dt * mass_rate.mean;
            let p1 = [0, 1, 2].map(|x| p0[x] + dt * momentum_rate[x].mean);
            let mean_flow_rate = (mean_flow_energy(rho1, p1) - mean_flow_energy(rho0, p0)) / dt;
            let kinetic_rate = stat(replicas, |r| (r.end.kinetic(k) - r.start.kinetic(k)) * per);
            // The fluctuation energy rate's SE (its mean is the kinetic energy rate's less
            // the mean-flow change above): per replica, the kinetic energy rate less the
            // mean-flow change linearised about the handed-back rates (the delta method:
            // ∂/∂(mass rate) = −½|u₁|², ∂/∂(momentum rate) = u₁, u₁ = p₁/ρ₁). A box whose
            // kinetic energy moved with its momentum along a fast drift (P04: 100 m/s)
            // then does not count as noise; with the kinetic energy rate's SE the spread
            // over identical cells was 0.58 of the reported SE (issue 37).
            let u1 = if rho1 > 0.0 {
                p1.map(|p| p / rho1)
            } else {
                [0.0; 3] // an emptied class has no mean-flow energy
            };
            let u1_squared: f64 = u1.iter().map(|u| u * u).sum();
            let fluctuation_se = stat(replicas, |r| {
                let mass = (r.end.mass[k] - r.start.mass[k]) * per;
                let mean_flow: f64 = (0..3)
                    .map(|x| u1[x] * (r.end.momentum[k][x] - r.start.momentum[k][x]) * per)
                    .sum::<f64>()
                    - 0.5 * u1_squared * mass;
                (r.end.kinetic(k) - r.start.kinetic(k)) * per - mean_flow
            })
            .se;
            let measured = |r: &Replica| r.end.effective_mass(k) > 0.0;
            ClassOutput {
                number_rate: count_rate(&|r| r.end.count[k] as f64 - r.start.count[k] as f64),
                mass_rate,
                momentum_rate,
                number_density: {
                    let counts: Vec<f64> = replicas.iter().map(|r| r.end.count[k] as f64).collect();
                    let densities: Vec<f64> = counts.iter().map(|n| n / volume).collect();
                    Stat::of_counts(&densities, &counts, 1.0 / volume)
                },
                mass_density: stat(replicas, |r| r.end.mass[k] / volume),
                velocity: [0, 1, 2]
                    .map(|x| stat_where(replicas, present, |r| r.end.momentum[k][x] / end_mass(r))),
                temperature: stat_where(replicas, present, |r| {
                    r.end.mass_temperature[k] / end_mass(r)
                }),
                granular_temperature: stat_where(replicas, measured, |r| {
                    r.end.fluctuation[k] / (3.0 * r.end.effective_mass(k))
                }),
                granular_temperature_axes: [0, 1, 2].map(|x| {
                    stat_where(replicas, measured, |r| {
                        r.end.fluctuation_axes[k][x] / r.end.effective_mass(k)
                    })
                }),
                present: replicas.iter().filter(|r| present(r)).count() as u32,
                granular_replicas: replicas.iter().filter(|r| measured(r)).count() as u32,
                fluctuation_energy_rate: Stat {
                    mean: kinetic_rate.mean - mean_flow_rate,
                    se: fluctuation_se,
                },
                thermal_energy_rate: stat(replicas, |r| {
                    heat_capacity * (r.end.mass_temperature[k] - r.start.mass_temperature[k]) * per
                }),
                ignored: ignored.get(k).copied().unwrap_or(false),
            }
        })
        .collect();
    let ledger_rate = |f: fn(&EnergyLedger) -> f64| stat(replicas, |r| f(&r.ledger) * per);
    let total = |s: &ClassSums| s.count.iter().sum::<u64>() as f64;
    let unbiased_granular = |s: &ClassSums| {
        let m: f64 = (0..s.count.len()).map(|k| s.effective_mass(k)).sum();
        s.fluctuation.iter().sum::<f64>() / (3.0 * m)
    };
    CellOutput {
        cell,
        macro_step,
        dt,
        replicas: replicas.len() as u32,
        box_volume: volume,
        bodies: stat(replicas, |r| total(&r.start)),
        classes,
        total_number_rate: count_rate(&|r| total(&r.end) - total(&r.start)),
        granular_temperature: stat_where(
            replicas,
            |r| (0..r.end.count.len()).any(|k| r.end.count[k] >= 2),
            |r| unbiased_granular(&r.end),
        ),
        // The field's impulse is g's (M g Δt, mass being constant) plus the drag's; the
        // gas receives minus the drag's.
        gas_momentum_rate: [0, 1, 2].map(|x| {
            stat(replicas, |r| {
                -(r.ledger.force_impulse[x] - r.total_mass * g[x] * dt) * per
            })
        }),
        force_work_rate: ledger_rate(|l| l.force_work),
        heat_loss_rate: ledger_rate(|l| l.cooling_loss),
        reaction_heat_rate: ledger_rate(|l| l.reaction_heat),
        dissipation_rate: ledger_rate(|l| l.impact_dissipation),
        fracture_energy_rate: ledger_rate(|l| l.fracture_energy),
        impact_rate: count_rate(&|r| r.events[0] as f64),
        bond_rate: count_rate(&|r| r.events[1] as f64),
        bounce_rate: count_rate(&|r| r.events[2] as f64),
        fragment_rate: count_rate(&|r| r.events[3] as f64),
        kernel: None,
    }
}
