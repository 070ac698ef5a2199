//! systemd integration: the shipped units verify, and a service really speaks the notify protocol
//! (READY=1 once up, WATCHDOG=1 from its loop, STOPPING=1 on SIGTERM).

use std::os::unix::net::UnixDatagram;
use std::process::Command;
use std::time::{Duration, Instant};

use mtanet_system_tests::*;

#[test]
fn rendered_units_pass_systemd_analyze_verify() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let bins = bin_dir();
    let out = Command::new(root.join("ops/install-systemd.sh"))
        .args([
            "--dest",
            dir.path().to_str().unwrap(),
            "--bin",
            bins.to_str().unwrap(),
        ])
        .output()
        .expect("running ops/install-systemd.sh");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let units: Vec<String> = [
        "mtanet-simulator.service",
        "mtanet-predictor.service",
        "mtanet-trainer.service",
        "mtanet.target",
    ]
    .iter()
    .map(|u| dir.path().join(u).to_string_lossy().into_owned())
    .collect();
    // The scheduling `mta up` gives: the 50 Hz path real-time, the trainer normal and niced.
    let read = |u: &str| std::fs::read_to_string(dir.path().join(u)).unwrap();
    let predictor = read("mtanet-predictor.service");
    assert!(
        predictor.contains("CPUSchedulingPolicy=fifo\nCPUSchedulingPriority=20"),
        "{predictor}"
    );
    let trainer = read("mtanet-trainer.service");
    assert!(
        trainer.contains("CPUSchedulingPolicy=other\nNice=10"),
        "{trainer}"
    );
    let verify = Command::new("systemd-analyze")
        .arg("verify")
        .args(&units)
        .output()
        .expect("systemd-analyze is needed for this test (Debian package systemd)");
    let stderr = String::from_utf8_lossy(&verify.stderr);
    // verify only warns about unknown keys; treat any complaint about our units as a failure.
    let complaints: Vec<&str> = stderr.lines().filter(|l| l.contains("mtanet")).collect();
    assert!(
        verify.status.success() && complaints.is_empty(),
        "systemd-analyze verify:\n{stderr}"
    );
}

/// A checkout under a path with a space, `%` and `$`: the units quote and escape the binary and
/// the config so systemd finds both (verify checks that ExecStart's program exists).
#[test]
fn units_for_a_path_with_space_percent_and_dollar_verify() {
    let dir = tempfile::tempdir().unwrap();
    let odd = dir.path().join("my robots 100% $HOME");
    let bins = odd.join("bin");
    std::fs::create_dir_all(&bins).unwrap();
    for b in ["mta", "mta-simulator", "mta-predictor", "mta-trainer"] {
        std::os::unix::fs::symlink(bin_dir().join(b), bins.join(b)).unwrap();
    }
    let config = odd.join("stack 50%.toml");
    std::fs::copy(here().join("../ops/mtanet.toml"), &config).unwrap();
    let dest = dir.path().join("units");
    let out = Command::new(bins.join("mta"))
        .args(["systemd", "--user", "root", "--dest"])
        .arg(&dest)
        .arg("--config")
        .arg(&config)
        .arg("--bin")
        .arg(&bins)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sim = std::fs::read_to_string(dest.join("mtanet-simulator.service")).unwrap();
    let exec = sim.lines().find(|l| l.starts_with("ExecStart=")).unwrap();
    assert!(
        exec.contains("100%% $$HOME") && exec.contains("stack 50%%.toml"),
        "{exec}"
    );
    let units: Vec<_> = [
        "mtanet-simulator.service",
        "mtanet-predictor.service",
        "mtanet-trainer.service",
        "mtanet.target",
    ]
    .iter()
    .map(|u| dest.join(u))
    .collect();
    let verify = Command::new("systemd-analyze")
        .arg("verify")
        .args(&units)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&verify.stderr);
    let complaints: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("mtanet") || l.contains("robots"))
        .collect();
    assert!(
        verify.status.success() && complaints.is_empty(),
        "systemd-analyze verify:\n{stderr}"
    );
}

#[test]
fn predictor_notifies_ready_watchdog_and_stopping() {
    let dir = tempfile::tempdir().unwrap();
    let sock_path = dir.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let ns = unique_namespace("sd");
    let log = std::fs::File::create(dir.path().join("predictor.log")).unwrap();
    // systemd sets WATCHDOG_PID to the service's pid; `exec` keeps the shell's pid for it.
    let mut child = Command::new("sh")
        .args(["-c", r#"WATCHDOG_PID=$$ exec "$0" --namespace "$1""#])
        .arg(bin("mta-predictor"))
        .arg(&ns)
        .env("NOTIFY_SOCKET", &sock_path)
        .env("WATCHDOG_USEC", "400000")
        .stderr(log)
        .spawn()
        .unwrap();
    let mut seen = String::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut buf = [0u8; 512];
    let mut signalled = false;
    while Instant::now() < deadline && !seen.contains("STOPPING=1") {
        if let Ok(n) = sock.recv(&mut buf) {
            seen.push_str(&String::from_utf8_lossy(&buf[..n]));
            seen.push('\n');
        }
        if !signalled && seen.contains("READY=1") && seen.matches("WATCHDOG=1").count() >= 2 {
            signal(child.id(), Signal::TERM);
            signalled = true;
        }
    }
    if !signalled {
        let _ = child.kill();
    }
    let status = child.wait().unwrap();
    remove_namespace_files(&ns);
    assert!(seen.contains("READY=1"), "no READY=1 in {seen:?}");
    assert!(
        seen.matches("WATCHDOG=1").count() >= 2,
        "watchdog not petted: {seen:?}"
    );
    assert!(seen.contains("STOPPING=1"), "no STOPPING=1 in {seen:?}");
    assert!(status.success(), "predictor exited with {status}");
}
