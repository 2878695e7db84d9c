//! Rigid aggregates (`physics.merge_mode = "rigid"`, docs/model.md §6.1): primaries held
//! at the points where they touched, flying together without rotation.
//!
//! An aggregate is an entity of its own that owns its primaries through the bevy_ecs
//! relationship [`MemberOf`] → [`Members`]; it carries the aggregate's stable id, mass
//! and velocity ([`Aggregate`]). The primaries stay bodies (`Particle`) with all their
//! components: their own mass, radius, temperature and hardness, and the aggregate's
//! velocity, the same f64 value for every member — so two primaries of one aggregate
//! never approach, and the event core never predicts a contact between them.
//!
//! Each primary also carries its [`Offset`]: its centre relative to a point fixed in the
//! aggregate, *unwrapped* (not reduced to the periodic box), set when it joined. Without
//! rotation the offsets never change, so the shape of an aggregate — its radius of
//! gyration — comes from the offsets alone, exact however the aggregate straddles the
//! periodic boundary, while the primaries' positions stay wrapped one by one.
//!
//! The aggregate id is the smallest stable id of its primaries (a bond keeps the
//! smaller of the two), so it is as stable as the bodies' ids.

use bevy_ecs::prelude::*;
use glam::DVec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::components::{Mass, Particle, ParticleId, Radius, Velocity};

/// A primary's aggregate (the relationship's source side).
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq)]
#[relationship(relationship_target = Members)]
pub struct MemberOf(pub Entity);

/// An aggregate's primaries (the relationship's target side, kept by bevy_ecs).
#[derive(Component, Debug, Default)]
#[relationship_target(relationship = MemberOf)]
pub struct Members(Vec<Entity>);

impl Members {
    /// The primaries' entities, in the order they joined.
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

/// The aggregate itself.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Aggregate {
    /// Stable id: the smallest stable id of its primaries.
    pub id: u64,
    /// Mass M = Σ m_k [kg].
    pub mass: f64,
    /// Velocity V [m/s], shared by every primary (no rotation).
    pub velocity: DVec3,
}

/// A primary's centre relative to a point fixed in its aggregate, unwrapped [m].
#[derive(Component, Debug, Clone, Copy, PartialEq, Default)]
pub struct Offset(pub DVec3);

/// Present when the scene's bonds make rigid aggregates (`physics.merge_mode = "rigid"`).
#[derive(Resource, Debug, Clone, Copy, Default)]
pub struct RigidAggregates;

/// Make every body in the world an aggregate of one primary (at t = 0, rigid scenes).
pub fn spawn_singletons(world: &mut World) {
    let mut bodies: Vec<(Entity, u64, f64, DVec3)> = world
        .query_filtered::<(Entity, &ParticleId, &Mass, &Velocity), With<Particle>>()
        .iter(world)
        .map(|(e, id, m, v)| (e, id.0, m.0, v.0))
        .collect();
    // Spawned in id order, so that entity numbers do not depend on the query's order.
    bodies.sort_by_key(|b| b.1);
    for (entity, id, mass, velocity) in bodies {
        let aggregate = world.spawn(Aggregate { id, mass, velocity }).id();
        world
            .entity_mut(entity)
            .insert((MemberOf(aggregate), Offset(DVec3::ZERO)));
    }
    world.insert_resource(RigidAggregates);
}

/// Each primary's aggregate id, in the order of the primaries' stable ids (the order of
/// `Simulation::bodies()`); None when the scene is not rigid.
pub fn aggregate_ids(world: &World) -> Option<Vec<u64>> {
    world.get_resource::<RigidAggregates>()?;
    let mut query = world.try_query::<(&ParticleId, &MemberOf)>()?;
    let mut rows: Vec<(u64, u64)> = query
        .iter(world)
        .map(|(id, of)| (id.0, world.get::<Aggregate>(of.0).map_or(id.0, |a| a.id)))
        .collect();
    rows.sort_unstable_by_key(|r| r.0);
    Some(rows.into_iter().map(|r| r.1).collect())
}

