//! Ballistic particle–cluster aggregation (BPCA): one aggregate grown by monomers fired
//! at it one at a time along straight lines from random directions with random impact
//! parameters; the first primary a monomer touches holds it where it touched (every
//! contact sticks), and a monomer that misses is removed (docs/aggregates.md).
//!
//! This is the ballistic limit of the rigid aggregates of docs/model.md §6.1 — straight
//! flights, sticking at first touch, no rotation — computed directly, by casting each
//! monomer's line against the primaries, rather than through the event core: the core
//! has no way to add a body mid-run or to remove one that flew past, and one monomer
//! in flight at a time is what defines BPCA. Each shot costs O(k) (every primary is
//! tested against the line), so growing to N primaries costs O(N²) line tests: 10⁴
//! primaries take about 10⁸.
//!
//! Lines are drawn uniformly from the isotropic flux through a sphere around the seed
//! that encloses the aggregate (a uniform direction, then a point uniform on the disk
//! across it): of those, the lines that meet the aggregate are uniform in the flux
//! that meets it, whichever enclosing sphere is used, so the sphere's size changes how
//! many monomers miss, not the aggregate grown.

use glam::DVec3;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use crate::aggregates::{AggregateShape, shape_of};

/// A grown aggregate and how it grew.
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleClusterGrowth {
    /// Primary radius a [m].
    pub primary_radius: f64,
    /// The primaries' centres [m], in the order they joined (the seed at the origin first).
    pub centres: Vec<DVec3>,
    /// Radius of gyration of the primaries' centres after the k-th joined [m]
    /// (`radius_of_gyration[k − 1]`, 0 for the seed alone).
    pub radius_of_gyration: Vec<f64>,
    /// Monomers fired (those that stuck and those that missed).
    pub fired: u64,
    /// Monomers that missed and were removed.
    pub missed: u64,
}

/// Grow one BPCA aggregate of `primaries` (≥ 1) equal primaries of radius `a` [m] from
/// a seed primary at the origin, with the random stream of `seed`. Deterministic: the
/// same arguments give the same aggregate bit for bit.
pub fn grow(primaries: usize, a: f64, seed: u64) -> ParticleClusterGrowth {
    let mut rng = StdRng::seed_from_u64(seed);
    let contact = 2.0 * a; // centre distance of two touching primaries
    let mut centres = vec![DVec3::ZERO];
    // Σ x and Σ |x|² of the centres (equal masses), for R_g after every join. The
    // centres stay within a few R_g of the origin, so the cancellation in
    // Σ|x|²/k − |Σx/k|² costs a few ulps of R_g², not digits.
    let mut sum = DVec3::ZERO;
    let mut sum_sq = 0.0;
    let mut radius_of_gyration = vec![0.0];
    // The farthest centre from the origin: the lines are drawn through the sphere of
    // radius reach + 2a, which every line that can touch a primary crosses.
    let mut reach: f64 = 0.0;
    let (mut fired, mut missed) = (0u64, 0u64);
    while centres.len() < primaries.max(1) {
        fired += 1;
        let direction = uniform_direction(&mut rng);
        let (u, v) = perpendicular_basis(direction);
        let disk = reach + contact;
        let r = disk * rng.random_range(0.0..1.0f64).sqrt();
        let angle = std::f64::consts::TAU * rng.random_range(0.0..1.0f64);
        let start = r * (angle.cos() * u + angle.sin() * v) - (disk + contact) * direction;
        let Some(s) = first_touch(&centres, start, direction, contact) else {
            missed += 1;
            continue;
        };
        let x = start + s * direction;
        centres.push(x);
        sum += x;
        sum_sq += x.length_squared();
        reach = reach.max(x.length());
        let k = centres.len() as f64;
        let mean = sum / k;
        radius_of_gyration.push((sum_sq / k - mean.length_squared()).max(0.0).sqrt());
    }
    ParticleClusterGrowth {
        primary_radius: a,
        centres,
        radius_of_gyration,
        fired,
        missed,
    }
}

