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
    /// Done, its report printed (with `--json`, the JSON that says what failed), but nothing came
    /// of it (every frame or shard failed, an invalid submission): exit 1 with this message.
    Failed(String),
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so every `println!` into a closed pipe (`| head`) would panic: take
    // the default action back, and the process ends quietly there, as Unix tools do.
    #[cfg(unix)]
    // SAFETY: called first thing, before any thread exists; SIG_DFL is a valid disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    kitti2pgm::alloc::tune_mimalloc();
    let args = cli::Args::parse();
    let json = args.json();
    match commands::run(args) {
        Ok(Outcome::Ok) => ExitCode::SUCCESS,
        Ok(Outcome::Partial | Outcome::Findings) => ExitCode::from(3),
        Ok(Outcome::Failed(why)) => {
            eprintln!("kitti2pgm: error: {why}");
            ExitCode::FAILURE
        }
        Err(e) => {
            if let Some(io) = e.downcast_ref::<std::io::Error>() {
                if io.kind() == std::io::ErrorKind::BrokenPipe {
                    return ExitCode::SUCCESS;
                }
            }
            let message = chain_text(&e);
            eprintln!("kitti2pgm: error: {message}");
            let hint = commands::hint(&e);
            if let Some(hint) = &hint {
                eprintln!("kitti2pgm: hint: {hint}");
            }
            let library = e.chain().find_map(|c| c.downcast_ref::<kitti2pgm::Error>());
            // Options out of range or contradicting each other are usage errors, as clap's.
            let usage = library.is_some_and(|l| {
                matches!(
                    l,
                    kitti2pgm::Error::Config(_)
                        | kitti2pgm::Error::NeedsScans { .. }
                        | kitti2pgm::Error::OutputOverInput { .. }
                )
            });
            let status = if usage { 2 } else { 1 };
            if json {
                // The same error for programs: its kind (the library's, or `command`), the message.
                let record = serde_json::json!({ "error": {
                    "kind": library.map_or("command", kitti2pgm::Error::kind),
                    "message": message,
                    "hint": hint,
                    "exit": status,
                }});
                println!("{record:#}");
            }
            ExitCode::from(status)
        }
    }
}

/// The error and its causes, each once: a library error's text already holds its source (the
/// operating system's error), which anyhow's chain would print again.
pub(crate) fn chain_text(e: &anyhow::Error) -> String {
    let mut out = e.to_string();
    for cause in e.chain().skip(1) {
        let text = cause.to_string();
        if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
    }
    out
}
