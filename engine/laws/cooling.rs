//! The cooling law of one grain between impacts, and its exact solution.
//!
//! A grain is a lumped-capacitance sphere (mass m, heat capacity C, surface a_s = 4π b²) that
//! loses heat to the gas by convection and to the far field by radiation (docs/model.md §8, P04
//! stage II):
//!
//! ```text
//! dθ/dt = −g(θ),   g(θ) = k_c (θ − θ0) + k_r (θ⁴ − θs⁴),
//! k_c = hc a_s / (m C),   k_r = B ε a_s / (m C).
//! ```
//!
//! # Why an accurate solution, not just a stable one
//!
//! The event-driven core does not cool every body every step: it advances a body's
//! temperature over whatever interval has passed since that body's last update, anything
//! from picoseconds to hours. Such an interval often starts right after an impact has heated
//! the grain to 1e6–1e9 K, where radiation is violently stiff (k_r θ³ reaches 1e15 /s against
//! intervals of 1e-2 s). Forward Euler explodes there. Backward Euler is stable, but over one
//! such interval it lags the true cooling badly: one 10 µs step from 1e9 K leaves a 0.8 mm
//! grain 12× too hot (1.8e6 K instead of 1.55e5 K). [`CoolingLaw::advance`] is accurate to
//! ~1e-13 relative for any interval and any temperature, at a cost of about a microsecond.
//!
//! # Method of [`CoolingLaw::advance`]
//!
//! The equation is scalar and autonomous, so it is solved exactly by quadrature: the time to
//! go from θ_a to θ_b is T = ∫ dθ/g(θ) from θ_b to θ_a, and θ(t + dt) is the θ_b for which
//! T = dt, found by safeguarded Newton. g is increasing and convex on θ ≥ 0, so it has one
//! positive root θ_eq, every trajectory moves monotonically toward it, and T is monotone in
//! θ_b. Exact formulas replace time stepping because stepping is what is hard here: in time,
//! θ(t) has a singularity (θ = ∞) in the past at about the age u/(3 k_r), u = θ^{-3}, so any
//! Runge–Kutta in any variable must crawl through the hot range in steps shorter than that age
//! (an adaptive Dormand–Prince 5(4) in u and ln|θ − θ_eq| took 100–270 steps, ~50 µs, for
//! long intervals). As a function of the state the integrand 1/g is analytic, and the cost is
//! the same for any interval.
//!
//! * Closed forms where they exist: k_r = 0 gives θ0 + (θ − θ0) e^{−k_c t}; with no heat
//!   source (k_c θ0 + k_r θs⁴ = 0, so θ_eq = 0; this covers k_c = 0 with θs = 0) u = θ^{-3}
//!   obeys the linear du/dt = 3 k_r + 3 k_c u.
//! * Otherwise g has four simple roots: θ_eq > 0, one negative root, and a complex pair, all
//!   found by Newton and deflation. Let R be the largest root modulus.
//! * **Hot** (θ > 2R): with x = 1/θ, the time from θ = ∞ is
//!   T_∞(x) = (1/k_r) ∫₀ˣ s² ds / (1 + a s³ − b s⁴), a = k_c/k_r, b = (k_c θ0 + k_r θs⁴)/k_r,
//!   a power series in x whose coefficients follow from a three-term recurrence and which
//!   converges at least like 2⁻ⁿ. Newton runs in u = x³, in which T_∞ is nearly linear.
//!   The stiffness that defeats time stepping is just the x³/(3 k_r) leading term here.
//! * **Near** (θ ≤ 2R, cooling or warming): partial fractions, T = Σ_r ln((θ_a − r)/(θ_b − r))
//!   / g'(r) over the four roots, each term in log1p form. The θ_eq term is carried exactly as
//!   −v/g'(θ_eq), v = ln(δ_b/δ_a), δ = θ − θ_eq, and Newton runs in v, in which T is nearly
//!   linear: dT/dv = −δ/g = −1/λ(δ), and the mean slope λ(δ) = (g(θ) − g(θ_eq))/δ rises at
//!   most 12-fold (55 by a bound on R) from θ_eq to 2R. The exponential approach to θ_eq is
//!   thus exact for any dt (1e6 s costs what 1 µs does), δ keeps its sign, and the result
//!   never overshoots θ_eq. Below 2R the terms cancel by at most a factor 22 (measured over
//!   k_c = 0…1e3, k_r = 1e-20…1e-9, θ0, θs = 0…1e4), so T keeps ~14 digits; above 2R they
//!   would cancel like (θ/R)³, which is why the hot range has its series.
//!
//! The hc = 0 references [`radiative_closed_form`] (θs = 0), [`radiative_time_to`] and
//! [`radiative_closed_form_with_far_field`] (θs > 0), and [`convective_closed_form`] (ε = 0)
//! are exact and serve the tests here and elsewhere.

/// Stefan–Boltzmann constant B [W/(m² K⁴)].
pub const STEFAN_BOLTZMANN: f64 = 5.670374419e-8;

// How temperatures are advanced between impacts (docs/model.md §8): the `physics.cooling`
// option (no doc comment: the schema carries the variants' own).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
/// How the cooling ODE of each body is integrated over a step (`physics.cooling`,
/// docs/model.md §8).
pub enum CoolingMethod {
    /// No cooling system.
    Off,
    /// Forward Euler (the papers' choice, P04 (6.21)); conditionally stable.
    Explicit,
    /// Reading: forward Euler kept from blowing up — a step that would cross the
    /// equilibrium temperature stops at it (stepped core only, like `explicit`).
    ExplicitClamped,
    /// Backward Euler by safeguarded Newton; unconditionally stable and monotone. The
    /// event core integrates cooling accurately instead (as `exact`).
    #[default]
    Implicit,
    /// Accurate integration over each interval (≤ 1e-9 relative to the closed forms).
    Exact,
}

/// Newton iterations allowed for any root here: a guard, not a tolerance. Most solves take
/// 3–6 (quadratic convergence from a bracket end or a close first guess); the most seen in a
/// sweep of 150 000 cases was 26, where bisection stood in for a few steps.
const MAX_NEWTON_ITERATIONS: usize = 100;

/// ln(δ/δ_a) beyond which θ is θ_eq to rounding: e^{−800} δ_a is far below any ulp of θ_eq.
const EQUILIBRATED: f64 = 800.0;

/// Terms allowed in the hot-range series; with x R ≤ 1/2 it needs ~60 to reach 1e-18.
const MAX_SERIES_TERMS: usize = 400;

/// The cooling law of one body: dθ/dt = −(k_c (θ − θ0) + k_r (θ⁴ − θs⁴)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoolingLaw {
    /// hc a_s / (m C) [1/s].
    pub k_convection: f64,
    /// B ε a_s / (m C) [1/(s K³)].
    pub k_radiation: f64,
    /// Gas temperature θ0 [K].
    pub theta_gas: f64,
    /// Far-field temperature θs [K].
    pub theta_far: f64,
}

impl CoolingLaw {
    /// One step with the chosen method.
    pub fn step(&self, method: CoolingMethod, theta: f64, dt: f64) -> f64 {
        match method {
            CoolingMethod::Off => theta,
            CoolingMethod::Explicit => self.explicit_step(theta, dt),
            CoolingMethod::ExplicitClamped => self.explicit_clamped_step(theta, dt),
            CoolingMethod::Implicit => self.implicit_step(theta, dt),
            CoolingMethod::Exact => self.advance(theta, dt),
        }
    }

