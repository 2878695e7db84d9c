//! The impact / heat law of a pair (docs/model.md §5): the staggered fixed point
//! e* = G(e*) of restitution, impact duration, contact area, impulsive force, friction,
//! heating and thermal softening; its safeguarded solve; the closed forms of the
//! restitution (docs/model.md §14); and the options by which the papers' readings differ.
//! Plain functions of plain values, free of ECS types: the impact system
//! (`systems/impact/`) calls [`solve_pair`] for each contact, and tests and studies call
//! it directly.

use glam::DVec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::laws::hardness::hardness;

/// One body's state entering an impact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairBody {
    /// Mass [kg].
    pub mass: f64,
    /// Radius [m].
    pub radius: f64,
    /// Velocity [m/s].
    pub velocity: DVec3,
    /// Temperature [K].
    pub temperature: f64,
}

/// Material and model constants the pair solve needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairModel {
    /// Contact-area fraction at full rebound (e = 1).
    pub a0: f64,
    /// Contact-area fraction at adhesion (e = 0).
    pub af: f64,
    /// Impact-duration scale β.
    pub beta: f64,
    /// The impact-duration law.
    pub duration: DurationLaw,
    /// μ = μ0 (1 − e) when true (P02), μ = μ0 otherwise (P04).
    pub friction_scales_with_adhesion: bool,
    /// μ0.
    pub mu0: f64,
    /// α [J/m²].
    pub alpha: f64,
    /// C [J/(kg K)].
    pub heat_capacity: f64,
    /// H0 [Pa].
    pub h0: f64,
    /// Q [J/mol].
    pub activation_energy: f64,
    /// Relative tolerance TOL of |e_{K+1} − e_K| ≤ TOL·e_K.
    pub tol: f64,
    /// Plain iterations before the fallback.
    pub max_iterations: u32,
    /// How the fixed point is found.
    pub solver: SolverKind,
    /// Which hardness the pair bonds against (a reading, docs/model.md §5.1 step 7).
    pub pair_hardness: PairHardness,
    /// Whether the friction impulse is capped at sticking (a reading, §5.1 step 5).
    pub friction_cap: FrictionCap,
    /// When the pair bonds (a reading, §5.3).
    pub bond_test: BondTest,
    /// Whether the dissipation heats the pair once or twice (a reading, §5.1 step 6).
    pub work_heat: WorkHeat,
}

/// Everything G(e) computes for one trial restitution e.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trial {
    /// G(e).
    pub g: f64,
    /// Body i's velocity after the impact [m/s].
    pub velocity_i: DVec3,
    /// Body j's velocity after the impact [m/s].
    pub velocity_j: DVec3,
    /// Body i's temperature after the impact [K].
    pub temperature_i: f64,
    /// Body j's temperature after the impact [K].
    pub temperature_j: f64,
    /// Kinetic energy lost by the pair W [J].
    pub dissipated: f64,
    /// Reaction heat per body R_c = α a_c [J].
    pub reaction_heat: f64,
    /// Contact area a_c [m²].
    pub contact_area: f64,
}

/// How the fixed point was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveMethod {
    /// The papers' iteration converged.
    FixedPoint,
    /// The iteration failed; the bracketed (Illinois) solve found the root.
    Fallback,
    /// Solver `plain` and the iteration failed: the last iterate is used.
    Unconverged,
    /// The closed-form seed was the fixed point (exact when Q = 0): one evaluation of G.
    ClosedForm,
    /// The closed-form seed bracketed the root, which Illinois then found.
    Seeded,
    /// Bond test `any_iterate`: an iterate of the papers' iteration pressed at ≥ 2H and
    /// the pair bonded there (P02 (20)), whatever the fixed point.
    IterateBonded,
}

/// Result of one pair solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairOutcome {
    /// Restitution e* (0 when bonded).
    pub restitution: f64,
    /// True when the pair bonds.
    pub bonded: bool,
    /// Body i's velocity after the impact [m/s].
    pub velocity_i: DVec3,
    /// Body j's velocity after the impact [m/s].
    pub velocity_j: DVec3,
    /// Body i's temperature after the impact [K].
    pub temperature_i: f64,
    /// Body j's temperature after the impact [K].
    pub temperature_j: f64,
    /// Kinetic energy lost by the pair [J].
    pub dissipated: f64,
    /// Reaction heat added to the pair, 2 α a_c [J].
    pub reaction_heat: f64,
    /// Kinetic energy body i lost in the pair's centre-of-mass frame [J].
    pub lost_i: f64,
    /// Kinetic energy body j lost in the pair's centre-of-mass frame [J].
    pub lost_j: f64,
    /// Plain fixed-point iterations used.
    pub iterations: u32,
    /// Bracketed iterations used (0 without fallback).
    pub fallback_iterations: u32,
    /// How the fixed point was found.
    pub method: SolveMethod,
}

