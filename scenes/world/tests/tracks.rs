//! Track files: every shipped track loads and is drivable from its start; bad files give errors
//! that name the file and the line.

use std::path::{Path, PathBuf};

use mtanet_scenes::{SceneConfig, Track, World, tracks_dir};
use mtanet_track::TrackError;

fn shipped() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(tracks_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    v.sort();
    v
}

#[test]
fn every_shipped_track_loads_and_the_car_starts_on_the_line() {
    let tracks = shipped();
    let names: Vec<_> = tracks
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().to_string())
        .collect();
    for required in ["oval", "bends", "s_loop", "square"] {
        assert!(
            names.iter().any(|n| n == required),
            "missing {required}.csv"
        );
    }
    for path in tracks {
        let track = Track::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            track.length_m() > 2.0,
            "{}: suspiciously short",
            path.display()
        );
        assert_eq!(track.line_width_m(), 0.025, "{}", path.display());
        let mut world = World::new(&SceneConfig::default().with_track(&path)).unwrap();
        let s = world.sense();
        assert!(
            s.truth.on_line && s.truth.lateral_m.abs() < 1e-3,
            "{path:?}: {:?}",
            s.truth
        );
        assert_eq!(
            s.line,
            [false, true, false],
            "{path:?}: only the middle sensor on the line"
        );
        let (_, heading) = track.pose_at(0.0);
        let dyaw = (s.truth.yaw - heading + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        assert!(
            dyaw.abs() < 1e-3,
            "{path:?}: car heading {} vs track {heading}",
            s.truth.yaw
        );
    }
}

#[test]
fn the_car_starts_on_the_line_of_generated_tracks() {
    for seed in 0..10 {
        let name = format!("generated:{seed}");
        let mut world = World::new(&SceneConfig::default().with_track(&name))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(world.track().path(), Path::new(&name));
        let s = world.sense();
        assert!(
            s.truth.on_line && s.truth.lateral_m.abs() < 1e-3,
            "{name}: {:?}",
            s.truth
        );
        assert_eq!(s.line, [false, true, false], "{name}: sensors {:?}", s.line);
    }
}

#[test]
fn bends_are_sampled_densely() {
    for path in shipped() {
        let t = Track::load(&path).unwrap();
        let n = t.segment_count();
        for i in 0..n {
            let (a, b) = t.segment(i);
            let (_, c) = t.segment(i + 1);
            let h1 = (b[1] - a[1]).atan2(b[0] - a[0]);
            let h2 = (c[1] - b[1]).atan2(c[0] - b[0]);
            let turn = (h2 - h1 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            // A visible kink would be > ~15 degrees between neighbouring segments.
            assert!(
                turn.abs() < 0.26,
                "{path:?}: turn {turn} at point {}",
                i + 1
            );
        }
    }
}

/// Writes `text` to a temp file named `name` and loads it.
fn load_text(dir: &Path, name: &str, text: &str) -> (PathBuf, TrackError) {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    let err = Track::load(&path).expect_err("bad track loaded");
    (path, err)
}

fn circle(r: f64, n: usize) -> String {
    let mut s = String::from("x,y\n");
    for i in 0..n {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        s += &format!("{},{}\n", r * a.cos(), r * a.sin());
    }
    s
}

/// The message names the file, and the line when given.
fn assert_names(err: &TrackError, path: &Path, line: Option<usize>) {
    let msg = err.to_string();
    assert!(
        msg.contains(&path.display().to_string()),
        "no file in: {msg}"
    );
    if let Some(l) = line {
        assert!(
            msg.contains(&format!("line {l}")),
            "no `line {l}` in: {msg}"
        );
    }
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.csv");
    let err = Track::load(&path).unwrap_err();
    assert!(matches!(err, TrackError::Io { .. }), "{err}");
    assert_names(&err, &path, None);
}

#[test]
fn malformed_number_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = circle(0.5, 60);
    text = text.replacen("\n", "\n# comment\n", 1); // line 2 is a comment, points start at 3
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[9] = "0.3,0.4x".into(); // file line 10
    let (path, err) = load_text(dir.path(), "bad_number.csv", &(lines.join("\n") + "\n"));
    assert!(matches!(err, TrackError::Parse { line: 10, .. }), "{err}");
    assert_names(&err, &path, Some(10));
    assert!(err.to_string().contains("0.4x"), "{err}");

    let (path, err) = load_text(dir.path(), "three_fields.csv", "0,0\n1,0\n1,1,2\n");
    assert!(matches!(err, TrackError::Parse { line: 3, .. }), "{err}");
    assert_names(&err, &path, Some(3));
}

#[test]
fn too_few_points() {
    let dir = tempfile::tempdir().unwrap();
    let (path, err) = load_text(dir.path(), "two.csv", "x,y\n0,0\n1,0\n");
    assert!(
        matches!(err, TrackError::TooFewPoints { count: 2, .. }),
        "{err}"
    );
    assert_names(&err, &path, None);
    // A closing repeat of the first point does not count as a third point.
    let (_, err) = load_text(dir.path(), "two_closed.csv", "0,0\n1,0\n0,0\n");
    assert!(
        matches!(err, TrackError::TooFewPoints { count: 2, .. }),
        "{err}"
    );
}

