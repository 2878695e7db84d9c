//! The plugin API: [`SimPlugin`], a unit of physics, and the [`SimBuilder`] it adds
//! its resources and systems to; [`SimBuilder::build`] checks the pipeline (access
//! rules in [`super::access`]) and hands back the [`Simulation`].

use bevy_ecs::message::{Message, Messages};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{LogLevel, ScheduleBuildSettings, SingleThreadedExecutor};
use bevy_ecs::system::ScheduleSystem;

use crate::bodies::BodiesGate;
use crate::cloud::PrimaryGrain;
use crate::cloud::generate_cloud;
use crate::components::{BodyState, Particle, StoredBody};
use crate::error::SimError;
use crate::field::Field;
use crate::resources::*;
use crate::scene::{Physics, uses_event_core};
use crate::setup::Scene;
use crate::totals::totals;

use super::access::{ExtensionSystems, refuse_unsafe_access};
use super::simulation::Simulation;
use super::{
    ForceStep, Pipeline, Rotate, RunInfo, SimStep, StepSystems, advance_clock, run_forces,
    short_name,
};

/// Entity indices kept below the bodies' for resources (a default scene holds 27, the
/// engine's and the plugins'; more would still work, costing 4 bytes per body each).
const RESOURCE_INDICES: usize = 256;

/// A unit of physics: adds resources and systems to a simulation being built.
/// Built-in physics uses this too; see `examples/` for one written outside the crate.
pub trait SimPlugin {
    /// Short name, listed by [`Simulation::plugins`].
    fn name(&self) -> &'static str;
    /// Add resources and systems. Read [`SimBuilder::scenario`] to add only what the scene needs.
    fn build(&self, sim: &mut SimBuilder);
}

/// Work a plugin leaves for [`SimBuilder::build`].
pub(crate) type Finisher = Box<dyn FnOnce(&mut World)>;

impl Simulation {
    /// Start building with custom plugins. The built-in physics is one call away
    /// (`SimBuilder::add_default_plugins`, from `agglo_systems::AddDefaultPlugins`);
    /// `agglo_systems::NewBuiltinSimulation::new` builds a scene with it alone, and
    /// `agglo::prelude`'s `Simulation::new` with it and the registered extensions.
    pub fn builder(scene: &dyn Scene) -> Result<SimBuilder, SimError> {
        SimBuilder::new(scene)
    }
}

/// A world and schedule under construction: the calls every plugin may make (its own
/// resources, systems in any stage, forces, fields, hooks, carried quantities, restart
/// parts). What only a core plugin needs is in [`crate::core_only::SimBuilderCore`];
/// docs/extending.md, "The plugin API", lists both.
pub struct SimBuilder {
    pub(crate) world: World,
    pub(crate) schedule: Schedule,
    forces: Option<Schedule>,
    runs_forces: bool,
    info: RunInfo,
    plugins: Vec<&'static str>,
    pub(crate) core_reason: String,
    left_out: Vec<String>,
    pub(crate) core_stats: Option<fn(&World) -> EventStats>,
    /// Work left for [`SimBuilder::build`], once every plugin has had its say.
    pub(crate) finishers: Vec<Finisher>,
    /// Subscribed message types and the function that rotates each one's buffers.
    subscriptions: Vec<(std::any::TypeId, Rotate)>,
    /// True once an extension added impact-outcome systems.
    outcome_hooks: bool,
    /// Adds the system that applies pending impact outcomes (the impact plugin's).
    pub(crate) outcome_applier: Option<fn(&mut Schedule)>,
    /// Why [`SimBuilder::build`] must fail: a plugin replaced the run's books.
    refused: Vec<String>,
}

impl SimBuilder {
    /// A world holding the scene's cloud and resources, with an empty pipeline: every
    /// section of the scene is a resource (the engine's own and, through
    /// [`Scene::insert_settings`], the others), plus the run state the stages share.
    pub fn new(scene: &dyn Scene) -> Result<Self, SimError> {
        scene.validate()?;
        let material = *scene.material();
        let primary = PrimaryGrain::of(scene.cloud(), scene.domain(), &material);
        let mut rng = SimRng::seeded(scene.seed());
        let cloud = generate_cloud(
            scene.cloud(),
            scene.domain(),
            &material,
            &primary,
            &mut rng.0,
        )?;
        // Past every id given (explicit bodies may bring their own, e.g. a run's end state).
        let ids = IdAllocator::after(cloud.iter().map(|b| b.id));
        let initial_bodies = cloud.len();
        Self::assemble(scene, primary, rng, cloud, initial_bodies, ids)
    }