/// Evaluate G(e) (docs/model.md §5, steps 1–7). `normal` is the unit vector from i to j;
/// the pair must be approaching: (v_i − v_j)·n > 0.
pub fn trial(model: &PairModel, bi: &PairBody, bj: &PairBody, normal: DVec3, e: f64) -> Trial {
    let (mi, mj) = (bi.mass, bj.mass);
    let vin = bi.velocity.dot(normal);
    let vjn = bj.velocity.dot(normal);
    let vti = bi.velocity - vin * normal;
    let vtj = bj.velocity - vjn * normal;
    let closing = vin - vjn;

    // 1. normal velocities (P04 (2.4), (2.5))
    let vin_new = (mi * vin + mj * (vjn - e * closing)) / (mi + mj);
    let vjn_new = vin_new + e * closing;

    // 2. impact duration
    let bmin = bi.radius.min(bj.radius);
    let duration = match model.duration {
        DurationLaw::P04 => (1.0 + e) * model.beta * bmin / (0.5 * closing),
        DurationLaw::P02 => 2.0 * model.beta * bmin / ((1.0 + e) * closing.abs()),
    };

    // 3. contact area (P04 (4.12))
    let contact_area =
        (model.a0 + (model.af - model.a0) * (1.0 - e)) * std::f64::consts::PI * bmin * bmin;

    // 4. mean impulsive force
    let normal_impulse = mi * (vin_new - vin).abs();
    let force = normal_impulse / duration;

    // 5. friction, capped so the tangential relative velocity is not reversed
    let mu = if model.friction_scales_with_adhesion {
        model.mu0 * (1.0 - e)
    } else {
        model.mu0
    };
    let slip = vti - vtj;
    let slip_speed = slip.length();
    let (mut vti_new, mut vtj_new) = (vti, vtj);
    if slip_speed > 0.0 && mu > 0.0 {
        let coulomb = mu * force * duration;
        let reduced = mi * mj / (mi + mj);
        let jt = match model.friction_cap {
            FrictionCap::Sticking => coulomb.min(slip_speed * reduced),
            FrictionCap::None => coulomb,
        };
        let t_hat = slip / slip_speed;
        vti_new -= (jt / mi) * t_hat;
        vtj_new += (jt / mj) * t_hat;
    }
    let velocity_i = vin_new * normal + vti_new;
    let velocity_j = vjn_new * normal + vtj_new;

    // 6. heat: W split equally, reaction heat R_c to each body (P02 (14)–(17))
    let ke = |m: f64, v: DVec3| 0.5 * m * v.length_squared();
    let loss = ke(mi, bi.velocity) + ke(mj, bj.velocity) - ke(mi, velocity_i) - ke(mj, velocity_j);
    // W ≥ 0 in exact arithmetic when friction is capped, so a negative value is rounding;
    // uncapped friction can really create kinetic energy, which then leaves the heat
    // (signed W) so that the energy ledgers still close (docs/model.md §10).
    let dissipated = match model.friction_cap {
        FrictionCap::Sticking => loss.max(0.0),
        FrictionCap::None => loss,
    };
    let reaction_heat = model.alpha * contact_area;
    let c = model.heat_capacity;
    let heat = dissipated * work_heat_factor(model.work_heat);
    let temperature_i = bi.temperature + heat / (2.0 * mi * c) + reaction_heat / (mi * c);
    let temperature_j = bj.temperature + heat / (2.0 * mj * c) + reaction_heat / (mj * c);
    let hi = hardness(model.h0, model.activation_energy, temperature_i);
    let hj = hardness(model.h0, model.activation_energy, temperature_j);

    // 7. G(e) = max(1 − Ī / (2 a_c H_pair), 0), never forming 0·∞
    let h = pair_hardness(model.pair_hardness, hi, hj);
    let g = if h.is_infinite() {
        1.0
    } else if contact_area <= 0.0 {
        0.0
    } else {
        (1.0 - force / (2.0 * contact_area * h)).max(0.0)
    };

    Trial {
        g,
        velocity_i,
        velocity_j,
        temperature_i,
        temperature_j,
        dissipated,
        reaction_heat,
        contact_area,
    }
}

/// How many times the dissipated energy W heats the pair: 1, or 2 under P04 (6.10).
pub fn work_heat_factor(rule: WorkHeat) -> f64 {
    match rule {
        WorkHeat::Once => 1.0,
        WorkHeat::Twice => 2.0,
        WorkHeat::None => 0.0,
    }
}

