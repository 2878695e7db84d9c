//! For the C tests (c_program.rs, c_fuzz.rs): the crate's directory, libagglo_c.so built by
//! the cargo that runs it (as c_program.rs builds it for the example), and a C
//! program compiled against the header and the library with warnings as errors. For
//! the tests that call the library from Rust (anisotropy.rs, batch_faults.rs): the last
//! error's message and a two-class coupling of ballistic_aggregation.json.
//!
//! Each test crate uses a part of this module, hence `dead_code` allowed.
#![allow(dead_code)]

use std::ffi::CStr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::ptr::null_mut;

use agglo_c::AggloStatus;
use agglo_c::coupling::{
    AggloCoupling, AggloCouplingOptions, agglo_coupling_load, agglo_scenario_primary_load,
};
use agglo_c::error::agglo_last_error;

pub fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The directory holding libagglo_c.so. `cargo test` builds every crate type of this
/// crate's library, the cdylib included, into target/<profile>/deps/ beside the test
/// binary, but only `cargo build` copies it up to target/<profile>/: the test takes the
/// one in deps/, built by the same `cargo test` that runs it. Only when that is missing
/// (the test binary run by hand) does it build the library itself with cargo, in the same
/// profile and target directory. (It used to build it always: `cargo build -p agglo-capi`
/// resolves features apart from the workspace's `cargo test` and recompiled dependencies,
/// about 40 s of the test run on a fresh clone.)
pub fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let deps = exe.parent().unwrap().to_path_buf();
    if deps.join("libagglo_c.so").exists() {
        return deps;
    }
    // target/<profile>/deps/c_program-… → target/<profile>
    let dir = deps.parent().unwrap().to_path_buf();
    let profile = dir.file_name().unwrap().to_string_lossy().into_owned();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut build = Command::new(&cargo);
    build
        .args(["build", "--quiet", "-p", "agglo-capi", "--lib"])
        .current_dir(crate_dir());
    // The test binary sits in target/<profile>; `debug` is cargo's name for the dev profile.
    if profile != "debug" {
        build.args(["--profile", &profile]);
    }
    let target_dir = dir.parent().unwrap();
    build.env("CARGO_TARGET_DIR", target_dir);
    let status = build
        .status()
        .unwrap_or_else(|e| panic!("running {cargo}: {e}"));
    assert!(status.success(), "{cargo} build -p agglo-capi --lib failed");
    assert!(
        dir.join("libagglo_c.so").exists(),
        "no libagglo_c.so in {} after building it",
        dir.display()
    );
    dir
}

/// Compile the C program `source` (under capi/) against the header and the library,
/// with warnings as errors, into `dir`; the executable's path.
pub fn compile_c(source: &str, dir: &Path) -> PathBuf {
    let exe = dir.join(Path::new(source).file_stem().unwrap());
    let lib = library_dir();
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let compiled = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"])
        .arg("-I")
        .arg(crate_dir().join("include"))
        .arg(crate_dir().join(source))
        .arg("-L")
        .arg(&lib)
        .arg("-lagglo_c")
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .args(["-lm", "-o"])
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("running {cc}: {e}"));
    assert!(
        compiled.status.success(),
        "{cc} failed:\n{}",
        String::from_utf8_lossy(&compiled.stderr)
    );
    exe
}

/// A command running the C program `exe` against the library it was linked with. The
/// rpath names that library, but `cargo test` puts target/<profile> on LD_LIBRARY_PATH,
/// which outranks it: a libagglo_c.so that an earlier `cargo build` left there (an older
/// interface) would be loaded instead. The library's own directory goes first.
pub fn c_command(exe: &Path) -> Command {
    let lib = library_dir();
    let mut path = std::ffi::OsString::from(lib.as_os_str());
    if let Some(old) = std::env::var_os("LD_LIBRARY_PATH") {
        path.push(":");
        path.push(old);
    }
    let mut command = Command::new(exe);
    command.env("LD_LIBRARY_PATH", path);
    command
}

/// The message of the last failed call on this thread.
pub fn message() -> String {
    // SAFETY: the library's message is a valid C string until the next call.
    unsafe { CStr::from_ptr(agglo_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// A coupling of ballistic_aggregation.json's grains on two classes (1 and 2+
/// primaries: edges 0.5, 1.5 and 1e9 primary masses) with `options`; and the primary
/// mass [kg].
pub fn two_class_coupling(options: &AggloCouplingOptions) -> (*mut AggloCoupling, f64) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/ballistic_aggregation.json\0"
    );
    let path = CStr::from_bytes_with_nul(path.as_bytes()).unwrap();
    let (mut b0, mut m0) = (0.0, 0.0);
    let mut c = null_mut();
    // SAFETY: valid pointers throughout.
    unsafe {
        assert_eq!(
            agglo_scenario_primary_load(path.as_ptr(), &mut b0, &mut m0),
            AggloStatus::Ok
        );
        let edges = [0.5 * m0, 1.5 * m0, 1e9 * m0];
        let status = agglo_coupling_load(path.as_ptr(), edges.as_ptr(), 3, options, &mut c);
        assert_eq!(status, AggloStatus::Ok, "{}", message());
    }
    (c, m0)
}