    /// dθ/dt at θ [K/s].
    pub fn rate(&self, theta: f64) -> f64 {
        -(self.k_convection * (theta - self.theta_gas)
            + self.k_radiation * (theta.powi(4) - self.theta_far.powi(4)))
    }

    /// Forward Euler step (P04 (6.21)). Unbounded for large Δt: may go negative or infinite.
    pub fn explicit_step(&self, theta: f64, dt: f64) -> f64 {
        theta + dt * self.rate(theta)
    }

    /// Forward Euler step that stops at the equilibrium temperature instead of crossing
    /// it (the `explicit_clamped` reading): the papers' scheme without its blow-up.
    pub fn explicit_clamped_step(&self, theta: f64, dt: f64) -> f64 {
        let next = self.explicit_step(theta, dt);
        match self.equilibrium_temperature() {
            Some(eq) => next.clamp(theta.min(eq), theta.max(eq)),
            None => theta,
        }
    }

    /// Backward Euler step: solves θ − θ_old − Δt·rate(θ) = 0 by Newton, safeguarded by
    /// the bracket [min(θ_old, θ0, θs), max(θ_old, θ0, θs)] on which the residual changes sign.
    pub fn implicit_step(&self, theta_old: f64, dt: f64) -> f64 {
        let f = |t: f64| t - theta_old - dt * self.rate(t);
        let df = |t: f64| 1.0 + dt * (self.k_convection + 4.0 * self.k_radiation * t.powi(3));
        let mut lo = theta_old.min(self.theta_gas).min(self.theta_far);
        let mut hi = theta_old.max(self.theta_gas).max(self.theta_far);
        if self.k_convection == 0.0 {
            // Without convection θ0 is no attractor: the bracket is [θs, θ_old] (or reversed).
            lo = theta_old.min(self.theta_far);
            hi = theta_old.max(self.theta_far);
        }
        if self.k_radiation == 0.0 && self.k_convection == 0.0 {
            return theta_old;
        }
        let mut t = theta_old;
        for _ in 0..100 {
            let ft = f(t);
            if ft == 0.0 {
                return t;
            }
            if ft > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let mut next = t - ft / df(t);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            // Stop at rounding level. (A looser stop, 1e-8, left errors of ~1e-8 θ for
            // steps far below the explicit limit: the study's cooling map showed it.)
            if (next - t).abs() <= 1e-14 * next.abs() {
                return next;
            }
            t = next;
        }
        t
    }

    /// Forward Euler's stability limit at θ [s]: 1 / (k_c + 4 k_r θ³).
    pub fn explicit_limit(&self, theta: f64) -> f64 {
        1.0 / (self.k_convection + 4.0 * self.k_radiation * theta.powi(3))
    }

    /// The equilibrium temperature θ_eq [K], the root of the rate: between θ0 and θs with both
    /// terms on, θs without convection, θ0 without radiation; `None` when both are off.
    pub fn equilibrium_temperature(&self) -> Option<f64> {
        let (kc, kr) = (self.k_convection, self.k_radiation);
        match (kc > 0.0, kr > 0.0) {
            (false, false) => None,
            (true, false) => Some(self.theta_gas),
            (false, true) => Some(self.theta_far),
            (true, true) => Some(solve_equilibrium(kc, kr, self.heat_source())),
        }
    }

    /// θ(t + dt) given θ(t) = `theta` (finite, ≥ 0), for any dt ≥ 0, exact to ~1e-13 relative
    /// (see the module documentation for the method). Monotone toward θ_eq, never past it;
    /// `theta` unchanged when dt = 0 or both coefficients are 0.
    pub fn advance(&self, theta: f64, dt: f64) -> f64 {
        // A negative or non-finite temperature is left as it is, for the invariant checks
        // to report (a broken scheme upstream, e.g. explicit cooling), not hidden here.
        if !(theta >= 0.0 && theta.is_finite()) {
            return theta;
        }
        let (kc, kr) = (self.k_convection, self.k_radiation);
        if !is_positive(dt) || (kc == 0.0 && kr == 0.0) {
            return theta;
        }
        if kr == 0.0 {
            let cooled = convective_closed_form(theta, kc, self.theta_gas, dt);
            return cooled.clamp(theta.min(self.theta_gas), theta.max(self.theta_gas));
        }
        let source = self.heat_source();
        let (theta_eq, cooled) = if source == 0.0 {
            (0.0, sourceless_closed_form(theta, kc, kr, dt))
        } else {
            let relaxation = Relaxation::new(*self, source);
            (relaxation.theta_eq, relaxation.advance(theta, dt))
        };
        // The exact θ(t) lies between θ and θ_eq; this clamp only removes the last ulp that
        // rounding (u = θ^{-3} and back, say) could add on the wrong side.
        cooled.clamp(theta.min(theta_eq), theta.max(theta_eq))
    }

    /// k_c θ0 + k_r θs⁴ [K/s]: the heating the rate would have at θ = 0.
    fn heat_source(&self) -> f64 {
        self.k_convection * self.theta_gas + self.k_radiation * self.theta_far.powi(4)
    }
}

/// Exact radiative cooling with hc = 0, θs = 0: θ(t) = (θ(0)^{-3} + 3 k t)^{-1/3}, k = k_r.
pub fn radiative_closed_form(theta_initial: f64, k_radiation: f64, t: f64) -> f64 {
    (theta_initial.powi(-3) + 3.0 * k_radiation * t).powf(-1.0 / 3.0)
}

/// Exact convective cooling with ε = 0: θ(t) = θ0 + (θ(0) − θ0) e^{−k t}, k = k_c,
/// evaluated as θ(0) + (θ(0) − θ0) expm1(−k t) so that a small change keeps its digits.
pub fn convective_closed_form(
    theta_initial: f64,
    k_convection: f64,
    theta_gas: f64,
    t: f64,
) -> f64 {
    theta_initial + (theta_initial - theta_gas) * (-k_convection * t).exp_m1()
}

/// Exact time [s] for dθ/dt = −k (θ⁴ − θs⁴) (hc = 0) to take θ from `theta_from` to
/// `theta_to`: cooling with θs < θ_to ≤ θ_from, or warming with θ_from ≤ θ_to < θs.
/// Infinite when θ_to is never reached (beyond θs, or on the wrong side of θ_from), or k = 0.
///
/// The antiderivative of 1/(θ⁴ − θs⁴) is G(θ) = (1/(4θs³)) [ln|(θ−θs)/(θ+θs)| − 2 atan(θ/θs)].
/// Differences of G are taken in log1p/atan form, exact for nearby end points, while both
/// lie within 2θs. Above 2θs, G(θ) − G(∞) = −θ^{-3} Σ_n (θs/θ)^{4n}/(4n+3) (the leading terms
/// of G cancel to (θs/θ)³ there, hopelessly at θ/θs = 1e7), differenced term by term.
pub fn radiative_time_to(theta_from: f64, theta_to: f64, k_radiation: f64, theta_far: f64) -> f64 {
    let s = theta_far;
    if theta_to == theta_from {
        return 0.0;
    }
    let cooling = s < theta_to && theta_to < theta_from;
    let warming = theta_from < theta_to && theta_to < s;
    if !(cooling || warming) || !is_positive(k_radiation) {
        return f64::INFINITY;
    }
    let knee = 2.0 * s;
    if warming || theta_from <= knee {
        let to_gap = (theta_to - s).abs();
        return near_far_field_time(theta_from, theta_to, to_gap, s) / k_radiation;
    }
    if theta_to >= knee {
        return above_knee_time(theta_from, theta_to, s) / k_radiation;
    }
    (above_knee_time(theta_from, knee, s) + near_far_field_time(knee, theta_to, theta_to - s, s))
        / k_radiation
}

