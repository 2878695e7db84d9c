//! Lifting (docs/model.md §15): from a cell's size classes to a box of bodies.
//!
//! 1. **Box size.** V = N / Σ n_k for N bodies ([`BoxSize::Bodies`]), or the N whose
//!    expected impacts give the target standard error ([`BoxSize::TargetSe`]).
//! 2. **Counts.** N_k = ⌊n_k V⌋ plus one with probability n_k V − ⌊n_k V⌋ (random
//!    rounding: E[N_k] = n_k V, so no class is dropped on average, however dilute).
//! 3. **Placement.** Random sequential addition without overlap in the periodic cube,
//!    largest bodies first, over a cell grid (O(N) for the volume fractions allowed).
//! 4. **Velocities.** u_k plus Maxwellian fluctuations of variance T_k per component,
//!    shifted so that each class's mean is u_k to rounding (the class momentum
//!    n_k m_k u_k V is then what the box holds); temperatures θ_k.
//!
//! Every draw comes from one generator seeded by [`replica_seed`], so a box depends only
//! on (base seed, cell, macro step, replica) and the input: never on which thread or
//! rank builds it, or in which order the cells were submitted.

use std::f64::consts::PI;

use crate::cloud::{Cloud, PlacedBody};
use crate::inverse::ensemble::{derive_seed, splitmix64};
use crate::scenario::Scenario;
use agglo_engine::field::Drag;

use super::config::{BoxSize, Coupling};
use super::error::SubgridError;
use super::exchange::CellInput;

/// The word that tells subgrid seeds apart from the other derived seeds ("subg").
const SUBGRID_TAG: u64 = 0x7375_6267;

/// The highest volume fraction a box may be lifted at: random sequential addition of
/// equal spheres jams at about 0.38, and gets slow well before.
pub const MAX_VOLUME_FRACTION: f64 = 0.3;

/// A body's diameter may be at most this fraction of the box side (the periodic box
/// must be large against its bodies, or a body meets its own image's neighbours).
pub const MAX_DIAMETER_PER_SIDE: f64 = 0.25;

/// The seed of replica `replica` of cell `cell` at macro step `macro_step`:
/// `derive_seed([base, 0x73756267, cell, macro_step, replica])`, the splitmix64 chain
/// of [`crate::inverse::ensemble::derive_seed`].
pub fn replica_seed(base: u64, cell: u64, macro_step: u64, replica: u32) -> u64 {
    derive_seed(&[base, SUBGRID_TAG, cell, macro_step, replica as u64])
}

/// A generator of its own: splitmix64 over a counter (as the kernel's samples).
struct Stream(u64);

impl Stream {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        splitmix64(self.0)
    }
    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// Standard normal (Box–Muller, one value per two uniforms).
    fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

/// The radius [m] of a body of mass `m` [kg] and density `rho` [kg/m³].
pub fn radius_of(m: f64, rho: f64) -> f64 {
    (3.0 * m / (4.0 * PI * rho)).cbrt()
}

