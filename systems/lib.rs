//! # agglo-systems
//!
//! The built-in physics, one module per concern, each registered through the same
//! public [`SimPlugin`] API that extensions use (see `examples/`): this crate depends
//! on `agglo-engine` alone, so nothing a built-in does is out of an extension's reach.
//!
//! Each plugin looks at the scenario and adds its systems only if the scene needs
//! them (docs/model.md §3, last line): no cooling system when ε = hc = 0 or cooling is
//! `off`, no fragmentation when γ is ∞, no diagnostics when switched off. The plugin
//! that leaves a system out says why ([`SimBuilder::leave_out`]), so `agglo validate`,
//! the summary and the recording can show it. The stage order lives in the engine
//! ([`StepSystems`]); [`default_plugins`] lists the built-ins and [`DefaultPlugins`]
//! adds them to a simulation.

pub mod boundary;
pub mod contact;
pub mod cooling;
pub mod diagnostics;
pub mod drift;
pub mod events;
pub mod fragment;
pub mod impact;
pub mod merge;
pub mod time_step;

use bevy_ecs::prelude::*;

use agglo_engine::components::{Mass, Particle, ParticleId, Temperature, Velocity};
use agglo_engine::error::SimError;
use agglo_engine::scene::Material;
use agglo_engine::scene::{CoolingMethod, Core, Physics, TimeControl, event_core_needs};
use agglo_engine::schedule::{SimBuilder, SimPlugin, Simulation, StepSystems};
use agglo_engine::setup::Scene;

/// Contact detection (stage 1) and step-size selection (stage 5): the event core
/// when the scene allows it (docs/model.md §4), the stepped core otherwise.
pub struct ContactPlugin;
impl SimPlugin for ContactPlugin {
    fn name(&self) -> &'static str {
        "contact"
    }
    fn build(&self, sim: &mut SimBuilder) {
        let time = sim.resource::<TimeControl>().clone();
        let physics = *sim.resource::<Physics>();
        let why = core_reason(&time, &physics, sim.uses_event_core());
        sim.explain_core(why);
        if sim.uses_event_core() {
            let brute_force = time.core == Core::EventsBruteForce;
            // Built last, so that it sees every setting (a field set by an extension).
            sim.when_built(move |world| {
                let core = events::build_core(world, brute_force);
                world.insert_resource(core);
            })
            .add_systems(StepSystems::Contact, events::pop_due_contacts)
            .add_systems(StepSystems::TimeStep, events::schedule_next_step)
            .add_systems(StepSystems::Boundary, events::report_overlaps)
            .report_core_stats(|world| world.resource::<events::core::EventCore>().stats)
            .add_restart_part(events::resync::restart_part());
            return;
        }
        sim.init_resource::<contact::NeighbourTable>()
            .init_resource::<contact::ContactScratch>()
            .add_restart_part(contact::ContactScratch::restart_part())
            .add_systems(StepSystems::Contact, contact::detect_contacts)
            .add_systems(StepSystems::TimeStep, time_step::choose_time_step);
    }
}

/// Why the scene runs on the core it runs on, in the scenario's terms.
fn core_reason(time: &TimeControl, physics: &Physics, event_core: bool) -> String {
    match time.core {
        Core::Events => "time.core = \"events\"".into(),
        Core::EventsBruteForce => {
            "time.core = \"events_brute_force\" (the O(N²) reference predictor)".into()
        }
        Core::Stepped => "time.core = \"stepped\"".into(),
        Core::Auto if event_core => "time.core = \"auto\" and the scene allows it \
             (adaptive stepping with step_factor = 1, contact rule \"all\", cooling not \"explicit\" or \"explicit_clamped\")"
            .into(),
        // The obstacle in the words `validate` uses under `time.core` (one source for the
        // rule, engine/scene.rs, so the two cannot drift apart).
        Core::Auto => format!(
            "time.core = \"auto\", and {}",
            event_core_needs(time, physics)
                .unwrap_or_else(|| "the scene does not fit the event core".into())
        ),
    }
}

/// The impact / heat solve (stage 2).
pub struct ImpactPlugin;
impl SimPlugin for ImpactPlugin {
    fn name(&self) -> &'static str {
        "impact"
    }
    fn build(&self, sim: &mut SimBuilder) {
        // The scene's `impact` section, or the defaults when it gives none.
        sim.init_resource::<impact::ImpactModel>()
            .init_resource::<impact::SolvedImpacts>()
            .add_systems(StepSystems::Impact, impact::resolve_impacts)
            .set_impact_outcome_applier(impact::add_outcome_applier);
        let settings = *sim.resource::<impact::ImpactModel>();
        if settings.restitution.is_some() {
            // The TC model against inelastic collapse (docs/model.md §5.4).
            let t_c = settings.collapse_time.unwrap_or_else(|| {
                let b0 = sim.resource::<agglo_engine::cloud::PrimaryGrain>().radius;
                let world = sim.world_mut();
                let mut query = world.query_filtered::<(&ParticleId, &Velocity), With<Particle>>();
                let mut bodies: Vec<_> = query.iter(world).map(|(id, v)| (id.0, v.0)).collect();
                bodies.sort_by_key(|b| b.0); // sums in id order, not entity order
                let velocities: Vec<_> = bodies.into_iter().map(|b| b.1).collect();
                impact::default_collapse_time(b0, &velocities)
            });
            if t_c > 0.0 {
                sim.insert_resource(impact::CollapseGuard::new(t_c))
                    .add_restart_part(impact::CollapseGuard::restart_part());
            }
        }
    }
}

