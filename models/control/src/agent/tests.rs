use super::*;
use crate::planner::Imagination;
use crate::planner::PlannerConfig;
use crate::preference::tests::line_frame;
use crate::worker::{Inline, PlanDone, PlanJob};

mod takeover;

/// A model that counts its steps and reports the health it is given.
struct Toy {
    skip: usize,
    health: Health,
    observed: Vec<Wheels>,
}

impl AgentModel for Toy {
    type Snapshot = f32;
    fn frame_skip(&self) -> Option<usize> {
        Some(self.skip)
    }
    fn observe(&mut self, _: &[f32], a: Wheels) -> anyhow::Result<()> {
        self.observed.push(a);
        Ok(())
    }
    fn reset(&mut self) {}
    fn snapshot(&mut self) -> anyhow::Result<f32> {
        Ok(0.0)
    }
    fn health(&self) -> Health {
        self.health
    }
}

impl Toy {
    fn new(skip: usize, health: Health) -> Self {
        Self {
            skip,
            health,
            observed: Vec::new(),
        }
    }
}

/// The health of a model that earned trust: well under copy-last, a good probe.
const TRUSTED: Health = Health {
    model_over_copy: Some(0.3),
    model_steps: 10,
    probe: Some(0.9),
};

/// Imagines the line where it is, whatever the plan: every plan sees the same frames.
struct Still;

impl Imagination for Still {
    type Start = f32;
    fn start(&mut self, _: f32, _: Wheels) -> anyhow::Result<()> {
        Ok(())
    }
    fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
        Ok(plans
            .iter()
            .map(|p| p.iter().flat_map(|_| line_frame(6.0, 0.0)).collect())
            .collect())
    }
}

/// The real planner, in line, over the [`Still`] imagination.
fn still_planner() -> Inline<Still> {
    Inline::new(
        crate::Planner::new(&PlannerConfig::default()).unwrap(),
        Still,
    )
}

/// A plan for `segment`: straight on at 8 rad/s for 4 segments.
fn straight_on(segment: u64) -> PlanDone {
    PlanDone {
        segment,
        outcome: Ok(Outcome {
            plan: vec![Drive::from_wheels([8.0, 8.0]); 4],
            terms: Some(crate::cost::Terms::default()),
            evaluations: 0,
            iterations: 1,
            candidates: 1,
            cut: false,
            rollout_s_per_candidate_segment: None,
        }),
        compute: Duration::ZERO,
    }
}

/// A planner that answers its first job (so active inference can take over) and no other; it
/// records the longest wait asked of it.
#[derive(Default)]
struct FirstOnly {
    job: Option<u64>,
    answered: bool,
    longest: Duration,
}

impl PlanService<f32> for FirstOnly {
    fn submit(&mut self, job: PlanJob<f32>) -> anyhow::Result<()> {
        self.job = Some(job.segment);
        Ok(())
    }
    fn wait(&mut self, timeout: Duration) -> Option<PlanDone> {
        self.longest = self.longest.max(timeout);
        let segment = self.job?;
        if self.answered {
            return None;
        }
        self.answered = true;
        self.job = None;
        Some(straight_on(segment))
    }
    fn idle(&self) -> bool {
        self.job.is_none()
    }
}

fn cfg() -> AgentConfig {
    AgentConfig {
        preference_frames: 5,
        trust_after_steps: 2,
        ..Default::default()
    }
}

fn agent(cfg: &AgentConfig) -> Agent {
    let off = ExplorationConfig {
        enabled: false,
        ..Default::default()
    };
    Agent::new(cfg, &ReactiveConfig::default(), &off, FrameShape::CAR, 0.02)
}

fn tick<'a>(frame: &'a [f32], line: [bool; 3], applied: Wheels) -> Tick<'a> {
    Tick {
        step: 0,
        episode: 0,
        frame,
        line,
        applied,
        // An ideal car: the wheels turn at the command.
        measured: applied,
        lockstep: true,
    }
}

const CENTRED: [bool; 3] = [false, true, false];

