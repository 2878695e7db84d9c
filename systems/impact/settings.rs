//! The `impact` section of a scenario (docs/model.md §5): the impact/heat solve's
//! parameters and the readings of the papers it can take. Deserialised from the
//! scenario file into [`ImpactModel`], inserted into the world as it is, and read there
//! by [`super::resolve_impacts`].

use bevy_ecs::prelude::*;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use agglo_engine::error::ValidationIssue;
use agglo_engine::issues::Issues;
pub use agglo_engine::laws::impact::{
    BondTest, DurationLaw, FrictionCap, PairHardness, Separation, SolverKind, WorkHeat,
};
use agglo_engine::scene::is_default;

/// The impact/heat solve (docs/model.md §5).
#[derive(Resource, Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImpactModel {
    /// Contact-area fraction at full rebound (e = 1), 0 ≤ a0 ≤ af.
    pub a0: f64,
    /// Contact-area fraction at adhesion (e = 0), a0 ≤ af ≤ 1.
    pub af: f64,
    /// Impact-duration scale β (P02's k), > 0.
    pub beta: f64,
    /// Impact-duration law: `p04` (P04 (4.10)) or `p02` (P02 (12)).
    #[serde(default)]
    pub duration: DurationLaw,
    /// μ = μ0 (1 − e) when true (P02), μ = μ0 otherwise (P04).
    #[serde(default)]
    pub friction_scales_with_adhesion: bool,
    /// Relative tolerance TOL of the fixed point: |e_{K+1} − e_K| ≤ TOL·e_K (+ an absolute floor).
    #[serde(default = "default_solver_tol")]
    pub tol: f64,
    /// Plain fixed-point iterations before the bracketed fallback takes over.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: u32,
    /// Solver: `safeguarded` (papers' iteration, then bracketed fallback; default) or
    /// `plain` (the papers' iteration only; non-convergence is counted, the last iterate used).
    #[serde(default)]
    pub solver: SolverKind,
    /// Reading: which hardness a pair bonds against in G(e) (docs/model.md §5.1 step 7):
    /// `min` (the softer body governs, P04's footnote to (3.1); default), `harmonic`,
    /// `arithmetic` (means of the two) or `max` (both surfaces must yield).
    #[serde(default, skip_serializing_if = "is_default")]
    pub pair_hardness: PairHardness,
    /// Reading: `sticking` caps the friction impulse where sliding stops (default), `none`
    /// applies the papers' full Coulomb impulse, which can reverse sliding and create
    /// kinetic energy (docs/model.md §5.1 step 5).
    #[serde(default, skip_serializing_if = "is_default")]
    pub friction_cap: FrictionCap,
    /// Reading: `fixed_point` bonds only when e* = 0 (default); `any_iterate` is P02 (20),
    /// which bonds as soon as one iterate of the papers' iteration from e0 = 0 presses at
    /// ≥ 2H (docs/model.md §5.3).
    #[serde(default, skip_serializing_if = "is_default")]
    pub bond_test: BondTest,
    /// Reading: how a bouncing pair that overlaps is separated: `normal` (along n̂,
    /// mass-weighted, centre of mass fixed; default) or `velocities` (P02 (8): each body
    /// moves b(1 − δ) along its own outgoing velocity, δ = |r_ij|/(b_i + b_j)).
    #[serde(default, skip_serializing_if = "is_default")]
    pub separation: Separation,
    /// Reading: `once` heats the pair by its kinetic-energy loss W (P02 (14)–(17); default);
    /// `twice` is P04 (6.10), which adds the deformation work δW — the same dissipated
    /// energy — on top, so the pair is heated by W more (docs/model.md §5.1 step 6).
    #[serde(default, skip_serializing_if = "is_default")]
    pub work_heat: WorkHeat,
    /// The restitution law: absent = the impact/heat solve of §5.1–5.3 (bonding and
    /// bouncing from hardness and heat); `{"constant": e}`, 0 ≤ e ≤ 1, the granular-gas
    /// law of docs/model.md §5.4: smooth spheres, normal restitution e, no bonding, no
    /// reaction heat; the lost energy heats the pair unless `work_heat` is `none`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<RestitutionLaw>,
    /// The TC model's t_c [s] for the constant law (docs/model.md §5.4): a pair either of
    /// whose bodies had an impact less than t_c ago bounces elastically (e = 1), which
    /// stops inelastic collapse. Default: 1e-3 b0 / v_s, the time a body at the cloud's
    /// initial rms speed about its mean, v_s, takes to cross a thousandth of the primary
    /// radius b0. 0 switches the model off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collapse_time: Option<f64>,
}

impl ImpactModel {
    /// Range problems of the `impact` section, by full path.
    pub fn issues(&self) -> Vec<ValidationIssue> {
        let mut v = Issues::default();
        let i = self;
        v.range_closed("impact.af", i.af, 0.0, 1.0, "0 < af ≤ 1");
        if i.af == 0.0 {
            v.push("impact.af", "0 < af ≤ 1", i.af);
        }
        v.range_closed("impact.a0", i.a0, 0.0, 1.0, "0 ≤ a0 ≤ af");
        if i.a0.is_finite() && i.af.is_finite() && i.a0 > i.af {
            v.issues.push(ValidationIssue {
                path: "impact.a0".into(),
                message: format!("must satisfy a0 ≤ af (got a0 = {}, af = {})", i.a0, i.af),
            });
        }
        v.positive("impact.beta", i.beta);
        v.range_open("impact.tol", i.tol, 0.0, 1.0, "0 < tol < 1");
        if i.max_iterations == 0 {
            v.push("impact.max_iterations", "≥ 1", 0.0);
        }
        if i.solver == SolverKind::ClosedFormPrinted && i.duration != DurationLaw::P04 {
            v.issues.push(ValidationIssue {
                path: "impact.solver".into(),
                message: "closed_form_printed is P04 (4.14), derived for P04's duration law: \
                          it needs impact.duration = \"p04\""
                    .into(),
            });
        }

        if let Some(RestitutionLaw::Constant(e)) = i.restitution {
            v.range_closed("impact.restitution.constant", e, 0.0, 1.0, "0 ≤ e ≤ 1");
        }
        if let Some(tc) = i.collapse_time {
            v.non_negative("impact.collapse_time", tc);
        }
        v.issues
    }
}

/// A restitution law other than the impact/heat solve (docs/model.md §5.4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum RestitutionLaw {
    /// Constant normal restitution e, 0 ≤ e ≤ 1 (smooth spheres, no bonding).
    Constant(f64),
}

fn default_solver_tol() -> f64 {
    1e-12
}
fn default_max_iterations() -> u32 {
    100
}

impl Default for ImpactModel {
    fn default() -> Self {
        Self {
            a0: 0.0,
            af: 1.0,
            beta: 1.0,
            duration: DurationLaw::P04,
            friction_scales_with_adhesion: false,
            tol: default_solver_tol(),
            max_iterations: default_max_iterations(),
            solver: SolverKind::Safeguarded,
            pair_hardness: PairHardness::Min,
            friction_cap: FrictionCap::Sticking,
            bond_test: BondTest::FixedPoint,
            separation: Separation::Normal,
            work_heat: WorkHeat::Once,
            restitution: None,
            collapse_time: None,
        }
    }
}
