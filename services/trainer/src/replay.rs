//! The trainer's replay buffer: chunks copied out of shared memory (a chunk must be released
//! quickly so the simulator can reuse its memory), joined into training windows at the model's
//! frame skip. Consecutive chunks of one episode (contiguous steps) form one run of driving; a
//! window may start anywhere in a run, at any phase of the frame skip.

use std::collections::VecDeque;

use mtanet_ipc::{ACTION_DIM, CommandSource, IMAGE_PIXELS, REPLAY_STEPS, ReplayChunk};
use mtanet_models::sequences::{push_window, window_span};
use rand::Rng;

struct Chunk {
    first_step: u64,
    episode: u32,
    images: Vec<[f32; IMAGE_PIXELS]>,
    actions: Vec<[f32; ACTION_DIM]>,
}

impl Chunk {
    /// A slot with room for a whole chunk, its memory written once so that it is resident.
    fn slot() -> Self {
        let mut images = vec![[0.0; IMAGE_PIXELS]; REPLAY_STEPS];
        let mut actions = vec![[0.0; ACTION_DIM]; REPLAY_STEPS];
        images.clear();
        actions.clear();
        Self {
            first_step: 0,
            episode: 0,
            images,
            actions,
        }
    }
}

/// Chunks held beyond the capacity (this share of it), so that an update of lockstep learning
/// whose horizon lags the newest chunks (by ~70 with the defaults) still sees the same
/// `capacity` chunks before it.
const LOOKAHEAD_SHARE: usize = 4;

pub struct ReplayBuffer {
    chunks: VecDeque<Chunk>,
    /// Chunks a batch is drawn from (the newest before its horizon).
    capacity: usize,
    /// Slots not yet filled.
    free: Vec<Chunk>,
    received: u64,
    /// Steps in all chunks received (a chunk's `len`).
    steps_received: u64,
    /// Steps received per command source (`CommandSource as usize`; unknown values last).
    steps_by_source: [u64; 6],
    lost: u64,
    next_seq: Option<u64>,
    /// The pacing of the newest chunk (`ReplayChunk::pace`).
    pace: f32,
}

/// One training batch: `[B, T, H, W]` frames and `[B, T, A]` actions, flattened.
pub struct Batch {
    pub batch: usize,
    pub steps: usize,
    pub images: Vec<f32>,
    pub actions: Vec<f32>,
}

