use std::cell::Cell;
use std::time::Duration;

use super::*;
use crate::cost::tests::every_mode;
use crate::preference::tests::{learnt, line_frame};

/// A toy world: the line's column moves by the turn each segment (a positive turn, to the left,
/// moves the line right in the image), from a start offset. Each imagined step of a batch costs
/// `per_candidate_step` per candidate, like a model's batched rollout, on the toy's own clock:
/// timing is exact, whatever the machine running the test is doing.
struct Toy {
    offset: f32,
    per_candidate_step: Duration,
    clock_zero: Instant,
    clock: Cell<Duration>,
    /// Batches rolled out with a deadline before it counts as passed (`None`: by the clock).
    batches_in_time: Option<usize>,
}

impl Toy {
    fn new(start: f32, per_candidate_step: Duration) -> Self {
        let mut toy = Self {
            offset: 0.0,
            per_candidate_step,
            clock_zero: Instant::now(),
            clock: Cell::new(Duration::ZERO),
            batches_in_time: None,
        };
        toy.start(start, [8.0, 8.0]).unwrap();
        toy
    }

    fn rollout(&self, plans: &[Vec<Drive>], deadline: Option<Instant>) -> Option<Vec<Vec<f32>>> {
        let h = plans.first().map_or(0, Vec::len);
        let mut offsets = vec![self.offset; plans.len()];
        let mut frames = vec![Vec::new(); plans.len()];
        for s in 0..h {
            if deadline.is_some_and(|d| self.now() >= d) {
                return None;
            }
            // The model's compute of one imagined step of the whole batch.
            self.clock
                .set(self.clock.get() + self.per_candidate_step * plans.len() as u32);
            for (i, p) in plans.iter().enumerate() {
                offsets[i] += 0.1 * p[s].turn;
                frames[i].extend(line_frame(6.0 + offsets[i], 0.0));
            }
        }
        Some(frames)
    }
}

impl Imagination for Toy {
    type Start = f32;
    fn start(&mut self, from: f32, committed: Wheels) -> anyhow::Result<()> {
        self.offset = from + 0.1 * Drive::from_wheels(committed).turn;
        Ok(())
    }
    fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
        Ok(self.rollout(plans, None).expect("no deadline"))
    }
    fn imagine_until(
        &mut self,
        plans: &[Vec<Drive>],
        deadline: Instant,
    ) -> anyhow::Result<Option<Vec<Vec<f32>>>> {
        if let Some(n) = self.batches_in_time.as_mut() {
            let in_time = *n > 0;
            *n = n.saturating_sub(1);
            return Ok(in_time.then(|| self.rollout(plans, None)).flatten());
        }
        Ok(self.rollout(plans, Some(deadline)))
    }
    fn now(&self) -> Instant {
        self.clock_zero + self.clock.get()
    }
}

/// Every mode weighed (see `cost::tests::every_mode`): these tests steer by the offset.
fn cost() -> Cost {
    Cost::new(learnt(), every_mode())
}

#[test]
fn steers_the_line_back_to_the_centre_and_keeps_moving() {
    let mut planner = Planner::new(&PlannerConfig::default()).unwrap();
    assert_eq!(planner.batch_sizes(), vec![8, 16, 24, 32]);
    // Line 3 pixels left of the centre: turning left (positive turn) brings it back.
    let mut toy = Toy::new(-3.0, Duration::ZERO);
    let out = planner
        .plan(&mut toy, &cost(), Drive::new(8.0, 0.0), None)
        .unwrap();
    assert!(out.plan[0].turn > 2.0, "{out:?}");
    assert!(
        out.plan[0].speed > 5.0,
        "the progress prior keeps it moving: {out:?}"
    );
    // Without a deadline the configured work runs to the end: the warm start's batch of 8,
    // then 3 iterations of 32.
    assert_eq!(
        (out.evaluations, out.iterations, out.candidates, out.cut),
        (8 + 3 * 32, 3, 32, false)
    );
    // Same seed, same inputs: the same plan.
    let mut again = Planner::new(&PlannerConfig::default()).unwrap();
    let out2 = again
        .plan(&mut toy, &cost(), Drive::new(8.0, 0.0), None)
        .unwrap();
    assert_eq!((&out.plan, out.terms), (&out2.plan, out2.terms));
}

