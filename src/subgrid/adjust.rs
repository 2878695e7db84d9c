//! Boxes that persist across macro steps (issue 37 item 3; docs/model.md §15).
//!
//! With [`super::Coupling::persist`], a cell keeps its boxes, as a closed cell does, and
//! remembers what its flow solver holds after applying the step's rates
//! ([`apply_rates`]). At the next step the solver's input differs from that only by
//! what transport changed; each box is adjusted by exactly that difference, class by
//! class, and otherwise continues: so what the box forgets scales with what transport
//! changed, not with the whole box, and with no transport the cell is the closed cell.
//!
//! Per class, from the remembered state e to the input a (each body's class by its
//! mass):
//! - **fewer bodies** (n_a < n_e): each body of the class is removed with probability
//!   1 − n_a/n_e (thinning: the expected count is n_a V);
//! - **more bodies** (n_a > n_e): Poisson((n_a − n_e)V) new bodies of mass m_a, drawn as
//!   lifting draws them (Maxwellian about u_a at T_a, θ_a), placed at random free spots
//!   among the kept bodies;
//! - **the kept bodies' state**: velocities shifted by u_a − u_e and their fluctuations
//!   about the box's class mean scaled per axis by √(T_a,ii/T_e,ii) (the diagonal of
//!   the granular temperature tensor, `ClassInput::granular_temperature_axes`);
//!   temperatures shifted by θ_a − θ_e.
//!
//! A class whose input equals the remembered state bit for bit is left untouched; when
//! every class is, the box resumes its snapshot exactly as a closed cell does (cell.rs).
//! Otherwise the adjusted bodies become a new scene (overlaps left by merges pushed
//! apart, `crate::separate`), which runs over Δt from a fresh clock.

use crate::cloud::PlacedBody;
use crate::scenario::Scenario;
use agglo_engine::restart::BodyRow;

use super::config::Coupling;
use super::error::SubgridError;
use super::exchange::{CellInput, CellOutput, ClassInput};
use super::lift::{PlacementGrid, box_scene, is_trace, radius_of};
use super::stream::Stream;

/// What a flow solver without transport holds after adding Δt times `out`'s rates to
/// `input`, per class: n ← n + Δt·number rate (clipped at 0), ρ, the momentum
/// ρu, the granular energy ½ρ·3T and the thermal energy Cρθ likewise, and from them the
/// representative mass ρ/n (kept inside the class's edges), u, T and θ; the anisotropy
/// is the boxes' measured T_xx : T_yy : T_zz at the end (the input's where the class was
/// not measured). A class left without bodies or mass keeps its old mass, velocity,
/// temperatures and anisotropy.
pub fn apply_rates(c: &Coupling, input: &CellInput, out: &CellOutput) -> CellInput {
    let dt = input.dt;
    let heat_capacity = c.base.material.C;
    let m0 = c.primary().1;
    let classes = input
        .classes
        .iter()
        .zip(&out.classes)
        .enumerate()
        .map(|(k, (a, o))| {
            let n = (a.number_density + dt * o.number_rate.mean).max(0.0);
            let rho0 = a.number_density * a.mass;
            let rho = rho0 + dt * o.mass_rate.mean;
            if !(n > 0.0 && rho > 0.0) {
                return ClassInput {
                    number_density: n,
                    ..*a
                };
            }
            let p = [0, 1, 2].map(|x| rho0 * a.velocity[x] + dt * o.momentum_rate[x].mean);
            let g = 1.5 * rho0 * a.granular_temperature + dt * o.fluctuation_energy_rate.mean;
            let heat = heat_capacity * rho0 * a.temperature + dt * o.thermal_energy_rate.mean;
            let (lo, hi) = (c.edges[k].max(m0), c.edges[k + 1]);
            let mass = if k + 1 == c.classes() {
                (rho / n).max(lo)
            } else {
                (rho / n).clamp(lo, hi * (1.0 - 1e-12))
            };
            let temperature = heat / (heat_capacity * rho);
            let axes = o.granular_temperature_axes.map(|s| s.mean);
            let measured =
                axes.iter().all(|t| t.is_finite() && *t >= 0.0) && axes.iter().sum::<f64>() > 0.0;
            ClassInput {
                number_density: n,
                mass,
                velocity: p.map(|x| x / rho),
                temperature: if temperature > 0.0 {
                    temperature
                } else {
                    a.temperature
                },
                granular_temperature: (g / (1.5 * rho)).max(0.0),
                granular_anisotropy: if measured {
                    axes
                } else {
                    a.granular_anisotropy
                },
            }
        })
        .collect();
    CellInput {
        classes,
        ..input.clone()
    }
}

