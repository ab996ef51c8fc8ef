//! Regenerates the shard message code from `proto/kitti2pgm/frame.proto`, run from the
//! repository's root after the `.proto` changed:
//!
//! ```sh
//! cargo run --manifest-path tools/protogen/Cargo.toml
//! ```
//!
//! It writes into `src/format/shard/generated/`: `kitti2pgm.rs` (prost-build's Rust types, the
//! `.proto`'s comments as their docs), `frame_descriptor_set.bin` (the compiled
//! `FileDescriptorSet` without source info, which every shard stores as its schema) and
//! `frame.proto.sha256` (the digest of the `.proto` they were made from, which a unit test of
//! kitti2pgm compares with the `.proto` in the tree). protox compiles the `.proto` in pure Rust:
//! no `protoc` needed.

use std::path::Path;

use sha2::{Digest, Sha256};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let proto = Path::new("proto/kitti2pgm/frame.proto");
    let out = Path::new("src/format/shard/generated");
    if !proto.is_file() || !out.is_dir() {
        return Err("run from the repository's root: proto/kitti2pgm/frame.proto and src/format/shard/generated/ not found".into());
    }
    let fds = protox::Compiler::new(["proto"])?
        .include_source_info(true)
        .include_imports(true)
        .open_file("kitti2pgm/frame.proto")?
        .file_descriptor_set();
    // The stored schema without the comments (the generated code keeps them as docs).
    let mut stored = fds.clone();
    for f in &mut stored.file {
        f.source_code_info = None;
    }
    std::fs::write(
        out.join("frame_descriptor_set.bin"),
        prost::Message::encode_to_vec(&stored),
    )?;
    prost_build::Config::new().out_dir(out).compile_fds(fds)?;
    let digest = Sha256::digest(std::fs::read(proto)?);
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    std::fs::write(out.join("frame.proto.sha256"), format!("{hex}\n"))?;
    eprintln!("protogen: wrote {}", out.display());
    Ok(())
}
