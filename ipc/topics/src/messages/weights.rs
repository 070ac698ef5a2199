use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

/// User header of the weights topic, whose payload is a `[u8]` slice holding one checkpoint
/// (safetensors with config and metadata, exactly the bytes of a checkpoint file).
#[derive(Debug, Clone, Copy, Default, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::WeightsHeader/v3")]
#[repr(C)]
pub struct WeightsHeader {
    /// `CLOCK_MONOTONIC` ns when published.
    pub stamp_ns: u64,
    /// Increases by one per published checkpoint of a trainer run.
    pub version: u64,
    /// Training updates done when the checkpoint was taken.
    pub train_step: u64,
    /// Payload length in bytes (the slice may be longer when the allocator rounds up).
    pub len: u64,
    /// Last training loss.
    pub loss: f32,
    /// Checkpoint schema version.
    pub schema: u32,
    /// Training step at which the trainer last ran the counterfactual probe (0: never).
    pub probe_step: u64,
    /// That probe's rank correlation (NaN: never measured).
    pub probe: f32,
    pub _reserved: u32,
    /// Lockstep learning: the observation step from which the predictor drives with these
    /// weights, fixed by the data they were learnt from (0: as soon as they are decoded).
    pub install_step: u64,
}
