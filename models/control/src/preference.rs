//! The preferred observation, learnt from the car's own frames while only the middle line sensor
//! is on (the car centred on the line), and the line-position feature it is expressed in.
//!
//! A distance between raw pixels is flat once the line has moved by more than its width, and it
//! rates bare floor (line lost) better than a line seen off to the side. So observations are
//! compared through a feature of each image row: where the line is (soft centroid of "line-ness",
//! in half image widths from the centre) and how much of it is there. The preference is a
//! Gaussian over each row's line position (mean and variance over the centred frames), and a
//! row without the line costs as much as a line at the edge of the view; the cost therefore grows
//! monotonically with lateral offset and heading error until the line leaves the view.

use serde::{Deserialize, Serialize};

/// Image rows and columns (row-major frames of `height * width` grey values).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameShape {
    pub height: usize,
    pub width: usize,
}

impl FrameShape {
    /// The car's 8x12 middle camera.
    pub const CAR: FrameShape = FrameShape {
        height: mtanet_summaries::IMAGE_HEIGHT,
        width: mtanet_summaries::IMAGE_WIDTH,
    };

    pub fn pixels(self) -> usize {
        self.height * self.width
    }
}

/// How the line stands out from the floor: the floor's grey (the median pixel: most of the
/// view is floor) and the signed contrast floor - line, with the line's grey the 5th or 95th
/// percentile pixel, whichever lies farther from the floor (a dark or a bright line).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Contrast {
    pub floor: f32,
    pub amplitude: f32,
}

impl Contrast {
    /// From the pixels of many frames; `None` when the line does not stand out by
    /// `min_amplitude`.
    pub fn from_pixels(pixels: &mut [f32], min_amplitude: f32) -> Option<Self> {
        if pixels.is_empty() {
            return None;
        }
        pixels.sort_by(f32::total_cmp);
        let at = |q: f64| pixels[((pixels.len() - 1) as f64 * q).round() as usize];
        let floor = at(0.5);
        let (dark, bright) = (at(0.05), at(0.95));
        let line = if floor - dark >= bright - floor {
            dark
        } else {
            bright
        };
        let amplitude = floor - line;
        (amplitude.abs() >= min_amplitude).then_some(Self { floor, amplitude })
    }

    /// 0 for floor, 1 for line (clamped), for one pixel.
    fn lineness(&self, grey: f32) -> f32 {
        ((self.floor - grey) / self.amplitude).clamp(0.0, 1.0)
    }
}

/// Line-position feature of one frame, per row (row 0 = farthest ahead).
#[derive(Debug, Clone, PartialEq)]
pub struct LineFeature {
    /// Soft centroid of the line in half image widths from the centre (-1 left edge, +1 right
    /// edge); 0 where the row holds no line.
    pub position: Vec<f32>,
    /// Sum of line-ness over the row, in pixels (a line 3 pixels wide: ~3).
    pub mass: Vec<f32>,
}

/// Window (standard deviation, half widths) around the image centre in which the nearest row
/// looks for the line, and around the row below's position in which each farther row does.
const NEAR_WINDOW: f32 = 0.7;
const TRACK_WINDOW: f32 = 0.35;

impl LineFeature {
    /// Follows the line from the nearest row (the bottom) to the farthest: each row takes the
    /// soft centroid of line-ness under a Gaussian window around where the row below saw it, so
    /// a second piece of line in view (the far side of a hairpin or notch) does not pull the
    /// position between the two.
    pub fn of(frame: &[f32], shape: FrameShape, contrast: &Contrast) -> Self {
        let half = shape.width as f32 / 2.0;
        let mut position = vec![0.0; shape.height];
        let mut mass = vec![0.0; shape.height];
        let (mut centre, mut window) = (0.0f32, NEAR_WINDOW);
        for r in (0..shape.height).rev() {
            let row = &frame[r * shape.width..(r + 1) * shape.width];
            let (mut m, mut moment) = (0.0f32, 0.0f32);
            for (c, &g) in row.iter().enumerate() {
                let x = (c as f32 + 0.5 - half) / half;
                let d =
                    contrast.lineness(g) * (-(x - centre).powi(2) / (2.0 * window * window)).exp();
                m += d;
                moment += d * x;
            }
            if m > 0.25 {
                position[r] = moment / m;
                centre = position[r];
                window = TRACK_WINDOW;
            } else {
                // No line here: farther rows look around the last place it was seen, more widely.
                position[r] = 0.0;
                window = (window * 1.5).min(NEAR_WINDOW);
            }
            mass[r] = m;
        }
        Self { position, mass }
    }
}

