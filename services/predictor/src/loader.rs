//! The weights loader: decodes and checks each checkpoint the trainer sends on a thread of its
//! own (normal priority), so the real-time control loop only copies decoded weights in. Decoding
//! on the loop took 5-8 ms per checkpoint (measured in `mta soak`), enough to push a step's
//! answer past its deadline when weights arrived just before an observation.

use std::sync::mpsc;
use std::thread::JoinHandle;

use crate::policy::{Prepared, background_priority, prepare};

struct Job {
    bytes: Vec<u8>,
    version: u64,
    probe: f32,
}

pub struct Loader {
    to: Option<mpsc::Sender<Job>>,
    from: mpsc::Receiver<(u64, anyhow::Result<Prepared>)>,
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
                    if done.send((job.version, r)).is_err() {
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
    pub fn submit(&self, bytes: &[u8], version: u64, probe: f32) -> anyhow::Result<()> {
        let job = Job {
            bytes: bytes.to_vec(),
            version,
            probe,
        };
        self.to
            .as_ref()
            .expect("sender lives until drop")
            .send(job)
            .map_err(|_| anyhow::anyhow!("the weights loader has stopped"))
    }

    /// A decoded checkpoint (or why it was refused), with its version, when one is ready.
    pub fn try_take(&self) -> Option<(u64, anyhow::Result<Prepared>)> {
        self.from.try_recv().ok()
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
