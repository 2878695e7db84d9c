//! Lifting (docs/model.md §15): from a cell's size classes to a box of bodies.
//!
//! The box is a sample of the cell's ideal gas: each class a Poisson number of bodies,
//! each body's velocity an independent Maxwellian draw. Then every pair rate of the box
//! is the cell's at the first instant, in expectation: E[N_i N_j] = λ_i λ_j and
//! E[N_i (N_i − 1)] = λ_i² for Poisson counts (random rounding gives λ² − λ + f(1 − f)),
//! and independent velocities give each pair the relative velocity the cell's
//! distribution gives it (subtracting a class's sample mean, as this lift did before
//! issue 37, shrinks every body's variance by (N_k − 1)/N_k and leaves a one-body class
//! at rest: a collector-monomer kernel 0.80 of the cell's with 1.5 collectors per box,
//! examples/lifting_bias.py).
//!
//! 1. **Box size.** V = N / Σ n_k for N bodies ([`BoxSize::Bodies`]), or the N whose
//!    expected impacts give the target standard error ([`BoxSize::TargetSe`]), raised
//!    to the smallest box the cell's largest drawn class fits.
//! 2. **Traces.** A class expecting fewer than [`TRACE_BODIES`] bodies per box is not
//!    lifted (its rates are 0 and the output flags it): it neither fits nor refuses.
//! 3. **Counts.** N_k Poisson with mean n_k V.
//! 4. **Placement.** Random sequential addition without overlap in the periodic cube,
//!    largest bodies first, over a cell grid (O(N) for the volume fractions allowed).
//! 5. **Velocities.** u_k plus independent Maxwellian fluctuations of variance T_k per
//!    component; temperatures θ_k.
//! 6. **Structure.** At a volume fraction ≥ [`EQUILIBRATE_FROM`], over a step short
//!    against the collision time ([`SWEEPS_BELOW_IMPACTS`]), [`SWEEPS`] sweeps of
//!    hard-core Metropolis moves relax the packing to the equilibrium hard-sphere
//!    fluid's (structure.rs): random sequential addition's excess of pairs near contact
//!    would otherwise set the first impacts.
//!
//! Every draw comes from one generator seeded by [`replica_seed`], so a box depends only
//! on (base seed, cell, macro step, replica) and the input: never on which thread or
//! rank builds it, or in which order the cells were submitted.

use std::f64::consts::PI;

use crate::cloud::{Cloud, PlacedBody};
use crate::inverse::ensemble::derive_seed;
use crate::scenario::{MAX_SPEED, MAX_TEMPERATURE, Scenario};
use agglo_engine::field::Drag;
use agglo_engine::readable::exact;

use super::config::{BoxSize, Coupling};
use super::error::SubgridError;
use super::exchange::CellInput;
use super::stream::Stream;
use super::structure::{EQUILIBRATE_FROM, SWEEPS, equilibrate};

/// The word that tells subgrid seeds apart from the other derived seeds ("subg").
const SUBGRID_TAG: u64 = 0x7375_6267;

/// The highest volume fraction a box may be lifted at: random sequential addition of
/// equal spheres jams at about 0.38, and gets slow well before.
pub const MAX_VOLUME_FRACTION: f64 = 0.3;

/// A body's diameter may be at most this fraction of the box side (the periodic box
/// must be large against its bodies, or a body meets its own image's neighbours).
pub const MAX_DIAMETER_PER_SIDE: f64 = 0.25;

/// A class expecting fewer bodies than this per box is a trace: not lifted, flagged in
/// the output ([`super::ClassOutput::ignored`]). Lifting it would draw a body in at most
/// one box in a thousand, so the rates it could give are far below any replica noise;
/// refusing the cell for it (a trace of large bodies does not fit a small box) would
/// stop a flow solver whose transport leaves such traces in every cell.
pub const TRACE_BODIES: f64 = 1e-3;

/// True when class input `n` [1/m³] is a trace in a box of `volume` [m³].
pub fn is_trace(n: f64, volume: f64) -> bool {
    n > 0.0 && n * volume < TRACE_BODIES
}

