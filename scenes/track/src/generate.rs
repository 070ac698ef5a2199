//! Tracks nobody tuned on: `generated:N` names a closed track drawn from seed `N`.
//!
//! A candidate is a random row of features (corners, sweeping bends, S-bends, hairpins) joined
//! by straights, its bends scaled so that it turns exactly once round (`profile.rs`); curvature
//! ramps between the pieces, and the straights' lengths are solved so the loop closes
//! (`trace.rs`). A candidate that fails the checks every loaded track passes (crossings,
//! clearance, bend radius) or the length range is dropped and the next one drawn from the same
//! generator, so a seed always names the same track.

mod profile;
mod trace;

use std::path::Path;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::{DEFAULT_LINE_WIDTH_M, Track, TrackError};

/// How a generated track is named wherever a track file is expected.
pub const GENERATED_PREFIX: &str = "generated:";
/// A generated track with hairpins: `hairpins:N` (bends down to `HAIRPIN_DEFAULT_CURVATURE`),
/// or `hairpins:N:K` with its tightest curvature K in 1/m.
pub const HAIRPINS_PREFIX: &str = "hairpins:";
/// The tightest curvature of `hairpins:N` (1/m): the shipped square's corners.
pub const HAIRPIN_DEFAULT_CURVATURE: f64 = 10.0;
/// The gentlest tightest curvature `hairpins:N:K` takes (1/m).
const HAIRPIN_MIN_CURVATURE: f64 = 5.0;
/// Tightest radius the generator draws: well above `MIN_BEND_RADIUS_M` (0.07 m) and above the
/// shipped square's 0.1 m corners, so the teacher takes every bend without being tuned for it.
pub const GENERATED_MIN_RADIUS_M: f64 = 0.13;
/// Length of a generated track, metres.
pub const LENGTH_RANGE_M: (f64, f64) = (3.0, 8.0);
/// A seed that no candidate among this many passes is a bug in the generator, not bad luck.
const MAX_CANDIDATES: u32 = 2000;
/// Waypoints are rounded to the 10 um (5 decimals) a track file holds, so `generated:N` and the
/// file written for it are the same track, bit for bit. Dividing by an exact power of ten gives
/// the same double as parsing the decimal text.
const PER_M: f64 = 1e5;

/// What kind of track the generator draws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Style {
    /// Tightest radius of any bend, metres.
    pub min_radius_m: f64,
    /// Hairpins are drawn with radii in `[min_radius_m, hairpin_max_radius_m)`.
    pub hairpin_max_radius_m: f64,
    /// Cumulative shares (percent) of corners, sweeping bends and S-bends; hairpins the rest.
    pub shares: [u32; 3],
    /// A candidate with fewer hairpins is drawn again.
    pub min_hairpins: usize,
}

impl Style {
    /// `generated:N`: every feature alike, as the generator always drew them (names in docs
    /// and tests keep their tracks).
    pub const MIXED: Style = Style {
        min_radius_m: GENERATED_MIN_RADIUS_M,
        hairpin_max_radius_m: 0.2,
        shares: [35, 45, 75],
        min_hairpins: 0,
    };

    /// `hairpins:N:K`: at least two hairpins, half the features hairpins, bends down to a
    /// radius of 1/K.
    pub fn hairpins(curvature: f64) -> Style {
        let r = 1.0 / curvature;
        Style {
            min_radius_m: r,
            hairpin_max_radius_m: r + 0.04,
            shares: [20, 25, 50],
            min_hairpins: 2,
        }
    }
}

/// The track of seed `seed`.
pub fn generate(seed: u64) -> Result<Track, TrackError> {
    generate_counting(seed).map(|(t, _)| t)
}

/// The track of seed `seed` and how many candidates were drawn to find it (1 = the first).
pub fn generate_counting(seed: u64) -> Result<(Track, u32), TrackError> {
    generate_styled(&format!("{GENERATED_PREFIX}{seed}"), seed, &Style::MIXED)
}

/// A track of seed `seed` in `style`, named `name`, and the candidates drawn to find it.
pub(crate) fn generate_styled(
    name: &str,
    seed: u64,
    style: &Style,
) -> Result<(Track, u32), TrackError> {
    let name = name.to_string();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for candidate in 1..=MAX_CANDIDATES {
        let Some(mut prof) = profile::draw(&mut rng, style) else {
            continue;
        };
        let Some(points) = trace::close(&mut prof) else {
            continue;
        };
        let points = points
            .into_iter()
            .map(|p| p.map(|c| (c * PER_M).round() / PER_M))
            .collect();
        let Ok(track) = Track::from_points(&name, points, DEFAULT_LINE_WIDTH_M) else {
            continue;
        };
        if (LENGTH_RANGE_M.0..=LENGTH_RANGE_M.1).contains(&track.length_m()) {
            return Ok((track, candidate));
        }
    }
    Err(TrackError::GeneratorGaveUp {
        path: name.into(),
        candidates: MAX_CANDIDATES,
    })
}

/// The seed and style if `path` names a generated track (`generated:N`, `hairpins:N`,
/// `hairpins:N:K`), `None` for a file.
pub(crate) fn spec_of(path: &Path) -> Result<Option<(u64, Style)>, TrackError> {
    let bad = || TrackError::GeneratedName {
        path: path.to_path_buf(),
    };
    let Some(s) = path.to_str() else {
        return Ok(None);
    };
    if let Some(seed) = s.strip_prefix(GENERATED_PREFIX) {
        return seed
            .parse()
            .map(|n| Some((n, Style::MIXED)))
            .map_err(|_| bad());
    }
    let Some(rest) = s.strip_prefix(HAIRPINS_PREFIX) else {
        return Ok(None);
    };
    let (seed, k) = match rest.split_once(':') {
        Some((seed, k)) => (seed, k.parse::<f64>().map_err(|_| bad())?),
        None => (rest, HAIRPIN_DEFAULT_CURVATURE),
    };
    // From a hairpin of 0.2 m radius to the tightest bend the track checks allow.
    let (k_min, k_max) = (HAIRPIN_MIN_CURVATURE, 1.0 / crate::check::MIN_BEND_RADIUS_M);
    if !(k_min..=k_max).contains(&k) {
        return Err(TrackError::HairpinCurvature {
            path: path.to_path_buf(),
            curvature: k,
            min: k_min,
            max: k_max,
        });
    }
    let seed = seed.parse().map_err(|_| bad())?;
    Ok(Some((seed, Style::hairpins(k))))
}