/// The hardness a pair bonds against, from the two bodies' hardnesses [Pa] (either may
/// be +∞, docs/model.md §1); never NaN for non-NaN inputs.
pub fn pair_hardness(rule: PairHardness, hi: f64, hj: f64) -> f64 {
    match rule {
        PairHardness::Min => hi.min(hj),
        PairHardness::Max => hi.max(hj),
        PairHardness::Arithmetic => 0.5 * hi + 0.5 * hj,
        // 2/(1/H_i + 1/H_j): an infinite hardness contributes 0, so ∞ and H give 2H.
        PairHardness::Harmonic => 2.0 / (1.0 / hi + 1.0 / hj),
    }
}

/// P02 (20)'s in-loop accretion test: the papers' iteration from e0 = 0, bonding as
/// soon as one iterate presses at ≥ 2H, i.e. G(e_K) = 0 (G is clamped at 0 exactly
/// there). Returns the iterations used if the pair bonds this way, `None` when the
/// iteration converges (or runs out of iterations) without such an iterate.
fn bonds_at_an_iterate(model: &PairModel, g: impl Fn(f64) -> f64) -> Option<u32> {
    let mut e = 0.0_f64;
    for k in 1..=model.max_iterations {
        let next = g(e);
        if next <= 0.0 {
            return Some(k);
        }
        if converged(model.tol, e, next) {
            return None;
        }
        e = next;
    }
    None
}

/// Converged when |e_{K+1} − e_K| ≤ TOL·e_K, with an absolute floor so that e = 0 converges.
#[inline]
fn converged(tol: f64, previous: f64, next: f64) -> bool {
    (next - previous).abs() <= tol * previous.abs().max(next.abs()) + ABSOLUTE_FLOOR
}

/// Absolute floor of the convergence test on e ∈ [0, 1].
pub const ABSOLUTE_FLOOR: f64 = 1e-15;

/// Result of finding e* alone (no velocities).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedPoint {
    /// The restitution e* = G(e*).
    pub e: f64,
    /// Plain fixed-point iterations used.
    pub iterations: u32,
    /// Bracketed iterations used (0 without fallback).
    pub fallback_iterations: u32,
    /// How it was found.
    pub method: SolveMethod,
}

/// Find the fixed point e* = G(e*) on [0, 1]: the papers' iteration from e0 = 0 first,
/// then (solver `safeguarded`) the Illinois method on F(e) = e − G(e) over the bracket
/// narrowed by the iterates, when the iteration has not converged after
/// `max_iterations` or stops contracting.
pub fn find_fixed_point(model: &PairModel, g: impl Fn(f64) -> f64) -> FixedPoint {
    // Bracket of the root of F(e) = e − G(e): F(lo) ≤ 0 ≤ F(hi).
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut e = 0.0_f64;
    let mut last_step = f64::INFINITY;
    let mut stalled = 0u32;
    let mut iterations = 0u32;
    while iterations < model.max_iterations {
        let next = g(e);
        iterations += 1;
        if converged(model.tol, e, next) {
            return FixedPoint {
                e: next,
                iterations,
                fallback_iterations: 0,
                method: SolveMethod::FixedPoint,
            };
        }
        // F(e) = e − G(e) = e − next tells which side of the root e lies on.
        if next > e {
            lo = lo.max(e);
        } else {
            hi = hi.min(e);
        }
        let step = (next - e).abs();
        // Not contracting (|G'| ≥ 1 near e*: e.g. the 2-cycle at a0 = 0): give up early.
        stalled = if step >= 0.999 * last_step {
            stalled + 1
        } else {
            0
        };
        last_step = step;
        e = next;
        if stalled >= 3 && model.solver == SolverKind::Safeguarded {
            break;
        }
    }
    if model.solver == SolverKind::Plain {
        return FixedPoint {
            e,
            iterations,
            fallback_iterations: 0,
            method: SolveMethod::Unconverged,
        };
    }
    let (root, fallback_iterations) = illinois(|x| x - g(x), lo, hi, model.tol);
    FixedPoint {
        e: root,
        iterations,
        fallback_iterations,
        method: SolveMethod::Fallback,
    }
}

