//! The plugin that chooses the scene's core and builds its contact detection (stage 1)
//! and step-size selection (stage 5): the event core ([`crate::events`]) when the scene
//! allows it, else the stepped core's neighbour-list detection ([`crate::contact`]) and
//! step choice ([`crate::time_step`]). A file of its own because it schedules all three.

use agglo_engine::core_only::SimBuilderCore;
use agglo_engine::scene::{Core, Physics, TimeControl, event_core_needs};
use agglo_engine::schedule::{SimBuilder, SimPlugin, StepSystems};

use crate::contact::{ContactScratch, NeighbourTable, detect_contacts};

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
                let core = crate::events::build_core(world, brute_force);
                world.insert_resource(core);
            })
            .add_core_systems(StepSystems::Contact, crate::events::pop_due_contacts)
            .add_core_systems(StepSystems::TimeStep, crate::events::schedule_next_step)
            .add_core_systems(StepSystems::Boundary, crate::events::report_overlaps)
            .report_core_stats(|world| world.resource::<crate::events::core::EventCore>().stats)
            .add_restart_part(crate::events::resync::restart_part());
            return;
        }
        sim.init_resource::<NeighbourTable>()
            .init_resource::<ContactScratch>()
            .add_restart_part(ContactScratch::restart_part())
            .add_core_systems(StepSystems::Contact, detect_contacts)
            .add_core_systems(StepSystems::TimeStep, crate::time_step::choose_time_step);
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
