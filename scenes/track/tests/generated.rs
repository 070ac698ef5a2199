//! Generated tracks: 200 seeds, each closed, valid, within the length range and the curvature
//! bound, and the same for the same seed; `generated:N` loads wherever a track file does.

use std::f64::consts::TAU;
use std::path::Path;
use std::time::{Duration, Instant};

use mtanet_track::{
    GENERATED_MIN_RADIUS_M, LENGTH_RANGE_M, Track, TrackError, generate, generate_counting,
};

const SEEDS: u64 = 200;

/// Signed turn at each vertex, radians.
fn turns(t: &Track) -> Vec<f64> {
    let n = t.segment_count();
    (0..n)
        .map(|i| {
            let (a, b) = t.segment(i + n - 1);
            let (_, c) = t.segment(i);
            let h1 = (b[1] - a[1]).atan2(b[0] - a[0]);
            let h2 = (c[1] - b[1]).atan2(c[0] - b[0]);
            (h2 - h1 + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI
        })
        .collect()
}

#[test]
fn two_hundred_seeds_give_closed_valid_tracks_within_the_bounds() {
    let (mut lengths, mut radii, mut candidates) = (Vec::new(), Vec::new(), 0u32);
    let (mut clockwise, mut slowest) = (0, Duration::ZERO);
    let mut seen = std::collections::HashSet::new();
    let started = Instant::now();
    for seed in 0..SEEDS {
        let t0 = Instant::now();
        let (t, c) = generate_counting(seed).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        slowest = slowest.max(t0.elapsed());
        candidates += c;
        assert_eq!(t.path(), Path::new(&format!("generated:{seed}")));
        // Closed: the implicit closing segment is an ordinary one (no gap bridged, no kink),
        // and the line turns exactly once round.
        let (a, b) = t.segment(t.segment_count() - 1);
        let gap = mtanet_track::dist(a, b);
        assert!(
            gap > 0.0 && gap <= 0.25 + 1e-6,
            "seed {seed}: closing gap {gap}"
        );
        let turns = turns(&t);
        let total: f64 = turns.iter().sum();
        assert!(
            (total.abs() - TAU).abs() < 1e-6,
            "seed {seed}: total turn {total}"
        );
        clockwise += usize::from(total < 0.0);
        let kink = turns.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        assert!(
            kink < 0.26,
            "seed {seed}: a {kink} rad kink between segments"
        );
        let len = t.length_m();
        assert!(
            (LENGTH_RANGE_M.0..=LENGTH_RANGE_M.1).contains(&len),
            "seed {seed}: length {len}"
        );
        // The loaders' check: written out and read back, the same validated points.
        let csv = t.to_csv(&[&format!("seed {seed}")]);
        let back = Track::parse(Path::new("back.csv"), &csv)
            .unwrap_or_else(|e| panic!("seed {seed}: the written file fails the check: {e}"));
        assert_eq!(back.points(), t.points(), "seed {seed}: CSV round trip");
        // The polyline's measured radius may fall a little short of the curve's.
        let r = t.min_bend_radius_m();
        assert!(
            r >= 0.95 * GENERATED_MIN_RADIUS_M,
            "seed {seed}: bend radius {r}"
        );
        assert!(
            seen.insert(
                t.points()
                    .iter()
                    .map(|p| p.map(f64::to_bits))
                    .collect::<Vec<_>>()
            ),
            "seed {seed} repeats an earlier seed's track"
        );
        lengths.push(len);
        radii.push(r);
    }
    let range = |v: &[f64]| {
        v.iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(*x), hi.max(*x)))
    };
    let ((l0, l1), (r0, r1)) = (range(&lengths), range(&radii));
    println!(
        "{SEEDS} seeds in {:.2} s (slowest {:.0} ms): length {l0:.2}..{l1:.2} m, min bend radius {r0:.3}..{r1:.3} m, {:.2} candidates a track, {clockwise} clockwise",
        started.elapsed().as_secs_f64(),
        slowest.as_secs_f64() * 1e3,
        candidates as f64 / SEEDS as f64
    );
    // Variety, not one shape: both directions, short and long loops.
    assert!(
        clockwise > 40 && clockwise < 160,
        "{clockwise} of {SEEDS} clockwise"
    );
    assert!(l0 < 4.0 && l1 > 7.0, "lengths only {l0}..{l1}");
    if !cfg!(debug_assertions) {
        assert!(
            slowest < Duration::from_secs(1),
            "slowest seed took {slowest:?}"
        );
    }
}

