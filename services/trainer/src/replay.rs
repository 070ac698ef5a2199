//! The trainer's replay buffer: a ring of training sequences copied out of the shared-memory
//! chunks (a chunk must be released quickly so the simulator can reuse its memory).

use std::collections::VecDeque;

use mtanet_ipc::{ACTION_DIM, IMAGE_PIXELS, ReplayChunk};

/// One training sequence.
#[derive(Clone)]
pub struct Sequence {
    pub first_step: u64,
    pub images: Vec<[f32; IMAGE_PIXELS]>,
    pub actions: Vec<[f32; ACTION_DIM]>,
}

pub struct ReplayBuffer {
    capacity: usize,
    sequences: VecDeque<Sequence>,
    received: u64,
    /// Steps in all chunks received (a chunk's `len`).
    steps_received: u64,
    lost: u64,
    next_seq: Option<u64>,
}

impl ReplayBuffer {
    pub fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            sequences: VecDeque::new(),
            received: 0,
            steps_received: 0,
            lost: 0,
            next_seq: None,
        }
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
        self.steps_received += u64::from(c.len);
        let len = (c.len as usize).min(c.images.len());
        if self.sequences.len() == self.capacity {
            self.sequences.pop_front();
        }
        self.sequences.push_back(Sequence {
            first_step: c.first_step,
            images: c.images[..len].to_vec(),
            actions: c.actions[..len].to_vec(),
        });
    }

    pub fn len(&self) -> usize {
        self.sequences.len()
    }

    pub fn is_empty(&self) -> bool {
        self.sequences.is_empty()
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

    pub fn sequences(&self) -> impl Iterator<Item = &Sequence> {
        self.sequences.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(seq: u64) -> Box<ReplayChunk> {
        let mut c: Box<ReplayChunk> = bytemuck::zeroed_box();
        c.seq = seq;
        c.len = 3;
        c.first_step = seq * 20;
        c.images[1][5] = seq as f32;
        c
    }

    #[test]
    fn counts_losses_and_keeps_capacity() {
        let mut b = ReplayBuffer::new(2);
        for s in [0, 1, 4] {
            b.push(&chunk(s));
        }
        assert_eq!(b.received(), 3);
        assert_eq!(b.steps_received(), 9);
        assert_eq!(b.lost(), 2);
        assert_eq!(b.len(), 2);
        let kept: Vec<u64> = b.sequences().map(|s| s.first_step).collect();
        assert_eq!(kept, vec![20, 80]);
        let last = b.sequences().last().unwrap();
        assert_eq!(last.images.len(), 3);
        assert_eq!(last.images[1][5], 4.0);
    }
}
