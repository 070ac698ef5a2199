//! The weights loader: decodes and checks each checkpoint the trainer sends on a thread of its
//! own (normal priority), so the real-time control loop only copies decoded weights in. Decoding
//! on the loop took 5-8 ms per checkpoint (measured in `mta soak`), enough to push a step's
//! answer past its deadline when weights arrived just before an observation.

use std::sync::mpsc;
use std::thread::JoinHandle;

use mtanet_ipc::{ACTION_DIM, IMAGE_HEIGHT, IMAGE_WIDTH};
use mtanet_models::ModelConfig;
use mtanet_models::live::{Imagined, LiveModel};

use crate::policy::background_priority;

/// A checkpoint's network must read the frames and actions the simulator sends.
pub fn check_wire_contract(cfg: &ModelConfig) -> anyhow::Result<()> {
    cfg.check_wire((IMAGE_HEIGHT, IMAGE_WIDTH), ACTION_DIM)
        .map_err(|e| anyhow::anyhow!("the checkpoint's network: {e}"))
}

/// Weights decoded and checked, ready for [`crate::policy::Policy::install`].
pub struct Prepared {
    pub(crate) model: LiveModel,
    pub(crate) imagined: Imagined,
    pub version: u64,
    pub(crate) probe: Option<f64>,
    /// Time taken to decode and check them, ms.
    pub decode_ms: f64,
}

/// Decodes and checks a checkpoint completely, on any thread (several ms for the default
/// network: the weights loader does it off the control loop); nothing of a bad one is used.
pub fn prepare(bytes: &[u8], version: u64, probe: f32) -> anyhow::Result<Prepared> {
    let t0 = std::time::Instant::now();
    // Decoded and verified once; the wire contract checked before anything is built.
    let ck = mtanet_models::checkpoint::from_bytes(bytes)?;
    check_wire_contract(&ck.config)?;
    let model = LiveModel::from_checkpoint(&ck, version)?;
    let imagined = Imagined::from_checkpoint(&ck)?;
    Ok(Prepared {
        model,
        imagined,
        version,
        // The sender's probe, else the one recorded in the checkpoint (a file).
        probe: probe
            .is_finite()
            .then_some(f64::from(probe))
            .or(ck.meta.probe),
        decode_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

struct Job {
    bytes: Vec<u8>,
    version: u64,
    probe: f32,
    install_step: u64,
}

/// A checkpoint the loader is done with: version, install step, and the model or why not.
pub type Decoded = (u64, u64, anyhow::Result<Prepared>);

pub struct Loader {
    to: Option<mpsc::Sender<Job>>,
    from: mpsc::Receiver<Decoded>,
    thread: Option<JoinHandle<()>>,
}

impl Loader {
    pub fn spawn(nice: i32) -> anyhow::Result<Self> {
        let (to, jobs) = mpsc::channel::<Job>();
        let (done, from) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("weights-loader".into())
            .spawn(move || {
                background_priority(nice, "weights loader");
                for job in jobs {
                    let r = prepare(&job.bytes, job.version, job.probe);
                    if done.send((job.version, job.install_step, r)).is_err() {
                        break;
                    }
                }
            })?;
        Ok(Self {
            to: Some(to),
            from,
            thread: Some(thread),
        })
    }

    /// Queues a checkpoint (copied out of shared memory: the sample goes back at once).
    pub fn submit(
        &self,
        bytes: &[u8],
        version: u64,
        probe: f32,
        install_step: u64,
    ) -> anyhow::Result<()> {
        let job = Job {
            bytes: bytes.to_vec(),
            version,
            probe,
            install_step,
        };
        self.to
            .as_ref()
            .expect("sender lives until drop")
            .send(job)
            .map_err(|_| anyhow::anyhow!("the weights loader has stopped"))
    }

    /// A decoded checkpoint (or why it was refused), when one is ready.
    pub fn try_take(&self) -> Option<Decoded> {
        self.from.try_recv().ok()
    }

    /// The next decoded checkpoint, waiting for it.
    pub fn take(&self) -> anyhow::Result<Decoded> {
        self.from
            .recv()
            .map_err(|_| anyhow::anyhow!("the weights loader has stopped"))
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        drop(self.to.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