/// Check a cell's input against the coupling; the error names the cell and the field.
pub fn check_input(c: &Coupling, cell: u64, input: &CellInput) -> Result<(), SubgridError> {
    let bad = |field: String, value: String, allowed: &str| {
        Err(SubgridError::input(cell, field, value, allowed))
    };
    if !(input.dt.is_finite() && input.dt > 0.0) {
        return bad(
            "dt".into(),
            format!("{:e}", input.dt),
            "must be > 0 and finite [s]",
        );
    }
    if input.classes.len() != c.classes() {
        return bad(
            "classes".into(),
            format!("{} classes", input.classes.len()),
            &format!("must be {} (one per class of the edges)", c.classes()),
        );
    }
    let (_, m0) = c.primary();
    for (k, class) in input.classes.iter().enumerate() {
        let f = |name: &str| format!("classes[{k}].{name}");
        let n = class.number_density;
        if !(n.is_finite() && n >= 0.0) {
            return bad(
                f("number_density"),
                format!("{n}"),
                "must be ≥ 0 and finite [1/m³]",
            );
        }
        let m = class.mass;
        if !(m.is_finite() && m > 0.0) {
            return bad(f("mass"), format!("{m:e}"), "must be > 0 and finite [kg]");
        }
        if n > 0.0 {
            if m < m0 * (1.0 - 1e-12) {
                return bad(
                    f("mass"),
                    format!("{m:e}"),
                    &format!("must be ≥ the primary grain's mass {m0:e} kg (base cloud.radius)"),
                );
            }
            let (lo, hi) = (c.edges[k], c.edges[k + 1]);
            let inside = (k == 0 || m >= lo) && (k + 1 == c.classes() || m < hi);
            if !inside {
                return bad(
                    f("mass"),
                    format!("{m:e}"),
                    &format!("must lie in the class's edges [{lo:e}, {hi:e}) kg"),
                );
            }
        }
        for (i, v) in class.velocity.iter().enumerate() {
            if !(v.is_finite() && v.abs() <= crate::scene::MAX_SPEED) {
                return bad(
                    format!("classes[{k}].velocity[{i}]"),
                    format!("{v}"),
                    &format!("must be finite, |v| ≤ {:e} m/s", crate::scene::MAX_SPEED),
                );
            }
        }
        let t = class.temperature;
        if !(t.is_finite() && t > 0.0) {
            return bad(
                f("temperature"),
                format!("{t}"),
                "must be > 0 and finite [K]",
            );
        }
        let g = class.granular_temperature;
        if !(g.is_finite() && g >= 0.0) {
            return bad(
                f("granular_temperature"),
                format!("{g}"),
                "must be ≥ 0 and finite [m²/s²]",
            );
        }
    }
    if input.classes.iter().all(|c| c.number_density == 0.0) {
        return bad(
            "classes[*].number_density".into(),
            "0 in every class".into(),
            "at least one class must hold bodies",
        );
    }
    let gas = &input.gas;
    for (i, u) in gas.velocity.iter().enumerate() {
        if !(u.is_finite() && u.abs() <= 1e5) {
            return bad(
                format!("gas.velocity[{i}]"),
                format!("{u}"),
                "must be finite, |u| ≤ 1e5 m/s",
            );
        }
    }
    if !(gas.temperature.is_finite() && gas.temperature > 0.0) {
        return bad(
            "gas.temperature".into(),
            format!("{}", gas.temperature),
            "must be > 0 and finite [K]",
        );
    }
    let field = gas_field(c, input);
    if let Some(issue) = field.issues().into_iter().next() {
        let path = issue.path.replace("field.drag.relaxation", "gas.drag");
        return bad(path, issue.message, "see docs/model.md §4.7");
    }
    Ok(())
}

/// The base scenario's field with the cell's gas drag.
pub(crate) fn gas_field(c: &Coupling, input: &CellInput) -> agglo_engine::field::Field {
    let mut field = c.base.field;
    field.drag = input.gas.drag.map(|relaxation| Drag {
        gas_velocity: input.gas.velocity,
        relaxation,
    });
    field
}

/// Mean relative speed of two Maxwellian classes (means `du` apart, variances `s2`
/// summed per component): √(|Δu|² + 8 s²/π), exact at Δu = 0 and for |Δu|² ≫ s².
fn mean_relative_speed(du: [f64; 3], s2: f64) -> f64 {
    (du.iter().map(|x| x * x).sum::<f64>() + 8.0 * s2 / PI).sqrt()
}

/// Expected impacts per unit volume over Δt from the free-molecular kernel
/// π(b_i + b_j)² ⟨|Δv|⟩ of the input classes (½ on the diagonal).
pub fn expected_impact_density(c: &Coupling, input: &CellInput) -> f64 {
    let rho = c.base.material.rho;
    let k = input.classes.len();
    let mut rate = 0.0;
    for i in 0..k {
        for j in i..k {
            let (a, b) = (&input.classes[i], &input.classes[j]);
            if a.number_density == 0.0 || b.number_density == 0.0 {
                continue;
            }
            let sigma = radius_of(a.mass, rho) + radius_of(b.mass, rho);
            let du = [0, 1, 2].map(|x| a.velocity[x] - b.velocity[x]);
            let w = mean_relative_speed(du, a.granular_temperature + b.granular_temperature);
            let pairs = if i == j { 0.5 } else { 1.0 } * a.number_density * b.number_density;
            rate += PI * sigma * sigma * w * pairs;
        }
    }
    rate * input.dt
}

/// The box volume V [m³] for `input` (checked).
pub fn box_volume(c: &Coupling, cell: u64, input: &CellInput) -> Result<f64, SubgridError> {
    let total: f64 = input.classes.iter().map(|c| c.number_density).sum();
    let bodies = match c.bodies {
        BoxSize::Bodies(n) => n as f64,
        BoxSize::TargetSe {
            relative,
            min_bodies,
            max_bodies,
        } => {
            // Impacts in one box C = r V = r N / n, and the K boxes' relative SE
            // 1/√(K C): N = n / (K r se²).
            let r = expected_impact_density(c, input);
            let n = if r > 0.0 {
                total / (c.replicas as f64 * r * relative * relative)
            } else {
                f64::INFINITY
            };
            n.clamp(min_bodies as f64, max_bodies as f64).ceil()
        }
    };
    let volume = bodies / total;
    if !(volume.is_finite() && volume > 0.0) {
        return Err(SubgridError::input(
            cell,
            "classes[*].number_density",
            format!("Σ n_k = {total:e} 1/m³"),
            "gives no finite box volume N / Σ n_k",
        ));
    }
    Ok(volume)
}

