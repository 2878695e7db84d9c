//! The `agglo` command: the library's command line with the built-in physics alone
//! (a program with its own plugins calls `agglo::cli::main_with` with them).

#[global_allocator]
static ALLOCATOR: agglo::huge_pages::HugePages = agglo::huge_pages::HugePages;

fn main() -> std::process::ExitCode {
    agglo::cli::main_with([])
}
