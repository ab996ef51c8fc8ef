//! The `kitti2pgm` binary: parses arguments, dispatches to `commands::*`, maps the outcome to an
//! exit status (0 ok, 1 fatal error, 2 usage, 3 finished with failed frames). All the work is in
//! the library.

mod cli;
mod commands;

use std::process::ExitCode;

use clap::Parser;

/// Why: every frame allocates and frees buffers of 0.5-2 MB (scan, decoded image, tensors). The
/// system allocator hands such blocks back to the kernel and takes fresh zeroed pages for the
/// next frame: page faults and page clearing were 15% of a conversion's profile. mimalloc keeps
/// them for reuse (docs/performance.md).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// How a command ended, when it did not fail outright.
pub enum Outcome {
    /// Everything done.
    Ok,
    /// Done, but some items (frames) failed and were reported.
    Partial,
    /// Done, and the findings reach the severity asked to fail on (`check`).
    Findings,
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so every `println!` into a closed pipe (`| head`) would panic: take
    // the default action back, and the process ends quietly there, as Unix tools do.
    #[cfg(unix)]
    // SAFETY: called first thing, before any thread exists; SIG_DFL is a valid disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args = cli::Args::parse();
    match commands::run(args) {
        Ok(Outcome::Ok) => ExitCode::SUCCESS,
        Ok(Outcome::Partial | Outcome::Findings) => ExitCode::from(3),
        Err(e) => {
            if let Some(io) = e.downcast_ref::<std::io::Error>() {
                if io.kind() == std::io::ErrorKind::BrokenPipe {
                    return ExitCode::SUCCESS;
                }
            }
            eprintln!("kitti2pgm: error: {e:#}");
            if let Some(hint) = commands::hint(&e) {
                eprintln!("kitti2pgm: hint: {hint}");
            }
            // Options out of range or contradicting each other are usage errors, as clap's.
            let usage = e.chain().any(|c| {
                matches!(
                    c.downcast_ref(),
                    Some(
                        kitti2pgm::Error::Config(_)
                            | kitti2pgm::Error::NeedsScans { .. }
                            | kitti2pgm::Error::OutputOverInput { .. }
                    )
                )
            });
            if usage {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