/// θ(t) for dθ/dt = −k (θ⁴ − θs⁴) (hc = 0) from θ(0) = `theta_initial`: the inverse of
/// [`radiative_time_to`], solved by safeguarded Newton to rounding. Newton runs in a
/// variable in which the time is nearly linear: u = θ^{-3} above 2θs, ln|θ − θs| from θs/2
/// to 2θs (dt/d ln|θ − θs| lies within a factor 4 of −1/(k θs³) there), θ itself below θs/2.
pub fn radiative_closed_form_with_far_field(
    theta_initial: f64,
    k_radiation: f64,
    theta_far: f64,
    t: f64,
) -> f64 {
    let (theta, k, s) = (theta_initial, k_radiation, theta_far);
    if !is_positive(t) || !is_positive(k) || theta == s {
        return theta;
    }
    if s == 0.0 {
        return radiative_closed_form(theta, k, t);
    }
    if t == f64::INFINITY {
        return s;
    }
    if theta < s {
        return warm_toward_far_field(theta, k, s, t);
    }
    let knee = 2.0 * s;
    if theta > knee {
        let to_knee = above_knee_time(theta, knee, s) / k;
        if t <= to_knee {
            return cool_above_knee(theta, k, s, t);
        }
        return cool_below_knee(knee, k, s, t - to_knee);
    }
    cool_below_knee(theta, k, s, t)
}

/// Whether x > 0 (false for NaN).
fn is_positive(x: f64) -> bool {
    x > 0.0
}

/// θ(t) with no heat source (k_c θ0 + k_r θs⁴ = 0): u = θ^{-3} obeys du/dt = 3 k_r + 3 k_c u,
/// so u(t) = u(0) e^x + 3 k_r t (e^x − 1)/x with x = 3 k_c t (the limit 3 k_r t at k_c = 0).
fn sourceless_closed_form(theta: f64, kc: f64, kr: f64, t: f64) -> f64 {
    let x = 3.0 * kc * t;
    let growth = if x == 0.0 { 1.0 } else { x.exp_m1() / x };
    let u = inverse_cube(theta) * x.exp() + 3.0 * kr * t * growth;
    1.0 / u.cbrt()
}

/// θ^{-3}, infinite at θ = 0.
fn inverse_cube(theta: f64) -> f64 {
    let r = 1.0 / theta;
    r * r * r
}

/// The root of k_c θ + k_r θ⁴ − source on θ > 0 (k_c, k_r, source > 0). The function is
/// increasing and convex, so Newton started at or above the root descends monotonically onto
/// it. Both source/k_c and (source/k_r)^{1/4} are upper bounds, and the smaller is within a
/// factor 2 of the root (one of the two terms is at least source/2 there).
fn solve_equilibrium(kc: f64, kr: f64, source: f64) -> f64 {
    let mut theta = (source / kc).min((source / kr).sqrt().sqrt());
    for _ in 0..MAX_NEWTON_ITERATIONS {
        let residual = kc * theta + kr * theta.powi(4) - source;
        let next = theta - residual / (kc + 4.0 * kr * theta.powi(3));
        // At the root to rounding the iterate stops descending.
        if next < theta {
            theta = next;
        } else {
            break;
        }
    }
    theta
}

/// G(from) − G(to) for θs (1/(4θs³) [ln|(θ−θs)/(θ+θs)| − 2 atan(θ/θs)]), both end points on
/// the same side of θs and within 2θs. The gap |to − θs| is passed in so that an end point
/// within rounding of θs keeps its distance. Both terms add (cooling and warming alike), so
/// nothing cancels by more than a factor 2.5.
fn near_far_field_time(from: f64, to: f64, to_gap: f64, s: f64) -> f64 {
    let distance = (from - to).abs();
    let log_part = (2.0 * s * distance / ((from + s) * to_gap)).ln_1p();
    let atan_part = 2.0 * (s * (from - to) / (s * s + from * to)).atan();
    (log_part - atan_part) / (4.0 * s.powi(3))
}

/// k × time to cool from `from` to `to`, both ≥ 2θs (or θs = 0), from the series
/// H(θ) = G(∞) − G(θ) = θ^{-3} S((θs/θ)⁴), S(y) = Σ_n yⁿ/(4n+3), differenced term by term:
/// H(to) − H(from) = (to^{-3} − from^{-3}) S(y_to) + from^{-3} (S(y_to) − S(y_from)), where
/// S(y_to) − S(y_from) = (y_to − y_from) Σ_{n≥1} q_n/(4n+3), q_n = Σ_{j<n} y_to^j y_from^{n−1−j}.
/// Every term is positive; y ≤ 1/16 so 14 terms reach rounding.
fn above_knee_time(from: f64, to: f64, s: f64) -> f64 {
    let (x_to, x_from) = (s / to, s / from);
    let (y_to, y_from) = (x_to.powi(4), x_from.powi(4));
    let ratio = to / from;
    let inverse_cube_gap = inverse_cube(to) * ((from - to) / from) * (1.0 + ratio + ratio * ratio);
    let x_gap = s * ((from - to) / (to * from));
    let y_gap = x_gap * (x_to + x_from) * (x_to * x_to + x_from * x_from);
    let (mut series_to, mut series_gap) = (1.0 / 3.0, 0.0);
    let (mut power_to, mut q) = (1.0, 1.0);
    for n in 1..40 {
        let denominator = (4 * n + 3) as f64;
        power_to *= y_to;
        series_to += power_to / denominator;
        series_gap += q / denominator;
        if q / denominator <= 1e-17 * series_gap && power_to <= 1e-17 {
            break;
        }
        // q_{n+1} = y_from q_n + y_to^n.
        q = y_from * q + power_to;
    }
    inverse_cube_gap * series_to + inverse_cube(from) * y_gap * series_gap
}

/// Cooling from `theta` > 2θs while the answer stays ≥ 2θs: Newton in u = θ^{-3}, where
/// d(k t)/du = 1/(3 (1 − (θs/θ)⁴)) ∈ [1/3, 16/45], so u − u(0) ∈ [45 k t/16, 3 k t].
fn cool_above_knee(theta: f64, k: f64, s: f64, t: f64) -> f64 {
    let u0 = inverse_cube(theta);
    // The bounds are attained (at θ = 2θs, θ = ∞): widened so rounding keeps the root inside.
    let lo = u0 + 2.75 * k * t;
    let hi = (u0 + 3.1 * k * t).min(inverse_cube(2.0 * s));
    let residual = |u: f64| {
        let to = 1.0 / u.cbrt();
        let y = (s / to).powi(4);
        (
            above_knee_time(theta, to, s) / k - t,
            1.0 / (3.0 * k * (1.0 - y)),
        )
    };
    // First guess: the starting slope 1/(3 (1 − y)) held.
    let guess = u0 + 3.0 * k * t * (1.0 - (s / theta).powi(4));
    1.0 / safeguarded_newton(residual, lo, hi, guess).cbrt()
}

/// Cooling from `theta` ∈ (θs, 2θs]: Newton in z = ln(θ − θs), where
/// dz/dt = −k (θ + θs)(θ² + θs²) ∈ [−15 k θs³, −4 k θs³].
fn cool_below_knee(theta: f64, k: f64, s: f64, t: f64) -> f64 {
    let z0 = (theta - s).ln();
    let s3 = s.powi(3);
    // Widened, as the bound −15 k θs³ is attained at θ = 2θs.
    let (lo, hi) = (z0 - 16.0 * k * s3 * t, z0 - 3.5 * k * s3 * t);
    let residual = |z: f64| {
        let gap = z.exp();
        let to = s + gap;
        let time = near_far_field_time(theta, to, gap, s) / k;
        (time - t, -1.0 / (k * (to + s) * (to * to + s * s)))
    };
    s + safeguarded_newton(residual, lo, hi, 0.5 * (lo + hi)).exp()
}

