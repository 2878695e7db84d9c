//! When two spheres in ballistic flight touch (docs/model.md §4): the exact time to
//! contact that both cores use, the stepped core to choose Δt and the event core to
//! predict its calendar.

use glam::DVec3;

/// Smallest t ≥ 0 with |d + u t| = s, for separation d = r_j − r_i, relative velocity
/// u = v_j − v_i and contact distance s = b_i + b_j; `None` if the pair never touches.
/// Uses the cancellation-free root c / (−b + √(b² − a c)).
pub fn time_to_contact(d: DVec3, u: DVec3, s: f64) -> Option<f64> {
    let b = d.dot(u);
    if b >= 0.0 {
        return None; // not approaching
    }
    let c = d.length_squared() - s * s;
    if c <= 0.0 {
        return Some(0.0); // already touching
    }
    let a = u.length_squared();
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None; // passes by
    }
    Some(c / (-b + disc.sqrt()))
}