#[test]
fn nan_and_infinity() {
    let dir = tempfile::tempdir().unwrap();
    let (path, err) = load_text(dir.path(), "nan.csv", "x,y\n0,0\n1,NaN\n1,1\n");
    assert!(
        matches!(err, TrackError::NonFinite { line: 3, .. }),
        "{err}"
    );
    assert_names(&err, &path, Some(3));
    let (path, err) = load_text(dir.path(), "inf.csv", "0,0\n1,0\ninf,1\n");
    assert!(
        matches!(err, TrackError::NonFinite { line: 3, .. }),
        "{err}"
    );
    assert_names(&err, &path, Some(3));
}

#[test]
fn bad_width_comment() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("# width=25\n{}", circle(0.5, 60));
    let (path, err) = load_text(dir.path(), "width.csv", &text);
    assert!(matches!(err, TrackError::Parse { line: 1, .. }), "{err}");
    assert_names(&err, &path, Some(1));
}

#[test]
fn duplicate_point() {
    let dir = tempfile::tempdir().unwrap();
    let (path, err) = load_text(dir.path(), "dup.csv", "0,0\n1,0\n1,0\n1,1\n");
    assert!(
        matches!(err, TrackError::DuplicatePoint { line: 3, .. }),
        "{err}"
    );
    assert_names(&err, &path, Some(3));
}

#[test]
fn self_crossing_names_both_segments() {
    // A bow tie: (0,0)->(1,1) crosses (1,0)->(0,1). Lines 2..5 after the header.
    let dir = tempfile::tempdir().unwrap();
    let (path, err) = load_text(dir.path(), "bowtie.csv", "x,y\n0,0\n1,1\n1,0\n0,1\n");
    match &err {
        TrackError::SelfCrossing {
            a_lines, b_lines, ..
        } => {
            assert_eq!(*a_lines, (2, 3), "{err}");
            assert_eq!(*b_lines, (4, 5), "{err}");
        }
        _ => panic!("expected SelfCrossing, got {err}"),
    }
    assert_names(&err, &path, None);
    assert!(err.to_string().contains("lines (2, 3)"), "{err}");
}

#[test]
fn too_tight_bend_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    // A 0.5 m circle with one kink: point 20 (file line 22) pushed 3 cm outwards.
    let mut text = String::from("x,y\n");
    for i in 0..80 {
        let a = i as f64 / 80.0 * std::f64::consts::TAU;
        let r = if i == 20 { 0.53 } else { 0.5 };
        text += &format!("{},{}\n", r * a.cos(), r * a.sin());
    }
    let (path, err) = load_text(dir.path(), "kink.csv", &text);
    assert!(
        matches!(
            err,
            TrackError::TooTight {
                line: 22,
                point: 20,
                ..
            }
        ),
        "{err}"
    );
    assert_names(&err, &path, Some(22));
    // Without the kink the same circle is fine.
    let smooth = dir.path().join("smooth.csv");
    std::fs::write(&smooth, circle(0.5, 80)).unwrap();
    Track::load(&smooth).unwrap();

    // A smooth but small circle: every point is too tight; the error still names a line.
    let (path, err) = load_text(dir.path(), "small.csv", &circle(0.05, 40));
    assert!(matches!(err, TrackError::TooTight { .. }), "{err}");
    assert_names(&err, &path, None);
    assert!(err.to_string().contains("line "), "{err}");
}

#[test]
fn parts_of_the_line_too_close() {
    // A stadium whose 1 m straights are only 6 cm apart: far apart along the track, close in
    // the plane. (Its 3 cm end radius is too tight as well, but clearance is checked first.)
    let dir = tempfile::tempdir().unwrap();
    let gap = 0.06;
    let rr = gap / 2.0;
    let mut text = String::from("x,y\n");
    for i in 0..=10 {
        text += &format!("{},{}\n", 0.1 * i as f64, 0.0);
    }
    for i in 1..20 {
        let a = -std::f64::consts::FRAC_PI_2 + i as f64 / 20.0 * std::f64::consts::PI;
        text += &format!("{},{}\n", 1.0 + rr * a.cos(), rr + rr * a.sin());
    }
    for i in 0..=10 {
        text += &format!("{},{}\n", 1.0 - 0.1 * i as f64, gap);
    }
    for i in 1..20 {
        let a = std::f64::consts::FRAC_PI_2 + i as f64 / 20.0 * std::f64::consts::PI;
        text += &format!("{},{}\n", rr * a.cos(), rr + rr * a.sin());
    }
    let (path, err) = load_text(dir.path(), "neck.csv", &text);
    assert!(matches!(err, TrackError::TooClose { .. }), "{err}");
    assert_names(&err, &path, None);
    assert!(err.to_string().contains("lines ("), "{err}");
}

#[test]
fn scene_error_wraps_track_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("absent.csv");
    let err = match World::new(&SceneConfig::default().with_track(&path)) {
        Ok(_) => panic!("world built on a missing track"),
        Err(e) => e,
    };
    assert!(err.to_string().contains("absent.csv"), "{err}");
}