#[test]
fn the_same_seed_gives_the_same_track() {
    for seed in [0, 1, 7, 123, u64::MAX] {
        let (a, b) = (generate(seed).unwrap(), generate(seed).unwrap());
        assert_eq!(a.points(), b.points(), "seed {seed}");
        let by_name = Track::load(Path::new(&format!("generated:{seed}"))).unwrap();
        assert_eq!(by_name.points(), a.points(), "seed {seed} by name");
    }
    assert_ne!(generate(1).unwrap().points(), generate(2).unwrap().points());
}

#[test]
fn a_bad_generated_name_is_named_in_the_error() {
    for name in ["generated:", "generated:x", "generated:-1", "generated:1.5"] {
        let err = Track::load(Path::new(name)).unwrap_err();
        assert!(
            matches!(err, TrackError::GeneratedName { .. }),
            "{name}: {err}"
        );
        assert!(err.to_string().contains(name), "{err}");
    }
    // Only the exact prefix: a file whose name merely contains it is still a file.
    let err = Track::load(Path::new("./generated:7")).unwrap_err();
    assert!(matches!(err, TrackError::Io { .. }), "{err}");
}

/// Largest |curvature| along the line (1/m), sampled every centimetre over 10 cm windows.
fn max_curvature(t: &Track) -> f64 {
    let n = (t.length_m() / 0.01) as usize;
    (0..n)
        .map(|i| t.curvature_at(i as f64 * 0.01, 0.05).abs())
        .fold(0.0, f64::max)
}

#[test]
fn hairpin_tracks_bend_as_tightly_as_asked_and_generated_names_keep_their_tracks() {
    let started = Instant::now();
    for (k, seeds) in [(10.0, 0..30u64), (7.0, 0..10)] {
        for seed in seeds {
            let name = format!("hairpins:{seed}:{k}");
            let t = Track::load(Path::new(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(t.path(), Path::new(&name));
            let r = t.min_bend_radius_m();
            assert!(r >= 0.95 / k, "{name}: bend radius {r}");
            let kmax = max_curvature(&t);
            // Hairpins are drawn with radii from 1/k to 1/k + 4 cm.
            assert!(
                kmax >= 1.0 / (1.0 / k + 0.045) && kmax <= 1.05 * k,
                "{name}: tightest curvature {kmax}, asked for {k}"
            );
            let len = t.length_m();
            assert!(
                (LENGTH_RANGE_M.0..=LENGTH_RANGE_M.1).contains(&len),
                "{name}: {len} m"
            );
        }
    }
    // The default knob is the square's corners.
    let a = Track::load(Path::new("hairpins:3")).unwrap();
    let b = Track::load(Path::new("hairpins:3:10")).unwrap();
    assert_eq!(a.points(), b.points());
    assert!(started.elapsed() < Duration::from_secs(30));
    // `generated:N` is what it always was (docs and tests name these tracks): a checksum of
    // generated:101's waypoints, taken before hairpin tracks existed.
    let sum: f64 = generate(101)
        .unwrap()
        .points()
        .iter()
        .enumerate()
        .map(|(i, p)| (i as f64 + 1.0) * (p[0] + 2.0 * p[1]))
        .sum();
    assert_eq!(format!("{sum:.5}"), "-2059.12863");
    for bad in [
        "hairpins:x",
        "hairpins:1:20",
        "hairpins:1:2",
        "hairpins:1:k",
    ] {
        assert!(
            Track::load(Path::new(bad)).is_err(),
            "{bad} must be refused"
        );
    }
}
