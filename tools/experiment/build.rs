use std::process::Command;

fn main() {
    mtanet_rpath::emit();
    // The commit the binary was built from, for the experiment's records: a result names the
    // code that made it. "unknown" outside a git checkout; "-dirty" with uncommitted changes.
    let git = |args: &[&str]| {
        Command::new("git")
            // Without this, `describe --dirty` refreshes .git/index, whose new mtime would rerun
            // this script (and rebuild every binary above it) on every build.
            .env("GIT_OPTIONAL_LOCKS", "0")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let commit = git(&["describe", "--always", "--dirty", "--abbrev=12"]);
    println!(
        "cargo:rustc-env=MTANET_COMMIT={}",
        commit.as_deref().unwrap_or("unknown")
    );
    if let Some(dir) = git(&["rev-parse", "--absolute-git-dir"]) {
        // A new commit moves HEAD (or the branch it names); staging changes the index.
        // Only paths that exist: cargo counts a missing one as changed and reruns every build
        // (a fresh clone has no packed-refs until git packs).
        for f in ["HEAD", "index", "refs/heads", "packed-refs"] {
            if std::path::Path::new(&format!("{dir}/{f}")).exists() {
                println!("cargo:rerun-if-changed={dir}/{f}");
            }
        }
        // An edit anywhere in the tracked tree changes "-dirty" (not target/ or run folders).
        if let (Some(top), Some(names)) = (
            git(&["rev-parse", "--show-toplevel"]),
            git(&["ls-tree", "--full-tree", "--name-only", "HEAD"]),
        ) {
            for name in names.lines() {
                println!("cargo:rerun-if-changed={top}/{name}");
            }
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
