//! A random curvature profile: straights and arcs of constant curvature in a row, turning once
//! round in all. Only its straights' lengths are left free, for `trace::close` to shut the loop.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::{LENGTH_RANGE_M, Style};

/// One stretch of constant curvature (`k` = 1/radius, left positive; 0 on a straight).
#[derive(Debug, Clone, Copy)]
pub(super) struct Hold {
    pub k: f64,
    pub len: f64,
    /// For a straight: which of `Profile::straights` it is, and its share of that length (the
    /// starting straight is split in two halves, one at each end of the loop).
    pub straight: Option<(usize, f64)>,
}

#[derive(Debug, Clone)]
pub(super) struct Profile {
    pub holds: Vec<Hold>,
    /// Shortest length each straight may be given (room for its ramps; the start's is longer so
    /// the car starts on a straight).
    pub straight_min: Vec<f64>,
}

/// Straights between features, and the one the car starts in the middle of.
const STRAIGHT_MIN_M: f64 = 0.1;
const START_STRAIGHT_MIN_M: f64 = 0.4;
/// Features per track: a short loop holds few, a long one up to this many.
const MAX_FEATURES: usize = 8;
/// How far the left turns may be scaled to make the loop turn exactly once round.
const TURN_SCALE_RANGE: (f64, f64) = (0.6, 1.6);
/// No single arc turns more than this after scaling (a hairpin and a bit).
const MAX_ARC_RAD: f64 = 4.0 * PI / 3.0;

enum Item {
    /// `fixed`: a hairpin keeps its angle when the turns are scaled, or it would not be one.
    Arc {
        k: f64,
        angle: f64,
        fixed: bool,
    },
    Straight {
        min: f64,
    },
}

/// Draws one candidate; `None` when its features cannot be made to turn once round or do not
/// fit the drawn length (the caller then draws again from the same generator).
pub(super) fn draw(rng: &mut ChaCha8Rng, style: &Style) -> Option<Profile> {
    let target = rng.random_range(LENGTH_RANGE_M.0 + 0.3..LENGTH_RANGE_M.1 - 0.3);
    // Roughly one feature per metre: a long loop of few features is mostly straights.
    let n = rng.random_range((target / 1.3) as usize..=(target / 0.8) as usize);
    let n = n.clamp(3, MAX_FEATURES);
    let mut items = vec![Item::Straight {
        min: START_STRAIGHT_MIN_M,
    }];
    for i in 0..n {
        // Lean towards the turn still missing, so that few draws need scaling beyond reach.
        let missing = (TAU - net_turn(&items)) / (n - i) as f64;
        let p_left = (0.5 + 0.4 * missing / FRAC_PI_2).clamp(0.15, 0.85);
        feature(rng, &mut items, p_left, style);
        if i + 1 < n {
            items.push(Item::Straight {
                min: STRAIGHT_MIN_M,
            });
        }
    }
    let hairpins = items
        .iter()
        .filter(|it| matches!(it, Item::Arc { fixed: true, .. }))
        .count();
    if hairpins < style.min_hairpins {
        return None;
    }
    turn_once_round(&mut items)?;
    let mirror = if rng.random_bool(0.5) { -1.0 } else { 1.0 };
    build(rng, &items, target, mirror)
}

