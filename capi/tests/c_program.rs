//! The C interface as a C program sees it: `examples/advance_cells.c` and the short
//! `examples/one_cell.c` compile against the committed header (kept current by `cargo
//! run -p agglo-capi-header`, checked in CI) with warnings as errors, link to the shared
//! library and pass their own checks; and the calls refuse NULLs and bad lengths by
//! name, from Rust.

use agglo_c::AggloStatus;

mod common;
use common::{c_command, compile_c, crate_dir};

/// Compile the example `source` (under capi/) with warnings as errors, run it on
/// ballistic_aggregation.json and return what it printed, failing if it failed.
fn run_example(source: &str) -> String {
    let build = tempfile::tempdir().unwrap();
    let exe = compile_c(source, build.path());
    let scenario = crate_dir().join("../scenarios/ballistic_aggregation.json");
    let run = c_command(&exe).arg(&scenario).output().unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(
        run.status.success(),
        "{source} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    stdout
}

#[test]
fn the_c_example_compiles_runs_and_its_checks_hold() {
    let stdout = run_example("examples/advance_cells.c");
    // Its own checks held; the lines below show they ran.
    for line in [
        "all checks hold",
        "alone: the same bytes as in the batch",
        "bad input: status 3: cell 7: classes[2].number_density",
        "damaged state: refused: state: ",
    ] {
        assert!(stdout.contains(line), "no {line:?} in:\n{stdout}");
    }
}

/// The short example (`examples/one_cell.c`, the first C a reader sees) compiles with
/// warnings as errors, runs its three steps and its one check holds (monomers stick into
/// larger bodies: the monomer rate is negative, the larger class's positive).
#[test]
fn the_short_c_example_compiles_and_runs() {
    let source = crate_dir().join("examples/one_cell.c");
    let lines = std::fs::read_to_string(&source).unwrap().lines().count();
    // The bound (REBOUND's drag example is 70 lines): short enough to read at once.
    assert!(lines <= 80, "examples/one_cell.c has {lines} lines");
    let stdout = run_example("examples/one_cell.c");
    assert_eq!(stdout.matches("dn/dt = ").count(), 3, "{stdout}");
    assert!(stdout.ends_with("done\n"), "{stdout}");
}

/// NULLs, wrong lengths and unknown names are refused with a message naming the
/// argument, never a crash.
#[test]
fn nulls_and_bad_lengths_are_refused_by_name() {
    use agglo_c::coupling::*;
    use agglo_c::error::agglo_last_error;
    let message = || {
        // SAFETY: the library's message is a valid C string until the next call.
        unsafe { std::ffi::CStr::from_ptr(agglo_last_error()) }
            .to_string_lossy()
            .into_owned()
    };
    let mut coupling = std::ptr::null_mut();
    let edges = [1e-9, 1e-6];
    // SAFETY: every pointer is valid or NULL, as each case says.
    unsafe {
        let status = agglo_coupling_new(
            std::ptr::null(),
            edges.as_ptr(),
            2,
            std::ptr::null(),
            &mut coupling,
        );
        assert_eq!(status, AggloStatus::Argument);
        assert!(message().contains("scenario_json is NULL"), "{}", message());
        let json = c"{\"name\": \"x\"";
        let status = agglo_coupling_new(
            json.as_ptr(),
            edges.as_ptr(),
            2,
            std::ptr::null(),
            &mut coupling,
        );
        assert_eq!(status, AggloStatus::Config);
        assert!(message().starts_with("scenario:"), "{}", message());
        let path = c"../scenarios/ballistic_aggregation.json";
        let status = agglo_coupling_load(
            path.as_ptr(),
            std::ptr::null(),
            3,
            std::ptr::null(),
            &mut coupling,
        );
        assert_eq!(status, AggloStatus::Argument);
        assert!(message().contains("edges is NULL"), "{}", message());
        let falling = [1e-6, 1e-9];
        let status = agglo_coupling_load(
            path.as_ptr(),
            falling.as_ptr(),
            2,
            std::ptr::null(),
            &mut coupling,
        );
        assert_eq!(status, AggloStatus::Config);
        assert!(message().contains("edges[1]"), "{}", message());
        // A closed cell and a persistent one at once.
        let mut both = agglo_coupling_options_default();
        both.keep_bodies = true;
        both.persist = true;
        let status = agglo_coupling_load(path.as_ptr(), edges.as_ptr(), 2, &both, &mut coupling);
        assert_eq!(status, AggloStatus::Config);
        assert!(message().contains("persist"), "{}", message());
        assert!(coupling.is_null());
        // A thread count beyond any machine (each is an OS thread) is refused by name.
        let good = [1e-9, 1e-6];
        let mut live = std::ptr::null_mut();
        let status =
            agglo_coupling_load(path.as_ptr(), good.as_ptr(), 2, std::ptr::null(), &mut live);
        assert_eq!(status, AggloStatus::Ok, "{}", message());
        let status = agglo_c::cell::agglo_cells_advance(
            live,
            0,
            0,
            std::ptr::null(),
            std::ptr::null(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            100_000,
        );
        assert_eq!(status, AggloStatus::Argument);
        assert!(
            message().starts_with("threads: allowed 0 ≤ threads ≤ 1024"),
            "{}",
            message()
        );
        agglo_coupling_free(live);
        assert_eq!(agglo_coupling_classes(std::ptr::null()), 0);
        agglo_coupling_free(std::ptr::null_mut());
    }
}

/// The primary grain of a scenario, without a coupling: the same numbers a coupling
/// gives, and a scenario with no primary grain refused by name.
#[test]
fn the_primary_grain_is_read_from_a_scenario() {
    use agglo_c::coupling::*;
    use agglo_c::error::agglo_last_error;
    let path = crate_dir().join("../scenarios/ballistic_aggregation.json");
    let path = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    let (mut b0, mut m0) = (0.0, 0.0);
    let (mut cb, mut cm) = (0.0, 0.0);
    let edges = [1e-30, 1.0];
    let mut coupling = std::ptr::null_mut();
    // SAFETY: every pointer is valid or NULL.
    unsafe {
        assert_eq!(
            agglo_scenario_primary_load(path.as_ptr(), &mut b0, &mut m0),
            AggloStatus::Ok
        );
        assert_eq!(
            agglo_coupling_load(
                path.as_ptr(),
                edges.as_ptr(),
                2,
                std::ptr::null(),
                &mut coupling
            ),
            AggloStatus::Ok
        );
        assert_eq!(
            agglo_coupling_primary(coupling, &mut cb, &mut cm),
            AggloStatus::Ok
        );
        agglo_coupling_free(coupling);
        // ballistic_aggregation.json: b0 = 2.12e-4 m from its size ratio, ρ = 1000 kg/m³.
        assert_eq!((b0, m0), (cb, cm));
        assert!((b0 - 2.12e-4).abs() < 0.01 * 2.12e-4, "{b0:e}");
        let want = 4.0 / 3.0 * std::f64::consts::PI * b0.powi(3) * 1000.0;
        assert!((m0 - want).abs() <= 1e-12 * want, "{m0:e} vs {want:e}");
        let json = c"{\"name\": \"x\", \"seed\": 1, \"box\": {\"half_width\": 0.01}, \
            \"cloud\": {\"count\": 2, \"radius\": -1}, \"material\": {\"rho\": 1000, \
            \"H0\": 1e-6, \"C\": 1000, \"theta0\": 300}, \"impact\": {\"a0\": 0.5, \
            \"af\": 1, \"beta\": 1}, \"time\": {\"end\": 1}}";
        let status = agglo_scenario_primary(json.as_ptr(), &mut b0, std::ptr::null_mut());
        assert_eq!(status, AggloStatus::Config);
        let message = std::ffi::CStr::from_ptr(agglo_last_error()).to_string_lossy();
        assert!(
            message.starts_with("scenario:") && message.contains("radius"),
            "{message}"
        );
    }
}
