//! Policies turn an observation into wheel velocities: active inference through the world model
//! when it is loaded and trusted, the reactive line-sensor rule otherwise.

use mtanet_ipc::{CommandSource, Observation};

use crate::active_inference::{self, ActiveInferenceConfig, Preference};
use crate::config::PredictorConfig;
use crate::world_model::WorldModel;

/// The fallback before any usable weights exist: steer toward the side sensor that sees the
/// line. Deliberately simple; it only has to keep the car near the line while data accumulates.
#[derive(Debug, Clone)]
pub struct Reactive {
    cruise: f32,
    turn: f32,
    last_side: f32,
}

impl Reactive {
    pub fn new(cfg: &PredictorConfig) -> Self {
        Self {
            cruise: cfg.cruise,
            turn: cfg.turn,
            last_side: 0.0,
        }
    }

    pub fn act(&mut self, obs: &Observation) -> [f32; 2] {
        let [l, m, r] = obs.line_sensors.map(|v| v != 0);
        // +1: turn left, -1: turn right.
        let side = match (l, m, r) {
            (true, _, false) => 1.0,
            (false, _, true) => -1.0,
            (false, false, false) => self.last_side,
            _ => 0.0,
        };
        if side != 0.0 {
            self.last_side = side;
        }
        let (c, t) = (self.cruise, self.turn * side);
        [c - t, c + t]
    }
}

/// Everything the predictor decides with.
pub struct Policy {
    reactive: Reactive,
    pub world: Option<WorldModel>,
    preference: Preference,
    cfg: ActiveInferenceConfig,
    candidates: Vec<[f32; 2]>,
    previous: [f32; 2],
    episode: Option<u8>,
    /// The latest observation, while the world model has not seen it (`act` did not need it).
    unobserved: Option<Observation>,
}

impl Policy {
    pub fn new(cfg: &PredictorConfig) -> Self {
        Self {
            reactive: Reactive::new(cfg),
            world: None,
            preference: Preference::default(),
            candidates: active_inference::candidates(&cfg.active_inference),
            cfg: cfg.active_inference.clone(),
            previous: [0.0; 2],
            episode: None,
            unobserved: None,
        }
    }

    /// Decides the next command. Only active inference needs the world model stepped with this
    /// frame first; otherwise the command goes out at once and [`Policy::after_command`] steps
    /// the model, so bookkeeping never delays the car.
    pub fn act(&mut self, obs: &Observation) -> anyhow::Result<([f32; 2], CommandSource)> {
        self.after_command()?; // catch up if the caller skipped it for the previous frame
        if self.episode.is_some_and(|e| e != obs.episode) {
            // The simulator put the car back: the past no longer predicts the present.
            if let Some(world) = self.world.as_mut() {
                world.reset_state();
            }
            self.reactive.last_side = 0.0;
            self.previous = [0.0; 2];
        }
        self.episode = Some(obs.episode);
        self.preference.observe(obs);
        let mut decided = None;
        if self.cfg.enabled
            && let Some(world) = self.world.as_mut()
            && world.trusted(self.cfg.trust_ratio, self.cfg.trust_after_steps)
            && let Some(preferred) = self.preference.image(self.cfg.preference_frames)
        {
            world.observe(obs)?;
            let (cmd, _cost) = active_inference::choose(
                world,
                &self.candidates,
                &preferred,
                self.previous,
                &self.cfg,
            )?;
            decided = Some((cmd, CommandSource::ActiveInference));
        }
        let (cmd, source) =
            decided.unwrap_or_else(|| (self.reactive.act(obs), CommandSource::Reactive));
        self.previous = cmd;
        if source == CommandSource::Reactive && self.world.is_some() {
            self.unobserved = Some(*obs);
        }
        Ok((cmd, source))
    }

    /// Work the command did not wait for: steps the world model with the frame `act` decided
    /// on without it. Returns whether there was such a frame.
    pub fn after_command(&mut self) -> anyhow::Result<bool> {
        match (self.world.as_mut(), self.unobserved.take()) {
            (Some(world), Some(obs)) => {
                world.observe(&obs)?;
                Ok(true)
            }
            _ => Ok(false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(line: [u8; 3]) -> Observation {
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.line_sensors = line;
        o
    }

    #[test]
    fn reactive_turns_toward_the_line() {
        let mut p = Reactive::new(&PredictorConfig::default());
        let [l, r] = p.act(&obs([1, 0, 0]));
        assert!(r > l, "line on the left must turn left: {l} {r}");
        let [l, r] = p.act(&obs([0, 0, 1]));
        assert!(l > r, "line on the right must turn right: {l} {r}");
        let [l, r] = p.act(&obs([0, 1, 0]));
        assert_eq!(l, r);
        // Lost: keep turning toward where the line was last seen (right).
        let [l, r] = p.act(&obs([0, 0, 0]));
        assert!(l > r);
    }

    #[test]
    fn without_a_model_the_reactive_rule_drives() {
        let mut p = Policy::new(&PredictorConfig::default());
        let (_, source) = p.act(&obs([0, 1, 0])).unwrap();
        assert_eq!(source, CommandSource::Reactive);
    }

    #[test]
    fn the_command_waits_for_the_world_model_only_when_planning_needs_it() {
        use crate::active_inference::ActiveInferenceConfig;
        use crate::world_model::tests::small_checkpoint;
        let steps = |p: &Policy| p.world.as_ref().unwrap().steps;
        let mut p = Policy::new(&PredictorConfig::default());
        p.world = Some(WorldModel::from_bytes(&small_checkpoint(1), 1).unwrap());
        let (_, source) = p.act(&obs([0, 1, 0])).unwrap();
        assert_eq!(source, CommandSource::Reactive);
        assert_eq!(
            steps(&p),
            0,
            "the reactive command goes out before the model step"
        );
        assert!(p.after_command().unwrap());
        assert_eq!(steps(&p), 1);
        assert!(!p.after_command().unwrap(), "each frame is observed once");
        // A caller that skips after_command loses no frame: the next act catches up first.
        p.act(&obs([0, 1, 0])).unwrap();
        p.act(&obs([0, 1, 0])).unwrap();
        assert_eq!(steps(&p), 2);

        // Planning with a trusted model steps the model before deciding, and leaves nothing over.
        let cfg = PredictorConfig {
            active_inference: ActiveInferenceConfig {
                enabled: true,
                trust_ratio: 1e9,
                trust_after_steps: 0,
                preference_frames: 1,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut p = Policy::new(&cfg);
        p.world = Some(WorldModel::from_bytes(&small_checkpoint(1), 1).unwrap());
        let lit = |v: f32| Observation {
            image: [v; mtanet_ipc::IMAGE_PIXELS],
            ..obs([0, 1, 0])
        };
        for v in [0.2, 0.6] {
            let (_, source) = p.act(&lit(v)).unwrap();
            assert_eq!(
                source,
                CommandSource::Reactive,
                "no statistics yet: not trusted"
            );
            p.after_command().unwrap();
        }
        let (_, source) = p.act(&lit(0.4)).unwrap();
        assert_eq!(source, CommandSource::ActiveInference);
        assert_eq!(steps(&p), 3, "planning needed this frame first");
        assert!(!p.after_command().unwrap());
    }
}
