//! The step pipeline, the plugin API and the [`Simulation`] that runs a scenario.
//!
//! The pipeline is read here, top to bottom, in [`StepSystems`]: the sets are
//! chained once, in the order of docs/model.md §3 (with the step-size choice moved after
//! the events it depends on — see `systems/time_step.rs`). Physics is added by
//! [`SimPlugin`]s — the built-ins in `systems/` and any extension alike — which put
//! systems into these sets. `First`/`Last` are empty slots for extensions.
//!
//! The schedule runs single-threaded and treats ambiguous system order as an error,
//! so a missing ordering constraint fails loudly instead of making runs differ.

use std::ops::ControlFlow;

use bevy_ecs::component::ComponentId;
use bevy_ecs::message::{Message, Messages};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{LogLevel, ScheduleBuildSettings, ScheduleLabel, SingleThreadedExecutor};
use bevy_ecs::system::ScheduleSystem;
use serde::{Deserialize, Serialize};

use crate::bodies::{BodiesGate, Brought, Clockwork, LazyBody, bring_to, state_at};
use crate::cloud::PrimaryGrain;
use crate::cloud::generate_cloud;
use crate::components::{
    BodyState, Hardness, LocalTime, Mass, Particle, Position, Radius, StoredBody, Temperature,
    Velocity,
};
use crate::error::SimError;
use crate::field::Field;
use crate::resources::*;
use crate::scene::{Material, Physics, TimeControl, uses_event_core};
use crate::setup::Scene;
use crate::totals::totals;

/// Entity indices kept below the bodies' for resources (a default scene holds 27, the
/// engine's and the plugins'; more would still work, costing 4 bytes per body each).
const RESOURCE_INDICES: usize = 256;

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

