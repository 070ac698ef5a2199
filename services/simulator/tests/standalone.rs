//! The standalone teacher run: report contents, the dataset format and its determinism, errors.

use std::path::{Path, PathBuf};
use std::process::Command;

use mtanet_ipc::shutdown::Shutdown;
use mtanet_scenes::{SceneConfig, Teacher, TeacherConfig, World, shipped_track};
use mtanet_simulator::standalone::{StandaloneRun, run};
use ndarray::{Array3, Array4};
use ndarray_npy::NpzReader;

fn record(
    dir: &Path,
    name: &str,
    seed: u64,
    noise: f32,
    seconds: f64,
) -> (PathBuf, mtanet_simulator::standalone::Report) {
    let mut world = World::new(&SceneConfig::default()).unwrap();
    let mut teacher = Teacher::new(&TeacherConfig {
        seed,
        noise_std: noise,
        ..TeacherConfig::default()
    });
    let path = dir.join(name);
    let spec = StandaloneRun {
        sim_seconds: seconds,
        record: Some(path.clone()),
        seq_len: 20,
        seed,
    };
    let report = run(&mut world, &mut teacher, &spec, &Shutdown::manual()).unwrap();
    (path, report)
}

fn load(path: &Path) -> (Array4<f32>, Array3<f32>) {
    let mut npz = NpzReader::new(std::fs::File::open(path).unwrap()).unwrap();
    (
        npz.by_name("images").unwrap(),
        npz.by_name("actions").unwrap(),
    )
}

#[test]
fn recording_has_the_dataset_layout_and_follows_the_actions() {
    let dir = tempfile::tempdir().unwrap();
    let (path, report) = record(dir.path(), "d.npz", 1, 1.0, 8.0);
    assert_eq!(report.steps, 400);
    assert_eq!(report.recorded_sequences, 20);
    let (images, actions) = load(&path);
    assert_eq!(images.shape(), &[20, 20, 8, 12]);
    assert_eq!(actions.shape(), &[20, 20, 2]);
    assert!(
        images.iter().all(|v| (0.0..=1.0).contains(v)),
        "images outside [0,1]"
    );
    // The car drives forward: the measured wheel velocities are mostly positive and vary (noise).
    let mean = actions.mean().unwrap();
    assert!(mean > 1.0, "mean wheel velocity {mean}");
    let first = actions[[5, 3, 0]];
    assert!(
        actions.iter().any(|v| (v - first).abs() > 0.1),
        "actions are constant"
    );
    assert!(
        report.lateral_error_m.max < 0.0125,
        "teacher left the line: {:?}",
        report.lateral_error_m
    );
}

#[test]
fn same_seed_same_bytes_other_seed_other_data() {
    let dir = tempfile::tempdir().unwrap();
    let (a, _) = record(dir.path(), "a.npz", 7, 1.5, 4.0);
    let (b, _) = record(dir.path(), "b.npz", 7, 1.5, 4.0);
    let (c, _) = record(dir.path(), "c.npz", 8, 1.5, 4.0);
    assert_eq!(
        std::fs::read(&a).unwrap(),
        std::fs::read(&b).unwrap(),
        "same seed must give identical files"
    );
    assert_ne!(
        load(&a).0,
        load(&c).0,
        "another noise seed must change the images"
    );
}

