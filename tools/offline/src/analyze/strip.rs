//! The model's figure strip on a track: the checkpoint run on a fresh drive of the track (the
//! reactive rule with exploration, at the model's frame skip), drawn by [`super::figure`].
//! `mta report` and the end of `mta up` put it in the run folder as `figure.png`.

use std::path::Path;

use super::figure::DEFAULT_FRAMES;
use anyhow::Context;
use mtanet_models::checkpoint;
use mtanet_models::sequences::push_window;

/// The figure strip of the checkpoint at `model` on a fresh drive of `track` (the reactive rule
/// with exploration, at the model's frame skip), written to `out`.
pub fn strip_on_track(model: &Path, track: &Path, out: &Path) -> anyhow::Result<()> {
    let ck = checkpoint::load(model).with_context(|| format!("loading {}", model.display()))?;
    let (_vs, net) = ck.build()?;
    let skip = ck.config.frame_skip.max(1) as usize;
    let len = DEFAULT_FRAMES.iter().max().copied().unwrap_or(130) + 1;
    let scene = mtanet_scenes::SceneConfig::default().with_track(track.to_path_buf());
    let mut world = mtanet_scenes::World::new(&scene)?;
    let mtanet_eval::drive::Recorded {
        frames, applied, ..
    } = mtanet_eval::drive::record_reactive(&mut world, (len + 1) * skip, 11)?;
    let (mut f, mut a) = (Vec::new(), Vec::new());
    push_window(&frames, &applied, skip - 1, skip, len, &mut f, &mut a);
    let images = tch::Tensor::from_slice(&f).view([len as i64, 8, 12]);
    let actions = tch::Tensor::from_slice(&a).view([len as i64, 2]);
    super::figure::figure_strip(&net, &images, &actions, &DEFAULT_FRAMES, out)?;
    Ok(())
}
