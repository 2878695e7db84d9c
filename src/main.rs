//! The `agglo` command: parse → run → exit code. Errors print with their causes.

mod cli;

#[global_allocator]
static ALLOCATOR: agglo::huge_pages::HugePages = agglo::huge_pages::HugePages;

use std::process::ExitCode;

fn main() -> ExitCode {
    restore_default_sigpipe();
    match cli::main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// Rust ignores SIGPIPE, so `println!` into a closed pipe (`agglo … | head`) panics.
/// Restore the default action: the process ends quietly, like any Unix filter.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called once at start-up, before any thread exists; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
