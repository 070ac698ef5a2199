use super::*;
use ndarray::IxDyn;
use ndarray_npy::NpzWriter;

fn tiny() -> Dataset {
    let images = Tensor::rand([3, 4, 8, 12], (Kind::Float, tch::Device::Cpu));
    let actions = Tensor::randn([3, 4, 2], (Kind::Float, tch::Device::Cpu));
    Dataset::new(images, actions).unwrap()
}

#[test]
fn npz_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.npz");
    let d = tiny();
    d.save_npz(&path).unwrap();
    let back = Dataset::load_npz(&path).unwrap();
    assert!(back.images.equal(&d.images) && back.actions.equal(&d.actions));
    assert_eq!(
        (
            back.len(),
            back.steps(),
            back.image_size(),
            back.action_dim()
        ),
        (3, 4, (8, 12), 2)
    );
}

#[test]
fn reads_numpy_savez_compressed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zipped.npz");
    let d = tiny();
    let to_nd = |t: &Tensor| {
        let shape: Vec<usize> = t.size().iter().map(|&s| s as usize).collect();
        ArrayD::from_shape_vec(
            IxDyn(&shape),
            Vec::<f32>::try_from(t.flatten(0, -1)).unwrap(),
        )
        .unwrap()
    };
    let mut w = NpzWriter::new_compressed(File::create(&path).unwrap());
    w.add_array("images", &to_nd(&d.images)).unwrap();
    w.add_array("actions", &to_nd(&d.actions)).unwrap();
    w.finish().unwrap();
    let back = Dataset::load_npz(&path).unwrap();
    assert!(back.images.equal(&d.images) && back.actions.equal(&d.actions));
}

#[test]
fn bad_files_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.npz");
    tiny().save_npz(&path).unwrap();
    // Truncated archive.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.npz");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = Dataset::load_npz(&cut).unwrap_err().to_string();
    assert!(e.contains("cut.npz"), "{e}");
    // Missing array.
    let only = dir.path().join("only.npz");
    let mut w = NpzWriter::new(File::create(&only).unwrap());
    w.add_array("images", &ArrayD::<f32>::zeros(IxDyn(&[1, 2, 8, 12])))
        .unwrap();
    w.finish().unwrap();
    let e = Dataset::load_npz(&only).unwrap_err();
    assert!(
        matches!(
            e,
            DataError::Missing {
                array: "actions",
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string().contains("images"),
        "lists what is present: {e}"
    );
    // Out of range images.
    let big = Tensor::ones([1, 2, 8, 12], (Kind::Float, tch::Device::Cpu)) * 255.0;
    let e = Dataset::new(
        big,
        Tensor::zeros([1, 2, 2], (Kind::Float, tch::Device::Cpu)),
    )
    .unwrap_err();
    assert!(e.to_string().contains("[0, 1]"), "{e}");
    // Mismatched N.
    let e = Dataset::new(
        tiny().images,
        Tensor::zeros([2, 4, 2], (Kind::Float, tch::Device::Cpu)),
    )
    .unwrap_err();
    assert!(matches!(e, DataError::Shape { .. }), "{e}");
}

#[test]
fn shuffled_actions_is_a_derangement() {
    let n = 7;
    let actions = Tensor::arange(n, (Kind::Float, tch::Device::Cpu))
        .view([n, 1, 1])
        .expand([n, 3, 2], false);
    let d = Dataset::new(
        Tensor::zeros([n, 3, 8, 12], (Kind::Float, tch::Device::Cpu)),
        actions,
    )
    .unwrap();
    let s = d.shuffled_actions(5);
    let firsts = Vec::<f32>::try_from(s.select(1, 0).select(1, 0)).unwrap();
    let mut sorted = firsts.clone();
    sorted.sort_by(f32::total_cmp);
    assert_eq!(
        sorted,
        (0..n).map(|i| i as f32).collect::<Vec<_>>(),
        "a permutation"
    );
    assert!(
        firsts.iter().enumerate().all(|(i, v)| *v != i as f32),
        "no fixed point: {firsts:?}"
    );
    let (train, eval) = d.split(0.2, 1);
    assert_eq!((train.len(), eval.len()), (5, 2));
    let both = Dataset::concat(&[train, eval]).unwrap();
    assert_eq!(both.len(), 7);
    let longer = Dataset::new(
        Tensor::zeros([1, 4, 8, 12], (Kind::Float, tch::Device::Cpu)),
        Tensor::zeros([1, 4, 2], (Kind::Float, tch::Device::Cpu)),
    )
    .unwrap();
    assert!(
        Dataset::concat(&[both, longer]).is_err(),
        "T 3 and T 4 do not concatenate"
    );
}
