//! Thermal softening (docs/model.md §1): the Arrhenius hardness H = H0 · exp(Q / (R θ))
//! with its overflow rule.

/// Universal gas constant R [J/(mol K)].
pub const GAS_CONSTANT: f64 = 8.314462618;
/// Exponents Q/(Rθ) above this give H = +∞ (exp(709) overflows f64).
pub const HARDNESS_EXPONENT_LIMIT: f64 = 700.0;

/// H0 · exp(Q / (R θ)) with the overflow rule of docs/model.md §1.
pub fn hardness(h0: f64, q: f64, theta: f64) -> f64 {
    if q == 0.0 {
        return h0;
    }
    let exponent = q / (GAS_CONSTANT * theta);
    if exponent > HARDNESS_EXPONENT_LIMIT || exponent.is_nan() {
        f64::INFINITY
    } else {
        h0 * exponent.exp()
    }
}
