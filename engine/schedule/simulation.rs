//! The built [`Simulation`]: a scenario's world and pipeline, stepped to T, with its
//! clock, counters, bodies, messages and checkpoints read between steps.

use std::ops::ControlFlow;

use bevy_ecs::message::{Message, Messages};
use bevy_ecs::prelude::*;

use crate::bodies::{Brought, Clockwork, LazyBody, bring_to, state_at};
use crate::cloud::PrimaryGrain;
use crate::components::{
    BodyState, Hardness, LocalTime, Mass, Particle, Position, Radius, StoredBody, Temperature,
    Velocity,
};
use crate::error::SimError;
use crate::field::Field;
use crate::resources::*;
use crate::scene::{Material, Physics, TimeControl};

use super::{Pipeline, Rotate, RunInfo, kick};

/// A scenario's world and pipeline, ready to step.
pub struct Simulation {
    pub(super) world: World,
    pub(super) schedule: Schedule,
    /// True when force systems run (their last interval is applied when the run ends).
    pub(super) has_forces: bool,
    pub(super) info: RunInfo,
    pub(super) plugins: Vec<&'static str>,
    pub(super) pipeline: Pipeline,
    pub(super) core_stats: Option<fn(&World) -> EventStats>,
    pub(super) wall_seconds: f64,
    /// Rotate the buffers of each subscribed message type (before each step).
    pub(super) rotations: Vec<Rotate>,
    /// The snapshot taken at the end of the last step, if it was a checkpoint.
    pub(super) checkpoint: Option<crate::restart::RestartSnapshot>,
    /// Wall-clock seconds spent taking checkpoints (part of `wall_seconds`).
    pub(super) checkpoint_seconds: f64,
    /// True once the run reached T and was completed (see [`Simulation::run_until`]).
    pub(super) completed: bool,
}

impl Simulation {
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
    /// The ECS world: every body and resource (read it for what this type has no
    /// accessor for).
    pub fn world(&self) -> &World {
        &self.world
    }
    /// The world, to change: a change outside the step's stages is the caller's to keep
    /// consistent (the event core's predictions, the ledgers).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }
    /// The clock now: time [s], step count, last Δt [s].
    pub fn clock(&self) -> SimClock {
        *self.world.resource::<SimClock>()
    }
    /// The event counters so far (impacts, bonds, bounces, fragmentations, …).
    pub fn counters(&self) -> Counters {
        *self.world.resource::<Counters>()
    }
    /// The energy ledger so far: every term booked [J].
    pub fn ledger(&self) -> EnergyLedger {
        *self.world.resource::<EnergyLedger>()
    }
    /// The invariant references at t = 0 and the worst errors seen so far.
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
    /// were written; empty when nobody subscribed to `M` ([`crate::schedule::SimBuilder::subscribe`]).
    /// Read it from the observer of [`Simulation::run_with`], after each step.
    pub fn step_messages<M: Message>(&self) -> impl Iterator<Item = &M> + '_ {
        self.world
            .get_resource::<Messages<M>>()
            .into_iter()
            .flat_map(|m| m.iter_current_update_messages())
    }

    /// The carried quantities an extension registered ([`crate::schedule::SimBuilder::carry`]) of every
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
