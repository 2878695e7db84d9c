//! The built-in physics, one module per concern, each registered through the same
//! public [`SimPlugin`] API that extensions use (see `examples/`).
//!
//! Each plugin looks at the scenario and adds its systems only if the scene needs
//! them (docs/model.md §3, last line): no cooling system when ε = hc = 0 or cooling is
//! `off`, no fragmentation when γ is ∞, no diagnostics when switched off.
//! Only `src/schedule.rs` imports from here; the order lives there.

pub mod bodies;
pub mod boundary;
pub mod contact;
pub mod cooling;
pub mod cooling_law;
pub mod diagnostics;
pub mod drift;
pub mod events;
pub mod fragment;
pub mod grid;
pub mod impact;
pub mod merge;
pub mod time_step;

use bevy_ecs::prelude::*;

use crate::components::{Mass, Particle, Temperature, Velocity};
use crate::resources::MaterialConstants;
use crate::scenario::{CoolingMethod, Core};
use crate::schedule::{SimBuilder, SimPlugin, StepSystems};

/// Contact detection (stage 1) and step-size selection (stage 5): the event core
/// when the scene allows it (docs/model.md §4), the stepped core otherwise.
pub struct ContactPlugin;
impl SimPlugin for ContactPlugin {
    fn name(&self) -> &'static str {
        "contact"
    }
    fn build(&self, sim: &mut SimBuilder) {
        if sim.scenario().uses_event_core() {
            let brute_force = sim.scenario().time.core == Core::EventsBruteForce;
            let core = events::build_core(sim.world_mut(), brute_force);
            sim.insert_resource(core)
                .add_systems(StepSystems::Contact, events::pop_due_contacts)
                .add_systems(StepSystems::TimeStep, events::schedule_next_step)
                .add_systems(StepSystems::Boundary, events::report_overlaps);
            return;
        }
        sim.init_resource::<contact::NeighbourTable>()
            .init_resource::<contact::ContactScratch>()
            .add_systems(StepSystems::Contact, contact::detect_contacts)
            .add_systems(StepSystems::TimeStep, time_step::choose_time_step);
    }
}

/// The impact / heat solve (stage 2).
pub struct ImpactPlugin;
impl SimPlugin for ImpactPlugin {
    fn name(&self) -> &'static str {
        "impact"
    }
    fn build(&self, sim: &mut SimBuilder) {
        sim.add_systems(StepSystems::Impact, impact::resolve_impacts);
    }
}

/// Merging of bonded pairs (stage 3).
pub struct MergePlugin;
impl SimPlugin for MergePlugin {
    fn name(&self) -> &'static str {
        "merge"
    }
    fn build(&self, sim: &mut SimBuilder) {
        if sim.scenario().physics.merging {
            sim.add_systems(StepSystems::Merge, merge::merge_bonded);
        }
    }
}

/// Fragmentation (stage 4); not scheduled when γ = ∞.
pub struct FragmentPlugin;
impl SimPlugin for FragmentPlugin {
    fn name(&self) -> &'static str {
        "fragment"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let s = sim.scenario();
        if s.physics.fragmentation && s.material.gamma.is_some() {
            sim.add_systems(StepSystems::Fragment, fragment::fragment_bodies);
        }
    }
}

/// Cooling (stage 6); not scheduled when off or when ε = hc = 0, nor on the event core,
/// which cools each body over the whole interval when it is read (`bodies.rs`).
pub struct CoolingPlugin;
impl SimPlugin for CoolingPlugin {
    fn name(&self) -> &'static str {
        "cooling"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let s = sim.scenario();
        let cools = s.material.epsilon > 0.0 || s.material.hc > 0.0;
        if cools && s.physics.cooling != CoolingMethod::Off && !s.uses_event_core() {
            sim.add_systems(StepSystems::Cooling, cooling::cool_bodies);
        }
    }
}

/// Drift (stage 7) and periodic wrapping (stage 8); on the event core both happen when
/// a body is read, so nothing is scheduled.
pub struct MotionPlugin;
impl SimPlugin for MotionPlugin {
    fn name(&self) -> &'static str {
        "motion"
    }
    fn build(&self, sim: &mut SimBuilder) {
        if sim.scenario().uses_event_core() {
            return;
        }
        sim.add_systems(StepSystems::Drift, drift::drift)
            .add_systems(StepSystems::Boundary, boundary::wrap_positions);
    }
}

/// Invariant checks (stage 9), when `diagnostics.invariants` is on.
pub struct DiagnosticsPlugin;
impl SimPlugin for DiagnosticsPlugin {
    fn name(&self) -> &'static str {
        "diagnostics"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let d = sim.scenario().diagnostics.clone();
        sim.insert_resource(diagnostics::DiagnosticsSettings {
            every: d.every,
            tolerance: d.tolerance,
        });
        if d.invariants && sim.scenario().uses_event_core() {
            let start = initial_totals(sim.world_mut());
            let full_every = d.every.max(sim.scenario().cloud.count as u64);
            sim.insert_resource(diagnostics::RunningTotals::new(&start, full_every))
                .add_systems(StepSystems::Diagnostics, diagnostics::check_step_totals);
        } else if d.invariants {
            sim.add_systems(StepSystems::Diagnostics, diagnostics::check_invariants);
        }
    }
}

/// The built-in physics in pipeline order. A scene that needs less gets fewer systems:
/// each plugin decides from the scenario.
pub fn default_plugins() -> Vec<Box<dyn SimPlugin>> {
    vec![
        Box::new(ContactPlugin),
        Box::new(ImpactPlugin),
        Box::new(MergePlugin),
        Box::new(FragmentPlugin),
        Box::new(CoolingPlugin),
        Box::new(MotionPlugin),
        Box::new(DiagnosticsPlugin),
    ]
}

/// Totals over the bodies now in the world.
fn initial_totals(world: &mut World) -> diagnostics::Totals {
    let c = world.resource::<MaterialConstants>().heat_capacity;
    let rows: Vec<_> = world
        .query_filtered::<(&Mass, &Velocity, &Temperature), With<Particle>>()
        .iter(world)
        .map(|(m, v, t)| (m.0, v.0, t.0))
        .collect();
    diagnostics::totals(rows.into_iter(), c)
}
