//! Overlapping placed bodies pushed apart, so that the end state of a run can seed a
//! new scene (issue 37 item 9).
//!
//! `cloud.bodies` refuses overlapping pairs (engine/cloud.rs). A run's end state can
//! hold some: a merged body grows at its pair's centre of mass and may reach into a
//! neighbour, which the engine meets as a contact (sticky runs: 1–8 such pairs per 5000
//! bodies, centres at 0.85 of the radii sum). [`separate_overlaps`] moves each
//! overlapping pair apart along its line of centres, mass-weighted as the engine's own
//! overlap removal (docs/model.md §5.3: the pair's centre of mass stays), to contact
//! plus 1e-9 of the radii sum, and repeats until no pair overlaps. Velocities, masses,
//! temperatures and ids are left alone.

use glam::DVec3;

use crate::scenario::Scenario;
use agglo_engine::laws::grid::NeighbourGrid;

/// Rounds of pushing before giving up: a pushed pair can meet a third body, but in a
/// dilute end state one or two rounds suffice.
const MAX_ROUNDS: usize = 1000;

/// The relative clearance left between a pushed pair (so that rounding cannot leave it
/// overlapping by an ulp).
const CLEARANCE: f64 = 1e-9;

/// Push apart the overlapping pairs of `s.cloud.bodies` (radius and mass of each as
/// their check reads them: given, or from the primaries and `material.rho`) in the
/// periodic box. Returns how many pair pushes it took (0: nothing overlapped, the
/// scene is untouched); an error when overlaps remain after many rounds (a jammed
/// packing that cannot be separated by small moves).
pub fn separate_overlaps(s: &mut Scenario) -> Result<usize, String> {
    let m0 = s.primary_mass();
    let material = s.material;
    let geometry = s.domain;
    let bodies = &mut s.cloud.bodies;
    let mass: Vec<f64> = bodies
        .iter()
        .map(|b| b.mass.unwrap_or(m0 * b.primaries))
        .collect();
    let radius: Vec<f64> = bodies
        .iter()
        .zip(&mass)
        .map(|(b, &m)| b.radius.unwrap_or(material.radius_of_mass(m)))
        .collect();
    let mut positions: Vec<DVec3> = bodies
        .iter()
        .map(|b| DVec3::from_array(b.position))
        .collect();
    let mut grid = NeighbourGrid::default();
    let mut pairs = Vec::new();
    let mut pushes = 0;
    for _ in 0..MAX_ROUNDS {
        grid.pairs_within(&positions, &radius, geometry.half_width, 0.0, &mut pairs);
        let mut overlapping: Vec<_> = pairs.iter().filter(|p| p.gap < 0.0).collect();
        if overlapping.is_empty() {
            for (b, p) in bodies.iter_mut().zip(&positions) {
                b.position = p.to_array();
            }
            return Ok(pushes);
        }
        // In index order, so the result depends only on the bodies.
        overlapping.sort_by_key(|p| (p.i.min(p.j), p.i.max(p.j)));
        for p in overlapping {
            let (i, j) = (p.i as usize, p.j as usize);
            let contact = radius[i] + radius[j];
            // Recomputed: an earlier push this round may have moved either body.
            let d = geometry.min_image(positions[j] - positions[i]);
            let distance = d.length();
            let need = contact * (1.0 + CLEARANCE) - distance;
            if need <= 0.0 {
                continue;
            }
            // Coincident centres: any direction will do; x, for determinism.
            let n = if distance > 0.0 {
                d / distance
            } else {
                DVec3::X
            };
            let total = mass[i] + mass[j];
            positions[i] = geometry.wrap(positions[i] - n * (need * mass[j] / total));
            positions[j] = geometry.wrap(positions[j] + n * (need * mass[i] / total));
            pushes += 1;
        }
    }
    Err(format!(
        "cloud.bodies: overlapping pairs remain after {MAX_ROUNDS} rounds of pushing \
         them apart (a packing too dense to separate by small moves)"
    ))
}
