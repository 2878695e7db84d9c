//! How a body flies between events in a field (docs/model.md §4.7): pure numerics.
//!
//! Three flights, each in closed form, for a body at position x0 [m] with velocity v0
//! [m/s] after s [s]:
//!
//! - [`Flight::Ballistic`]: no field, x = x0 + v0 s;
//! - [`Flight::Uniform`]: uniform acceleration g [m/s²], a parabola,
//!   x = x0 + v0 s + ½ g s², v = v0 + g s. Two bodies in the same uniform field move
//!   in straight lines relative to each other, so their time to contact is the
//!   ballistic one ([`crate::laws::contact_time::time_to_contact`]) with the
//!   velocities of the same instant;
//! - [`Flight::Drag`]: linear drag toward a gas velocity u with relaxation time τ, plus
//!   g: dv/ds = (u − v)/τ + g, so with the terminal velocity c = u + g τ,
//!   v = c + (v0 − c) e^(−s/τ) and x = x0 + c s + (v0 − c) τ (1 − e^(−s/τ)).
//!   Two bodies with different τ no longer move in straight lines relative to each
//!   other: [`contact_search`] finds their first contact by a safeguarded search.
//!
//! **The safeguarded search.** For a gap G(s) = |d(s)| − R between two spheres (or a
//! body and a cell wall), with relative acceleration bounded by A for all later s,
//! G'' ≥ −A (for the sphere gap, |d|'' = (|d'|² − (d̂·d')²)/|d| + d̂·d'' ≥ −|d''|). So
//! G(s + h) ≥ G + G' h − ½ A h², and no root lies before the smallest positive root of
//! that parabola, h = 2G / (−G' + √(G'² + 2 A G)) ([`safe_step`]). Stepping by h never
//! jumps a contact; near a root approached at speed |G'| the step is Newton's, so the
//! search converges quadratically. Under drag the acceleration bound decays,
//! A(s) = Σ |v0 − c|/τ · e^(−s/τ), and a bound taken at s holds for every later time.

use glam::DVec3;

use crate::laws::contact_time::time_to_contact;

/// One body's motion law between events.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Flight {
    /// Straight line at constant velocity.
    Ballistic,
    /// Uniform acceleration `g` [m/s²].
    Uniform {
        /// g [m/s²].
        g: DVec3,
    },
    /// Linear drag with relaxation time `tau` [s] toward `terminal` = u + g τ [m/s].
    Drag {
        /// The terminal velocity u + g τ [m/s].
        terminal: DVec3,
        /// τ [s].
        tau: f64,
    },
}

impl Flight {
    /// Position and velocity after `s` [s] from (x0, v0).
    #[inline]
    pub fn advance(&self, x0: DVec3, v0: DVec3, s: f64) -> (DVec3, DVec3) {
        match *self {
            Flight::Ballistic => (x0 + v0 * s, v0),
            Flight::Uniform { g } => (x0 + v0 * s + 0.5 * g * s * s, v0 + g * s),
            Flight::Drag { terminal, tau } => {
                // Written from v0, not from the terminal velocity c = u + g τ: with a weak
                // drag (τ ≫ s) c is huge (g τ = 1e17 m/s at τ = 1e16 s), and c s + (v0 − c)
                // τ (1 − e^(−s/τ)) cancelled to the last bits of c s, quantising velocities
                // and stalling the event core. Here every term is as small as the motion.
                let x = s / tau;
                let gone = -(-x).exp_m1(); // 1 − e^(−x), exact for x ≪ 1
                let pull = terminal - v0;
                (x0 + v0 * s + pull * (tau * lag(x)), v0 + pull * gone)
            }
        }
    }

    /// Displacement after `s` [s] from velocity v0 [m].
    #[inline]
    pub fn displacement(&self, v0: DVec3, s: f64) -> DVec3 {
        self.advance(DVec3::ZERO, v0, s).0
    }

