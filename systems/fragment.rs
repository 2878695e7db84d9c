//! Stage 4 — fragmentation (docs/model.md §7, P04 §5).
//!
//! For every body that took part in an impact this step (a merged body counts the
//! energy of both partners), with δK the kinetic energy it lost in the pair's
//! centre-of-mass frame (frame-independent; P04 Remark 5.1 works in that frame),
//! b0 its radius and V0 = (4/3)π b0³: x = δK b0 / (3 γ V0) (P04 (5.2)) and
//! k = ⌊(1 + x)³⌋. It fragments when k ≥ 2 and n ≥ 2, into p = min(k, ⌊n⌋) equal
//! spheres with equal shares of mass, momentum and primaries, the parent's
//! velocity, placed around the parent's centre without overlapping each other.
//! The surface energy of the p pieces, δZ = γ 4π b0² (p^{1/3} − 1) ≤ δK, is taken
//! from their heat (P04 (6.8)). Pieces get new ids; the parent is despawned. Quantities
//! an extension carries (engine/carried.rs) are split by their rules.
//!
//! Reads: [`ImpactRecords`] (after merging). Writes: despawns/spawns bodies,
//! [`Counters`], [`EnergyLedger`], [`IdAllocator`], [`SimClock::bodies_reshaped`],
//! [`StepEvents`] (pieces spawned, parent removed); one [`FragmentMessage`] per
//! fragmentation when an extension subscribed (engine/hooks.rs).

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::scene::{Material, MergeMode, Physics};
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};

use agglo_engine::params::{RunBooks, SceneConstants};
use glam::DVec3;

use agglo_engine::carried::{CarriedState, Split, queue_split};
use agglo_engine::components::{
    BodyState, Mass, Particle, ParticleId, Position, Primaries, Radius, Temperature, Velocity,
};
use agglo_engine::hooks::{FragmentMessage, Messages};
use agglo_engine::resources::{IdAllocator, ImpactRecords};

pub use agglo_engine::laws::fragmentation::{piece_count, surface_energy};

/// `count` unit directions spread evenly over the sphere (the Fibonacci lattice).
fn fibonacci_directions(count: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Offsets of `count` pieces of radius `piece_radius` around a centre, pairwise
/// non-overlapping (Fibonacci-sphere directions scaled so the closest pair just touches).
pub fn piece_offsets(count: usize, piece_radius: f64) -> Vec<DVec3> {
    if count <= 1 {
        return vec![DVec3::ZERO; count];
    }
    let dirs = fibonacci_directions(count);
    let closest = closest_distance(&dirs);
    // Slightly more than touching so rounding never makes the pieces overlap.
    let scale = 2.0 * piece_radius * (1.0 + 1e-9) / closest;
    dirs.into_iter().map(|d| d * scale).collect()
}

/// The smallest distance between two of `points` (Fibonacci-sphere points), the same value
/// the all-pairs minimum gives, in O(n log n): an upper bound U from the pairs a
/// Fibonacci number of indices apart (the Fibonacci sphere's near neighbours), then a
/// hash grid of cells U wide, in which any pair closer than U is in neighbouring cells.
/// The all-pairs loop took 23 s for a body of 3e4 primaries and minutes for 1e5.
pub fn closest_distance(points: &[DVec3]) -> f64 {
    let n = points.len();
    let mut upper = f64::INFINITY;
    let (mut step, mut next) = (1usize, 2usize);
    while step < n {
        for i in 0..n - step {
            upper = upper.min(points[i].distance(points[i + step]));
        }
        (step, next) = (next, step + next);
    }
    if !(upper > 0.0 && upper.is_finite()) {
        return upper;
    }
    // Cells a little wider than U, so rounding never puts a pair closer than U two
    // cells apart.
    let width = upper * (1.0 + 1e-9);
    let cell = |p: DVec3| {
        let c = (p / width).floor();
        (c.x as i64, c.y as i64, c.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<usize>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i);
    }
    let mut closest = upper;
    for (i, &p) in points.iter().enumerate() {
        let (x, y, z) = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(members) = grid.get(&(x + dx, y + dy, z + dz)) else {
                        continue;
                    };
                    for &j in members {
                        if j > i {
                            closest = closest.min(p.distance(points[j]));
                        }
                    }
                }
            }
        }
    }
    closest
}

/// What fragmentation reads of a body it may break (the pieces are new bodies).
#[derive(QueryData)]
pub struct FragmentBody {
    /// The body's stable id ([`ParticleId`]).
    pub id: &'static ParticleId,
    /// Position [m].
    pub position: &'static Position,
    /// Velocity [m/s].
    pub velocity: &'static Velocity,
    /// Mass [kg].
    pub mass: &'static Mass,
    /// Radius [m].
    pub radius: &'static Radius,
    /// Temperature θ [K].
    pub temperature: &'static Temperature,
    /// The primary grains it is made of.
    pub primaries: &'static Primaries,
}

type FragmentQuery<'w, 's> = Query<'w, 's, FragmentBody, With<Particle>>;