/// The learnt preference: a Gaussian over the rows' line positions (mean and full covariance:
/// in bends the far rows move together with the curvature, which centred frames vary in freely,
/// while offset and heading, which they hold tight, get a high precision), and the usual line
/// mass per row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PreferredLine {
    pub shape: FrameShape,
    pub contrast: Contrast,
    pub position_mean: Vec<f32>,
    /// Row-major `height x height` covariance of the rows' positions.
    pub position_cov: Vec<f32>,
    pub mass_mean: Vec<f32>,
    /// Centred frames it was learnt from.
    pub frames: usize,
}

/// Collects centred frames (a bounded ring of the newest) and turns them into a
/// [`PreferredLine`]. A frame is centred when only the middle line sensor has been on for
/// `steady` control steps in a row: the car sits on the line *and* runs along it. Without the
/// steadiness, frames from bends (where the rule keeps correcting) pull the preferred view to
/// one side and the car holds itself off the line on straights.
#[derive(Debug, Clone)]
pub struct PreferenceLearner {
    shape: FrameShape,
    capacity: usize,
    steady: u32,
    run: u32,
    frames: std::collections::VecDeque<Vec<f32>>,
    seen: u64,
    mirror: bool,
}

impl PreferenceLearner {
    pub fn new(shape: FrameShape, capacity: usize, steady: u32) -> Self {
        Self {
            shape,
            capacity: capacity.max(1),
            steady: steady.max(1),
            run: 0,
            frames: Default::default(),
            seen: 0,
            mirror: true,
        }
    }

    /// Learn from the frames alone, not also from their mirror images.
    pub fn without_mirror(mut self) -> Self {
        self.mirror = false;
        self
    }

    /// Offers a frame with the line sensors' reading; only centred frames (only the middle
    /// sensor on, steadily) are kept. Returns whether it was kept.
    pub fn observe(&mut self, frame: &[f32], line_sensors: [bool; 3]) -> bool {
        self.run = if line_sensors == [false, true, false] {
            self.run + 1
        } else {
            0
        };
        if self.run < self.steady || frame.len() != self.shape.pixels() {
            return false;
        }
        if self.frames.len() == self.capacity {
            self.frames.pop_front();
        }
        self.frames.push_back(frame.to_vec());
        self.seen += 1;
        true
    }

    /// Centred frames offered so far (not only those still kept).
    pub fn seen(&self) -> u64 {
        self.seen
    }