    /// A builder for a simulation that [`Simulation::resume`] will set to `snapshot`
    /// next: the scene's settings and plugins as [`Self::new`] makes them, but no body
    /// generated or spawned — the snapshot's bodies arrive with the resume — so that
    /// resuming a small end state does not first place, check, spawn and predict the
    /// scene's whole initial cloud only to despawn it (a subgrid box resumed 22 bodies
    /// out of a 1000-body lifted scene; issue 37).
    ///
    /// What a run reads of its initial cloud while it is built must then be given:
    /// `initial_bodies`, the cloud's body count (the diagnostics' full recount cadence);
    /// the diagnostics' initial energies (`agglo_systems::diagnostics::InitialEnergies`,
    /// inserted as a resource before `build`); and, for a scene with a restitution,
    /// `impact.collapse_time` set (its default is drawn from the initial velocities). The
    /// rest is the snapshot's: the ids (the range new ids come from), the report's
    /// initial totals, the core's frame. The scene's random generator is seeded and not
    /// drawn from — its state after a cloud whose bodies are all given with their
    /// velocities, the only scenes this resumes as [`Self::new`] would (a generated cloud
    /// draws from it).
    pub fn resuming(
        scene: &dyn Scene,
        snapshot: &crate::restart::RestartSnapshot,
        initial_bodies: usize,
    ) -> Result<Self, SimError> {
        scene.validate()?;
        let material = *scene.material();
        let primary = PrimaryGrain::of(scene.cloud(), scene.domain(), &material);
        let rng = SimRng::seeded(scene.seed());
        let ids = IdAllocator::after(snapshot.bodies.iter().map(|b| b.id));
        Self::assemble(scene, primary, rng, Vec::new(), initial_bodies, ids)
    }

    /// The world holding `cloud` and the scene's resources, with an empty pipeline, for a
    /// run that starts with `initial_bodies` bodies (the cloud's, or a snapshot's).
    fn assemble(
        scene: &dyn Scene,
        primary: PrimaryGrain,
        rng: SimRng,
        cloud: Vec<BodyState>,
        initial_bodies: usize,
        ids: IdAllocator,
    ) -> Result<Self, SimError> {
        let mut world = World::new();
        let material = *scene.material();
        let time = scene.time();
        let physics = scene.physics();
        let info = RunInfo {
            name: scene.name().to_string(),
            seed: scene.seed(),
            initial_bodies,
        };
        let initial = totals(
            cloud.iter().map(|b| (b.mass, b.velocity, b.temperature)),
            material.C,
        );
        // Resources are entities in bevy_ecs 0.20, each stored in a sparse set indexed by
        // entity index: one spawned after a million bodies costs 4 MB (its sparse array
        // spans every index below it; 25 of them took 100 MB at N = 1e6). Low indices are
        // held for them while the bodies are spawned, then freed, and the allocator hands
        // freed indices out first, so every resource inserted later (here or by a
        // plugin) gets one of them. Without a cloud (a resumed simulation, whose bodies
        // are spawned after every resource) the resources get the low indices anyway:
        // nothing is held (spawning and freeing the 256 indices was a fifth of building
        // a resumed subgrid box, issue 37).
        if !cloud.is_empty() {
            let held: Vec<_> = (0..RESOURCE_INDICES)
                .map(|_| world.spawn_empty().id())
                .collect();
            world.spawn_batch(cloud.iter().map(|b| b.bundle()));
            for entity in held.into_iter().rev() {
                world.despawn(entity);
            }
        }
        drop(cloud);
        world.insert_resource(material);
        world.insert_resource(primary);
        world.insert_resource(*scene.domain());
        world.insert_resource(*physics);
        world.insert_resource(time.clone());
        scene.insert_settings(&mut world);
        world.init_resource::<SimClock>();
        world.insert_resource(rng);
        world.insert_resource(ids);
        world.insert_resource(InvariantReport {
            initial_mass: initial.mass,
            initial_momentum: initial.momentum.to_array(),
            initial_energy: initial.energy(),
            momentum_scale: initial.momentum_scale,
            ..Default::default()
        });
        world.init_resource::<Counters>();
        world.init_resource::<crate::resources::NonFiniteState>();
        world.init_resource::<EnergyLedger>();
        world.init_resource::<ContactList>();
        world.init_resource::<ImpactRecords>();
        world.init_resource::<StateChanged>();
        world.init_resource::<StepEvents>();
        world.init_resource::<BodiesGate>();
        world.init_resource::<ForceKicks>();
        world.insert_resource(LazyState(uses_event_core(time, physics)));

        let mut schedule = Schedule::new(SimStep);
        schedule.set_executor(SingleThreadedExecutor::new());
        schedule.set_build_settings(ScheduleBuildSettings {
            ambiguity_detection: LogLevel::Error,
            ..Default::default()
        });
        // The pipeline, in the one place it is written: each stage after the one before.
        for pair in StepSystems::ORDER.windows(2) {
            schedule.configure_sets(pair[1].after(pair[0]));
        }
        schedule.add_systems(advance_clock.after(StepSystems::Last));
        Ok(Self {
            world,
            schedule,
            forces: None,
            runs_forces: false,
            info,
            plugins: Vec::new(),
            core_reason: String::new(),
            left_out: Vec::new(),
            core_stats: None,
            finishers: Vec::new(),
            subscriptions: Vec::new(),
            outcome_hooks: false,
            outcome_applier: None,
            refused: Vec::new(),
        })
    }

