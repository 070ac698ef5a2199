//! A 1-minute real-time soak of the real workload (its own test binary, so no other test shares
//! the two cores): `mta soak` runs the shipped stack from the committed checkpoint, the predictor
//! planning by active inference at 50 Hz and the trainer learning, beside a raw iceoryx2
//! ping-pong. No step may miss its 20 ms deadline, no command may be dropped and no plan may be
//! late, except while the machine itself ran nothing (a host pausing the VM, which the soak
//! measures with a SCHED_FIFO 99 thread per CPU); no process may end with more open files than
//! it had once warmed up. The latency targets and what each plan could afford are reported by
//! the soak itself (a benchmark), not asserted here.

use std::collections::BTreeMap;

use mtanet_system_tests::{here, one_minute_soak};

#[test]
fn a_one_minute_realtime_soak_misses_no_deadline_and_leaks_no_files() {
    let dir = tempfile::tempdir().unwrap();
    let soak = one_minute_soak(dir.path(), &here().join("../ops/mtanet.toml"), &[]);
    assert_eq!(soak.steps, 3000, "{soak:#?}");
    assert!(soak.clean_exit, "{soak:#?}");
    // Every missed command, overrun and late plan (a dropped command is a missed one) must have
    // happened while the machine itself ran nothing (a VM paused by its host): none the stack's.
    assert_eq!(soak.incidents.unexplained, 0, "{soak:#?}");
    assert_eq!(soak.replay.chunks_lost, 0, "{soak:#?}");
    let no_restarts: BTreeMap<String, u32> = ["predictor", "simulator", "trainer"]
        .map(|n| (n.to_string(), 0))
        .into();
    assert_eq!(soak.restarts, no_restarts, "{soak:#?}");
    assert!(
        soak.control.active_inference_steps > 1500,
        "the predictor must plan: {soak:#?}"
    );
    for name in ["simulator", "predictor", "trainer"] {
        let fds = soak.processes.get(name).map(|p| p.fds).unwrap_or_default();
        assert!(
            fds.start > 0 && fds.end <= fds.start,
            "{name}'s open files grew: {soak:#?}"
        );
    }
}
