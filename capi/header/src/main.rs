//! Writes `capi/include/agglo.h`, the header cbindgen generates from `capi/src`, or with
//! `--check` fails when the committed header is not what the source generates now.
//!
//!     cargo run -p agglo-capi-header            # rewrite the header after changing capi/src
//!     cargo run -p agglo-capi-header -- --check # CI: the committed header is current

use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// capi/, the crate whose header this is.
fn capi_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("capi/header sits inside capi/")
        .to_path_buf()
}

/// The header cbindgen makes from capi/src now, with capi/cbindgen.toml.
fn generated_header(capi: &Path) -> Result<String, String> {
    let config = cbindgen::Config::from_file(capi.join("cbindgen.toml"))
        .map_err(|e| format!("reading capi/cbindgen.toml: {e}"))?;
    let mut out = Vec::new();
    cbindgen::Builder::new()
        .with_crate(capi)
        .with_config(config)
        .generate()
        .map_err(|e| format!("cbindgen could not read capi/src: {e}"))?
        .write(&mut out);
    String::from_utf8(out).map_err(|e| format!("cbindgen wrote non-UTF-8: {e}"))
}

fn main() -> ExitCode {
    let check = match std::env::args().nth(1).as_deref() {
        None => false,
        Some("--check") => true,
        Some(other) => {
            eprintln!("unknown argument `{other}`: give none (write the header) or --check");
            return ExitCode::from(2);
        }
    };
    let capi = capi_dir();
    let path = capi.join("include/agglo.h");
    let generated = match generated_header(&capi) {
        Ok(text) => text,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    if check {
        let committed = std::fs::read_to_string(&path).unwrap_or_default();
        if committed != generated {
            eprintln!(
                "{} is not what cbindgen generates from capi/src: run \
                 `cargo run -p agglo-capi-header` and commit the header",
                path.display()
            );
            return ExitCode::FAILURE;
        }
        println!("{} is current", path.display());
    } else if let Err(e) = std::fs::write(&path, &generated) {
        eprintln!("writing {}: {e}", path.display());
        return ExitCode::FAILURE;
    } else {
        println!("wrote {}", path.display());
    }
    ExitCode::SUCCESS
}
