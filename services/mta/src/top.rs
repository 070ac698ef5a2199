//! `mta top`: a live terminal view of a running stack (ratatui), refreshed once a second, that
//! fits an 80x24 terminal over SSH: per process alive / restarts / CPU / RSS / rate / latency;
//! the topics' rates; who drives, laps, the model's live error against copy-last and the probe;
//! the trainer's updates, loss and replay fill; sparklines of the trends. It reads what the
//! processes publish (the stats topic, the same as `mta status`, and the latest observation,
//! command and trainer status), never their logs.
//!
//! `--frames N` prints N frames as plain text instead (no terminal needed: tests, captures).

use std::collections::{BTreeMap, VecDeque};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::{IpcConfig, create_observer_node};
use mtanet_ipc::ports::{Receiver, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, CommandSource, Observation, ProcessStats, TrainerStatus, names, stats};
use ratatui::Terminal;
use ratatui::backend::TestBackend;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph, Row, Sparkline, Table};

use crate::status::{Status, snapshot};

#[derive(Debug, clap::Args)]
pub struct TopArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Print this many frames as plain text, one a second, and exit (no terminal needed).
    #[arg(long)]
    frames: Option<u32>,
    /// Size of the plain-text frames.
    #[arg(long, default_value_t = 80)]
    width: u16,
    #[arg(long, default_value_t = 24)]
    height: u16,
}

/// Samples kept for the sparklines (one a second).
const HISTORY: usize = 120;

/// A value and when it was seen, for rates from counters.
#[derive(Clone, Copy)]
struct Seen {
    value: u64,
    at: Instant,
}

/// Rate of a counter between two refreshes.
#[derive(Default)]
struct Rate {
    last: Option<Seen>,
    pub hz: Option<f64>,
}

impl Rate {
    fn update(&mut self, value: Option<u64>, now: Instant) {
        let Some(value) = value else { return };
        if let Some(l) = self.last {
            let dt = now.duration_since(l.at).as_secs_f64();
            if dt > 0.2 {
                // A restarted process counts from 0 again: no negative rate.
                self.hz = Some(value.saturating_sub(l.value) as f64 / dt);
                self.last = Some(Seen { value, at: now });
            }
        } else {
            self.last = Some(Seen { value, at: now });
        }
    }
}

/// Everything one frame shows.
#[derive(Default)]
pub struct View {
    pub status: Option<Status>,
    pub observation: Option<Observation>,
    pub command: Option<Command>,
    pub trainer: Option<TrainerStatus>,
    /// Topic rates (Hz): observation, command, replay, weights.
    rates: [Rate; 4],
    /// Histories for the sparklines.
    step_p99_us: VecDeque<u64>,
    predictor_p99_us: VecDeque<u64>,
    model_ratio_milli: VecDeque<u64>,
    loss_micro: VecDeque<u64>,
    started: Option<Instant>,
}

fn push(h: &mut VecDeque<u64>, v: Option<f64>) {
    if h.len() == HISTORY {
        h.pop_front();
    }
    h.push_back(v.filter(|v| v.is_finite() && *v >= 0.0).unwrap_or(0.0) as u64);
}

impl View {
    /// Takes in one refresh's readings.
    pub fn update(
        &mut self,
        status: Status,
        observation: Option<Observation>,
        command: Option<Command>,
        trainer: Option<TrainerStatus>,
    ) {
        let now = Instant::now();
        self.started.get_or_insert(now);
        self.observation = observation.or(self.observation);
        self.command = command.or(self.command);
        self.trainer = trainer.or(self.trainer);
        let [obs, cmd, replay, weights] = &mut self.rates;
        obs.update(observation.map(|o| o.step), now);
        cmd.update(command.map(|c| c.step), now);
        replay.update(trainer.map(|t| t.chunks_received), now);
        weights.update(command.map(|c| c.model_version), now);
        let p = |role: &str, k: &str| {
            status
                .processes
                .get(role)
                .and_then(|p| p.latency_us.get(k).copied())
        };
        push(&mut self.step_p99_us, p("simulator", "p99"));
        push(&mut self.predictor_p99_us, p("predictor", "p99"));
        push(
            &mut self.model_ratio_milli,
            self.command.map(|c| f64::from(c.model_error_ratio) * 1e3),
        );
        let loss = status
            .processes
            .get("trainer")
            .and_then(|t| t.detail.get("loss"))
            .and_then(|v| v.as_f64());
        push(&mut self.loss_micro, loss.map(|l| l * 1e6));
        self.status = Some(status);
    }
}

