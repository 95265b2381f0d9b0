//! Compiles the GLSL compute shaders of `shaders/glsl/` to SPIR-V with `glslc`.
//!
//! `glslc` comes from the Debian/Ubuntu package `glslc` (or the Vulkan SDK); `cargo xtask setup`
//! installs it. Without it the build stops with a message saying so.

use std::path::PathBuf;
use std::process::Command;

fn main() {
    let glsl = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("../../shaders/glsl");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    let glslc = std::env::var("GLSLC").unwrap_or_else(|_| "glslc".into());
    for entry in std::fs::read_dir(&glsl).expect("shaders/glsl exists") {
        let path = entry.expect("readable shaders/glsl").path();
        println!("cargo:rerun-if-changed={}", path.display());
    }
    println!("cargo:rerun-if-env-changed=GLSLC");
    for kernel in ["cloth_step", "cloth_step_tiled", "xpbd", "vbd", "implicit", "self_hash", "copy"] {
        let status = Command::new(&glslc)
            // No -O: the driver optimises the SPIR-V anyway, and the unoptimised module keeps the
            // struct and constant names the layout test reflects on.
            .args(["--target-env=vulkan1.1", "-I"])
            .arg(&glsl)
            .arg(glsl.join(format!("{kernel}.comp")))
            .arg("-o")
            .arg(out.join(format!("{kernel}.spv")))
            .status();
        match status {
            Ok(s) if s.success() => {}
            Ok(s) => panic!("glslc failed ({s}) compiling shaders/glsl/{kernel}.comp: see its message above"),
            Err(e) => panic!(
                "cannot run `{glslc}` ({e}): the vulkano backend compiles its GLSL shaders with glslc. \
                 Install it with `apt-get install glslc` (or run `cargo xtask setup`), or point the GLSLC \
                 environment variable at a glslc binary."
            ),
        }
    }
}
