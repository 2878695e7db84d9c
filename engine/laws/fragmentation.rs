//! Fragmentation's energy balance (docs/model.md §7, P04 (5.2)): how many equal pieces the
//! absorbed energy breaks a sphere into, and the surface energy that costs. Shared by the
//! coalesce fragmentation (systems/fragment.rs) and the rigid one, which applies it to the
//! sphere of an aggregate's volume (systems/fragment_rigid.rs).

/// Number of equal pieces k = ⌊(1 + x)³⌋, x = δK / (4π γ b0²) (P04 (5.2)).
pub fn piece_count(absorbed: f64, radius: f64, gamma: f64) -> u64 {
    if !(gamma.is_finite() && absorbed > 0.0) {
        return 1;
    }
    let x = absorbed / (4.0 * std::f64::consts::PI * gamma * radius * radius);
    let k = (1.0 + x).powi(3).floor();
    if k >= u64::MAX as f64 {
        u64::MAX
    } else {
        k as u64
    }
}

/// Surface energy δZ = γ 4π b0² (p^{1/3} − 1) of splitting a sphere of radius b0 into p [J].
pub fn surface_energy(gamma: f64, radius: f64, pieces: u64) -> f64 {
    gamma * 4.0 * std::f64::consts::PI * radius * radius * ((pieces as f64).cbrt() - 1.0)
}