/// Check that every class the cell holds fits a box of `volume` [m³] — whether or not
/// a replica draws one of its bodies, so the answer does not depend on the draw — and
/// that the cell's volume fraction allows random placement. Returns the volume fraction.
pub fn check_box(
    c: &Coupling,
    cell: u64,
    input: &CellInput,
    volume: f64,
) -> Result<f64, SubgridError> {
    let rho = c.base.material.rho;
    let side = volume.cbrt();
    let mut fraction = 0.0;
    for (k, class) in input.classes.iter().enumerate() {
        if class.number_density == 0.0 {
            continue;
        }
        let b = radius_of(class.mass, rho);
        if 2.0 * b > MAX_DIAMETER_PER_SIDE * side {
            return Err(SubgridError::input(
                cell,
                format!("classes[{k}].mass"),
                format!("{:e}", class.mass),
                format!(
                    "a body of radius {b:e} m is too large for the box of side {side:e} m \
                     (diameter at most {MAX_DIAMETER_PER_SIDE} of the side): raise N"
                ),
            ));
        }
        fraction += class.number_density * 4.0 / 3.0 * PI * b * b * b;
    }
    if fraction > MAX_VOLUME_FRACTION {
        return Err(SubgridError::input(
            cell,
            "classes[*].number_density",
            format!("volume fraction {fraction:.3}"),
            format!("must be at most {MAX_VOLUME_FRACTION} to place the bodies at random"),
        ));
    }
    Ok(fraction)
}

/// The box of replica `seed` for `input`, in a cube of volume `volume` [m³]: a
/// scenario with explicit bodies running over Δt. Input checked by [`check_input`];
/// the scenario is validated when its simulation is built.
pub fn lift(
    c: &Coupling,
    cell: u64,
    input: &CellInput,
    volume: f64,
    seed: u64,
) -> Result<Scenario, SubgridError> {
    let rho = c.base.material.rho;
    let (b0, m0) = c.primary();
    let side = volume.cbrt();
    let fraction = check_box(c, cell, input, volume)?;
    let mut rng = Stream(seed);
    // Counts by random rounding, class by class in class order.
    let counts: Vec<usize> = input
        .classes
        .iter()
        .map(|class| {
            let x = class.number_density * volume;
            let whole = x.floor();
            whole as usize + usize::from(rng.uniform() < x - whole)
        })
        .collect();
    let total: usize = counts.iter().sum();
    if total == 0 {
        return Err(SubgridError::input(
            cell,
            "bodies",
            format!("a box of {volume:e} m³ drew no body"),
            "raise N (the box holds Σ n_k V bodies on average)",
        ));
    }
    // Largest first (ties in class order): the big ones find room before the box fills.
    let mut order: Vec<usize> = (0..c.classes()).filter(|&k| counts[k] > 0).collect();
    order.sort_by(|&a, &b| input.classes[b].mass.total_cmp(&input.classes[a].mass));
    let max_radius = radius_of(input.classes[order[0]].mass, rho);
    let mut grid = PlacementGrid::new(side, 2.0 * max_radius, total);
    let mut bodies = Vec::with_capacity(total);
    for &k in &order {
        let class = &input.classes[k];
        let b = radius_of(class.mass, rho);
        let first = bodies.len();
        for _ in 0..counts[k] {
            let position = grid.place(b, &mut rng).ok_or_else(|| {
                SubgridError::input(
                    cell,
                    "classes[*].number_density",
                    format!("volume fraction {fraction:.3}"),
                    "no room left to place the bodies at random: dilute the cell or raise N",
                )
            })?;
            bodies.push(PlacedBody {
                position,
                velocity: Some([0.0; 3]),
                primaries: (class.mass / m0).max(1.0),
                id: Some(bodies.len() as u64),
                temperature: Some(class.temperature),
                mass: Some(class.mass),
                radius: None,
            });
        }
        // Fluctuations, then the class's mean fluctuation removed (all bodies of a class
        // have one mass, so the mass-weighted mean is the plain mean).
        let sd = class.granular_temperature.sqrt();
        let members = &mut bodies[first..];
        let mut mean = [0.0; 3];
        for body in members.iter_mut() {
            let v = [0, 1, 2].map(|_| sd * rng.normal());
            for x in 0..3 {
                mean[x] += v[x];
            }
            body.velocity = Some(v);
        }
        let n = members.len() as f64;
        for body in members.iter_mut() {
            let v = body.velocity.as_mut().expect("set just above");
            for x in 0..3 {
                v[x] = class.velocity[x] + (v[x] - mean[x] / n);
            }
        }
    }
    let mut s = c.base.clone();
    s.seed = seed;
    s.domain.half_width = 0.5 * side;
    s.cloud = Cloud {
        count: total,
        radius: Some(b0),
        size_ratio: None,
        v_mean: [0.0; 3],
        v_rel: None,
        velocity_distribution: Default::default(),
        granular_temperature: None,
        remove_drift: false,
        bodies,
        from_file: None,
    };
    s.material.theta0 = input.gas.temperature;
    s.field = gas_field(c, input);
    s.time.end = input.dt;
    s.output = Default::default();
    // Not validated here: building its simulation validates it (once, 12 % of a lift
    // at P04's conditions).
    Ok(s)
}