    /// Have bodies fly in `field` between events (uniform g, linear drag; docs/model.md
    /// §4.7), replacing the scene's `field` section. Both cores fly it exactly; on the
    /// event core it costs nothing per event (g) or a short root search per predicted
    /// pair (drag), where a force system ([`Self::add_force_systems`]) costs a kick to
    /// every body every step. May be called before or after the built-in plugins.
    pub fn set_field(&mut self, field: crate::field::Field) -> &mut Self {
        self.world.insert_resource(field);
        self
    }

    /// A resource of the world being built, e.g. the section of the scene a plugin owns
    /// (plugins decide from these what the scene needs).
    pub fn resource<R: Resource>(&self) -> &R {
        self.world.resource::<R>()
    }

    /// The run's name, seed and initial body count.
    pub fn info(&self) -> &RunInfo {
        &self.info
    }

    /// True when the scene runs on the event core (docs/model.md §4): bodies then
    /// hold their state at their own reference times ([`LazyState`]).
    pub fn uses_event_core(&self) -> bool {
        self.world.resource::<LazyState>().0
    }

    /// Add systems to one stage. Systems within a stage run in the order they are chained.
    /// At build they are checked: on the event core a system that queries a body's
    /// time-dependent state without [`crate::bodies::Bodies`] is refused (it would read
    /// stale state), and on either core one that writes the run's books (clock,
    /// counters, ledgers, the step's records) is refused — read them with
    /// [`crate::params::RunView`]; docs/extending.md, "What an extension may write".
    pub fn add_systems<M>(
        &mut self,
        stage: StepSystems,
        systems: impl IntoScheduleConfigs<ScheduleSystem, M>,
    ) -> &mut Self {
        self.schedule
            .add_systems(systems.in_set(stage).in_set(ExtensionSystems));
        self
    }

    /// Give every body components of the plugin's own at t = 0 (e.g. the initial value
    /// of a quantity it carries, [`Self::carry`]; a tuple for several), made from the
    /// body's initial state; `make` is called in id order, so it may count the bodies.
    pub fn init_each_body<B: Bundle>(
        &mut self,
        mut make: impl FnMut(&BodyState) -> B,
    ) -> &mut Self {
        let mut query = self
            .world
            .query_filtered::<(Entity, StoredBody), With<Particle>>();
        let bodies: Vec<(Entity, BodyState)> = query
            .iter(&self.world)
            .map(|(e, body)| (e, body.state()))
            .collect();
        let mut by_id: Vec<usize> = (0..bodies.len()).collect();
        by_id.sort_unstable_by_key(|&k| bodies[k].1.id);
        let mut made: Vec<Option<B>> = bodies.iter().map(|_| None).collect();
        for k in by_id {
            made[k] = Some(make(&bodies[k].1));
        }
        // Inserted in the world's order, as a plugin iterating a query does: the bodies
        // keep their order in their new table, so sums taken in query order afterwards
        // (the event core's mean velocity) come out as they did before this call.
        for ((entity, _), bundle) in bodies.iter().zip(made) {
            if let Some(bundle) = bundle {
                self.world.entity_mut(*entity).insert(bundle);
            }
        }
        self
    }

