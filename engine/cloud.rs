//! The cloud generator (docs/model.md §2): N equal primary spheres placed at random
//! without overlap in the periodic cube (random sequential addition over a cell
//! grid), with velocities v_i = v̄ + v_rel ∘ λ_i (or Maxwellian, at a given granular
//! temperature), all from the scene's one RNG; or explicit bodies (`cloud.bodies`, or
//! loaded from a table by the driver: `cloud.from_file`), checked by [`placed_bodies`]
//! — in the box, distinct ids, mass and radius consistent, no two overlapping (over
//! the neighbour grid: O(N)) — the one check both `agglo validate` and a run make.
//!
//! Draw order (part of the reproducibility contract): positions for particles
//! 0, 1, … (each retried until it fits), then velocities for 0, 1, … with λ drawn
//! x, y, z (Maxwellian: one Box–Muller normal per component, from two uniforms).
//! Explicit bodies draw only the velocities they lack, in list order.

use glam::DVec3;
use rand::{Rng, RngExt};

use crate::components::BodyState;
use crate::error::{SimError, ValidationIssue};
use crate::issues::{Issues, norm};
use crate::laws::grid::NeighbourGrid;
use crate::scene::MAX_SPEED;
use crate::scene::{BoxGeometry, Material};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Attempts allowed per particle on average before placement is declared impossible.
const ATTEMPTS_PER_PARTICLE: u64 = 2_000;

/// The initial cloud of N equal primary spheres (docs/model.md §2), or explicit bodies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Cloud {
    /// Number of primary particles N; with explicit bodies (`bodies`, `from_file`) it may
    /// be left out (0), and is then the number of bodies given.
    #[serde(default)]
    pub count: usize,
    /// Primary size: give exactly one of `radius` [m] or `size_ratio`
    /// s = d / (V/N)^(1/3) (volume fraction (π/6) s³). With `from_file`, give the
    /// `radius` b0 of the run that wrote the file (a size ratio would be taken of the
    /// file's body count).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Size ratio s = 2b / (V/N)^(1/3), 0 < s < 0.9 (P04's L and P02's s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size_ratio: Option<f64>,
    /// Mean velocity v̄ [m/s] of the velocities drawn.
    #[serde(default)]
    pub v_mean: [f64; 3],
    /// Relative velocity amplitudes v_rel [m/s] per component (`symmetric`, `positive`):
    /// required when velocities are drawn that way, i.e. unless every body is given
    /// with its velocity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v_rel: Option<[f64; 3]>,
    /// Distribution of the velocities drawn: `symmetric` (λ ~ U[−1, 1], P04),
    /// `positive` (λ ~ U[0, 1], P02) or `maxwell` (Gaussian about v̄ at
    /// `granular_temperature`).
    #[serde(default)]
    pub velocity_distribution: VelocityDistribution,
    /// Granular temperature T_g [m²/s²] of `maxwell`: each velocity component is drawn
    /// from a normal distribution of mean v̄ and variance T_g (so ⟨|v − v̄|²⟩ = 3 T_g).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub granular_temperature: Option<f64>,
    /// Shift every velocity by the same vector so that the total momentum Σ m v is zero
    /// (to rounding), after drawing; for generated and explicit bodies alike. Needs v̄ = 0.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub remove_drift: bool,
    /// Explicit bodies instead of a random cloud (for set-ups such as a head-on pair).
    /// Bodies without a velocity get one drawn from `velocity_distribution`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<PlacedBody>,
    /// Read the explicit bodies from this table (CSV, or Parquet if it ends in
    /// `.parquet`) with the columns of `--final-state` / `--snapshots` (x, y, z required;
    /// vx, vy, vz, id, mass, radius, temperature, primaries optional; hardness follows
    /// θ; a `t` column: the rows of the last t), so a run continues from another's end
    /// state. Loaded when the scenario is (a path relative to the working directory);
    /// the scenario then holds the bodies, and this field is cleared.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_file: Option<String>,
}

