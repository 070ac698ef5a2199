//! Layer timescales on held-out sequences, and the figure strip.

use mtanet_models::analysis::{LayerTimescales, figure_strip, timescales};
use mtanet_models::figure::FigureError;
use mtanet_models::synth::{SynthConfig, generate};
use mtanet_models::{ModelConfig, MtaPredNet};
use tch::{Device, nn::VarStore};

/// libtorch has one global generator: a test that builds a model while another has just seeded
/// it would change the other's weights (the timescale test failed that way in a clean clone).
static TORCH_RNG: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn small(tau: Vec<f64>) -> ModelConfig {
    ModelConfig {
        channels: vec![4, 6, 8],
        a_channels: vec![1, 4, 6],
        tau,
        ..Default::default()
    }
}

#[test]
fn timescales_rise_with_tau_for_the_same_weights() {
    tch::set_num_threads(1);
    let _rng = TORCH_RNG.lock().unwrap_or_else(|p| p.into_inner());
    tch::manual_seed(3);
    let fast_vs = VarStore::new(Device::Cpu);
    let fast = MtaPredNet::new(&fast_vs.root(), &small(vec![1.0, 1.0, 1.0]));
    let mut slow_vs = VarStore::new(Device::Cpu);
    let slow = MtaPredNet::new(&slow_vs.root(), &small(vec![1.0, 1.0, 4.0]));
    slow_vs.copy(&fast_vs).unwrap();
    let data = generate(&SynthConfig {
        sequences: 8,
        steps: 60,
        ..Default::default()
    })
    .unwrap();
    let f = timescales(&fast, &data, 8, 5).unwrap();
    let s = timescales(&slow, &data, 8, 5).unwrap();
    let steps = |ls: &[LayerTimescales]| -> Vec<_> {
        ls.iter().map(|l| (l.r.steps, l.units_steps())).collect()
    };
    eprintln!(
        "(R, units) steps: tau 1 {:?}, tau 4 {:?}",
        steps(&f),
        steps(&s)
    );
    assert_eq!((f.len(), f[2].units.len()), (3, 2));
    // The units' own states integrate with tau: the top layer's must forget clearly slower,
    // the layers below (same taus, same weights) about as fast.
    let (fu, su) = (f[2].units_steps().unwrap(), s[2].units_steps().unwrap());
    assert!(su > 1.5 * fu, "tau 4 units {su} vs tau 1 {fu} steps");
    // R also jumps with the action weights; it must still slow down.
    let (fr, sr) = (f[2].r.steps.unwrap(), s[2].r.steps.unwrap());
    assert!(sr > fr, "tau 4 R {sr} vs tau 1 {fr} steps");
    assert!(f.iter().chain(&s).all(|l| l.r.interval.is_some()));
    let short = generate(&SynthConfig {
        sequences: 2,
        steps: 6,
        ..Default::default()
    })
    .unwrap();
    assert!(timescales(&fast, &short, 2, 5).is_err());
}

#[test]
fn figure_strip_draws_the_frames_that_exist() {
    tch::set_num_threads(1);
    let vs = VarStore::new(Device::Cpu);
    let m = {
        let _rng = TORCH_RNG.lock().unwrap_or_else(|p| p.into_inner());
        MtaPredNet::new(&vs.root(), &small(vec![1.0, 1.3, 2.0]))
    };
    let data = generate(&SynthConfig {
        sequences: 1,
        steps: 60,
        ..Default::default()
    })
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("strip.png");
    let info = figure_strip(
        &m,
        &data.images.get(0),
        &data.actions.get(0),
        &[1, 10, 50, 100, 130],
        &path,
    )
    .unwrap();
    assert_eq!(info.frames, [1, 10, 50]);
    assert_eq!(info.frames_missing, [100, 130]);
    assert_eq!(
        info.rows.len(),
        5,
        "original, predicted, one row per layer: {:?}",
        info.rows
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let reader = decoder.read_info().unwrap();
    let (w, h) = (reader.info().width, reader.info().height);
    // 3 columns of 96 px and 5 rows of 64 px, 3 px gaps; a left margin for the row labels
    // ("predicted" at 16 px) and a top one for the frame numbers.
    let (grid_w, top) = (3 * 96 + 4 * 3, 16 + 3 * 3);
    let left = w - grid_w;
    assert!(
        (50..200).contains(&left),
        "a margin for the row labels: {left} px"
    );
    assert_eq!(h, top + 5 * 64 + 6 * 3);
    let mut px = vec![0u8; reader.output_buffer_size().unwrap()];
    let mut reader = reader;
    reader.next_frame(&mut px).unwrap();
    assert_eq!(reader.info().color_type, png::ColorType::Rgb);
    // Text is antialiased: its strokes are dark rather than exactly black.
    let dark_in = |x0: u32, x1: u32, y0: u32, y1: u32| {
        (y0..y1).any(|y| (x0..x1).any(|x| px[3 * (y * w + x) as usize] < 80))
    };
    assert!(
        dark_in(0, left, top, h),
        "row labels drawn in the left margin"
    );
    assert!(
        dark_in(left, w, 0, top),
        "frame labels drawn in the top margin"
    );
    let err =
        figure_strip(&m, &data.images.get(0), &data.actions.get(0), &[200], &path).unwrap_err();
    assert!(
        matches!(err, FigureError::NoFrames { steps: 60, .. }),
        "{err}"
    );
}