/// Warming from `theta` < θs, through θs/2 if it starts below.
fn warm_toward_far_field(theta: f64, k: f64, s: f64, t: f64) -> f64 {
    let half = 0.5 * s;
    if theta < half {
        let to_half = near_far_field_time(theta, half, half, s) / k;
        if t <= to_half {
            return warm_below_half(theta, k, s, t);
        }
        return warm_above_half(half, k, s, t - to_half);
    }
    warm_above_half(theta, k, s, t)
}

/// Warming within [0, θs/2]: Newton in θ itself, which keeps its relative digits at a few
/// kelvin (θs − θ would not); dθ/dt = k (θs⁴ − θ⁴) ∈ [15/16 k θs⁴, k θs⁴] there.
fn warm_below_half(theta: f64, k: f64, s: f64, t: f64) -> f64 {
    let s4 = s.powi(4);
    // Widened, as the bound k θs⁴ is attained at θ = 0.
    let lo = theta + 0.9 * k * s4 * t;
    let hi = (theta + 1.05 * k * s4 * t).min(0.5 * s);
    let residual = |to: f64| {
        let time = near_far_field_time(theta, to, s - to, s) / k;
        (time - t, 1.0 / (k * (s4 - to.powi(4))))
    };
    let guess = theta + k * (s4 - theta.powi(4)) * t;
    safeguarded_newton(residual, lo, hi, guess)
}

/// Warming from `theta` ∈ [θs/2, θs): Newton in z = ln(θs − θ), where
/// dz/dt = −k (θs + θ)(θs² + θ²) ∈ [−4 k θs³, −k (θs + θ(0))(θs² + θ(0)²)].
fn warm_above_half(theta: f64, k: f64, s: f64, t: f64) -> f64 {
    let z0 = (s - theta).ln();
    let slowest = k * (s + theta) * (s * s + theta * theta);
    // Widened, as the second bound is attained at the start.
    let (lo, hi) = (z0 - 4.2 * k * s.powi(3) * t, z0 - 0.95 * slowest * t);
    let residual = |z: f64| {
        let gap = z.exp();
        let to = s - gap;
        let time = near_far_field_time(theta, to, gap, s) / k;
        (time - t, -1.0 / (k * (to + s) * (to * to + s * s)))
    };
    s - safeguarded_newton(residual, lo, hi, 0.5 * (lo + hi)).exp()
}

/// The root of a monotone `f` (returning value and derivative) on [lo, hi], where f changes
/// sign: Newton from `guess` (the midpoint if it is outside), falling back to bisection
/// whenever a step leaves the bracket, until the iterate stops moving at rounding level.
fn safeguarded_newton(f: impl Fn(f64) -> (f64, f64), mut lo: f64, mut hi: f64, guess: f64) -> f64 {
    let at_lo = f(lo).0;
    if at_lo == 0.0 {
        return lo;
    }
    let negative_at_lo = at_lo < 0.0;
    let inside = guess > lo.min(hi) && guess < lo.max(hi);
    let mut x = if inside { guess } else { 0.5 * (lo + hi) };
    for _ in 0..MAX_NEWTON_ITERATIONS {
        let (value, slope) = f(x);
        if value == 0.0 {
            return x;
        }
        if (value < 0.0) == negative_at_lo {
            lo = x;
        } else {
            hi = x;
        }
        let mut next = x - value / slope;
        if !(next > lo.min(hi) && next < lo.max(hi)) {
            next = 0.5 * (lo + hi);
        }
        // Done when the step or the bracket is down to a few ulps (rounding noise in f can
        // otherwise make Newton cycle between neighbours).
        let ulps = 4.0 * f64::EPSILON * x.abs();
        if (next - x).abs() <= ulps || (hi - lo).abs() <= ulps {
            return next;
        }
        x = next;
    }
    x
}

/// The negative root of k_r θ⁴ + k_c θ − source (k_c, k_r, source > 0). The function is
/// convex and decreasing through that root, so Newton started left of it (where it is ≥ 0)
/// climbs monotonically onto it. The start |θ| = max((2 k_c/k_r)^{1/3}, (2 source/k_r)^{1/4})
/// is such a point: there k_r θ⁴ ≥ 2 k_c |θ| and ≥ 2 source.
fn solve_negative_root(kc: f64, kr: f64, source: f64) -> f64 {
    let magnitude = (2.0 * kc / kr)
        .cbrt()
        .max((2.0 * source / kr).sqrt().sqrt());
    let mut theta = -magnitude;
    for _ in 0..MAX_NEWTON_ITERATIONS {
        let residual = kr * theta.powi(4) + kc * theta - source;
        let next = theta - residual / (4.0 * kr * theta.powi(3) + kc);
        // At the root to rounding the iterate stops climbing.
        if next > theta {
            theta = next;
        } else {
            break;
        }
    }
    theta
}

/// A complex number, for the complex pair of roots of g and their residues.
#[derive(Debug, Clone, Copy)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn mul(self, other: Self) -> Self {
        Self {
            re: self.re * other.re - self.im * other.im,
            im: self.re * other.im + self.im * other.re,
        }
    }

    /// 1/z: z̄/|z|² while |z|² is a normal number (every scene that ran before, bit for
    /// bit), else Smith's algorithm, dividing through by the larger part first, so that a
    /// tiny z (a slope k_r θ³ of 1e-164 /s, a heat capacity of 1e163 J/(kg·K)) does not
    /// square to 0 and give a NaN residue, nor a huge one overflow.
    fn recip(self) -> Self {
        let norm = self.re * self.re + self.im * self.im;
        if norm.is_normal() {
            return Self {
                re: self.re / norm,
                im: -self.im / norm,
            };
        }
        if self.re.abs() >= self.im.abs() {
            let r = self.im / self.re;
            let d = self.re + self.im * r;
            Self {
                re: 1.0 / d,
                im: -r / d,
            }
        } else {
            let r = self.re / self.im;
            let d = self.re * r + self.im;
            Self {
                re: r / d,
                im: -1.0 / d,
            }
        }
    }

    /// ln(1 + self), with the modulus through log1p so that a small argument keeps its digits:
    /// |1 + z|² − 1 = Re z (2 + Re z) + (Im z)².
    fn ln_1p(self) -> Self {
        Self {
            re: 0.5 * (self.re * (2.0 + self.re) + self.im * self.im).ln_1p(),
            im: self.im.atan2(1.0 + self.re),
        }
    }
}

/// A law with radiation and a heat source, in the form its exact solution needs: the four
/// roots of g (θ_eq, a negative root, a complex pair) with the residues 1/g'(r) of 1/g.
#[derive(Debug, Clone, Copy)]
struct Relaxation {
    k_radiation: f64,
    /// k_c/k_r and (k_c θ0 + k_r θs⁴)/k_r: g/k_r = θ⁴ + a θ − b.
    a: f64,
    b: f64,
    theta_eq: f64,
    /// g'(θ_eq) = k_c + 4 k_r θ_eq³ [1/s]: the rate of the final exponential approach.
    lambda_eq: f64,
    negative_root: f64,
    negative_residue: f64,
    /// The root of the complex pair with positive imaginary part, and its residue.
    complex_root: Complex,
    complex_residue: Complex,
    /// 2R, R the largest root modulus: above it the hot-range series converges like 2⁻ⁿ.
    hot_threshold: f64,
}

