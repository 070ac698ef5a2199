use super::*;

fn obs(step: u64) -> Observation {
    let mut o: Observation = bytemuck::Zeroable::zeroed();
    o.stamp_ns = 1_000 + step * 20_000_000;
    o.step = step;
    o.sim_time_s = step as f64 * 0.02;
    for (i, p) in o.image.iter_mut().enumerate() {
        // Values JSON's shortest decimal form must carry exactly.
        *p = (i as f32 * 0.1 + step as f32 / 3.0).fract();
    }
    o.command = [8.123_457, f32::MIN_POSITIVE];
    o.truth.lateral_m = -0.001_234_567_89;
    o
}

fn cmd(step: u64) -> Command {
    let mut c: Command = bytemuck::Zeroable::zeroed();
    c.stamp_ns = 2_000 + step * 20_000_000;
    c.step = step;
    c.wheel_velocity = [7.5, 1.0 / 3.0];
    c.model_error_ratio = f32::NAN;
    c
}

fn write(path: &Path, n: u64, flush_every: u64) {
    let mut w = RecordingWriter::create(path).unwrap();
    for s in 0..n {
        w.observation(&obs(s)).unwrap();
        w.command(&cmd(s)).unwrap();
        if s % flush_every == flush_every - 1 {
            w.flush().unwrap();
        }
    }
    let h = WeightsHeader {
        version: 3,
        len: 4,
        stamp_ns: 5,
        ..Default::default()
    };
    w.weights(&h, Some(&[1, 2, 3, 4])).unwrap();
    w.finish().unwrap();
}

#[test]
fn round_trips_every_message_bit_for_bit_in_stamp_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.mcap");
    write(&path, 50, 10);
    let r = read(&path).unwrap();
    assert!(r.damaged.is_none(), "{:?}", r.damaged);
    assert_eq!(r.messages.len(), 101);
    let Recorded::Weights(h, Some(blob)) = &r.messages[0].1 else {
        panic!("the weights (stamp 5) come first: {:?}", r.messages[0]);
    };
    assert_eq!((h.version, blob.as_slice()), (3, &[1u8, 2, 3, 4][..]));
    let observations: Vec<&Observation> = r
        .messages
        .iter()
        .filter_map(|m| match &m.1 {
            Recorded::Observation(o) => Some(o),
            _ => None,
        })
        .collect();
    assert_eq!(observations.len(), 50);
    for (s, o) in observations.iter().enumerate() {
        assert_eq!(bytemuck::bytes_of(*o), bytemuck::bytes_of(&obs(s as u64)));
    }
    let c = r.messages.iter().find_map(|m| match &m.1 {
        Recorded::Command(c) => Some(*c),
        _ => None,
    });
    let c = c.unwrap();
    assert!(c.model_error_ratio.is_nan(), "NaN survives through raw");
    assert_eq!(bytemuck::bytes_of(&c), bytemuck::bytes_of(&cmd(0)));
}

#[test]
fn a_truncated_recording_replays_what_is_readable_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.mcap");
    write(&path, 400, 100);
    let full = std::fs::read(&path).unwrap();
    // A recorder killed mid-write: the file ends inside the last chunks.
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &full[..full.len() * 2 / 3]).unwrap();
    let r = read(&cut).unwrap();
    let n = r.messages.len();
    assert!(r.damaged.is_some(), "the damage is reported");
    assert!(
        (200..800).contains(&n),
        "the flushed chunks before the cut are read: {n}"
    );
    assert!(
        r.damaged.as_ref().unwrap().contains("cut.mcap"),
        "{:?}",
        r.damaged
    );
    // Not an MCAP file at all: an error naming it.
    let junk = dir.path().join("junk.mcap");
    std::fs::write(&junk, b"not a recording").unwrap();
    let e = read(&junk).unwrap_err();
    assert!(format!("{e:#}").contains("junk.mcap"), "{e:#}");
}

#[test]
fn message_times_are_dates_the_offset_kept_in_the_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.mcap");
    let mut w = RecordingWriter::create(&path).unwrap();
    let mut o = obs(0);
    o.stamp_ns = mtanet_ipc::stamp::monotonic_ns();
    w.observation(&o).unwrap();
    w.finish().unwrap();
    let now_unix = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    let buf = std::fs::read(&path).unwrap();
    let m = mcap::MessageStream::new(&buf)
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    // A date of today (within a minute), not seconds since boot.
    assert!(
        now_unix.abs_diff(m.log_time) < 60_000_000_000,
        "{} vs {now_unix}",
        m.log_time
    );
    let summary = mcap::Summary::read(&buf).unwrap().unwrap();
    let index = &summary.metadata_indexes[0];
    assert_eq!(index.name, CLOCK_METADATA);
    let meta = mcap::read::metadata(&buf, index).unwrap();
    let offset: u64 = meta.metadata["monotonic_to_unix_offset_ns"]
        .parse()
        .unwrap();
    assert_eq!(
        m.log_time - offset,
        o.stamp_ns,
        "the stamp comes back exactly"
    );
}