fn num(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or("-".into(), |v| format!("{v:.digits$}"))
}

fn bold() -> Style {
    Style::default().add_modifier(Modifier::BOLD)
}

/// Draws one frame; pure (tests render it on a test backend).
pub fn render(f: &mut ratatui::Frame, v: &View) {
    let [title, procs, mid, trainer, trends] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(6),
        Constraint::Length(6),
        Constraint::Length(5),
        Constraint::Min(5),
    ])
    .areas(f.area());
    let Some(s) = &v.status else {
        f.render_widget(Paragraph::new("mta top: connecting..."), title);
        return;
    };
    let dead = if s.nodes.dead.is_empty() {
        Span::raw(String::new())
    } else {
        Span::styled(
            format!(", {} DEAD (mta status --cleanup)", s.nodes.dead.len()),
            Style::default().fg(Color::Red),
        )
    };
    let up = v.started.map_or(0, |t| t.elapsed().as_secs());
    f.render_widget(
        Paragraph::new(Line::from(vec![
            Span::styled("mtanet top", bold()),
            Span::raw(format!(
                "  namespace {}  nodes {} alive",
                s.namespace,
                s.nodes.alive.len()
            )),
            dead,
            Span::raw(format!("  watching {up} s  (q quits)")),
        ])),
        title,
    );
    processes(f, procs, s);
    let [topics, control] =
        Layout::horizontal([Constraint::Length(30), Constraint::Min(20)]).areas(mid);
    topics_box(f, topics, v);
    control_box(f, control, v);
    trainer_box(f, trainer, v);
    trends_box(f, trends, v);
}

fn processes(f: &mut ratatui::Frame, area: Rect, s: &Status) {
    let header = Row::new([
        "process",
        "pid",
        "state",
        "rst",
        "cpu%",
        "rss MB",
        "rate/s",
        "us p50/p99/p99.9/max",
    ])
    .style(bold());
    let rows = ["simulator", "predictor", "trainer"].map(|role| {
        let Some(p) = s.processes.get(role) else {
            return Row::new([role.to_string(), "-".into(), "absent".into()])
                .style(Style::default().fg(Color::DarkGray));
        };
        let alive = p.age_s <= 3.0;
        let l = |k| p.latency_us.get(k).copied().unwrap_or(f64::NAN);
        let lat = format!(
            "{:.0}/{:.0}/{:.0}/{:.0}",
            l("p50"),
            l("p99"),
            l("p999"),
            l("max")
        );
        let row = Row::new([
            role.to_string(),
            p.pid.to_string(),
            if alive {
                "alive".into()
            } else {
                format!("silent {:.0}s", p.age_s)
            },
            p.restarts.to_string(),
            format!("{:.0}", p.cpu_percent),
            format!("{:.0}", p.rss_kb as f64 / 1024.0),
            num(p.rate_hz, 1),
            lat,
        ]);
        if alive {
            row
        } else {
            row.style(Style::default().fg(Color::Red))
        }
    });
    let widths = [
        Constraint::Length(9),
        Constraint::Length(7),
        Constraint::Length(9),
        Constraint::Length(3),
        Constraint::Length(4),
        Constraint::Length(6),
        Constraint::Length(6),
        Constraint::Min(10),
    ];
    f.render_widget(
        Table::new(rows, widths)
            .header(header)
            .block(Block::bordered().title("processes")),
        area,
    );
}

