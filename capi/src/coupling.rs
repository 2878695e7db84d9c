//! The coupling handle: the base scenario, the class edges and the box settings, made
//! once and shared by every cell (docs/coupling.md, "Choosing N and K").

use std::ffi::c_char;

use agglo::scenario::Scenario;
use agglo::subgrid::{BoxSize, Coupling};

use crate::error::{AggloStatus, Failure, guard, handle, out_pointer, slice, text};

/// A coupling (opaque): made by `agglo_coupling_new` or `agglo_coupling_load`, freed by
/// `agglo_coupling_free`.
pub struct AggloCoupling(pub(crate) Coupling);

/// How each cell's boxes are made. Start from `agglo_coupling_options_default()` and
/// change what you need.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AggloCouplingOptions {
    /// Bodies per box N (the box volume is N / Σ n_k). 0: size the box by `target_se`.
    pub bodies: u32,
    /// With `bodies` = 0: bodies enough that the cell's total impact rate has this
    /// relative standard error (0 < target_se < 1), clamped to [min_bodies, max_bodies].
    pub target_se: f64,
    /// The fewest bodies per box `target_se` may choose (with `bodies` = 0), ≥ 1.
    pub min_bodies: u32,
    /// The most bodies per box `target_se` may choose (with `bodies` = 0), ≥ `min_bodies`.
    pub max_bodies: u32,
    /// Replica boxes K per cell and macro step (independent seeds), ≥ 1.
    pub replicas: u32,
    /// Keep each cell's bodies between macro steps (a closed cell): later steps
    /// continue the state's boxes and use only the input's gas and Δt. Excludes
    /// `persist` (set it to false).
    pub keep_bodies: bool,
    /// Pool the kernel counts and exposure of the boxes (`agglo kernel`'s sums) into
    /// each output: the figures `kernel_exposure` [s/m³], `kernel_bonds`,
    /// `kernel_bounces`, `kernel_fragments` [impacts], (classes × classes) sums over the
    /// replicas whose standard errors are NaN.
    pub kernel: bool,
    /// Keep each cell's boxes between macro steps and adjust them to each new input by
    /// what transport changed since the last step's rates were applied (bodies added or
    /// removed, velocities shifted and rescaled, per class); with no transport the
    /// closed cell. Excludes `keep_bodies`. The default (re-lifted chains drift as Δt
    /// shrinks, persistent ones do not: docs/coupling.md); false with `keep_bodies`
    /// false lifts every step afresh.
    pub persist: bool,
}

/// The defaults: N = 1000 bodies per box, K = 4 replicas, persistent boxes (`persist`,
/// not `keep_bodies`), no kernel (target_se 0.05 within [100, 100 000] bodies when
/// `bodies` is set to 0).
#[unsafe(no_mangle)]
pub extern "C" fn agglo_coupling_options_default() -> AggloCouplingOptions {
    AggloCouplingOptions {
        bodies: 1000,
        target_se: 0.05,
        min_bodies: 100,
        max_bodies: 100_000,
        replicas: 4,
        keep_bodies: false,
        kernel: false,
        persist: true,
    }
}

/// Make a coupling from a scenario given as JSON text (the format of `scenarios/*.json`;
/// its material, impact, physics, core and seed are used, its box, cloud velocities,
/// end time and outputs are set by each cell), `n_edges` class edges [kg] (strictly
/// increasing; classes [e_k, e_k+1), open at both ends) and `options` (NULL: the
/// defaults). On success `*out` holds the new coupling.
///
/// # Safety
/// `scenario_json` is a NUL-terminated string; `edges` points to `n_edges` doubles;
/// `options` is NULL or points to options; `out` points to writable storage for a handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_coupling_new(
    scenario_json: *const c_char,
    edges: *const f64,
    n_edges: usize,
    options: *const AggloCouplingOptions,
    out: *mut *mut AggloCoupling,
) -> AggloStatus {
    guard(|| {
        out_pointer(out, "out")?;
        // SAFETY: the caller's contract, passed on.
        let json = unsafe { text(scenario_json, "scenario_json") }?;
        let scenario = Scenario::from_json(json).map_err(scenario_failure)?;
        // SAFETY: as above; `out` checked non-NULL.
        unsafe { make_into(scenario, edges, n_edges, options, out) }
    })
}

/// As `agglo_coupling_new`, with the scenario read from the file at `path` (a
/// `cloud.from_file` in it is read too, relative to the scenario).
///
/// # Safety
/// As `agglo_coupling_new`, `path` a NUL-terminated string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_coupling_load(
    path: *const c_char,
    edges: *const f64,
    n_edges: usize,
    options: *const AggloCouplingOptions,
    out: *mut *mut AggloCoupling,
) -> AggloStatus {
    guard(|| {
        out_pointer(out, "out")?;
        // SAFETY: the caller's contract, passed on.
        let path = unsafe { text(path, "path") }?;
        let scenario = Scenario::load(std::path::Path::new(path)).map_err(scenario_failure)?;
        // SAFETY: as above; `out` checked non-NULL.
        unsafe { make_into(scenario, edges, n_edges, options, out) }
    })
}

/// The number of size classes (one fewer than the edges); 0 for NULL.
///
/// # Safety
/// `coupling` is NULL or a live coupling.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_coupling_classes(coupling: *const AggloCoupling) -> usize {
    // SAFETY: the caller's contract.
    unsafe { coupling.as_ref() }.map_or(0, |c| c.0.classes())
}