#[test]
fn teacher_report_on_the_oval() {
    let dir = tempfile::tempdir().unwrap();
    let report_path = dir.path().join("rep.json");
    let out = Command::new(env!("CARGO_BIN_EXE_mta-simulator"))
        .args(["--teacher-only", "--sim-seconds", "60", "--report"])
        .arg(&report_path)
        .arg("--track")
        .arg(shipped_track("oval"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: mtanet_simulator::standalone::Report =
        serde_json::from_slice(&std::fs::read(&report_path).unwrap()).unwrap();
    assert!(r.laps >= 2, "{r:?}");
    assert_eq!(r.steps, 3000);
    assert!(r.lateral_error_m.max < 0.0125, "{r:?}");
    assert!(r.lateral_error_m.mean < r.lateral_error_m.max);
    assert!(r.real_time_factor > 1.0, "{r:?}");
}

/// Runs the simulator binary, expecting failure; returns its stderr.
fn failing_run(args: &[&std::ffi::OsStr]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_mta-simulator"))
        .args(args)
        .output()
        .unwrap();
    assert!(!out.status.success(), "expected a failure for {args:?}");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn bad_inputs_fail_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let teacher_run = |track: &Path| {
        let args = [
            "--teacher-only",
            "--sim-seconds",
            "1",
            "--report",
            "/dev/null",
            "--track",
        ];
        let mut v: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
        v.push(track.as_os_str());
        failing_run(&v)
    };
    let err = teacher_run(&dir.path().join("nope.csv"));
    assert!(err.contains("nope.csv"), "{err}");

    let bad = dir.path().join("two.csv");
    std::fs::write(&bad, "x,y\n0,0\n1,0\n").unwrap();
    let err = teacher_run(&bad);
    assert!(err.contains("two.csv"), "{err}");

    let cfg = dir.path().join("bad.toml");
    std::fs::write(&cfg, "[simulator]\nmode = \"warp\"\n").unwrap();
    let err = failing_run(&["--config".as_ref(), cfg.as_os_str()]);
    assert!(err.contains("bad.toml") && err.contains("mode"), "{err}");
}

/// `--write-mjcf` writes the scene MuJoCo 3.17 loaded, for the user's own viewer, and the same
/// file compiles with another MuJoCo (Debian's 2.2.2 `mujoco-compile`, which exits 0 even on
/// failure: the output file is the verdict).
#[test]
fn write_mjcf_writes_a_scene_that_another_mujoco_loads() {
    let dir = tempfile::tempdir().unwrap();
    let xml = dir.path().join("bends.xml");
    let out = Command::new(env!("CARGO_BIN_EXE_mta-simulator"))
        .arg("--write-mjcf")
        .arg(&xml)
        .arg("--track")
        .arg(shipped_track("bends"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&xml).unwrap();
    let scene = World::new(&SceneConfig::default().with_track(shipped_track("bends"))).unwrap();
    assert_eq!(
        text,
        scene.mjcf(),
        "the file is the generated scene of that track"
    );
    let mjb = dir.path().join("bends.mjb");
    let c = Command::new("mujoco-compile").arg(&xml).arg(&mjb).output();
    let c = c.expect("mujoco-compile (Debian's libmujoco-samples; ./ops/setup.sh installs it)");
    assert!(
        mjb.is_file(),
        "MuJoCo 2.2.2: {}",
        String::from_utf8_lossy(&c.stdout)
    );
    // A track that does not exist: a clear error, no file.
    let bad = dir.path().join("none.xml");
    let out = Command::new(env!("CARGO_BIN_EXE_mta-simulator"))
        .arg("--write-mjcf")
        .arg(&bad)
        .args(["--track", "no/such/track.csv"])
        .output()
        .unwrap();
    assert!(!out.status.success() && !bad.exists());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/track.csv"));
}

/// Tracks nobody tuned on: the teacher as configured for the shipped tracks laps a sample of
/// generated ones (seeds 0 to 4, and the tightest bend among the first 200 seeds), on the line.
#[test]
fn teacher_laps_generated_tracks() {
    let radius = |seed: u64| mtanet_track::generate(seed).unwrap().min_bend_radius_m();
    let tightest = (0..200)
        .min_by(|a, b| radius(*a).total_cmp(&radius(*b)))
        .unwrap();
    let mut seeds: Vec<u64> = (0..5).collect();
    if !seeds.contains(&tightest) {
        seeds.push(tightest);
    }
    for seed in seeds {
        let name = format!("generated:{seed}");
        let mut world = World::new(&SceneConfig::default().with_track(&name)).unwrap();
        let (len, width) = (world.track().length_m(), world.track().line_width_m());
        // The teacher cruises at about 0.2 m/s: a lap at 0.15 m/s is the time allowed.
        let spec = StandaloneRun {
            sim_seconds: len / 0.15,
            record: None,
            seq_len: 20,
            seed: 0,
        };
        let mut teacher = Teacher::new(&TeacherConfig::default());
        let r = run(&mut world, &mut teacher, &spec, &Shutdown::manual()).unwrap();
        println!(
            "{name}: {len:.2} m, tightest bend {:.3} m: {} lap(s) in {:.0} s, lateral max {:.4} m, on the line {:.3}",
            world.track().min_bend_radius_m(),
            r.laps,
            r.sim_seconds,
            r.lateral_error_m.max,
            r.on_line_fraction
        );
        assert!(
            r.laps >= 1,
            "{name} ({len:.2} m): no lap in {} s",
            r.sim_seconds
        );
        assert!(
            r.lateral_error_m.max < width,
            "{name}: {:?}",
            r.lateral_error_m
        );
        assert!(r.on_line_fraction > 0.99, "{name}: {}", r.on_line_fraction);
        assert_eq!(r.rejected_commands, 0, "{name}");
    }
}

/// `generated:N` on the command line: the teacher run, the scene written with `--write-mjcf`
/// (which MuJoCo 2.2.2 compiles too), and a malformed name named in the error.
#[test]
fn generated_tracks_by_name_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("rep.json");
    let out = Command::new(env!("CARGO_BIN_EXE_mta-simulator"))
        .args([
            "--teacher-only",
            "--sim-seconds",
            "60",
            "--track",
            "generated:3",
        ])
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["track"], "generated:3", "{r}");
    assert!(r["laps"].as_u64().unwrap() >= 1, "{r}");

    let xml = dir.path().join("g7.xml");
    let out = Command::new(env!("CARGO_BIN_EXE_mta-simulator"))
        .arg("--write-mjcf")
        .arg(&xml)
        .args(["--track", "generated:7"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let scene = World::new(&SceneConfig::default().with_track("generated:7")).unwrap();
    assert_eq!(std::fs::read_to_string(&xml).unwrap(), scene.mjcf());
    let mjb = dir.path().join("g7.mjb");
    let c = Command::new("mujoco-compile").arg(&xml).arg(&mjb).output();
    let c = c.expect("mujoco-compile (Debian's libmujoco-samples; ./ops/setup.sh installs it)");
    assert!(
        mjb.is_file(),
        "MuJoCo 2.2.2: {}",
        String::from_utf8_lossy(&c.stdout)
    );

    let err = failing_run(&[
        "--write-mjcf".as_ref(),
        xml.as_os_str(),
        "--track".as_ref(),
        "generated:seven".as_ref(),
    ]);
    assert!(err.contains("generated:seven"), "{err}");
}
