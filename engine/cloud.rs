//! The cloud generator (docs/model.md §2): N equal primary spheres placed at random
//! without overlap in the periodic cube (random sequential addition over a cell
//! grid), with velocities v_i = v̄ + v_rel ∘ λ_i, all from the scene's one RNG.
//!
//! Draw order (part of the reproducibility contract): positions for particles
//! 0, 1, … (each retried until it fits), then velocities for 0, 1, … with λ drawn
//! x, y, z.

use glam::DVec3;
use rand::{Rng, RngExt};

use crate::components::BodyState;
use crate::error::SimError;
use crate::scene::{BoxGeometry, Material};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Attempts allowed per particle on average before placement is declared impossible.
const ATTEMPTS_PER_PARTICLE: u64 = 2_000;

/// The initial cloud of N equal primary spheres (docs/model.md §2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Cloud {
    /// Number of primary particles N.
    pub count: usize,
    /// Primary size: give exactly one of `radius` [m] or `size_ratio`
    /// s = d / (V/N)^(1/3) (volume fraction (π/6) s³).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Size ratio s = 2b / (V/N)^(1/3), 0 < s < 0.9 (P04's L and P02's s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size_ratio: Option<f64>,
    /// Mean velocity v̄ [m/s].
    #[serde(default)]
    pub v_mean: [f64; 3],
    /// Relative velocity amplitudes v_rel [m/s] per component.
    pub v_rel: [f64; 3],
    /// Distribution of λ_i per component: `symmetric` = U[−1, 1] (P04), `positive` = U[0, 1] (P02).
    #[serde(default)]
    pub velocity_distribution: VelocityDistribution,
    /// Explicit bodies instead of a random cloud (for set-ups such as a head-on pair):
    /// when given, its length must equal `count`, and `v_mean`/`v_rel` are ignored.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<PlacedBody>,
}

/// One explicitly placed body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlacedBody {
    /// Centre [m], inside [−D, D]³.
    pub position: [f64; 3],
    /// Velocity [m/s].
    pub velocity: [f64; 3],
    /// Primary grains in the body (mass = primaries · m_primary), ≥ 1.
    #[serde(default = "crate::scene::one")]
    pub primaries: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum VelocityDistribution {
    /// λ ~ U[−1, 1] per component (P04).
    #[default]
    Symmetric,
    /// λ ~ U[0, 1] per component (P02).
    Positive,
}

/// One primary grain of the scene: derived once from the `cloud`, `box` and `material`
/// sections (the radius given or implied by the size ratio, and its mass).
#[derive(bevy_ecs::prelude::Resource, Debug, Clone, Copy, PartialEq)]
pub struct PrimaryGrain {
    /// Radius b0 [m].
    pub radius: f64,
    /// Mass 4/3 π b0³ ρ [kg].
    pub mass: f64,
}

impl PrimaryGrain {
    /// The primary grain of `cloud` in `domain`, of density ρ = `material.rho`.
    pub fn of(cloud: &Cloud, domain: &BoxGeometry, material: &Material) -> Self {
        let b0 = cloud.primary_radius(domain);
        Self {
            radius: b0,
            mass: 4.0 / 3.0 * std::f64::consts::PI * b0.powi(3) * material.rho,
        }
    }
}

impl Cloud {
    /// Primary radius b0 [m] in the box `domain`, from `radius` or `size_ratio`.
    pub fn primary_radius(&self, domain: &BoxGeometry) -> f64 {
        match (self.radius, self.size_ratio) {
            (Some(b), _) => b,
            (None, Some(s)) => 0.5 * s * self.spacing(domain),
            (None, None) => f64::NAN, // rejected by validation
        }
    }

    /// Volume fraction of the initial cloud in the box `domain`.
    pub fn volume_fraction(&self, domain: &BoxGeometry) -> f64 {
        let b = self.primary_radius(domain);
        let side = domain.side();
        self.count as f64 * 4.0 / 3.0 * std::f64::consts::PI * b.powi(3) / side.powi(3)
    }

    /// The size ratio s = 2 b / (V/N)^(1/3) of primaries of radius `b` [m].
    pub fn size_ratio_of_radius(&self, b: f64, domain: &BoxGeometry) -> f64 {
        2.0 * b / self.spacing(domain)
    }

    /// Mean spacing (V/N)^(1/3) of N primaries in the box [m].
    fn spacing(&self, domain: &BoxGeometry) -> f64 {
        (domain.side().powi(3) / self.count as f64).cbrt()
    }
}

/// Generate the initial bodies, ids 0..N.
pub fn generate_cloud(
    cloud: &Cloud,
    domain: &BoxGeometry,
    material: &Material,
    primary: &PrimaryGrain,
    rng: &mut impl Rng,
) -> Result<Vec<BodyState>, SimError> {
    let count = cloud.count;
    let b = primary.radius;
    if !cloud.bodies.is_empty() {
        return placed_bodies(cloud, domain, material, primary);
    }
    let half = domain.half_width;
    let positions =
        place_spheres(count, b, half, rng).map_err(|(placed, attempts)| SimError::Placement {
            placed,
            requested: count,
            radius: b,
            volume_fraction: cloud.volume_fraction(domain),
            attempts,
        })?;
    let c = cloud;
    let lambda = |rng: &mut dyn FnMut() -> f64| DVec3::new(rng(), rng(), rng());
    let theta = material.theta0;
    let bodies = positions
        .into_iter()
        .enumerate()
        .map(|(i, position)| {
            let mut draw = || match c.velocity_distribution {
                VelocityDistribution::Symmetric => rng.random_range(-1.0..=1.0),
                VelocityDistribution::Positive => rng.random_range(0.0..=1.0),
            };
            let l = lambda(&mut draw);
            BodyState {
                id: i as u64,
                position,
                velocity: DVec3::from_array(c.v_mean) + DVec3::from_array(c.v_rel) * l,
                mass: primary.mass,
                radius: b,
                temperature: theta,
                hardness: material.hardness(theta),
                primaries: 1.0,
            }
        })
        .collect();
    Ok(bodies)
}

