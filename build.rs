//! Generates the shard message types from `proto/kitti2pgm/frame.proto` with prost-build, compiled
//! by protox (a pure-Rust protobuf compiler, so no `protoc` is needed), and keeps the compiled
//! `FileDescriptorSet`, which every shard stores as its schema.

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let proto = "proto/kitti2pgm/frame.proto";
    println!("cargo:rerun-if-changed={proto}");
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
    let out = PathBuf::from(std::env::var("OUT_DIR")?);
    std::fs::write(
        out.join("frame_descriptor_set.bin"),
        prost::Message::encode_to_vec(&stored),
    )?;
    prost_build::Config::new().compile_fds(fds)?;
    Ok(())
}