    /// Velocity after `s` [s] from v0 [m/s].
    #[inline]
    pub fn velocity(&self, v0: DVec3, s: f64) -> DVec3 {
        match *self {
            Flight::Ballistic => v0,
            Flight::Uniform { g } => v0 + g * s,
            Flight::Drag { terminal, tau } => v0 - (terminal - v0) * (-s / tau).exp_m1(),
        }
    }

    /// A bound on |acceleration| at every time ≥ s [m/s²] of a flight that had v0 at 0.
    #[inline]
    pub fn acceleration_bound(&self, v0: DVec3, s: f64) -> f64 {
        match *self {
            Flight::Ballistic => 0.0,
            Flight::Uniform { g } => g.length(),
            Flight::Drag { terminal, tau } if s == 0.0 => (v0 - terminal).length() / tau,
            Flight::Drag { terminal, tau } => (v0 - terminal).length() / tau * (-s / tau).exp(),
        }
    }

    /// A bound on |velocity| at every time ≥ 0 of a flight from v0 [m/s] (finite except
    /// under uniform acceleration, where speed grows without bound).
    #[inline]
    pub fn speed_bound(&self, v0: DVec3) -> f64 {
        match *self {
            Flight::Ballistic => v0.length(),
            Flight::Uniform { .. } => f64::INFINITY,
            Flight::Drag { terminal, .. } => terminal.length() + (v0 - terminal).length(),
        }
    }
}

/// x − (1 − e^(−x)) for x ≥ 0, to rounding: the lag of a drag flight behind the
/// terminal velocity, in units of τ (the displacement is v0 s + (c − v0) τ lag(s/τ)).
/// Below x = 1e-2 the series x²/2 − x³/6 + … (to x⁷; the next term is below 1e-16 of the
/// sum), where x + expm1(−x) would lose the digits of x that cancel.
#[inline]
pub fn lag(x: f64) -> f64 {
    if x < 1e-2 {
        // Horner in x of x²(1/2 − x/6 + x²/24 − x³/120 + x⁴/720 − x⁵/5040).
        let tail = 1.0 / 720.0 - x / 5040.0;
        let tail = 1.0 / 120.0 - x * tail;
        let tail = 1.0 / 24.0 - x * tail;
        let tail = 1.0 / 6.0 - x * tail;
        let tail = 0.5 - x * tail;
        x * x * tail
    } else {
        x + (-x).exp_m1()
    }
}

/// The largest step h ≥ 0 over which a gap G [m] with rate G' [m/s] and G'' ≥ −A
/// [m/s²] cannot reach zero: the smallest positive root of G + G' h − ½ A h²
/// (∞ when there is none). G must be ≥ 0.
#[inline]
pub fn safe_step(gap: f64, rate: f64, accel: f64) -> f64 {
    let gap = gap.max(0.0);
    let root = (rate * rate + 2.0 * accel * gap).sqrt();
    // Each of the two forms of the root is free of cancellation on its side of G' = 0.
    if rate < 0.0 {
        2.0 * gap / (root - rate)
    } else if accel > 0.0 {
        (rate + root) / accel
    } else {
        f64::INFINITY // not approaching and nothing can turn it: never
    }
}

/// What a search along curved flights found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Search {
    /// First contact after this many seconds.
    At(f64),
    /// No contact before the horizon.
    Clear,
    /// No contact before this many seconds; search again from there (the search was
    /// cut short: a grazing pair, or an overlapping pair that separates for now).
    NotBefore(f64),
}

/// Iterations before a search hands back [`Search::NotBefore`].
const MAX_ITERATIONS: usize = 64;

/// A gap this small relative to the contact distance counts as touching.
const TOUCHING: f64 = 1e-12;

/// A touching pair whose closing speed is below this fraction of its relative speed
/// grazes rather than meets ([`line_contact`], and the curved search alike).
pub const GRAZING: f64 = 1e-10;

