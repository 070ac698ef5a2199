//! The soak's console table: latency percentiles against the targets, control and planning.

use mtanet_summaries::LatencySummary;
use mtanet_summaries::soak::{LEGS, SoakReport};

/// Prints `soak`'s table to stdout (what `mta soak` ends with).
pub fn print_table(soak: &SoakReport) {
    println!(
        "soak: {} {} steps ({} min) on {}",
        soak.mode, soak.steps, soak.minutes, soak.machine.cpu_model
    );
    println!(
        "| {:<18} | {:>9} | {:>9} | {:>9} | {:>9} | {:>9} |",
        "latency (us)", "p50", "p90", "p99", "p99.9", "max"
    );
    println!(
        "|{:-<20}|{:-<11}|{:-<11}|{:-<11}|{:-<11}|{:-<11}|",
        "", "", "", "", "", ""
    );
    print_targets(soak);
    println!(
        "overruns {}, missed commands {}, steps following the last plan {}, dropped commands {}, lost replay chunks {}",
        soak.overruns,
        soak.missed_commands,
        soak.plan_followed,
        soak.dropped_commands,
        soak.replay.chunks_lost,
    );
    print_incidents_and_plans(soak);
    for (name, p) in &soak.processes {
        println!(
            "{name} ({}): rss {} -> {} kB, fds {} -> {}",
            p.scheduling, p.rss_kb.start, p.rss_kb.end, p.fds.start, p.fds.end
        );
    }
}

/// The latency table and whether it meets the targets.
fn print_targets(soak: &SoakReport) {
    let leg = |k: &str| soak.latency.get(k).copied().unwrap_or_default();
    for k in LEGS {
        let p = leg(k);
        println!(
            "| {k:<18} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} |",
            p.p50_us, p.p90_us, p.p99_us, p.p999_us, p.max_us
        );
    }
    let (raw, predictor, step): (LatencySummary, _, _) =
        (leg("raw_pingpong"), leg("predictor"), leg("step"));
    let transport = leg("round_trip").p50_us - predictor.p50_us;
    let ratio = transport / raw.p50_us.max(1e-9);
    let check = |ok: bool| if ok { "met" } else { "NOT met" };
    println!(
        "targets: predictor p99 {:.0} us <= 1000: {}; step p99.9 {:.0} us <= 3000: {}; transport p50 {:.1} us = {:.2} x raw ping-pong <= 1.2: {}",
        predictor.p99_us,
        check(predictor.p99_us <= 1000.0),
        step.p999_us,
        check(step.p999_us <= 3000.0),
        transport,
        ratio,
        check(ratio <= 1.2)
    );
}

/// Machine pauses and what fell in them, who drove, and what the plans could afford.
fn print_incidents_and_plans(soak: &SoakReport) {
    let (mp, inc) = (&soak.machine_pauses, &soak.incidents);
    println!(
        "machine pauses (a CPU that ran nothing for >= 3 ms): {} ({:.1}/min, worst {:.1} ms){}; missed commands {}, overruns {}, late plans {}: {} during a machine pause, {} the stack's own",
        mp.count,
        mp.per_minute,
        mp.worst_ms,
        if mp.measured {
            ""
        } else {
            " (not measured: no SCHED_FIFO 99)"
        },
        inc.missed_commands,
        inc.overruns,
        inc.late_plans,
        inc.during_machine_pauses,
        inc.unexplained
    );
    let (c, pl) = (&soak.control, &soak.planning);
    println!(
        "active inference {:.1}% of the steps (first takeover after {:.1} s); late plans {}, fallbacks {}",
        100.0 * soak.active_inference_share,
        c.first_takeover_s.unwrap_or(f64::NAN),
        c.late_plans,
        c.fallbacks
    );
    println!(
        "plans {}: iterations p50 {} (min {}), candidates p50 {} (min {}), cut by the deadline {:.1}%, cost p50 {:.3}, rollout {:.1} us per candidate-segment",
        pl.plans,
        pl.iterations_p50,
        pl.iterations_min,
        pl.candidates_p50,
        pl.candidates_min,
        100.0 * pl.cut_share,
        pl.cost_p50,
        pl.rollout_us_per_candidate_segment_p50
    );
}
