//! The MuJoCo world itself as the agent's world model: plans are rolled out by copying the
//! simulator state and stepping each candidate. Same planner, same cost as with the learned
//! model, so a failure to drive here is the cost's (or the planner's), not the model's.

use mtanet_control::{AgentModel, Drive, Health, Imagination, Wheels};
use mtanet_scenes::{SceneConfig, World, WorldState};

/// The world as seen by the agent: no learning, a snapshot of the real state to plan from.
pub struct OracleModel {
    frame_skip: usize,
    latest: Option<WorldState>,
}

impl OracleModel {
    pub fn new(frame_skip: usize) -> Self {
        Self {
            frame_skip: frame_skip.max(1),
            latest: None,
        }
    }
}

/// Lets the driving loop show a model the real world before each decision (only the oracle
/// looks).
pub trait SeesWorld {
    fn sees(&mut self, _world: &mut World) {}
}

impl SeesWorld for OracleModel {
    fn sees(&mut self, world: &mut World) {
        self.latest = Some(world.snapshot());
    }
}

impl AgentModel for OracleModel {
    type Snapshot = WorldState;

    fn frame_skip(&self) -> Option<usize> {
        Some(self.frame_skip)
    }

    fn observe(&mut self, _frame: &[f32], _action: Wheels) -> anyhow::Result<()> {
        Ok(())
    }

    fn reset(&mut self) {}

    fn snapshot(&mut self) -> anyhow::Result<WorldState> {
        self.latest
            .clone()
            .ok_or_else(|| anyhow::anyhow!("the oracle has not seen the world yet"))
    }

    fn health(&self) -> Health {
        Health::PERFECT
    }
}

/// Rolls plans out in a private copy of the world.
pub struct OracleImagination {
    world: World,
    frame_skip: usize,
    start: Option<WorldState>,
}

impl OracleImagination {
    pub fn new(scene: &SceneConfig, frame_skip: usize) -> anyhow::Result<Self> {
        Ok(Self {
            world: World::new(scene)?,
            frame_skip: frame_skip.max(1),
            start: None,
        })
    }

    /// Plans start from `from` itself (no committed segment to roll through).
    pub fn start_here(&mut self, from: WorldState) {
        self.start = Some(from);
    }

    fn hold(&mut self, wheels: Wheels) {
        for _ in 0..self.frame_skip {
            self.world.step(wheels);
        }
    }
}

impl Imagination for OracleImagination {
    type Start = WorldState;

    fn start(&mut self, from: WorldState, committed: Wheels) -> anyhow::Result<()> {
        self.world.restore(&from);
        self.hold(committed);
        self.start = Some(self.world.snapshot());
        Ok(())
    }

    fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
        let start = self
            .start
            .clone()
            .ok_or_else(|| anyhow::anyhow!("imagine before start"))?;
        let mut out = Vec::with_capacity(plans.len());
        for plan in plans {
            self.world.restore(&start);
            let mut frames = Vec::with_capacity(plan.len() * mtanet_scenes::IMAGE_PIXELS);
            for d in plan {
                self.hold(d.wheels());
                frames.extend_from_slice(&self.world.sense().image);
            }
            out.push(frames);
        }
        Ok(out)
    }
}
