//! Layer timescales on held-out sequences.

use mtanet_models::analysis::{LayerTimescales, timescales};
use mtanet_models::synth::{SynthConfig, generate};
use mtanet_models::{ModelConfig, MtaPredNet};
use tch::{Device, nn::VarStore};

/// libtorch has one global generator: a test that builds a model while another has just seeded
/// it would change the other's weights (the timescale test failed that way in a clean clone).
static TORCH_RNG: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn small(tau: Vec<f64>) -> ModelConfig {
    ModelConfig::small(&tau)
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