fn topics_box(f: &mut ratatui::Frame, area: Rect, v: &View) {
    let names = ["observation", "command", "replay", "weights"];
    let lines: Vec<Line> = names
        .iter()
        .zip(&v.rates)
        .map(|(n, r)| {
            let hz = match (n, r.hz) {
                // Weights come every ~15 s: per minute reads better.
                (&"weights", Some(h)) => format!("{:>6.1} /min", h * 60.0),
                (_, h) => format!("{:>6} Hz", num(h, 1)),
            };
            Line::from(format!("{n:<12}{hz}"))
        })
        .collect();
    f.render_widget(
        Paragraph::new(lines).block(Block::bordered().title("topics")),
        area,
    );
}

fn control_box(f: &mut ratatui::Frame, area: Rect, v: &View) {
    let detail = |role: &str, k: &str| {
        v.status
            .as_ref()
            .and_then(|s| s.processes.get(role))
            .and_then(|p| p.detail.get(k).cloned())
    };
    let driver = v
        .command
        .and_then(|c| CommandSource::from_u32(c.source))
        .map_or("-", CommandSource::name);
    let colour = if driver == "active_inference" {
        Color::Green
    } else {
        Color::Yellow
    };
    let c = v.command;
    let laps = detail("simulator", "laps").map_or("-".into(), |x| x.to_string());
    let misses = detail("simulator", "deadline_misses").map_or("-".into(), |x| x.to_string());
    let fallbacks = detail("predictor", "fallbacks").map_or("-".into(), |x| x.to_string());
    let lines = vec![
        Line::from(vec![
            Span::raw("driver "),
            Span::styled(
                driver,
                Style::default().fg(colour).add_modifier(Modifier::BOLD),
            ),
            Span::raw(format!("  laps {laps}")),
        ]),
        Line::from(format!(
            "step {}  episode {}",
            v.observation.map_or("-".into(), |o| o.step.to_string()),
            v.observation.map_or("-".into(), |o| o.episode.to_string()),
        )),
        Line::from(format!(
            "model/copy-last {}  probe {}",
            num(c.map(|c| f64::from(c.model_error_ratio)), 2),
            num(c.map(|c| f64::from(c.probe)), 2)
        )),
        Line::from(format!(
            "fallbacks {fallbacks}  deadline misses {misses}  weights v{}",
            c.map_or("-".into(), |c| c.model_version.to_string())
        )),
    ];
    f.render_widget(
        Paragraph::new(lines).block(Block::bordered().title("control")),
        area,
    );
}

fn trainer_box(f: &mut ratatui::Frame, area: Rect, v: &View) {
    let p = v.status.as_ref().and_then(|s| s.processes.get("trainer"));
    let t = v.trainer;
    let line = Line::from(format!(
        "updates {} ({}/s)  loss {}  replay {}  chunks {} lost {}",
        t.map_or("-".into(), |t| t.updates.to_string()),
        num(p.and_then(|p| p.rate_hz), 1),
        p.and_then(|p| p.detail.get("loss"))
            .and_then(|l| l.as_f64())
            .map_or("-".into(), |l| format!("{l:.4}")),
        t.map_or("-".into(), |t| t.sequences.to_string()),
        t.map_or("-".into(), |t| t.chunks_received.to_string()),
        t.map_or("-".into(), |t| t.chunks_lost.to_string()),
    ));
    let block = Block::bordered().title("trainer");
    let inner = block.inner(area);
    f.render_widget(block, area);
    let [text, spark] = Layout::vertical([Constraint::Length(1), Constraint::Min(1)]).areas(inner);
    f.render_widget(Paragraph::new(line), text);
    sparkline(f, spark, "loss", &v.loss_micro, Color::Blue);
}

