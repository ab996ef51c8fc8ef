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

/// mimalloc's purging, set for frame-sized buffers: every frame frees and allocates the same
/// 0.5-2 MB again. With its defaults (freed memory decommitted after 10 ms) the kernel faulted in
/// and cleared fresh pages, often 2 MB huge ones, frame after frame: 37,000 page faults for 300
/// Pandar40P frames on one thread, page clearing 8-15% of the profile on two. Kept a second, and
/// then reset (the kernel may take the pages when it needs them; untaken, they are reused as they
/// are) instead of decommitted: 230 faults, page clearing under 1%.
const ALLOCATOR_OPTIONS: [(libmimalloc_sys::mi_option_t, std::ffi::c_long); 2] = [
    // `mi_option_purge_delay` (15 in mimalloc's v2 and v3 headers; the bindings do not name it).
    (15, 1000),
    // `mi_option_purge_decommits` (5): 0 = purge by resetting.
    (5, 0),
];

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
    // SAFETY: sets plain integer options; mimalloc reads its options lazily, any time.
    for (option, value) in ALLOCATOR_OPTIONS {
        unsafe { libmimalloc_sys::mi_option_set(option, value) };
    }
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
            eprintln!("kitti2pgm: error: {e:#}");
            let hint = commands::hint(&e);
            if let Some(hint) = hint {
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
                    "message": format!("{e:#}"),
                    "hint": hint,
                    "exit": status,
                }});
                println!("{record:#}");
            }
            ExitCode::from(status)
        }
    }
}