/// Illinois (modified regula falsi) on [lo, hi] with f(lo) ≤ 0 ≤ f(hi); falls back to
/// bisection steps when it stagnates. Returns the root and the iterations used.
fn illinois(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64, tol: f64) -> (f64, u32) {
    let mut f_lo = f(lo);
    let mut f_hi = f(hi);
    if f_lo == 0.0 {
        return (lo, 1);
    }
    if f_hi == 0.0 {
        return (hi, 1);
    }
    // The bracket is guaranteed by F(0) ≤ 0 ≤ F(1); guard against a bracket the
    // iterates mislabelled through rounding by restoring the full interval.
    if f_lo > 0.0 || f_hi < 0.0 {
        lo = 0.0;
        hi = 1.0;
        f_lo = f(lo);
        f_hi = f(hi);
        if f_lo >= 0.0 {
            return (lo, 1);
        }
        if f_hi <= 0.0 {
            return (hi, 1);
        }
    }
    let mut side = 0i8;
    let mut iterations = 0u32;
    while iterations < 200 {
        iterations += 1;
        let width = hi - lo;
        if width <= tol * hi.abs() + ABSOLUTE_FLOOR {
            break;
        }
        let mut x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        // Keep the secant point strictly inside; bisect every 8th iteration for safety.
        if !(x > lo && x < hi) || iterations.is_multiple_of(8) {
            x = 0.5 * (lo + hi);
        }
        let fx = f(x);
        if fx == 0.0 {
            return (x, iterations);
        }
        if fx < 0.0 {
            lo = x;
            f_lo = fx;
            if side == -1 {
                f_hi *= 0.5;
            }
            side = -1;
        } else {
            hi = x;
            f_hi = fx;
            if side == 1 {
                f_lo *= 0.5;
            }
            side = 1;
        }
    }
    // The smaller-|F| end of the final bracket.
    let root = if f_lo.abs() <= f_hi.abs() { lo } else { hi };
    (root, iterations)
}

/// The fixed point with the pre-impact hardness, in closed form (docs/model.md §14,
/// generalised to unequal masses and either duration law).
///
/// Without softening (Q = 0) G(e) does not depend on heating. With the mean force
/// Ī = m_red w² (1 + e)^{2κ} / (2 β b) (w the closing speed, b = min(b_i, b_j); κ = 0
/// for the P04 duration law, where Ī does not depend on e, κ = 1 for P02's), the
/// contact area a_c = (af − (af − a0) e) π b² and λ = m_red w² / (2 β b · 2 π b² H),
/// e = G(e) becomes the quadratic
///   (af − a0 − κλ) e² − (2af − a0 + 2κλ) e + (af − λ) = 0,
/// whose smaller root is e* (for κ = 0 and equal masses: docs/model.md §14). With Q > 0
/// heating lowers H, so this is the root for the hardest the pair can be: a first
/// guess and one end of a bracket. `None` when the pair does not approach.
pub fn restitution_seed(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    normal: DVec3,
) -> Option<f64> {
    let lambda = match pre_impact_lambda(model, bi, bj, normal)? {
        PreImpact::Rigid => return Some(1.0),
        PreImpact::Lambda(lambda) => lambda,
    };
    let kappa = match model.duration {
        DurationLaw::P04 => 0.0,
        DurationLaw::P02 => 1.0,
    };
    let (a, b) = (model.af, model.af - model.a0);
    let qc = a - lambda;
    if qc <= 0.0 {
        return Some(0.0); // G(0) ≤ 0: the pair bonds
    }
    let qa = b - kappa * lambda;
    let qb = -(a + b + 2.0 * kappa * lambda);
    let disc = qb * qb - 4.0 * qa * qc;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    // The smaller root without cancellation: 2 qc / (−qb + √disc).
    let e = 2.0 * qc / (-qb + disc.sqrt());
    (0.0..=1.0).contains(&e).then_some(e)
}

/// A pair as the closed forms see it before the impact.
enum PreImpact {
    /// Infinitely hard (no softening at this temperature): full rebound, e = 1.
    Rigid,
    /// λ of the closed form with the pre-impact pair hardness.
    Lambda(f64),
}

/// The closing speed along `normal` and λ with the pre-impact pair hardness, shared by
/// both closed forms; `None` when the pair does not approach.
fn pre_impact_lambda(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    normal: DVec3,
) -> Option<PreImpact> {
    let closing = (bi.velocity - bj.velocity).dot(normal);
    if closing.is_nan() || closing <= 0.0 {
        return None;
    }
    let h = pair_hardness(
        model.pair_hardness,
        hardness(model.h0, model.activation_energy, bi.temperature),
        hardness(model.h0, model.activation_energy, bj.temperature),
    );
    if h.is_infinite() {
        return Some(PreImpact::Rigid);
    }
    Some(PreImpact::Lambda(closed_form_lambda(
        model, bi, bj, closing, h,
    )))
}

/// λ = m_red w² / (2 β b · 2π b² H) of the closed form (docs/model.md §5.2), with the
/// closing speed `closing` [m/s] and the pair hardness `h` [Pa] (finite).
fn closed_form_lambda(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    closing: f64,
    h: f64,
) -> f64 {
    let bmin = bi.radius.min(bj.radius);
    let reduced = bi.mass * bj.mass / (bi.mass + bj.mass);
    let force = reduced * closing * closing / (2.0 * model.beta * bmin);
    force / (2.0 * std::f64::consts::PI * bmin * bmin * h)
}