fn trends_box(f: &mut ratatui::Frame, area: Rect, v: &View) {
    let block = Block::bordered().title("trends (one a second)");
    let inner = block.inner(area);
    f.render_widget(block, area);
    let rows = Layout::vertical([Constraint::Length(1); 3]).split(inner);
    let last = |h: &VecDeque<u64>| h.back().copied().unwrap_or(0);
    sparkline(
        f,
        rows[0],
        &format!("step p99 {:>5}us", last(&v.step_p99_us)),
        &v.step_p99_us,
        Color::Cyan,
    );
    sparkline(
        f,
        rows[1],
        &format!("pred p99 {:>5}us", last(&v.predictor_p99_us)),
        &v.predictor_p99_us,
        Color::Magenta,
    );
    sparkline(
        f,
        rows[2],
        &format!(
            "model/copy {:>5.2}",
            last(&v.model_ratio_milli) as f64 / 1e3
        ),
        &v.model_ratio_milli,
        Color::Green,
    );
}

/// A one-line sparkline with a label in front, newest sample at the right.
fn sparkline(f: &mut ratatui::Frame, area: Rect, label: &str, h: &VecDeque<u64>, c: Color) {
    let [l, s] = Layout::horizontal([Constraint::Length(19), Constraint::Min(1)]).areas(area);
    f.render_widget(Paragraph::new(label.to_string()), l);
    let n = (s.width as usize).min(h.len());
    let data: Vec<u64> = h.iter().skip(h.len() - n).copied().collect();
    f.render_widget(
        Sparkline::default()
            .data(data)
            .style(Style::default().fg(c)),
        s,
    );
}