impl Cloud {
    /// Range problems of the `cloud` section, by full path (a radius is checked against the box it must fit).
    pub fn issues(&self, domain: &BoxGeometry) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        let c = self;
        // The upper limit is the machine's memory (crate::memory, checked by `run` and
        // `validate` before anything is allocated), and the event core's 32-bit slots.
        if c.count == 0 || c.count >= u32::MAX as usize {
            v.push(
                "cloud.count",
                "1 ≤ N < 2^32 and within the machine's memory (left out only with \
                 cloud.bodies or cloud.from_file)",
                c.count as f64,
            );
        }
        match (c.radius, c.size_ratio) {
            (Some(_), Some(_)) => v.issues.push(ValidationIssue {
                path: "cloud".into(),
                message: "give exactly one of `radius` [m] or `size_ratio`, not both (over a \
                          scenario that gives the other: --set cloud.radius=R --set \
                          cloud.size_ratio=null, or --set cloud.size_ratio=S --set \
                          cloud.radius=null)"
                    .into(),
            }),
            (None, None) => v.issues.push(ValidationIssue {
                path: "cloud".into(),
                message: "give exactly one of `radius` [m] or `size_ratio`".into(),
            }),
            (Some(b), None) => {
                v.positive("cloud.radius", b);
                if b.is_finite() && b > 0.0 && domain.half_width > 0.0 {
                    let s = self.size_ratio_of_radius(b, domain);
                    if s >= 0.9 {
                        v.issues.push(ValidationIssue {
                            path: "cloud.radius".into(),
                            message: format!(
                                "radius {b:e} m gives size ratio s = {s:.4}; allowed s < 0.9 (volume fraction < 0.38)"
                            ),
                        });
                    }
                }
            }
            (None, Some(s)) => v.range_open("cloud.size_ratio", s, 0.0, 0.9, "0 < s < 0.9"),
        }
        for k in 0..3 {
            v.finite(&format!("cloud.v_mean.{k}"), c.v_mean[k]);
        }
        v.below_speed_limit("cloud.v_mean", norm(c.v_mean));
        let maxwell = c.velocity_distribution == VelocityDistribution::Maxwell;
        match c.v_rel {
            Some(v_rel) if maxwell => {
                let _ = v_rel;
                v.issues.push(ValidationIssue {
                    path: "cloud.v_rel".into(),
                    message: "not used by velocity_distribution = \"maxwell\" (give granular_temperature)".into(),
                });
            }
            Some(v_rel) => {
                for (k, &x) in v_rel.iter().enumerate() {
                    v.non_negative(&format!("cloud.v_rel.{k}"), x);
                    v.below_speed_limit(&format!("cloud.v_rel.{k}"), x);
                }
            }
            None if c.draws_uniform_velocities() => v.issues.push(ValidationIssue {
                path: "cloud.v_rel".into(),
                message: "required: velocities are drawn as v̄ + v_rel ∘ λ (a generated cloud, or \
                          explicit bodies without a velocity); give [vx, vy, vz] amplitudes [m/s], \
                          or every body its velocity"
                    .into(),
            }),
            None => {}
        }
        match (maxwell, c.granular_temperature) {
            (true, Some(tg)) => {
                v.non_negative("cloud.granular_temperature", tg);
                v.below_speed_limit("cloud.granular_temperature (as √T_g)", tg.max(0.0).sqrt());
            }
            (true, None) => v.issues.push(ValidationIssue {
                path: "cloud.granular_temperature".into(),
                message: "required by velocity_distribution = \"maxwell\": T_g [m²/s²], the variance of each velocity component".into(),
            }),
            (false, Some(_)) => v.issues.push(ValidationIssue {
                path: "cloud.granular_temperature".into(),
                message: "used only by velocity_distribution = \"maxwell\"".into(),
            }),
            (false, None) => {}
        }
        if c.remove_drift && c.v_mean != [0.0; 3] {
            v.issues.push(ValidationIssue {
                path: "cloud.remove_drift".into(),
                message: format!(
                    "sets the total momentum to zero, which contradicts v_mean = {:?}; give v_mean = [0, 0, 0]",
                    c.v_mean
                ),
            });
        }
        if !c.bodies.is_empty() {
            if c.bodies.len() != c.count {
                v.issues.push(ValidationIssue {
                    path: "cloud.bodies".into(),
                    message: format!(
                        "lists {} bodies but cloud.count = {}; they must agree",
                        c.bodies.len(),
                        c.count
                    ),
                });
            }
            for (i, body) in c.bodies.iter().enumerate() {
                // Paths are formatted only for a body with a problem: 10⁶ bodies are
                // checked in milliseconds, not in the seconds 10⁷ `format!`s take.
                if body_is_plausible(body) {
                    continue;
                }
                for k in 0..3 {
                    v.finite(&format!("cloud.bodies.{i}.position.{k}"), body.position[k]);
                }
                if let Some(velocity) = body.velocity {
                    for (k, &x) in velocity.iter().enumerate() {
                        v.finite(&format!("cloud.bodies.{i}.velocity.{k}"), x);
                    }
                    v.below_speed_limit(&format!("cloud.bodies.{i}.velocity"), norm(velocity));
                }
                if !(body.primaries >= 1.0 && body.primaries.is_finite()) {
                    v.push(
                        &format!("cloud.bodies.{i}.primaries"),
                        "a finite number ≥ 1",
                        body.primaries,
                    );
                }
                if let Some(theta) = body.temperature {
                    v.positive(&format!("cloud.bodies.{i}.temperature"), theta);
                }
                if let Some(m) = body.mass {
                    v.positive(&format!("cloud.bodies.{i}.mass"), m);
                }
                if let Some(b) = body.radius {
                    v.positive(&format!("cloud.bodies.{i}.radius"), b);
                }
            }
        }
        v.issues
    }
}

