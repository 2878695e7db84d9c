//! Stage 5 — the next time-step size (docs/model.md §4, P04 (6.14) made exact).
//!
//! Runs after impacts, merging and fragmentation so that t_c is computed from the
//! post-impact velocities and the current bodies: that is what makes "no collision
//! missed for c ≤ 1" hold (docs/model.md §3, item 5: computing it with contact detection
//! would use pre-impact velocities). When nothing changed this
//! step, contact detection's neighbour table is reused; after bounces only, its
//! positions and velocities are refreshed; after merging or fragmentation it is rebuilt.
//!
//! Adaptive: Δt = clamp(c·t_c, Δt_min, min(Δt_max, skin / (2 v_max))), t_c the exact
//! ballistic time to the next contact among neighbour pairs (0 for a touching,
//! approaching pair deferred to the next step), v_max the largest speed relative to
//! the mass-weighted mean velocity. Fixed: Δt as given. Both end exactly on T.
//!
//! Reads: [`NeighbourTable`], the scene's `time` section, [`StateChanged`]. Writes: [`SimClock`]
//! (dt, clamped flag), [`Counters`] (clamped steps).

use bevy_ecs::prelude::*;
use glam::DVec3;

use super::contact::{BodyQuery, NeighbourTable, search_margin};
pub use agglo_engine::laws::contact_time::time_to_contact;
use agglo_engine::params::SceneConstants;
use agglo_engine::resources::{Counters, ForceKicks, SimClock, StateChanged};
use agglo_engine::scene::Stepping;

/// Stage 5 as a system: choose the next Δt [s] from the time to the next contact and
/// the stepping rule (docs/model.md §4).
pub fn choose_time_step(
    bodies: BodyQuery,
    scene: SceneConstants,
    changed: Res<StateChanged>,
    mut table: ResMut<NeighbourTable>,
    mut clock: ResMut<SimClock>,
    mut counters: ResMut<Counters>,
    kicks: Res<ForceKicks>,
) {
    let SceneConstants {
        geometry,
        time,
        primary,
        ..
    } = scene;
    let remaining = (time.end - clock.time).max(0.0);
    clock.clamped_at_min = false;
    let dt = match time.stepping {
        Stepping::Fixed { dt } => dt,
        Stepping::Adaptive {
            step_factor,
            dt_min,
            dt_max,
            ..
        } => {
            let skin = time.stepping.search_skin(primary.radius);
            if clock.bodies_reshaped {
                let max_radius = bodies.iter().map(|b| b.radius.0).fold(0.0, f64::max);
                table.rebuild(
                    &bodies,
                    &geometry,
                    search_margin(&time.stepping, primary.radius, max_radius),
                );
            } else if changed.0 {
                table.refresh(&bodies, &geometry);
            }
            let t_c = next_contact_time(&table);
            let v_max = max_relative_speed(&table);
            // The pair list is complete for gaps up to margin − 2·(displacement so far):
            // no unlisted pair may close that much in this step.
            let usable = (table.margin.min(skin) - 2.0 * table.max_displacement).max(0.0);
            let upper = if v_max > 0.0 {
                dt_max.min(usable / (2.0 * v_max))
            } else {
                dt_max
            };
            let wanted = step_factor * t_c;
            if wanted < dt_min && dt_min <= upper {
                clock.clamped_at_min = true;
                counters.clamped_steps += 1;
            }
            // Not `f64::clamp`: the skin bound wins if it is below Δt_min.
            wanted.max(dt_min).min(upper)
        }
    };
    // Land on the next kick of forces that declared an interval.
    let to_kick = kicks
        .next()
        .map_or(f64::INFINITY, |t| (t - clock.time).max(0.0));
    clock.dt = dt.min(remaining).min(to_kick);
}

/// Smallest exact time to contact over approaching neighbour pairs [s] (∞ if none).
pub fn next_contact_time(table: &NeighbourTable) -> f64 {
    let mut t_c = f64::INFINITY;
    for p in &table.pairs {
        let (i, j) = (p.i as usize, p.j as usize);
        let u = table.velocities[j] - table.velocities[i];
        if let Some(t) = time_to_contact(p.d, u, table.radii[i] + table.radii[j]) {
            t_c = t_c.min(t);
        }
    }
    t_c
}

/// Largest |v − v̄| with v̄ the mass-weighted mean velocity [m/s].
pub fn max_relative_speed(table: &NeighbourTable) -> f64 {
    let mut momentum = DVec3::ZERO;
    let mut mass = 0.0;
    for (m, v) in table.masses.iter().zip(&table.velocities) {
        momentum += *m * *v;
        mass += m;
    }
    if mass <= 0.0 {
        return 0.0;
    }
    let mean = momentum / mass;
    table
        .velocities
        .iter()
        .map(|v| (*v - mean).length())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn head_on_time_to_contact_is_gap_over_closing_speed() {
        let t = time_to_contact(DVec3::new(3.0, 0.0, 0.0), DVec3::new(-2.0, 0.0, 0.0), 1.0);
        assert!((t.unwrap() - 1.0).abs() < 1e-15);
        assert_eq!(time_to_contact(DVec3::X * 3.0, DVec3::X, 1.0), None);
        assert_eq!(
            time_to_contact(DVec3::X * 3.0, DVec3::new(-1.0, 5.0, 0.0), 1.0),
            None
        );
    }
}
