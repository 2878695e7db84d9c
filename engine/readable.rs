//! Numbers as a person reads them in messages and reports: times such as `9e-3` rather
//! than `9.000000000000001e-3` (a checkpoint time summed from steps, a `--set` value
//! scaled by a unit). Outputs meant for programs (CSV, JSON, MCAP) keep every bit.

/// Significant digits kept: a time given in a scenario (`1e-3`, `2.5e-4`) or reached by
/// a run prints as written, and two times a person compares differ in the first six
/// digits unless they are the same time for every purpose of a message.
const DIGITS: usize = 6;

/// `x` in scientific notation with at most [`DIGITS`] significant digits and no trailing
/// zeros: `9e-3`, `1.25e-4`, `0e0`; non-finite values as Rust prints them (`NaN`, `inf`).
pub fn sci(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    let text = format!("{x:.prec$e}", prec = DIGITS - 1);
    let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    format!("{mantissa}e{exponent}")
}

/// `x` to every digit (shortest round-trip), in the shorter of the two notations a
/// person reads: plain between 1e-3 and 1e6 (`0.25`, `300`), scientific outside (`1e-300`,
/// `2e154`). For the value a message says it was given: Rust's `{}` prints 1e-300 as
/// 302 characters of zeros.
pub fn exact(x: f64) -> String {
    let magnitude = x.abs();
    if !x.is_finite() || x == 0.0 || (1e-3..1e6).contains(&magnitude) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::{exact, sci};

    #[test]
    fn given_values_print_to_every_digit_and_briefly() {
        assert_eq!(exact(1e-300), "1e-300");
        assert_eq!(exact(2e154), "2e154");
        assert_eq!(exact(0.25), "0.25");
        assert_eq!(exact(-300.0), "-300");
        assert_eq!(exact(7.904000000000001e-4), "7.904000000000001e-4");
        assert_eq!(exact(0.0), "0");
        assert_eq!(exact(f64::NAN), "NaN");
    }

    #[test]
    fn times_print_as_a_person_wrote_them() {
        assert_eq!(sci(9.000000000000001e-3), "9e-3");
        assert_eq!(sci(0.009), "9e-3");
        assert_eq!(sci(3.0 * 0.1), "3e-1");
        assert_eq!(sci(1.25e-4), "1.25e-4");
        assert_eq!(sci(7.45e-4), "7.45e-4");
        assert_eq!(sci(-2.5), "-2.5e0");
        assert_eq!(sci(0.0), "0e0");
        assert_eq!(sci(123456789.0), "1.23457e8");
        assert_eq!(sci(f64::NAN), "NaN");
    }
}