impl Relaxation {
    fn new(law: CoolingLaw, source: f64) -> Self {
        let (kc, kr) = (law.k_convection, law.k_radiation);
        let (theta_eq, negative_root) = if kc == 0.0 {
            // g = k_r (θ⁴ − θs⁴): roots ±θs, ±i θs, exactly.
            (law.theta_far, -law.theta_far)
        } else {
            (
                solve_equilibrium(kc, kr, source),
                solve_negative_root(kc, kr, source),
            )
        };
        // Deflation: θ⁴ + a θ − b = (θ² − S θ + P)(θ² + S θ + S² − P), S and P the sum and
        // product of the real roots (the θ³ and θ² terms vanish). P < 0 makes the second
        // factor's discriminant negative: roots −S/2 ± i √(3S²/4 − P).
        let (sum, product) = (theta_eq + negative_root, theta_eq * negative_root);
        let complex_root = Complex {
            re: -0.5 * sum,
            im: (0.75 * sum * sum - product).sqrt(),
        };
        let slope = |r: f64| kc + 4.0 * kr * r.powi(3);
        let cube = complex_root.mul(complex_root).mul(complex_root);
        let complex_slope = Complex {
            re: kc + 4.0 * kr * cube.re,
            im: 4.0 * kr * cube.im,
        };
        let largest_root = theta_eq
            .max(-negative_root)
            .max(complex_root.re.hypot(complex_root.im));
        Self {
            k_radiation: kr,
            a: kc / kr,
            b: source / kr,
            theta_eq,
            lambda_eq: slope(theta_eq),
            negative_root,
            negative_residue: 1.0 / slope(negative_root),
            complex_root,
            complex_residue: complex_slope.recip(),
            hot_threshold: 2.0 * largest_root,
        }
    }

    fn advance(&self, theta: f64, dt: f64) -> f64 {
        let (mut theta, mut dt) = (theta, dt);
        if theta > self.hot_threshold {
            match self.cool_while_hot(theta, dt) {
                Ok(cooled) => return cooled,
                Err(time_left) => (theta, dt) = (self.hot_threshold, time_left),
            }
        }
        if theta == self.theta_eq {
            return theta;
        }
        self.relax(theta, dt)
    }

    /// λ(δ) = (g(θ_eq + δ) − g(θ_eq))/δ, the mean slope of g, written out so that nothing
    /// cancels near θ_eq: k_c + k_r (4θ_eq³ + 6θ_eq² δ + 4θ_eq δ² + δ³). Positive for θ ≥ 0
    /// and increasing in δ.
    fn mean_slope(&self, delta: f64) -> f64 {
        let te = self.theta_eq;
        self.lambda_eq + self.k_radiation * delta * (6.0 * te * te + delta * (4.0 * te + delta))
    }

    /// Cooling above 2R: θ after dt, or Err(time left) if the grain reaches 2R first.
    /// Solves T_∞(x_b) = T_∞(x_a) + dt by Newton in u = x³, where dT_∞/du = 1/(3 k_r q(x)),
    /// q(x) = 1 + a x³ − b x⁴ = g(θ) x⁴/k_r, within [u_a, u(2R)].
    fn cool_while_hot(&self, theta: f64, dt: f64) -> Result<f64, f64> {
        let x_start = 1.0 / theta;
        let x_end = 1.0 / self.hot_threshold;
        let (time_start, time_end) = (
            self.time_from_infinity(x_start),
            self.time_from_infinity(x_end),
        );
        let target = time_start + dt;
        if target >= time_end {
            return Err(target - time_end);
        }
        let q = |x: f64| 1.0 + x.powi(3) * (self.a - self.b * x);
        let residual = |u: f64| {
            let x = u.cbrt();
            let time = self.time_from_infinity(x);
            (time - target, 1.0 / (3.0 * self.k_radiation * q(x)))
        };
        // First guess: the start's rate held constant in u.
        let u_start = x_start.powi(3);
        let guess = u_start + 3.0 * self.k_radiation * q(x_start) * dt;
        let u = safeguarded_newton(residual, u_start, x_end.powi(3), guess);
        Ok(1.0 / u.cbrt())
    }

    /// T_∞(x) = (1/k_r) ∫₀ˣ s² ds / q(s) = (1/k_r) Σ h_n x^{n+1}/(n+1): the time to cool from
    /// θ = ∞ to θ = 1/x. From h(s) q(s) = s², h_n = [n = 2] − a h_{n−3} + b h_{n−4}; the
    /// terms t_n = h_n xⁿ obey the same recurrence with a x³ and b x⁴, which never overflow.
    /// The radius of convergence is 1/R, and x ≤ 1/(2R) here.
    fn time_from_infinity(&self, x: f64) -> f64 {
        let x3 = x.powi(3);
        let (ax3, bx4) = (self.a * x3, self.b * x3 * x);
        let negligible = 1e-18 * x * x;
        // t_{n−4}, t_{n−3}, t_{n−2}, t_{n−1}.
        let mut recent = [0.0_f64; 4];
        let mut sum = 0.0;
        for n in 2..MAX_SERIES_TERMS {
            let term = if n == 2 {
                x * x
            } else {
                -ax3 * recent[1] + bx4 * recent[0]
            };
            sum += term / (n + 1) as f64;
            recent = [recent[1], recent[2], recent[3], term];
            // Four negligible terms in a row: every later term is built from them.
            if recent.iter().all(|t| t.abs() <= negligible) {
                break;
            }
        }
        x * sum / self.k_radiation
    }

    /// θ after dt from θ ≠ θ_eq at or below 2R: the θ_b on θ's side of θ_eq for which the
    /// exact time T(θ → θ_b) is dt. Newton in v = ln(δ_b/δ_a) ≤ 0, δ = θ − θ_eq, where
    /// dT/dv = −1/λ(δ_b). Since λ is monotone in δ, v lies in [−λ_fast dt, −λ_slow dt],
    /// λ_slow and λ_fast the smaller and larger of λ_eq and λ(δ_a). T is convex in v when
    /// cooling and concave when warming, so Newton started at the matching end of that
    /// bracket converges monotonically. v (not ln|δ_b|) keeps full precision for short dt.
    fn relax(&self, theta: f64, dt: f64) -> f64 {
        let delta = theta - self.theta_eq;
        let slope_start = self.mean_slope(delta);
        let (slow, fast) = if delta > 0.0 {
            (self.lambda_eq, slope_start)
        } else {
            (slope_start, self.lambda_eq)
        };
        let (lo, hi) = (-fast * dt, -slow * dt);
        if hi < -EQUILIBRATED {
            return self.theta_eq;
        }
        let mut v = if delta > 0.0 { lo } else { hi };
        let mut previous_change = f64::INFINITY;
        for _ in 0..MAX_NEWTON_ITERATIONS {
            let excess = self.time_near(theta, delta, v) - dt;
            let next = (v + excess * self.mean_slope(delta * v.exp())).clamp(lo, hi);
            let change = (next - v).abs();
            v = next;
            // Done when the step moves θ by under a quarter ulp, or when Newton, which
            // contracts quadratically, stops contracting: it has reached the rounding noise
            // of T (about 1e-15 of it) and would otherwise cycle between neighbours.
            let moved = change * delta.abs() * v.exp();
            let stalled = change >= previous_change && change <= 1e-9 * (1.0 + v.abs());
            if moved <= 0.25 * f64::EPSILON * theta.min(self.theta_eq) || stalled {
                break;
            }
            previous_change = change;
        }
        // Whichever form rounds less: near θ_eq its offset, else the change from θ (which at
        // θ far below θ_eq keeps digits that θ_eq + δ would lose).
        if v < -std::f64::consts::LN_2 {
            self.theta_eq + delta * v.exp()
        } else {
            theta + delta * v.exp_m1()
        }
    }

