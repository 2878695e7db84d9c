//! Per-body state an extension adds (charge, a species' mass, provenance, porosity),
//! carried through merges and fragmentations by a rule it chooses (docs/extending.md).
//!
//! An extension registers a scalar component with [`crate::schedule::SimBuilder::carry`],
//! naming it and giving a [`Combine`] rule (what a merged body carries, docs/model.md §6)
//! and a [`Split`] rule (what each of a fragmenting body's p equal pieces carries, §7).
//! The built-in merge and fragment stages then apply the rules to every registered
//! component (queued as commands, applied at the sync point right after the stage, in
//! the stage's order: by stable ids). Nothing is queued when nothing is registered.
//! `--final-state` writes each as a named column after the built-in ones, and each
//! recorded `/stats` message carries the value of the whole cloud combined by the rule
//! ([`carried_totals`]).
//!
//! Restart checkpoints keep them ([`restart_part`], registered with the first carried
//! quantity): each body's values by id, set again when the world is restored.
//!
//! The built-in quantities go through the same rules where they fit: mass and primaries
//! are [`Combine::Sum`] and [`Split::ByMass`], temperature is [`Combine::MassWeighted`]
//! (the heat Σ m C θ adds, one C) — written with the same arithmetic as before, so no
//! output changed.

use bevy_ecs::component::Mutable;
use bevy_ecs::prelude::*;

use crate::components::{Particle, ParticleId};

/// What a merged body carries, from its parents' values a, b and masses m_a, m_b [kg].
#[derive(Debug, Clone, Copy)]
pub enum Combine {
    /// Extensive: a + b (charge, mass of a species).
    Sum,
    /// Intensive, mass-weighted: (m_a a + m_b b) / (m_a + m_b) (composition; temperature
    /// with one heat capacity).
    MassWeighted,
    /// max(a, b) (e.g. the highest temperature a grain has seen).
    Max,
    /// min(a, b) (e.g. the time a body was first formed).
    Min,
    /// Any rule: `f(a, m_a, b, m_b)`.
    Function(fn(f64, f64, f64, f64) -> f64),
}

impl Combine {
    /// The merged value.
    pub fn combine(self, a: f64, mass_a: f64, b: f64, mass_b: f64) -> f64 {
        match self {
            Combine::Sum => a + b,
            Combine::MassWeighted => (mass_a * a + mass_b * b) / (mass_a + mass_b),
            Combine::Max => a.max(b),
            Combine::Min => a.min(b),
            Combine::Function(f) => f(a, mass_a, b, mass_b),
        }
    }
}

/// What each of the p equal pieces of a fragmenting body carries (docs/model.md §7: the
/// pieces share mass equally).
#[derive(Debug, Clone, Copy)]
pub enum Split {
    /// By mass fraction, value / p (extensive quantities).
    ByMass,
    /// Every piece keeps the parent's value (intensive quantities, labels).
    Copy,
    /// Any rule: `f(value, p)`.
    Function(fn(f64, u64) -> f64),
}

impl Split {
    /// One piece's value.
    pub fn split(self, value: f64, pieces: u64) -> f64 {
        match self {
            Split::ByMass => value / pieces as f64,
            Split::Copy => value,
            Split::Function(f) => f(value, pieces),
        }
    }
}

/// A scalar component carried through merges and fragmentations.
pub trait Carried: Component<Mutability = Mutable> {
    /// Its value (SI; the unit is the extension's to document).
    fn value(&self) -> f64;
    /// The component holding `value`.
    fn from_value(value: f64) -> Self;
}

/// One registered quantity.
#[derive(Clone)]
struct Entry {
    name: String,
    combine: Combine,
    split: Split,
    get: fn(&World, Entity) -> Option<f64>,
    set: fn(&mut World, Entity, f64),
}

fn get<C: Carried>(world: &World, entity: Entity) -> Option<f64> {
    world.get::<C>(entity).map(C::value)
}

fn set<C: Carried>(world: &mut World, entity: Entity, value: f64) {
    if let Ok(mut e) = world.get_entity_mut(entity) {
        e.insert(C::from_value(value));
    }
}

/// The registered quantities, in registration order (present only when one is).
#[derive(Resource, Clone, Default)]
pub struct CarriedState {
    entries: Vec<Entry>,
}

impl CarriedState {
    pub(crate) fn register<C: Carried>(&mut self, name: &str, combine: Combine, split: Split) {
        self.entries.retain(|e| e.name != name);
        self.entries.push(Entry {
            name: name.to_string(),
            combine,
            split,
            get: get::<C>,
            set: set::<C>,
        });
    }

    /// The column names, in registration order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.name.as_str())
    }

    /// `gone` (mass `mass_gone` [kg]) merges into `keep` (mass `mass_keep`, before the
    /// merge): `keep` gets each combined value. A parent without the component counts as
    /// 0; if neither has it, nothing is written.
    pub fn merge(
        &self,
        world: &mut World,
        (keep, mass_keep): (Entity, f64),
        (gone, mass_gone): (Entity, f64),
    ) {
        for e in &self.entries {
            let (a, b) = ((e.get)(world, keep), (e.get)(world, gone));
            if a.is_none() && b.is_none() {
                continue;
            }
            let v = e
                .combine
                .combine(a.unwrap_or(0.0), mass_keep, b.unwrap_or(0.0), mass_gone);
            (e.set)(world, keep, v);
        }
    }

    /// `parent` split into `pieces`: each gets the split value of each component the
    /// parent has.
    pub fn split(&self, world: &mut World, parent: Entity, pieces: &[Entity]) {
        for e in &self.entries {
            let Some(v) = (e.get)(world, parent) else {
                continue;
            };
            let piece = e.split.split(v, pieces.len() as u64);
            for &p in pieces {
                (e.set)(world, p, piece);
            }
        }
    }
}