/// The primary grain's radius [m] and mass [kg] (the smallest body a class may hold).
///
/// # Safety
/// `coupling` a live coupling; `radius` and `mass` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_coupling_primary(
    coupling: *const AggloCoupling,
    radius: *mut f64,
    mass: *mut f64,
) -> AggloStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let c = unsafe { handle(coupling, "coupling") }?;
        let (b0, m0) = c.0.primary();
        // SAFETY: each is NULL (skipped) or writable.
        unsafe {
            if let Some(r) = radius.as_mut() {
                *r = b0;
            }
            if let Some(m) = mass.as_mut() {
                *m = m0;
            }
        }
        Ok(())
    })
}

/// The primary grain's radius [m] and mass [kg] of a scenario given as JSON text — the
/// mass unit a flow solver's class edges are usually given in — without making a
/// coupling first. The scenario is validated; a primary grain that is not a finite
/// radius > 0 is refused.
///
/// # Safety
/// `scenario_json` is a NUL-terminated string; `radius` and `mass` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_scenario_primary(
    scenario_json: *const c_char,
    radius: *mut f64,
    mass: *mut f64,
) -> AggloStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let json = unsafe { text(scenario_json, "scenario_json") }?;
        let scenario = Scenario::from_json(json).map_err(scenario_failure)?;
        // SAFETY: as above.
        unsafe { write_primary(&scenario, radius, mass) }
    })
}

/// As `agglo_scenario_primary`, with the scenario read from the file at `path`.
///
/// # Safety
/// `path` is a NUL-terminated string; `radius` and `mass` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_scenario_primary_load(
    path: *const c_char,
    radius: *mut f64,
    mass: *mut f64,
) -> AggloStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let path = unsafe { text(path, "path") }?;
        let scenario = Scenario::load(std::path::Path::new(path)).map_err(scenario_failure)?;
        // SAFETY: as above.
        unsafe { write_primary(&scenario, radius, mass) }
    })
}

/// Validate `scenario` and write its primary radius and mass.
///
/// # Safety
/// `radius` and `mass` NULL or writable.
unsafe fn write_primary(
    scenario: &Scenario,
    radius: *mut f64,
    mass: *mut f64,
) -> Result<(), Failure> {
    scenario.validate().map_err(scenario_failure)?;
    let (b0, m0) = (scenario.primary_radius(), scenario.primary_mass());
    if !(b0.is_finite() && b0 > 0.0 && m0.is_finite()) {
        return Err(scenario_failure(format!(
            "cloud: primary radius {b0:e} m (give cloud.radius [m], a finite radius > 0)"
        )));
    }
    // SAFETY: each is NULL (skipped) or writable (the caller's contract).
    unsafe {
        if let Some(r) = radius.as_mut() {
            *r = b0;
        }
        if let Some(m) = mass.as_mut() {
            *m = m0;
        }
    }
    Ok(())
}

/// Free a coupling (NULL is ignored). No cell call may be running on it.
///
/// # Safety
/// `coupling` is NULL or a coupling from this library not freed before.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_coupling_free(coupling: *mut AggloCoupling) {
    if !coupling.is_null() {
        // SAFETY: made by Box::into_raw in this module, freed once (the caller's word).
        drop(unsafe { Box::from_raw(coupling) });
    }
}

fn scenario_failure(e: impl std::fmt::Display) -> Failure {
    Failure {
        status: AggloStatus::Config,
        message: format!("scenario: {e}"),
    }
}

/// Make the coupling of `scenario` on the edges with the options, checked, into `*out`.
///
/// # Safety
/// `edges` points to `n_edges` doubles; `options` is NULL or points to options; `out`
/// is non-NULL and writable.
unsafe fn make_into(
    scenario: Scenario,
    edges: *const f64,
    n_edges: usize,
    options: *const AggloCouplingOptions,
    out: *mut *mut AggloCoupling,
) -> Result<(), Failure> {
    // SAFETY: the caller's contract.
    let coupling = unsafe { make(scenario, edges, n_edges, options) }?;
    // SAFETY: `out` is non-NULL and writable (the caller's contract).
    unsafe { *out = Box::into_raw(Box::new(AggloCoupling(coupling))) };
    Ok(())
}

/// The coupling of `scenario` on the edges with the options, checked.
///
/// # Safety
/// `edges` points to `n_edges` doubles; `options` is NULL or points to options.
unsafe fn make(
    scenario: Scenario,
    edges: *const f64,
    n_edges: usize,
    options: *const AggloCouplingOptions,
) -> Result<Coupling, Failure> {
    // SAFETY: the caller's contract.
    let edges = unsafe { slice(edges, n_edges, "edges") }?.to_vec();
    // SAFETY: as above.
    let options = unsafe { options.as_ref() }
        .copied()
        .unwrap_or_else(|| agglo_coupling_options_default());
    let mut c = Coupling::new(scenario, edges)?;
    c.bodies = if options.bodies > 0 {
        BoxSize::Bodies(options.bodies)
    } else {
        BoxSize::TargetSe {
            relative: options.target_se,
            min_bodies: options.min_bodies,
            max_bodies: options.max_bodies,
        }
    };
    c.replicas = options.replicas;
    c.keep_bodies = options.keep_bodies;
    c.kernel = options.kernel;
    c.persist = options.persist;
    c.check()?;
    Ok(c)
}
