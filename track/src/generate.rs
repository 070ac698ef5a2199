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

/// The track of seed `seed`.
pub fn generate(seed: u64) -> Result<Track, TrackError> {
    generate_counting(seed).map(|(t, _)| t)
}

/// The track of seed `seed` and how many candidates were drawn to find it (1 = the first).
pub fn generate_counting(seed: u64) -> Result<(Track, u32), TrackError> {
    let name = format!("{GENERATED_PREFIX}{seed}");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for candidate in 1..=MAX_CANDIDATES {
        let Some(mut prof) = profile::draw(&mut rng) else {
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

/// The seed if `path` names a generated track (`generated:N`), `None` for a file.
pub(crate) fn seed_of(path: &Path) -> Result<Option<u64>, TrackError> {
    let Some(seed) = path.to_str().and_then(|s| s.strip_prefix(GENERATED_PREFIX)) else {
        return Ok(None);
    };
    seed.parse()
        .map(Some)
        .map_err(|_| TrackError::GeneratedName {
            path: path.to_path_buf(),
        })
}