/// Queue the merge of the registered quantities (for the merge stage): applied at the
/// sync point after it, before `gone` is despawned if queued before that.
pub fn queue_merge(commands: &mut Commands, keep: (Entity, f64), gone: (Entity, f64)) {
    commands.queue(move |world: &mut World| {
        world.resource_scope(|world, state: Mut<CarriedState>| state.merge(world, keep, gone));
    });
}

/// Queue the split of the registered quantities (for the fragment stage).
pub fn queue_split(commands: &mut Commands, parent: Entity, pieces: Vec<Entity>) {
    commands.queue(move |world: &mut World| {
        world.resource_scope(|world, state: Mut<CarriedState>| state.split(world, parent, &pieces));
    });
}

/// The registered quantities of every body: names, and one row per body sorted by id
/// (`None` where a body lacks the component).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CarriedColumns {
    /// The registered quantities' names, in registration order.
    pub names: Vec<String>,
    /// One row per body: its stable id and its value of each quantity, in `names`' order.
    pub rows: Vec<(u64, Vec<Option<f64>>)>,
}

/// Read the registered quantities of every body (empty when none is registered), and in
/// a rigid scene (docs/model.md §6.1) each primary's aggregate id as the last column,
/// `aggregate` (an id below 2⁵³, exact as f64).
pub fn carried_columns(world: &World) -> CarriedColumns {
    let state = world.get_resource::<CarriedState>();
    let rigid = world
        .get_resource::<crate::aggregates::RigidAggregates>()
        .is_some();
    if state.is_none() && !rigid {
        return CarriedColumns::default();
    }
    let Some(mut query) = world.try_query_filtered::<(Entity, &ParticleId), With<Particle>>()
    else {
        return CarriedColumns::default();
    };
    let entries = state.map_or(&[][..], |s| &s.entries[..]);
    let aggregate_of = |entity: Entity| {
        let of = world.get::<crate::aggregates::MemberOf>(entity)?;
        Some(world.get::<crate::aggregates::Aggregate>(of.0)?.id as f64)
    };
    let mut rows: Vec<(u64, Vec<Option<f64>>)> = query
        .iter(world)
        .map(|(entity, id)| {
            let mut values: Vec<Option<f64>> =
                entries.iter().map(|e| (e.get)(world, entity)).collect();
            if rigid {
                values.push(aggregate_of(entity));
            }
            (id.0, values)
        })
        .collect();
    rows.sort_by_key(|r| r.0);
    let mut names: Vec<String> = entries.iter().map(|e| e.name.clone()).collect();
    if rigid {
        names.push("aggregate".to_string());
    }
    CarriedColumns { names, rows }
}

/// Each registered quantity for the whole cloud: the bodies combined by its rule in
/// id order (what one body made of them all would carry), by name. Masses are needed
/// for [`Combine::MassWeighted`]; bodies lacking the component are skipped.
pub fn carried_totals(world: &World) -> Vec<(String, f64)> {
    let Some(state) = world.get_resource::<CarriedState>() else {
        return Vec::new();
    };
    let Some(mut query) = world
        .try_query_filtered::<(Entity, &ParticleId, &crate::components::Mass), With<Particle>>()
    else {
        return Vec::new();
    };
    let mut bodies: Vec<(u64, Entity, f64)> =
        query.iter(world).map(|(e, id, m)| (id.0, e, m.0)).collect();
    bodies.sort_by_key(|b| b.0);
    state
        .entries
        .iter()
        .filter_map(|e| {
            let mut acc: Option<(f64, f64)> = None;
            for &(_, entity, mass) in &bodies {
                let Some(v) = (e.get)(world, entity) else {
                    continue;
                };
                acc = Some(match acc {
                    None => (v, mass),
                    Some((a, m)) => (e.combine.combine(a, m, v, mass), m + mass),
                });
            }
            acc.map(|(v, _)| (e.name.clone(), v))
        })
        .collect()
}

/// The restart part of the carried quantities (engine/restart.rs): every body's values,
/// by id, saved with a checkpoint and set again on the restored bodies.
pub fn restart_part() -> crate::restart::RestartPart {
    crate::restart::RestartPart {
        name: "carried",
        save: save_carried,
        load: load_carried,
    }
}

fn save_carried(world: &World) -> Vec<u8> {
    let columns = carried_columns(world);
    postcard::to_allocvec(&(columns.names, columns.rows)).expect("plain data always encodes")
}

fn load_carried(world: &mut World, bytes: &[u8]) -> Result<(), String> {
    type Saved = (Vec<String>, Vec<(u64, Vec<Option<f64>>)>);
    let (names, rows): Saved =
        postcard::from_bytes(bytes).map_err(|e| format!("carried quantities: {e}"))?;
    let Some(state) = world.get_resource::<CarriedState>().cloned() else {
        return Err("carried quantities in the snapshot, none registered in this scene".into());
    };
    let registered: Vec<&str> = state.names().collect();
    if names != registered {
        return Err(format!(
            "carried quantities: the snapshot holds {names:?}, this scene registers {registered:?}"
        ));
    }
    let mut query = world.query_filtered::<(Entity, &ParticleId), With<Particle>>();
    let entities: std::collections::HashMap<u64, Entity> =
        query.iter(world).map(|(e, id)| (id.0, e)).collect();
    for (id, values) in rows {
        let Some(&entity) = entities.get(&id) else {
            return Err(format!(
                "carried quantities of body {id}, which the snapshot lacks"
            ));
        };
        for (entry, value) in state.entries.iter().zip(values) {
            if let Some(v) = value {
                (entry.set)(world, entity, v);
            }
        }
    }
    Ok(())
}