/// Random sequential addition in the periodic cube [−D, D)³ over a uniform grid of
/// cells at least one largest diameter wide, so an overlapping pair is always in
/// neighbouring cells. Most attempts in a dense box fail (P04's volume fraction 0.26:
/// about ten per body), so a failing attempt is made cheap: the own cell is looked at
/// first, then the faces, edges and corners, and the periodic image of a neighbour
/// cell is a fixed shift, not a rounding per pair.
struct PlacementGrid {
    side: f64,
    cells: usize,
    /// Bodies [x, y, z, radius] per cell.
    members: Vec<Vec<[f64; 4]>>,
    /// The 27 neighbour offsets, nearest first (or, with fewer than 3 cells per side,
    /// every cell once).
    offsets: Vec<[isize; 3]>,
    attempts_left: u64,
}

impl PlacementGrid {
    fn new(side: f64, min_cell: f64, bodies: usize) -> Self {
        // At most ~8 cells per body (a dilute box would otherwise allocate a huge
        // grid); wider cells stay correct, only slower.
        let by_size = (side / min_cell).floor().max(1.0);
        let by_count = (8.0 * bodies as f64).cbrt().floor().max(3.0);
        let cells = by_size.min(by_count).max(1.0) as usize;
        let offsets = if cells >= 3 {
            let mut o: Vec<[isize; 3]> = (-1..=1)
                .flat_map(|x| (-1..=1).flat_map(move |y| (-1..=1).map(move |z| [x, y, z])))
                .collect();
            o.sort_by_key(|d| d.iter().map(|x| x * x).sum::<isize>());
            o
        } else {
            let n = cells as isize;
            (0..n)
                .flat_map(|x| (0..n).flat_map(move |y| (0..n).map(move |z| [x, y, z])))
                .collect()
        };
        Self {
            side,
            cells,
            members: vec![Vec::new(); cells * cells * cells],
            offsets,
            attempts_left: 2000 * bodies as u64 + 10_000,
        }
    }

    fn cell_of(&self, p: [f64; 3]) -> [usize; 3] {
        p.map(|x| {
            let u = (x / self.side + 0.5) * self.cells as f64;
            (u.floor().max(0.0) as usize).min(self.cells - 1)
        })
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[0] * self.cells + c[1]) * self.cells + c[2]
    }

    /// A free position for a body of radius `b`, or `None` when the attempts ran out.
    fn place(&mut self, b: f64, rng: &mut Stream) -> Option<[f64; 3]> {
        let half = 0.5 * self.side;
        while self.attempts_left > 0 {
            self.attempts_left -= 1;
            let p = [0, 1, 2].map(|_| -half + self.side * rng.uniform());
            let c = self.cell_of(p);
            if self.free(p, c, b) {
                let cell = self.index(c);
                self.members[cell].push([p[0], p[1], p[2], b]);
                return Some(p);
            }
        }
        None
    }

    fn free(&self, p: [f64; 3], c: [usize; 3], b: f64) -> bool {
        let n = self.cells as isize;
        if self.cells < 3 {
            // Few cells: every cell once, minimum images by rounding.
            return self.offsets.iter().all(|o| {
                let cell = self.index(o.map(|x| x as usize));
                self.members[cell].iter().all(|q| {
                    let mut d2 = 0.0;
                    for x in 0..3 {
                        let d = p[x] - q[x];
                        let d = d - self.side * (d / self.side).round();
                        d2 += d * d;
                    }
                    d2 >= (b + q[3]) * (b + q[3])
                })
            });
        }
        for o in &self.offsets {
            // The neighbour cell, and the shift that brings its bodies next to p when
            // it lies across the periodic boundary.
            let mut at = [0usize; 3];
            let mut image = p;
            for x in 0..3 {
                let i = c[x] as isize + o[x];
                if i < 0 {
                    image[x] += self.side;
                } else if i >= n {
                    image[x] -= self.side;
                }
                at[x] = i.rem_euclid(n) as usize;
            }
            for q in &self.members[self.index(at)] {
                let (dx, dy, dz) = (image[0] - q[0], image[1] - q[1], image[2] - q[2]);
                let reach = b + q[3];
                if dx * dx + dy * dy + dz * dz < reach * reach {
                    return false;
                }
            }
        }
        true
    }
}
