//! Independent check of the generated MJCF with another MuJoCo: Debian's `mujoco-compile`
//! (MuJoCo 2.2.2). It exits 0 even when loading fails (printing `XML Error`), so success is
//! judged by the output file.

use std::path::{Path, PathBuf};
use std::process::Command;

use mtanet_scenes::{SceneConfig, World, tracks_dir};

fn shipped_tracks() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(tracks_dir())
        .expect("tracks dir")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    v.sort();
    v
}

/// Compiles `xml` (written into `dir`) with MuJoCo 2.2.2 and asserts an .mjb came out.
fn compile_with_mujoco_2_2(dir: &Path, name: &str, xml: &str) {
    let input = dir.join(format!("{name}.xml"));
    let output = dir.join(format!("{name}.mjb"));
    std::fs::write(&input, xml).expect("write MJCF");
    let out = match Command::new("mujoco-compile")
        .arg(&input)
        .arg(&output)
        .output()
    {
        Ok(o) => o,
        Err(e) => panic!(
            "cannot run `mujoco-compile` ({e}): it comes from Debian's libmujoco-samples; run ./ops/setup.sh"
        ),
    };
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        output.is_file() && !text.contains("Error"),
        "MuJoCo 2.2.2 rejected the scene for {name}:\n{text}"
    );
}

#[test]
fn every_shipped_track_compiles_with_mujoco_2_2() {
    let tracks = shipped_tracks();
    assert!(
        tracks.len() >= 4,
        "expected the 4 shipped tracks, found {tracks:?}"
    );
    let dir = tempfile::tempdir().expect("temp dir");
    for track in tracks {
        let name = track.file_stem().unwrap().to_string_lossy().to_string();
        for side_cameras in [false, true] {
            let cfg = SceneConfig {
                side_cameras,
                ..SceneConfig::default().with_track(&track)
            };
            let world = World::new(&cfg).unwrap_or_else(|e| panic!("{name}: {e}"));
            compile_with_mujoco_2_2(dir.path(), &name, world.mjcf());
        }
    }
}

#[test]
fn broken_mjcf_is_detected() {
    // The check itself must be able to fail: an unknown attribute is an XML error in 2.2.
    let dir = tempfile::tempdir().expect("temp dir");
    let r = std::panic::catch_unwind(|| {
        compile_with_mujoco_2_2(
            dir.path(),
            "broken",
            r#"<mujoco><worldbody><geom type="sphere" size="0.1" bogus="1"/></worldbody></mujoco>"#,
        )
    });
    assert!(r.is_err(), "a broken MJCF passed the mujoco-compile check");
}

#[test]
fn generated_tracks_compile_with_mujoco_2_2() {
    // Tracks nobody drew by hand: their many short bend segments must load in 2.2.2 too.
    let dir = tempfile::tempdir().expect("temp dir");
    for seed in [0, 7, 42] {
        let name = format!("generated:{seed}");
        let world = World::new(&SceneConfig::default().with_track(&name))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        compile_with_mujoco_2_2(dir.path(), &format!("generated_{seed}"), world.mjcf());
    }
}