/// The distance along the line `start + s·direction` (`direction` a unit vector) at
/// which its centre first comes within `contact` of one of `centres` (None: it passes
/// them all). `start` is outside every contact sphere.
fn first_touch(centres: &[DVec3], start: DVec3, direction: DVec3, contact: f64) -> Option<f64> {
    let contact_sq = contact * contact;
    let mut first: Option<f64> = None;
    for &c in centres {
        let d = c - start;
        let along = d.dot(direction);
        let miss_sq = d.length_squared() - along * along;
        if miss_sq >= contact_sq {
            continue;
        }
        let s = along - (contact_sq - miss_sq).sqrt();
        if first.is_none_or(|f| s < f) {
            first = Some(s);
        }
    }
    first
}

/// A direction uniform on the unit sphere (z uniform in [−1, 1], azimuth uniform).
fn uniform_direction(rng: &mut StdRng) -> DVec3 {
    let z: f64 = rng.random_range(-1.0..=1.0);
    let phi = std::f64::consts::TAU * rng.random_range(0.0..1.0f64);
    let rho = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(rho * phi.cos(), rho * phi.sin(), z)
}

/// Two unit vectors perpendicular to the unit vector `n` and to each other.
fn perpendicular_basis(n: DVec3) -> (DVec3, DVec3) {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let u = n.cross(helper).normalize();
    (u, n.cross(u))
}

impl ParticleClusterGrowth {
    /// The grown aggregate's shape (mass in units of one primary's: 1 each).
    pub fn shape(&self) -> AggregateShape {
        let primaries: Vec<(f64, f64, DVec3)> = self
            .centres
            .iter()
            .map(|&c| (1.0, self.primary_radius, c))
            .collect();
        shape_of(0, &primaries)
    }

    /// The growth as a population for [`crate::aggregates::fractal_fit`]: the aggregate
    /// after each join from k = `from` to `to` primaries (inclusive), as shapes. They
    /// are one aggregate at successive sizes, not independent aggregates, so the fit's
    /// standard error understates the uncertainty of D_f.
    pub fn history(&self, from: usize, to: usize) -> Vec<AggregateShape> {
        let to = to.min(self.centres.len());
        (from.max(1)..=to)
            .map(|k| AggregateShape {
                id: k as u64,
                primaries: k,
                mass: k as f64,
                radius_of_gyration: self.radius_of_gyration[k - 1],
                volume_radius: self.primary_radius * (k as f64).cbrt(),
                filling_factor: f64::NAN,
            })
            .collect()
    }

    /// The filling factor of the sphere of radius `radius` [m] about the aggregate's
    /// centre of mass: the volume of the primaries inside it (the parts of those that
    /// cross its surface counted exactly) over its volume.
    pub fn filling_factor_within(&self, radius: f64) -> f64 {
        let k = self.centres.len() as f64;
        let centre = self.centres.iter().sum::<DVec3>() / k;
        let inside: f64 = self
            .centres
            .iter()
            .map(|c| sphere_overlap(radius, self.primary_radius, (*c - centre).length()))
            .sum();
        inside / (4.0 / 3.0 * std::f64::consts::PI * radius.powi(3))
    }
}

/// The volume common to two spheres of radii `r1` and `r2` [m] whose centres are `d`
/// apart [m] (the lens where they cross).
pub fn sphere_overlap(r1: f64, r2: f64, d: f64) -> f64 {
    let ball = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    if d >= r1 + r2 {
        0.0
    } else if d <= (r1 - r2).abs() {
        ball(r1.min(r2))
    } else {
        // The lens: two spherical caps (e.g. Weisstein, "Sphere-Sphere Intersection").
        std::f64::consts::PI
            * (r1 + r2 - d).powi(2)
            * (d * d + 2.0 * d * (r1 + r2) - 3.0 * (r1 - r2).powi(2))
            / (12.0 * d)
    }
}