/// P04 (4.14) as printed: the smaller root of e² + c1 e + c2 = 0 with
/// c1 = (λ − (a0 − 2af))/(a0 − af) (the printed, wrong coefficient) and
/// c2 = (λ − af)/(a0 − af), λ from [`closed_form_lambda`] with the pre-impact pair
/// hardness; 0 (bond) for λ ≥ af. `None` when the pair does not approach or the
/// printed quadratic has no root in [0, 1].
pub fn printed_closed_form(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    normal: DVec3,
) -> Option<f64> {
    let lambda = match pre_impact_lambda(model, bi, bj, normal)? {
        PreImpact::Rigid => return Some(1.0),
        PreImpact::Lambda(lambda) => lambda,
    };
    let (a0, af) = (model.a0, model.af);
    if lambda >= af {
        return Some(0.0);
    }
    if a0 == af {
        return Some(1.0 - lambda / af); // G does not depend on e
    }
    let c1 = (lambda - (a0 - 2.0 * af)) / (a0 - af);
    let c2 = (lambda - af) / (a0 - af);
    let disc = c1 * c1 - 4.0 * c2;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    // The smaller root without cancellation: 2 c2 / (−c1 + √disc) (here −c1 > 0).
    let e = 2.0 * c2 / (-c1 + disc.sqrt());
    (0.0..=1.0).contains(&e).then_some(e)
}

/// The fixed point from a seed: accept it if G(seed) agrees to the tolerance (one
/// evaluation), otherwise run Illinois on the side of the seed where F = e − G(e)
/// changes sign.
pub fn find_fixed_point_from(model: &PairModel, seed: f64, g: impl Fn(f64) -> f64) -> FixedPoint {
    let next = g(seed);
    if converged(model.tol, seed, next) {
        return FixedPoint {
            e: next,
            iterations: 1,
            fallback_iterations: 0,
            method: SolveMethod::ClosedForm,
        };
    }
    let (lo, hi) = if next > seed {
        (seed, 1.0)
    } else {
        (0.0, seed)
    };
    let (root, fallback_iterations) = illinois(|x| x - g(x), lo, hi, model.tol);
    FixedPoint {
        e: root,
        iterations: 1,
        fallback_iterations,
        method: SolveMethod::Seeded,
    }
}

/// Solve one impact (docs/model.md §5): the fixed point, then bond (e* = 0) or bounce.
///
/// The safeguarded solver starts from [`restitution_seed`] (exact without softening);
/// the `plain` solver is the papers' iteration from e0 = 0, kept for the studies.
pub fn solve_pair(model: &PairModel, bi: &PairBody, bj: &PairBody, normal: DVec3) -> PairOutcome {
    let g = |e| trial(model, bi, bj, normal, e).g;
    let accreted = match model.bond_test {
        BondTest::FixedPoint => None,
        BondTest::AnyIterate => bonds_at_an_iterate(model, g),
    };
    let fp = if let Some(iterations) = accreted {
        FixedPoint {
            e: 0.0,
            iterations,
            fallback_iterations: 0,
            method: SolveMethod::IterateBonded,
        }
    } else {
        let answer = match model.solver {
            SolverKind::ClosedForm => restitution_seed(model, bi, bj, normal),
            SolverKind::ClosedFormPrinted => printed_closed_form(model, bi, bj, normal),
            SolverKind::Safeguarded | SolverKind::Plain => None,
        };
        let seed = match model.solver {
            SolverKind::Safeguarded => restitution_seed(model, bi, bj, normal),
            SolverKind::Plain | SolverKind::ClosedForm | SolverKind::ClosedFormPrinted => None,
        };
        match (answer, seed) {
            // A closed form taken as the answer: one evaluation of G, no check.
            (Some(e), _) => FixedPoint {
                e,
                iterations: 1,
                fallback_iterations: 0,
                method: SolveMethod::ClosedForm,
            },
            (None, Some(seed)) => find_fixed_point_from(model, seed, g),
            (None, None) => find_fixed_point(model, g),
        }
    };
    if fp.e <= 0.0 {
        bonded_outcome(model, bi, bj, normal, fp)
    } else {
        bounce_outcome(model, bi, bj, normal, fp)
    }
}

/// Kinetic energy each body loses in the pair's centre-of-mass frame [J] when the pair
/// goes from (bi, bj) to the velocities (after_i, after_j).
fn lost_in_cm_frame(bi: &PairBody, bj: &PairBody, after_i: DVec3, after_j: DVec3) -> (f64, f64) {
    let (mi, mj) = (bi.mass, bj.mass);
    let total = mi + mj;
    let v_cm = (mi * bi.velocity + mj * bj.velocity) / total;
    let lost = |m: f64, before: DVec3, after: DVec3| {
        (0.5 * m * ((before - v_cm).length_squared() - (after - v_cm).length_squared())).max(0.0)
    };
    (
        lost(mi, bi.velocity, after_i),
        lost(mj, bj.velocity, after_j),
    )
}