    /// Add force systems (drag, gravity, …). They run at the start of every step and
    /// act over the interval just completed, Δt = `SimClock::dt` (a kick at the end of
    /// each interval: between kicks every body moves ballistically, which is what the
    /// event core predicts), and once more when the run ends. They must read and write
    /// bodies through [`crate::bodies::Bodies`], which brings each body to the
    /// current time and has the event core re-predict what they change.
    pub fn add_force_systems<M>(
        &mut self,
        systems: impl IntoScheduleConfigs<ScheduleSystem, M>,
    ) -> &mut Self {
        let forces = self.forces.get_or_insert_with(|| {
            let mut forces = Schedule::new(ForceStep);
            forces.set_executor(SingleThreadedExecutor::new());
            forces.set_build_settings(ScheduleBuildSettings {
                ambiguity_detection: LogLevel::Error,
                ..Default::default()
            });
            forces
        });
        forces.add_systems(systems);
        if !self.runs_forces {
            self.schedule
                .add_systems(run_forces.in_set(StepSystems::Forces));
            self.runs_forces = true;
        }
        self
    }

    /// Declare the longest interval h [s] between kicks of the force systems: they then
    /// run when h has passed since the last kick, acting over it, instead of at every
    /// step, and steps land on the kick times. Between kicks bodies fly as the core
    /// predicts (exact contacts along the piecewise trajectory), so the event core
    /// re-predicts the kicked bodies once per h instead of once per event; the kick's
    /// error is O(h) (docs/model.md §4.7). h must be positive and finite.
    pub fn set_force_interval(&mut self, h: f64) -> Result<&mut Self, SimError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(SimError::Schedule(format!(
                "the force interval must be a positive, finite time [s]; got {h:e}"
            )));
        }
        self.world.resource_mut::<ForceKicks>().interval = Some(h);
        Ok(self)
    }

    /// Insert (or replace) a resource of the plugin's own: its settings, its state. The
    /// engine's run state (clock, counters, ledgers, the records the stages hand on) is
    /// not a plugin's to replace: [`Self::build`] then fails, naming the type.
    pub fn insert_resource<R: Resource>(&mut self, value: R) -> &mut Self {
        self.refuse_run_state::<R>("insert_resource");
        self.world.insert_resource(value);
        self
    }

    /// Insert a resource of the plugin's own from its `Default` (or `FromWorld`), unless
    /// it is there already. Refused for the engine's run state, as [`Self::insert_resource`].
    pub fn init_resource<R: Resource + FromWorld>(&mut self) -> &mut Self {
        self.refuse_run_state::<R>("init_resource");
        self.world.init_resource::<R>();
        self
    }

    /// Note a plugin's attempt to replace one of the engine's run-state resources.
    fn refuse_run_state<R: Resource>(&mut self, call: &str) {
        use std::any::TypeId;
        let engine_owned = [
            TypeId::of::<SimClock>(),
            TypeId::of::<Counters>(),
            TypeId::of::<EnergyLedger>(),
            TypeId::of::<InvariantReport>(),
            TypeId::of::<crate::resources::NonFiniteState>(),
            TypeId::of::<StepEvents>(),
            TypeId::of::<StateChanged>(),
            TypeId::of::<ContactList>(),
            TypeId::of::<ImpactRecords>(),
            TypeId::of::<IdAllocator>(),
            TypeId::of::<ForceKicks>(),
            TypeId::of::<LazyState>(),
            TypeId::of::<BodiesGate>(),
        ];
        if engine_owned.contains(&TypeId::of::<R>()) {
            self.refused.push(format!(
                "{call}::<{}>: the engine's run state is not a plugin's to replace (an \
                 extension reads the clock and counters through agglo::params::RunView; \
                 docs/extending.md, \"What an extension may write\")",
                std::any::type_name::<R>()
            ));
        }
    }

    /// Say why a system this scene could run is left out, e.g. `cooling off: ε = hc = 0
    /// (material.epsilon, material.hc)`: the plugin that decides says why
    /// (listed by [`Simulation::pipeline`]).
    pub fn leave_out(&mut self, what_and_why: impl Into<String>) -> &mut Self {
        self.left_out.push(what_and_why.into());
        self
    }

    /// Subscribe to a message type (e.g. [`crate::hooks::ImpactMessage`]): inserts its
    /// `Messages<M>` buffer, which the built-in stages write only when it exists, and has
    /// the simulation rotate it once per step, so that [`Simulation::step_messages`] and a
    /// `MessageReader<M>` in [`StepSystems::Last`] see each message of a step once.
    /// Subscribing twice is the same as once.
    pub fn subscribe<M: Message>(&mut self) -> &mut Self {
        let key = std::any::TypeId::of::<M>();
        if !self.subscriptions.iter().any(|(k, _)| *k == key) {
            self.world.init_resource::<Messages<M>>();
            self.subscriptions.push((key, crate::hooks::rotate::<M>));
        }
        self
    }

    /// Add systems that may change impact outcomes before they are applied
    /// ([`crate::hooks::ImpactOutcomeSystems::Decide`], in stage
    /// [`StepSystems::ImpactOutcome`]): they edit [`crate::hooks::PendingImpacts`]. The
    /// impact stage then solves every contact first and applies the outcomes after them,
    /// which is exact because a body has at most one impact per step; a scene with
    /// `physics.impacts_per_step = "every_contact"` refuses outcome systems at build.
    pub fn add_impact_outcome_systems<M>(
        &mut self,
        systems: impl IntoScheduleConfigs<ScheduleSystem, M>,
    ) -> &mut Self {
        use crate::hooks::{ImpactOutcomeSystems, PendingImpacts};
        if !self.outcome_hooks {
            self.world.init_resource::<PendingImpacts>();
            self.schedule.configure_sets(
                (ImpactOutcomeSystems::Decide, ImpactOutcomeSystems::Apply)
                    .chain()
                    .in_set(StepSystems::ImpactOutcome),
            );
            self.outcome_hooks = true;
        }
        self.schedule.add_systems(
            systems
                .in_set(ImpactOutcomeSystems::Decide)
                .in_set(ExtensionSystems),
        );
        self
    }

    /// Carry a per-body scalar component through merges and fragmentations
    /// (engine/carried.rs): `combine` says what a merged body carries, `split` what each
    /// piece of a fragmented body does; `name` is its column in `--final-state` and its
    /// field in the recording's `/stats`. Registering a name again replaces its rules.
    pub fn carry<C: crate::carried::Carried>(
        &mut self,
        name: &str,
        combine: crate::carried::Combine,
        split: crate::carried::Split,
    ) -> &mut Self {
        let first = !self
            .world
            .contains_resource::<crate::carried::CarriedState>();
        self.world
            .get_resource_or_insert_with(crate::carried::CarriedState::default)
            .register::<C>(name, combine, split);
        if first {
            // Checkpoints keep every carried quantity, by body id.
            self.add_restart_part(crate::carried::restart_part());
        }
        self
    }

    /// Keep a plugin's own state in restart snapshots (engine/restart.rs): `part.save`
    /// writes it at each checkpoint, `part.load` sets it when the world is restored from
    /// a snapshot (in the run that took it, and in a resumed run).
    pub fn add_restart_part(&mut self, part: crate::restart::RestartPart) -> &mut Self {
        let mut parts = self
            .world
            .get_resource_or_insert_with(crate::restart::RestartParts::default);
        parts.0.retain(|p| p.name != part.name);
        parts.0.push(part);
        self
    }

    /// Build one plugin into the simulation.
    pub fn add_plugin(&mut self, plugin: &dyn SimPlugin) -> &mut Self {
        plugin.build(self);
        self.plugins.push(plugin.name());
        self
    }

    /// Build several plugins, in order (e.g. the built-in physics,
    /// `agglo_systems::default_plugins()`).
    pub fn add_plugins(
        &mut self,
        plugins: impl IntoIterator<Item = Box<dyn SimPlugin>>,
    ) -> &mut Self {
        for plugin in plugins {
            self.add_plugin(plugin.as_ref());
        }
        self
    }

    /// Finish: the runnable simulation. Fails if the pipeline is ill-formed (e.g. two
    /// systems in one stage touching the same data without an order between them).
    pub fn build(mut self) -> Result<Simulation, SimError> {
        if let Some(why) = self.refused.first() {
            return Err(SimError::Schedule(why.clone()));
        }
        for finish in std::mem::take(&mut self.finishers) {
            finish(&mut self.world);
        }
        if self.outcome_hooks {
            if self.world.resource::<Physics>().impacts_per_step
                != crate::scene::ImpactsPerStep::OnePerBody
            {
                return Err(SimError::Schedule(
                    "impact-outcome systems need physics.impacts_per_step = \"one_per_body\" \
                     (each body's impact solved once per step, so outcomes can wait for the hook)"
                        .into(),
                ));
            }
            let Some(add) = self.outcome_applier else {
                if self
                    .world
                    .contains_resource::<crate::aggregates::RigidAggregates>()
                {
                    // The rigid impact system solves and applies each contact at once
                    // (a bond moves whole aggregates), so no outcome can wait for a hook.
                    return Err(SimError::Schedule(
                        "impact-outcome systems are not supported in a rigid scene \
                         (physics.merge_mode = \"rigid\", docs/model.md §6.1): use \
                         physics.merge_mode = \"coalesce\", or observe the impacts without \
                         changing their outcome"
                            .into(),
                    ));
                }
                return Err(SimError::Schedule(
                    "impact-outcome systems were added but no plugin applies impact outcomes \
                     (add the impact plugin)"
                        .into(),
                ));
            };
            add(&mut self.schedule);
        }
        if let Err(e) = self.schedule.initialize(&mut self.world) {
            let message = e.to_string(self.schedule.graph(), &self.world);
            return Err(SimError::Schedule(message));
        }
        let lazy = self.uses_event_core();
        let extensions = Some(ExtensionSystems.intern());
        refuse_unsafe_access(&self.schedule, extensions, &self.world, lazy)?;
        let mut systems: Vec<String> = self
            .schedule
            .systems()
            .map_err(|e| SimError::Schedule(format!("{e:?}")))?
            .map(|(_, system)| short_name(&system.name().to_string()))
            .collect();
        let has_forces = self.forces.is_some();
        if let Some(mut forces) = self.forces.take() {
            if let Err(e) = forces.initialize(&mut self.world) {
                let message = e.to_string(forces.graph(), &self.world);
                return Err(SimError::Schedule(message));
            }
            refuse_unsafe_access(&forces, None, &self.world, lazy)?;
            // List the force systems where they run: in place of their runner.
            let names: Vec<String> = forces
                .systems()
                .map_err(|e| SimError::Schedule(format!("{e:?}")))?
                .map(|(_, system)| short_name(&system.name().to_string()))
                .collect();
            if let Some(at) = systems.iter().position(|s| s.ends_with("run_forces")) {
                systems.splice(at..=at, names);
            }
            self.world.add_schedule(forces);
        }
        let pipeline = Pipeline {
            core: if self.uses_event_core() {
                "event"
            } else {
                "stepped"
            }
            .into(),
            core_reason: self.core_reason,
            systems,
            left_out: self.left_out,
            forces: forces_text(
                self.world.get_resource::<Field>(),
                has_forces,
                self.world.resource::<ForceKicks>(),
            ),
        };
        Ok(Simulation {
            world: self.world,
            schedule: self.schedule,
            has_forces,
            info: self.info,
            plugins: self.plugins,
            pipeline,
            core_stats: self.core_stats,
            wall_seconds: 0.0,
            rotations: self.subscriptions.into_iter().map(|(_, f)| f).collect(),
            checkpoint: None,
            checkpoint_seconds: 0.0,
            completed: false,
        })
    }
}

/// The fields and forces of a scene and the path each takes (for [`Pipeline::forces`]).
fn forces_text(field: Option<&Field>, has_force_systems: bool, kicks: &ForceKicks) -> Vec<String> {
    let mut lines: Vec<String> = field.and_then(Field::describe).into_iter().collect();
    if has_force_systems {
        lines.push(match kicks.interval {
            None => "general forces (SimBuilder::add_force_systems): a kick to every body they \
                     change at the start of each step, over the step just taken — the slow \
                     path: O(N) per step on either core, accurate to O(Δt) (Δt ≤ Δt_max); \
                     declare a force interval (SimBuilder::set_force_interval) to kick less \
                     often, or uniform g or linear drag as a field"
                .into(),
            Some(h) => format!(
                "general forces (SimBuilder::add_force_systems): a kick every h = {h:e} s \
                 (SimBuilder::set_force_interval) over the interval since the last, steps \
                 landing on the kicks — the slow path: O(N) per kick, accurate to O(h); \
                 between kicks the core's exact contacts"
            ),
        });
    }
    lines
}