/// Merging of bonded pairs (stage 3).
pub struct MergePlugin;
impl SimPlugin for MergePlugin {
    fn name(&self) -> &'static str {
        "merge"
    }
    fn build(&self, sim: &mut SimBuilder) {
        if sim.resource::<Physics>().merging {
            sim.add_systems(StepSystems::Merge, merge::merge_bonded);
        } else {
            sim.leave_out("merging off: physics.merging = false");
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
        match fragmentation_off(sim.resource::<Material>(), sim.resource::<Physics>()) {
            Some(why) => sim.leave_out(format!("fragmentation off: {why}")),
            None => sim.add_systems(StepSystems::Fragment, fragment::fragment_bodies),
        };
    }
}

/// Why the scene has no fragmentation, if it has none.
fn fragmentation_off(material: &Material, physics: &Physics) -> Option<&'static str> {
    if material.surface_energy() == f64::INFINITY {
        Some("γ = ∞ (material.gamma = null)")
    } else if !physics.fragmentation {
        Some("physics.fragmentation = false")
    } else {
        None
    }
}

/// Cooling (stage 6); not scheduled when off or when ε = hc = 0, nor on the event core,
/// which cools each body over the whole interval when it is read (`engine/bodies.rs`).
pub struct CoolingPlugin;
impl SimPlugin for CoolingPlugin {
    fn name(&self) -> &'static str {
        "cooling"
    }
    fn build(&self, sim: &mut SimBuilder) {
        match no_cooling_system(sim) {
            Some(why) => sim.leave_out(why),
            None => sim.add_systems(StepSystems::Cooling, cooling::cool_bodies),
        };
    }
}

/// Why the scene schedules no cooling system, if it schedules none.
fn no_cooling_system(sim: &SimBuilder) -> Option<&'static str> {
    let material = sim.resource::<Material>();
    if sim.resource::<Physics>().cooling == CoolingMethod::Off {
        Some("cooling off: physics.cooling = \"off\"")
    } else if material.epsilon == 0.0 && material.hc == 0.0 {
        Some("cooling off: ε = hc = 0 (material.epsilon, material.hc)")
    } else if sim.uses_event_core() {
        Some(
            "cooling: done lazily by the event core (each body cooled exactly over its interval when read)",
        )
    } else {
        None
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
        if sim.uses_event_core() {
            sim.leave_out(
                "drift, boundary: done lazily by the event core (each body moved and wrapped when read)",
            );
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
        // The scene's `diagnostics` section, or the defaults when it gives none.
        let d = sim
            .world_mut()
            .get_resource_or_init::<diagnostics::Diagnostics>()
            .clone();
        if d.invariants && sim.uses_event_core() {
            let start = initial_totals(sim.world_mut());
            let full_every = d.every.max(sim.info().initial_bodies as u64);
            sim.insert_resource(diagnostics::RunningTotals::new(&start, full_every))
                .add_systems(StepSystems::Diagnostics, diagnostics::check_step_totals)
                .add_restart_part(agglo_engine::restart::RestartPart {
                    name: "running_totals",
                    save: |_| Vec::new(),
                    load: |world, _| diagnostics::RunningTotals::recompute(world),
                });
        } else if d.invariants {
            sim.add_systems(StepSystems::Diagnostics, diagnostics::check_invariants);
        } else {
            sim.leave_out("diagnostics off: diagnostics.invariants = false");
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

/// The built-in physics for a simulation: `Simulation::new(&scenario)` and
/// `builder.add_default_plugins()` (bring the trait into scope, e.g. with
/// `agglo::prelude::*`).
pub trait DefaultPlugins {
    /// The scenario with the built-in physics ([`default_plugins`]).
    fn new(scene: &dyn Scene) -> Result<Self, SimError>
    where
        Self: Sized;
}

impl DefaultPlugins for Simulation {
    fn new(scene: &dyn Scene) -> Result<Self, SimError> {
        let mut builder = Simulation::builder(scene)?;
        builder.add_plugins(default_plugins());
        builder.build()
    }
}

/// [`SimBuilder::add_default_plugins`]: the built-ins, in pipeline order.
pub trait AddDefaultPlugins {
    /// Add the built-in physics (each plugin schedules only what the scene needs).
    fn add_default_plugins(&mut self) -> &mut Self;
}

impl AddDefaultPlugins for SimBuilder {
    fn add_default_plugins(&mut self) -> &mut Self {
        self.add_plugins(default_plugins())
    }
}

/// Totals over the bodies now in the world.
pub(crate) fn initial_totals(world: &mut World) -> diagnostics::Totals {
    let c = world.resource::<Material>().C;
    let rows: Vec<_> = world
        .query_filtered::<(&Mass, &Velocity, &Temperature), With<Particle>>()
        .iter(world)
        .map(|(m, v, t)| (m.0, v.0, t.0))
        .collect();
    diagnostics::totals(rows.into_iter(), c)
}