/// True when none of the per-body checks of [`Cloud::issues`] would complain.
fn body_is_plausible(b: &PlacedBody) -> bool {
    let positive = |x: Option<f64>| x.is_none_or(|x| x.is_finite() && x > 0.0);
    b.position.iter().all(|x| x.is_finite())
        && b.velocity
            .is_none_or(|v| v.iter().all(|x| x.is_finite()) && norm(v) <= MAX_SPEED)
        && b.primaries >= 1.0
        && b.primaries.is_finite()
        && positive(b.temperature)
        && positive(b.mass)
        && positive(b.radius)
}

/// One explicitly placed body.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlacedBody {
    /// Centre [m], inside [−D, D]³.
    pub position: [f64; 3],
    /// Velocity [m/s]; drawn from the cloud's velocity distribution when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Primary grains in the body (mass = primaries · m_primary), ≥ 1.
    #[serde(default = "crate::scene::one")]
    pub primaries: f64,
    /// Stable id (default: the body's index); ids must be distinct.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<u64>,
    /// Temperature θ [K] (default θ0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<f64>,
    /// Mass [kg] (default primaries · m_primary; if given, it must agree to 1e-9).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Radius [m] (default (3m / 4πρ)^(1/3); if given, it must agree to 1e-9).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
}

impl From<&BodyState> for PlacedBody {
    /// A body of a run, placed as it is: every field given (hardness follows from the
    /// temperature), so that a run's state can seed another scene.
    fn from(b: &BodyState) -> Self {
        Self {
            position: b.position.to_array(),
            velocity: Some(b.velocity.to_array()),
            primaries: b.primaries,
            id: Some(b.id),
            temperature: Some(b.temperature),
            mass: Some(b.mass),
            radius: Some(b.radius),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
/// How the initial cloud's velocities are drawn (`cloud.velocity_distribution`): scaled
/// by `cloud.v_rel` [m/s], or at `cloud.granular_temperature` [m²/s²] for `maxwell`.
pub enum VelocityDistribution {
    /// λ ~ U[−1, 1] per component (P04).
    #[default]
    Symmetric,
    /// λ ~ U[0, 1] per component (P02).
    Positive,
    /// Each component ~ N(v̄_k, T_g), T_g = `granular_temperature` [m²/s²].
    Maxwell,
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

/// Relative tolerance of a given mass or radius against the one implied by the
/// primaries (rounding of sums over merges is ~1e-16; a wrong b0 or ρ is off by far more).
pub const CONSISTENCY_TOLERANCE: f64 = 1e-9;

impl Cloud {
    /// True when velocities are drawn from `v_rel` (uniform distributions) for some body:
    /// a generated cloud, or explicit bodies some of which lack a velocity.
    pub fn draws_uniform_velocities(&self) -> bool {
        self.velocity_distribution != VelocityDistribution::Maxwell
            && (self.bodies.is_empty() || self.bodies.iter().any(|b| b.velocity.is_none()))
    }
}

/// Generate the initial bodies, ids 0..N (explicit bodies: their ids).
pub fn generate_cloud(
    cloud: &Cloud,
    domain: &BoxGeometry,
    material: &Material,
    primary: &PrimaryGrain,
    rng: &mut impl Rng,
) -> Result<Vec<BodyState>, SimError> {
    let count = cloud.count;
    let b = primary.radius;
    let mut bodies = if !cloud.bodies.is_empty() {
        let mut bodies = placed_bodies(cloud, domain, material, primary)?;
        for (body, placed) in bodies.iter_mut().zip(&cloud.bodies) {
            if placed.velocity.is_none() {
                body.velocity = draw_velocity(cloud, rng);
            }
        }
        bodies
    } else {
        let half = domain.half_width;
        let positions = place_spheres(count, b, half, rng).map_err(|(placed, attempts)| {
            SimError::Placement {
                placed,
                requested: count,
                radius: b,
                volume_fraction: cloud.volume_fraction(domain),
                attempts,
            }
        })?;
        let theta = material.theta0;
        let hardness = material.hardness(theta);
        // Positions first, then velocities (the draw order above).
        let velocities: Vec<DVec3> = (0..count).map(|_| draw_velocity(cloud, rng)).collect();
        positions
            .into_iter()
            .zip(velocities)
            .enumerate()
            .map(|(i, (position, velocity))| BodyState {
                id: i as u64,
                position,
                velocity,
                mass: primary.mass,
                radius: b,
                temperature: theta,
                hardness,
                primaries: 1.0,
            })
            .collect()
    };
    if cloud.remove_drift {
        remove_drift(&mut bodies);
    }
    Ok(bodies)
}

/// One velocity from the cloud's distribution: v̄ + v_rel ∘ λ, or Maxwellian.
fn draw_velocity(c: &Cloud, rng: &mut impl Rng) -> DVec3 {
    let mean = DVec3::from_array(c.v_mean);
    match c.velocity_distribution {
        VelocityDistribution::Maxwell => {
            let sigma = c.granular_temperature.unwrap_or(0.0).sqrt();
            let mut normal = || {
                // Box–Muller: u1 in (0, 1] keeps the logarithm finite.
                let u1: f64 = 1.0 - rng.random_range(0.0..1.0);
                let u2: f64 = rng.random_range(0.0..1.0);
                (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
            };
            let (x, y, z) = (normal(), normal(), normal());
            mean + sigma * DVec3::new(x, y, z)
        }
        distribution => {
            let mut draw = || match distribution {
                VelocityDistribution::Positive => rng.random_range(0.0..=1.0),
                _ => rng.random_range(-1.0..=1.0),
            };
            let (x, y, z) = (draw(), draw(), draw());
            mean + DVec3::from_array(c.v_rel.unwrap_or_default()) * DVec3::new(x, y, z)
        }
    }
}

/// Subtract the centre-of-mass velocity Σ m v / Σ m from every body (summed in id order).
pub fn remove_drift(bodies: &mut [BodyState]) {
    let mass: f64 = bodies.iter().map(|b| b.mass).sum();
    if mass <= 0.0 {
        return;
    }
    let v_cm = bodies.iter().map(|b| b.mass * b.velocity).sum::<DVec3>() / mass;
    for b in bodies {
        b.velocity -= v_cm;
    }
}

/// The scenario's explicit bodies as they start (velocities not yet drawn are zero),
/// after every check a run makes on them: in the box [−D, D]³, distinct ids, a given
/// mass or radius consistent with the primaries, and no two overlapping (over the
/// periodic neighbour grid: O(N) for any radii). `agglo validate` and the generator both
/// call this, so they agree.
pub fn placed_bodies(
    cloud: &Cloud,
    geometry: &BoxGeometry,
    material: &Material,
    primary: &PrimaryGrain,
) -> Result<Vec<BodyState>, SimError> {
    let d = geometry.half_width;
    let invalid = |i: usize, field: &str, message: String| SimError::InvalidBody {
        path: format!("cloud.bodies.{i}.{field}"),
        message,
    };
    let mut bodies = Vec::with_capacity(cloud.bodies.len());
    for (i, p) in cloud.bodies.iter().enumerate() {
        for (k, &x) in p.position.iter().enumerate() {
            if !(x >= -d && x <= d) {
                return Err(invalid(
                    i,
                    &format!("position.{k}"),
                    format!(
                        "allowed −D ≤ x ≤ D = {d:e} (got {})",
                        crate::readable::exact(x)
                    ),
                ));
            }
        }
        let implied = primary.mass * p.primaries;
        let mass = p.mass.unwrap_or(implied);
        // Written to also refuse NaN.
        let mass_agrees = (mass - implied).abs() <= CONSISTENCY_TOLERANCE * implied;
        if !mass_agrees {
            return Err(invalid(
                i,
                "mass",
                format!(
                    "{mass:e} kg, but {} primaries of {:e} kg make {implied:e} kg: is cloud.radius \
                     (b0) or material.rho that of the run that wrote the body? (`agglo \
                     validate` prints b0 to every digit)",
                    p.primaries, primary.mass
                ),
            ));
        }
        let implied_radius = material.radius_of_mass(mass);
        let radius = p.radius.unwrap_or(implied_radius);
        let radius_agrees =
            (radius - implied_radius).abs() <= CONSISTENCY_TOLERANCE * implied_radius;
        if !radius_agrees {
            return Err(invalid(
                i,
                "radius",
                format!(
                    "{radius:e} m, but a sphere of {mass:e} kg at ρ = {} kg/m³ has radius {implied_radius:e} m",
                    material.rho
                ),
            ));
        }
        // Larger than half the box is allowed (a body may overlap its own periodic
        // images, tests/suite/stepping.rs); a sphere of more volume than the box is not.
        let largest = (6.0 / std::f64::consts::PI).cbrt() * d;
        if radius > largest {
            return Err(invalid(
                i,
                "radius",
                format!(
                    "{radius:e} m: the body is larger than the box (its volume exceeds the \
                     box's (2D)³); allowed radius ≤ (6/π)^(1/3) D = {largest:e} m"
                ),
            ));
        }
        let theta = p.temperature.unwrap_or(material.theta0);
        bodies.push(BodyState {
            id: p.id.unwrap_or(i as u64),
            position: geometry.wrap(DVec3::from_array(p.position)),
            velocity: DVec3::from_array(p.velocity.unwrap_or_default()),
            mass,
            radius,
            temperature: theta,
            hardness: material.hardness(theta),
            primaries: p.primaries,
        });
    }
    let mut ids: Vec<(u64, usize)> = bodies.iter().enumerate().map(|(i, b)| (b.id, i)).collect();
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(invalid(
            w[1].1,
            "id",
            format!(
                "id {} is also cloud.bodies.{}'s; ids must be distinct",
                w[1].0, w[0].1
            ),
        ));
    }
    if let Some((i, j, distance, contact)) = first_overlap(&bodies, geometry) {
        return Err(SimError::Overlap {
            i,
            j,
            distance,
            contact,
        });
    }
    Ok(bodies)
}

/// The overlapping pair (i < j, the smallest in that order) with its centre distance
/// and radii sum [m], if any: over the neighbour grid, O(N).
pub fn first_overlap(
    bodies: &[BodyState],
    geometry: &BoxGeometry,
) -> Option<(usize, usize, f64, f64)> {
    let positions: Vec<DVec3> = bodies.iter().map(|b| b.position).collect();
    let radii: Vec<f64> = bodies.iter().map(|b| b.radius).collect();
    let mut pairs = Vec::new();
    NeighbourGrid::default().pairs_within(&positions, &radii, geometry.half_width, 0.0, &mut pairs);
    pairs
        .iter()
        .filter(|p| p.gap < 0.0)
        .map(|p| {
            let (i, j) = (p.i.min(p.j) as usize, p.i.max(p.j) as usize);
            let contact = radii[i] + radii[j];
            (i, j, p.gap + contact, contact)
        })
        .min_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)))
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
    // Cells at least one diameter wide: overlaps can only come from the 27 around. At
    // most 8 cells per sphere, each cell a list threaded through `next` (a head per cell,
    // a link per sphere): a Vec per cell cost 24 bytes a cell and an allocation per
    // sphere, 300 MB written and freed again at N = 1e6.
    let by_count = (8.0 * count.max(1) as f64).cbrt().ceil() as usize;
    let n = ((side / (2.0 * b)).floor() as usize).clamp(1, by_count.max(3));
    let width = side / n as f64;
    const EMPTY: u32 = u32::MAX;
    let mut heads: Vec<u32> = vec![EMPTY; n * n * n];
    let mut next: Vec<u32> = Vec::with_capacity(count);
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
                        let mut j = heads[cell];
                        while j != EMPTY {
                            if overlaps(j) {
                                fits = false;
                                break 'search;
                            }
                            j = next[j as usize];
                        }
                    }
                }
            }
            fits
        };
        if fits {
            let cell = ((c[2] as usize * n) + c[1] as usize) * n + c[0] as usize;
            next.push(heads[cell]);
            heads[cell] = positions.len() as u32;
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