impl ReplayBuffer {
    /// Every slot is allocated here, up front: filling the buffer and then replacing its
    /// oldest chunks allocates nothing, so the trainer's memory stays flat through a long run.
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        let slots = capacity + capacity / LOOKAHEAD_SHARE;
        Self {
            chunks: VecDeque::with_capacity(slots),
            capacity,
            free: (0..slots).map(|_| Chunk::slot()).collect(),
            received: 0,
            steps_received: 0,
            steps_by_source: [0; 6],
            lost: 0,
            next_seq: None,
            pace: 0.0,
        }
    }

    /// Lockstep pacing the simulator runs at (updates per 1000 steps; 0: none).
    pub fn pace(&self) -> f32 {
        self.pace
    }

    /// Copies a chunk in; counts chunks lost in transport by the gap in sequence numbers.
    pub fn push(&mut self, c: &ReplayChunk) {
        if let Some(expected) = self.next_seq
            && c.seq > expected
        {
            self.lost += c.seq - expected;
        }
        self.next_seq = Some(c.seq + 1);
        self.received += 1;
        self.pace = if c.pace.is_finite() {
            c.pace.max(0.0)
        } else {
            0.0
        };
        self.steps_received += u64::from(c.len);
        let len = (c.len as usize).min(c.images.len());
        for &s in &c.sources[..len] {
            self.steps_by_source[(s as usize).min(5)] += 1;
        }
        let mut slot = match self.free.pop() {
            Some(slot) => slot,
            None => self.chunks.pop_front().expect("a full buffer holds chunks"),
        };
        slot.first_step = c.first_step;
        slot.episode = c.episode;
        slot.images.clear();
        slot.images.extend_from_slice(&c.images[..len]);
        slot.actions.clear();
        slot.actions.extend_from_slice(&c.actions[..len]);
        self.chunks.push_back(slot);
    }

    /// Chunks a batch is drawn from now (at most the capacity).
    pub fn len(&self) -> usize {
        self.chunks.len().min(self.capacity)
    }

    /// The step after the last one of the `arrival`-th chunk received (0-based), if held.
    pub fn end_step(&self, arrival: u64) -> Option<u64> {
        let first = self.received - self.chunks.len() as u64;
        let c = self
            .chunks
            .get(usize::try_from(arrival.checked_sub(first)?).ok()?)?;
        Some(c.first_step + c.images.len() as u64)
    }

    /// Positions in `chunks` a batch draws from: the `capacity` newest chunks before the
    /// `upto`-th received (all received: None).
    fn window(&self, upto: Option<u64>) -> std::ops::Range<usize> {
        let first = self.received - self.chunks.len() as u64;
        let end = upto.map_or(self.chunks.len(), |u| {
            (u.saturating_sub(first) as usize).min(self.chunks.len())
        });
        end.saturating_sub(self.capacity)..end
    }

    pub fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    pub fn received(&self) -> u64 {
        self.received
    }

    pub fn steps_received(&self) -> u64 {
        self.steps_received
    }

    pub fn lost(&self) -> u64 {
        self.lost
    }

    /// Share of the steps received that exploration segments drove.
    pub fn exploration_fraction(&self) -> f64 {
        let total: u64 = self.steps_by_source.iter().sum();
        if total == 0 {
            return 0.0;
        }
        self.steps_by_source[CommandSource::Exploration as usize] as f64 / total as f64
    }

    /// Control steps from chunk `c`, offset `o` on, that continue without a gap or a reset
    /// and end before position `end`.
    fn contiguous_from(&self, c: usize, o: usize, need: usize, end: usize) -> bool {
        let mut have = self.chunks[c].images.len() - o;
        let mut i = c;
        while have < need {
            if i + 1 >= end {
                return false;
            }
            let (a, b) = match (self.chunks.get(i), self.chunks.get(i + 1)) {
                (Some(a), Some(b)) => (a, b),
                _ => return false,
            };
            if b.episode != a.episode || b.first_step != a.first_step + a.images.len() as u64 {
                return false;
            }
            have += b.images.len();
            i += 1;
        }
        true
    }

    /// Copies `span` consecutive steps from (c, o) into flat slices.
    fn gather(
        &self,
        c: usize,
        o: usize,
        span: usize,
    ) -> (Vec<[f32; IMAGE_PIXELS]>, Vec<[f32; ACTION_DIM]>) {
        let (mut imgs, mut acts) = (Vec::with_capacity(span), Vec::with_capacity(span));
        let (mut i, mut off) = (c, o);
        while imgs.len() < span {
            let ch = &self.chunks[i];
            let take = (ch.images.len() - off).min(span - imgs.len());
            imgs.extend_from_slice(&ch.images[off..off + take]);
            acts.extend_from_slice(&ch.actions[off..off + take]);
            i += 1;
            off = 0;
        }
        (imgs, acts)
    }

    /// A random batch of `batch` windows of `steps` model steps at `skip`, from the chunks
    /// received before the `upto`-th (all: None); `None` when they hold no run long enough
    /// (after a bounded number of tries per window). With `mirror`, each window is mirrored
    /// left-right with probability 1/2 (see [`mirror`]).
    pub fn sample(
        &self,
        rng: &mut impl Rng,
        shape: (usize, usize, usize),
        mirror_windows: bool,
        upto: Option<u64>,
    ) -> Option<Batch> {
        let (batch, steps, skip) = shape;
        let window = self.window(upto);
        if window.is_empty() {
            return None;
        }
        let span = window_span(skip, steps);
        let mut out = Batch {
            batch,
            steps,
            images: Vec::with_capacity(batch * steps * IMAGE_PIXELS),
            actions: Vec::with_capacity(batch * steps * ACTION_DIM),
        };
        for _ in 0..batch {
            let found = (0..64).find_map(|_| {
                let c = rng.random_range(window.clone());
                let o = rng.random_range(0..self.chunks[c].images.len().max(1));
                (self.chunks[c].images.len() > o && self.contiguous_from(c, o, span, window.end))
                    .then_some((c, o))
            });
            let (c, o) = found?;
            let (mut imgs, mut acts) = self.gather(c, o, span);
            if mirror_windows && rng.random::<bool>() {
                mirror(&mut imgs, &mut acts);
            }
            // The window's first frame comes skip - 1 steps in, after the commands of its action.
            push_window(
                &imgs,
                &acts,
                skip - 1,
                skip,
                steps,
                &mut out.images,
                &mut out.actions,
            );
        }
        Some(out)
    }
}