/// The pair bonds: common velocity, all relative kinetic energy becomes heat (plus the
/// reaction heat at e = 0). `fp` says how the solve got there (e is ignored).
pub fn bonded_outcome(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    normal: DVec3,
    fp: FixedPoint,
) -> PairOutcome {
    let (mi, mj) = (bi.mass, bj.mass);
    let total = mi + mj;
    let v_cm = (mi * bi.velocity + mj * bj.velocity) / total;
    let at_zero = trial(model, bi, bj, normal, 0.0);
    let dissipated = (0.5 * mi * bi.velocity.length_squared()
        + 0.5 * mj * bj.velocity.length_squared()
        - 0.5 * total * v_cm.length_squared())
    .max(0.0);
    let c = model.heat_capacity;
    let rc = at_zero.reaction_heat;
    let heat = dissipated * work_heat_factor(model.work_heat);
    let (lost_i, lost_j) = lost_in_cm_frame(bi, bj, v_cm, v_cm);
    PairOutcome {
        restitution: 0.0,
        bonded: true,
        velocity_i: v_cm,
        velocity_j: v_cm,
        temperature_i: bi.temperature + heat / (2.0 * mi * c) + rc / (mi * c),
        temperature_j: bj.temperature + heat / (2.0 * mj * c) + rc / (mj * c),
        dissipated,
        reaction_heat: 2.0 * rc,
        lost_i,
        lost_j,
        iterations: fp.iterations,
        fallback_iterations: fp.fallback_iterations,
        method: fp.method,
    }
}

/// The pair bounces with restitution `fp.e` > 0: G's step 1–6 at that e (friction,
/// contact area and reaction heat as the law has them), whether or not e is G's fixed point.
pub fn bounce_outcome(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    normal: DVec3,
    fp: FixedPoint,
) -> PairOutcome {
    let t = trial(model, bi, bj, normal, fp.e);
    let (lost_i, lost_j) = lost_in_cm_frame(bi, bj, t.velocity_i, t.velocity_j);
    PairOutcome {
        restitution: fp.e,
        bonded: false,
        velocity_i: t.velocity_i,
        velocity_j: t.velocity_j,
        temperature_i: t.temperature_i,
        temperature_j: t.temperature_j,
        dissipated: t.dissipated,
        reaction_heat: 2.0 * t.reaction_heat,
        lost_i,
        lost_j,
        iterations: fp.iterations,
        fallback_iterations: fp.fallback_iterations,
        method: fp.method,
    }
}

/// The granular-gas law (docs/model.md §5.4): smooth spheres with a constant normal
/// restitution e ∈ [0, 1] — the normal relative velocity is reversed and scaled by e, the
/// tangential velocities are unchanged, there is no bonding, no contact area and no
/// reaction heat. The kinetic energy lost, ½ μ (1 − e²) v_n², heats the pair as the
/// `work_heat` reading says (`none`: it leaves the pair).
pub fn constant_restitution_outcome(
    model: &PairModel,
    bi: &PairBody,
    bj: &PairBody,
    normal: DVec3,
    e: f64,
) -> PairOutcome {
    let (mi, mj) = (bi.mass, bj.mass);
    let closing = (bi.velocity - bj.velocity).dot(normal);
    // Normal impulse J = μ (1 + e) v_n along n̂ (from i to j).
    let impulse = mi * mj / (mi + mj) * (1.0 + e) * closing;
    let velocity_i = bi.velocity - (impulse / mi) * normal;
    let velocity_j = bj.velocity + (impulse / mj) * normal;
    let ke = |m: f64, v: DVec3| 0.5 * m * v.length_squared();
    let dissipated =
        (ke(mi, bi.velocity) + ke(mj, bj.velocity) - ke(mi, velocity_i) - ke(mj, velocity_j))
            .max(0.0);
    let c = model.heat_capacity;
    let heat = dissipated * work_heat_factor(model.work_heat);
    let (lost_i, lost_j) = lost_in_cm_frame(bi, bj, velocity_i, velocity_j);
    PairOutcome {
        restitution: e,
        bonded: false,
        velocity_i,
        velocity_j,
        temperature_i: bi.temperature + heat / (2.0 * mi * c),
        temperature_j: bj.temperature + heat / (2.0 * mj * c),
        dissipated,
        reaction_heat: 0.0,
        lost_i,
        lost_j,
        iterations: 0,
        fallback_iterations: 0,
        method: SolveMethod::ClosedForm,
    }
}

