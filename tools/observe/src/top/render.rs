//! Drawing one frame of `mta top` (pure: tests render it on ratatui's test backend).

use std::collections::VecDeque;

use mtanet_ipc::CommandSource;
use ratatui::backend::TestBackend;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph, Row, Sparkline, Table};

use super::view::View;
use crate::status::Status;

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
        let lat = p.latency_text();
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
    let misses = detail("simulator", "missed_commands").map_or("-".into(), |x| x.to_string());
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

#[cfg(test)]
mod tests {
    use super::*;
    use mtanet_ipc::node::NodeCensus;
    use mtanet_ipc::{Command, ProcessStats};
    use ratatui::Terminal;
    use std::collections::BTreeMap;

    fn status() -> Status {
        let mut s: ProcessStats = bytemuck::Zeroable::zeroed();
        s.set_role("simulator");
        s.pid = 4242;
        s.count = 1000;
        s.rate_hz = 50.0;
        s.p99_us = 812.0;
        s.laps = 7;
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
}