/// The car is left-right symmetric (centred camera, symmetric sensors and wheels), so a drive
/// seen in a mirror is a drive too: images flipped left-right, left and right wheel commands
/// swapped. A track that turns only one way (the oval turns left) then also teaches what the
/// other way looks like.
pub fn mirror(images: &mut [[f32; IMAGE_PIXELS]], actions: &mut [[f32; ACTION_DIM]]) {
    for img in images.iter_mut() {
        for row in img.chunks_exact_mut(mtanet_ipc::IMAGE_WIDTH) {
            row.reverse();
        }
    }
    for a in actions.iter_mut() {
        a.swap(0, 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn chunk(seq: u64, first_step: u64, episode: u32) -> Box<ReplayChunk> {
        let mut c: Box<ReplayChunk> = bytemuck::zeroed_box();
        c.seq = seq;
        c.len = 20;
        c.first_step = first_step;
        c.episode = episode;
        for i in 0..20 {
            let step = (first_step + i as u64) as f32;
            c.images[i] = [step; IMAGE_PIXELS];
            c.actions[i] = [step, 0.0];
            c.sources[i] = if i < 5 {
                CommandSource::Exploration as u8
            } else {
                0
            };
        }
        c
    }

    #[test]
    fn slots_are_allocated_once_and_reused_when_full() {
        let mut b = ReplayBuffer::new(3);
        let at = |b: &ReplayBuffer| -> Vec<*const [f32; IMAGE_PIXELS]> {
            b.chunks.iter().map(|c| c.images.as_ptr()).collect()
        };
        for k in 0..3 {
            b.push(&chunk(k, k * 20, 0));
        }
        let mut first = at(&b);
        for k in 3..9 {
            b.push(&chunk(k, k * 20, 0));
        }
        let mut later = at(&b);
        first.sort();
        later.sort();
        assert_eq!(first, later, "the same three slots, refilled");
        assert_eq!(b.chunks[0].first_step, 120, "the newest three chunks");
        assert_eq!(b.chunks[2].images[19], [179.0; IMAGE_PIXELS]);
    }

    #[test]
    fn counts_losses_sources_and_keeps_capacity() {
        let mut b = ReplayBuffer::new(2);
        for s in [0, 1, 4] {
            b.push(&chunk(s, s * 20, 0));
        }
        assert_eq!(
            (b.received(), b.steps_received(), b.lost(), b.len()),
            (3, 60, 2, 2)
        );
        assert!((b.exploration_fraction() - 0.25).abs() < 1e-12);
    }

    #[test]
    fn windows_run_across_chunks_of_one_episode_only() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut b = ReplayBuffer::new(16);
        // Steps 0..60 of episode 0, then a reset: episode 1 restarts at step 60.
        for (seq, first, ep) in [(0, 0, 0), (1, 20, 0), (2, 40, 0), (3, 60, 1)] {
            b.push(&chunk(seq, first, ep));
        }
        // 4 model steps at skip 5 need 5 - 1 + 3 * 5 + 1 = 20 steps: fits in either episode.
        let batch = b.sample(&mut rng, (32, 4, 5), false, None).unwrap();
        for w in batch.images.chunks(4 * IMAGE_PIXELS) {
            let f: Vec<f32> = w.chunks(IMAGE_PIXELS).map(|p| p[0]).collect();
            assert!(
                f.windows(2).all(|p| p[1] - p[0] == 5.0),
                "frames 5 steps apart: {f:?}"
            );
            let ep = |s: f32| if s < 60.0 { 0 } else { 1 };
            assert_eq!(
                ep(f[0] - 4.0),
                ep(f[3]),
                "a window never spans a reset: {f:?}"
            );
        }
        // The action of a model step is the mean command of the 5 steps before its frame.
        let (f0, a0) = (batch.images[IMAGE_PIXELS], batch.actions[2]);
        assert_eq!(a0, f0 - 2.0, "mean of steps f-4..=f");
        // 12 model steps (60 steps) fit only in episode 0 from its very start: never found in
        // episode 1, and all windows come from episode 0.
        assert!(
            b.sample(&mut rng, (4, 13, 5), false, None).is_none(),
            "65 steps exist nowhere"
        );
    }

    #[test]
    fn a_mirrored_window_flips_the_images_and_swaps_the_wheels() {
        let mut img = [[0.0f32; IMAGE_PIXELS]; 1];
        img[0][0] = 1.0; // top row, far left
        img[0][13] = 2.0; // second row, second from the left
        let mut act = [[3.0f32, 5.0]];
        mirror(&mut img, &mut act);
        assert_eq!((img[0][11], img[0][22], img[0][0]), (1.0, 2.0, 0.0));
        assert_eq!(act[0], [5.0, 3.0], "a left turn becomes a right turn");
        // About half of the windows of a batch come mirrored.
        let mut b = ReplayBuffer::new(4);
        b.push(&chunk(0, 0, 0));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let batch = b.sample(&mut rng, (200, 2, 1), true, None).unwrap();
        let swapped = batch.actions.chunks(4).filter(|a| a[1] != 0.0).count();
        assert!((60..140).contains(&swapped), "{swapped} of 200 mirrored");
    }
}