/// The exact time to contact along a line ([`time_to_contact`], Bannerman et al.'s
/// stable form: an approaching overlapping pair meets "now"), except that a touching
/// pair that only grazes — closing slower than [`GRAZING`] of its relative speed `u` —
/// is not due. The step that resolves a contact re-checks the approach with the
/// synchronised positions; a pair this close to tangential could pass one test and fail
/// the other by rounding and be handed back forever with zero-length steps. The event
/// core predicts straight flights with it.
#[inline]
pub fn line_contact(d: DVec3, u: DVec3, reach: f64) -> Option<f64> {
    let t = time_to_contact(d, u, reach)?;
    if t == 0.0 && d.dot(u) > -GRAZING * d.length() * u.length() {
        return None;
    }
    Some(t)
}

/// First time s in [0, `horizon`] at which two spheres at separation `d` = x_b − x_a
/// [m] (now), with velocities `va`, `vb` [m/s] (now) and flights `fa`, `fb`, come within
/// `reach` = b_a + b_b [m] while approaching. An approaching, touching or overlapping
/// pair is due at once (At(0)), as with [`time_to_contact`]; a touching pair that only
/// grazes (closing slower than 1e-10 of its relative speed) is not.
pub fn contact_search(
    d: DVec3,
    va: DVec3,
    vb: DVec3,
    fa: &Flight,
    fb: &Flight,
    reach: f64,
    horizon: f64,
) -> Search {
    // Same uniform field (or none): relative motion is a straight line, exactly.
    let straight = match (fa, fb) {
        (Flight::Ballistic, Flight::Ballistic) => true,
        (Flight::Uniform { g: ga }, Flight::Uniform { g: gb }) => ga == gb,
        _ => false,
    };
    if straight {
        return match line_contact(d, vb - va, reach) {
            Some(t) if t <= horizon => Search::At(t),
            _ => Search::Clear,
        };
    }
    // Same drag (equal τ, so equal terminal velocity): the relative velocity decays as
    // e^(−s/τ) along a fixed direction, so the pair moves along a straight line with
    // the "time" λ = τ (1 − e^(−s/τ)) < τ; contact at λ* means s = −τ ln(1 − λ*/τ).
    if let (
        Flight::Drag {
            terminal: ca,
            tau: ta,
        },
        Flight::Drag {
            terminal: cb,
            tau: tb,
        },
    ) = (fa, fb)
        && ta == tb
        && ca == cb
    {
        let tau = *ta;
        return match line_contact(d, vb - va, reach) {
            Some(lambda) if lambda < tau => {
                let s = -tau * (-lambda / tau).ln_1p();
                if s <= horizon {
                    Search::At(s)
                } else {
                    Search::Clear
                }
            }
            _ => Search::Clear,
        };
    }
    let tolerance = TOUCHING * reach + 4.0 * f64::EPSILON * d.length();
    let mut s = 0.0;
    for _ in 0..MAX_ITERATIONS {
        // At s = 0 the flights are where and as fast as they are now (no exponentials:
        // most pairs are cleared by this first step).
        let (sep, w) = if s == 0.0 {
            (d, vb - va)
        } else {
            (
                d + fb.displacement(vb, s) - fa.displacement(va, s),
                fb.velocity(vb, s) - fa.velocity(va, s),
            )
        };
        let distance = sep.length();
        let gap = distance - reach;
        let rate = if distance > 0.0 {
            sep.dot(w) / distance
        } else {
            -w.length()
        };
        // Touching and closing faster than rounding can fake (the event core's grazing
        // rule): a contact. A pair that only grazes would be declined when its contact is
        // resolved (the approach re-checked from the synchronised positions may round the
        // other way) and handed back at once, forever: it steps on instead.
        if gap <= tolerance && rate < -GRAZING * w.length() {
            return Search::At(s);
        }
        // Touching but separating (a pair that has just bounced): the step below treats
        // the gap as zero, so it runs to where the bound parabola G' h − ½ A h² comes
        // back to zero — a differential flight may turn the pair back before it.
        let accel = fa.acceleration_bound(va, s) + fb.acceleration_bound(vb, s);
        let mut h = safe_step(gap, rate, accel);
        if h <= f64::EPSILON * s {
            if rate < -GRAZING * w.length() {
                return Search::At(s); // converged to rounding
            }
            // Grazing at rounding level, not approaching: step past it by the time the
            // bound parabola needs to move by the touching tolerance.
            h = (2.0 * tolerance / accel).sqrt();
        }
        // An infinite step (nothing can close the gap) or one past the horizon ends it.
        if !h.is_finite() || s + h > horizon {
            return Search::Clear;
        }
        s += h;
    }
    Search::NotBefore(s)
}

