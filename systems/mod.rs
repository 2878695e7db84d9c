//! The built-in physics, one module per concern, each registered through the same
//! public [`SimPlugin`] API that extensions use (see `examples/`).
//!
//! Each plugin looks at the scenario and adds its systems only if the scene needs
//! them (MODEL.md §3, last line): no cooling system when ε = hc = 0 or cooling is
//! `off`, no fragmentation when γ is ∞, no diagnostics when switched off.
//! Only `src/schedule.rs` imports from here; the order lives there.

pub mod boundary;
pub mod contact;
pub mod cooling;
pub mod diagnostics;
pub mod drift;
pub mod fragment;
pub mod grid;
pub mod impact;
pub mod merge;
pub mod time_step;

use crate::scenario::CoolingMethod;
use crate::schedule::{SimBuilder, SimPlugin, StepSystems};

/// Contact detection (stage 1) and step-size selection (stage 5).
pub struct ContactPlugin;
impl SimPlugin for ContactPlugin {
    fn name(&self) -> &'static str {
        "contact"
    }
    fn build(&self, sim: &mut SimBuilder) {
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

/// Cooling (stage 6); not scheduled when off or when ε = hc = 0.
pub struct CoolingPlugin;
impl SimPlugin for CoolingPlugin {
    fn name(&self) -> &'static str {
        "cooling"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let s = sim.scenario();
        let cools = s.material.epsilon > 0.0 || s.material.hc > 0.0;
        if cools && s.physics.cooling != CoolingMethod::Off {
            sim.add_systems(StepSystems::Cooling, cooling::cool_bodies);
        }
    }
}

/// Drift (stage 7) and periodic wrapping (stage 8).
pub struct MotionPlugin;
impl SimPlugin for MotionPlugin {
    fn name(&self) -> &'static str {
        "motion"
    }
    fn build(&self, sim: &mut SimBuilder) {
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
        if d.invariants {
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