/// A machine too slow for any CEM iteration plans from the fixed candidates alone: a line a
/// little off the centre (a slow drift) is brought back by the gentlest turn, not left to grow
/// by going straight on or overshot by a hard turn.
#[test]
fn without_time_for_an_iteration_a_gentle_turn_corrects_a_small_offset() {
    let cfg = PlannerConfig::default();
    let mut planner = Planner::new(&cfg).unwrap();
    // 1.1 pixels left (within a pixel the cost's floor keeps it straight; from 1.3 a half turn
    // wins): a quarter turn (2 rad/s) brings it back over the 4 segments.
    let mut toy = Toy::new(-1.1, Duration::ZERO);
    toy.batches_in_time = Some(1);
    let deadline = toy.now() + Duration::from_secs(3600);
    let out = planner
        .plan(&mut toy, &cost(), Drive::new(8.0, 0.0), Some(deadline))
        .unwrap();
    assert_eq!((out.iterations, out.cut), (0, true), "{out:?}");
    assert_eq!(out.plan[0].turn, 0.25 * cfg.max_turn, "{out:?}");
}

/// A model whose full plan takes ~4x its deadline: the plan comes by the deadline (within one
/// imagined step of a batch), improved as far as the time allowed, and says it was cut.
#[test]
fn a_slow_imagination_plans_less_never_late() {
    let per = Duration::from_micros(200);
    let cfg = PlannerConfig::default();
    // The full work: (8 + 3 x 32) candidates x 4 steps x 0.2 ms = ~83 ms.
    let budget = Duration::from_millis(20);
    let mut planner = Planner::new(&cfg).unwrap();
    let mut toy = Toy::new(-3.0, per);
    let mut iterations = Vec::new();
    for _ in 0..5 {
        toy.start(-3.0, [8.0, 8.0]).unwrap();
        let t0 = toy.now();
        let out = planner
            .plan(&mut toy, &cost(), Drive::new(8.0, 0.0), Some(t0 + budget))
            .unwrap();
        let took = toy.now() - t0;
        // One imagined step of the largest batch (32 x 0.2 ms) may finish after the deadline.
        assert!(took <= budget + per * 32, "{took:?}");
        assert!(took >= budget / 2, "it used the time it had: {took:?}");
        assert!(out.cut && out.terms.is_some(), "{out:?}");
        assert!(
            out.plan[0].turn > 0.0,
            "still steers towards the line: {out:?}"
        );
        iterations.push(out.iterations);
    }
    // Once it has measured its rollouts it sizes them to fit: at least one CEM iteration.
    assert!(iterations[1..].iter().all(|&i| i >= 1), "{iterations:?}");
}

#[test]
fn a_deadline_already_past_drives_the_warm_start_unscored() {
    let mut planner = Planner::new(&PlannerConfig::default()).unwrap();
    let mut toy = Toy::new(-3.0, Duration::ZERO);
    let first = planner
        .plan(&mut toy, &cost(), Drive::new(8.0, 0.0), None)
        .unwrap();
    let now = toy.now();
    let out = planner
        .plan(&mut toy, &cost(), Drive::new(8.0, 0.0), Some(now))
        .unwrap();
    let mut shifted = first.plan[1..].to_vec();
    shifted.push(*first.plan.last().unwrap());
    assert_eq!(out.plan, shifted, "the previous plan, shifted by a segment");
    assert_eq!(
        (out.terms, out.evaluations, out.iterations, out.cut),
        (None, 0, 0, true)
    );
}

#[test]
fn bad_configs_are_refused() {
    for cfg in [
        PlannerConfig {
            horizon: 0,
            ..Default::default()
        },
        PlannerConfig {
            elites: 40,
            ..Default::default()
        },
        PlannerConfig {
            iterations: 0,
            ..Default::default()
        },
    ] {
        assert!(Planner::new(&cfg).is_err());
    }
}
