//! The subgrid's random stream: splitmix64 over a counter (as the kernel's samples),
//! with the uniform, normal and Poisson draws that lifting, adjusting and the structure
//! sweeps take. A module of its own so that those three share it without importing
//! each other.

use std::f64::consts::PI;

use crate::inverse::ensemble::splitmix64;

/// A generator of its own: splitmix64 over a counter (as the kernel's samples).
#[doc(hidden)]
pub struct Stream(pub u64);

impl Stream {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        splitmix64(self.0)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// Standard normal (Box–Muller, one value per two uniforms).
    pub(crate) fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
    /// Poisson with mean `lambda` ≥ 0: inversion below 10, Hörmann's transformed
    /// rejection (PTRS, 1993; as NumPy) above, exact in both.
    pub(crate) fn poisson(&mut self, lambda: f64) -> u64 {
        if lambda <= 0.0 {
            return 0;
        }
        if lambda < 10.0 {
            let u = self.uniform();
            let (mut k, mut p) = (0u64, (-lambda).exp());
            let mut cdf = p;
            // The tail past 200 terms is below 1e-100 for λ < 10.
            while u >= cdf && k < 200 {
                k += 1;
                p *= lambda / k as f64;
                cdf += p;
            }
            return k;
        }
        let slam = lambda.sqrt();
        let loglam = lambda.ln();
        let b = 0.931 + 2.53 * slam;
        let a = -0.059 + 0.02483 * b;
        let inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
        let vr = 0.9277 - 3.6224 / (b - 2.0);
        loop {
            let u = self.uniform() - 0.5;
            let v = self.uniform();
            let us = 0.5 - u.abs();
            let k = ((2.0 * a / us + b) * u + lambda + 0.43).floor();
            if us >= 0.07 && v <= vr {
                return k as u64;
            }
            if k < 0.0 || (us < 0.013 && v > us) {
                continue;
            }
            let lhs = v.ln() + inv_alpha.ln() - (a / (us * us) + b).ln();
            if lhs <= -lambda + k * loglam - ln_factorial(k) {
                return k as u64;
            }
        }
    }
}

/// ln k! for a whole k ≥ 0: summed below 16, Stirling's series above (error < 1e-13).
fn ln_factorial(k: f64) -> f64 {
    if k < 16.0 {
        return (2..=k as u64).map(|i| (i as f64).ln()).sum();
    }
    let x = k + 1.0;
    let x2 = x * x;
    (x - 0.5) * x.ln() - x + 0.5 * (2.0 * PI).ln() + 1.0 / (12.0 * x) - 1.0 / (360.0 * x * x2)
        + 1.0 / (1260.0 * x * x2 * x2)
}