/// The frame as plain text, one line per terminal row.
pub fn text(backend: &TestBackend) -> String {
    let buf = backend.buffer();
    let mut out = String::new();
    for y in 0..buf.area.height {
        let line: String = (0..buf.area.width).map(|x| buf[(x, y)].symbol()).collect();
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

/// The topics `mta top` reads, through an observer node (it never cleans dead nodes).
pub struct Feeds {
    _node: iceoryx2::prelude::Node<iceoryx2::prelude::ipc::Service>,
    stats: Receiver<ProcessStats>,
    obs: Receiver<Observation>,
    cmds: Receiver<Command>,
    trainer: Receiver<TrainerStatus>,
    latest: BTreeMap<String, ProcessStats>,
    ipc: IpcConfig,
}

impl Feeds {
    pub fn open(ipc: &IpcConfig) -> anyhow::Result<Self> {
        let node = create_observer_node(ipc, &format!("top-{}", std::process::id()))?;
        Ok(Self {
            stats: Receiver::open(&node, names::STATS, stats::SHAPE)?,
            obs: Receiver::open(&node, names::OBSERVATION, TopicShape::STEP)?,
            cmds: Receiver::open(&node, names::COMMAND, TopicShape::STEP)?,
            trainer: Receiver::open(&node, names::TRAINER_STATUS, TopicShape::STATUS)?,
            _node: node,
            latest: BTreeMap::new(),
            ipc: ipc.clone(),
        })
    }

    /// One refresh: waits up to `wait` for the processes' stats, then takes the newest of each.
    pub fn refresh(&mut self, view: &mut View, wait: Duration) -> anyhow::Result<()> {
        let s = snapshot(&self.ipc, &self.stats, &mut self.latest, wait)?;
        view.update(
            s,
            self.obs.latest()?,
            self.cmds.latest()?,
            self.trainer.latest()?,
        );
        Ok(())
    }
}

pub fn run(args: TopArgs) -> anyhow::Result<()> {
    let (_, ipc) = args.common.load()?;
    let shutdown = Shutdown::install()?;
    let mut feeds = Feeds::open(&ipc)?;
    let mut view = View::default();
    let frames = match args.frames {
        Some(n) => Some(n),
        None if !std::io::stdout().is_terminal() => {
            tracing::warn!("stdout is not a terminal: printing one text frame (see --frames)");
            Some(1)
        }
        None => None,
    };
    if let Some(n) = frames {
        let mut term = Terminal::new(TestBackend::new(args.width, args.height))?;
        for i in 0..n {
            if shutdown.requested() {
                break;
            }
            let t0 = Instant::now();
            feeds.refresh(&mut view, Duration::from_millis(1500))?;
            term.draw(|f| render(f, &view))?;
            print!("{}", text(term.backend()));
            if i + 1 < n {
                println!();
                std::thread::sleep(Duration::from_secs(1).saturating_sub(t0.elapsed()));
            }
        }
        return Ok(());
    }
    let mut term = ratatui::init();
    let res = interactive(&mut term, &mut feeds, &mut view, &shutdown);
    ratatui::restore();
    res
}

fn interactive(
    term: &mut ratatui::DefaultTerminal,
    feeds: &mut Feeds,
    view: &mut View,
    shutdown: &Shutdown,
) -> anyhow::Result<()> {
    use ratatui::crossterm::event::{self, Event, KeyCode, KeyModifiers};
    let mut next = Instant::now();
    while !shutdown.requested() {
        if Instant::now() >= next {
            feeds.refresh(view, Duration::from_millis(300))?;
            term.draw(|f| render(f, view))?;
            next = Instant::now() + Duration::from_secs(1);
        }
        if event::poll(
            next.saturating_duration_since(Instant::now())
                .min(Duration::from_millis(200)),
        )? {
            if let Event::Key(k) = event::read()? {
                let ctrl_c =
                    k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL);
                if matches!(k.code, KeyCode::Char('q') | KeyCode::Esc) || ctrl_c {
                    return Ok(());
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mtanet_ipc::node::NodeCensus;

    fn status() -> Status {
        let mut s: ProcessStats = bytemuck::Zeroable::zeroed();
        s.set_role("simulator");
        s.pid = 4242;
        s.count = 1000;
        s.rate_hz = 50.0;
        s.p99_us = 812.0;
        s.laps_or_driver_or_fill = 7;
        s.stamp_ns = mtanet_ipc::stamp::monotonic_ns();
        let mut processes = BTreeMap::new();
        processes.insert("simulator".to_string(), crate::status::view(&s));
        Status {
            namespace: "test".into(),
            nodes: NodeCensus {
                alive: vec!["mta-simulator".into()],
                dead: vec![],
                other: 0,
            },
            services: vec![],
            processes,
        }
    }

    #[test]
    fn renders_processes_driver_and_trends_in_80x24() {
        let mut view = View::default();
        let mut cmd: Command = bytemuck::Zeroable::zeroed();
        cmd.source = CommandSource::ActiveInference as u32;
        cmd.model_error_ratio = 0.42;
        cmd.probe = 0.8;
        view.update(status(), None, Some(cmd), None);
        let mut term = Terminal::new(TestBackend::new(80, 24)).unwrap();
        term.draw(|f| render(f, &view)).unwrap();
        let t = text(term.backend());
        assert_eq!(t.lines().count(), 24);
        assert!(t.lines().all(|l| l.chars().count() <= 80));
        for want in [
            "simulator",
            "4242",
            "alive",
            "50.0",
            "laps 7",
            "active_inference",
            "0.42",
            "predictor",
            "absent",
            "step p99   812us",
        ] {
            assert!(t.contains(want), "{want:?} missing from\n{t}");
        }
    }

    #[test]
    fn rates_come_from_counters_and_survive_a_restart() {
        let mut r = Rate::default();
        let t0 = Instant::now();
        r.update(Some(100), t0);
        assert_eq!(r.hz, None, "one reading has no rate");
        r.update(Some(150), t0 + Duration::from_secs(1));
        assert_eq!(r.hz, Some(50.0));
        r.update(Some(3), t0 + Duration::from_secs(2));
        assert_eq!(
            r.hz,
            Some(0.0),
            "a counter that restarted is not a negative rate"
        );
    }
}