/// First time s ≥ 0 at which one coordinate (`component`: 0, 1, 2) of a body at
/// `offset` inside a cell of width `width` [m] now, with velocity `velocity` [m/s] now
/// along `flight`, in a grid whose frame has velocity `frame_velocity` now along
/// `frame`, leaves
/// [0, width]; with the side it leaves by (+1 or −1). None when it never does (within
/// `horizon`). A side of 0 means the search was cut short (a coordinate creeping along a
/// wall): it does not leave before that time, and must be asked again from there.
#[allow(clippy::too_many_arguments)] // one coordinate of two flights: body and frame
pub fn wall_crossing(
    offset: f64,
    velocity: DVec3,
    flight: &Flight,
    frame_velocity: DVec3,
    frame: &Flight,
    component: usize,
    width: f64,
    horizon: f64,
) -> Option<(f64, i8)> {
    let q0 = velocity[component] - frame_velocity[component];
    // The frame flies as the body does (same drag, or both straight): the coordinate
    // moves along a line in λ = τ (1 − e^(−s/τ)) (or s), so the crossing is closed-form.
    if flight == frame {
        let lambda = if q0 > 0.0 {
            (width - offset) / q0
        } else if q0 < 0.0 {
            offset / -q0
        } else {
            return None;
        };
        let s = match *flight {
            Flight::Drag { tau, .. } if lambda < tau => -tau * (-lambda.max(0.0) / tau).ln_1p(),
            Flight::Drag { .. } => return None,
            _ => lambda.max(0.0),
        };
        return (s <= horizon).then_some((s, if q0 > 0.0 { 1 } else { -1 }));
    }
    let mut s = 0.0;
    for _ in 0..MAX_ITERATIONS {
        let (p, q) = if s == 0.0 {
            (offset, q0)
        } else {
            let moved = flight.displacement(velocity, s)[component]
                - frame.displacement(frame_velocity, s)[component];
            (
                offset + moved,
                flight.velocity(velocity, s)[component]
                    - frame.velocity(frame_velocity, s)[component],
            )
        };
        if p >= width && q > 0.0 {
            return Some((s, 1));
        }
        if p <= 0.0 && q < 0.0 {
            return Some((s, -1));
        }
        let accel =
            flight.acceleration_bound(velocity, s) + frame.acceleration_bound(frame_velocity, s);
        // Each wall is a gap of its own (top: G = w − p, G' = −q; bottom: G = p, G' = q);
        // step by the safer of the two.
        let (top, bottom) = (safe_step(width - p, -q, accel), safe_step(p, q, accel));
        let h = top.min(bottom);
        if !h.is_finite() || s + h > horizon {
            return None;
        }
        if h <= f64::EPSILON * s.max(f64::MIN_POSITIVE) {
            // At a wall to rounding and closing on it: leave by that wall.
            return Some((s, if top <= bottom { 1 } else { -1 }));
        }
        s += h;
    }
    // Cut short (a coordinate creeping along a wall): hand back a safe lower bound.
    Some((s, 0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drag(tau: f64, terminal: DVec3) -> Flight {
        Flight::Drag { terminal, tau }
    }

    /// The lag x − (1 − e^(−x)) against its series summed far past rounding, on both
    /// sides of the switch at 1e-2, and in the large-x limit x − 1.
    #[test]
    fn the_lag_is_exact_to_rounding() {
        let series = |x: f64| {
            let (mut term, mut sum) = (x * x / 2.0, 0.0);
            for k in 3..40 {
                sum += term;
                term *= -x / k as f64;
            }
            sum
        };
        for x in [1e-12, 1e-6, 1e-3, 0.009_999, 0.010_001, 0.05, 0.3] {
            let rel = (lag(x) - series(x)).abs() / series(x);
            assert!(rel < 2e-14, "x = {x}: relative error {rel:e}");
        }
        assert!((lag(50.0) - 49.0).abs() < 1e-12);
    }

    /// A weak drag under gravity (τ = 1e16 s, terminal velocity g τ ≈ 1e17 m/s) flies as
    /// the parabola it is over any short time: no quantised velocities (vz was 20.3359375
    /// for every body with the c-based form) and positions to rounding.
    #[test]
    fn a_weak_drag_under_gravity_is_the_free_fall_it_approximates() {
        let (g, tau) = (DVec3::new(0.0, 0.0, -9.81), 1e16);
        let f = drag(tau, g * tau); // u = 0
        let (x0, v0) = (DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3, -0.2, 20.0));
        for s in [1e-9, 1e-6, 1e-3, 0.5] {
            let (x, v) = f.advance(x0, v0, s);
            let (fx, fv) = (x0 + v0 * s + 0.5 * g * s * s, v0 + g * s);
            // Drag changes the motion by ~ s/τ of it: far below rounding here.
            assert!(
                (v - fv).length() <= 4.0 * f64::EPSILON * fv.length(),
                "s = {s}: {v} vs {fv}"
            );
            assert!(
                (x - fx).length() <= 4.0 * f64::EPSILON * fx.length(),
                "s = {s}: {x} vs {fx}"
            );
            assert!((f.velocity(v0, s) - v).length() <= 4.0 * f64::EPSILON * fv.length());
        }
    }

    #[test]
    fn drag_flight_matches_its_differential_equation() {
        // dv/ds = (c − v)/τ and dx/ds = v, checked by central differences.
        let f = drag(2e-3, DVec3::new(0.0, 0.0, -3.0));
        let (x0, v0) = (DVec3::new(0.1, 0.2, 0.3), DVec3::new(5.0, -1.0, 2.0));
        let s = 1.3e-3;
        let h = 1e-7;
        let (xp, vp) = f.advance(x0, v0, s + h);
        let (xm, vm) = f.advance(x0, v0, s - h);
        let (_, v) = f.advance(x0, v0, s);
        let dv = (vp - vm) / (2.0 * h);
        let dx = (xp - xm) / (2.0 * h);
        let expected_dv = (DVec3::new(0.0, 0.0, -3.0) - v) / 2e-3;
        assert!((dv - expected_dv).length() < 1e-6 * expected_dv.length());
        assert!((dx - v).length() < 1e-8 * v.length());
        // The velocity formula and advance agree.
        assert!((f.velocity(v0, s) - v).length() <= 1e-15 * v.length());
    }

    #[test]
    fn uniform_flight_is_a_parabola() {
        let g = DVec3::new(0.0, 0.0, -9.81);
        let (x, v) = Flight::Uniform { g }.advance(DVec3::ZERO, DVec3::new(1.0, 0.0, 2.0), 0.5);
        assert_eq!(x, DVec3::new(0.5, 0.0, 1.0 - 0.5 * 9.81 * 0.25));
        assert_eq!(v, DVec3::new(1.0, 0.0, 2.0 - 9.81 * 0.5));
    }

    #[test]
    fn safe_step_never_jumps_a_root() {
        // G(h) = G + G' h − ½ A h² is the worst case: the step lands on its root.
        for &(g, r, a) in &[
            (1.0, -2.0, 0.5),
            (1.0, 3.0, 4.0),
            (0.3, 0.0, 1.0),
            (2.0, -1.0, 0.0),
        ] {
            let h = safe_step(g, r, a);
            let at = g + r * h - 0.5 * a * h * h;
            assert!(at.abs() < 1e-12, "G = {g}, G' = {r}, A = {a}: G(h) = {at}");
        }
        assert_eq!(safe_step(1.0, 1.0, 0.0), f64::INFINITY);
    }

    /// Brute force: the first sampled time the gap closes, for comparison.
    fn first_touch_sampled(
        d: DVec3,
        va: DVec3,
        vb: DVec3,
        fa: &Flight,
        fb: &Flight,
        reach: f64,
        horizon: f64,
    ) -> Option<f64> {
        let n = 200_000;
        (0..=n)
            .map(|k| horizon * k as f64 / n as f64)
            .find(|&s| (d + fb.displacement(vb, s) - fa.displacement(va, s)).length() <= reach)
    }

    #[test]
    fn drag_contact_search_finds_the_first_touch() {
        // A big grain (b, larger τ, faster terminal fall) settles onto a small one below
        // it (differential settling).
        let g = DVec3::new(0.0, 0.0, -9.81);
        let u = DVec3::ZERO;
        let (tau_a, tau_b) = (1e-3, 1e-2);
        let fa = drag(tau_a, u + g * tau_a);
        let fb = drag(tau_b, u + g * tau_b);
        let reach = 2e-5;
        let d = DVec3::new(1e-5, 0.0, 3e-4); // b above a
        let (va, vb) = (DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 0.0));
        let found = contact_search(d, va, vb, &fa, &fb, reach, 1.0);
        let Search::At(s) = found else {
            panic!("{found:?}")
        };
        let sampled = first_touch_sampled(d, va, vb, &fa, &fb, reach, 0.2).unwrap();
        assert!((s - sampled).abs() <= 0.2 / 200_000.0, "{s} vs {sampled}");
        let gap = (d + fb.displacement(vb, s) - fa.displacement(va, s)).length() - reach;
        assert!(gap.abs() <= 1e-11 * reach, "gap at contact {gap:e}");
    }

    #[test]
    fn drag_contact_search_misses_nothing_that_grazes_and_returns() {
        // Two grains whose relative path dips inside the contact distance briefly: the
        // safeguarded search must stop at the first entry, not step over the dip.
        let fa = drag(1e-3, DVec3::new(0.0, 0.0, -1.0));
        let fb = drag(5e-3, DVec3::new(0.0, 0.0, 1.0));
        let reach = 1e-5;
        // Lateral velocities relax at different rates, so the relative path curves.
        for k in 0..40 {
            let lateral = 0.31e-5 + 0.05e-5 * k as f64;
            let d = DVec3::new(lateral, 0.0, 5e-5);
            let (va, vb) = (DVec3::new(0.01, 0.0, 0.5), DVec3::new(-0.01, 0.0, -0.5));
            let sampled = first_touch_sampled(d, va, vb, &fa, &fb, reach, 2e-3);
            match (contact_search(d, va, vb, &fa, &fb, reach, 2e-3), sampled) {
                (Search::At(s), Some(t)) => assert!((s - t).abs() <= 2e-3 / 200_000.0 + 1e-12),
                (Search::Clear, None) => {}
                (found, sampled) => panic!("lateral {lateral:e}: {found:?} vs {sampled:?}"),
            }
        }
    }

    #[test]
    fn a_pair_that_has_just_bounced_is_found_again_when_settling_brings_it_back() {
        // Touching and separating now (a bounce), but the big grain (b, larger τ) falls
        // faster and catches the small one below it again: found at the sampled time.
        let g = DVec3::new(0.0, 0.0, -9.81e3);
        let (ta, tb) = (1e-3, 2e-3);
        let (fa, fb) = (drag(ta, g * ta), drag(tb, g * tb));
        let reach = 2e-4;
        let d = DVec3::new(0.0, 0.0, reach); // b directly above a, touching
        let (va, vb) = (DVec3::new(0.0, 0.0, -5.0), DVec3::new(0.0, 0.0, -4.0)); // separating
        let found = contact_search(d, va, vb, &fa, &fb, reach, 1.0);
        let Search::At(s) = found else {
            panic!("{found:?}")
        };
        let sampled = (1..=200_000)
            .map(|k| 0.02 * k as f64 / 200_000.0)
            .find(|&t| (d + fb.displacement(vb, t) - fa.displacement(va, t)).length() <= reach)
            .unwrap();
        assert!(
            s > 0.0 && (s - sampled).abs() <= 0.02 / 200_000.0,
            "{s} vs {sampled}"
        );
    }

    #[test]
    fn equal_drag_contact_matches_the_general_search() {
        // Equal τ takes the closed form; a τ one part in 1e12 larger takes the search:
        // the two agree to the search's tolerance.
        let c = DVec3::new(0.0, 0.0, -2.0);
        let (fa, fb) = (drag(1e-3, c), drag(1e-3, c));
        let fb_near = drag(1e-3 * (1.0 + 1e-12), c);
        let d = DVec3::new(1e-6, 2e-6, 6e-5);
        let (va, vb) = (DVec3::new(0.0, 0.0, 0.3), DVec3::new(0.01, 0.0, -0.4));
        let (Search::At(closed), Search::At(searched)) = (
            contact_search(d, va, vb, &fa, &fb, 2e-5, 1.0),
            contact_search(d, va, vb, &fa, &fb_near, 2e-5, 1.0),
        ) else {
            panic!("both meet")
        };
        assert!(
            (closed - searched).abs() <= 1e-9 * closed,
            "{closed} vs {searched}"
        );
    }

    #[test]
    fn wall_crossing_matches_sampling() {
        let f = drag(1e-3, DVec3::new(0.0, 0.0, -2.0));
        // Moving up at first, turned back by the drag and the settling: leaves below.
        let still = Flight::Ballistic;
        let found = wall_crossing(
            0.4e-3,
            DVec3::new(0.0, 0.0, 1.0),
            &f,
            DVec3::ZERO,
            &still,
            2,
            1e-3,
            1.0,
        );
        let (s, side) = found.unwrap();
        assert_eq!(side, -1);
        let z = 0.4e-3 + f.displacement(DVec3::new(0.0, 0.0, 1.0), s).z;
        assert!(z.abs() < 1e-15, "z at the crossing {z:e}");
        // Its highest point stays inside the cell: it never leaves by the top.
        let top = (0..10_000)
            .map(|k| {
                0.4e-3
                    + f.displacement(DVec3::new(0.0, 0.0, 1.0), s * k as f64 / 1e4)
                        .z
            })
            .fold(f64::MIN, f64::max);
        assert!(top < 1e-3);
        // In a frame that flies as the body does, the closed form; against a frame on
        // a slightly different flight, the search: the two agree.
        let frame_v = DVec3::new(0.0, 0.0, -0.5);
        let closed = wall_crossing(
            0.4e-3,
            DVec3::new(0.0, 0.0, 1.0),
            &f,
            frame_v,
            &f,
            2,
            1e-3,
            1.0,
        );
        let near = drag(1e-3 * (1.0 + 1e-12), DVec3::new(0.0, 0.0, -2.0));
        let searched = wall_crossing(
            0.4e-3,
            DVec3::new(0.0, 0.0, 1.0),
            &f,
            frame_v,
            &near,
            2,
            1e-3,
            1.0,
        );
        let ((a, sa), (b, sb)) = (closed.unwrap(), searched.unwrap());
        assert_eq!((sa, sb), (1, 1));
        assert!((a - b).abs() <= 1e-9 * a, "{a} vs {b}");
    }
}