/// The seed of replica `replica` of cell `cell` at macro step `macro_step`:
/// `derive_seed([base, 0x73756267, cell, macro_step, replica])`, the splitmix64 chain
/// of [`crate::inverse::ensemble::derive_seed`].
pub fn replica_seed(base: u64, cell: u64, macro_step: u64, replica: u32) -> u64 {
    derive_seed(&[base, SUBGRID_TAG, cell, macro_step, replica as u64])
}

/// The counts of classes with expected counts `lambda` drawn from the stream seeded by
/// `seed`, as [`lift`] draws them (Poisson, class by class) — for checking the count
/// law without building boxes.
pub fn draw_counts(seed: u64, lambda: &[f64]) -> Vec<u64> {
    let mut rng = Stream(seed);
    lambda.iter().map(|&l| rng.poisson(l)).collect()
}

/// The radius [m] of a body of mass `m` [kg] and density `rho` [kg/m³].
pub fn radius_of(m: f64, rho: f64) -> f64 {
    (3.0 * m / (4.0 * PI * rho)).cbrt()
}

/// Standard deviations of a class's velocity draw that must stay under the speed limit.
const DRAWN_SIGMAS: f64 = 10.0;

/// |v| without overflow (hypot: 1e200 on one axis is 1e200, not ∞).
fn norm(v: [f64; 3]) -> f64 {
    v[0].hypot(v[1]).hypot(v[2])
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
                exact(n),
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
            if !(v.is_finite() && v.abs() <= MAX_SPEED) {
                return bad(
                    format!("classes[{k}].velocity[{i}]"),
                    exact(*v),
                    &format!("must be finite, |v| ≤ {MAX_SPEED:e} m/s"),
                );
            }
        }
        // The speed, not only each component: 1e5 m/s on every axis passed here, then
        // failed as the lifted box's `cloud.bodies.59.velocity` (issue 39).
        let speed = norm(class.velocity);
        if speed > MAX_SPEED {
            return bad(
                f("velocity"),
                format!("|v| = {speed:e} m/s"),
                &format!("the speed must be ≤ {MAX_SPEED:e} m/s"),
            );
        }
        let t = class.temperature;
        if !(t.is_finite() && t > 0.0 && t <= MAX_TEMPERATURE) {
            return bad(
                f("temperature"),
                exact(t),
                &format!("must be > 0 and ≤ {MAX_TEMPERATURE:e} K (the radiation law takes θ⁴)"),
            );
        }
        // Bodies are drawn about v̄ with σ = √T_g per axis: 10 σ keeps every drawn speed
        // under the limit (a draw beyond 10 σ in 3D has probability ~1e-21).
        let g = class.granular_temperature;
        let sigma_limit = (MAX_SPEED - speed) / DRAWN_SIGMAS;
        if !(g.is_finite() && g >= 0.0 && g.sqrt() <= sigma_limit) {
            return bad(
                f("granular_temperature"),
                exact(g),
                &format!(
                    "must be ≥ 0 with {DRAWN_SIGMAS} √T_g ≤ {MAX_SPEED:e} m/s − |v| \
                     (here T_g ≤ {:e} m²/s²), so that drawn speeds stay under the limit",
                    sigma_limit * sigma_limit
                ),
            );
        }
        let a = class.granular_anisotropy;
        for (i, x) in a.iter().enumerate() {
            if !(x.is_finite() && *x >= 0.0 && *x <= 1e300) {
                return bad(
                    format!("classes[{k}].granular_anisotropy[{i}]"),
                    format!("{x}"),
                    "must be ≥ 0 and finite, at most 1e300 ([1, 1, 1]: isotropic)",
                );
            }
        }
        if a.iter().sum::<f64>() <= 0.0 {
            return bad(
                f("granular_anisotropy"),
                format!("{a:?}"),
                "the three weights must not all be 0 ([1, 1, 1]: isotropic)",
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
        if !(u.is_finite() && u.abs() <= MAX_SPEED) {
            return bad(
                format!("gas.velocity[{i}]"),
                exact(*u),
                "must be finite, |u| ≤ 1e5 m/s",
            );
        }
    }
    if norm(gas.velocity) > MAX_SPEED {
        return bad(
            "gas.velocity".into(),
            format!("|u| = {:e} m/s", norm(gas.velocity)),
            "the speed must be ≤ 1e5 m/s",
        );
    }
    // The gas temperature is the box's θ0: 1e300 passed here, then failed as the box's
    // `material.theta0`.
    if !(gas.temperature.is_finite() && gas.temperature > 0.0 && gas.temperature <= MAX_TEMPERATURE)
    {
        return bad(
            "gas.temperature".into(),
            exact(gas.temperature),
            &format!("must be > 0 and ≤ {MAX_TEMPERATURE:e} K (the radiation law takes θ⁴)"),
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

/// The box volume V [m³] for `input` (checked): N / Σ n_k, with N given or picked for
/// the target standard error; a picked N is raised to the smallest box every class that
/// is not a trace in it fits (so `TargetSe` never picks a box that [`check_box`]
/// refuses), and that box is refused only when it needs more than `max_bodies`.
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
            let picked = n.clamp(min_bodies as f64, max_bodies as f64).ceil();
            let need = fitting_volume(c, input, picked / total);
            if need == picked / total {
                picked
            } else {
                // A hair above, so that the side's cube root does not round below the fit.
                let fitting = (need * total * (1.0 + 1e-9)).ceil();
                if fitting > max_bodies as f64 {
                    return Err(SubgridError::input(
                        cell,
                        "bodies.max_bodies",
                        format!("{max_bodies}"),
                        format!(
                            "the cell's largest class needs a box of {fitting:.0} bodies (its \
                             diameter at most {MAX_DIAMETER_PER_SIDE} of the side): raise \
                             max_bodies"
                        ),
                    ));
                }
                fitting
            }
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

/// The smallest volume ≥ `volume` [m³] in which every class that is not a trace fits
/// (its diameter at most [`MAX_DIAMETER_PER_SIDE`] of the side). Growing the box can
/// turn a trace into a class, so this repeats until nothing changes (at most once per
/// class: the volume only grows).
fn fitting_volume(c: &Coupling, input: &CellInput, volume: f64) -> f64 {
    let rho = c.base.material.rho;
    let mut v = volume;
    for _ in 0..=input.classes.len() {
        let need = input
            .classes
            .iter()
            .filter(|k| k.number_density > 0.0 && !is_trace(k.number_density, v))
            .map(|k| (2.0 * radius_of(k.mass, rho) / MAX_DIAMETER_PER_SIDE).powi(3))
            .fold(v, f64::max);
        if need == v {
            break;
        }
        v = need;
    }
    v
}

/// Check that every class the cell holds, traces aside, fits a box of `volume` [m³] —
/// whether or not a replica draws one of its bodies, so the answer does not depend on
/// the draw — and that the cell's volume fraction allows random placement. Returns the
/// volume fraction (traces included: they are part of the cell).
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
        fraction += class.number_density * 4.0 / 3.0 * PI * b * b * b;
        if is_trace(class.number_density, volume) {
            continue;
        }
        if 2.0 * b > MAX_DIAMETER_PER_SIDE * side {
            return Err(SubgridError::input(
                cell,
                format!("classes[{k}].mass"),
                format!("{:e}", class.mass),
                format!(
                    "a body of radius {b:e} m is too large for the box of side {side:e} m \
                     (diameter at most {MAX_DIAMETER_PER_SIDE} of the side; it expects \
                     {:.3e} bodies per box, a trace below {TRACE_BODIES:e} would be \
                     ignored): raise N",
                    class.number_density * volume
                ),
            ));
        }
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

/// The box of replica `seed` for `input`, in a cube of volume `volume` [m³] (with no
/// body when the Poisson draws hold none, probability e^−N): a
/// scenario with explicit bodies running over Δt. Input checked by [`check_input`];
/// the scenario is validated when its simulation is built.
pub fn lift(
    c: &Coupling,
    cell: u64,
    input: &CellInput,
    volume: f64,
    seed: u64,
) -> Result<Scenario, SubgridError> {
    lift_with_sweeps(c, cell, input, volume, seed, None)
}

/// True when a box lifted for `input` at volume fraction `fraction` gets the Metropolis
/// sweeps (structure.rs): a fraction ≥ [`EQUILIBRATE_FROM`] and a step short enough that
/// its first impacts weigh — fewer than [`SWEEPS_BELOW_IMPACTS`] impacts per body
/// expected over Δt (free-molecular estimate). Over a longer step the box's own impacts
/// bring it to the fluid's structure within its first impacts per body, while the sweeps
/// would cost most of a short run: at P04's cell (Δt = 1 ms, thousands of impacts per
/// body) 20 sweeps took 0.8 of the boxes' run time (docs/coupling.md).
fn needs_sweeps(c: &Coupling, input: &CellInput, fraction: f64) -> bool {
    if fraction < EQUILIBRATE_FROM {
        return false;
    }
    let n: f64 = input.classes.iter().map(|k| k.number_density).sum();
    let per_body = 2.0 * expected_impact_density(c, input) / n;
    per_body < SWEEPS_BELOW_IMPACTS
}

/// Lifting sweeps a dense box only when fewer impacts than this are expected per body
/// over Δt ([`needs_sweeps`]).
pub const SWEEPS_BELOW_IMPACTS: f64 = 10.0;

/// [`lift`] with `sweeps` Metropolis sweeps after placement (structure.rs), or, with
/// `None`, the default: [`SWEEPS`] at a volume fraction ≥ [`EQUILIBRATE_FROM`] over a
/// step with fewer than [`SWEEPS_BELOW_IMPACTS`] impacts expected per body, none
/// otherwise. For measuring the structure against the sweeps.
pub fn lift_with_sweeps(
    c: &Coupling,
    cell: u64,
    input: &CellInput,
    volume: f64,
    seed: u64,
    sweeps: Option<u32>,
) -> Result<Scenario, SubgridError> {
    let rho = c.base.material.rho;
    let m0 = c.primary().1;
    let side = volume.cbrt();
    let fraction = check_box(c, cell, input, volume)?;
    let mut rng = Stream(seed);
    // Poisson counts, class by class in class order; traces get none (module doc).
    let counts: Vec<usize> = input
        .classes
        .iter()
        .map(|class| {
            let lambda = class.number_density * volume;
            let lambda = if is_trace(class.number_density, volume) {
                0.0
            } else {
                lambda
            };
            rng.poisson(lambda) as usize
        })
        .collect();
    let total: usize = counts.iter().sum();
    if total == 0 {
        // A Poisson draw of nothing (probability e^−N): an empty box, which the run
        // skips (cell.rs); it counts as a box that saw nothing.
        return Ok(box_scene(c, input, side, seed, Vec::new()));
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
        // Independent Maxwellian draws about the class mean (module doc: no sample mean
        // subtracted, so each body and each pair has the cell's velocity statistics).
        let sd = class.granular_temperature_axes().map(f64::sqrt);
        for body in &mut bodies[first..] {
            body.velocity = Some([0, 1, 2].map(|x| class.velocity[x] + sd[x] * rng.normal()));
        }
    }
    let sweeps = sweeps.unwrap_or(if needs_sweeps(c, input, fraction) {
        SWEEPS
    } else {
        0
    });
    let size = |b: &PlacedBody| radius_of(b.mass.unwrap_or(m0), rho);
    equilibrate(&mut bodies, side, size, sweeps, &mut rng);
    // Not validated here: building its simulation validates it (once, 12 % of a lift
    // at P04's conditions).
    Ok(box_scene(c, input, side, seed, bodies))
}

/// The base scenario as a box of side `side` [m] holding exactly `bodies`, seeded by
/// `seed`, in the cell's gas, running over its Δt.
pub(crate) fn box_scene(
    c: &Coupling,
    input: &CellInput,
    side: f64,
    seed: u64,
    bodies: Vec<PlacedBody>,
) -> Scenario {
    let mut s = c.base.clone();
    s.seed = seed;
    s.domain.half_width = 0.5 * side;
    s.cloud = Cloud {
        count: bodies.len(),
        radius: Some(c.primary().0),
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
    s
}

/// Random sequential addition in the periodic cube [−D, D)³ over a uniform grid of
/// cells at least one largest diameter wide, so an overlapping pair is always in
/// neighbouring cells. Most attempts in a dense box fail (P04's volume fraction 0.26:
/// about eleven per body), so a failing attempt is made cheap: the own cell is looked
/// at first, then the seven of the octant p lies in (the neighbours on the sides of
/// the cell p is nearer to), then the rest; a cell off the boundary reaches its
/// neighbours by fixed index steps, and the periodic image of a neighbour across the
/// boundary is a fixed shift worked out once per attempt, not a rounding per pair.
/// Whether a position is free does not depend on the order the cells are looked at,
/// so the bodies placed are the same bit for bit as with any other order. Against
/// the layout before, which looked at the 27 cells in a fixed order with a remainder
/// per axis and cell and a call to floor per axis, placing P04's boxes takes 0.72 of
/// the instructions (callgrind, 16 lifts, dev profile: 147 → 106 M; the grid alone
/// at -O: 0.59).
#[doc(hidden)]
pub struct PlacementGrid {
    side: f64,
    cells: usize,
    /// Bodies [x, y, z, radius] per cell.
    members: Vec<Vec<[f64; 4]>>,
    /// With 3 or more cells per side: the 27 neighbour cells, per axis 0 (the own
    /// cell's row), 1 (the neighbour on the side p is nearer to) or 2 (the other),
    /// the octant's 8 first. With fewer: every cell once, by its coordinates.
    near_first: Vec<[usize; 3]>,
    /// For an own cell off the boundary, the same 27 cells as index steps from it,
    /// for each octant p may lie in (bit x set: p in the upper half of the cell along
    /// axis x).
    steps: [Vec<isize>; 8],
    attempts_left: u64,
}

impl PlacementGrid {
    pub fn new(side: f64, min_cell: f64, bodies: usize) -> Self {
        // At most ~8 cells per body (a dilute box would otherwise allocate a huge
        // grid); wider cells stay correct, only slower.
        let by_size = (side / min_cell).floor().max(1.0);
        let by_count = (8.0 * bodies as f64).cbrt().floor().max(3.0);
        let cells = by_size.min(by_count).max(1.0) as usize;
        let near_first: Vec<[usize; 3]> = if cells >= 3 {
            let mut o: Vec<[usize; 3]> = (0..3)
                .flat_map(|x| (0..3).flat_map(move |y| (0..3).map(move |z| [x, y, z])))
                .collect();
            // The octant's cells first (own, faces, edges, corner), then the faces,
            // edges and corners beyond it.
            o.sort_by_key(|d| (d.contains(&2), d.iter().filter(|&&x| x > 0).count()));
            o
        } else {
            (0..cells)
                .flat_map(|x| (0..cells).flat_map(move |y| (0..cells).map(move |z| [x, y, z])))
                .collect()
        };
        let n = cells as isize;
        let steps = std::array::from_fn(|octant| {
            if cells < 3 {
                return Vec::new();
            }
            near_first
                .iter()
                .map(|o| {
                    let d = [0, 1, 2].map(|x| {
                        let near = if octant >> x & 1 == 1 { 1 } else { -1 };
                        [0, near, -near][o[x]]
                    });
                    (d[0] * n + d[1]) * n + d[2]
                })
                .collect()
        });
        Self {
            side,
            cells,
            members: vec![Vec::new(); cells * cells * cells],
            near_first,
            steps,
            attempts_left: 2000 * bodies as u64 + 10_000,
        }
    }

    /// The cell of p, and where p lies in it along each axis, in cell widths.
    pub fn locate(&self, p: [f64; 3]) -> ([usize; 3], [f64; 3]) {
        let mut c = [0usize; 3];
        let mut within = [0.0; 3];
        for x in 0..3 {
            let u = (p[x] / self.side + 0.5) * self.cells as f64;
            // `as` truncates toward 0 and saturates: the floor for u ≥ 0, and 0 for a
            // rounding below the cube's lower face (a call to floor was an eighth of
            // the placement's instructions).
            c[x] = (u as usize).min(self.cells - 1);
            within[x] = u - c[x] as f64;
        }
        (c, within)
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[0] * self.cells + c[1]) * self.cells + c[2]
    }

    /// Mark a body of radius `b` at `p` (inside the cube) as present, unchecked: the
    /// bodies a kept box already holds, before new ones are placed among them.
    pub(crate) fn occupy(&mut self, p: [f64; 3], b: f64) {
        let cell = self.index(self.locate(p).0);
        self.members[cell].push([p[0], p[1], p[2], b]);
    }

    /// A free position for a body of radius `b`, or `None` when the attempts ran out.
    pub fn place(&mut self, b: f64, rng: &mut Stream) -> Option<[f64; 3]> {
        let half = 0.5 * self.side;
        while self.attempts_left > 0 {
            self.attempts_left -= 1;
            let p = [0, 1, 2].map(|_| -half + self.side * rng.uniform());
            let (c, within) = self.locate(p);
            if self.free(p, c, within, b) {
                let cell = self.index(c);
                self.members[cell].push([p[0], p[1], p[2], b]);
                return Some(p);
            }
        }
        None
    }

    /// True when a body of radius `b` at `p` (already shifted to the cell's side of
    /// the boundary) overlaps one in `cell`.
    fn overlaps(&self, cell: usize, p: [f64; 3], b: f64) -> bool {
        self.members[cell].iter().any(|q| {
            let (dx, dy, dz) = (p[0] - q[0], p[1] - q[1], p[2] - q[2]);
            let reach = b + q[3];
            dx * dx + dy * dy + dz * dz < reach * reach
        })
    }

    pub fn free(&self, p: [f64; 3], c: [usize; 3], within: [f64; 3], b: f64) -> bool {
        let n = self.cells;
        if n < 3 {
            // Few cells: every cell once, minimum images by rounding.
            return self.near_first.iter().all(|o| {
                self.members[self.index(*o)].iter().all(|q| {
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
        let octant = (0..3).fold(0, |o, x| o | (usize::from(within[x] >= 0.5) << x));
        if c.iter().all(|&i| i > 0 && i < n - 1) {
            // Off the boundary: no neighbour is a periodic image.
            let own = self.index(c) as isize;
            return !self.steps[octant]
                .iter()
                .any(|d| self.overlaps((own + d) as usize, p, b));
        }
        // Per axis, the row of the own cell, of the near and of the far neighbour,
        // and p shifted by a side where that row lies across the periodic boundary.
        let mut at = [[0usize; 3]; 3];
        let mut image = [[0.0f64; 3]; 3];
        let n = n as isize;
        for x in 0..3 {
            let near: isize = if octant >> x & 1 == 1 { 1 } else { -1 };
            for (j, o) in [0, near, -near].into_iter().enumerate() {
                let i = c[x] as isize + o;
                (at[x][j], image[x][j]) = if i < 0 {
                    ((i + n) as usize, p[x] + self.side)
                } else if i >= n {
                    ((i - n) as usize, p[x] - self.side)
                } else {
                    (i as usize, p[x])
                };
            }
        }
        !self.near_first.iter().any(|o| {
            let cell = self.index([at[0][o[0]], at[1][o[1]], at[2][o[2]]]);
            let image = [image[0][o[0]], image[1][o[1]], image[2][o[2]]];
            self.overlaps(cell, image, b)
        })
    }
}
