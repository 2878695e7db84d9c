//! Unit tests of `record::layout` (src/record/layout.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::record::layout::*;
use serde_json::Value;
use std::path::Path;

#[test]
fn camera_scales_with_the_box() {
    let p04 = CameraFit::for_box(1e-2);
    let p02 = CameraFit::for_box(1e-5);
    assert!((p04.distance / p02.distance - 1e3).abs() < 1e-9);
    assert!((p04.near / p02.near - 1e3).abs() < 1e-9);
    // The whole box (bounding sphere √3 D) is in front of the near plane and inside
    // the far plane.
    for fit in [p04, p02] {
        let d = fit.distance / DISTANCE_PER_HALF_WIDTH;
        assert!(fit.near < fit.distance - 3f64.sqrt() * d);
        assert!(fit.far > fit.distance + 3f64.sqrt() * d);
    }
}

#[test]
fn fitted_layout_sets_the_camera_and_keeps_the_rest() {
    let generic = generic_layout().unwrap();
    let fitted = fitted_layout(1e-5).unwrap();
    let camera = &fitted["configById"]["3D!agglo"]["cameraState"];
    let close = |key: &str, want: f64| {
        let got = camera[key].as_f64().unwrap();
        assert!((got / want - 1.0).abs() < 1e-12, "{key}: {got} vs {want}");
    };
    close("distance", 5.5e-5);
    close("near", 1e-7);
    close("far", 1e-2);
    assert_eq!(fitted["layout"], generic["layout"]);
    assert_eq!(
        fitted["configById"].as_object().unwrap().len(),
        generic["configById"].as_object().unwrap().len()
    );
}

#[test]
fn the_generic_layout_is_the_one_fitted_to_p04s_box() {
    let generic = generic_layout().unwrap();
    let fitted = fitted_layout(GENERIC_HALF_WIDTH).unwrap();
    let camera = |l: &Value| l["configById"]["3D!agglo"]["cameraState"].clone();
    let (a, b) = (camera(&generic), camera(&fitted));
    for key in ["distance", "near", "far"] {
        let (x, y) = (a[key].as_f64().unwrap(), b[key].as_f64().unwrap());
        assert!((x / y - 1.0).abs() < 1e-12, "{key}: docs {x}, fitted {y}");
    }
}

#[test]
fn bad_half_widths_are_rejected_with_the_field_name() {
    for d in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = fitted_layout(d).unwrap_err().to_string();
        assert!(e.contains("box.half_width"), "{e}");
    }
}

#[test]
fn layout_sits_beside_its_recording() {
    assert_eq!(
        layout_path_for(Path::new("out/run.mcap")),
        Path::new("out/run.layout.json")
    );
    assert_eq!(
        layout_path_for(Path::new("run")),
        Path::new("run.layout.json")
    );
}
