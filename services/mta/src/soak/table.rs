//! The soak's console table: latency percentiles against the targets, control and planning.

use mtanet_ipc::latency::LatencySummary;
use serde_json::Value;

pub(super) fn print_table(soak: &Value, raw: &LatencySummary) {
    println!(
        "soak: {} {} steps ({} min) on {}",
        soak["mode"], soak["steps"], soak["minutes"], soak["machine"]["cpu_model"]
    );
    println!(
        "| {:<18} | {:>9} | {:>9} | {:>9} | {:>9} | {:>9} |",
        "latency (us)", "p50", "p90", "p99", "p99.9", "max"
    );
    println!(
        "|{:-<20}|{:-<11}|{:-<11}|{:-<11}|{:-<11}|{:-<11}|",
        "", "", "", "", "", ""
    );
    for k in [
        "raw_pingpong_idle",
        "raw_pingpong",
        "round_trip",
        "obs_to_predictor",
        "predictor",
        "cmd_to_sim",
        "step",
        "plan",
    ] {
        let p = &soak["latency_us"][k];
        let f = |q: &str| p[q].as_f64().unwrap_or(f64::NAN);
        println!(
            "| {k:<18} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} |",
            f("p50"),
            f("p90"),
            f("p99"),
            f("p999"),
            f("max")
        );
    }
    let l = &soak["latency_us"];
    let transport = l["round_trip"]["p50"].as_f64().unwrap_or(f64::NAN)
        - l["predictor"]["p50"].as_f64().unwrap_or(0.0);
    let ratio = transport / raw.p50_us.max(1e-9);
    let check = |ok: bool| if ok { "met" } else { "NOT met" };
    let pred_p99 = l["predictor"]["p99"].as_f64().unwrap_or(f64::NAN);
    let step_p999 = l["step"]["p999"].as_f64().unwrap_or(f64::NAN);
    println!(
        "targets: predictor p99 {:.0} us <= 1000: {}; step p99.9 {:.0} us <= 3000: {}; transport p50 {:.1} us = {:.2} x raw ping-pong <= 1.2: {}",
        pred_p99,
        check(pred_p99 <= 1000.0),
        step_p999,
        check(step_p999 <= 3000.0),
        transport,
        ratio,
        check(ratio <= 1.2)
    );
    println!(
        "deadline misses {}, late commands {}, dropped commands {}, dropped replay chunks {}, tick jitter p99 {:.0} us",
        soak["deadline_misses"],
        soak["late_commands"],
        soak["dropped_commands"],
        soak["replay"]["dropped_chunks"],
        soak["tick_jitter_us"]["p99"].as_f64().unwrap_or(f64::NAN)
    );
    let (mp, inc) = (&soak["machine_pauses"], &soak["incidents"]);
    println!(
        "machine pauses (a CPU that ran nothing for >= 3 ms): {} ({:.1}/min, worst {:.1} ms){}; missed commands {}, overruns {}, late plans {}: {} during a machine pause, {} the stack's own",
        mp["count"],
        mp["per_minute"].as_f64().unwrap_or(0.0),
        mp["worst_ms"].as_f64().unwrap_or(0.0),
        if mp["measured"].as_bool() == Some(true) {
            ""
        } else {
            " (not measured: no SCHED_FIFO 99)"
        },
        inc["missed_commands"],
        inc["overruns"],
        inc["late_plans"],
        inc["during_machine_pauses"],
        inc["unexplained"]
    );
    let pl = &soak["planning"];
    println!(
        "active inference {:.1}% of the steps (first takeover after {:.1} s); late plans {}, fallbacks {}",
        100.0 * soak["active_inference_share"].as_f64().unwrap_or(0.0),
        soak["first_takeover_s"].as_f64().unwrap_or(f64::NAN),
        soak["late_plans"],
        soak["fallbacks"]
    );
    println!(
        "plans {}: iterations p50 {} (min {}), candidates p50 {} (min {}), cut by the deadline {:.1}%, cost p50 {:.3}, rollout {:.1} us per candidate-segment",
        pl["plans"],
        pl["iterations_p50"],
        pl["iterations_min"],
        pl["candidates_p50"],
        pl["candidates_min"],
        100.0 * pl["cut_share"].as_f64().unwrap_or(0.0),
        pl["cost_p50"].as_f64().unwrap_or(f64::NAN),
        pl["rollout_us_per_candidate_segment_p50"]
            .as_f64()
            .unwrap_or(f64::NAN)
    );
    for (name, p) in soak["processes"].as_object().into_iter().flatten() {
        println!(
            "{name} ({}): rss {} -> {} kB, fds {} -> {}",
            p["scheduling"].as_str().unwrap_or("?"),
            p["rss_kb"]["start"],
            p["rss_kb"]["end"],
            p["fds"]["start"],
            p["fds"]["end"]
        );
    }
}