/// One aggregate's size and shape.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AggregateShape {
    /// The aggregate's stable id.
    pub id: u64,
    /// Number of primaries k.
    pub primaries: usize,
    /// Mass [kg].
    pub mass: f64,
    /// Radius of gyration of the primaries' centres, mass-weighted,
    /// R_g² = Σ m_k |x_k − x_cm|² / M [m] (without the primaries' own extent; 0 for k = 1).
    pub radius_of_gyration: f64,
    /// Radius of the sphere of the primaries' total volume, (Σ a_k³)^(1/3) [m].
    pub volume_radius: f64,
    /// Filling factor φ_c = Σ a_k³ / R_c³ [-]: the primaries' volume over the volume of
    /// the sphere of the characteristic radius R_c = √(5/3) R_g, the radius of a
    /// homogeneous sphere of that R_g (Mukai et al. 1992, A&A 262, 315; Kozasa, Blum &
    /// Mukai 1992, A&A 263, 423, whose large ballistic particle–cluster aggregates reach
    /// φ_c ≈ 0.15). 1 for an aggregate of one primary (the sphere itself).
    pub filling_factor: f64,
}

/// The ratio of the characteristic radius of an aggregate to its radius of gyration,
/// R_c / R_g = √(5/3): a homogeneous sphere of radius R has R_g = √(3/5) R.
pub const CHARACTERISTIC_OVER_GYRATION: f64 = 1.290_994_448_735_805_6;

/// The shape of an aggregate of the primaries `(mass [kg], radius [m], offset [m])`.
pub fn shape_of(id: u64, primaries: &[(f64, f64, DVec3)]) -> AggregateShape {
    let mass: f64 = primaries.iter().map(|p| p.0).sum();
    let centre = primaries.iter().map(|p| p.0 * p.2).sum::<DVec3>() / mass;
    // Two passes (centre first): no cancellation between Σ m x² and M x_cm².
    let spread: f64 = primaries
        .iter()
        .map(|p| p.0 * (p.2 - centre).length_squared())
        .sum();
    let radius_of_gyration = (spread / mass).sqrt();
    let volume: f64 = primaries.iter().map(|p| p.1.powi(3)).sum();
    let filling_factor = if primaries.len() < 2 {
        1.0
    } else {
        volume / (CHARACTERISTIC_OVER_GYRATION * radius_of_gyration).powi(3)
    };
    AggregateShape {
        id,
        primaries: primaries.len(),
        mass,
        radius_of_gyration,
        volume_radius: volume.cbrt(),
        filling_factor,
    }
}

/// Every aggregate's shape, sorted by id (empty when the scene is not rigid).
pub fn aggregate_shapes(world: &World) -> Vec<AggregateShape> {
    if world.get_resource::<RigidAggregates>().is_none() {
        return Vec::new();
    }
    let Some(mut primaries) =
        world.try_query::<(&ParticleId, &Mass, &Radius, &Offset, &MemberOf)>()
    else {
        return Vec::new();
    };
    // (aggregate, primary id, mass, radius, offset), sorted so that each aggregate's sums
    // run in id order whatever order the query gives.
    let mut rows: Vec<(Entity, u64, f64, f64, DVec3)> = primaries
        .iter(world)
        .map(|(id, m, r, o, of)| (of.0, id.0, m.0, r.0, o.0))
        .collect();
    rows.sort_by_key(|r| (r.0, r.1));
    let mut shapes = Vec::new();
    let mut group: Vec<(f64, f64, DVec3)> = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        group.push((row.2, row.3, row.4));
        if rows.get(i + 1).is_none_or(|next| next.0 != row.0) {
            let id = world.get::<Aggregate>(row.0).map_or(row.1, |a| a.id);
            shapes.push(shape_of(id, &group));
            group.clear();
        }
    }
    shapes.sort_by_key(|s| s.id);
    shapes
}

/// The fractal law N = k_f (R_g / a)^D_f fitted over a population of aggregates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FractalFit {
    /// Fractal dimension D_f: 1 / the slope of ln(R_g / a) against ln k.
    pub dimension: f64,
    /// Prefactor k_f.
    pub prefactor: f64,
    /// Standard error of D_f from the fit's residuals (∞ for two aggregates).
    pub dimension_se: f64,
    /// Aggregates in the fit (those with k ≥ `min_primaries`).
    pub aggregates: usize,
    /// Smallest k fitted.
    pub min_primaries: usize,
    /// Primary radius a [m].
    pub primary_radius: f64,
}

