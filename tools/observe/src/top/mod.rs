//! `mta top`: a live terminal view of a running stack (ratatui), refreshed once a second, that
//! fits an 80x24 terminal over SSH: per process alive / restarts / CPU / RSS / rate / latency;
//! the topics' rates; who drives, laps, the model's live error against copy-last and the probe;
//! the trainer's updates, loss and replay fill; sparklines of the trends. It reads what the
//! processes publish (the stats topic, the same as `mta status`, and the latest observation,
//! command and trainer status), never their logs.
//!
//! `--frames N` prints N frames as plain text instead (no terminal needed: tests, captures).

mod render;
mod view;

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::time::{Duration, Instant};

use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::{IpcConfig, create_observer_node};
use mtanet_ipc::ports::{Receiver, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, Observation, ProcessStats, TrainerStatus, names, stats};
use ratatui::Terminal;
use ratatui::backend::TestBackend;

use crate::status::snapshot;
pub use render::{render, text};
pub use view::View;

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