    /// The preference from the kept frames, once there are `min_frames` of them and the line
    /// stands out from the floor.
    pub fn preferred(&self, min_frames: usize) -> Option<PreferredLine> {
        let n = self.frames.len();
        if n < min_frames.max(2) {
            return None;
        }
        let mut pixels: Vec<f32> = self.frames.iter().flatten().copied().collect();
        let contrast = Contrast::from_pixels(&mut pixels, 0.05)?;
        let rows = self.shape.height;
        // Rows without the line (< half a pixel of it) take no part in the position statistics.
        let feats: Vec<LineFeature> = self
            .frames
            .iter()
            .map(|f| LineFeature::of(f, self.shape, &contrast))
            .collect();
        let whole: Vec<&LineFeature> = feats
            .iter()
            .filter(|f| f.mass.iter().all(|m| *m > 0.5))
            .collect();
        if whole.len() < min_frames.max(2) / 2 {
            return None;
        }
        // The car and its camera are symmetric: a frame and its mirror image (positions
        // negated) are equally centred, so the preference is learnt from both and does not
        // lean towards the side the learning track happens to bend to.
        let signs: &[f64] = if self.mirror { &[1.0, -1.0] } else { &[1.0] };
        let k = (whole.len() * signs.len()) as f64;
        let mut position_mean = vec![0.0f64; rows];
        for f in &whole {
            for &sg in signs {
                for r in 0..rows {
                    position_mean[r] += sg * f64::from(f.position[r]) / k;
                }
            }
        }
        let mut cov = vec![0.0f64; rows * rows];
        for f in &whole {
            for &sg in signs {
                for i in 0..rows {
                    let di = sg * f64::from(f.position[i]) - position_mean[i];
                    for j in 0..rows {
                        cov[i * rows + j] +=
                            di * (sg * f64::from(f.position[j]) - position_mean[j]) / k;
                    }
                }
            }
        }
        let mut mass_mean = vec![0.0f64; rows];
        for f in &feats {
            for r in 0..rows {
                mass_mean[r] += f64::from(f.mass[r]) / n as f64;
            }
        }
        Some(PreferredLine {
            shape: self.shape,
            contrast,
            position_mean: position_mean.iter().map(|v| *v as f32).collect(),
            position_cov: cov.iter().map(|v| *v as f32).collect(),
            mass_mean: mass_mean.iter().map(|v| *v as f32).collect(),
            frames: n,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A synthetic 8x12 frame: floor 0.85, a dark line 4 pixels wide whose centre column is
    /// `centre + slope * (7 - row)` (slope: the line leans as with a heading error).
    pub(crate) fn line_frame(centre: f32, slope: f32) -> Vec<f32> {
        let s = FrameShape::CAR;
        let mut f = vec![0.85; s.pixels()];
        for r in 0..s.height {
            let c0 = centre + slope * (7 - r) as f32;
            for c in 0..s.width {
                if (c as f32 + 0.5 - c0).abs() <= 1.5 {
                    f[r * s.width + c] = 0.1;
                }
            }
        }
        f
    }

    pub(crate) fn learnt() -> PreferredLine {
        let mut p = PreferenceLearner::new(FrameShape::CAR, 100, 1);
        for k in 0..40 {
            let wiggle = [-0.5, 0.0, 0.5][k % 3];
            p.observe(&line_frame(6.0 + wiggle, 0.0), [false, true, false]);
        }
        p.preferred(10).unwrap()
    }

    #[test]
    fn only_centred_frames_teach_the_preference() {
        let mut p = PreferenceLearner::new(FrameShape::CAR, 4, 3);
        assert!(!p.observe(&line_frame(2.0, 0.0), [true, true, false]));
        assert!(p.preferred(1).is_none());
        for k in 0..8 {
            let kept = p.observe(&line_frame(6.0, 0.0), [false, true, false]);
            assert_eq!(kept, k >= 2, "kept only after 3 centred steps in a row");
        }
        assert!(!p.observe(&line_frame(6.0, 0.0), [false, true, true]));
        assert!(
            !p.observe(&line_frame(6.0, 0.0), [false, true, false]),
            "steadiness restarts"
        );
        assert_eq!(p.seen(), 6);
        let pref = p.preferred(2).unwrap();
        assert_eq!(pref.frames, 4, "a bounded ring of the newest frames");
        assert!((pref.contrast.floor - 0.85).abs() < 1e-6);
        assert!((pref.contrast.amplitude - 0.75).abs() < 1e-6);
        for r in 0..8 {
            assert!(pref.position_mean[r].abs() < 1e-6, "centred line: {pref:?}");
            // 4 pixels of line, seen through the tracking window.
            assert!((3.0..=4.0).contains(&pref.mass_mean[r]), "{pref:?}");
        }
    }

    #[test]
    fn bare_floor_teaches_nothing() {
        let mut p = PreferenceLearner::new(FrameShape::CAR, 10, 1);
        for _ in 0..5 {
            p.observe(&[0.85; 96], [false, true, false]);
        }
        assert!(p.preferred(2).is_none());
    }

    #[test]
    fn the_feature_follows_the_line() {
        let pref = learnt();
        let left = LineFeature::of(&line_frame(3.0, 0.0), FrameShape::CAR, &pref.contrast);
        assert!((left.position[4] + 0.5).abs() < 0.05, "{left:?}");
        let bare = LineFeature::of(&[0.85; 96], FrameShape::CAR, &pref.contrast);
        assert!(bare.mass.iter().all(|m| *m == 0.0));
    }

    #[test]
    fn a_second_piece_of_line_far_ahead_does_not_pull_the_position() {
        let pref = learnt();
        // The line runs straight up the middle; the far three rows also show another piece of
        // line at the left edge (the far side of a notch).
        let mut f = line_frame(6.0, 0.0);
        for r in 0..3 {
            f[r * 12] = 0.1;
            f[r * 12 + 1] = 0.1;
        }
        let feat = LineFeature::of(&f, FrameShape::CAR, &pref.contrast);
        for r in 0..8 {
            assert!(
                feat.position[r].abs() < 0.05,
                "row {r} pulled aside: {feat:?}"
            );
        }
    }
}
