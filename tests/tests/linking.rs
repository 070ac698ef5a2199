//! The native libraries load in test binaries too (rpaths from build.rs), and work.

use tch::{Kind, Tensor};

#[test]
fn libtorch_runs_forward_and_backward() {
    tch::set_num_threads(1);
    let w = Tensor::from_slice(&[1.0f32, -2.0, 3.0]).set_requires_grad(true);
    let x = Tensor::from_slice(&[0.5f32, 0.25, -1.0]);
    let y = (&w * &x).sum(Kind::Float);
    y.backward();
    let grad: Vec<f32> = Vec::try_from(w.grad()).unwrap();
    assert_eq!(grad, vec![0.5, 0.25, -1.0]);
    assert!((y.double_value(&[]) - (0.5 - 0.5 - 3.0)).abs() < 1e-6);
}

#[test]
fn mujoco_loads_and_steps_a_falling_body() {
    let xml = r#"<mujoco><worldbody><body pos="0 0 1"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>"#;
    let model = mujoco_rs::prelude::MjModel::from_xml_string(xml).expect("model loads");
    let mut data = model.make_data();
    for _ in 0..100 {
        data.step();
    }
    let z = data.qpos()[2];
    // 100 steps of 2 ms free fall: z = 1 - g t^2 / 2 ~ 0.80.
    assert!(z < 0.85 && z > 0.75, "body at z = {z}");
}