/// A unit of physics: adds resources and systems to a simulation being built.
/// Built-in physics uses this too; see `examples/` for one written outside the crate.
pub trait SimPlugin {
    /// Short name, listed by [`Simulation::plugins`].
    fn name(&self) -> &'static str;
    /// Add resources and systems. Read [`SimBuilder::scenario`] to add only what the scene needs.
    fn build(&self, sim: &mut SimBuilder);
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

/// Swaps one subscribed message type's buffers (engine/hooks.rs).
type Rotate = fn(&mut World);

/// Work a plugin leaves for [`SimBuilder::build`].
pub(crate) type Finisher = Box<dyn FnOnce(&mut World)>;

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
        let mut world = World::new();
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
        let time = scene.time();
        let physics = scene.physics();
        let info = RunInfo {
            name: scene.name().to_string(),
            seed: scene.seed(),
            initial_bodies: cloud.len(),
        };
        // Past every id given (explicit bodies may bring their own, e.g. a run's end state).
        let ids = IdAllocator::after(cloud.iter().map(|b| b.id));
        let initial = totals(
            cloud.iter().map(|b| (b.mass, b.velocity, b.temperature)),
            material.C,
        );
        // Resources are entities in bevy_ecs 0.20, each stored in a sparse set indexed by
        // entity index: one spawned after a million bodies costs 4 MB (its sparse array
        // spans every index below it; 25 of them took 100 MB at N = 1e6). Low indices are
        // held for them while the bodies are spawned, then freed, and the allocator hands
        // freed indices out first, so every resource inserted later (here or by a
        // plugin) gets one of them.
        let held: Vec<_> = (0..RESOURCE_INDICES)
            .map(|_| world.spawn_empty().id())
            .collect();
        world.spawn_batch(cloud.iter().map(|b| b.bundle()));
        drop(cloud);
        for entity in held.into_iter().rev() {
            world.despawn(entity);
        }
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

/// The systems added through the API open to every plugin ([`SimBuilder::add_systems`],
/// [`SimBuilder::add_impact_outcome_systems`]): the ones [`SimBuilder::build`] checks.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct ExtensionSystems;

/// Refuse an extension's system that would read stale state or write the run's books.
/// Checked for the systems in `only` (those added through the API open to every plugin,
/// whatever the stage) or, with `None`, every system of `schedule` (the forces):
/// - on the event core (`lazy`), one that queries a body's time-dependent state without
///   [`crate::bodies::Bodies`] (docs/model.md §4: it would read each body at its own
///   reference time, not now, silently);
/// - on either core, one that writes the clock, the counters, the invariant report or the
///   records the stages hand on (they are the core's; an extension reads them through
///   [`crate::params::RunView`]), or the energy ledger or the step's events other than
///   through `Bodies` (which books what it changes).
///
/// Exclusive systems (`&mut World`) cannot be inspected and are let through.
fn refuse_unsafe_access(
    schedule: &Schedule,
    only: Option<bevy_ecs::schedule::InternedSystemSet>,
    world: &World,
    lazy: bool,
) -> Result<(), SimError> {
    let ids = |list: &[(Option<ComponentId>, &'static str)]| -> Vec<(ComponentId, &'static str)> {
        list.iter()
            .filter_map(|&(id, name)| Some((id?, name)))
            .collect()
    };
    let gate = world.component_id::<BodiesGate>();
    let lazy_state = ids(&[
        (world.component_id::<Position>(), "Position"),
        (world.component_id::<Velocity>(), "Velocity"),
        (world.component_id::<Temperature>(), "Temperature"),
        (world.component_id::<Hardness>(), "Hardness"),
        (world.component_id::<LocalTime>(), "LocalTime"),
    ]);
    // Resources are components of their own entity in bevy_ecs 0.20.
    let books = ids(&[
        (world.component_id::<SimClock>(), "SimClock"),
        (world.component_id::<Counters>(), "Counters"),
        (world.component_id::<InvariantReport>(), "InvariantReport"),
        (
            world.component_id::<crate::resources::NonFiniteState>(),
            "NonFiniteState",
        ),
        (world.component_id::<StateChanged>(), "StateChanged"),
        (world.component_id::<ContactList>(), "ContactList"),
        (world.component_id::<ImpactRecords>(), "ImpactRecords"),
        (world.component_id::<IdAllocator>(), "IdAllocator"),
        (world.component_id::<ForceKicks>(), "ForceKicks"),
    ]);
    let booked_by_bodies = ids(&[
        (world.component_id::<EnergyLedger>(), "EnergyLedger"),
        (world.component_id::<StepEvents>(), "StepEvents"),
    ]);
    // A set no system was put in is unknown to the schedule: nothing to check.
    let checked: Option<std::collections::HashSet<_>> = only.map(|set| {
        schedule
            .graph()
            .systems_in_set(set)
            .map(|keys| keys.iter().copied().collect())
            .unwrap_or_default()
    });
    let systems = schedule
        .systems_with_access()
        .map_err(|e| SimError::Schedule(format!("{e:?}")))?;
    for (key, system) in systems {
        if checked.as_ref().is_some_and(|keys| !keys.contains(&key)) {
            continue;
        }
        let bevy_ecs::system::SystemAccess::Shared(access) = system.access() else {
            continue;
        };
        let access = access.combined_access();
        let through_bodies = gate.is_some_and(|g| access.has_read(g));
        let name = || short_name(&system.name().to_string());
        let stale: Vec<&str> = lazy_state
            .iter()
            .filter(|(id, _)| access.has_read(*id) || access.has_write(*id))
            .map(|(_, name)| *name)
            .collect();
        if lazy && !through_bodies && !stale.is_empty() {
            return Err(SimError::Schedule(format!(
                "system `{}` queries {} directly, but this scene runs on the event core, where \
                 each body holds its state at its own reference time (docs/model.md §4): the \
                 query would read stale state. Read and write bodies through the `Bodies` \
                 system parameter (agglo::bodies::Bodies), which brings each body to the \
                 current time and has the event core re-predict what changes; or run the scene \
                 on the stepped core (time.core = \"stepped\")",
                name(),
                stale.join(", ")
            )));
        }
        let written: Vec<&str> = books
            .iter()
            .chain(booked_by_bodies.iter().filter(|_| !through_bodies))
            .filter(|(id, _)| access.has_write(*id))
            .map(|(_, name)| *name)
            .collect();
        if !written.is_empty() {
            return Err(SimError::Schedule(format!(
                "system `{}` writes {}, which belong to the core: an extension reads the clock \
                 and counters (agglo::params::RunView) and changes bodies through `Bodies`, \
                 which books the work and heat it adds in the energy ledger \
                 (docs/extending.md, \"What an extension may write\")",
                name(),
                written.join(", ")
            )));
        }
    }
    Ok(())
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

/// `agglo::systems::drift::drift` → `drift::drift`.
fn short_name(full: &str) -> String {
    let parts: Vec<&str> = full.rsplit("::").take(2).collect();
    parts.into_iter().rev().collect::<Vec<_>>().join("::")
}

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

/// A scenario's world and pipeline, ready to step.
pub struct Simulation {
    world: World,
    schedule: Schedule,
    /// True when force systems run (their last interval is applied when the run ends).
    has_forces: bool,
    info: RunInfo,
    plugins: Vec<&'static str>,
    pipeline: Pipeline,
    core_stats: Option<fn(&World) -> EventStats>,
    wall_seconds: f64,
    /// Rotate the buffers of each subscribed message type (before each step).
    rotations: Vec<Rotate>,
    /// The snapshot taken at the end of the last step, if it was a checkpoint.
    checkpoint: Option<crate::restart::RestartSnapshot>,
    /// Wall-clock seconds spent taking checkpoints (part of `wall_seconds`).
    checkpoint_seconds: f64,
    /// True once the run reached T and was completed (see [`Simulation::run_until`]).
    completed: bool,
}

impl Simulation {
    /// Start building with custom plugins. The built-in physics is one call away
    /// (`SimBuilder::add_default_plugins`, from `agglo_systems::DefaultPlugins`), and
    /// `Simulation::new` builds a scene with it alone.
    pub fn builder(scene: &dyn Scene) -> Result<SimBuilder, SimError> {
        SimBuilder::new(scene)
    }

    /// The run's name, seed and initial body count.
    pub fn info(&self) -> &RunInfo {
        &self.info
    }
    /// Names of the plugins built in, in order.
    pub fn plugins(&self) -> &[&'static str] {
        &self.plugins
    }
    /// The systems scheduled, in execution order (`module::function`): a scene runs only
    /// the physics it needs, and this says which.
    pub fn systems(&self) -> &[String] {
        &self.pipeline.systems
    }
    /// The core, the systems and why the others were left out.
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }
    pub fn world(&self) -> &World {
        &self.world
    }
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }
    pub fn clock(&self) -> SimClock {
        *self.world.resource::<SimClock>()
    }
    pub fn counters(&self) -> Counters {
        *self.world.resource::<Counters>()
    }
    pub fn ledger(&self) -> EnergyLedger {
        *self.world.resource::<EnergyLedger>()
    }
    pub fn invariants(&self) -> InvariantReport {
        self.world.resource::<InvariantReport>().clone()
    }
    /// The scene's material (its `material` section).
    pub fn material(&self) -> Material {
        *self.world.resource::<Material>()
    }
    /// The primary grain (radius b0 [m] and mass) of the scene.
    pub fn primary(&self) -> PrimaryGrain {
        *self.world.resource::<PrimaryGrain>()
    }
    /// The core's own counts, when its plugin reports them
    /// ([`crate::core_only::SimBuilderCore::report_core_stats`]; the event core does).
    pub fn core_stats(&self) -> Option<EventStats> {
        self.core_stats.map(|read| read(&self.world))
    }
    /// Wall-clock seconds spent in [`Simulation::step`] so far.
    pub fn wall_seconds(&self) -> f64 {
        self.wall_seconds
    }

    /// True once t = T.
    pub fn is_finished(&self) -> bool {
        let c = self.clock();
        c.time >= self.world.resource::<TimeControl>().end
    }

    /// Advance one step.
    pub fn step(&mut self) -> Result<(), SimError> {
        let clock = self.clock();
        let limit = self.world.resource::<TimeControl>().max_steps;
        if clock.step >= limit {
            return Err(SimError::StepLimit {
                step: clock.step,
                time: clock.time,
                end: self.world.resource::<TimeControl>().end,
                max_steps: limit,
            });
        }
        let start = std::time::Instant::now();
        self.checkpoint = None;
        for rotate in &self.rotations {
            rotate(&mut self.world);
        }
        self.schedule.run(&mut self.world);
        // A NaN or infinite body state seen by the checks (stage 9) ends the run here,
        // naming the body, the quantity and the step (it once ran on to T, exit 0).
        if let Some((step, what)) = self
            .world
            .resource::<crate::resources::NonFiniteState>()
            .first
            .clone()
        {
            return Err(SimError::NonFinite { step, what });
        }
        // bevy_ecs keeps a message per component of every despawned body until trackers
        // are cleared (for `RemovedComponents` readers; the engine has none): left alone,
        // a merging 1e6 cloud held 168 MB of them at its end.
        self.world.clear_trackers();
        let checkpoint = self.checkpoint_if_due();
        self.wall_seconds += start.elapsed().as_secs_f64();
        checkpoint
    }

    /// At a checkpoint time (engine/restart.rs): bring every body to now, capture the
    /// state, and restore the world from that capture, exactly as a resumed run does.
    fn checkpoint_if_due(&mut self) -> Result<(), SimError> {
        use crate::restart::{Checkpoints, capture, restore};
        let Some(mut checkpoints) = self.world.get_resource::<Checkpoints>().copied() else {
            return Ok(());
        };
        let now = self.clock().time;
        let end = self.world.resource::<TimeControl>().end;
        if !checkpoints.due(now) || checkpoints.next() >= end {
            return Ok(());
        }
        let start = std::time::Instant::now();
        checkpoints.pass(now);
        *self.world.resource_mut::<Checkpoints>() = checkpoints;
        self.bring_all_to_now();
        let snapshot = capture(&mut self.world);
        restore(&mut self.world, &snapshot).map_err(SimError::Schedule)?;
        self.checkpoint = Some(snapshot);
        self.checkpoint_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// A restart snapshot of now, taken as a checkpoint is: every body brought to now,
    /// the state captured, and the world restored from that capture, so that this run
    /// and any run resumed from the snapshot continue bit for bit alike (the Python
    /// module pickles a simulation with it). A finished run is refused: its end is done.
    pub fn snapshot_now(&mut self) -> Result<crate::restart::RestartSnapshot, SimError> {
        use crate::restart::{capture, restore};
        if self.completed {
            let c = self.clock();
            return Err(SimError::Schedule(format!(
                "the run is finished (t = {:e} s at step {}): there is nothing to continue",
                c.time, c.step
            )));
        }
        let start = std::time::Instant::now();
        self.bring_all_to_now();
        let snapshot = capture(&mut self.world);
        restore(&mut self.world, &snapshot).map_err(SimError::Schedule)?;
        self.checkpoint_seconds += start.elapsed().as_secs_f64();
        Ok(snapshot)
    }

    /// Wall-clock seconds spent taking checkpoints so far: bringing bodies to the
    /// checkpoint time, capturing, restoring (part of [`Simulation::wall_seconds`]).
    pub fn checkpoint_seconds(&self) -> f64 {
        self.checkpoint_seconds
    }

    /// The restart snapshot taken at the end of the step just taken, if that step
    /// reached a checkpoint time (read it from the observer of [`Simulation::run_with`]).
    pub fn restart_snapshot(&self) -> Option<&crate::restart::RestartSnapshot> {
        self.checkpoint.as_ref()
    }

    /// Continue from `snapshot`, taken by a run of this same scene (same settings and
    /// plugins): the world is restored from it as that run restored its own, so the
    /// rest of the run is bit-identical to that run's.
    pub fn resume(&mut self, snapshot: &crate::restart::RestartSnapshot) -> Result<(), SimError> {
        crate::restart::restore(&mut self.world, snapshot).map_err(SimError::Schedule)?;
        self.checkpoint = None;
        self.completed = false;
        Ok(())
    }

    /// Run to T.
    pub fn run(&mut self) -> Result<(), SimError> {
        self.run_with(|_| ControlFlow::Continue(()))
    }

    /// Run to T, calling `observe` after every step; `Break` stops early with [`SimError::Interrupted`].
    pub fn run_with(
        &mut self,
        observe: impl FnMut(&Simulation) -> ControlFlow<()>,
    ) -> Result<(), SimError> {
        self.run_until(|_| false, observe)
    }

    /// Step until `done` holds (asked before each step) or T is reached, calling
    /// `observe` after every step; `Break` stops early with [`SimError::Interrupted`],
    /// leaving a valid simulation that a later call continues bit for bit. At T the run
    /// is completed once (the last force interval's kick, every body brought to T);
    /// calling again after that does nothing.
    pub fn run_until(
        &mut self,
        mut done: impl FnMut(&Simulation) -> bool,
        mut observe: impl FnMut(&Simulation) -> ControlFlow<()>,
    ) -> Result<(), SimError> {
        while !self.is_finished() {
            if done(self) {
                return Ok(());
            }
            self.step()?;
            if observe(self).is_break() {
                let c = self.clock();
                return Err(SimError::Interrupted {
                    step: c.step,
                    time: c.time,
                });
            }
        }
        if !self.completed {
            self.completed = true;
            if self.has_forces {
                // The last interval's kick (forces act at the end of each interval).
                kick(&mut self.world, true);
            }
            self.bring_all_to_now();
        }
        Ok(())
    }

    /// Bring every body to the current time (event core: lazy state, docs/model.md §4),
    /// tallying the heat lost by cooling. Done at the end of a run; O(N).
    pub fn bring_all_to_now(&mut self) {
        if !self.world.resource::<LazyState>().0 {
            return;
        }
        let now = self.clock().time;
        // Copies of the scene constants, so the world can be borrowed mutably below.
        let geometry = *self.world.resource::<BoxGeometry>();
        let material = *self.world.resource::<Material>();
        let physics = *self.world.resource::<Physics>();
        let field = self.world.get_resource::<Field>().copied();
        let clockwork = Clockwork::new(&geometry, &material, &physics).with_field(field.as_ref());
        let mut ledger = *self.world.resource::<EnergyLedger>();
        let mut query = self.world.query_filtered::<(
            &mut Position,
            &mut Velocity,
            &Mass,
            &Radius,
            &mut Temperature,
            &mut Hardness,
            &mut LocalTime,
        ), With<Particle>>();
        let mut lost = 0.0;
        for (mut p, mut v, m, b, mut t, mut h, mut lt) in query.iter_mut(&mut self.world) {
            let brought = bring_to(
                now,
                &clockwork,
                LazyBody::of(&mut p, &mut v, m, b, &mut t, &mut h, &mut lt),
            );
            lost += brought.cooling_loss;
            // The field's account body by body (its turnovers are per body).
            Brought {
                cooling_loss: 0.0,
                ..brought
            }
            .enter(&mut ledger);
        }
        ledger.cooling_loss += lost;
        *self.world.resource_mut::<EnergyLedger>() = ledger;
    }

    fn clockwork(&self) -> Clockwork<'_> {
        Clockwork::new(
            self.world.resource::<BoxGeometry>(),
            self.world.resource::<Material>(),
            self.world.resource::<Physics>(),
        )
        .with_field(self.world.get_resource::<Field>())
    }

    /// Every body as columns (the fields of [`BodyState`]), sorted by stable id: what
    /// [`Simulation::bodies`] reads, laid out for a front end that hands columns on
    /// (the Python module's NumPy arrays) without transposing rows. The bodies are read
    /// in the world's order, which is usually already by id; otherwise the columns are
    /// put in id order through one permutation.
    pub fn body_columns(&self) -> crate::components::BodyColumns {
        use crate::components::BodyColumns;
        let Some(mut query) = self
            .world
            .try_query_filtered::<StoredBody, With<Particle>>()
        else {
            return BodyColumns::default();
        };
        let lazy = self.world.resource::<LazyState>().0;
        let now = self.clock().time;
        let clockwork = self.clockwork();
        let mut c = BodyColumns::with_capacity(self.body_count());
        for body in query.iter(&self.world) {
            let state = body.state();
            c.push(&if lazy {
                state_at(&state, body.local_time.0, now, &clockwork)
            } else {
                state
            });
        }
        c.sort_by_id();
        c
    }

    /// Every body, sorted by stable id (from a shared reference, so observers of
    /// [`Simulation::run_with`] can read it).
    pub fn bodies(&self) -> Vec<BodyState> {
        let Some(mut query) = self
            .world
            .try_query_filtered::<StoredBody, With<Particle>>()
        else {
            return Vec::new(); // components never registered: no particles
        };
        // Event core: each body is brought to the current time as it is read.
        let lazy = self.world.resource::<LazyState>().0;
        let now = self.clock().time;
        let clockwork = self.clockwork();
        let mut bodies: Vec<BodyState> = query
            .iter(&self.world)
            .map(|body| {
                let state = body.state();
                if lazy {
                    state_at(&state, body.local_time.0, now, &clockwork)
                } else {
                    state
                }
            })
            .collect();
        // Ids are unique, so an unstable sort gives the same order, without the stable
        // sort's buffer of half the bodies (48 MB at N = 1e6, at the run's peak).
        bodies.sort_unstable_by_key(|b| b.id);
        bodies
    }

    /// The messages of type `M` written during the step just taken, in the order they
    /// were written; empty when nobody subscribed to `M` ([`SimBuilder::subscribe`]).
    /// Read it from the observer of [`Simulation::run_with`], after each step.
    pub fn step_messages<M: Message>(&self) -> impl Iterator<Item = &M> + '_ {
        self.world
            .get_resource::<Messages<M>>()
            .into_iter()
            .flat_map(|m| m.iter_current_update_messages())
    }

    /// The carried quantities an extension registered ([`SimBuilder::carry`]) of every
    /// body, sorted by id (no columns when none is registered).
    pub fn carried(&self) -> crate::carried::CarriedColumns {
        crate::carried::carried_columns(&self.world)
    }

    /// Each carried quantity for the whole cloud, combined by its rule (empty when none
    /// is registered).
    pub fn carried_totals(&self) -> Vec<(String, f64)> {
        crate::carried::carried_totals(&self.world)
    }

    /// Number of bodies now.
    pub fn body_count(&self) -> usize {
        self.world
            .try_query_filtered::<(), With<Particle>>()
            .map_or(0, |mut q| q.iter(&self.world).count())
    }
}
