//! Slowness index and figure strip.

use mtanet_models::analysis::{figure_strip, slowness};
use mtanet_models::figure::FigureError;
use mtanet_models::synth::{SynthConfig, generate};
use mtanet_models::{ModelConfig, MtaPredNet};
use tch::{Device, nn::VarStore};

/// libtorch has one global generator: a test that builds a model while another has just seeded
/// it would change the other's weights (the slowness test failed that way in a clean clone).
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
fn slowness_rises_with_tau_for_the_same_weights() {
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
    let f = slowness(&fast, &data, 8, 5).unwrap();
    let s = slowness(&slow, &data, 8, 5).unwrap();
    eprintln!("tau 1: {f:?}\ntau 4: {s:?}");
    assert_eq!(f.len(), 3);
    // The units' own states integrate with tau: their step-to-step change must shrink clearly.
    assert!(
        s[2].units.delta_ratio < 0.7 * f[2].units.delta_ratio,
        "tau 4 units not slower by delta ratio"
    );
    assert!(
        s[2].units.pc_autocorr_time > f[2].units.pc_autocorr_time,
        "tau 4 units not slower by PC time"
    );
    // R also jumps with the action weights; its leading components must still slow down.
    assert!(
        s[2].r.pc_autocorr_time > f[2].r.pc_autocorr_time,
        "tau 4 R not slower by PC time"
    );
    assert!(
        f.iter()
            .chain(&s)
            .all(|l| l.r.explained > 0.0 && l.units.components >= 1)
    );
    assert!(
        slowness(
            &fast,
            &generate(&SynthConfig {
                sequences: 2,
                steps: 6,
                ..Default::default()
            })
            .unwrap(),
            2,
            5
        )
        .is_err()
    );
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