/// Closed-form restitution for two identical spheres head on without softening
/// (docs/model.md §14): λ = 2 ρ v_p² / (3 H β), each approaching at speed v_p.
pub fn closed_form_restitution(a0: f64, af: f64, lambda: f64) -> f64 {
    if lambda >= af {
        return 0.0;
    }
    if af == a0 {
        // G(e) = 1 − λ/af does not depend on e.
        return 1.0 - lambda / af;
    }
    ((2.0 * af - a0) - (a0 * a0 + 4.0 * lambda * (af - a0)).sqrt()) / (2.0 * (af - a0))
}

/// Critical approach speed of each of two identical spheres for bonding,
/// v_p = √(3 af H β / (2ρ)) (P04 (4.15)) [m/s].
pub fn critical_speed(af: f64, hardness: f64, beta: f64, rho: f64) -> f64 {
    (3.0 * af * hardness * beta / (2.0 * rho)).sqrt()
}

/// How often the dissipated energy heats the pair (docs/model.md §5.1 step 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum WorkHeat {
    /// W once, split equally (P02 (14)–(17)).
    #[default]
    Once,
    /// W twice: δK plus the deformation work δW of P04 (4.7)–(4.9), (6.10).
    Twice,
    /// Not at all: the dissipated energy leaves the pair (e.g. the granular-gas law of
    /// §5.4 when its heat does not matter); the ledgers book it (docs/model.md §10).
    None,
}

/// Which hardness a pair bonds against (docs/model.md §5.1 step 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PairHardness {
    /// min(H_i, H_j): the softer body governs (P04, footnote to (3.1) and §6(b)).
    #[default]
    Min,
    /// 2 H_i H_j / (H_i + H_j).
    Harmonic,
    /// (H_i + H_j) / 2.
    Arithmetic,
    /// max(H_i, H_j): both surfaces must yield.
    Max,
}

/// Whether the tangential (friction) impulse is capped (docs/model.md §5.1 step 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FrictionCap {
    /// Capped at the impulse m_red |v_ti − v_tj| that stops the sliding.
    #[default]
    Sticking,
    /// The papers' uncapped impulse μ Ī δτ (P04 (4.17), P02 (7)); may create energy.
    None,
}

/// When a pair bonds (docs/model.md §5.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BondTest {
    /// Only when the fixed point itself is e* = 0.
    #[default]
    FixedPoint,
    /// P02 (20): when any iterate of the papers' iteration from e0 = 0 reaches P ≥ 2H.
    AnyIterate,
}

/// How an overlapping bouncing pair is separated (docs/model.md §5.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Separation {
    /// Along n̂ to touching, each body in inverse proportion to its mass.
    #[default]
    Normal,
    /// P02 (8): r_i += b_i (1 − δ) v_i/|v_i|, and the same for j.
    Velocities,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
/// The impact-duration law δτ(e, v) (`impact.duration`, docs/model.md §5).
pub enum DurationLaw {
    /// δτ = (1 + e) β min(b) / ((v_in − v_jn)/2)  (P04 (4.10)).
    #[default]
    P04,
    /// δτ = 2 β min(b) / ((1 + e)|v_in − v_jn|)  (P02 (12)).
    P02,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
/// How a pair's fixed point e* = G(e*) is found (`impact.solver`, docs/model.md §5).
pub enum SolverKind {
    /// The papers' fixed-point iteration, with a bracketed fallback that cannot fail.
    #[default]
    Safeguarded,
    /// The papers' fixed-point iteration alone (for stability studies).
    Plain,
    /// Reading: the closed form's smaller root as the answer, no iteration — the
    /// quadratic of docs/model.md §5.2 with the pre-impact hardness (exact without
    /// softening).
    ClosedForm,
    /// Reading: the same with P04 (4.14)'s coefficient c1 as printed, which carries a
    /// spurious λ (docs/model.md §14); `p04` duration law only.
    ClosedFormPrinted,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(a0: f64, af: f64, beta: f64) -> PairModel {
        PairModel {
            a0,
            af,
            beta,
            duration: DurationLaw::P04,
            friction_scales_with_adhesion: false,
            mu0: 0.0,
            alpha: 0.0,
            heat_capacity: 1000.0,
            h0: 1e6,
            activation_energy: 0.0,
            tol: 1e-12,
            max_iterations: 100,
            solver: SolverKind::Safeguarded,
            pair_hardness: PairHardness::Min,
            friction_cap: FrictionCap::Sticking,
            bond_test: BondTest::FixedPoint,
            work_heat: WorkHeat::Once,
        }
    }

    fn sphere(radius: f64, rho: f64, v: DVec3) -> PairBody {
        PairBody {
            mass: 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3) * rho,
            radius,
            velocity: v,
            temperature: 300.0,
        }
    }