/// The scenario's explicit bodies; fails if two of them overlap.
fn placed_bodies(
    cloud: &Cloud,
    geometry: &BoxGeometry,
    material: &Material,
    primary: &PrimaryGrain,
) -> Result<Vec<BodyState>, SimError> {
    let theta = material.theta0;
    let bodies: Vec<BodyState> = cloud
        .bodies
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mass = primary.mass * p.primaries;
            BodyState {
                id: i as u64,
                position: geometry.wrap(DVec3::from_array(p.position)),
                velocity: DVec3::from_array(p.velocity),
                mass,
                radius: material.radius_of_mass(mass),
                temperature: theta,
                hardness: material.hardness(theta),
                primaries: p.primaries,
            }
        })
        .collect();
    // Set-up only (explicit lists are small): a direct overlap check.
    for i in 0..bodies.len() {
        for j in i + 1..bodies.len() {
            let d = geometry
                .min_image(bodies[j].position - bodies[i].position)
                .length();
            if d < bodies[i].radius + bodies[j].radius {
                return Err(SimError::Overlap {
                    i,
                    j,
                    distance: d,
                    contact: bodies[i].radius + bodies[j].radius,
                });
            }
        }
    }
    Ok(bodies)
}

/// Random sequential addition of `count` spheres of radius `b` in [−half, half)³,
/// periodic. Err((placed, attempts)) when the attempt budget runs out.
pub fn place_spheres(
    count: usize,
    b: f64,
    half: f64,
    rng: &mut impl Rng,
) -> Result<Vec<DVec3>, (usize, u64)> {
    let side = 2.0 * half;
    let min_dist2 = (2.0 * b) * (2.0 * b);
    // Cells at least one diameter wide: overlaps can only come from the 27 around.
    let n = ((side / (2.0 * b)).floor() as usize).clamp(1, 256);
    let width = side / n as f64;
    let mut cells: Vec<Vec<u32>> = vec![Vec::new(); n * n * n];
    let mut positions: Vec<DVec3> = Vec::with_capacity(count);
    let budget = ATTEMPTS_PER_PARTICLE * count as u64 + 10_000;
    let mut attempts = 0u64;
    let coord = |x: f64| (((x + half) / width).floor() as isize).clamp(0, n as isize - 1);
    while positions.len() < count {
        if attempts >= budget {
            return Err((positions.len(), attempts));
        }
        attempts += 1;
        let r = DVec3::new(
            rng.random_range(-half..half),
            rng.random_range(-half..half),
            rng.random_range(-half..half),
        );
        let c = [coord(r.x), coord(r.y), coord(r.z)];
        let overlaps = |j: u32| {
            let d = positions[j as usize] - r;
            let d = d - side * (d / side).round();
            d.length_squared() < min_dist2
        };
        let fits = if n < 3 {
            // Too few cells for a 27-cell window without repeats: check everything.
            !(0..positions.len() as u32).any(overlaps)
        } else {
            let wrap = |k: usize, d: isize| (c[k] + d).rem_euclid(n as isize) as usize;
            let mut fits = true;
            'search: for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let cell = (wrap(2, dz) * n + wrap(1, dy)) * n + wrap(0, dx);
                        if cells[cell].iter().any(|&j| overlaps(j)) {
                            fits = false;
                            break 'search;
                        }
                    }
                }
            }
            fits
        };
        if fits {
            let cell = ((c[2] as usize * n) + c[1] as usize) * n + c[0] as usize;
            cells[cell].push(positions.len() as u32);
            positions.push(r);
        }
    }
    Ok(positions)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::StdRng;

    #[test]
    fn placed_spheres_never_overlap_at_volume_fraction_0_27() {
        // s = 0.8 → v_f = (π/6)·0.512 ≈ 0.268, the papers' upper end.
        let count = 1000;
        let half = 1.0;
        let spacing = (8.0f64 / count as f64).cbrt();
        let b = 0.4 * spacing;
        let mut rng = StdRng::seed_from_u64(3);
        let pos = place_spheres(count, b, half, &mut rng).expect("places");
        let side = 2.0;
        for i in 0..count {
            for j in i + 1..count {
                let d = pos[j] - pos[i];
                let d = d - side * (d / side).round();
                assert!(d.length() >= 2.0 * b, "{i} and {j} overlap");
            }
        }
    }

    #[test]
    fn impossible_packing_is_reported() {
        let mut rng = StdRng::seed_from_u64(1);
        // v_f ≈ 0.52: far past random sequential addition's jamming limit (~0.38).
        let spacing = (8.0f64 / 200.0).cbrt();
        let err = place_spheres(200, 0.499 * spacing, 1.0, &mut rng).unwrap_err();
        assert!(err.0 < 200);
    }
}