#[test]
fn drives_by_rule_until_trusted_then_plans_and_holds_each_segment() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(3, Health::default());
    let mut plans = still_planner();
    let mut a = agent(&cfg());
    let mut applied = [0.0; 2];
    for _ in 0..30 {
        let d = a
            .step(&tick(&frame, CENTRED, applied), &mut model, &mut plans)
            .unwrap();
        assert_eq!(
            d.driver,
            Driver::Reactive,
            "an untrusted model never drives"
        );
        applied = d.wheels;
    }
    assert_eq!(
        model.observed.len(),
        10,
        "a model step every 3 control steps"
    );
    assert_eq!(
        model.observed[1],
        [8.0, 8.0],
        "the mean command of its segment"
    );
    model.health = TRUSTED;
    // Trusted: the rule's command is held for one segment while the first plan is made from it.
    let mut arming = Vec::new();
    for _ in 0..3 {
        let d = a
            .step(&tick(&frame, CENTRED, applied), &mut model, &mut plans)
            .unwrap();
        assert_eq!(d.driver, Driver::Reactive, "arming: no plan in hand yet");
        arming.push(d.wheels);
        applied = d.wheels;
    }
    assert!(arming.iter().all(|w| *w == arming[0]), "{arming:?}");
    let mut segments: Vec<Vec<Wheels>> = Vec::new();
    for k in 0..12 {
        let d = a
            .step(&tick(&frame, CENTRED, applied), &mut model, &mut plans)
            .unwrap();
        assert_eq!(d.driver, Driver::ActiveInference, "step {k}");
        if k % 3 == 0 {
            segments.push(Vec::new());
        }
        segments.last_mut().unwrap().push(d.wheels);
        applied = d.wheels;
    }
    for s in &segments {
        assert!(
            s.iter().all(|w| *w == s[0]),
            "a command is held over its segment: {s:?}"
        );
    }
    assert_eq!(a.stats.switches_to_active_inference, 1);
    assert_eq!(
        a.stats.plans, 4,
        "each segment takes up the plan made a segment ago"
    );
    // With the line held in view, only the priors decide: straight on, near the preferred speed.
    let d = Drive::from_wheels(segments[2][0]);
    assert!(d.turn.abs() < 2.0 && d.speed > 5.0, "{d:?}");
}

/// An agent that took the wheel with a trusted model, the line centred in `frame`.
fn under_active_inference(frame: &[f32], model: &mut Toy, plans: &mut Inline<Still>) -> Agent {
    let mut a = agent(&cfg());
    for _ in 0..30 {
        a.step(&tick(frame, CENTRED, [8.0; 2]), model, plans)
            .unwrap();
    }
    assert!(a.driving_by_active_inference());
    a
}

