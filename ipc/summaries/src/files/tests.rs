use super::*;

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("report.json");
    write_json(&path, &serde_json::json!({"v": 1})).unwrap();
    let failed = write_atomic(&path, |w| {
        w.write_all(b"{\"v\": 2, half").unwrap();
        Err(FileError::Encode {
            path: path.clone(),
            detail: "the writer gave up".into(),
        })
    });
    assert!(failed.is_err());
    let kept: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(kept["v"], 1);
    assert_eq!(entries(dir.path()), ["report.json"]);
}

#[test]
fn writes_create_the_directory_and_replace_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a/b/weights.bin");
    write_bytes(&path, b"one").unwrap();
    write_bytes(&path, b"two").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"two");
    assert_eq!(entries(&dir.path().join("a/b")), ["weights.bin"]);
}

#[test]
fn npz_arrays_read_back_with_their_shapes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.npz");
    let images: Vec<f32> = (0..24).map(|i| i as f32).collect();
    let actions = [0.5f32, -0.5, 1.0, 2.0];
    write_npz(
        &path,
        &[
            NpzArray {
                name: "images",
                shape: vec![1, 2, 3, 4],
                data: &images,
            },
            NpzArray {
                name: "actions",
                shape: vec![1, 2, 2],
                data: &actions,
            },
        ],
    )
    .unwrap();
    let mut npz = ndarray_npy::NpzReader::new(std::fs::File::open(&path).unwrap()).unwrap();
    let got: ndarray::ArrayD<f32> = npz.by_name("images").unwrap();
    assert_eq!(got.shape(), [1, 2, 3, 4]);
    assert_eq!(got.as_slice().unwrap(), images.as_slice());
    let got: ndarray::ArrayD<f32> = npz.by_name("actions").unwrap();
    assert_eq!(got.shape(), [1, 2, 2]);
    assert_eq!(got.as_slice().unwrap(), actions);
}

#[test]
fn a_shape_that_does_not_fit_the_data_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.npz");
    let e = write_npz(
        &path,
        &[NpzArray {
            name: "actions",
            shape: vec![3, 2],
            data: &[1.0; 5],
        }],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("bad.npz") && e.contains("actions"), "{e}");
    assert!(!path.exists());
}

#[test]
fn toml_errors_name_the_file_and_the_key() {
    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct Cfg {
        seed: u64,
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.toml");
    std::fs::write(&path, "seed = \"three\"\n").unwrap();
    let e = read_toml::<Cfg>(&path).unwrap_err().to_string();
    assert!(e.contains("run.toml") && e.contains("seed"), "{e}");
    let missing = read_table(&dir.path().join("none.toml"))
        .unwrap_err()
        .to_string();
    assert!(missing.contains("none.toml"), "{missing}");
}

#[test]
fn json_reads_back_typed_and_names_the_file_it_cannot_read() {
    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Summary {
        steps: u64,
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("summary.json");
    write_json(&path, &Summary { steps: 3000 }).unwrap();
    assert_eq!(
        read_json::<Summary>(&path).unwrap(),
        Summary { steps: 3000 }
    );
    std::fs::write(&path, "{\"steps\": \"many\"}").unwrap();
    let e = read_json::<Summary>(&path).unwrap_err().to_string();
    assert!(e.contains("summary.json") && e.contains("steps"), "{e}");
    let missing = read_json::<Summary>(&dir.path().join("none.json")).unwrap_err();
    assert!(missing.is_not_found(), "{missing}");
}