    /// The exact time from θ_a = θ_eq + δ_a to θ_eq + δ_a e^v (v ≤ 0):
    /// Σ_r ln((θ_a − r)/(θ_b − r)) / g'(r) over the roots of g. The θ_eq term is −v/λ_eq,
    /// exact at any distance from θ_eq; the others are log1p of (θ_a − θ_b)/(θ_b − r),
    /// accurate for nearby end points.
    fn time_near(&self, theta_a: f64, delta_a: f64, v: f64) -> f64 {
        let drop = -delta_a * v.exp_m1();
        let theta_b = theta_a - drop;
        let negative = self.negative_residue * (drop / (theta_b - self.negative_root)).ln_1p();
        let from_pair = Complex {
            re: theta_b - self.complex_root.re,
            im: -self.complex_root.im,
        };
        let log_ratio = Complex { re: drop, im: 0.0 }.mul(from_pair.recip()).ln_1p();
        let pair = 2.0 * self.complex_residue.mul(log_ratio).re;
        -v / self.lambda_eq + negative + pair
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative difference of `value` from `reference`.
    fn relative_error(value: f64, reference: f64) -> f64 {
        ((value - reference) / reference).abs()
    }

    /// `per_decade` log-spaced values per decade from 10^`from` to 10^`to`.
    fn log_range(from: i32, to: i32, per_decade: i32) -> impl Iterator<Item = f64> {
        (from * per_decade..=to * per_decade)
            .map(move |i| 10f64.powf(f64::from(i) / f64::from(per_decade)))
    }

    /// θ_eq by 200 bisections of the rate on [0, max(θ0, θs)], independent of the Newton
    /// solvers under test.
    fn bisected_equilibrium(law: &CoolingLaw) -> f64 {
        let (mut lo, mut hi) = (0.0, law.theta_gas.max(law.theta_far));
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if law.rate(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Nodes and weights of n-point Gauss–Legendre quadrature on [−1, 1] (Newton on the
    /// Legendre recurrence).
    fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
        let legendre = |x: f64| {
            let (mut previous, mut current) = (1.0, x);
            for k in 2..=n {
                let k = k as f64;
                let next = ((2.0 * k - 1.0) * x * current - (k - 1.0) * previous) / k;
                (previous, current) = (current, next);
            }
            let derivative = n as f64 * (x * current - previous) / (x * x - 1.0);
            (current, derivative)
        };
        (0..n)
            .map(|i| {
                let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
                for _ in 0..100 {
                    let (value, derivative) = legendre(x);
                    let step = value / derivative;
                    x -= step;
                    if step.abs() < 1e-16 {
                        break;
                    }
                }
                let (_, derivative) = legendre(x);
                (x, 2.0 / ((1.0 - x * x) * derivative * derivative))
            })
            .collect()
    }

    /// The time to go from θ_a to θ_b (same side of θ_eq) by numerical quadrature of
    /// ∫ dθ/g = ∫ δ/g(θ_eq + δ) dw, w = ln|θ − θ_eq|: an integrand that is smooth and bounded
    /// from 1e12 K to θ_eq (1/λ_eq near it, ~e^{−3w}/k_r far above). Composite 20-point
    /// Gauss–Legendre on panels ≤ 0.5 wide in w, whose nearest singularities lie ≥ ~1 away:
    /// converged to rounding. It uses `rate` alone, nothing of `advance`.
    fn quadrature_time(law: &CoolingLaw, theta_eq: f64, theta_a: f64, theta_b: f64) -> f64 {
        let delta_b = theta_b - theta_eq;
        let w_b = delta_b.abs().ln();
        let length = ((theta_a - theta_b) / delta_b).ln_1p();
        let panels = (length / 0.5).ceil().max(1.0);
        let width = length / panels;
        let rule = gauss_legendre(20);
        let mut time = 0.0;
        for panel in 0..panels as usize {
            for &(x, weight) in &rule {
                let w = w_b + (panel as f64 + 0.5 + 0.5 * x) * width;
                let delta = delta_b.signum() * w.exp();
                time += 0.5 * width * weight * (-delta / law.rate(theta_eq + delta));
            }
        }
        time
    }

    /// The relative error of θ_b = advance(θ_a, dt) implied by the quadrature: a time
    /// residual ΔT moves θ_b by ΔT |rate(θ_b)|. None when θ_b is θ_eq or θ_a to rounding
    /// (no time to measure; the monotonicity tests cover those).
    fn quadrature_error(law: &CoolingLaw, theta_eq: f64, theta_a: f64, dt: f64) -> Option<f64> {
        let theta_b = law.advance(theta_a, dt);
        let rounding = 4.0 * f64::EPSILON;
        if (theta_b - theta_eq).abs() <= rounding * theta_eq || theta_b == theta_a {
            return None;
        }
        let residual = quadrature_time(law, theta_eq, theta_a, theta_b) - dt;
        Some((residual * law.rate(theta_b) / theta_b).abs())
    }

    /// A fine reference by classical RK4 in u = θ^{-3} (du/dt = −3 u^{4/3} rate, not stiff),
    /// on a grid graded as (i/N)³ so that the first steps out of a hot start are tiny, and
    /// Richardson-extrapolated from N and 2N steps (error O(h⁵)).
    fn runge_kutta_reference(law: &CoolingLaw, theta: f64, dt: f64) -> f64 {
        let slope = |u: f64| -3.0 * u * u.cbrt() * law.rate(1.0 / u.cbrt());
        let integrate = |steps: usize| {
            let mut u = theta.powi(-3);
            let time = |i: usize| dt * (i as f64 / steps as f64).powi(3);
            for i in 0..steps {
                let h = time(i + 1) - time(i);
                let k1 = slope(u);
                let k2 = slope(u + 0.5 * h * k1);
                let k3 = slope(u + 0.5 * h * k2);
                let k4 = slope(u + h * k3);
                u += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            }
            u
        };
        let (coarse, fine) = (integrate(20_000), integrate(40_000));
        let u = fine + (fine - coarse) / 15.0;
        1.0 / u.cbrt()
    }

    fn cooling_law(
        k_convection: f64,
        k_radiation: f64,
        theta_gas: f64,
        theta_far: f64,
    ) -> CoolingLaw {
        CoolingLaw {
            k_convection,
            k_radiation,
            theta_gas,
            theta_far,
        }
    }

    /// Both terms on, gas above the far field: θ_eq ≈ 471 K, λ_eq ≈ 1.35e-2 /s.
    fn both_terms() -> CoolingLaw {
        cooling_law(1e-2, 7e-12, 500.0, 300.0)
    }

    #[test]
    fn equilibrium_is_the_root_between_gas_and_far_field() {
        for (kc, kr, gas, far) in [
            (1e-2, 7e-12, 500.0, 300.0),
            (1e-2, 7e-12, 300.0, 500.0),
            (1.0, 1e-20, 300.0, 0.0),
            (1e3, 1e-9, 1.0, 300.0),
            (1e-8, 1e-9, 5000.0, 3.0),
        ] {
            let law = cooling_law(kc, kr, gas, far);
            let theta_eq = law.equilibrium_temperature().unwrap();
            assert!(
                theta_eq >= gas.min(far) && theta_eq <= gas.max(far),
                "{law:?}: {theta_eq}"
            );
            // Newton stops at rounding; 200 bisections end there too: a few ulps apart.
            let bisected = bisected_equilibrium(&law);
            assert!(
                relative_error(theta_eq, bisected) <= 1e-14,
                "{law:?}: {theta_eq} vs {bisected}"
            );
        }
        assert_eq!(
            cooling_law(0.0, 1e-9, 500.0, 300.0).equilibrium_temperature(),
            Some(300.0)
        );
        assert_eq!(
            cooling_law(1e-2, 0.0, 500.0, 300.0).equilibrium_temperature(),
            Some(500.0)
        );
        assert_eq!(
            cooling_law(0.0, 0.0, 500.0, 300.0).equilibrium_temperature(),
            None
        );
    }

    #[test]
    fn advance_matches_radiative_closed_form() {
        // θs = 0 takes the no-source closed form in u; θs = 1e-3 K takes the general path (the
        // hot-range series), where the far field changes the rate by (θs/θ)⁴ < 1e-20.
        // Exact formulas on both sides, so rounding alone separates them: measured 2e-15.
        for theta_far in [0.0, 1e-3] {
            for kr in [1e-12, 7e-12, 1e-9] {
                let law = cooling_law(0.0, kr, 0.0, theta_far);
                for theta in [500.0, 1e4, 1e6, 1e9] {
                    for dt in log_range(-12, 3, 4) {
                        let exact = radiative_closed_form(theta, kr, dt);
                        let error = relative_error(law.advance(theta, dt), exact);
                        assert!(
                            error <= 1e-13,
                            "θs {theta_far}, k_r {kr}, θ {theta}, dt {dt}: {error:e}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn advance_matches_convective_closed_form() {
        // k_r = 0 takes the closed form itself; k_r = 1e-30 takes the general path (partial
        // fractions, R = (k_c/k_r)^{1/3} ≥ 2e9 K), where radiation changes the rate by
        // k_r θ³/k_c ≤ 1e-16. Measured: 0 and 2e-15.
        for kr in [0.0, 1e-30] {
            for kc in [1e-2, 1.0] {
                let law = cooling_law(kc, kr, 500.0, 300.0);
                for theta in [1.0, 100.0, 499.0, 501.0, 1e3, 1e4] {
                    for scaled in log_range(-12, 4, 4) {
                        let dt = scaled / kc;
                        let exact = convective_closed_form(theta, kc, 500.0, dt);
                        let error = relative_error(law.advance(theta, dt), exact);
                        assert!(
                            error <= 1e-13,
                            "k_r {kr}, k_c {kc}, θ {theta}, dt {dt}: {error:e}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn advance_matches_far_field_closed_form() {
        // hc = 0, θs = 300 K: cooling from 1e9 K down and warming from 0.01 K up (where θ_eq + δ
        // would keep only ~1e-11 of θ: the result must come from θ + change). Two independent
        // exact solutions (partial fractions over ±θs, ±iθs and the 1/θ series here; G's
        // log/atan form and the (θs/θ)⁴ series in the reference), each good to ~1e-15.
        // Measured: 3e-15.
        for kr in [1e-12, 7e-12, 1e-9] {
            let law = cooling_law(0.0, kr, 0.0, 300.0);
            for theta in [
                1e9, 1e6, 1e4, 1e3, 600.0, 400.0, 301.0, 299.0, 200.0, 100.0, 10.0, 1.0, 0.01,
            ] {
                for dt in log_range(-12, 6, 3) {
                    let exact = radiative_closed_form_with_far_field(theta, kr, 300.0, dt);
                    let error = relative_error(law.advance(theta, dt), exact);
                    assert!(error <= 1e-12, "k_r {kr}, θ {theta}, dt {dt}: {error:e}");
                }
            }
        }
    }

    #[test]
    fn far_field_references_agree_with_quadrature_and_each_other() {
        let (kr, far) = (7e-12, 300.0);
        let law = cooling_law(0.0, kr, 0.0, far);
        let pairs = [
            (1e9, 1e6),
            (1e9, 0.999e9),
            (1e9, 601.0),
            (1e4, 650.0),
            (650.0, 300.5),
            (1e9, 300.001),
            (620.0, 590.0),
            (0.0, 200.0),
            (100.0, 299.0),
            (160.0, 299.999),
        ];
        for (from, to) in pairs {
            // The quadrature loses ~1e-16 |ln(θ − θs)| / (length in w) to rounding in w: the
            // short (1e9 → 0.999e9) interval is good to ~1e-12, the others to ~1e-14.
            let exact = radiative_time_to(from, to, kr, far);
            let quadrature = quadrature_time(&law, far, from, to);
            assert!(
                relative_error(exact, quadrature) <= 1e-11,
                "{from} → {to}: {exact} vs {quadrature}"
            );
            // The inverse recovers the end point to rounding.
            let back = radiative_closed_form_with_far_field(from, kr, far, exact);
            assert!(relative_error(back, to) <= 1e-14, "{from} → {to}: {back}");
        }
        // Far above θs the series reduces to the θs = 0 closed form, (θ_to⁻³ − θ_from⁻³)/(3k).
        let time = radiative_time_to(1e9, 1e7, kr, far);
        assert!(relative_error(time, (1e-21 - 1e-27) / (3.0 * kr)) <= 1e-14);
        // Never reached: below θs while cooling, the wrong way, or with k = 0.
        assert_eq!(radiative_time_to(1e3, 200.0, kr, far), f64::INFINITY);
        assert_eq!(radiative_time_to(1e3, 2e3, kr, far), f64::INFINITY);
        assert_eq!(radiative_time_to(1e3, 500.0, 0.0, far), f64::INFINITY);
    }

    #[test]
    fn both_terms_match_the_quadrature_reference() {
        // k_c = 1e-2, k_r = 7e-12, θ0 = 500, θs = 300 across 18 decades of dt, from 1e12 K
        // down and from 1 K up. The reference is good to ~1e-15; measured 2e-15.
        let law = both_terms();
        let theta_eq = bisected_equilibrium(&law);
        let starts = [
            1e12, 1e9, 1e6, 1e4, 2000.0, 600.0, 480.0, 460.0, 400.0, 100.0, 1.0,
        ];
        for theta in starts {
            for dt in log_range(-12, 6, 4) {
                if let Some(error) = quadrature_error(&law, theta_eq, theta, dt) {
                    assert!(error <= 1e-12, "θ {theta}, dt {dt}: {error:e}");
                }
            }
        }
    }

    #[test]
    fn both_terms_match_a_fine_runge_kutta_reference() {
        // Richardson-extrapolated RK4 with 40 000 steps: h λ_eq ≤ 0.002 at dt = 1e3 s, so the
        // reference is good to ~1e-14. Measured: 8e-15.
        let law = both_terms();
        for theta in [1e9, 1e4, 600.0, 400.0, 100.0] {
            for dt in [1e-6, 1e-3, 1.0, 10.0, 100.0, 1e3] {
                let reference = runge_kutta_reference(&law, theta, dt);
                let error = relative_error(law.advance(theta, dt), reference);
                assert!(error <= 1e-12, "θ {theta}, dt {dt}: {error:e}");
            }
        }
    }

    #[test]
    fn long_intervals_stay_monotone_on_their_side() {
        let law = both_terms();
        let theta_eq = law.equilibrium_temperature().unwrap();
        for start in [1e12, 1e9, 1e4, 600.0, 472.0, 470.0, 400.0, 100.0, 1.0] {
            let side = (start - theta_eq).signum();
            // θ(dt) as dt grows to 1e6 s (1.3e4 relaxation times): never away from θ_eq,
            // never past it. Successive values may tie, or differ by an ulp the wrong way
            // where the change per dt is below rounding.
            let mut previous = start;
            for dt in log_range(-12, 6, 8) {
                let theta = law.advance(start, dt);
                assert!(
                    (theta - theta_eq) * side >= 0.0,
                    "{start}, {dt}: {theta} crossed {theta_eq}"
                );
                assert!(
                    (theta - start) * side <= 0.0,
                    "{start}, {dt}: {theta} moved away"
                );
                let backwards = (theta - previous) * side;
                assert!(
                    backwards <= 2.0 * f64::EPSILON * theta,
                    "{start}, {dt}: {previous} → {theta}"
                );
                previous = theta;
            }
            assert_eq!(law.advance(start, 1e6), theta_eq, "{start}");
            // Chained steps: the same guarantees, strictly.
            let mut theta = start;
            for dt in log_range(-6, 6, 1) {
                let next = law.advance(theta, dt);
                assert!((next - theta_eq) * side >= 0.0 && (next - theta) * side <= 0.0);
                theta = next;
            }
        }
    }

    #[test]
    fn composition_matches_one_long_step() {
        // θ(a + b) = θ(b) after θ(a) holds exactly for the flow; both sides carry the ~1e-15
        // of the method. Measured: 2e-16.
        let laws = [
            both_terms(),
            cooling_law(0.0, 7e-12, 0.0, 300.0),
            cooling_law(1.0, 1e-15, 300.0, 1e3),
        ];
        for law in laws {
            for theta in [1e9, 1e4, 600.0, 400.0, 100.0] {
                for (a, b) in [
                    (1e-9, 1e-3),
                    (1e-3, 1e-9),
                    (0.3, 7.0),
                    (10.0, 1e3),
                    (5e3, 5e3),
                ] {
                    let chained = law.advance(law.advance(theta, a), b);
                    let direct = law.advance(theta, a + b);
                    let error = relative_error(chained, direct);
                    assert!(error <= 1e-12, "{law:?}, θ {theta}, {a} + {b}: {error:e}");
                }
            }
        }
    }

    #[test]
    fn p04_grain_just_after_a_bond() {
        // P04's best case: a 0.8 mm grain (ρ = 6652.7, C = 1796.3, ε = 0.5, hc = 0, θs = 300 K)
        // heated to 1e9 K by a bond, 10 µs later.
        let (radius, density, heat_capacity, emissivity) = (0.8e-3, 6652.7, 1796.3, 0.5);
        let area = 4.0 * std::f64::consts::PI * radius * radius;
        let mass = 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3) * density;
        let kr = 5.670374419e-8 * emissivity * area / (mass * heat_capacity);
        let law = cooling_law(0.0, kr, 0.0, 300.0);
        let (theta, dt) = (1e9, 1e-5);
        let exact = radiative_closed_form_with_far_field(theta, kr, 300.0, dt);
        let error = relative_error(law.advance(theta, dt), exact);
        assert!(error <= 1e-12, "{error:e}");
        // One backward Euler step is stable but lags: θ_new ≈ (θ_old/(k_r dt))^{1/4} ≈ 1.8e6 K
        // against the true 1.5e5 K.
        assert!(law.implicit_step(theta, dt) > 2.0 * exact);
    }

    #[test]
    fn wide_parameter_sweep_matches_quadrature() {
        // Convection from off to dominant, radiation from negligible to dominant, gas above,
        // below and without far field; every start from 1 K to 1e9 K; 18 decades of dt.
        // Measured: 3e-14 here, 1.3e-13 over 150 000 cases of a finer sweep.
        for kc in [0.0, 1e-6, 1e-2, 1.0, 1e3] {
            for kr in [1e-20, 7e-12, 1e-9] {
                for (gas, far) in [
                    (500.0, 300.0),
                    (300.0, 500.0),
                    (300.0, 0.0),
                    (0.0, 300.0),
                    (1.0, 300.0),
                ] {
                    let law = cooling_law(kc, kr, gas, far);
                    if kc * gas + kr * far.powi(4) == 0.0 {
                        continue;
                    }
                    let theta_eq = bisected_equilibrium(&law);
                    let starts = [
                        1.0,
                        100.0,
                        0.5 * theta_eq,
                        0.99 * theta_eq,
                        1.01 * theta_eq,
                        2.0 * theta_eq,
                        1e4,
                        1e9,
                    ];
                    for theta in starts {
                        for dt in log_range(-12, 6, 1) {
                            if let Some(error) = quadrature_error(&law, theta_eq, theta, dt) {
                                assert!(error <= 1e-12, "{law:?}, θ {theta}, dt {dt}: {error:e}");
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn degenerate_inputs_are_safe() {
        let law = both_terms();
        let theta_eq = law.equilibrium_temperature().unwrap();
        assert_eq!(law.advance(1e9, 0.0), 1e9);
        assert_eq!(cooling_law(0.0, 0.0, 500.0, 300.0).advance(1e9, 1e6), 1e9);
        assert_eq!(law.advance(theta_eq, 1e3), theta_eq);
        assert_eq!(law.advance(1e9, f64::INFINITY), theta_eq);
        assert_eq!(law.advance(1e9, 1e300), theta_eq);
        for theta in [0.0, 1e-300, 1.0, 1e12, 1e300] {
            for dt in [1e-300, 1e-12, 1.0, 1e12, 1e300] {
                let next = law.advance(theta, dt);
                assert!(
                    next.is_finite() && next >= 0.0,
                    "θ {theta}, dt {dt}: {next}"
                );
            }
        }
        // No heat source: θ_eq = 0 and u = θ⁻³ grows without bound.
        let sourceless = cooling_law(1e-2, 7e-12, 0.0, 0.0);
        assert_eq!(sourceless.advance(1e9, 1e6), 0.0);
        assert!(sourceless.advance(1e9, 1.0) > 0.0);
    }

    /// Radiation so weak that k_r² underflows (a heat capacity of 1e163 J/(kg·K) or an
    /// emissivity of 1e-160 on a 0.5 mm grain: k_r ≈ 5e-171 /(s K³)) squared the complex
    /// slope to 0 and made every temperature NaN at step 1 (issue 39). Over a Δt long
    /// enough to move θ, the exact step must match the explicit one: the change is
    /// Δθ ≈ k_r (θ⁴ − θs⁴) Δt ≈ 0.34 K here, and its curvature term is Δθ·(4Δθ/θ) ≈ 3e-3 of
    /// it, so 1 % separates the right step from a wrong one.
    #[test]
    fn radiation_too_weak_to_square_still_cools_exactly() {
        for (kc, kr) in [(0.0, 5.4e-171), (1e-200, 5.4e-171), (0.0, 1e-250)] {
            let law = cooling_law(kc, kr, 400.0, 300.0);
            let (theta, dt) = (500.0, 0.34 / (kr * (500f64.powi(4) - 300f64.powi(4))));
            let next = law.advance(theta, dt);
            let explicit = law.explicit_step(theta, dt);
            assert!(next.is_finite(), "k_r {kr:e}: {next}");
            let (change, expected) = (theta - next, theta - explicit);
            assert!(
                relative_error(change, expected) < 1e-2,
                "k_r {kr:e}: Δθ {change} against {expected}"
            );
            // And over an ordinary step, θ does not move at all (or by an ulp).
            assert!((law.advance(theta, 1e-4) - theta).abs() <= 1e-13 * theta);
        }
    }
}
