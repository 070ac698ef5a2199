//! Called from each crate's `build.rs`. torch-sys and mujoco-rs link their libraries but add no
//! rpath, and an `LD_LIBRARY_PATH` in `.cargo/config.toml` does not reach test processes, so
//! without this every test binary would fail to start with exit code 127.

use std::path::PathBuf;

/// Emits `-Wl,-rpath` for libtorch and MuJoCo, as located by `.cargo/config.toml` `[env]`.
pub fn emit() {
    for (var, sub) in [("LIBTORCH", "lib"), ("MUJOCO_DYNAMIC_LINK_DIR", "")] {
        println!("cargo:rerun-if-env-changed={var}");
        let Some(dir) = std::env::var_os(var) else {
            println!(
                "cargo:warning={var} is not set: run ./ops/setup.sh (binaries may not find their libraries)"
            );
            continue;
        };
        let dir = PathBuf::from(dir).join(sub);
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", dir.display());
    }
}
