//! Regenerates a run's analysis from a checkpoint, without training:
//! `cargo run --release -p mtanet-models --example figures -- CHECKPOINT DATA.npz[,MORE.npz] OUT_DIR [FRAMES] [SEQUENCE]`
//! writes OUT_DIR/figure.png and OUT_DIR/analysis.json (held-out metrics, slowness per layer,
//! figure layout). FRAMES is comma-separated (default 1,10,50,100,130).

use mtanet_models::analysis::analyse;
use mtanet_models::checkpoint;
use mtanet_models::data::Dataset;
use mtanet_models::figure::DEFAULT_FRAMES;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    tch::set_num_threads(1);
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [ck, data, out, rest @ ..] = args.as_slice() else {
        return Err(
            "usage: figures CHECKPOINT DATA.npz[,MORE.npz] OUT_DIR [FRAMES] [SEQUENCE]".into(),
        );
    };
    let frames: Vec<usize> = match rest.first() {
        Some(f) => f.split(',').map(str::parse).collect::<Result<_, _>>()?,
        None => DEFAULT_FRAMES.to_vec(),
    };
    let sequence: i64 = rest.get(1).map(|s| s.parse()).transpose()?.unwrap_or(0);
    let sets = data
        .split(',')
        .map(Dataset::load_npz)
        .collect::<Result<Vec<_>, _>>()?;
    let data = Dataset::concat(&sets)?;
    let ck = checkpoint::load(ck)?;
    let (_vs, model) = ck.build()?;
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out)?;
    let report = analyse(&model, &data, &frames, sequence, &out.join("figure.png"), 0)?;
    for note in &report.notes {
        eprintln!("note: {note}");
    }
    std::fs::write(
        out.join("analysis.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    println!(
        "step {}: mse {:.6} copy-last {:.6} ({:.3}x), shuffled actions {:?}, top slower than bottom: {:?}",
        ck.meta.step,
        report.eval.mse,
        report.eval.copy_last_mse,
        report.eval.mse_over_copy_last,
        report.eval.mse_shuffled_actions,
        report.top_slower_than_bottom
    );
    Ok(())
}
