//! No build step: the shard message's code is generated ahead of time (`tools/protogen`). The
//! build script is here so that cargo honours `[build-dependencies]`, which unify the features of
//! the host crates across the CLI's and the Python module's builds (as cargo-hakari's
//! workspace-hack does); it reruns only when it changes itself.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
}