/// The scene that continues a kept box's `rows` (its bodies at the end of the last
/// step) under `input`, adjusted from the remembered `expected` state (module doc), in a
/// cube of volume `volume` [m³]; draws from `seed`.
pub(crate) fn adjusted_box(
    c: &Coupling,
    cell: u64,
    input: &CellInput,
    expected: &CellInput,
    volume: f64,
    seed: u64,
    rows: &[BodyRow],
) -> Result<Scenario, SubgridError> {
    let side = volume.cbrt();
    let m0 = c.primary().1;
    let rho = c.base.material.rho;
    let mut rng = Stream(seed);
    let class_of: Vec<usize> = rows.iter().map(|b| c.class_of(b.mass)).collect();
    let mut bodies: Vec<PlacedBody> = Vec::with_capacity(rows.len());
    let mut fresh: Vec<(usize, u64)> = Vec::new(); // (class, how many) to place
    let mut kept: Vec<(usize, &BodyRow)> = Vec::new();
    for (k, (a, e)) in input.classes.iter().zip(&expected.classes).enumerate() {
        let members: Vec<&BodyRow> = rows
            .iter()
            .zip(&class_of)
            .filter(|(_, ck)| **ck == k)
            .map(|(b, _)| b)
            .collect();
        if a == e {
            kept.extend(members.into_iter().map(|b| (k, b)));
            continue;
        }
        let keep = if a.number_density < e.number_density && e.number_density > 0.0 {
            a.number_density / e.number_density
        } else {
            1.0
        };
        for b in members {
            if keep >= 1.0 || rng.uniform() < keep {
                kept.push((k, b));
            }
        }
        if a.number_density > e.number_density && !is_trace(a.number_density, volume) {
            fresh.push((
                k,
                rng.poisson((a.number_density - e.number_density) * volume),
            ));
        }
    }
    // The kept bodies' new states, class by class about the box's class means.
    let mut mean = vec![[0.0f64; 3]; c.classes()];
    let mut mass = vec![0.0f64; c.classes()];
    for (k, b) in &kept {
        mass[*k] += b.mass;
        for (p, v) in mean[*k].iter_mut().zip(b.velocity) {
            *p += b.mass * v;
        }
    }
    for (k, b) in &kept {
        let (a, e) = (&input.classes[*k], &expected.classes[*k]);
        let (velocity, temperature) = if a == e {
            (b.velocity, b.temperature)
        } else {
            let m = mean[*k].map(|p| p / mass[*k]);
            let (ta, te) = (a.granular_temperature_axes(), e.granular_temperature_axes());
            let scale = [0, 1, 2].map(|x| {
                if te[x] > 0.0 {
                    (ta[x] / te[x]).sqrt()
                } else {
                    1.0
                }
            });
            let v = [0, 1, 2].map(|x| {
                m[x] + (a.velocity[x] - e.velocity[x]) + scale[x] * (b.velocity[x] - m[x])
            });
            let theta = b.temperature + (a.temperature - e.temperature);
            (v, if theta > 0.0 { theta } else { b.temperature })
        };
        bodies.push(PlacedBody {
            position: b.position,
            velocity: Some(velocity),
            primaries: b.primaries,
            id: Some(b.id),
            temperature: Some(temperature),
            mass: Some(b.mass),
            radius: None,
        });
    }
    // New bodies among the kept ones, in class order.
    let placed: u64 = fresh.iter().map(|f| f.1).sum();
    let largest = bodies
        .iter()
        .map(|b| radius_of(b.mass.unwrap_or(m0), rho))
        .chain(
            fresh
                .iter()
                .map(|&(k, _)| radius_of(input.classes[k].mass, rho)),
        )
        .fold(0.0, f64::max);
    let mut grid = PlacementGrid::new(side, 2.0 * largest, bodies.len() + placed as usize);
    for b in &bodies {
        grid.occupy(b.position, radius_of(b.mass.unwrap_or(m0), rho));
    }
    let mut next_id = rows.iter().map(|b| b.id + 1).max().unwrap_or(0);
    for &(k, count) in &fresh {
        let class = &input.classes[k];
        let b = radius_of(class.mass, rho);
        let sd = class.granular_temperature_axes().map(f64::sqrt);
        for _ in 0..count {
            let position = grid.place(b, &mut rng).ok_or_else(|| {
                SubgridError::input(
                    cell,
                    format!("classes[{k}].number_density"),
                    format!("{:e}", class.number_density),
                    "no room left in the kept box for the bodies transport brought in",
                )
            })?;
            bodies.push(PlacedBody {
                position,
                velocity: Some([0, 1, 2].map(|x| class.velocity[x] + sd[x] * rng.normal())),
                primaries: (class.mass / m0).max(1.0),
                id: Some(next_id),
                temperature: Some(class.temperature),
                mass: Some(class.mass),
                radius: None,
            });
            next_id += 1;
        }
    }
    let mut s = box_scene(c, input, side, seed, bodies);
    crate::separate::separate_overlaps(&mut s).map_err(|reason| SubgridError::Run {
        cell,
        replica: 0,
        reason,
    })?;
    Ok(s)
}
