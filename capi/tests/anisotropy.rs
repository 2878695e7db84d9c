//! Issue 37 item 4b through C: each class's granular temperature split over the axes
//! (`AggloCellInput::granular_anisotropy`, NULL: isotropic) is lifted and comes back as
//! the figure `class_granular_temperature_axes` (T_xx, T_yy, T_zz per class).

use std::ptr::{null, null_mut};

use agglo_c::AggloStatus;
use agglo_c::cell::*;
use agglo_c::coupling::*;
use agglo_c::output::{agglo_output_free, agglo_output_get};
use agglo_c::state::agglo_state_free;

mod common;
use common::{message, two_class_coupling};

/// Two classes (1 and 2+ primaries) of ballistic_aggregation.json's grains, boxes of
/// 300 bodies, 48 replicas (the defaults otherwise); and the primary mass [kg].
fn coupling() -> (*mut AggloCoupling, f64) {
    let mut options = agglo_coupling_options_default();
    options.bodies = 300;
    options.replicas = 48;
    two_class_coupling(&options)
}

#[test]
fn an_anisotropic_class_comes_back_with_its_axes() {
    let (c, m0) = coupling();
    let grain = m0 / 1000.0; // its volume [m³] at ρ = 1000 kg/m³
    let n = [0.02 / grain, 0.0];
    let m = [m0, 2.0 * m0];
    let v = [0.0; 6];
    let theta = [300.0; 2];
    let tg = [1.0; 2];
    // Variances 2.5, 0.25, 0.25 m²/s² (mean 1).
    let anisotropy = [10.0, 1.0, 1.0, 1.0, 1.0, 1.0];
    let mut input = AggloCellInput {
        number_density: n.as_ptr(),
        mass: m.as_ptr(),
        velocity: v.as_ptr(),
        temperature: theta.as_ptr(),
        granular_temperature: tg.as_ptr(),
        granular_anisotropy: anisotropy.as_ptr(),
        gas: AggloGas {
            velocity: [0.0; 3],
            temperature: 300.0,
            drag: AGGLO_DRAG_NONE,
            drag_a: 0.0,
            drag_b: 0.0,
        },
        // 1 ns: no impact, what comes back is what lifting drew.
        dt: 1e-9,
    };
    let (mut state, mut out) = (null_mut(), null_mut());
    let (mut mean, mut se) = ([0.0; 6], [0.0; 6]);
    // SAFETY: valid pointers; the handles are freed below.
    unsafe {
        let status = agglo_cell_advance(c, 0, 0, &input, &mut state, &mut out);
        assert_eq!(status, AggloStatus::Ok, "{}", message());
        let name = c"class_granular_temperature_axes";
        let status = agglo_output_get(out, name.as_ptr(), mean.as_mut_ptr(), se.as_mut_ptr(), 6);
        assert_eq!(status, AggloStatus::Ok, "{}", message());
        agglo_output_free(out);
    }
    for (x, want) in [2.5, 0.25, 0.25].into_iter().enumerate() {
        assert!(
            se[x] > 0.0 && se[x] < 0.1 * want,
            "axis {x}: {} ± {}",
            mean[x],
            se[x]
        );
        assert!(
            (mean[x] - want).abs() <= 3.0 * se[x],
            "axis {x}: {} ± {} against {want}",
            mean[x],
            se[x]
        );
    }
    // A weight out of range is refused naming it.
    let bad = [1.0, -1.0, 1.0, 1.0, 1.0, 1.0];
    input.granular_anisotropy = bad.as_ptr();
    let mut fresh = null_mut();
    // SAFETY: as above.
    unsafe {
        let status = agglo_cell_advance(c, 0, 0, &input, &mut fresh, &mut out);
        assert_eq!(status, AggloStatus::Input, "{}", message());
        assert!(
            message().contains("classes[0].granular_anisotropy[1]"),
            "{}",
            message()
        );
        // NULL is isotropic.
        input.granular_anisotropy = null();
        let status = agglo_cell_advance(c, 0, 0, &input, &mut fresh, &mut out);
        assert_eq!(status, AggloStatus::Ok, "{}", message());
        agglo_output_free(out);
        agglo_state_free(fresh);
        agglo_state_free(state);
        agglo_coupling_free(c);
    }
}