    #[test]
    fn a0_zero_oscillates_and_the_fallback_finds_the_root() {
        // λ = 0.5 < af = 1: the plain iteration cycles 0 ↔ 1 − λ forever (docs/model.md §5).
        let m = model(0.0, 1.0, 1.0);
        let rho = 2000.0;
        let vp = (0.5 * 3.0 * m.h0 * m.beta / (2.0 * rho)).sqrt();
        let (bi, bj) = (
            sphere(1e-3, rho, DVec3::X * vp),
            sphere(1e-3, rho, -DVec3::X * vp),
        );
        let expected = closed_form_restitution(0.0, 1.0, 0.5);
        // The papers' iteration from e0 = 0 needs the bracketed fallback …
        let fp = find_fixed_point(&m, |e| trial(&m, &bi, &bj, DVec3::X, e).g);
        assert_eq!(fp.method, SolveMethod::Fallback);
        assert!((fp.e - expected).abs() < 1e-9, "{} vs {expected}", fp.e);
        // … while the closed-form seed is the root: one evaluation of G (Q = 0).
        let out = solve_pair(&m, &bi, &bj, DVec3::X);
        assert_eq!(out.method, SolveMethod::ClosedForm);
        assert_eq!(out.iterations + out.fallback_iterations, 1);
        assert!(
            (out.restitution - expected).abs() < 1e-12,
            "{} vs {expected}",
            out.restitution
        );
    }

    #[test]
    fn the_seed_solves_unequal_masses_and_both_duration_laws_without_softening() {
        for duration in [DurationLaw::P04, DurationLaw::P02] {
            for &(a0, speed) in &[(0.0, 3.0), (0.01, 7.0), (0.3, 12.0), (0.5, 30.0)] {
                let mut m = model(a0, 1.0, 0.7);
                m.duration = duration;
                m.mu0 = 0.2; // friction does not enter G
                let bi = sphere(1e-3, 2000.0, DVec3::new(speed, 1.0, 0.0));
                let bj = sphere(2.3e-3, 2000.0, DVec3::new(-0.5 * speed, 0.0, 2.0));
                let seed = restitution_seed(&m, &bi, &bj, DVec3::X).expect("approaching");
                let g = trial(&m, &bi, &bj, DVec3::X, seed).g;
                // A fixed point of G to rounding: the quadratic is exact when Q = 0.
                assert!(
                    (g - seed).abs() < 1e-12,
                    "{duration:?} a0 = {a0}: {seed} vs {g}"
                );
            }
        }
    }

    #[test]
    fn with_softening_the_seed_brackets_the_root_in_a_few_evaluations() {
        let mut m = model(0.0, 1.0, 1.0);
        m.activation_energy = 2e3;
        m.alpha = 1e3;
        let rho = 2000.0;
        let vp = (0.3 * 3.0 * m.h0 * m.beta / (2.0 * rho)).sqrt();
        let (bi, bj) = (
            sphere(1e-3, rho, DVec3::X * vp),
            sphere(1e-3, rho, -DVec3::X * vp),
        );
        let out = solve_pair(&m, &bi, &bj, DVec3::X);
        assert_eq!(out.method, SolveMethod::Seeded);
        let g = trial(&m, &bi, &bj, DVec3::X, out.restitution).g;
        assert!(
            (g - out.restitution).abs() < 1e-9,
            "{} vs {g}",
            out.restitution
        );
        let plain = find_fixed_point(&m, |e| trial(&m, &bi, &bj, DVec3::X, e).g);
        assert!(
            out.iterations + out.fallback_iterations < plain.iterations + plain.fallback_iterations,
            "seeded {} + {} vs iteration {} + {}",
            out.iterations,
            out.fallback_iterations,
            plain.iterations,
            plain.fallback_iterations
        );
    }

    #[test]
    fn infinite_hardness_gives_full_rebound_without_nan() {
        let mut m = model(0.0, 1.0, 1.0);
        m.activation_energy = 1e6; // Q/(Rθ) ≈ 400 at 300 K → still finite; push higher:
        m.h0 = 1e6;
        let mut bi = sphere(1e-3, 2000.0, DVec3::X * 10.0);
        let mut bj = sphere(1e-3, 2000.0, -DVec3::X * 10.0);
        bi.temperature = 100.0; // Q/(Rθ) ≈ 1203 > 700 → H = ∞
        bj.temperature = 100.0;
        let out = solve_pair(&m, &bi, &bj, DVec3::X);
        assert_eq!(out.restitution, 1.0);
        assert!(out.velocity_i.is_finite() && out.velocity_j.is_finite());
        assert!((out.velocity_i.x + 10.0).abs() < 1e-12);
    }
}