/// Stage 4 as a system: break every body of this step's impacts whose lost energy δK
/// exceeds its fracture threshold into pieces (docs/model.md §7), booking the fracture
/// energy [J].
#[allow(clippy::too_many_arguments)] // a system: each parameter is one resource it uses
pub fn fragment_bodies(
    records: Res<ImpactRecords>,
    scene: SceneConstants,
    bodies: FragmentQuery,
    mut ids: ResMut<IdAllocator>,
    books: RunBooks,
    mut commands: Commands,
    mut absorbed: Local<Vec<(u64, Entity, f64)>>,
    mut messages: Option<ResMut<Messages<FragmentMessage>>>,
    carried: Option<Res<CarriedState>>,
) {
    let SceneConstants {
        material, geometry, ..
    } = scene;
    let RunBooks {
        mut clock,
        mut counters,
        mut ledger,
        mut changed,
        mut events,
    } = books;
    if records.records.is_empty() {
        return;
    }
    // (stable id, entity, absorbed energy): a merged pair is one body (b despawned).
    absorbed.clear();
    for r in &records.records {
        let merged = r.bonded && bodies.get(r.b).is_err();
        if merged {
            absorbed.push((r.id_a, r.a, r.lost_a + r.lost_b));
        } else {
            absorbed.push((r.id_a, r.a, r.lost_a));
            absorbed.push((r.id_b, r.b, r.lost_b));
        }
    }
    // Id allocation order must not depend on query order.
    absorbed.sort_by_key(|x| x.0);
    for &(_, entity, energy) in absorbed.iter() {
        let Ok(FragmentBodyItem {
            id,
            position: p,
            velocity: v,
            mass: m,
            radius: b,
            temperature: t,
            primaries: n,
        }) = bodies.get(entity)
        else {
            continue;
        };
        let k = piece_count(energy, b.0, material.surface_energy());
        if k < 2 || n.0 < 2.0 {
            continue;
        }
        let pieces = k.min(n.0.floor() as u64).max(2);
        let dz = surface_energy(material.surface_energy(), b.0, pieces);
        let theta = t.0 - dz / (m.0 * material.C);
        // Mass and primaries split by mass: equal shares.
        let piece_mass = Split::ByMass.split(m.0, pieces);
        let piece_radius = material.radius_of_mass(piece_mass);
        let first_piece = ids.next;
        for offset in piece_offsets(pieces as usize, piece_radius) {
            let state = BodyState {
                id: ids.allocate(),
                position: geometry.wrap(p.0 + offset),
                velocity: v.0,
                mass: piece_mass,
                radius: piece_radius,
                temperature: theta,
                hardness: material.hardness(theta),
                primaries: Split::ByMass.split(n.0, pieces),
            };
            // Pieces are placed now: their state holds at the current time.
            events
                .spawned
                .push(commands.spawn(state.bundle_at(clock.time)).id());
        }
        if carried.is_some() {
            // The extension's quantities, by their rules, before the parent is despawned.
            let spawned = &events.spawned;
            queue_split(
                &mut commands,
                entity,
                spawned[spawned.len() - pieces as usize..].to_vec(),
            );
        }
        if let Some(messages) = messages.as_mut() {
            messages.write(FragmentMessage {
                time: clock.time,
                parent: id.0,
                children: (first_piece..ids.next).collect(),
                parent_mass: m.0,
            });
        }
        commands.entity(entity).despawn();
        events.despawned.push(id.0);
        counters.fragmentations += 1;
        counters.fragments_created += pieces;
        ledger.fracture_energy += dz;
        clock.bodies_reshaped = true;
        changed.0 = true;
    }
}

/// Fragmentation (stage 4); not scheduled when γ = ∞.
pub struct FragmentPlugin;
impl SimPlugin for FragmentPlugin {
    fn name(&self) -> &'static str {
        "fragment"
    }
    fn build(&self, sim: &mut SimBuilder) {
        match fragmentation_off(sim.resource::<Material>(), sim.resource::<Physics>()) {
            Some(why) => sim.leave_out(format!("fragmentation off: {why}")),
            // Rigid scenes break aggregates into their primaries (docs/model.md §6.1).
            None if sim.resource::<Physics>().merge_mode == MergeMode::Rigid => sim
                .add_core_systems(
                    StepSystems::Fragment,
                    crate::fragment_rigid::fragment_aggregates,
                ),
            None => sim.add_core_systems(StepSystems::Fragment, fragment_bodies),
        };
    }
}

/// True when the plugin schedules fragmentation for a scene of this material and
/// physics (an output that bins sizes asks it: fragments break primaries into parts).
pub fn scene_fragments(material: &Material, physics: &Physics) -> bool {
    fragmentation_off(material, physics).is_none()
}

/// Why the scene has no fragmentation, if it has none.
fn fragmentation_off(material: &Material, physics: &Physics) -> Option<&'static str> {
    if material.surface_energy() == f64::INFINITY {
        Some("γ = ∞ (material.gamma = null)")
    } else if !physics.fragmentation {
        Some("physics.fragmentation = false")
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surface_energy_never_exceeds_the_absorbed_energy() {
        for &energy in &[1e-3, 1.0, 10.0, 1e3] {
            let k = piece_count(energy, 1e-3, 1.0);
            assert!(surface_energy(1.0, 1e-3, k) <= energy * (1.0 + 1e-12));
        }
    }

    #[test]
    fn the_closest_distance_is_the_all_pairs_minimum_bit_for_bit() {
        for count in [2, 3, 5, 17, 100, 1000, 2500] {
            let dirs = fibonacci_directions(count);
            let mut brute = f64::INFINITY;
            for i in 0..count {
                for j in i + 1..count {
                    brute = brute.min(dirs[i].distance(dirs[j]));
                }
            }
            assert_eq!(
                closest_distance(&dirs).to_bits(),
                brute.to_bits(),
                "{count}"
            );
        }
    }

    #[test]
    fn pieces_do_not_overlap() {
        for count in 2..40 {
            let offsets = piece_offsets(count, 1.0);
            for i in 0..count {
                for j in i + 1..count {
                    assert!(offsets[i].distance(offsets[j]) >= 2.0);
                }
            }
        }
    }
}
