//! Training windows at a frame skip, cut from a run of consecutive control steps.
//!
//! Convention: `frames[i]` is the frame of control step i and `applied[i]` the command applied
//! during the step that led to it (from frame i - 1 to frame i). A window of `len` model steps
//! starting at control step `start` takes frames `start, start + skip, ...`; the action of model
//! step j is the mean of the `skip` commands that led from its previous frame to its frame, so a
//! command held over a segment (as the planner holds them) is exactly the model's action.

/// Control steps a window needs: `skip - 1` before its first frame (its action) and
/// `(len - 1) * skip` after it.
pub fn window_span(skip: usize, len: usize) -> usize {
    skip.max(1) - 1 + (len.max(1) - 1) * skip.max(1) + 1
}

/// Appends one window's frames (`len` frames) and actions (`len` x A) to `out_frames` and
/// `out_actions`. `start` must leave `skip - 1` steps before it and `(len - 1) * skip` after it.
pub fn push_window<const P: usize, const A: usize>(
    frames: &[[f32; P]],
    applied: &[[f32; A]],
    start: usize,
    skip: usize,
    len: usize,
    out_frames: &mut Vec<f32>,
    out_actions: &mut Vec<f32>,
) {
    let skip = skip.max(1);
    for j in 0..len {
        let i = start + j * skip;
        out_frames.extend_from_slice(&frames[i]);
        let cmds = &applied[i + 1 - skip..=i];
        for a in 0..A {
            out_actions.push(cmds.iter().map(|c| c[a]).sum::<f32>() / skip as f32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_skip_frames_and_average_the_commands_between() {
        let frames: Vec<[f32; 1]> = (0..20).map(|i| [i as f32]).collect();
        let applied: Vec<[f32; 2]> = (0..20).map(|i| [i as f32, 1.0]).collect();
        assert_eq!(window_span(3, 4), 2 + 9 + 1);
        let (mut f, mut a) = (Vec::new(), Vec::new());
        push_window(&frames, &applied, 2, 3, 4, &mut f, &mut a);
        assert_eq!(f, vec![2.0, 5.0, 8.0, 11.0]);
        // Model step 1 (frame 5) was reached by the commands of steps 3, 4, 5.
        assert_eq!(&a[2..4], &[4.0, 1.0]);
        assert_eq!(&a[0..2], &[1.0, 1.0], "step 0: the commands of steps 0..=2");
        let (mut f1, mut a1) = (Vec::new(), Vec::new());
        push_window(&frames, &applied, 0, 1, 3, &mut f1, &mut a1);
        assert_eq!(f1, vec![0.0, 1.0, 2.0]);
        assert_eq!(a1, vec![0.0, 1.0, 1.0, 1.0, 2.0, 1.0]);
    }
}
