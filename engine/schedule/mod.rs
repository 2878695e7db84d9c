//! The step pipeline, the plugin API and the [`Simulation`] that runs a scenario, one
//! concern a file:
//!
//! - here, the stages: [`StepSystems`], chained once in the order of docs/model.md §3
//!   (with the step-size choice moved after the events it depends on — see
//!   `systems/time_step.rs`), the two schedules and the systems the engine itself runs
//!   (the force kicks, the clock);
//! - [`builder`]: the plugin API, [`SimPlugin`] and the [`SimBuilder`] it is given;
//! - [`access`]: the build-time checks on what an extension's systems read and write;
//! - [`simulation`]: the built [`Simulation`] that steps the world.
//!
//! Physics is added by [`SimPlugin`]s — the built-ins in `systems/` and any extension
//! alike — which put systems into these sets. `First`/`Last` are empty slots for
//! extensions. The schedule runs single-threaded and treats ambiguous system order as
//! an error, so a missing ordering constraint fails loudly instead of making runs differ.

mod access;
pub mod builder;
pub mod simulation;

pub use builder::{SimBuilder, SimPlugin};
pub use simulation::Simulation;

use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use serde::{Deserialize, Serialize};

use crate::resources::*;
use crate::scene::TimeControl;

/// The schedule that advances the world by one step.
#[derive(ScheduleLabel, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SimStep;

/// The schedule of force systems, run at the start of each step and at the end of a run.
#[derive(ScheduleLabel, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ForceStep;

/// Runs the force systems (stage `Forces`): every step, or when a declared interval has
/// passed since the last kick ([`ForceKicks`]).
fn run_forces(world: &mut World) {
    kick(world, false);
}

/// One kick of the force systems over the interval since the last one: `SimClock::dt`
/// is that interval while they run (what `Bodies::dt` reports), restored after. With a
/// declared interval the kick waits until it has passed (or the run ends, `at_end`).
fn kick(world: &mut World, at_end: bool) {
    let clock = *world.resource::<SimClock>();
    let kicks = *world.resource::<ForceKicks>();
    let Some(interval) = kicks.interval else {
        world.run_schedule(ForceStep);
        world.resource_mut::<ForceKicks>().kicks += 1;
        return;
    };
    let elapsed = clock.time - kicks.last;
    // Due at last + h (steps land there; allow rounding of the sum of step lengths).
    let due = elapsed >= interval * (1.0 - 1e-9);
    if !(due || at_end) || elapsed <= 0.0 {
        return;
    }
    world.resource_mut::<SimClock>().dt = elapsed;
    world.run_schedule(ForceStep);
    world.resource_mut::<SimClock>().dt = clock.dt;
    let mut k = world.resource_mut::<ForceKicks>();
    k.last = clock.time;
    k.kicks += 1;
}

/// The stages of one step L → L+1, chained in this order.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StepSystems {
    /// 0. Empty slot for extensions, before anything else.
    First,
    /// 0b. External forces over the interval just completed (extensions; see
    /// [`SimBuilder::add_force_systems`]).
    Forces,
    /// 1. Contact detection: periodic cell grid, contacts of this step (docs/model.md §4).
    Contact,
    /// 2. Impact / heat solve for every contact (docs/model.md §5).
    Impact,
    /// 2b. Outcome hooks: extensions may change the step's impact outcomes before they
    /// are applied (empty unless one does: [`SimBuilder::add_impact_outcome_systems`]).
    ImpactOutcome,
    /// 3. Merging of bonded pairs (docs/model.md §6).
    Merge,
    /// 4. Fragmentation of bodies that absorbed enough energy (docs/model.md §7).
    Fragment,
    /// 5. The next step size from post-impact velocities (docs/model.md §4).
    TimeStep,
    /// 6. Cooling by convection and radiation (docs/model.md §8).
    Cooling,
    /// 7. Drift r ← r + Δt v.
    Drift,
    /// 8. Periodic wrapping (docs/model.md §9).
    Boundary,
    /// 9. Invariant checks (docs/model.md §10).
    Diagnostics,
    /// 10. Empty slot for extensions (recording, statistics), after the step.
    Last,
}

impl StepSystems {
    /// Every stage, in pipeline order.
    pub const ORDER: [StepSystems; 13] = [
        StepSystems::First,
        StepSystems::Forces,
        StepSystems::Contact,
        StepSystems::Impact,
        StepSystems::ImpactOutcome,
        StepSystems::Merge,
        StepSystems::Fragment,
        StepSystems::TimeStep,
        StepSystems::Cooling,
        StepSystems::Drift,
        StepSystems::Boundary,
        StepSystems::Diagnostics,
        StepSystems::Last,
    ];
}

/// What a scene runs: its core, its systems in order, and why each system the scene
/// could have run was left out (docs/model.md §3: a scene runs only what it needs).
/// `agglo validate` prints it; the summary and the recording's metadata carry it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Pipeline {
    /// `event` or `stepped` (docs/model.md §4).
    pub core: String,
    /// Why that core, in the scenario's terms (said by the plugin that builds it).
    pub core_reason: String,
    /// The systems in execution order, as [`Simulation::systems`] lists them.
    pub systems: Vec<String>,
    /// One line per system left out: which and why, said by the plugin that decided,
    /// e.g. `fragmentation off: γ = ∞ (material.gamma = null)`.
    pub left_out: Vec<String>,
    /// The fields and forces bodies feel between events, each with the path it takes
    /// on the core (docs/model.md §4.7); empty without any.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub forces: Vec<String>,
}

/// Who a run is: what its summary and recording are labelled with.
#[derive(Debug, Clone, PartialEq)]
pub struct RunInfo {
    /// The scene's name.
    pub name: String,
    /// The seed of its random generator.
    pub seed: u64,
    /// Bodies at t = 0.
    pub initial_bodies: usize,
}

/// `agglo::systems::drift::drift` → `drift::drift`.
fn short_name(full: &str) -> String {
    let parts: Vec<&str> = full.rsplit("::").take(2).collect();
    parts.into_iter().rev().collect::<Vec<_>>().join("::")
}

/// Swaps one subscribed message type's buffers (engine/hooks.rs).
type Rotate = fn(&mut World);

/// Closes the step: t ← t + Δt (exactly T on the last step), L ← L + 1.
fn advance_clock(
    mut clock: ResMut<SimClock>,
    time: Res<TimeControl>,
    mut events: ResMut<StepEvents>,
) {
    events.clear();
    let next = clock.time + clock.dt;
    // Land exactly on T when the step was cut to the remaining time.
    clock.time = if time.end - next <= 1e-12 * time.end {
        time.end.max(next)
    } else {
        next
    };
    clock.step += 1;
}