#[test]
fn losing_the_line_hands_over_to_the_fallback_until_it_is_seen_again() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(2, TRUSTED);
    let mut plans = still_planner();
    let mut a = under_active_inference(&frame, &mut model, &mut plans);
    // The bar off the line while the camera still sees it (cutting a bend): not lost.
    for _ in 0..40 {
        a.step(&tick(&frame, [false; 3], [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert!(
        a.driving_by_active_inference(),
        "the camera still follows the line"
    );
    // 0.5 s with neither a line sensor on nor a line in view (25 steps), then the fallback.
    let floor = [0.85f32; 96];
    let mut drivers = Vec::new();
    for _ in 0..30 {
        drivers.push(
            a.step(&tick(&floor, [false; 3], [8.0; 2]), &mut model, &mut plans)
                .unwrap()
                .driver,
        );
    }
    assert_eq!(
        drivers
            .iter()
            .filter(|d| **d == Driver::ActiveInference)
            .count(),
        24
    );
    assert_eq!(drivers.last(), Some(&Driver::Fallback));
    assert_eq!(a.stats.fallbacks, 1);
    // Found again for 0.5 s, the middle sensor on it: active inference resumes.
    let mut back = None;
    for k in 0..40 {
        let d = a
            .step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
        if d.driver == Driver::ActiveInference {
            back = Some(k);
            break;
        }
    }
    let k = back.expect("active inference resumes");
    assert!(
        (24..=26).contains(&k),
        "after ~25 steps with the line found, at a model step: {k}"
    );
    assert_eq!(a.stats.switches_to_active_inference, 2);
}

#[test]
fn a_fallback_ends_with_the_line_found_even_when_the_model_lost_its_trust_meanwhile() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(2, TRUSTED);
    let mut plans = still_planner();
    let mut a = under_active_inference(&frame, &mut model, &mut plans);
    let floor = [0.85f32; 96];
    for _ in 0..30 {
        a.step(&tick(&floor, [false; 3], [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert_eq!(a.stats.fallbacks, 1);
    // A probe below the takeover's threshold came in meanwhile.
    model.health.probe = Some(0.5);
    let drivers: Vec<Driver> = (0..60)
        .map(|_| {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
                .unwrap()
                .driver
        })
        .collect();
    let fallback = drivers.iter().filter(|d| **d == Driver::Fallback).count();
    assert!(
        (24..=27).contains(&fallback),
        "the fallback drives until the line is found for ~25 steps: {drivers:?}"
    );
    assert_eq!(drivers.last(), Some(&Driver::Reactive), "{drivers:?}");
    assert!(!drivers.contains(&Driver::ActiveInference));
    // Trusted again: active inference takes over from the rule.
    model.health = TRUSTED;
    let back = (0..20).any(|_| {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap()
            .driver
            == Driver::ActiveInference
    });
    assert!(back, "active inference takes over again once trusted");
    assert_eq!(a.stats.fallbacks, 1);
}

#[test]
fn a_late_plan_keeps_the_car_going_on_the_last_plan_and_is_counted() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(2, TRUSTED);
    let mut a = agent(&cfg());
    let mut first_only = FirstOnly::default();
    let mut last = [0.0; 2];
    let mut flagged = 0;
    for _ in 0..40 {
        let d = a
            .step(
                &Tick {
                    lockstep: false,
                    ..tick(&frame, CENTRED, last)
                },
                &mut model,
                &mut first_only,
            )
            .unwrap();
        last = d.wheels;
        flagged += u64::from(d.late_plan);
    }
    assert!(
        a.driving_by_active_inference(),
        "planning late is no reason to stop"
    );
    assert!(a.stats.late_plans >= 5, "{:?}", a.stats);
    assert_eq!(flagged, a.stats.late_plans, "each late plan's step says so");
    assert_eq!(a.stats.plans, 1, "only the takeover's plan came");
    assert_eq!(last, [8.0, 8.0], "the last plan's segments, then held");
}

/// A planner that answers each job only after `waits` timed-out waits (a slow or starved
/// planner thread), recording the longest wait asked for.
#[derive(Default)]
struct Slow {
    job: Option<u64>,
    waits_left: u32,
    waits: u32,
    longest: Duration,
}

impl PlanService<f32> for Slow {
    fn submit(&mut self, job: PlanJob<f32>) -> anyhow::Result<()> {
        self.job = Some(job.segment);
        self.waits_left = self.waits;
        Ok(())
    }
    fn wait(&mut self, timeout: Duration) -> Option<PlanDone> {
        self.longest = self.longest.max(timeout);
        self.job?;
        if self.waits_left > 0 {
            self.waits_left -= 1;
            return None;
        }
        let segment = self.job.take()?;
        Some(straight_on(segment))
    }
    fn idle(&self) -> bool {
        self.job.is_none()
    }
}

#[test]
fn lockstep_waits_for_every_plan_however_slow_real_time_never_blocks() {
    let frame = line_frame(6.0, 0.0);
    let drive = |lockstep: bool| {
        let mut model = Toy::new(2, TRUSTED);
        let mut a = agent(&cfg());
        // Each plan misses 3 waits: 6 s in lockstep, more than a plan ever gets to take.
        let mut plans = Slow {
            waits: 3,
            ..Slow::default()
        };
        for i in 0..60 {
            let t = Tick {
                lockstep,
                episode: u32::from(i >= 40),
                ..tick(&frame, CENTRED, [8.0, 8.0])
            };
            a.step(&t, &mut model, &mut plans).unwrap();
        }
        (a.stats, plans.longest)
    };
    let cfg = cfg();
    // Real time: never blocks longer than a late plan's wait (blocking held a 50 Hz step 24 ms);
    // every plan comes after its segment, so none is taken up.
    let (stats, longest) = drive(false);
    assert!(
        longest <= Duration::from_secs_f64(cfg.plan_wait_ms / 1000.0),
        "{longest:?}"
    );
    assert_eq!(stats.plans, 0, "{stats:?}");
    // Lockstep: every plan is taken up, none late, the new episode's included (a dropped plan
    // would make the run depend on the machine's speed).
    let (stats, longest) = drive(true);
    assert_eq!(stats.late_plans, 0, "{stats:?}");
    assert!(
        stats.plans >= 8 && stats.active_inference_steps > 0,
        "{stats:?}"
    );
    assert_eq!(
        longest,
        Duration::from_secs_f64(cfg.lockstep_wait_ms / 1000.0)
    );
}