/// Appends one feature: a corner, a sweeping bend, an S-bend or a hairpin, drawn by the style's
/// shares (percent, cumulative) and its tightest radius.
fn feature(rng: &mut ChaCha8Rng, items: &mut Vec<Item>, p_left: f64, style: &Style) {
    let min_r = style.min_radius_m;
    let deg = |d: f64| d.to_radians();
    let s = if rng.random_bool(p_left) { 1.0 } else { -1.0 };
    let [corners, sweeping, s_bends] = style.shares;
    let pick = rng.random_range(0..100);
    match pick {
        p if p < corners => {
            let r = rng.random_range(min_r + 0.02..0.5);
            let a = rng.random_range(deg(40.0)..deg(135.0));
            items.push(Item::Arc {
                k: s / r,
                angle: a,
                fixed: false,
            });
        }
        p if p < sweeping => {
            let r = rng.random_range(0.5..1.2);
            let a = rng.random_range(deg(20.0)..deg(60.0));
            items.push(Item::Arc {
                k: s / r,
                angle: a,
                fixed: false,
            });
        }
        p if p < s_bends => {
            let (r1, r2) = (
                rng.random_range(min_r + 0.02..0.35),
                rng.random_range(min_r + 0.02..0.35),
            );
            let a1 = rng.random_range(deg(40.0)..deg(100.0));
            let a2 = a1 * rng.random_range(0.8..1.25);
            items.push(Item::Arc {
                k: s / r1,
                angle: a1,
                fixed: false,
            });
            items.push(Item::Straight {
                min: STRAIGHT_MIN_M / 2.0,
            });
            items.push(Item::Arc {
                k: -s / r2,
                angle: a2,
                fixed: false,
            });
        }
        _ => {
            let r = rng.random_range(min_r..style.hairpin_max_radius_m);
            let a = rng.random_range(deg(165.0)..deg(195.0));
            items.push(Item::Arc {
                k: s / r,
                angle: a,
                fixed: true,
            });
        }
    }
}

/// Left turns minus right turns so far, radians.
fn net_turn(items: &[Item]) -> f64 {
    items
        .iter()
        .map(|it| match it {
            Item::Arc { k, angle, .. } => k.signum() * angle,
            Item::Straight { .. } => 0.0,
        })
        .sum()
}

/// Scales the left turns by `f` and the right ones by `1/f` (hairpins aside) so that the loop
/// turns exactly once round, as a simple closed loop does: `f L - R / f = 2 pi - hairpins`.
/// `None` if that would distort the features too much.
fn turn_once_round(items: &mut [Item]) -> Option<()> {
    let (mut left, mut right, mut goal) = (0.0, 0.0, TAU);
    for it in items.iter() {
        match it {
            Item::Arc {
                k,
                angle,
                fixed: true,
            } => goal -= k.signum() * angle,
            Item::Arc { k, angle, .. } if *k > 0.0 => left += angle,
            Item::Arc { angle, .. } => right += angle,
            Item::Straight { .. } => {}
        }
    }
    let f = (goal + (goal * goal + 4.0 * left * right).sqrt()) / (2.0 * left);
    if !(TURN_SCALE_RANGE.0..=TURN_SCALE_RANGE.1).contains(&f) {
        return None;
    }
    for it in items.iter_mut() {
        if let Item::Arc {
            k,
            angle,
            fixed: false,
        } = it
        {
            *angle *= if *k > 0.0 { f } else { 1.0 / f };
            if *angle > MAX_ARC_RAD {
                return None;
            }
        }
    }
    Some(())
}

/// Lays the items out as holds, sharing out what the arcs leave of `target` among the straights
/// at random; the starting straight is split between the two ends of the loop.
fn build(rng: &mut ChaCha8Rng, items: &[Item], target: f64, mirror: f64) -> Option<Profile> {
    let arcs: f64 = items
        .iter()
        .map(|it| match it {
            Item::Arc { k, angle, .. } => angle / k.abs(),
            Item::Straight { .. } => 0.0,
        })
        .sum();
    let straight_min: Vec<f64> = items
        .iter()
        .filter_map(|it| match it {
            Item::Straight { min } => Some(*min),
            Item::Arc { .. } => None,
        })
        .collect();
    let spare = target - arcs - straight_min.iter().sum::<f64>();
    if spare <= 0.0 {
        return None;
    }
    let weights: Vec<f64> = straight_min
        .iter()
        .map(|_| rng.random_range(0.05..1.0))
        .collect();
    let total_w: f64 = weights.iter().sum();
    let mut holds = Vec::with_capacity(items.len() + 1);
    let mut v = 0;
    for it in items {
        match it {
            Item::Arc { k, angle, .. } => holds.push(Hold {
                k: mirror * k,
                len: angle / k.abs(),
                straight: None,
            }),
            Item::Straight { min } => {
                let len = min + spare * weights[v] / total_w;
                let share = if v == 0 { 0.5 } else { 1.0 };
                holds.push(Hold {
                    k: 0.0,
                    len: share * len,
                    straight: Some((v, share)),
                });
                v += 1;
            }
        }
    }
    holds.push(holds[0]);
    Some(Profile {
        holds,
        straight_min,
    })
}
