//! The paper's figure strip: the frames that exist, with row and frame labels.

use mtanet_models::synth::{SynthConfig, generate};
use mtanet_models::{ModelConfig, MtaPredNet};
use mtanet_offline::analyze::figure::{FigureError, figure_strip};
use tch::{Device, nn::VarStore};

#[test]
fn figure_strip_draws_the_frames_that_exist() {
    tch::set_num_threads(1);
    let vs = VarStore::new(Device::Cpu);
    let m = MtaPredNet::new(&vs.root(), &ModelConfig::small(&[1.0, 1.3, 2.0]));
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
