//! Foxglove layouts: the generic one shipped as `docs/foxglove_layout.json`, and the
//! same layout fitted to a recording's box.
//!
//! Foxglove's 3D camera is set in metres, so one camera cannot serve every scene: P04's
//! box is 2 cm wide (D = 1e-2 m), P02's 20 µm (D = 1e-5 m). A fitted layout is the
//! generic one with the 3D panel's camera distance, near and far planes scaled by D
//! ([`CameraFit`]). `agglo run --recording RUN.mcap` writes one as `RUN.layout.json`
//! ([`layout_path_for`]); `agglo layout RUN.mcap` writes one for an existing recording,
//! reading D from it ([`box_half_width`]).

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde_json::Value;

use super::inspect;

/// The generic layout (fitted to P04's box, D = 1e-2 m), compiled in so that the
/// binary needs no file beside it; it is also the template of every fitted layout.
pub const GENERIC_LAYOUT: &str = include_str!("../../docs/foxglove_layout.json");

/// Half-width D [m] the generic layout is fitted to (P04's box).
pub const GENERIC_HALF_WIDTH: f64 = 1e-2;

/// Camera distance over D. The box's bounding sphere has radius √3 D; Foxglove's
/// vertical field of view is 45°, so the whole box needs a distance ≥ √3 D / sin 22.5°
/// ≈ 4.5 D; 5.5 D leaves a margin for bodies that stick out of the box (checked in
/// Foxglove Studio 1.48: docs/foxglove_paper2004_best.png).
#[doc(hidden)]
pub const DISTANCE_PER_HALF_WIDTH: f64 = 5.5;
/// Near plane over D: small enough to zoom into the box without clipping it, large
/// enough for depth precision (a fixed near plane of 0.1 mm would clip P02's whole
/// 20 µm box).
const NEAR_PER_HALF_WIDTH: f64 = 1e-2;
/// Far plane over D: room to zoom out by two orders of magnitude.
const FAR_PER_HALF_WIDTH: f64 = 1e3;

/// The 3D camera of a box of half-width D.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraFit {
    /// Distance from the target (the box centre) [m].
    pub distance: f64,
    /// Near clipping plane [m].
    pub near: f64,
    /// Far clipping plane [m].
    pub far: f64,
}

impl CameraFit {
    /// The camera for half-width `half_width` [m] (the caller checks it is positive).
    pub fn for_box(half_width: f64) -> Self {
        Self {
            distance: DISTANCE_PER_HALF_WIDTH * half_width,
            near: NEAR_PER_HALF_WIDTH * half_width,
            far: FAR_PER_HALF_WIDTH * half_width,
        }
    }
}

/// The generic layout, parsed.
pub fn generic_layout() -> anyhow::Result<Value> {
    serde_json::from_str(GENERIC_LAYOUT).context("parsing the built-in docs/foxglove_layout.json")
}

/// The generic layout with every 3D panel's camera fitted to a box of half-width D [m].
pub fn fitted_layout(half_width: f64) -> anyhow::Result<Value> {
    check_half_width(half_width, "the box")?;
    let fit = CameraFit::for_box(half_width);
    let mut layout = generic_layout()?;
    let panels = layout
        .get_mut("configById")
        .and_then(Value::as_object_mut)
        .context("the built-in layout has no `configById` object")?;
    let mut fitted = 0;
    for (id, config) in panels.iter_mut() {
        if panel_type(id) == "3D" {
            set_camera(config, fit).with_context(|| format!("fitting panel {id}"))?;
            fitted += 1;
        }
    }
    anyhow::ensure!(fitted > 0, "the built-in layout has no 3D panel to fit");
    Ok(layout)
}

/// The panel type of a layout panel id: Foxglove ids are `TYPE!suffix`.
pub fn panel_type(id: &str) -> &str {
    id.split_once('!').map_or(id, |(kind, _)| kind)
}

fn set_camera(config: &mut Value, fit: CameraFit) -> anyhow::Result<()> {
    let camera = config
        .get_mut("cameraState")
        .and_then(Value::as_object_mut)
        .context("no `cameraState` object")?;
    camera.insert("distance".into(), fit.distance.into());
    camera.insert("near".into(), fit.near.into());
    camera.insert("far".into(), fit.far.into());
    Ok(())
}

/// Where `agglo run --recording RUN.mcap` puts its layout: `RUN.layout.json` beside it.
pub fn layout_path_for(recording: &Path) -> PathBuf {
    recording.with_extension("layout.json")
}

/// Write the layout fitted to half-width D [m] to `path`; returns the camera used.
pub fn write_fitted_layout(path: &Path, half_width: f64) -> anyhow::Result<CameraFit> {
    let layout = fitted_layout(half_width)?;
    let text = serde_json::to_string_pretty(&layout).context("the layout as JSON")?;
    std::fs::write(path, text + "\n")
        .with_context(|| format!("writing Foxglove layout {}", path.display()))?;
    Ok(CameraFit::for_box(half_width))
}

/// The box half-width D [m] of a recording: from its metadata, else from its embedded
/// scenario (older recordings). Errors name the file and what is missing.
pub fn box_half_width(recording: &Path) -> anyhow::Result<f64> {
    let found = inspect::inspect(recording)?;
    let d = found.box_half_width.with_context(|| {
        format!(
            "{} records no box half-width (metadata `{}` or scenario `box.half_width`): \
             not an agglo recording?",
            recording.display(),
            super::BOX_HALF_WIDTH_KEY
        )
    })?;
    check_half_width(d, &recording.display().to_string())?;
    Ok(d)
}

fn check_half_width(d: f64, whose: &str) -> anyhow::Result<()> {
    anyhow::ensure!(
        d.is_finite() && d > 0.0,
        "box.half_width of {whose} is {d}: a layout needs a finite D > 0"
    );
    Ok(())
}