/// The fractal law fitted over the aggregates with at least `min_primaries` (≥ 2)
/// primaries; None when fewer than two such aggregates of distinct k remain. Every
/// aggregate weighs the same (the population, not the mass, is fitted).
///
/// The fit is the least-squares line of ln(R_g / a) on ln k, with D_f = 1 / slope and
/// k_f = exp(−D_f · intercept). That way round because k is exact and R_g scatters
/// about its mean at a given k (aggregates of one size differ in shape): regressing
/// ln k on ln R_g instead puts that scatter in the regressor, which biases the slope
/// towards zero (regression dilution) — on 10⁵ primaries of scenarios/bcca.json it gave
/// D_f = 1.82 where this fit gives 1.85 (k ≥ 2) and 1.91 (k ≥ 5). The standard error
/// of D_f is the slope's, from the residuals, carried through D_f = 1/slope
/// (δD_f = δslope / slope²).
pub fn fractal_fit(
    shapes: &[AggregateShape],
    primary_radius: f64,
    min_primaries: usize,
) -> Option<FractalFit> {
    let points: Vec<(f64, f64)> = shapes
        .iter()
        .filter(|s| s.primaries >= min_primaries.max(2) && s.radius_of_gyration > 0.0)
        .map(|s| {
            (
                (s.primaries as f64).ln(),
                (s.radius_of_gyration / primary_radius).ln(),
            )
        })
        .collect();
    let n = points.len();
    if n < 2 {
        return None;
    }
    let nf = n as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / nf;
    let my = points.iter().map(|p| p.1).sum::<f64>() / nf;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 || sxy <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let residual: f64 = points
        .iter()
        .map(|p| (p.1 - intercept - slope * p.0).powi(2))
        .sum();
    let dimension = 1.0 / slope;
    let dimension_se = if n > 2 {
        (residual / (nf - 2.0) / sxx).sqrt() / (slope * slope)
    } else {
        f64::INFINITY
    };
    Some(FractalFit {
        dimension,
        prefactor: (-dimension * intercept).exp(),
        dimension_se,
        aggregates: n,
        min_primaries: min_primaries.max(2),
        primary_radius,
    })
}

/// The smallest aggregates the summary's fractal fit takes. Below five primaries the
/// shape is fixed by geometry rather than by how the aggregate grew (a dimer's R_g is
/// a, a trimer's between a·√(4/3), a triangle, and a·√(8/3), a line, whatever the process), so they do not
/// follow the growth's power law; with them, the fit on 10⁵ primaries of
/// scenarios/bcca.json gives D_f = 1.85, without them 1.91.
pub const FIT_MIN_PRIMARIES: usize = 5;

/// The mean filling factor φ_c over the aggregates with k ≥ `min_primaries` (None if
/// there are none).
pub fn mean_filling_factor(shapes: &[AggregateShape], min_primaries: usize) -> Option<f64> {
    let (sum, n) = shapes
        .iter()
        .filter(|s| s.primaries >= min_primaries)
        .fold((0.0, 0usize), |(sum, n), s| (sum + s.filling_factor, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// What the summary says of a rigid run's aggregates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AggregateSummary {
    /// Number of aggregates (singletons included).
    pub count: usize,
    /// Mean primaries per aggregate.
    pub mean_primaries: f64,
    /// Largest aggregate's k.
    pub max_primaries: usize,
    /// Mass-weighted mean radius of gyration [m].
    pub mean_radius_of_gyration: f64,
    /// Mean filling factor φ_c ([`AggregateShape::filling_factor`]) over the aggregates
    /// with k ≥ [`FIT_MIN_PRIMARIES`], each weighing the same, as in the fractal fit
    /// (None when there are none: smaller aggregates' φ_c is set by geometry).
    pub mean_filling_factor: Option<f64>,
    /// N = k_f (R_g/a)^D_f over the aggregates with k ≥ [`FIT_MIN_PRIMARIES`], a = the
    /// primary radius b0 (None with fewer than two such aggregates).
    pub fractal: Option<FractalFit>,
}

impl AggregateSummary {
    /// The summary of `shapes`, primaries of radius `primary_radius` [m] (None if empty).
    pub fn of(shapes: &[AggregateShape], primary_radius: f64) -> Option<Self> {
        if shapes.is_empty() {
            return None;
        }
        let total_mass: f64 = shapes.iter().map(|s| s.mass).sum();
        let primaries: usize = shapes.iter().map(|s| s.primaries).sum();
        Some(Self {
            count: shapes.len(),
            mean_primaries: primaries as f64 / shapes.len() as f64,
            max_primaries: shapes.iter().map(|s| s.primaries).max().unwrap_or(0),
            mean_radius_of_gyration: shapes
                .iter()
                .map(|s| s.mass * s.radius_of_gyration)
                .sum::<f64>()
                / total_mass,
            mean_filling_factor: mean_filling_factor(shapes, FIT_MIN_PRIMARIES),
            fractal: fractal_fit(shapes, primary_radius, FIT_MIN_PRIMARIES),
        })
    }
}
